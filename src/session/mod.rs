//! A run: decoded messages in, world state and collision ticks through, events and a summary
//! out. Synchronous; replay drives it directly, live from its own named thread.
//!
//! One collision tick is `tick`; the bodies a tick watches, `traffic`, within the reaches of
//! `watch`; what it shows whoever watches it (an `observe::Observer`: the viewer), `observed`;
//! the summary a run writes, `summary`.

mod observed;
pub mod summary;
mod tick;
mod traffic;
mod watch;

use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Instant;

use serde::Serialize;

use crate::codec::frame::{FrameStatus, RawFrame};
use crate::codec::outbox::Outbox;
use crate::codec::Ingestor;
use crate::collision::digest::EventDigest;
use crate::collision::events::{Event, EventKind};
use crate::daa::approach::{Approaches, WellClearChange};
use crate::error::{Error, Result};
use crate::feed::{Feed, FeedConfig, FeedMessage};
use crate::logs::tlog::TlogWriter;
use crate::observe::{Observer, RunStart};
use crate::pipeline::{CollisionConfig, MovingBodies, Pipeline};
use crate::scene::Scene;
use crate::world::SenderId;
use crate::world::{WorldConfig, WorldStore, WorldUpdate};

/// Most collision, near-miss and well-clear events kept in memory for the run's printed
/// report; the rest are counted (`notable_not_kept`), and every figure drawn from the run
/// comes from [`EventDigest`], which takes them all.
const NOTABLE_KEPT: usize = 1000;
/// Notes held for senders with no position yet, at most.
const HELD_NOTES: usize = 64;
/// Estimated positions held between two [`Session::drain_estimates`], at most.
pub const HELD_ESTIMATES: usize = 1024;

/// What a run's feed made for companions: each device's reading whole (images, clouds) and
/// each ADS-B report it sent, with the vehicle's system id.
#[derive(Debug, Clone, Default)]
pub struct CompanionInputs {
    /// Readings made whole (each names its vehicle).
    pub captures: Vec<Arc<crate::feed::capture::Capture>>,
    /// ADS-B reports sent: the vehicle's system id, the report.
    pub traffic: Vec<(u8, crate::feed::AdsbSent)>,
}

/// A run's state.
pub struct Session {
    /// Decoding and its counters.
    ingestor: Ingestor,
    /// Every track.
    world: WorldStore,
    /// The scene, when collisions are checked.
    scene: Option<Arc<Scene>>,
    /// The collision pipeline, when collisions are checked.
    pipeline: Option<Pipeline>,
    events_out: Option<(PathBuf, BufWriter<File>)>,
    events: Vec<Event>,
    /// Collisions, near misses and losses of well clear (the first `NOTABLE_KEPT`), for the
    /// printed report.
    notable: Vec<Event>,
    /// Those past `NOTABLE_KEPT`, counted.
    notable_not_kept: u64,
    /// Every event's contribution to the run's figures (closest approaches, first collision).
    digest: EventDigest,
    /// Per-tick collision cost.
    tick_costs: crate::costs::TickCosts,
    /// Closest approach of each vehicle to each moving body, on the receive clock.
    approaches: Approaches,
    /// A show's slots, when given (`--slots`).
    slots: Option<crate::daa::slots::Slots>,
    /// The most pairs each of the summary's lists holds (`None`: every pair).
    summary_pairs: Option<usize>,
    dynamic: MovingBodies,
    /// The bodies within the approach reach, by their positions (session::traffic).
    approached: Vec<traffic::Approached>,
    /// The largest model radius in the scene (the watch range's margin), metres.
    max_model_radius_m: f64,
    /// Scratch: the well-clear changes of the tick.
    well_clear_changes: Vec<WellClearChange>,
    flight_start_t_s: Option<f64>,
    last_expire_t_s: f64,
    started: Instant,
    /// Set when the run was stopped by a signal.
    interrupted: bool,
    /// What an autopilot log held, when the input is one (the summary's `log`).
    log: Option<crate::logs::flightlog::LogSummary>,
    /// Whoever watches the run (the viewer, `--rerun`): handed a frame at each tick, each line
    /// a vehicle says, and the run's end.
    observer: Option<Box<dyn Observer>>,
    /// What the vehicles say (STATUSTEXT, mode changes, COLLISION), for the observer.
    notes: crate::codec::notes::Notes,
    /// Notes of senders with no position yet, held until their first (at most
    /// [`HELD_NOTES`]).
    held_notes: Vec<(f64, crate::codec::notes::Note)>,
    ticks: u64,
    /// The closed-loop feed, when `--feed` is on.
    feed: Option<Feed>,
    /// Feed messages made and not yet sent (live) or written (replay).
    feed_out: Vec<FeedMessage>,
    /// What the feed's devices made and sent at each sample, kept for companions
    /// ([`Session::keep_companion_inputs`]).
    companion_inputs: Option<CompanionInputs>,
    /// Where replay writes the feed (`--feed-out`): a tlog, encoded as the feed's identity.
    feed_tlog: Option<(PathBuf, TlogWriter<BufWriter<File>>, Outbox)>,
    /// savsim's own MAVLink identities (its GCS, its feed): their frames, echoed back by a
    /// router, are counted and never applied to the world.
    own: Vec<SenderId>,
    /// Times are on the vehicle's clock, the flight starting at its boot
    /// ([`Session::use_vehicle_clock`]).
    vehicle_clock: bool,
    /// Vehicles savsim flies itself (lockstep): their truth comes through
    /// [`Session::on_report`], and the positions they send are their estimates, kept in
    /// `estimates` and never applied to the world.
    truth_fed: Vec<SenderId>,
    /// Estimated positions of `truth_fed` vehicles not yet taken ([`Session::drain_estimates`]).
    estimates: Vec<(SenderId, crate::world::inputs::PositionReport)>,
}

