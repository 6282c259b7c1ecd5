//! The per-tick orchestrator: for one vehicle and one telemetry sample, run the stages of the
//! mode (sensing frame, contacts, episodes: `stages`) and count what they did.
//!
//! Like rapier's `CollisionPipeline`, it owns only caches and scratch buffers; the scene and the
//! vehicle's samples come in as arguments. After warm-up a tick does not allocate, except when
//! a mesh is built or an event is reported.

mod stages;

use std::collections::BTreeMap;
use std::time::Instant;

pub use crate::collision::bodies::{
    BodyKey, BodyPose, BodySource, DynamicBody, ObstacleRef, VehicleKey,
};
pub use crate::collision::config::{CollisionConfig, Mode, SensorFan};
pub use crate::collision::fan::Rays;
pub use crate::collision::moving::MovingBodies;
pub use crate::collision::sensing::{RayHit, SensingState};

use crate::collision::broad_phase::StaticBroadPhase;
use crate::collision::contact::shapes::ExactShapes;
use crate::collision::contact::Contacts;
use crate::collision::episodes::{sweepable_from, Episodes};
use crate::collision::events::{Event, EventKind};
use crate::collision::meshes::MeshCache;
use crate::collision::sensing::octree::Octree;
use crate::collision::sensing::{self, Rules, Sensing};
use crate::collision::view::World;
use crate::reference::{Interval, Reference};
use crate::scene::{Aabb64, Scene};
use crate::world::TrackSample;

/// One vehicle's collision state across ticks.
#[derive(Debug, Clone, Default)]
pub struct VehicleCollision {
    generation: u32,
    /// What the vehicle perceives (the paper's node, rays and colliders).
    pub sensing: SensingState,
    episodes: Episodes,
    /// The last sample was implausible: do not sweep from it.
    last_implausible: bool,
    /// Exact gaps to static obstacles at the sample at `gaps_t_s` (sorted by obstacle), for
    /// the contact layer's next interval.
    gaps: Vec<(ObstacleRef, f64)>,
    gaps_t_s: Option<f64>,
}

impl VehicleCollision {
    /// Obstacles in contact at the last sample.
    pub fn touching(&self) -> &[ObstacleRef] {
        self.episodes.touching()
    }
}

/// What one tick did.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct TickReport {
    /// Obstacles with a box collider (the sensing layer's in `paper` and `exact`).
    pub active_box: usize,
    /// Obstacles with a mesh collider.
    pub active_mesh: usize,
    /// Triangles in active mesh colliders (the vehicle's included when it is a mesh).
    pub active_triangles: usize,
    /// Exact contact tests run (intersection, distance, sweep).
    pub narrow_tests: usize,
    /// Exact ray tests the sensing layer ran.
    pub ray_tests: usize,
    /// True when the contacts were swept from the previous sample.
    pub swept: bool,
    /// True when the sensing layer ran a frame at this tick.
    pub sensed: bool,
    /// Height of the vehicle's reference point above the terrain under it, metres (None
    /// where there is no terrain).
    pub terrain_clearance_m: Option<f64>,
    /// True when the sample was skipped as implausible (far below the terrain).
    pub implausible: bool,
    /// Time in the contact layer (and episodes), nanoseconds.
    pub contact_ns: u64,
    /// Time in the sensing layer, nanoseconds (0 when it did not run).
    pub sensing_ns: u64,
}

