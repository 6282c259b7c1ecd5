//! The closed-loop feed's sender on the session thread: its own identity, where it went, its
//! heartbeat, its latency and its `--feed-out` recording.

use std::io::BufWriter;
use std::path::PathBuf;

use super::{latency, new_histogram, FeedLinkReport};
use crate::codec::outbox::Outbox;
use crate::links::sockets::{Network, Outgoing};
use crate::links::supervisor::Endpoint;
use crate::logs::tlog::TlogWriter;
use crate::world::SenderId;

/// Sends the session's feed messages to each vehicle's route, as the feed's identity.
pub(super) struct FeedSender {
    pub(super) outbox: Outbox,
    /// Where the feed went, for the heartbeat.
    pub(super) endpoints: Vec<Endpoint>,
    pub(super) next_heartbeat_t_s: f64,
    pub(super) sent: u64,
    pub(super) unrouted: u64,
    pub(super) heartbeats: u64,
    pub(super) latency_us: hdrhistogram::Histogram<u64>,
    /// `--feed-out`: what was sent, as sent.
    pub(super) record: Option<(PathBuf, TlogWriter<BufWriter<std::fs::File>>)>,
    /// `--forward-own`: the stations see the feed's frames too (kept here until shown).
    pub(super) shown: bool,
    pub(super) shown_frames: Vec<Vec<u8>>,
}

impl FeedSender {
    pub(super) fn new(from: SenderId) -> Self {
        Self {
            outbox: Outbox::new(from),
            endpoints: Vec::new(),
            next_heartbeat_t_s: f64::NEG_INFINITY,
            sent: 0,
            unrouted: 0,
            heartbeats: 0,
            latency_us: new_histogram(),
            record: None,
            shown: false,
            shown_frames: Vec::new(),
        }
    }

    /// Hand `bytes` to the link for `to`, and record them.
    pub(super) fn send(&mut self, network: &Network, to: Endpoint, bytes: Vec<u8>, now_s: f64) {
        if let Some((path, rec)) = self.record.as_mut() {
            if let Err(e) = rec.write_record((now_s * 1e6).max(0.0) as u64, &bytes) {
                tracing::warn!("--feed-out {}: {e}; no longer recording", path.display());
                self.record = None;
            }
        }
        if self.shown {
            self.shown_frames.push(bytes.clone());
        }
        network.send(Outgoing { to, bytes });
    }

    pub(super) fn report(&self) -> FeedLinkReport {
        FeedLinkReport {
            sent: self.sent,
            unrouted: self.unrouted,
            heartbeats: self.heartbeats,
            latency: latency(&self.latency_us),
        }
    }
}