impl Session {
    /// A session; with a scene, collisions are checked with `collision`.
    pub fn new(
        scene: Option<Arc<Scene>>,
        collision: CollisionConfig,
        events_path: Option<&Path>,
    ) -> Result<Self> {
        let pipeline = scene.as_ref().map(|s| Pipeline::new(s, collision));
        Self::build(scene, pipeline, events_path)
    }

    /// A session over `scene` with a pipeline already built for it: a clone of one pipeline
    /// built once (its exact shapes, and any meshes made resident with
    /// [`Pipeline::build_every_mesh`]) serves many runs over one scene without building them
    /// again.
    pub fn with_pipeline(
        scene: Arc<Scene>,
        pipeline: Pipeline,
        events_path: Option<&Path>,
    ) -> Result<Self> {
        Self::build(Some(scene), Some(pipeline), events_path)
    }

    fn build(
        scene: Option<Arc<Scene>>,
        pipeline: Option<Pipeline>,
        events_path: Option<&Path>,
    ) -> Result<Self> {
        let origin = scene
            .as_ref()
            .map_or(crate::scene::gen::DEFAULT_ORIGIN, |s| s.origin);
        let events_out = events_path
            .map(|p| {
                File::create(p)
                    .map(|f| (p.to_path_buf(), BufWriter::new(f)))
                    .map_err(|e| Error::file(p, e))
            })
            .transpose()?;
        let max_model_radius_m = scene.as_deref().map_or(0.0, watch::max_model_radius_m);
        Ok(Self {
            ingestor: Ingestor::default(),
            world: WorldStore::new(origin, WorldConfig::default()),
            scene,
            pipeline,
            events_out,
            events: Vec::new(),
            notable: Vec::new(),
            notable_not_kept: 0,
            digest: EventDigest::default(),
            tick_costs: Default::default(),
            approaches: Approaches::default(),
            slots: None,
            summary_pairs: Some(summary::LISTED_PAIRS_MAX),
            well_clear_changes: Vec::new(),
            dynamic: MovingBodies::default(),
            approached: Vec::new(),
            max_model_radius_m,
            flight_start_t_s: None,
            last_expire_t_s: f64::NEG_INFINITY,
            started: Instant::now(),
            interrupted: false,
            log: None,
            observer: None,
            notes: crate::codec::notes::Notes::default(),
            held_notes: Vec::new(),
            ticks: 0,
            feed: None,
            feed_out: Vec::new(),
            companion_inputs: None,
            feed_tlog: None,
            own: Vec::new(),
            vehicle_clock: false,
            truth_fed: Vec::new(),
            estimates: Vec::new(),
        })
    }