/// Counters over a whole run.
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize)]
pub struct PipelineTotals {
    /// Ticks run.
    pub ticks: u64,
    /// Sensing frames run.
    pub sensing_frames: u64,
    /// Collision events.
    pub collisions: u64,
    /// Collider swap events.
    pub swaps: u64,
    /// Near-miss events.
    pub near_misses: u64,
    /// Telemetry gaps.
    pub telemetry_gaps: u64,
    /// Vehicle tracks whose collision state was reset (a reboot, or expiry and return).
    pub state_resets: u64,
    /// Sum of active boxes over ticks (divide by ticks for the mean).
    pub active_box_sum: u64,
    /// Sum of active meshes over ticks.
    pub active_mesh_sum: u64,
    /// Sum of active triangles over ticks.
    pub active_triangles_sum: u64,
    /// Most active boxes at one tick.
    pub active_box_max: usize,
    /// Most active meshes at one tick.
    pub active_mesh_max: usize,
    /// Most active triangles at one tick.
    pub active_triangles_max: usize,
    /// Exact contact tests run.
    pub narrow_tests: u64,
    /// Exact ray tests run.
    pub ray_tests: u64,
    /// Lowest terrain clearance seen over the run, metres.
    pub terrain_clearance_min_m: Option<f64>,
    /// Samples skipped as implausible (far below the terrain).
    pub implausible_samples: u64,
    /// `reference` mode: intervals that needed more sub-steps than it takes, stepped coarser
    /// (their answer is not the reference's).
    pub reference_capped: u64,
}

/// The collision pipeline for a scene.
#[derive(Debug, Clone)]
pub struct Pipeline {
    /// Settings.
    config: CollisionConfig,
    /// The static scene's octree (the sensing layer's nodes).
    octree: Octree,
    /// The static broad phase (parry's `Bvh`): region queries and rays.
    statics: StaticBroadPhase,
    /// Built triangle meshes (resident within the budget).
    meshes: MeshCache,
    /// The contact layer's exact solids.
    shapes: ExactShapes,
    /// The ground truth, in `reference` mode.
    reference: Option<Reference>,
    /// Per-vehicle state by (vehicle, component).
    vehicles: BTreeMap<(u16, u8), VehicleCollision>,
    /// Totals over the run.
    totals: PipelineTotals,
    sensing: Sensing,
    contacts: Contacts,
    static_triangles: usize,
    has_terrain: bool,
    /// Scratch of the exact ray fans.
    fan: crate::collision::fan::FanScratch,
}

impl Pipeline {
    /// A pipeline for `scene`: builds the octree (once), the exact solids (`exact`), and in
    /// `mesh` mode every obstacle's mesh (what "every obstacle a mesh" costs).
    pub fn new(scene: &Scene, config: CollisionConfig) -> Self {
        let boxes: Vec<Aabb64> = scene.obstacles.iter().map(|o| o.aabb_enu_m).collect();
        // Built in every mode: the contact layer's `exact` strategy uses them, and so does every
        // mode's exact ray fan (the feed's sensors see the world, whatever the mode).
        let shapes = ExactShapes::new(&scene.geometries);
        let mut pipeline = Self {
            config,
            octree: Octree::build(&boxes, config.octree),
            statics: StaticBroadPhase::build(&boxes),
            meshes: MeshCache::new(scene.geometries.len()),
            shapes,
            reference: (config.mode == Mode::Reference).then(Reference::default),
            vehicles: BTreeMap::new(),
            totals: PipelineTotals::default(),
            sensing: Sensing::default(),
            contacts: Contacts::default(),
            static_triangles: scene
                .obstacles
                .iter()
                .map(|o| o.geometry.triangle_count())
                .sum(),
            has_terrain: scene.obstacles.iter().any(|o| o.geometry.is_terrain()),
            fan: Default::default(),
        };
        if config.mode == Mode::Mesh {
            // "Every obstacle a mesh" keeps them all: what that costs is what it shows.
            pipeline.build_every_mesh(scene);
        } else {
            let mib = config.mesh_budget_mib.max(0.0);
            pipeline
                .meshes
                .set_budget((mib * 1024.0 * 1024.0).min(usize::MAX as f64) as usize);
        }
        pipeline
    }

    /// Build the mesh of every obstacle of `scene` now (within the cache's budget), instead of
    /// when the sensing layer or a contact first needs it.
    pub fn build_every_mesh(&mut self, scene: &Scene) {
        for o in &scene.obstacles {
            self.meshes.get(o.geometry_index, &o.geometry);
        }
    }

