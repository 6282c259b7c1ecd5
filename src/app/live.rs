//! `savsim live` and `savsim record`: the session thread and its wiring.
//!
//! The network runtime's worker runs one task per link ([`crate::ingest::live`]); this thread
//! frames each chunk (one framer per TCP link, restarted at each connection), lets the
//! [`Supervisor`] route and supervise, records, runs the session, and sends what the
//! supervisor says is due to the endpoint it names. It stops on SIGINT/SIGTERM, at the
//! deadline, or when a link fails; what was queued is still processed, so the summary counts
//! every byte received (after a signal, for at most [`STOP_DRAIN`]; the rest is counted as
//! unprocessed).

use std::collections::BTreeMap;
use std::io::BufWriter;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::RecvTimeoutError;
use std::sync::Arc;
use std::time::{Duration, Instant};

use serde::Serialize;

use crate::error::{Error, Result};
use crate::ingest::address::ConnectAddress;
use crate::ingest::forward::{ForwardCounts, Forwarder};
use crate::ingest::frame::{scan, FrameStatus, RawFrame, Scan};
use crate::ingest::live::{unix_now_s, Chunk, ChunkKind, Link, Network, Outgoing, Sender};
use crate::ingest::outbox::Outbox;
use crate::ingest::signing::{Signing, SigningCounts, SigningKey};
use crate::ingest::stats::SenderId;
use crate::ingest::stream::{frames_in_datagram, Skipped, StreamFramer};
use crate::ingest::supervisor::{
    Endpoint, LinkId, Supervisor, SupervisorConfig, SupervisorCounts, VehicleLink,
};
use crate::ingest::tlog::TlogWriter;
use crate::session::Session;

/// How a live run behaves.
#[derive(Debug, Clone, PartialEq)]
pub struct LiveOptions {
    /// Where to connect: one link per address.
    pub connect: Vec<ConnectAddress>,
    /// Rate asked for GLOBAL_POSITION_INT and ATTITUDE, Hz. Default 20.
    pub rate_hz: f64,
    /// Stop after this long (default: run until shutdown).
    pub duration: Option<Duration>,
    /// savsim's own identity as a GCS (`--sysid`, `--compid`). Default 245/190
    /// ([`crate::ingest::supervisor::DEFAULT_GCS`]).
    pub gcs: SenderId,
    /// Chunks the channel to the session thread holds before dropping. Default 65536.
    pub queue_len: usize,
    /// The closed-loop feed's own identity (docs/closed-loop.md): savsim's system,
    /// MAV_COMP_ID_OBSTACLE_AVOIDANCE (196). Default 245/196.
    pub feed_from: SenderId,
    /// Record every frame the feed sends (its heartbeats too) to this tlog, stamped with the
    /// time it was handed to the link (`--feed-out`). Default none.
    pub feed_out: Option<PathBuf>,
    /// Raised when the session first counts a collision (`savsim study` ends a row there).
    /// Default none.
    pub collided: Option<Flag>,
    /// Ground stations to route the vehicles to (`--forward`): the last links of a run, after
    /// the `connect` ones (docs/live.md). Default none.
    pub forward: Vec<ConnectAddress>,
    /// Show the stations savsim's own frames too (its heartbeat, requests and feed;
    /// `--forward-own`). Default false.
    pub forward_own: bool,
    /// Sign every frame sent, and judge every frame received, with this key (`--signing-key`).
    pub signing_key: Option<SigningKey>,
    /// Drop unsigned frames (`--signing require`); without it they are taken. Needs a key.
    pub signing_require: bool,
}

/// A flag shared between threads; two are equal when they are the same flag.
#[derive(Debug, Clone, Default)]
pub struct Flag(pub Arc<AtomicBool>);

impl PartialEq for Flag {
    fn eq(&self, other: &Self) -> bool {
        Arc::ptr_eq(&self.0, &other.0)
    }
}

impl Flag {
    /// Whether it was raised.
    pub fn is_raised(&self) -> bool {
        self.0.load(Ordering::Relaxed)
    }
}

impl Default for LiveOptions {
    fn default() -> Self {
        Self {
            connect: Vec::new(),
            rate_hz: 20.0,
            duration: None,
            gcs: SupervisorConfig::default().gcs,
            queue_len: 65_536,
            feed_from: FEED_FROM,
            feed_out: None,
            collided: None,
            forward: Vec::new(),
            forward_own: false,
            signing_key: None,
            signing_require: false,
        }
    }
}

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

/// The feed's component: MAV_COMP_ID_OBSTACLE_AVOIDANCE.
pub const FEED_COMPONENT: u8 = 196;

/// The feed's identity by default: savsim's default system, [`FEED_COMPONENT`]. Never the
/// vehicle's own (ArduPilot drops its own system's messages as a routing loop).
pub const FEED_FROM: SenderId = SenderId {
    system_id: crate::ingest::supervisor::DEFAULT_GCS.system_id,
    component_id: FEED_COMPONENT,
};

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