    /// Vehicles' samples keep their own clock's time (`WorldConfig::vehicle_clock`) and the
    /// flight starts at the vehicle's boot (its `time_boot_ms` 0): scripted traffic then moves
    /// on the vehicle's clock from its boot, at any speedup, and times in events and the
    /// summary are seconds of that clock (`savsim study`). With several vehicles, the clock of
    /// the first heard is the timeline and the others are mapped onto it
    /// ([`savsim_core::world::timeline`]). Set before the first frame (it starts the world
    /// again).
    pub fn use_vehicle_clock(&mut self) {
        self.use_vehicle_clock_of(None);
    }

    /// [`Session::use_vehicle_clock`], the timeline being the clock of the vehicle with
    /// `system_id` (`None`: the first heard); other vehicles' positions before its first are
    /// not applied.
    pub fn use_vehicle_clock_of(&mut self, system_id: Option<u8>) {
        self.vehicle_clock = true;
        let origin = self.world.plane().origin();
        self.world = WorldStore::new(
            origin,
            WorldConfig {
                vehicle_clock: true,
                timeline_system_id: system_id,
                ..WorldConfig::default()
            },
        );
    }

    /// What decoding counted.
    pub fn stats(&self) -> &crate::codec::stats::IngestStats {
        &self.ingestor.stats
    }

    /// What decoding counted, for a reader or a link that counts what it skipped or dropped.
    pub fn stats_mut(&mut self) -> &mut crate::codec::stats::IngestStats {
        &mut self.ingestor.stats
    }

    /// Every track.
    pub fn world(&self) -> &WorldStore {
        &self.world
    }

    /// The scene, when collisions are checked.
    pub fn scene(&self) -> Option<&Scene> {
        self.scene.as_deref()
    }

    /// The collision pipeline, when collisions are checked.
    pub fn pipeline(&self) -> Option<&Pipeline> {
        self.pipeline.as_ref()
    }

    /// Collisions, near misses and losses of well clear (the first 1000), for the printed
    /// report; [`Session::notable_not_kept`] counts the rest.
    pub fn notable(&self) -> &[Event] {
        &self.notable
    }

    /// Collisions, near misses and losses of well clear past the first 1000, not kept.
    pub fn notable_not_kept(&self) -> u64 {
        self.notable_not_kept
    }

    /// What every event of the run adds up to (closest approach per obstacle, first
    /// collision, counts).
    pub fn digest(&self) -> &EventDigest {
        &self.digest
    }

    /// Per-tick collision cost.
    pub fn tick_costs(&self) -> &crate::costs::TickCosts {
        &self.tick_costs
    }

    /// Closest approaches and well clear, so far.
    pub fn approaches(&self) -> &Approaches {
        &self.approaches
    }

    /// List at most `max` pairs in each of the summary's lists of pairs (the closest), or
    /// every pair (`None`). Default [`summary::LISTED_PAIRS_MAX`].
    pub fn set_summary_pairs(&mut self, max: Option<usize>) {
        self.summary_pairs = max;
    }

    /// Judge each vehicle against its slot in `slots` (before the first message).
    pub fn set_slots(&mut self, slots: crate::daa::slots::Slots) {
        self.slots = Some(slots);
    }

    /// Judge closest approaches, well clear and the separation minimum with `approaches`
    /// (before the first message).
    pub fn set_approaches(&mut self, approaches: Approaches) {
        self.approaches = approaches;
    }

    /// Whether the run was stopped by a signal.
    pub fn interrupted(&self) -> bool {
        self.interrupted
    }

    /// Say what the autopilot log being replayed held (the summary's `log`).
    pub fn set_log(&mut self, log: crate::logs::flightlog::LogSummary) {
        self.log = Some(log);
    }

    /// Record whether the run was stopped by a signal.
    pub fn set_interrupted(&mut self, interrupted: bool) {
        self.interrupted = interrupted;
    }

    /// The closed-loop feed, when on.
    pub fn feed(&self) -> Option<&Feed> {
        self.feed.as_ref()
    }

    /// Whether feed messages are waiting to be sent.
    pub fn has_feed_out(&self) -> bool {
        !self.feed_out.is_empty()
    }

    /// The feed messages made and not yet sent.
    pub fn pending_feed(&self) -> &[FeedMessage] {
        &self.feed_out
    }

