//! The live runner: a session fed by live links on its own thread, for `savsim live`,
//! `savsim record` and every study row. It sits below `app` (the commands' wiring) and
//! `study`, which both use it; it imports neither.
//!
//! The network runtime's worker runs one task per link ([`crate::links::sockets`]); this thread
//! frames each chunk (one framer per TCP link, restarted at each connection), lets the
//! [`Supervisor`] route and supervise, records, runs the session, and sends what the
//! supervisor says is due to the endpoint it names. It stops on SIGINT/SIGTERM, at the
//! deadline, or when a link fails; what was queued is still processed, so the summary counts
//! every byte received (after a signal, for at most [`STOP_DRAIN`]; the rest is counted as
//! unprocessed).
//!
//! The link report the summary carries is built in `report`; the thread's per-chunk work in
//! `session`, `forwarding` and `feed`.

use std::io::BufWriter;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{Receiver, RecvTimeoutError};
use std::sync::Arc;
use std::time::{Duration, Instant};

use crate::codec::outbox::Outbox;
use crate::codec::signing::{Signing, SigningKey};
use crate::error::{Error, Result};
use crate::links::address::ConnectAddress;
use crate::links::forward::Forwarder;
use crate::links::sockets::{unix_now_s, Chunk, Link, LinkCounters, Network, Outgoing};
use crate::links::supervisor::Endpoint;
use crate::links::supervisor::{LinkId, Supervisor, SupervisorConfig};
use crate::logs::tlog::TlogWriter;
use crate::session::Session;
use crate::world::SenderId;

mod companion;
mod feed;
mod forwarding;
mod link_summary;
mod session;

pub use companion::CompanionOptions;
use feed::FeedSender;
use link_summary::{latency, link_report, new_histogram, Ending};
pub use link_summary::{FeedLinkReport, ForwardReport, Latency, LinkReport};
pub use session::LiveSession;

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
    /// ([`crate::links::supervisor::DEFAULT_GCS`]).
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
    /// A planner beside the vehicle (`--companion`, docs/companion.md). Default none.
    pub companion: Option<CompanionOptions>,
    /// Raised when the run ends early on an error (a link, a recording, the companion): a
    /// study row's pilots stop with it. Default none.
    pub failed: Option<Flag>,
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
            companion: None,
            failed: None,
        }
    }
}

/// The feed's component: MAV_COMP_ID_OBSTACLE_AVOIDANCE.
pub const FEED_COMPONENT: u8 = 196;

/// The feed's identity by default: savsim's default system, [`FEED_COMPONENT`]. Never the
/// vehicle's own (ArduPilot drops its own system's messages as a routing loop).
pub const FEED_FROM: SenderId = SenderId {
    system_id: crate::links::supervisor::DEFAULT_GCS.system_id,
    component_id: FEED_COMPONENT,
};

/// After a signal, what the links had queued is processed for at most this long; the rest is
/// counted, not processed, so that a run behind its stream still stops promptly (within a
/// second of the signal with the summary written: docs/performance.md, "A drone show live").
pub const STOP_DRAIN: Duration = Duration::from_millis(500);