/// After a signal, what the links had queued is processed for at most this long; the rest is
/// counted, not processed, so that a run behind its stream still stops promptly.
pub const STOP_DRAIN: Duration = Duration::from_secs(1);

/// A link that brings nothing for this long is logged (once per silence), s.
const SILENT_LINK_S: f64 = 5.0;

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
    /// Chunks still queued when a signal stopped the run and [`STOP_DRAIN`] had passed: not
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

/// A finished live run: the session (for its summary), what the links did, and how the run
/// ended (a link's error, a recording that could not be written). The summary is written
/// whatever the ending.
pub struct LiveRun {
    /// The session.
    pub session: Session,
    /// The links.
    pub report: LinkReport,
    /// Ok, or why the run ended early.
    pub ended: Result<()>,
}

/// Open every link `options` names on a runtime of its own and run until the end.
pub fn run_blocking(
    options: &LiveOptions,
    session: Session,
    record: Option<&Path>,
    shutdown: Arc<AtomicBool>,
) -> Result<LiveRun> {
    let runtime = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(1)
        .thread_name("savsim-net")
        .enable_all()
        .build()
        .map_err(|source| Error::Net {
            what: "start the network runtime".into(),
            source,
        })?;
    let links = runtime.block_on(async {
        let mut links = Vec::new();
        for address in options.connect.iter().chain(&options.forward) {
            links.push(Link::open(address).await?);
        }
        Ok::<_, Error>(links)
    })?;
    run_links(runtime.handle(), links, options, session, record, shutdown)
}

/// What the session thread holds while a run lasts: the session, the supervisor, the
/// recording, a framer per TCP link and the latency histogram. The fuzz target `live_links`
/// drives it with chunks as the links would.
pub struct LiveSession {
    session: Session,
    supervisor: Supervisor,
    recorder: Option<TlogWriter<BufWriter<std::fs::File>>>,
    framers: BTreeMap<LinkId, StreamFramer>,
    latency_us: hdrhistogram::Histogram<u64>,
    feed: FeedSender,
    result: Result<()>,
    /// `--forward`: the router, the vehicle links' fixed endpoints, what to send, how long
    /// it waited.
    forward: Option<Forwarding>,
    /// The frames of the chunk at hand, between routing and mirroring.
    kept: Kept,
    /// `--signing-key`: the judge, and what it judged.
    signing: Option<(Arc<Signing>, SigningCounts)>,
}

/// The router's state on the session thread.
struct Forwarding {
    router: Forwarder,
    vehicle_fixed: Vec<Endpoint>,
    /// The links (none when driven without a network, as the fuzz target does).
    sender: Option<Sender>,
    /// Frames routed from the chunk at hand, handed to the links once it is framed.
    pending: Vec<Outgoing>,
    latency_us: hdrhistogram::Histogram<u64>,
}

impl Forwarding {
    fn route_from_vehicle(&mut self, t_s: f64, frame: &RawFrame<'_>) {
        let pending = &mut self.pending;
        self.router.from_vehicle(t_s, frame, |to| {
            pending.push(Outgoing {
                to,
                bytes: frame.bytes.to_vec(),
            })
        });
    }

    fn route_from_station(&mut self, chunk: &Chunk, frame: &RawFrame<'_>, supervisor: &Supervisor) {
        let pending = &mut self.pending;
        self.router.from_station(
            chunk.endpoint(),
            chunk.t_s,
            frame,
            supervisor.routes(),
            &self.vehicle_fixed,
            |to| {
                pending.push(Outgoing {
                    to,
                    bytes: frame.bytes.to_vec(),
                })
            },
        );
    }

    /// Hand what was routed to the links, noting how long after `received_t_s`.
    fn flush(&mut self, received_t_s: f64) {
        if self.pending.is_empty() {
            return;
        }
        match &self.sender {
            Some(sender) => self.pending.drain(..).for_each(|out| sender.send(out)),
            None => self.pending.clear(),
        }
        let waited_us = ((unix_now_s() - received_t_s) * 1e6).max(0.0) as u64;
        self.latency_us.saturating_record(waited_us);
    }
}

/// Sends the session's feed messages to each vehicle's route, as the feed's identity.
struct FeedSender {
    outbox: Outbox,
    /// Where the feed went, for the heartbeat.
    endpoints: Vec<Endpoint>,
    next_heartbeat_t_s: f64,
    sent: u64,
    unrouted: u64,
    heartbeats: u64,
    latency_us: hdrhistogram::Histogram<u64>,
    /// `--feed-out`: what was sent, as sent.
    record: Option<(PathBuf, TlogWriter<BufWriter<std::fs::File>>)>,
    /// `--forward-own`: the stations see the feed's frames too (kept here until shown).
    shown: bool,
    shown_frames: Vec<Vec<u8>>,
}

