//! The MAVLink codec: frames found and checked in bytes, decoded to SI reports and counted
//! ([`Ingestor`]: the one decode path for every source, live links and logs alike), what an
//! autopilot says as text, and what savsim sends encoded as one identity. The bytes come from
//! `links` (sockets) and `logs` (tlog files); autopilot logs join at the reports
//! (`Session::on_report`). MAVLink messages are also written by the feed (`feed::wire`) and the
//! study's pilot, each for its own purpose.
//!
//! - [`frame`]: find and check frames in bytes.
//! - [`decode`]: frames to typed reports in SI units.
//! - [`stats`]: counts of everything seen, for `--summary-json`.
//! - [`notes`]: what an autopilot says (STATUSTEXT, mode changes, COLLISION) as text.
//! - [`outbox`]: what savsim sends, encoded as one identity.
//! - [`signing`]: MAVLink 2 signing of what savsim sends, and judging what it receives.

pub mod decode;
pub mod frame;
pub mod notes;
pub mod outbox;
pub mod signing;
pub mod stats;

use crate::world::SenderId;
use decode::Report;
use frame::RawFrame;
use stats::IngestStats;

/// A valid frame turned into a report savsim uses, with who sent it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Decoded {
    /// The sender.
    pub sender: SenderId,
    /// The report.
    pub report: Report,
}

/// Counts and decodes frames; the single decode path for every source.
#[derive(Debug, Default)]
pub struct Ingestor {
    /// Everything counted so far.
    pub stats: IngestStats,
}

impl Ingestor {
    /// Count a frame that a reader already counted as valid, decode it, and count a rejection.
    pub fn decode_valid(&mut self, frame: &RawFrame<'_>) -> Option<Decoded> {
        match decode::decode(frame) {
            Ok(Some(report)) => Some(Decoded {
                sender: SenderId {
                    system_id: frame.system_id,
                    component_id: frame.component_id,
                },
                report,
            }),
            Ok(None) => None,
            Err(reason) => {
                self.stats.count_rejection(reason);
                None
            }
        }
    }

    /// Count any complete frame and decode it if valid.
    pub fn frame(&mut self, frame: &RawFrame<'_>) -> Option<Decoded> {
        if self.stats.count_frame(frame) {
            self.decode_valid(frame)
        } else {
            None
        }
    }
}