/// A link that brings nothing for this long is logged (once per silence), s.
const SILENT_LINK_S: f64 = 5.0;

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
    /// What its companion did, when it had one.
    pub companion: Option<crate::companion::slot::CompanionCounts>,
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
    let recorder = open_recording(record)?;
    let Wiring {
        supervisor,
        vehicle_fixed,
        station_fixed,
        first_station,
        endpoints,
    } = Wiring::of(&links, options)?;
    let feeding = session.feed().is_some();
    check_feed_and_signing(options, feeding)?;
    let signing = options
        .signing_key
        .as_ref()
        .map(|key| Arc::new(Signing::new(key, options.signing_require)));
    let mut outbox = Outbox::new(options.gcs).signed_with(signing.clone());
    let mut thread = session_thread(session, supervisor, recorder, options, signing)?;
    if let Some(companion) = &options.companion {
        thread.companion = Some(companion::LiveCompanion::start(
            companion,
            &mut thread.session,
            &shutdown,
        )?);
    }
    let (network, chunks) = Network::start(runtime, links, options.queue_len);
    if !options.forward.is_empty() {
        let router = Forwarder::new(
            first_station as LinkId,
            station_fixed,
            vec![options.gcs, options.feed_from],
        );
        thread.forward_with(router, vehicle_fixed, Some(network.sender()));
    }
    let deadline = options.duration.map(|d| Instant::now() + d);
    let mut chores = Chores::new(endpoints.len());
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
                thread.take(&chunk, &network, feeding, options.collided.as_ref());
            }
            Err(RecvTimeoutError::Timeout) => {}
            Err(RecvTimeoutError::Disconnected) => break,
        }
        chores.run(
            &mut thread,
            &network,
            &mut outbox,
            &endpoints,
            options.forward_own,
        );
    }
    if let (Some(flag), Err(_)) = (&options.failed, &thread.result) {
        flag.0.store(true, Ordering::Relaxed);
    }
    let counters = network.counters.clone();
    network.stop_receiving();
    let unprocessed = drain(&mut thread, &chunks, shutdown.load(Ordering::Relaxed));
    let stopped = network.stop();
    close_session(&mut thread, &counters, &shutdown);
    let ending = Ending {
        endpoints,
        first_station,
        unprocessed,
        silences: chores.silences,
        gcs_signed: outbox.signed,
        feeding,
    };
    let report = link_report(&thread, &counters, ending);
    let companion = thread.companion.take().map(|c| c.counts().clone());
    Ok(LiveRun {
        session: thread.session,
        report,
        ended: stopped.and(thread.result),
        companion,
    })
}

/// The tlog every frame received is recorded to (`record`), created now.
fn open_recording(record: Option<&Path>) -> Result<Option<TlogWriter<BufWriter<std::fs::File>>>> {
    record
        .map(|p| {
            std::fs::File::create(p)
                .map(|f| TlogWriter::new(BufWriter::new(f)))
                .map_err(|e| Error::file(p, e))
        })
        .transpose()
}

/// `--feed-out` needs the feed, and `--signing require` a key.
fn check_feed_and_signing(options: &LiveOptions, feeding: bool) -> Result<()> {
    if options.feed_out.is_some() && !feeding {
        return Err(Error::Usage("--feed-out needs --feed".into()));
    }
    if options.signing_require && options.signing_key.is_none() {
        return Err(Error::Usage("--signing require needs --signing-key".into()));
    }
    Ok(())
}

/// The end of the session thread's run, after the drain: the recordings flushed (the first
/// failure, if the run had none, becomes its ending), whether a signal stopped it, and what the links dropped, in the
/// session's counts.
fn close_session(thread: &mut LiveSession, counters: &LinkCounters, shutdown: &AtomicBool) {
    if let Some(rec) = thread.recorder.as_mut() {
        if let (Err(e), Ok(())) = (rec.flush(), &thread.result) {
            thread.result = Err(Error::file("recording", e));
        }
    }
    if let Some((path, rec)) = thread.feed.record.as_mut() {
        if let (Err(e), Ok(())) = (rec.flush(), &thread.result) {
            thread.result = Err(Error::file(path.clone(), e));
        }
    }
    thread
        .session
        .set_interrupted(shutdown.load(Ordering::Relaxed));
    let load = |c: &std::sync::atomic::AtomicU64| c.load(Ordering::Relaxed);
    thread.session.stats_mut().dropped_chunks = load(&counters.dropped_chunks);
    thread.session.stats_mut().dropped_bytes = load(&counters.dropped_bytes);
}

/// The session thread's state for a run: the feed's identity, signing and recording as
/// `options` say.
fn session_thread(
    session: Session,
    supervisor: Supervisor,
    recorder: Option<TlogWriter<BufWriter<std::fs::File>>>,
    options: &LiveOptions,
    signing: Option<Arc<Signing>>,
) -> Result<LiveSession> {
    let mut thread = LiveSession::new(session, supervisor, recorder);
    thread.feed = FeedSender::new(options.feed_from);
    thread.feed.outbox = Outbox::new(options.feed_from).signed_with(signing.clone());
    thread.feed.shown = options.forward_own;
    if let Some(path) = &options.feed_out {
        let file = std::fs::File::create(path).map_err(|e| Error::file(path, e))?;
        thread.feed.record = Some((path.clone(), TlogWriter::new(BufWriter::new(file))));
    }
    if let Some(signing) = signing {
        thread.sign_with(signing);
    }
    thread.session.set_own(vec![options.gcs, options.feed_from]);
    Ok(thread)
}