    /// Its settings.
    pub fn config(&self) -> &CollisionConfig {
        &self.config
    }

    /// The static scene's octree (the sensing layer's nodes).
    pub fn octree(&self) -> &Octree {
        &self.octree
    }

    /// The static broad phase (parry's `Bvh`): region queries and rays.
    pub fn statics(&self) -> &StaticBroadPhase {
        &self.statics
    }

    /// The built triangle meshes.
    pub fn meshes(&self) -> &MeshCache {
        &self.meshes
    }

    /// Build prefetched meshes on the mesh worker (the default) or on the caller's thread.
    pub fn set_mesh_worker(&mut self, worker: bool) {
        self.meshes.set_worker(worker);
    }

    /// Totals over the run.
    pub fn totals(&self) -> &PipelineTotals {
        &self.totals
    }

    /// True when the scene has terrain (a height field or terrain mesh).
    pub fn has_terrain(&self) -> bool {
        self.has_terrain
    }

    /// Whether `vehicle`'s tick at `t_s` would run a sensing frame (the only stage that looks
    /// at moving bodies beyond the contact layer's and the well-clear reach): the session
    /// fills a tick without one with the bodies near enough to matter to the rest.
    pub fn senses_at(&self, vehicle: VehicleKey, t_s: f64) -> bool {
        let Some(rules) = sensing_rules(self.config.mode) else {
            return false;
        };
        match self.vehicles.get(&(vehicle.vehicle, vehicle.component_id)) {
            Some(state) if state.generation == vehicle.generation => {
                stages::frame_due(&self.config, rules, state.sensing.last_frame_t_s, t_s)
            }
            _ => true,
        }
    }

    /// Where `vehicle`'s sensing frame at `current` desires moving bodies: its region, scene ENU
    /// metres, and how far ahead a body's speed carries it into the region, seconds (`None` in
    /// a mode without a sensing layer). A body whose box at its pose, grown by its speed over
    /// that lead, misses the region, and that the vehicle holds no collider for, changes
    /// nothing the frame does.
    pub fn sensing_region(
        &self,
        vehicle: VehicleKey,
        current: &TrackSample,
    ) -> Option<(Aabb64, f64)> {
        let rules = sensing_rules(self.config.mode)?;
        let fresh = SensingState::default();
        let state = match self.vehicles.get(&(vehicle.vehicle, vehicle.component_id)) {
            Some(v) if v.generation == vehicle.generation => &v.sensing,
            _ => &fresh,
        };
        let look = sensing::look(&self.octree, &self.config, rules, state, current);
        Some((look.region, sensing::moving_lead_s(&self.config, rules)))
    }

    /// The collision state of `vehicle` (component 1 when only a number is known), if it ever
    /// ticked.
    pub fn vehicle(&self, vehicle: u16, component_id: u8) -> Option<&VehicleCollision> {
        self.vehicles.get(&(vehicle, component_id))
    }

    /// Cast `rays` against every obstacle's exact shape and the moving bodies of `dynamic` but
    /// `own`: what a range sensor on the vehicle measures (`collision::fan`). `out[k]` is the
    /// nearest hit of ray `k`, metres, or `None`; `out` is as long as `rays.dirs_enu`.
    pub fn cast_exact_rays(
        &mut self,
        scene: &Scene,
        own: BodySource,
        dynamic: &MovingBodies,
        rays: Rays<'_>,
        out: &mut [Option<f64>],
    ) {
        self.cast_each(scene, own, dynamic, rays, |i, hit| {
            if let Some(o) = out.get_mut(i) {
                *o = hit.map(|(_, d)| d);
            }
        });
    }

    /// As [`Pipeline::cast_exact_rays`], with what each ray met: `out[i]` the obstacle and
    /// its distance.
    pub fn cast_exact_hits(
        &mut self,
        scene: &Scene,
        own: BodySource,
        dynamic: &MovingBodies,
        rays: Rays<'_>,
        out: &mut [Option<(ObstacleRef, f64)>],
    ) {
        self.cast_each(scene, own, dynamic, rays, |i, hit| {
            if let Some(o) = out.get_mut(i) {
                *o = hit;
            }
        });
    }

