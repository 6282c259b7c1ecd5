//! The rerun logger: streams what the collision core does so a flight can be scrubbed in the
//! rerun viewer (entity paths in [`paths`], documented in docs/rerun.md).
//!
//! The core never waits for it: a [`Logger`] is the session's `observe::Observer`, and passes
//! the frames it is handed over a bounded channel to a dedicated thread (`viz::log`) that owns
//! the `RecordingStream` (rerun's time cursor is per thread); a full channel drops the frame
//! and counts it. Positions are logged in the scene's
//! ENU metres minus a fixed offset (the scene's centre, rounded, when that is far from the
//! origin), so f32 stays precise; the 3D views are Z up. The layout is in [`blueprint`].

pub mod blueprint;
mod captures;
mod colliders;
pub mod draw;
mod log;
mod markers;
pub mod paths;
mod rows;
mod surroundings;

pub use draw::{beta_color, kind_color, viz_offset};
pub use log::VEHICLE_COLORS;

use std::path::PathBuf;
use std::str::FromStr;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::mpsc::{sync_channel, SyncSender, TrySendError};
use std::sync::Arc;
use std::thread::JoinHandle;

use rerun::{RecordingStream, RecordingStreamBuilder};

use crate::error::{Error, Result};
use crate::observe::{Frame, Observer, RunStart};

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
    tx: Option<SyncSender<Frame>>,
    dropped: Arc<AtomicU64>,
    sent: u64,
    thread: Option<JoinHandle<Result<(), log::LoggerError>>>,
}

/// Messages the channel holds before dropping.
const QUEUE_LEN: usize = 4096;

impl Logger {
    /// Start the logger thread on a stream (see [`open`]; tests pass a memory stream) for the
    /// run `start` tells of; its scene is logged first. On the vehicle's clock (a study row's),
    /// the time panel opens on `vehicle_time`.
    pub fn with_stream(rec: RecordingStream, start: RunStart, options: VizOptions) -> Result<Self> {
        let RunStart {
            scene,
            octree_leaves,
            vehicle_clock,
        } = start;
        let options = VizOptions {
            vehicle_clock: options.vehicle_clock || vehicle_clock,
            ..options
        };
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
}

impl Observer for Logger {
    /// Queue a frame; never blocks. A full queue drops it (counted).
    fn take(&mut self, frame: Frame) {
        let Some(tx) = &self.tx else { return };
        match tx.try_send(frame) {
            Ok(()) => self.sent += 1,
            Err(TrySendError::Full(_) | TrySendError::Disconnected(_)) => {
                self.dropped.fetch_add(1, Ordering::Relaxed);
            }
        }
    }

    /// Frames queued so far, and frames dropped.
    fn counts(&self) -> (u64, u64) {
        (self.sent, self.dropped.load(Ordering::Relaxed))
    }

    /// Stop: the thread logs what is queued, flushes, and ends.
    fn finish(&mut self) -> Result<()> {
        self.tx = None;
        match self.thread.take().map(JoinHandle::join) {
            Some(Ok(Ok(()))) | None => Ok(()),
            Some(Ok(Err(e))) => Err(Error::Usage(format!("rerun logger: {e}"))),
            Some(Err(_)) => Err(Error::Usage("rerun logger: the thread panicked".into())),
        }
    }
}

/// A logger for the run `start` tells of, streaming to `target` (a file is not watched as it
/// is written: rows go out by count, so it is the same however fast the run was).
pub fn logger(target: &RerunTarget, options: VizOptions, start: RunStart) -> Result<Logger> {
    let live = !matches!(target, RerunTarget::Save(_));
    Logger::with_stream(open(target)?, start, VizOptions { live, ..options })
}

impl Drop for Logger {
    fn drop(&mut self) {
        let _ = self.finish();
    }
}
