//! The rerun logger: streams what the collision core does so a flight can be scrubbed in the
//! rerun viewer (entity paths in [`paths`], documented in docs/rerun.md).
//!
//! The core never waits for it: the session sends [`VizMsg`]s over a bounded channel to a
//! dedicated thread (`viz::log`) that owns the `RecordingStream` (rerun's time cursor is per
//! thread); a full channel drops the message and counts it. Positions are logged in the scene's
//! ENU metres minus a fixed offset (the scene's centre, rounded, when that is far from the
//! origin), so f32 stays precise; the 3D views are Z up. The layout is in [`blueprint`].

pub mod blueprint;
mod colliders;
pub mod draw;
mod log;
mod markers;
pub mod paths;
mod rows;

pub use draw::{beta_color, kind_color, viz_offset};
pub use log::VEHICLE_COLORS;

use std::path::PathBuf;
use std::str::FromStr;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::mpsc::{sync_channel, SyncSender, TrySendError};
use std::sync::Arc;
use std::thread::JoinHandle;

use glam::DVec3;
use rerun::{RecordingStream, RecordingStreamBuilder};

use crate::collision::events::Event;
use crate::collision::ColliderKind;
use crate::error::{Error, Result};
use crate::pipeline::{BodyKey, BodyPose, ObstacleRef, TickReport};
use crate::scene::{Aabb64, Kind, Scene};

/// Where the recording goes (`--rerun`).
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum RerunTarget {
    /// `save=PATH`: an .rrd file.
    Save(PathBuf),
    /// `connect` or `connect=URL`: a running viewer (default rerun+http://127.0.0.1:9876/proxy).
    Connect(Option<String>),
    /// `spawn`: start a viewer (the `rerun` binary on PATH) and stream to it.
    Spawn,
}

impl FromStr for RerunTarget {
    type Err = Error;

    /// ```
    /// use savsim::viz::RerunTarget;
    /// assert_eq!("save=out.rrd".parse::<RerunTarget>().unwrap(), RerunTarget::Save("out.rrd".into()));
    /// assert_eq!("connect".parse::<RerunTarget>().unwrap(), RerunTarget::Connect(None));
    /// assert!("print".parse::<RerunTarget>().is_err());
    /// ```
    fn from_str(s: &str) -> Result<Self> {
        match s.split_once('=') {
            Some(("save", path)) if !path.is_empty() => Ok(RerunTarget::Save(path.into())),
            Some(("connect", url)) if !url.is_empty() => Ok(RerunTarget::Connect(Some(url.into()))),
            None if s == "connect" => Ok(RerunTarget::Connect(None)),
            None if s == "spawn" => Ok(RerunTarget::Spawn),
            _ => Err(Error::Usage(format!(
                "--rerun {s:?}: use save=OUT.rrd, connect, connect=URL or spawn"
            ))),
        }
    }
}

/// Open the recording stream a target names.
pub fn open(target: &RerunTarget) -> Result<RecordingStream> {
    let builder = RecordingStreamBuilder::new("savsim");
    match target {
        // A file is not watched as it is written: rerun's batcher cuts chunks by size only (and
        // savsim's rows go out by count, `VizOptions::live`), so the file is the same however
        // fast the run was, and loads in few, large chunks.
        RerunTarget::Save(path) => builder
            .batcher_config(rerun::log::ChunkBatcherConfig {
                flush_tick: std::time::Duration::MAX,
                flush_num_bytes: 8 << 20,
                ..rerun::log::ChunkBatcherConfig::DEFAULT
            })
            .save(path),
        RerunTarget::Connect(None) => builder.connect_grpc(),
        RerunTarget::Connect(Some(url)) => builder.connect_grpc_opts(url.clone()),
        RerunTarget::Spawn => builder.spawn(),
    }
    .map_err(|e| Error::Usage(format!("--rerun: {e}")))
}

/// One vehicle's tick, as the logger needs it.
#[derive(Debug, Clone)]
pub struct TickFrame {
    /// Tick number over the run (all vehicles).
    pub tick: u64,
    /// Receive/tlog time, UNIX seconds.
    pub t_s: f64,
    /// The first message's time, UNIX seconds: labels say "+N s" from it, as the report does.
    pub t0_s: f64,
    /// Vehicle clock, ms.
    pub time_boot_ms: u32,
    /// Vehicle system id.
    pub system_id: u8,
    /// Pose now.
    pub pose: BodyPose,
    /// Geometry index of the vehicle's model.
    pub model: usize,
    /// The sensing rays: direction (ENU unit vector) and hit distance (None: no hit within
    /// the ray length), in the fan's order.
    pub rays: Vec<(DVec3, Option<f64>)>,
    /// Ray length, metres.
    pub ray_length_m: f64,
    /// The closed-loop feed's readings cast at this tick (empty when none was): direction and
    /// what the autopilot was sent (docs/closed-loop.md).
    pub feed: Vec<crate::feed::Reading>,
    /// The feed's range, metres (a reading of nothing is drawn this long).
    pub feed_max_m: f64,
    /// The ADS-B reports the feed sent the vehicle at this tick: the ICAO address, a label
    /// (the address and the callsign) and where the report put the aircraft (scene ENU
    /// metres, its errors included).
    pub adsb_sent: Vec<(u32, String, DVec3)>,
    /// The vehicle's octree leaf.
    pub node: Option<Aabb64>,
    /// Obstacles with a collider: which, and beta.
    pub colliders: Vec<(ObstacleRef, ColliderKind, f64)>,
    /// Moving obstacles this tick: key, id, kind, model, pose.
    pub dynamic: Vec<(BodyKey, String, Kind, usize, BodyPose)>,
    /// Collisions and near misses reported at this tick.
    pub events: Vec<Event>,
    /// The well-clear volume losses are judged with: its horizontal and vertical thresholds
    /// (DTHR, ZTHR), metres.
    pub well_clear_m: Option<(f64, f64)>,
    /// The pipeline's counts for the tick.
    pub report: TickReport,
    /// What the tick cost, microseconds.
    pub cost_us: f64,
}