    fn cast_each(
        &mut self,
        scene: &Scene,
        own: BodySource,
        dynamic: &MovingBodies,
        rays: Rays<'_>,
        put: impl FnMut(usize, Option<(ObstacleRef, f64)>),
    ) {
        let world = World {
            scene,
            dynamic,
            own,
            octree: &self.octree,
            statics: &self.statics,
            shapes: &self.shapes,
        };
        crate::collision::fan::cast_fan(&world, &mut self.meshes, rays, &mut self.fan, put);
    }

    /// Run one tick for one vehicle: `current` is its new sample, `previous` the one before
    /// (if any), `dynamic` the moving obstacles at both times. Events are appended to `events`.
    /// State is kept per (vehicle, component) and reset when `vehicle.generation` changes.
    pub fn step(
        &mut self,
        scene: &Scene,
        vehicle: VehicleKey,
        previous: Option<&TrackSample>,
        current: &TrackSample,
        dynamic: &MovingBodies,
        events: &mut Vec<Event>,
    ) -> TickReport {
        let first_event = events.len();
        self.meshes.next_tick();
        let report = match self.config.mode {
            Mode::None => TickReport::default(),
            Mode::Reference => {
                let started = Instant::now();
                let interval = Interval {
                    scene,
                    cfg: &self.config,
                    key: vehicle,
                    previous,
                    current,
                    dynamic: dynamic.as_slice(),
                };
                let reference = self.reference.get_or_insert_with(Reference::default);
                reference.step(&interval, events);
                self.totals.reference_capped = reference.capped;
                TickReport {
                    swept: previous.is_some(),
                    contact_ns: stages::elapsed_ns(started),
                    ..TickReport::default()
                }
            }
            _ => self.step_vehicle(scene, vehicle, previous, current, dynamic, events),
        };
        let budget = self.meshes.budget();
        self.meshes.evict_to(budget);
        self.count(&report, &events[first_event..]);
        report
    }

    fn count(&mut self, report: &TickReport, events: &[Event]) {
        let t = &mut self.totals;
        t.ticks += 1;
        t.sensing_frames += u64::from(report.sensed);
        for e in events {
            match e.kind {
                EventKind::Collision { .. } => t.collisions += 1,
                EventKind::ColliderSwap { .. } => t.swaps += 1,
                EventKind::NearMiss { .. } => t.near_misses += 1,
                EventKind::TelemetryGap { .. } => t.telemetry_gaps += 1,
                // Well clear, separation and slots are judged by the session (daa), not here.
                EventKind::WellClearLost { .. }
                | EventKind::WellClearRegained { .. }
                | EventKind::SeparationLost { .. }
                | EventKind::SeparationRegained { .. }
                | EventKind::LeftSlot { .. }
                | EventKind::BackInSlot { .. } => {}
            }
        }
        t.active_box_sum += report.active_box as u64;
        t.active_mesh_sum += report.active_mesh as u64;
        t.active_triangles_sum += report.active_triangles as u64;
        t.active_box_max = t.active_box_max.max(report.active_box);
        t.active_mesh_max = t.active_mesh_max.max(report.active_mesh);
        t.active_triangles_max = t.active_triangles_max.max(report.active_triangles);
        t.narrow_tests += report.narrow_tests as u64;
        t.ray_tests += report.ray_tests as u64;
        if let Some(c) = report.terrain_clearance_m.filter(|_| !report.implausible) {
            t.terrain_clearance_min_m = Some(t.terrain_clearance_min_m.map_or(c, |m| m.min(c)));
        }
        t.implausible_samples += u64::from(report.implausible);
    }

