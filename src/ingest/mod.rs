//! Ingest: MAVLink bytes in, decoded reports out. The only mavlink-aware code in savsim.
//!
//! - [`frame`]: find and check frames in bytes.
//! - [`decode`]: frames to typed reports in SI units.
//! - [`stats`]: counts of everything seen, for `--summary-json`.
//! - [`tlog`]: tlog reading (with resync) and writing.
//! - [`ulog`], [`dataflash`]: PX4 ULog and ArduPilot DataFlash files, read generically.
//! - [`flightlog`]: those logs to the same reports, in time order (they skip the framer).
//! - [`stream`]: datagrams and byte streams (UDP, TCP) through the same framer.
//! - [`address`]: `--connect` addresses.
//! - [`live`]: tokio sockets: chunks in, addressed bytes out.
//! - [`outbox`]: what savsim sends, encoded as one identity.
//! - [`supervisor`]: per-vehicle routes, stream requests and their supervision (pure).
//! - [`forward`]: `--forward`, routing between vehicles and ground stations (pure).
//! - [`signing`]: MAVLink 2 signing of what savsim sends, and judging what it receives.
//! - [`notes`]: what an autopilot says (STATUSTEXT, mode changes, COLLISION) as text.
//!
//! Every MAVLink frame funnels into [`Ingestor::frame`], so replay and live decode identically;
//! autopilot logs join at the reports (`Session::on_report`).

pub mod address;
pub mod dataflash;
pub mod decode;
pub mod flightlog;
pub mod forward;
pub mod frame;
pub mod live;
pub mod notes;
pub mod outbox;
pub mod signing;
pub mod stats;
pub mod stream;
pub mod supervisor;
pub mod tlog;
pub mod ulog;

use decode::Report;
use frame::RawFrame;
use stats::{IngestStats, SenderId};

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
