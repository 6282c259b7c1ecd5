//! What a run shows as it goes, for whoever watches it (the rerun viewer, `viz`): the frames a
//! session makes at each tick, at each line a vehicle says and at its end, and the
//! [`Observer`] it hands them to. The session knows no viewer and the viewer no session: both
//! know this.

use std::sync::Arc;

use glam::DVec3;

use crate::collision::events::Event;
use crate::collision::ColliderKind;
use crate::error::Result;
pub use crate::feed::capture::{Capture, CaptureData};
use crate::feed::{AdsbSent, Reading};
use crate::pipeline::{BodyKey, BodyPose, ObstacleRef, TickReport};
use crate::scene::{Aabb64, Kind, Scene};

/// What an observer is told of a run before its first frame.
#[derive(Debug, Clone)]
pub struct RunStart {
    /// The scene.
    pub scene: Arc<Scene>,
    /// The leaves of the scene's octree (the paper's nodes).
    pub octree_leaves: Vec<Aabb64>,
    /// Times are on the vehicle's clock (a study row's), not the receive clock.
    pub vehicle_clock: bool,
}

/// One vehicle's tick.
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
    pub feed: Vec<Reading>,
    /// The feed's range, metres (a reading of nothing is drawn this long).
    pub feed_max_m: f64,
    /// The ADS-B reports the feed sent the vehicle at this tick: where each put its aircraft
    /// (its errors included).
    pub adsb_sent: Vec<AdsbSent>,
    /// The depth images and point clouds the vehicle's modelled devices made at this tick.
    pub captures: Vec<Arc<Capture>>,
    /// The vehicle's octree leaf.
    pub node: Option<Aabb64>,
    /// Obstacles with a collider: which, and beta.
    pub colliders: Vec<(ObstacleRef, ColliderKind, f64)>,
    /// Moving obstacles this tick: key, id, kind, model, pose.
    pub dynamic: Vec<(BodyKey, String, Kind, usize, BodyPose)>,
    /// Collisions, near misses and losses of well clear reported at this tick.
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

/// What a session shows.
#[derive(Debug)]
pub enum Frame {
    /// A vehicle's tick.
    Tick(Box<TickFrame>),
    /// A line a vehicle said.
    Note(Box<NoteFrame>),
    /// The closest approaches of the run, at its end.
    Approaches(Vec<ApproachFrame>),
}

/// Whoever watches a run. A session hands it every frame and never waits for it: an observer
/// that cannot keep up drops frames and counts them.
pub trait Observer: Send {
    /// Take a frame; never blocks.
    fn take(&mut self, frame: Frame);
    /// Frames kept so far, and frames dropped.
    fn counts(&self) -> (u64, u64);
    /// End: what was taken is written out.
    fn finish(&mut self) -> Result<()>;
}