impl FeedSender {
    fn new(from: SenderId) -> Self {
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
    fn send(&mut self, network: &Network, to: Endpoint, bytes: Vec<u8>, now_s: f64) {
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

    fn report(&self) -> FeedLinkReport {
        FeedLinkReport {
            sent: self.sent,
            unrouted: self.unrouted,
            heartbeats: self.heartbeats,
            latency: latency(&self.latency_us),
        }
    }
}

/// A latency histogram, microseconds: 1 us to an hour at 3 significant figures (fixed bounds:
/// `saturating_record` does not grow an auto-resizing one, it clamps to its initial range).
fn new_histogram() -> hdrhistogram::Histogram<u64> {
    hdrhistogram::Histogram::new_with_bounds(1, 3_600_000_000, 3).expect("valid bounds")
}

fn latency(h: &hdrhistogram::Histogram<u64>) -> Option<Latency> {
    (!h.is_empty()).then(|| Latency {
        chunks: h.len(),
        p50_us: h.value_at_quantile(0.5),
        p99_us: h.value_at_quantile(0.99),
        max_us: h.max(),
    })
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
        self.forward = Some(Forwarding {
            router,
            vehicle_fixed,
            sender,
            pending: Vec::new(),
            latency_us: new_histogram(),
        });
    }

    /// Judge every vehicle frame with `signing` before anything else sees it.
    pub fn sign_with(&mut self, signing: Arc<Signing>) {
        self.signing = Some((signing, SigningCounts::default()));
    }

    /// Show a frame savsim sent to the stations (`--forward-own`).
    fn show_own(&mut self, network: &Network, bytes: &[u8]) {
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
struct Kept {
    bytes: Vec<u8>,
    spans: Vec<std::ops::Range<usize>>,
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

/// [`run_blocking`] on links already open on `runtime` (tests bind them to port 0): the
/// vehicles' first, then `options.forward.len()` stations'.
pub fn run_links(
    runtime: &tokio::runtime::Handle,
    links: Vec<Link>,
    options: &LiveOptions,
    session: Session,
    record: Option<&Path>,
    shutdown: Arc<AtomicBool>,
) -> Result<LiveRun> {
    let recorder = record
        .map(|p| {
            std::fs::File::create(p)
                .map(|f| TlogWriter::new(BufWriter::new(f)))
                .map_err(|e| Error::file(p, e))
        })
        .transpose()?;
    let mut supervisor = Supervisor::new(SupervisorConfig {
        gcs: options.gcs,
        rate_hz: options.rate_hz,
        ..SupervisorConfig::default()
    });
    let Some(first_station) = links.len().checked_sub(options.forward.len()) else {
        return Err(Error::Usage("more --forward stations than links".into()));
    };
    let (mut vehicle_fixed, mut station_fixed) = (Vec::new(), Vec::new());
    for (index, link) in links.iter().enumerate() {
        if let Some(endpoint) = link.fixed_endpoint(index as LinkId) {
            if index < first_station {
                supervisor.add_fixed(endpoint);
                vehicle_fixed.push(endpoint);
            } else {
                station_fixed.push(endpoint);
            }
        }
    }
    // What the user typed names the links best; links opened by a caller describe themselves.
    let typed: Vec<String> = options
        .connect
        .iter()
        .chain(&options.forward)
        .map(ToString::to_string)
        .collect();
    let endpoints: Vec<String> = if typed.len() == links.len() {
        typed
    } else {
        links.iter().map(Link::describe).collect()
    };
    let (network, chunks) = Network::start(runtime, links, options.queue_len);
    let signing = options
        .signing_key
        .as_ref()
        .map(|key| Arc::new(Signing::new(key, options.signing_require)));
    if options.signing_require && signing.is_none() {
        return Err(Error::Usage("--signing require needs --signing-key".into()));
    }
    let mut outbox = Outbox::new(options.gcs).signed_with(signing.clone());
    let feeding = session.feed().is_some();
    let mut thread = LiveSession::new(session, supervisor, recorder);
    thread.feed = FeedSender::new(options.feed_from);
    thread.feed.outbox = Outbox::new(options.feed_from).signed_with(signing.clone());
    thread.feed.shown = options.forward_own;
    if let Some(signing) = signing {
        thread.sign_with(signing);
    }
    if !options.forward.is_empty() {
        let router = Forwarder::new(
            first_station as LinkId,
            station_fixed,
            vec![options.gcs, options.feed_from],
        );
        thread.forward_with(router, vehicle_fixed, Some(network.sender()));
    }
    if let Some(path) = &options.feed_out {
        if !feeding {
            return Err(Error::Usage("--feed-out needs --feed".into()));
        }
        let file = std::fs::File::create(path).map_err(|e| Error::file(path, e))?;
        thread.feed.record = Some((path.clone(), TlogWriter::new(BufWriter::new(file))));
    }
    thread.session.set_own(vec![options.gcs, options.feed_from]);
    let deadline = options.duration.map(|d| Instant::now() + d);
    // Per link: whether its present silence was logged.
    let mut silence_logged = vec![false; endpoints.len()];
    let mut silences = 0u64;
    let mut next_due_t_s = f64::NEG_INFINITY;
    loop {
        let stop = shutdown.load(Ordering::Relaxed)
            || deadline.is_some_and(|d| Instant::now() >= d)
            || !network.running()
            || thread.result.is_err();
        if stop {
            break;
        }
        match chunks.recv_timeout(Duration::from_millis(20)) {
            Ok(chunk) => {
                network.taken();
                thread.process(&chunk);
                if feeding {
                    thread.send_feed(&network, chunk.t_s);
                }
                if let Some(flag) = &options.collided {
                    let hit = thread
                        .session
                        .pipeline()
                        .is_some_and(|p| p.totals().collisions > 0);
                    if hit {
                        flag.0.store(true, Ordering::Relaxed);
                    }
                }
            }
            Err(RecvTimeoutError::Timeout) => {}
            Err(RecvTimeoutError::Disconnected) => break,
        }
        let now_s = unix_now_s();
        if now_s >= next_due_t_s {
            next_due_t_s = now_s + 0.02;
            for (index, logged) in silence_logged.iter_mut().enumerate() {
                let silent = now_s - network.last_heard_s(index as LinkId) > SILENT_LINK_S;
                if !silent {
                    *logged = false;
                } else if !*logged {
                    *logged = true;
                    silences += 1;
                    tracing::warn!(
                        "{}: nothing received for {SILENT_LINK_S} s",
                        endpoints[index]
                    );
                }
            }
            for (to, message) in thread.supervisor.due(now_s) {
                let bytes = outbox.encode(&message);
                if options.forward_own {
                    thread.show_own(&network, &bytes);
                }
                network.send(Outgoing { to, bytes });
            }
        }
    }
    let counters = network.counters.clone();
    let stopped = network.stop();
    // What the links had queued is still processed: all of it, or after a signal what
    // STOP_DRAIN allows (the rest counted).
    let drain_until = shutdown
        .load(Ordering::Relaxed)
        .then(|| Instant::now() + STOP_DRAIN);
    let (mut unprocessed_chunks, mut unprocessed_bytes) = (0u64, 0u64);
    while let Ok(chunk) = chunks.try_recv() {
        if drain_until.is_some_and(|d| Instant::now() >= d) {
            unprocessed_chunks += 1;
            unprocessed_bytes += chunk.bytes.len() as u64;
        } else {
            thread.process(&chunk);
        }
    }
    if let Some(rec) = thread.recorder.as_mut() {
        if let Err(e) = rec.flush() {
            thread.result = thread.result.and(Err(Error::file("recording", e)));
        }
    }
    if let Some((path, rec)) = thread.feed.record.as_mut() {
        if let Err(e) = rec.flush() {
            thread.result = thread.result.and(Err(Error::file(path.clone(), e)));
        }
    }
    let mut session = thread.session;
    let load = |c: &std::sync::atomic::AtomicU64| c.load(Ordering::Relaxed);
    session.stats_mut().dropped_chunks = load(&counters.dropped_chunks);
    session.stats_mut().dropped_bytes = load(&counters.dropped_bytes);
    session.set_interrupted(shutdown.load(Ordering::Relaxed));
    let h = &thread.latency_us;
    let report_endpoints = endpoints.clone();
    let report = LinkReport {
        endpoints,
        counts: thread.supervisor.counts,
        vehicles: thread.supervisor.vehicles(),
        dropped_chunks: session.stats().dropped_chunks,
        dropped_bytes: session.stats().dropped_bytes,
        unprocessed_chunks,
        unprocessed_bytes,
        unsent: load(&counters.unsent),
        silences,
        queue_peak: load(&counters.queue_peak),
        connects: load(&counters.connects),
        closes: load(&counters.closes),
        latency: latency(h),
        feed: feeding.then(|| thread.feed.report()),
        forward: thread.forward.as_ref().map(|f| ForwardReport {
            stations: report_endpoints[first_station..].to_vec(),
            counts: f.router.counts,
            latency: latency(&f.latency_us),
        }),
        signing: thread.signing.as_ref().map(|(_, counts)| SigningCounts {
            sent_signed: outbox.signed + thread.feed.outbox.signed,
            ..*counts
        }),
    };
    Ok(LiveRun {
        session,
        report,
        ended: stopped.and(thread.result),
    })
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
