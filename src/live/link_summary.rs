//! What the links of a live run did, for the summary's `link` object: counts, latencies, the
//! feed, forwarding and signing.

use std::sync::atomic::Ordering;

use serde::Serialize;

use super::LiveSession;
use crate::codec::signing::SigningCounts;
use crate::links::forward::ForwardCounts;
use crate::links::sockets::LinkCounters;
use crate::links::supervisor::{SupervisorCounts, VehicleLink};

/// Datagram (or TCP read) received -> its frames decoded, run through the session and their
/// events written, microseconds.
#[derive(Debug, Clone, Copy, Serialize)]
pub struct Latency {
    /// Chunks measured.
    pub chunks: u64,
    /// Median.
    pub p50_us: u64,
    /// 99th percentile.
    pub p99_us: u64,
    /// Largest.
    pub max_us: u64,
}

/// What the closed-loop feed sent, for the summary's `link.feed`.
#[derive(Debug, Clone, Serialize)]
pub struct FeedLinkReport {
    /// Messages sent to a vehicle's link.
    pub sent: u64,
    /// Messages for a vehicle with no route yet (not heard as an autopilot): not sent.
    pub unrouted: u64,
    /// The feed component's heartbeats sent.
    pub heartbeats: u64,
    /// Datagram (or read) with the pose received -> its feed frame handed to the link.
    pub latency: Option<Latency>,
}

/// What the links did, for the summary's `link` object.
#[derive(Debug, Clone, Serialize)]
pub struct LinkReport {
    /// The addresses, in `--connect` order (a link's index).
    pub endpoints: Vec<String>,
    /// Requests, re-requests, reboots, heartbeats.
    #[serde(flatten)]
    pub counts: SupervisorCounts,
    /// Each autopilot: where it was last heard, its requests, reboots and returns.
    pub vehicles: Vec<VehicleLink>,
    /// Chunks dropped because the session thread was behind.
    pub dropped_chunks: u64,
    /// Bytes in those.
    pub dropped_bytes: u64,
    /// Chunks still queued when a signal stopped the run and [`STOP_DRAIN`](super::STOP_DRAIN) had passed: not
    /// processed (0 when the run ended otherwise: then the whole queue is processed).
    pub unprocessed_chunks: u64,
    /// Bytes in those.
    pub unprocessed_bytes: u64,
    /// Messages to send that could not be (no connection yet, a full queue, an error).
    pub unsent: u64,
    /// TCP connections made or accepted.
    pub connects: u64,
    /// TCP connections the peer closed.
    pub closes: u64,
    /// Times a link brought nothing for 5 s (each logged as a warning).
    pub silences: u64,
    /// The most chunks that waited for the session thread at once (of `LiveOptions::queue_len`).
    pub queue_peak: u64,
    /// Receive -> processed.
    pub latency: Option<Latency>,
    /// The closed-loop feed, when on.
    pub feed: Option<FeedLinkReport>,
    /// `--forward`: what was routed to and from the ground stations.
    pub forward: Option<ForwardReport>,
    /// `--signing-key`: what signing judged and signed.
    pub signing: Option<SigningCounts>,
}

/// What `--forward` did, for the summary's `link.forward`.
#[derive(Debug, Clone, Serialize)]
pub struct ForwardReport {
    /// The stations' links, in `--forward` order.
    pub stations: Vec<String>,
    /// Frames routed each way, dropped and shown.
    #[serde(flatten)]
    pub counts: ForwardCounts,
    /// A chunk received -> its frames handed to the other side's links.
    pub latency: Option<Latency>,
}

/// A latency histogram, microseconds: 1 us to an hour at 3 significant figures (fixed bounds:
/// `saturating_record` does not grow an auto-resizing one, it clamps to its initial range).
pub(super) fn new_histogram() -> hdrhistogram::Histogram<u64> {
    hdrhistogram::Histogram::new_with_bounds(1, 3_600_000_000, 3).expect("valid bounds")
}

pub(super) fn latency(h: &hdrhistogram::Histogram<u64>) -> Option<Latency> {
    (!h.is_empty()).then(|| Latency {
        chunks: h.len(),
        p50_us: h.value_at_quantile(0.5),
        p99_us: h.value_at_quantile(0.99),
        max_us: h.max(),
    })
}

/// What the end of a run adds to the session thread's counts for its report.
pub(super) struct Ending {
    pub(super) endpoints: Vec<String>,
    pub(super) first_station: usize,
    /// Chunks and bytes left unprocessed.
    pub(super) unprocessed: (u64, u64),
    pub(super) silences: u64,
    /// Frames the GCS outbox signed.
    pub(super) gcs_signed: u64,
    pub(super) feeding: bool,
}

pub(super) fn link_report(
    thread: &LiveSession,
    counters: &LinkCounters,
    end: Ending,
) -> LinkReport {
    let load = |c: &std::sync::atomic::AtomicU64| c.load(Ordering::Relaxed);
    LinkReport {
        counts: thread.supervisor.counts,
        vehicles: thread.supervisor.vehicles(),
        dropped_chunks: load(&counters.dropped_chunks),
        dropped_bytes: load(&counters.dropped_bytes),
        unprocessed_chunks: end.unprocessed.0,
        unprocessed_bytes: end.unprocessed.1,
        unsent: load(&counters.unsent),
        silences: end.silences,
        queue_peak: load(&counters.queue_peak),
        connects: load(&counters.connects),
        closes: load(&counters.closes),
        latency: latency(&thread.latency_us),
        feed: end.feeding.then(|| thread.feed.report()),
        forward: thread.forward.as_ref().map(|f| ForwardReport {
            stations: end.endpoints[end.first_station..].to_vec(),
            counts: f.router.counts,
            latency: latency(&f.latency_us),
        }),
        signing: thread.signing.as_ref().map(|(_, counts)| SigningCounts {
            sent_signed: end.gcs_signed + thread.feed.outbox.signed,
            ..*counts
        }),
        endpoints: end.endpoints,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn latencies_are_recorded_as_they_are() {
        let mut h = new_histogram();
        for us in [3, 40, 5_000, 2_000_000] {
            h.saturating_record(us);
        }
        let l = latency(&h).unwrap();
        assert_eq!(l.chunks, 4);
        assert_eq!(l.p50_us, 40, "{l:?}");
        assert!((1_999_000..=2_001_000).contains(&l.p99_us), "{l:?}");
        assert!((1_999_000..=2_001_000).contains(&l.max_us), "{l:?}");
    }
}
