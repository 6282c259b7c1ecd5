//! The session thread's state and its work on one chunk: frame, judge (signing), route
//! (forwarding), supervise, record and mirror.

use std::collections::BTreeMap;
use std::io::BufWriter;
use std::sync::Arc;

use super::feed::FeedSender;
use super::forwarding::Forwarding;
use super::{new_histogram, FEED_FROM};
use crate::codec::frame::{scan, FrameStatus, RawFrame, Scan};
use crate::codec::signing::{Signing, SigningCounts};
use crate::error::{Error, Result};
use crate::links::forward::Forwarder;
use crate::links::sockets::{unix_now_s, Chunk, ChunkKind, Network, Outgoing, Sender};
use crate::links::stream::{frames_in_datagram, Skipped, StreamFramer};
use crate::links::supervisor::{Endpoint, LinkId, Supervisor};
use crate::logs::tlog::TlogWriter;
use crate::session::Session;
use crate::world::SenderId;

/// What the session thread holds while a run lasts: the session, the supervisor, the
/// recording, a framer per TCP link and the latency histogram. The fuzz target `live_links`
/// drives it with chunks as the links would.
pub struct LiveSession {
    pub(super) session: Session,
    pub(super) supervisor: Supervisor,
    pub(super) recorder: Option<TlogWriter<BufWriter<std::fs::File>>>,
    pub(super) framers: BTreeMap<LinkId, StreamFramer>,
    pub(super) latency_us: hdrhistogram::Histogram<u64>,
    pub(super) feed: FeedSender,
    pub(super) result: Result<()>,
    /// `--forward`: the router, the vehicle links' fixed endpoints, what to send, how long
    /// it waited.
    pub(super) forward: Option<Forwarding>,
    /// The frames of the chunk at hand, between routing and mirroring.
    pub(super) kept: Kept,
    /// `--signing-key`: the judge, and what it judged.
    pub(super) signing: Option<(Arc<Signing>, SigningCounts)>,
    /// `--companion`: the planner beside the vehicle.
    pub(super) companion: Option<super::companion::LiveCompanion>,
}

impl LiveSession {
    /// A live session over `session`, recording to `recorder` if given.
    pub fn new(
        session: Session,
        supervisor: Supervisor,
        recorder: Option<TlogWriter<BufWriter<std::fs::File>>>,
    ) -> Self {
        Self {
            session,
            supervisor,
            recorder,
            framers: BTreeMap::new(),
            latency_us: new_histogram(),
            feed: FeedSender::new(FEED_FROM),
            result: Ok(()),
            forward: None,
            signing: None,
            kept: Kept::default(),
            companion: None,
        }
    }

    /// Route between vehicles and stations with `router`, sending with `sender`;
    /// `vehicle_fixed` are the vehicle links' endpoints known before anything is heard (a
    /// station's heartbeat goes there).
    pub fn forward_with(
        &mut self,
        router: Forwarder,
        vehicle_fixed: Vec<Endpoint>,
        sender: Option<Sender>,
    ) {
        self.forward = Some(Forwarding::new(router, vehicle_fixed, sender));
    }

    /// Judge every vehicle frame with `signing` before anything else sees it.
    pub fn sign_with(&mut self, signing: Arc<Signing>) {
        self.signing = Some((signing, SigningCounts::default()));
    }

    /// Show a frame savsim sent to the stations (`--forward-own`).
    pub(super) fn show_own(&mut self, network: &Network, bytes: &[u8]) {
        if let Some(f) = self.forward.as_mut() {
            f.router.own_frame(unix_now_s(), |to| {
                network.send(Outgoing {
                    to,
                    bytes: bytes.to_vec(),
                })
            });
        }
    }

    /// Route a station's chunk: its frames go to the vehicles (or stations) they are for,
    /// and nowhere else in savsim.
    fn process_station(&mut self, chunk: &Chunk) {
        let Some(f) = self.forward.as_mut() else {
            return;
        };
        let supervisor = &self.supervisor;
        frame_chunk(&mut self.framers, chunk, |frame| {
            f.route_from_station(chunk, frame, supervisor);
        });
        f.flush(chunk.t_s);
    }

    /// The session.
    pub fn session(&self) -> &Session {
        &self.session
    }

    /// The supervisor.
    pub fn supervisor(&mut self) -> &mut Supervisor {
        &mut self.supervisor
    }

    /// Send the feed's messages made since the last call to each vehicle's route (the
    /// endpoint it was last heard on), and the feed's heartbeat once a second to every
    /// endpoint fed. `received_t_s` is when the chunk that made them arrived.
    pub fn send_feed(&mut self, network: &Network, received_t_s: f64) {
        self.send_feed_frames(network, received_t_s);
        for bytes in std::mem::take(&mut self.feed.shown_frames) {
            self.show_own(network, &bytes);
        }
    }

    fn send_feed_frames(&mut self, network: &Network, received_t_s: f64) {
        let feed = &mut self.feed;
        let now_s = unix_now_s();
        if self.session.has_feed_out() {
            for m in self.session.drain_feed() {
                let Some((_, to)) = self.supervisor.routes().find(|(id, _)| *id == m.to) else {
                    feed.unrouted += 1;
                    continue;
                };
                if let Some(other) = self
                    .supervisor
                    .routes()
                    .find(|(id, e)| *e == to && *id != m.to)
                {
                    if self.result.is_ok() {
                        self.result = Err(Error::SharedEndpoint {
                            vehicles: format!("{} and {}", m.to, other.0),
                            endpoint: to.to_string(),
                        });
                    }
                    return;
                }
                if !feed.endpoints.contains(&to) {
                    feed.endpoints.push(to);
                }
                let bytes = feed.outbox.encode(&m.message);
                feed.send(network, to, bytes, now_s);
                feed.sent += 1;
            }
            let waited_us = ((now_s - received_t_s) * 1e6).max(0.0) as u64;
            feed.latency_us.saturating_record(waited_us);
        }
        if now_s >= feed.next_heartbeat_t_s && !feed.endpoints.is_empty() {
            feed.next_heartbeat_t_s = now_s + 1.0;
            for k in 0..feed.endpoints.len() {
                let to = feed.endpoints[k];
                let bytes = feed.outbox.encode(&crate::feed::wire::heartbeat());
                feed.send(network, to, bytes, now_s);
                feed.heartbeats += 1;
            }
        }
    }