/// A line a vehicle said (a STATUSTEXT, a mode change, a COLLISION message), at its clock's
/// last position.
#[derive(Debug, Clone)]
pub struct NoteFrame {
    /// Ticks so far (all vehicles).
    pub tick: u64,
    /// Receive/tlog time, UNIX seconds.
    pub t_s: f64,
    /// The vehicle's clock at its last position, ms.
    pub time_boot_ms: u32,
    /// The vehicle's system id.
    pub system_id: u8,
    /// MAV_SEVERITY: 0 emergency .. 7 debug.
    pub severity: u8,
    /// The line.
    pub text: String,
}

/// A vehicle's closest approach to a moving body over the run (sent when the run ends).
#[derive(Debug, Clone)]
pub struct ApproachFrame {
    /// The vehicle's system id.
    pub system_id: u8,
    /// The body: a traffic id, a scripted track, another vehicle.
    pub track: String,
    /// When, seconds on the samples' clock (`tlog_time`).
    pub t_s: f64,
    /// Least 3D separation, metres.
    pub distance_m: f64,
    /// Horizontal and vertical separation then, metres.
    pub horizontal_m: f64,
    /// See `horizontal_m`.
    pub vertical_m: f64,
    /// Whether the two were ever within NMAC (500 ft and 100 ft at once).
    pub nmac: bool,
}

/// What goes to the logger thread.
#[derive(Debug)]
pub enum VizMsg {
    /// A vehicle's tick.
    Tick(Box<TickFrame>),
    /// A line a vehicle said.
    Note(Box<NoteFrame>),
    /// The closest approaches of the run, at its end.
    Approaches(Vec<ApproachFrame>),
}

/// What the logger draws beyond the defaults.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct VizOptions {
    /// Draw every octree leaf (`--rerun-octree`), not only each vehicle's node and the leaves
    /// touching it.
    pub whole_octree: bool,
    /// A viewer watches the run as it is logged (`connect`, `spawn`): gathered rows wait at most
    /// 200 ms. Otherwise (a file, a memory sink) they are sent by count only, so a file is cut
    /// into the same chunks however fast the run was.
    pub live: bool,
    /// The run is on the vehicle's clock (a study row): the time panel opens on
    /// `vehicle_time`, else on `tlog_time`.
    pub vehicle_clock: bool,
}

/// The running logger.
pub struct Logger {
    tx: Option<SyncSender<VizMsg>>,
    dropped: Arc<AtomicU64>,
    sent: u64,
    thread: Option<JoinHandle<Result<(), String>>>,
}

/// Messages the channel holds before dropping.
const QUEUE_LEN: usize = 4096;

impl Logger {
    /// Start the logger thread on a stream (see [`open`]; tests pass a memory stream); the
    /// scene is logged first.
    pub fn with_stream(
        rec: RecordingStream,
        scene: Arc<Scene>,
        octree_leaves: Vec<Aabb64>,
        options: VizOptions,
    ) -> Result<Self> {
        let (tx, rx) = sync_channel(QUEUE_LEN);
        let dropped = Arc::new(AtomicU64::new(0));
        let thread = std::thread::Builder::new()
            .name("savsim-rerun".into())
            .spawn(move || log::run(rec, rx, &scene, &octree_leaves, &options))
            .map_err(|e| Error::Usage(format!("--rerun: cannot start the logger thread: {e}")))?;
        Ok(Self {
            tx: Some(tx),
            dropped,
            sent: 0,
            thread: Some(thread),
        })
    }

    /// Queue a message; never blocks. A full queue drops it (counted).
    pub fn send(&mut self, msg: VizMsg) {
        let Some(tx) = &self.tx else { return };
        match tx.try_send(msg) {
            Ok(()) => self.sent += 1,
            Err(TrySendError::Full(_) | TrySendError::Disconnected(_)) => {
                self.dropped.fetch_add(1, Ordering::Relaxed);
            }
        }
    }

    /// Messages dropped so far.
    pub fn dropped(&self) -> u64 {
        self.dropped.load(Ordering::Relaxed)
    }

    /// Messages queued so far.
    pub fn sent(&self) -> u64 {
        self.sent
    }

    /// Stop: the thread logs what is queued, flushes, and ends.
    pub fn finish(&mut self) -> Result<()> {
        self.tx = None;
        match self.thread.take().map(JoinHandle::join) {
            Some(Ok(Ok(()))) | None => Ok(()),
            Some(Ok(Err(e))) => Err(Error::Usage(format!("rerun logger: {e}"))),
            Some(Err(_)) => Err(Error::Usage("rerun logger: the thread panicked".into())),
        }
    }
}

impl Drop for Logger {
    fn drop(&mut self) {
        let _ = self.finish();
    }
}