    /// Take the feed messages made and not yet sent.
    pub fn drain_feed(&mut self) -> std::vec::Drain<'_, FeedMessage> {
        self.feed_out.drain(..)
    }

    /// Keep what the feed's devices make (images, clouds) and the ADS-B reports it sends, for
    /// companions ([`Session::drain_companion_inputs`]).
    pub fn keep_companion_inputs(&mut self) {
        self.companion_inputs
            .get_or_insert_with(CompanionInputs::default);
        if let Some(feed) = self.feed.as_mut() {
            feed.keep_captures(true);
        }
    }

    /// The names of the feed's modelled devices (none with `ideal` sensors or no feed).
    pub fn sensor_names(&self) -> Vec<String> {
        self.feed.as_ref().map_or_else(Vec::new, |f| {
            f.config
                .sensors
                .devices()
                .iter()
                .map(|d| d.name.clone())
                .collect()
        })
    }

    /// What was kept for companions since the last call.
    pub fn drain_companion_inputs(&mut self) -> CompanionInputs {
        self.companion_inputs
            .as_mut()
            .map(std::mem::take)
            .unwrap_or_default()
    }

    /// savsim's own MAVLink identities: their frames, echoed back by a router, are never
    /// applied to the world.
    pub fn set_own(&mut self, own: Vec<SenderId>) {
        self.own = own;
    }

    /// Hand every frame of this run to `observer` (the viewer): a tick's, a vehicle's line,
    /// the closest approaches at its end.
    pub fn observe(&mut self, observer: Box<dyn Observer>) {
        self.observer = Some(observer);
        if let Some(feed) = self.feed.as_mut() {
            feed.keep_captures(true);
        }
    }

    /// What an observer is told of this run before its first frame: its scene, the scene's
    /// octree, its clock. `None` without a scene (nothing is drawn of a run without one).
    pub fn run_start(&self) -> Option<RunStart> {
        let (Some(scene), Some(pipeline)) = (&self.scene, &self.pipeline) else {
            return None;
        };
        Some(RunStart {
            scene: scene.clone(),
            octree_leaves: pipeline.octree().leaves().map(|(_, b, _)| b).collect(),
            vehicle_clock: self.vehicle_clock,
        })
    }

    /// Turn the closed-loop feed on (docs/closed-loop.md). Needs a scene.
    pub fn start_feed(&mut self, config: FeedConfig) -> Result<()> {
        if self.pipeline.is_none() {
            return Err(Error::Usage("--feed needs --scene".into()));
        }
        config.validate().map_err(|e| Error::Usage(e.to_string()))?;
        let mut feed = Feed::new(config);
        feed.keep_captures(self.observer.is_some() || self.companion_inputs.is_some());
        self.feed = Some(feed);
        Ok(())
    }

    /// Write the feed to `path` as a tlog (each message stamped with the receive time of the
    /// sample it was cast from, sent as `from`) instead of keeping it in `feed_out`.
    pub fn write_feed_to(&mut self, path: &Path, from: SenderId) -> Result<()> {
        if self.feed.is_none() {
            return Err(Error::Usage("--feed-out needs --feed".into()));
        }
        let file = File::create(path).map_err(|e| Error::file(path, e))?;
        self.feed_tlog = Some((
            path.to_path_buf(),
            TlogWriter::new(BufWriter::new(file)),
            Outbox::new(from),
        ));
        Ok(())
    }

    fn write_feed(&mut self) -> Result<()> {
        let Some((path, out, outbox)) = &mut self.feed_tlog else {
            return Ok(());
        };
        for m in self.feed_out.drain(..) {
            let t_us = (m.t_s * 1e6).max(0.0) as u64;
            out.write_record(t_us, &outbox.encode(&m.message))
                .map_err(|e| Error::file(path.clone(), e))?;
        }
        Ok(())
    }

    /// Seconds from the first message to `t_s` (on the vehicle's clock,
    /// [`Session::use_vehicle_clock`]: from the vehicle's boot): the clock of the printed
    /// report's "+N s", the viewer's labels and a study's times. `None` before the first
    /// message (its first position, on the vehicle's clock).
    pub fn elapsed_s(&self, t_s: f64) -> Option<f64> {
        if self.vehicle_clock {
            // On the vehicle's clock: seconds since its boot.
            return self.flight_start_t_s.map(|start| t_s - start);
        }
        self.ingestor
            .stats
            .time_span_s
            .map(|(first, _)| t_s - first)
    }

    /// Take one complete frame received (or recorded) at `t_s` (UNIX seconds).
    pub fn on_frame(&mut self, t_s: f64, frame: &RawFrame<'_>) -> Result<()> {
        let t_s = if frame.status == FrameStatus::Valid {
            self.ingestor.stats.observe_time(t_s)
        } else {
            t_s
        };
        if frame.status == FrameStatus::Valid {
            self.note_for_observer(t_s, frame);
        }
        let Some(decoded) = self.ingestor.frame(frame) else {
            return Ok(());
        };
        if self.own.contains(&decoded.sender) {
            return Ok(());
        }
        if let Some(feed) = &mut self.feed {
            if feed.is_echo(&decoded.report) {
                return Ok(());
            }
        }
        if self.truth_fed.contains(&decoded.sender) {
            use crate::world::inputs::Report;
            match decoded.report {
                Report::Position(p) => {
                    if self.estimates.len() < HELD_ESTIMATES {
                        self.estimates.push((decoded.sender, p));
                    }
                    return Ok(());
                }
                Report::Attitude(_) => return Ok(()),
                _ => {}
            }
        }
        self.on_report(t_s, decoded.sender, &decoded.report)
    }

    /// The vehicles savsim flies itself (lockstep): their positions and attitudes come only
    /// through [`Session::on_report`] (the truth); what they send of their own is their
    /// estimate ([`Session::drain_estimates`]).
    pub fn set_truth_fed(&mut self, vehicles: Vec<SenderId>) {
        self.truth_fed = vehicles;
    }

    /// The positions the truth-fed vehicles sent since the last call (at most
    /// [`HELD_ESTIMATES`] held; the rest dropped).
    pub fn drain_estimates(
        &mut self,
    ) -> std::vec::Drain<'_, (SenderId, crate::world::inputs::PositionReport)> {
        self.estimates.drain(..)
    }

    /// Take one report from `sender` at `t_s` (seconds on the source's clock): what a frame
    /// decodes to, or what an autopilot log holds (`crate::logs::flightlog`).
    pub fn on_report(
        &mut self,
        t_s: f64,
        sender: SenderId,
        report: &crate::codec::decode::Report,
    ) -> Result<()> {
        if let WorldUpdate::VehicleMoved(sender) = self.world.apply(t_s, sender, report) {
            self.tick(sender)?;
        }
        if t_s - self.last_expire_t_s >= 1.0 {
            self.world.expire(t_s);
            self.last_expire_t_s = t_s;
        }
        Ok(())
    }

    fn flush_events(&mut self) -> Result<()> {
        for e in self.events.drain(..) {
            self.digest.take(&e);
            if matches!(
                e.kind,
                EventKind::Collision { .. }
                    | EventKind::NearMiss { .. }
                    | EventKind::WellClearLost { .. }
                    | EventKind::SeparationLost { .. }
                    | EventKind::LeftSlot { .. }
            ) {
                if self.notable.len() < NOTABLE_KEPT {
                    self.notable.push(e.clone());
                } else {
                    self.notable_not_kept += 1;
                }
            }
            if let Some((path, out)) = &mut self.events_out {
                serde_json::to_writer(&mut *out, &e)
                    .map_err(|err| Error::file(path.clone(), err.into()))?;
                out.write_all(b"\n")
                    .map_err(|err| Error::file(path.clone(), err))?;
            }
        }
        Ok(())
    }

    /// End the run: close open near misses and flush the events file.
    pub fn finish(&mut self) -> Result<()> {
        if let Some(pipeline) = self.pipeline.as_mut() {
            pipeline.finish(&mut self.events);
        }
        self.flush_events()?;
        if let Some((path, out)) = &mut self.events_out {
            out.flush().map_err(|e| Error::file(path.clone(), e))?;
        }
        if let Some((path, out, _)) = &mut self.feed_tlog {
            out.flush().map_err(|e| Error::file(path.clone(), e))?;
        }
        self.observe_end()?;
        Ok(())
    }
}

/// Write a JSON value to `path` atomically (a temporary file renamed into place), so a reader
/// never sees half a file, even when savsim is stopped by a signal.
pub fn write_json_atomic(path: &Path, value: &impl Serialize) -> Result<()> {
    crate::files::write_atomic(path, |w| {
        serde_json::to_writer_pretty(w, value).map_err(std::io::Error::other)
    })
    .map_err(|e| Error::file(path, e))
}