    /// A chunk off the queue during the run: processed, the feed it made sent, and
    /// `collided` raised at the session's first collision.
    pub(super) fn take(
        &mut self,
        chunk: &Chunk,
        network: &Network,
        feeding: bool,
        collided: Option<&super::Flag>,
    ) {
        self.process(chunk);
        if feeding {
            self.send_feed(network, chunk.t_s);
        }
        if let Some(companion) = self.companion.as_mut() {
            let asked = companion.step(&mut self.session, self.supervisor.routes(), network);
            if let (Err(e), Ok(())) = (asked, &self.result) {
                self.result = Err(e);
            }
        }
        if let Some(flag) = collided {
            let hit = self
                .session
                .pipeline()
                .is_some_and(|p| p.totals().collisions > 0);
            if hit {
                flag.0.store(true, std::sync::atomic::Ordering::Relaxed);
            }
        }
    }

    /// Frame, judge (signing), route (forwarding), supervise, record and run one chunk
    /// through the session. Routing comes first for the whole chunk: the stations get its
    /// frames before any of the mirroring work.
    pub fn process(&mut self, chunk: &Chunk) {
        if self
            .forward
            .as_ref()
            .is_some_and(|f| f.router.is_station(chunk.link))
        {
            self.process_station(chunk);
            return;
        }
        let mut kept = std::mem::take(&mut self.kept);
        kept.clear();
        let Self {
            framers,
            forward,
            signing,
            ..
        } = self;
        let skipped = frame_chunk(framers, chunk, |frame| {
            if let Some((judge, counts)) = signing.as_mut() {
                let intact = !matches!(
                    frame.status,
                    FrameStatus::BadCrc | FrameStatus::BadIncompatFlags
                );
                if intact && !judge.keep(frame, counts) {
                    return;
                }
            }
            if let Some(f) = forward.as_mut() {
                f.route_from_vehicle(chunk.t_s, frame);
            }
            kept.push(frame.bytes);
        });
        if let Some(f) = self.forward.as_mut() {
            f.flush(chunk.t_s);
        }
        for bytes in kept.frames() {
            if let Scan::Frame(frame) = scan(bytes) {
                self.mirror(chunk, &frame);
            }
        }
        self.kept = kept;
        skipped.count_into(self.session.stats_mut());
        if chunk.kind != ChunkKind::Connected {
            let waited_us = ((unix_now_s() - chunk.t_s) * 1e6).max(0.0) as u64;
            self.latency_us.saturating_record(waited_us);
        }
    }

    /// Supervise, record and run one frame of a vehicle's chunk through the session.
    fn mirror(&mut self, chunk: &Chunk, frame: &RawFrame<'_>) {
        if self
            .supervisor
            .observe(chunk.endpoint(), chunk.t_s, frame)
            .rebooted
        {
            let sender = SenderId {
                system_id: frame.system_id,
                component_id: frame.component_id,
            };
            self.session
                .stats_mut()
                .restart_sequence(sender, frame.sequence);
        }
        if let Some(rec) = self.recorder.as_mut() {
            if let Err(e) = rec.write_record((chunk.t_s * 1e6) as u64, frame.bytes) {
                self.result = Err(Error::file("recording", e));
            }
        }
        if let Err(e) = self.session.on_frame(chunk.t_s, frame) {
            self.result = Err(e);
        }
    }
}

/// Every frame of a chunk, through the link's framer (a datagram alone; a TCP read after
/// what the connection left; a new connection restarts it); the bytes that were no frame.
fn frame_chunk(
    framers: &mut BTreeMap<LinkId, StreamFramer>,
    chunk: &Chunk,
    mut on_frame: impl FnMut(&RawFrame<'_>),
) -> Skipped {
    match chunk.kind {
        ChunkKind::Datagram => frames_in_datagram(&chunk.bytes, &mut on_frame),
        ChunkKind::Connected => {
            // A new byte stream: what the last connection left half-framed is gone.
            framers.insert(chunk.link, StreamFramer::default());
            Skipped::default()
        }
        ChunkKind::Stream => framers
            .entry(chunk.link)
            .or_default()
            .push(&chunk.bytes, &mut on_frame),
    }
}

/// The frames of one chunk kept for the mirroring after routing: their bytes end to end,
/// and where each is (both reused from chunk to chunk).
#[derive(Debug, Default)]
pub(super) struct Kept {
    pub(super) bytes: Vec<u8>,
    pub(super) spans: Vec<std::ops::Range<usize>>,
}

impl Kept {
    fn clear(&mut self) {
        self.bytes.clear();
        self.spans.clear();
    }

    fn push(&mut self, frame: &[u8]) {
        let at = self.bytes.len();
        self.bytes.extend_from_slice(frame);
        self.spans.push(at..self.bytes.len());
    }

    fn frames(&self) -> impl Iterator<Item = &[u8]> + '_ {
        self.spans.iter().map(|r| &self.bytes[r.clone()])
    }
}