    /// Report near misses still open (call at the end of a run).
    pub fn finish(&mut self, events: &mut Vec<Event>) {
        for (&(vehicle, compid), state) in self.vehicles.iter_mut() {
            let before = events.len();
            let event = |kind: EventKind| Event {
                t: 0.0,
                time_boot_ms: 0,
                vehicle,
                compid,
                kind,
            };
            state.episodes.close(&event, events);
            self.totals.near_misses += (events.len() - before) as u64;
        }
    }

    /// One tick of the mode's stages for one vehicle: its state (reset on a new generation),
    /// the gap and implausible-sample rules, the sensing frame if due, the contacts and the
    /// episodes.
    fn step_vehicle(
        &mut self,
        scene: &Scene,
        key: VehicleKey,
        previous: Option<&TrackSample>,
        current: &TrackSample,
        dynamic: &MovingBodies,
        events: &mut Vec<Event>,
    ) -> TickReport {
        let cfg = self.config;
        let event = |kind: EventKind| Event {
            t: current.t_s,
            time_boot_ms: current.time_boot_ms,
            vehicle: key.vehicle,
            compid: key.component_id,
            kind,
        };
        let mut report = TickReport::default();
        let state =
            stages::vehicle_state(&mut self.vehicles, &mut self.totals, key, &event, events);
        let previous = sweepable_from(previous, current, cfg.max_gap_s, &event, events);
        // Terrain under the vehicle; a sample far below it is implausible, and is not swept
        // from.
        if self.has_terrain {
            report.terrain_clearance_m =
                stages::terrain_clearance(&self.statics, scene, current.position_enu_m);
        }
        report.implausible = report
            .terrain_clearance_m
            .is_some_and(|c| c < -cfg.max_below_terrain_m);
        let previous = if std::mem::replace(&mut state.last_implausible, report.implausible) {
            None
        } else {
            previous
        };
        if report.implausible {
            return report;
        }
        let world = World {
            scene,
            dynamic,
            own: key.source(),
            octree: &self.octree,
            statics: &self.statics,
            shapes: &self.shapes,
        };
        let tick = stages::Tick {
            world: &world,
            cfg: &cfg,
            previous,
            current,
            // Vehicle numbers beyond the MAVLink range (the bench's fleets) use the default
            // model.
            geometry_index: scene.vehicle_model(u8::try_from(key.vehicle).unwrap_or(0)),
            event: &event,
        };
        // The sensing layer: every sample in `paper`, at the sensor rate in `exact`.
        if let Some(rules) = sensing_rules(cfg.mode) {
            let frame = tick.frame(rules);
            stages::sense(
                &mut self.sensing,
                &mut self.meshes,
                &frame,
                &mut state.sensing,
                events,
                &mut report,
            );
        }
        stages::collide(
            &mut self.contacts,
            &mut self.meshes,
            &tick,
            state,
            events,
            &mut report,
        );
        self.count_every_collider(&tick, &mut report);
        report
    }

    /// In `box` and `mesh` every obstacle is a collider: count them (and, in `mesh`, their
    /// triangles and the vehicle's).
    fn count_every_collider(&self, tick: &stages::Tick<'_>, report: &mut TickReport) {
        let (scene, dynamic) = (tick.world.scene, tick.world.dynamic);
        match tick.cfg.mode {
            Mode::Box => report.active_box = scene.obstacles.len() + dynamic.len(),
            Mode::Mesh => {
                report.active_mesh = scene.obstacles.len() + dynamic.len();
                report.active_triangles = self.static_triangles
                    + dynamic
                        .as_slice()
                        .iter()
                        .map(|d| scene.geometries[d.geometry_index].triangle_count())
                        .sum::<usize>()
                    + scene.geometries[tick.geometry_index].triangle_count();
            }
            _ => {}
        }
    }
}

/// The rules the sensing layer follows in `mode`, if it runs there.
fn sensing_rules(mode: Mode) -> Option<Rules> {
    match mode {
        Mode::Paper => Some(Rules::Paper),
        Mode::Exact => Some(Rules::Sensor),
        _ => None,
    }
}
