//! The stages of one vehicle's tick, each given only the parts of the pipeline it uses: the
//! vehicle's state, the sensing frame when due, the contacts and the episodes.

use std::collections::BTreeMap;
use std::time::Instant;

use glam::DVec3;

use super::{TickReport, VehicleCollision};
use crate::collision::bodies::{radius_m, BodyPose, VehicleKey};
use crate::collision::broad_phase::StaticBroadPhase;
use crate::collision::config::CollisionConfig;
use crate::collision::config::Mode;
use crate::collision::contact::{Before, Contacts, Motion};
use crate::collision::episodes::Found;
use crate::collision::events::{Event, EventKind};
use crate::collision::meshes::MeshCache;
use crate::collision::sensing::{Frame, Rules, Sensing, SensingState};
use crate::collision::view::World;
use crate::scene::Scene;
use crate::world::TrackSample;

/// What one vehicle's tick looks at: the world, the settings, its two samples (`previous`:
/// the one swept from, if any), its model, and how an event is stamped.
pub(super) struct Tick<'a> {
    pub world: &'a World<'a>,
    pub cfg: &'a CollisionConfig,
    pub previous: Option<&'a TrackSample>,
    pub current: &'a TrackSample,
    /// The vehicle's model, an index into `Scene::geometries`.
    pub geometry_index: usize,
    pub event: &'a dyn Fn(EventKind) -> Event,
}

impl<'a> Tick<'a> {
    /// The sensing layer's view of this tick under `rules`.
    pub fn frame(&self, rules: Rules) -> Frame<'a> {
        Frame {
            world: self.world,
            cfg: self.cfg,
            rules,
            current: self.current,
            event: self.event,
        }
    }
}

/// The collision state of `key`'s vehicle, made on its first tick. A new track generation
/// (a reboot, or expiry and return) closes what was open and starts again from nothing.
pub(super) fn vehicle_state<'v>(
    vehicles: &'v mut BTreeMap<(u16, u8), VehicleCollision>,
    totals: &mut super::PipelineTotals,
    key: VehicleKey,
    event: &dyn Fn(EventKind) -> Event,
    events: &mut Vec<Event>,
) -> &'v mut VehicleCollision {
    let state = vehicles
        .entry((key.vehicle, key.component_id))
        .or_insert_with(|| VehicleCollision {
            generation: key.generation,
            ..VehicleCollision::default()
        });
    if state.generation != key.generation {
        state.episodes.close(event, events);
        *state = VehicleCollision {
            generation: key.generation,
            ..VehicleCollision::default()
        };
        totals.state_resets += 1;
    }
    state
}

/// The sensing layer at this tick: a frame if one is due (every sample in `paper`, at
/// `sensor_hz` of the vehicle's clock in `exact`, and whenever the clock went back); between
/// frames the colliders are the last frame's.
pub(super) fn sense(
    sensing: &mut Sensing,
    meshes: &mut MeshCache,
    frame: &Frame<'_>,
    state: &mut SensingState,
    events: &mut Vec<Event>,
    report: &mut TickReport,
) {
    if frame_due(
        frame.cfg,
        frame.rules,
        state.last_frame_t_s,
        frame.current.t_s,
    ) {
        let started = Instant::now();
        // What the last frame asked the mesh worker for is resident from here on.
        meshes.install_requested();
        let counts = sensing.frame(frame, meshes, state, events);
        report.sensing_ns = elapsed_ns(started);
        report.sensed = true;
        report.ray_tests = counts.ray_tests;
    }
    let counts = state.counts;
    report.active_box = counts.active_box;
    report.active_mesh = counts.active_mesh;
    report.active_triangles = counts.active_triangles;
}

/// Whether a sensing frame is due at `t_s` after the last one at `last_frame_t_s`: always in
/// `paper`, at `sensor_hz` in `exact`, and whenever the clock went back.
pub(super) fn frame_due(
    cfg: &CollisionConfig,
    rules: Rules,
    last_frame_t_s: Option<f64>,
    t_s: f64,
) -> bool {
    let period_s = if rules == Rules::Paper || cfg.sensor_hz <= 0.0 {
        0.0
    } else {
        1.0 / cfg.sensor_hz
    };
    last_frame_t_s.is_none_or(|last| t_s - last >= period_s - 1e-9 || t_s < last)
}

/// The contact layer over the interval from `tick.previous` (or at the sample alone), then
/// the episodes: collisions that began, near misses that ended. Keeps the exact gaps at this
/// sample for the next interval.
pub(super) fn collide(
    contacts: &mut Contacts,
    meshes: &mut MeshCache,
    tick: &Tick<'_>,
    state: &mut VehicleCollision,
    events: &mut Vec<Event>,
    report: &mut TickReport,
) {
    let (world, cfg, previous) = (tick.world, tick.cfg, tick.previous);
    let t = tick.current.t_s;
    let started = Instant::now();
    let motion = Motion {
        before: previous.map(BodyPose::of),
        now: BodyPose::of(tick.current),
        geometry_index: tick.geometry_index,
        radius_m: radius_m(&world.scene.geometries[tick.geometry_index]),
    };
    report.swept = cfg.mode == Mode::Exact && motion.before.is_some();
    let before = Before {
        touching: state.episodes.touching(),
        gaps: match previous {
            Some(p) if state.gaps_t_s == Some(p.t_s) => &state.gaps,
            _ => &[],
        },
    };
    report.narrow_tests = contacts.run(world, meshes, cfg, &state.sensing, &motion, before);
    std::mem::swap(&mut state.gaps, &mut contacts.gaps);
    state.gaps_t_s = Some(t);
    let found = Found {
        touching: &contacts.touching,
        near: &contacts.near,
    };
    let interval = (previous.map_or(t, |p| p.t_s), t);
    state.episodes.update(
        world.scene,
        world.dynamic,
        found,
        interval,
        tick.event,
        events,
    );
    report.contact_ns = elapsed_ns(started);
}

/// Nanoseconds since `started` (saturating).
pub(super) fn elapsed_ns(started: Instant) -> u64 {
    started.elapsed().as_nanos().min(u128::from(u64::MAX)) as u64
}

/// Height of `position` above the highest terrain patch under it (None: no terrain there).
pub(super) fn terrain_clearance(
    statics: &StaticBroadPhase,
    scene: &Scene,
    position: DVec3,
) -> Option<f64> {
    statics
        .terrain_under(scene, position)
        .map(|(_, ground)| position.z - ground)
}