/// How a run's links divide: the vehicles' (with the supervisor that knows their fixed
/// endpoints) and the stations' (from `first_station` on), and what each is called.
struct Wiring {
    supervisor: Supervisor,
    vehicle_fixed: Vec<Endpoint>,
    station_fixed: Vec<Endpoint>,
    first_station: usize,
    endpoints: Vec<String>,
}

impl Wiring {
    fn of(links: &[Link], options: &LiveOptions) -> Result<Self> {
        let Some(first_station) = links.len().checked_sub(options.forward.len()) else {
            return Err(Error::Usage("more --forward stations than links".into()));
        };
        let mut supervisor = Supervisor::new(SupervisorConfig {
            gcs: options.gcs,
            rate_hz: options.rate_hz,
            ..SupervisorConfig::default()
        });
        let (mut vehicle_fixed, mut station_fixed) = (Vec::new(), Vec::new());
        for (index, link) in links.iter().enumerate() {
            let Some(endpoint) = link.fixed_endpoint(index as LinkId) else {
                continue;
            };
            if index < first_station {
                supervisor.add_fixed(endpoint);
                vehicle_fixed.push(endpoint);
            } else {
                station_fixed.push(endpoint);
            }
        }
        // What the user typed names the links best; links opened by a caller describe
        // themselves.
        let typed: Vec<String> = options
            .connect
            .iter()
            .chain(&options.forward)
            .map(ToString::to_string)
            .collect();
        let endpoints = if typed.len() == links.len() {
            typed
        } else {
            links.iter().map(Link::describe).collect()
        };
        Ok(Self {
            supervisor,
            vehicle_fixed,
            station_fixed,
            first_station,
            endpoints,
        })
    }
}

/// What the session thread does every 20 ms between chunks: log links that went silent, and
/// send what the supervisor says is due.
struct Chores {
    /// Per link: whether its present silence was logged.
    silence_logged: Vec<bool>,
    silences: u64,
    next_due_t_s: f64,
}

impl Chores {
    fn new(links: usize) -> Self {
        Self {
            silence_logged: vec![false; links],
            silences: 0,
            next_due_t_s: f64::NEG_INFINITY,
        }
    }

    fn run(
        &mut self,
        thread: &mut LiveSession,
        network: &Network,
        outbox: &mut Outbox,
        endpoints: &[String],
        show_own: bool,
    ) {
        let now_s = unix_now_s();
        if now_s < self.next_due_t_s {
            return;
        }
        self.next_due_t_s = now_s + 0.02;
        for (index, logged) in self.silence_logged.iter_mut().enumerate() {
            let silent = now_s - network.last_heard_s(index as LinkId) > SILENT_LINK_S;
            if !silent {
                *logged = false;
            } else if !*logged {
                *logged = true;
                self.silences += 1;
                tracing::warn!(
                    "{}: nothing received for {SILENT_LINK_S} s",
                    endpoints[index]
                );
            }
        }
        for (to, message) in thread.supervisor.due(now_s) {
            let bytes = outbox.encode(&message);
            if show_own {
                thread.show_own(network, &bytes);
            }
            network.send(Outgoing { to, bytes });
        }
    }
}

/// What the links had queued when they stopped receiving is still processed (routed,
/// recorded, mirrored): all of it, or after a signal what [`STOP_DRAIN`] allows. The queue
/// disconnects once every link has stopped receiving; a link that does not within
/// [`STOP_DRAIN`] is not waited for. Returns the chunks and bytes left unprocessed.
fn drain(thread: &mut LiveSession, chunks: &Receiver<Chunk>, signalled: bool) -> (u64, u64) {
    let started = Instant::now();
    let (mut unprocessed_chunks, mut unprocessed_bytes) = (0u64, 0u64);
    loop {
        let wait = STOP_DRAIN.saturating_sub(started.elapsed());
        let chunk = match chunks.recv_timeout(wait) {
            Ok(chunk) => chunk,
            Err(RecvTimeoutError::Disconnected) => break,
            Err(RecvTimeoutError::Timeout) => match chunks.try_recv() {
                Ok(chunk) => chunk,
                Err(_) => break,
            },
        };
        if signalled && started.elapsed() >= STOP_DRAIN {
            unprocessed_chunks += 1;
            unprocessed_bytes += chunk.bytes.len() as u64;
        } else {
            thread.process(&chunk);
        }
    }
    (unprocessed_chunks, unprocessed_bytes)
}
