//! The per-tick pipeline: for one vehicle and one telemetry sample, decide which obstacles have
//! which collider, cast the six rays, rate threats, test contacts, and report events.
//!
//! Like rapier's `CollisionPipeline`, it owns only caches and scratch buffers; the scene and the
//! vehicle's samples come in as arguments. After warm-up a tick does not allocate, except when
//! a mesh collider is built for the first time.

use glam::{DQuat, DVec3, Vec3};
use parry3d::shape::{Cuboid, Shape, TriMesh};
use std::sync::Arc;

use crate::collision::contact::{self, Placed, SweepHit};
use crate::collision::events::{Event, EventKind};
use crate::collision::meshes::MeshCache;
use crate::collision::octree::{NodeId, Octree, OctreeConfig, OctreeWorkspace};
use crate::collision::threat::{AhpWeights, PAPER_MATRIX};
use crate::collision::ColliderKind;
use crate::scene::geometry::Geometry;
use crate::scene::{Aabb64, Kind, Scene};
use crate::world::TrackSample;

/// How colliders are chosen and contacts tested.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, serde::Serialize, clap::ValueEnum)]
#[serde(rename_all = "snake_case")]
pub enum Mode {
    /// No colliders at all.
    None,
    /// Every obstacle and the vehicle a box; checks at samples only.
    Box,
    /// Every obstacle and the vehicle a mesh (all built at start-up); checks at samples only.
    Mesh,
    /// The paper as written: current node only, six rays, the beta rule, vehicle mesh,
    /// checks at samples only.
    Paper,
    /// savsim's algorithm: the paper plus a look-ahead region, hold times, mesh confirmation of
    /// every box contact, and sweeps between samples. The default.
    Adaptive,
    /// Ground truth: every obstacle and the vehicle a mesh, swept between samples.
    Oracle,
}

impl Mode {
    /// Every mode, cheapest first.
    pub const ALL: [Mode; 6] = [
        Mode::None,
        Mode::Box,
        Mode::Mesh,
        Mode::Paper,
        Mode::Adaptive,
        Mode::Oracle,
    ];

    /// The name used on the command line and in reports.
    pub fn name(self) -> &'static str {
        match self {
            Mode::None => "none",
            Mode::Box => "box",
            Mode::Mesh => "mesh",
            Mode::Paper => "paper",
            Mode::Adaptive => "adaptive",
            Mode::Oracle => "oracle",
        }
    }
}

/// Collision settings. Every default and unit is in the field's doc.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CollisionConfig {
    /// How colliders are chosen. Default `adaptive`.
    pub mode: Mode,
    /// Length of each of the six rays, metres. Default 300 (the paper's mesh distance).
    pub ray_length_m: f64,
    /// Look-ahead time for the activation box around the vehicle, seconds. Default 3.
    pub look_ahead_s: f64,
    /// Beta above which a seen obstacle gets a mesh. Default 50 (paper).
    pub mesh_beta: f64,
    /// ... if it is closer than this, metres. Default 300 (paper).
    pub mesh_within_m: f64,
    /// A mesh farther than this turns back into a box, metres. Default 800 (paper).
    pub box_beyond_m: f64,
    /// A collider keeps its state at least this long before it is downgraded, seconds.
    /// Default 2 (ArduPilot's AP_Avoidance never lowers a threat faster). 0 in `paper` mode.
    pub hold_s: f64,
    /// Closer than this without contact is a near miss, metres. Default 10.
    pub near_miss_m: f64,
    /// A telemetry gap longer than this is reported and not swept, seconds. Default 1.
    pub max_gap_s: f64,
    /// A sample more than this far below the terrain surface is implausible (an altitude
    /// reference not yet set, e.g. before the autopilot's EKF has an origin): it is counted
    /// and skipped, and no sweep starts or ends at it. Metres. Default 50.
    pub max_below_terrain_m: f64,
    /// AHP weights for beta. Default: the paper's Table 3.
    pub ahp: AhpWeights,
    /// Octree shape.
    pub octree: OctreeConfig,
}

impl Default for CollisionConfig {
    fn default() -> Self {
        Self {
            mode: Mode::Adaptive,
            ray_length_m: 300.0,
            look_ahead_s: 3.0,
            mesh_beta: 50.0,
            mesh_within_m: 300.0,
            box_beyond_m: 800.0,
            hold_s: 2.0,
            near_miss_m: 10.0,
            max_gap_s: 1.0,
            max_below_terrain_m: 50.0,
            ahp: AhpWeights::from_matrix(PAPER_MATRIX).expect("the paper's matrix is valid"),
            octree: OctreeConfig::default(),
        }
    }
}

/// An obstacle: static (index into `Scene::obstacles`) or dynamic (index into the tick's
/// dynamic bodies).
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum ObstacleRef {
    /// A static obstacle.
    Static(u32),
    /// A dynamic body of this tick.
    Dynamic(u32),
}

/// A rigid pose in the scene.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BodyPose {
    /// Reference point, scene ENU metres.
    pub position_enu_m: DVec3,
    /// Rotation from body FRD to ENU.
    pub enu_from_body: DQuat,
}

impl BodyPose {
    /// The pose of a track sample.
    pub fn of(sample: &TrackSample) -> Self {
        Self {
            position_enu_m: sample.position_enu_m,
            enu_from_body: sample.attitude.enu_from_frd,
        }
    }
}

/// A moving obstacle at this tick (another vehicle, ADS-B traffic, a scripted track).
#[derive(Debug, Clone, PartialEq)]
pub struct DynamicBody {
    /// Id for events (`vehicle:2`, `icao:4840D6`, or the scene's id); shared, so that filling
    /// a tick's moving obstacles does not allocate.
    pub id: Arc<str>,
    /// Kind (threat class).
    pub kind: Kind,
    /// Threat T.
    pub threat: f64,
    /// Its model, an index into `Scene::geometries`.
    pub geometry_index: usize,
    /// Pose at the previous tick of the vehicle being checked.
    pub previous: BodyPose,
    /// Pose now.
    pub current: BodyPose,
    /// Speed, m/s.
    pub speed_mps: f64,
}

/// The nearest hit of one of the six rays.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RayHit {
    /// What it hit.
    pub obstacle: ObstacleRef,
    /// How far, metres.
    pub distance_m: f64,
    /// Where, scene ENU metres.
    pub point_enu_m: DVec3,
}

/// The six body axes, in FRD: forward, back, right, left, down, up.
pub const RAY_AXES_FRD: [Vec3; 6] = [
    Vec3::X,
    Vec3::NEG_X,
    Vec3::Y,
    Vec3::NEG_Y,
    Vec3::Z,
    Vec3::NEG_Z,
];

#[derive(Debug, Clone, Copy)]
struct Active {
    obstacle: ObstacleRef,
    collider: ColliderKind,
    since_t_s: f64,
    beta: f64,
}

/// One vehicle's collision state across ticks.
#[derive(Debug, Clone, Default)]
pub struct VehicleCollision {
    node: Option<NodeId>,
    /// The region the static obstacles were last queried for.
    queried: Option<Aabb64>,
    active: Vec<Active>,
    touching: Vec<ObstacleRef>,
    /// Obstacles within the near-miss band: closest distance, when, and whether touched.
    near: Vec<(ObstacleRef, f64, f64, bool)>,
    /// The six rays' nearest hits at the last tick (FRD order of [`RAY_AXES_FRD`]).
    pub rays: [Option<RayHit>; 6],
    /// The last sample was implausible: do not sweep from it.
    last_implausible: bool,
}

impl VehicleCollision {
    const EMPTY: VehicleCollision = VehicleCollision {
        node: None,
        queried: None,
        active: Vec::new(),
        touching: Vec::new(),
        near: Vec::new(),
        rays: [None; 6],
        last_implausible: false,
    };

    /// The octree leaf the vehicle was in at the last tick.
    pub fn node(&self) -> Option<NodeId> {
        self.node
    }

    /// Obstacles with a collider and which one.
    pub fn colliders(&self) -> impl Iterator<Item = (ObstacleRef, ColliderKind, f64)> + '_ {
        self.active.iter().map(|a| (a.obstacle, a.collider, a.beta))
    }
}

/// What one tick did.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct TickReport {
    /// Obstacles with a box collider.
    pub active_box: usize,
    /// Obstacles with a mesh collider.
    pub active_mesh: usize,
    /// Triangles in active mesh colliders (the vehicle's included when it is a mesh).
    pub active_triangles: usize,
    /// Exact narrow-phase tests run (intersection, distance, sweep, ray).
    pub narrow_tests: usize,
    /// True when the contacts were swept from the previous sample.
    pub swept: bool,
    /// Height of the vehicle's reference point above the terrain under it, metres (None
    /// where there is no terrain).
    pub terrain_clearance_m: Option<f64>,
    /// True when the sample was skipped as implausible (far below the terrain).
    pub implausible: bool,
}

/// Counters over a whole run.
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize)]
pub struct PipelineTotals {
    /// Ticks run.
    pub ticks: u64,
    /// Collision events.
    pub collisions: u64,
    /// Collider swap events.
    pub swaps: u64,
    /// Near-miss events.
    pub near_misses: u64,
    /// Telemetry gaps.
    pub telemetry_gaps: u64,
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
    /// Narrow-phase tests run.
    pub narrow_tests: u64,
    /// Lowest terrain clearance seen over the run, metres.
    pub terrain_clearance_min_m: Option<f64>,
    /// Samples skipped as implausible (far below the terrain).
    pub implausible_samples: u64,
}

enum Holder {
    Box(Cuboid),
    Mesh(Arc<TriMesh>),
}

/// A shape with its placement, owning (or sharing) the shape.
struct Body {
    holder: Holder,
    position_enu_m: DVec3,
    rotation: DQuat,
    pivot_local_m: Vec3,
}

impl Body {
    fn new(
        geometry: &Geometry,
        geometry_index: usize,
        meshes: &mut MeshCache,
        kind: ColliderKind,
        position_enu_m: DVec3,
        rotation: DQuat,
    ) -> Body {
        if kind == ColliderKind::Mesh {
            Body {
                holder: Holder::Mesh(meshes.get(geometry_index, geometry)),
                position_enu_m,
                rotation,
                pivot_local_m: Vec3::ZERO,
            }
        } else {
            let (cuboid, centre) = geometry.box_collider();
            Body {
                holder: Holder::Box(cuboid),
                position_enu_m: position_enu_m + rotation * centre.as_dvec3(),
                rotation,
                pivot_local_m: -centre,
            }
        }
    }

    fn placed(&self) -> Placed<'_> {
        Placed {
            shape: match &self.holder {
                Holder::Box(c) => c as &dyn Shape,
                Holder::Mesh(m) => m.as_ref() as &dyn Shape,
            },
            position_enu_m: self.position_enu_m,
            enu_from_shape: self.rotation,
            pivot_local_m: self.pivot_local_m,
        }
    }

    /// The same body moved so its reference point is at `position` with `rotation`.
    fn at(&self, reference_enu_m: DVec3, rotation: DQuat) -> Placed<'_> {
        let offset = -(rotation * self.pivot_local_m.as_dvec3());
        self.placed().moved(reference_enu_m + offset, rotation)
    }
}

/// Everything the pipeline needs to know about an obstacle at this tick.
struct ObstacleView<'s> {
    geometry: &'s Geometry,
    geometry_index: usize,
    kind: Kind,
    threat: f64,
    speed_mps: f64,
    previous: BodyPose,
    current: BodyPose,
    aabb_enu_m: Aabb64,
    id: &'s str,
}

impl ObstacleView<'_> {
    /// The obstacle's collider of `kind`, placed where it is now.
    fn body(&self, meshes: &mut MeshCache, kind: ColliderKind) -> Body {
        Body::new(
            self.geometry,
            self.geometry_index,
            meshes,
            kind,
            self.current.position_enu_m,
            self.current.enu_from_body,
        )
    }
}

fn view<'s>(scene: &'s Scene, dynamic: &'s [DynamicBody], o: ObstacleRef) -> ObstacleView<'s> {
    match o {
        ObstacleRef::Static(i) => {
            let s = &scene.obstacles[i as usize];
            let pose = BodyPose {
                position_enu_m: s.placement.position_enu_m,
                enu_from_body: s.placement.enu_from_local,
            };
            ObstacleView {
                geometry: &s.geometry,
                geometry_index: s.geometry_index,
                kind: s.kind,
                threat: s.threat,
                speed_mps: 0.0,
                previous: pose,
                current: pose,
                aabb_enu_m: s.aabb_enu_m,
                id: &s.id,
            }
        }
        ObstacleRef::Dynamic(i) => {
            let d = &dynamic[i as usize];
            let g = &scene.geometries[d.geometry_index];
            let aabb = crate::scene::Placement {
                position_enu_m: d.current.position_enu_m,
                enu_from_local: d.current.enu_from_body,
            }
            .enu_aabb(&g.local_aabb);
            ObstacleView {
                geometry: g,
                geometry_index: d.geometry_index,
                kind: d.kind,
                threat: d.threat,
                speed_mps: d.speed_mps,
                previous: d.previous,
                current: d.current,
                aabb_enu_m: aabb,
                id: &d.id,
            }
        }
    }
}

/// The outcome of testing one obstacle for contact.
#[derive(Debug, Clone, Copy)]
struct Touch {
    point_enu_m: DVec3,
    normal_enu: DVec3,
    fraction: f64,
    swept: bool,
    /// Still in contact at the sample (a sweep can touch and leave within the interval).
    holds_now: bool,
}

/// The collision pipeline for a scene.
#[derive(Debug)]
pub struct Pipeline {
    /// Settings.
    pub config: CollisionConfig,
    /// The static scene's octree.
    pub octree: Octree,
    /// Built mesh colliders.
    pub meshes: MeshCache,
    /// Per-vehicle state, by vehicle number (the MAVLink system id in a session).
    vehicles: Vec<VehicleCollision>,
    /// Totals over the run.
    pub totals: PipelineTotals,
    ws: OctreeWorkspace,
    desired: Vec<ObstacleRef>,
    near: Vec<ObstacleRef>,
    merged: Vec<Active>,
    touching_now: Vec<(ObstacleRef, Touch)>,
    static_triangles: usize,
    has_terrain: bool,
}

impl Pipeline {
    /// A pipeline for `scene`: builds the octree (once) and the mesh cache, empty except in
    /// `mesh` mode, where every obstacle has its mesh from the start (what "every obstacle a
    /// mesh" costs in start-up time and memory).
    pub fn new(scene: &Scene, config: CollisionConfig) -> Self {
        let boxes: Vec<Aabb64> = scene.obstacles.iter().map(|o| o.aabb_enu_m).collect();
        let mut meshes = MeshCache::new(scene.geometries.len());
        if config.mode == Mode::Mesh {
            for o in &scene.obstacles {
                meshes.get(o.geometry_index, &o.geometry);
            }
        }
        Self {
            config,
            octree: Octree::build(&boxes, config.octree),
            meshes,
            vehicles: Vec::new(),
            totals: PipelineTotals::default(),
            ws: OctreeWorkspace::default(),
            desired: Vec::new(),
            near: Vec::new(),
            merged: Vec::new(),
            touching_now: Vec::new(),
            static_triangles: scene
                .obstacles
                .iter()
                .map(|o| o.geometry.triangle_count())
                .sum(),
            has_terrain: scene.obstacles.iter().any(|o| o.geometry.is_terrain()),
        }
    }

    /// The collision state of vehicle `vehicle` (empty if it never ticked).
    pub fn vehicle(&self, vehicle: u16) -> &VehicleCollision {
        static EMPTY: VehicleCollision = VehicleCollision::EMPTY;
        self.vehicles.get(usize::from(vehicle)).unwrap_or(&EMPTY)
    }

    /// Run one tick for one vehicle: `current` is its new sample, `previous` the one before
    /// (if any), `dynamic` the moving obstacles at both times. Events are appended to `events`.
    /// `vehicle` numbers the vehicle's state (a session passes the MAVLink system id; the
    /// state is created on the vehicle's first tick).
    pub fn step(
        &mut self,
        scene: &Scene,
        vehicle: u16,
        previous: Option<&TrackSample>,
        current: &TrackSample,
        dynamic: &[DynamicBody],
        events: &mut Vec<Event>,
    ) -> TickReport {
        let slot = usize::from(vehicle);
        if slot >= self.vehicles.len() {
            self.vehicles
                .resize_with(slot + 1, VehicleCollision::default);
        }
        let mut state = std::mem::take(&mut self.vehicles[slot]);
        let first_event = events.len();
        let report = self.step_vehicle(
            scene, &mut state, vehicle, previous, current, dynamic, events,
        );
        self.vehicles[slot] = state;
        let t = &mut self.totals;
        t.ticks += 1;
        for e in &events[first_event..] {
            match e.kind {
                EventKind::Collision { .. } => t.collisions += 1,
                EventKind::ColliderSwap { .. } => t.swaps += 1,
                EventKind::NearMiss { .. } => t.near_misses += 1,
                EventKind::TelemetryGap { .. } => t.telemetry_gaps += 1,
            }
        }
        t.active_box_sum += report.active_box as u64;
        t.active_mesh_sum += report.active_mesh as u64;
        t.active_triangles_sum += report.active_triangles as u64;
        t.active_box_max = t.active_box_max.max(report.active_box);
        t.active_mesh_max = t.active_mesh_max.max(report.active_mesh);
        t.active_triangles_max = t.active_triangles_max.max(report.active_triangles);
        t.narrow_tests += report.narrow_tests as u64;
        if let Some(c) = report.terrain_clearance_m.filter(|_| !report.implausible) {
            t.terrain_clearance_min_m = Some(t.terrain_clearance_min_m.map_or(c, |m| m.min(c)));
        }
        t.implausible_samples += u64::from(report.implausible);
        report
    }

    /// Report near misses still open (call at the end of a run).
    pub fn finish(&mut self, events: &mut Vec<Event>, scene: &Scene, dynamic: &[DynamicBody]) {
        for (vehicle, state) in self.vehicles.iter_mut().enumerate() {
            for (o, closest_m, closest_t, touched) in state.near.drain(..) {
                if touched {
                    continue;
                }
                let id = match o {
                    ObstacleRef::Static(i) => scene.obstacles[i as usize].id.clone(),
                    ObstacleRef::Dynamic(i) => dynamic
                        .get(i as usize)
                        .map_or_else(|| format!("dynamic#{i}"), |d| d.id.to_string()),
                };
                events.push(Event {
                    t: closest_t,
                    time_boot_ms: 0,
                    vehicle: vehicle as u16,
                    kind: EventKind::NearMiss {
                        obstacle: id,
                        closest_m,
                        closest_t,
                    },
                });
                self.totals.near_misses += 1;
            }
        }
    }

    #[allow(clippy::too_many_arguments)]
    fn step_vehicle(
        &mut self,
        scene: &Scene,
        state: &mut VehicleCollision,
        vehicle: u16,
        previous: Option<&TrackSample>,
        current: &TrackSample,
        dynamic: &[DynamicBody],
        events: &mut Vec<Event>,
    ) -> TickReport {
        let cfg = self.config;
        let t = current.t_s;
        let event = |kind: EventKind| Event {
            t,
            time_boot_ms: current.time_boot_ms,
            vehicle,
            kind,
        };
        let mut report = TickReport::default();
        if cfg.mode == Mode::None {
            return report;
        }
        // A gap: report it and do not sweep across it.
        let previous = match previous {
            Some(p) if t - p.t_s > cfg.max_gap_s => {
                events.push(event(EventKind::TelemetryGap {
                    gap_s: t - p.t_s,
                    moved_m: (current.position_enu_m - p.position_enu_m).length(),
                }));
                None
            }
            Some(p) if t > p.t_s => Some(p),
            _ => None,
        };
        // Terrain under the vehicle; a sample far below it is implausible.
        if self.has_terrain {
            report.terrain_clearance_m =
                terrain_clearance(&self.octree, &mut self.ws, scene, current.position_enu_m);
        }
        let implausible = report
            .terrain_clearance_m
            .is_some_and(|c| c < -cfg.max_below_terrain_m);
        let previous = if std::mem::replace(&mut state.last_implausible, implausible) {
            None
        } else {
            previous
        };
        if implausible {
            report.implausible = true;
            return report;
        }
        report.swept = previous.is_some() && matches!(cfg.mode, Mode::Adaptive | Mode::Oracle);

        // Vehicle numbers beyond the MAVLink range (the bench's fleets) use the default model.
        let vehicle_index = scene.vehicle_model(u8::try_from(vehicle).unwrap_or(0));
        let vehicle_geometry = &scene.geometries[vehicle_index];
        let radius_m = f64::from(
            vehicle_geometry
                .local_aabb
                .mins
                .abs()
                .max(vehicle_geometry.local_aabb.maxs.abs())
                .length(),
        );
        let position = current.position_enu_m;
        let start = previous.map_or(position, |p| p.position_enu_m);
        let vehicle_box_now = Aabb64::around(position, DVec3::splat(radius_m));
        let swept_box = vehicle_box_now.union(Aabb64::around(start, DVec3::splat(radius_m)));
        // Obstacles this interval could touch or come within the near-miss band of.
        let band = cfg.near_miss_m;
        let near_region = swept_box.inflated(band + radius_m);
        let vehicle_collider = match cfg.mode {
            Mode::Box => ColliderKind::Box,
            _ => ColliderKind::Mesh,
        };
        let vehicle_body = Body::new(
            vehicle_geometry,
            vehicle_index,
            &mut self.meshes,
            vehicle_collider,
            position,
            current.attitude.enu_from_frd,
        );
        let vehicle_box_body = Body::new(
            vehicle_geometry,
            vehicle_index,
            &mut self.meshes,
            ColliderKind::Box,
            position,
            current.attitude.enu_from_frd,
        );
        let vehicle_pose_now = BodyPose::of(current);
        let vehicle_pose_before = previous.map(BodyPose::of);

        // 1-2. Which obstacles have colliders.
        self.desired.clear();
        match cfg.mode {
            Mode::Box | Mode::Mesh | Mode::Oracle => {
                let query = if cfg.mode == Mode::Oracle {
                    swept_box
                } else {
                    vehicle_box_now
                }
                .inflated(band);
                let desired = &mut self.desired;
                self.octree.query_aabb(&query, &mut self.ws, |i| {
                    desired.push(ObstacleRef::Static(i))
                });
                for (i, _) in dynamic.iter().enumerate() {
                    let o = ObstacleRef::Dynamic(i as u32);
                    let v = view(scene, dynamic, o);
                    let reach = v
                        .aabb_enu_m
                        .union(Aabb64::around(v.previous.position_enu_m, DVec3::ZERO));
                    if reach
                        .inflated(band + v.aabb_enu_m.max.distance(v.aabb_enu_m.min))
                        .intersects(&query)
                    {
                        self.desired.push(o);
                    }
                }
                self.desired.sort_unstable();
                self.near.clear();
                self.near.extend_from_slice(&self.desired);
                state.active.clear();
                let kind = if cfg.mode == Mode::Box {
                    ColliderKind::Box
                } else {
                    ColliderKind::Mesh
                };
                state
                    .active
                    .extend(self.desired.iter().map(|&obstacle| Active {
                        obstacle,
                        collider: kind,
                        since_t_s: t,
                        beta: 0.0,
                    }));
                let all = scene.obstacles.len() + dynamic.len();
                if kind == ColliderKind::Box {
                    report.active_box = all;
                } else {
                    report.active_mesh = all;
                    report.active_triangles = self.static_triangles
                        + dynamic
                            .iter()
                            .map(|d| scene.geometries[d.geometry_index].triangle_count())
                            .sum::<usize>()
                        + vehicle_geometry.triangle_count();
                }
            }
            Mode::Paper | Mode::Adaptive => {
                let node = self.octree.leaf_at(position);
                // The region whose obstacles must have colliders: the node (paper), plus the
                // look-ahead box and this interval's path (adaptive).
                let required = if cfg.mode == Mode::Adaptive {
                    let speed = current.velocity_enu_mps.length();
                    let reach = cfg.ray_length_m.max(speed * cfg.look_ahead_s) + radius_m;
                    Aabb64::around(position, DVec3::splat(reach)).union(swept_box.inflated(band))
                } else {
                    node.map_or(vehicle_box_now, |n| self.octree.node_aabb(n))
                };
                // Static obstacles are queried with a margin and the answer reused while the
                // required region stays inside it (and the node is the same): most ticks skip
                // the octree query and the merge. Moving obstacles are re-checked every tick.
                let any_dynamic = !dynamic.is_empty()
                    || state
                        .active
                        .iter()
                        .any(|a| matches!(a.obstacle, ObstacleRef::Dynamic(_)));
                let hold = if cfg.mode == Mode::Paper {
                    0.0
                } else {
                    cfg.hold_s
                };
                let reuse_static = state.node == node
                    && state
                        .queried
                        .is_some_and(|q| q.contains(required.min) && q.contains(required.max));
                if !reuse_static || any_dynamic {
                    let region = match state.queried {
                        Some(q) if reuse_static => q,
                        _ if cfg.mode == Mode::Adaptive => {
                            let margin = (0.25 * (required.max.x - required.min.x)).max(10.0);
                            required.inflated(margin)
                        }
                        _ => required,
                    };
                    state.queried = Some(region);
                    let desired = &mut self.desired;
                    if reuse_static {
                        // The static part is the last query's answer: keep it as it is.
                        desired.extend(
                            state
                                .active
                                .iter()
                                .map(|a| a.obstacle)
                                .filter(|o| matches!(o, ObstacleRef::Static(_))),
                        );
                    } else {
                        if let Some(node) = node {
                            desired.extend(
                                self.octree
                                    .leaf_items(node)
                                    .iter()
                                    .map(|&i| ObstacleRef::Static(i)),
                            );
                        }
                        if cfg.mode == Mode::Adaptive {
                            self.octree.query_aabb(&region, &mut self.ws, |i| {
                                desired.push(ObstacleRef::Static(i))
                            });
                        }
                    }
                    for (i, d) in dynamic.iter().enumerate() {
                        let o = ObstacleRef::Dynamic(i as u32);
                        let v = view(scene, dynamic, o);
                        let lead = if cfg.mode == Mode::Adaptive {
                            d.speed_mps * cfg.look_ahead_s
                        } else {
                            0.0
                        };
                        if v.aabb_enu_m.inflated(lead).intersects(&region) {
                            desired.push(o);
                        }
                    }
                    desired.sort_unstable();
                    desired.dedup();
                    state.node = node;
                    let reason = if cfg.mode == Mode::Paper {
                        "node"
                    } else {
                        "look_ahead"
                    };
                    // Merge the active list (sorted) with the desired one.
                    self.merged.clear();
                    let (mut a, mut d) = (0, 0);
                    while a < state.active.len() || d < self.desired.len() {
                        let next_active = state.active.get(a).map(|x| x.obstacle);
                        let next_desired = self.desired.get(d).copied();
                        match (next_active, next_desired) {
                            (Some(x), Some(y)) if x == y => {
                                self.merged.push(state.active[a]);
                                a += 1;
                                d += 1;
                            }
                            (Some(x), y) if y.is_none() || y.is_some_and(|y| x < y) => {
                                let act = state.active[a];
                                a += 1;
                                let keep =
                                    act.collider == ColliderKind::Mesh && t - act.since_t_s < hold;
                                if keep {
                                    self.merged.push(act);
                                } else {
                                    let v = view(scene, dynamic, act.obstacle);
                                    events.push(event(EventKind::ColliderSwap {
                                        obstacle: v.id.to_owned(),
                                        from: act.collider,
                                        to: ColliderKind::None,
                                        beta: act.beta,
                                        distance_m: v.aabb_enu_m.distance_to(position),
                                        reason: "left",
                                    }));
                                }
                            }
                            (_, Some(y)) => {
                                let v = view(scene, dynamic, y);
                                events.push(event(EventKind::ColliderSwap {
                                    obstacle: v.id.to_owned(),
                                    from: ColliderKind::None,
                                    to: ColliderKind::Box,
                                    beta: 0.0,
                                    distance_m: v.aabb_enu_m.distance_to(position),
                                    reason,
                                }));
                                self.merged.push(Active {
                                    obstacle: y,
                                    collider: ColliderKind::Box,
                                    since_t_s: t,
                                    beta: 0.0,
                                });
                                d += 1;
                            }
                            _ => break,
                        }
                    }
                    std::mem::swap(&mut state.active, &mut self.merged);
                }

                // 3. Six rays along the body axes against the active colliders: static ones
                // front to back through the octree (stopping at the nearest hit), moving ones
                // by a scan.
                let forward = current.attitude.forward_enu();
                for (k, axis) in RAY_AXES_FRD.iter().enumerate() {
                    let dir = current.attitude.enu_from_frd * axis.as_dvec3();
                    let meshes = &mut self.meshes;
                    let active = &state.active;
                    let mut tests = 0;
                    // `bounds_checked`: the caller already knows the ray meets the obstacle's
                    // bounds (the octree walk tests them).
                    let mut ray_test = |o: ObstacleRef, limit: f64, bounds_checked: bool| {
                        let act = find_active(active, o)?;
                        let v = view(scene, dynamic, o);
                        if !bounds_checked && !v.aabb_enu_m.ray_hits(position, dir, limit) {
                            return None;
                        }
                        tests += 1;
                        if act.collider == ColliderKind::Box {
                            // A box collider is an oriented box: a slab test in its frame.
                            let (cuboid, centre) = v.geometry.box_collider();
                            let to_local = v.current.enu_from_body.inverse();
                            let origin = to_local * (position - v.current.position_enu_m)
                                - centre.as_dvec3();
                            let half = cuboid.half_extents.as_dvec3();
                            return Aabb64::new(-half, half).ray_entry(
                                origin,
                                to_local * dir,
                                limit,
                            );
                        }
                        let body = v.body(meshes, act.collider);
                        contact::ray_distance_m(position, dir, limit, &body.placed())
                    };
                    // The obstacle this ray hit last tick usually still is the nearest: its
                    // distance bounds the octree walk (same answer, far fewer nodes).
                    let seed = state.rays[k].and_then(|h| {
                        Some((h.obstacle, ray_test(h.obstacle, cfg.ray_length_m, false)?))
                    });
                    let seed_static = seed.filter(|(o, _)| matches!(o, ObstacleRef::Static(_)));
                    let mut best = self
                        .octree
                        .cast_ray(
                            position,
                            dir,
                            seed_static.map_or(cfg.ray_length_m, |s| s.1),
                            &mut self.ws,
                            |i, limit| ray_test(ObstacleRef::Static(i), limit, true),
                        )
                        .map(|(i, d)| (ObstacleRef::Static(i), d))
                        .or(seed_static);
                    for a in active
                        .iter()
                        .filter(|a| matches!(a.obstacle, ObstacleRef::Dynamic(_)))
                    {
                        let limit = best.map_or(cfg.ray_length_m, |b| b.1);
                        if let Some(d) = ray_test(a.obstacle, limit, false).filter(|&d| d < limit) {
                            best = Some((a.obstacle, d));
                        }
                    }
                    report.narrow_tests += tests;
                    state.rays[k] = best.map(|(obstacle, d)| RayHit {
                        obstacle,
                        distance_m: d,
                        point_enu_m: position + dir * d,
                    });
                }

                // 4-5. Threat of what the rays see, and the box <-> mesh rule.
                for k in 0..6 {
                    let Some(hit) = state.rays[k] else { continue };
                    let Some(act) = state.active.iter_mut().find(|a| a.obstacle == hit.obstacle)
                    else {
                        continue;
                    };
                    let v = view(scene, dynamic, hit.obstacle);
                    let to_hit = hit.point_enu_m - position;
                    let angle_deg = forward.angle_between(to_hit).to_degrees();
                    let beta = cfg.ahp.beta(v.threat, v.speed_mps, angle_deg);
                    act.beta = act.beta.max(beta);
                    if act.collider == ColliderKind::Box
                        && beta > cfg.mesh_beta
                        && hit.distance_m < cfg.mesh_within_m
                    {
                        swap(
                            act,
                            ColliderKind::Mesh,
                            t,
                            v.id,
                            beta,
                            hit.distance_m,
                            "threat",
                            &event,
                            events,
                        );
                    }
                }
                for act in state.active.iter_mut() {
                    if act.collider != ColliderKind::Mesh || t - act.since_t_s < hold {
                        continue;
                    }
                    let v = view(scene, dynamic, act.obstacle);
                    let distance_m = v.aabb_enu_m.distance_to(position);
                    if distance_m > cfg.box_beyond_m {
                        swap(
                            act,
                            ColliderKind::Box,
                            t,
                            v.id,
                            act.beta,
                            distance_m,
                            "far",
                            &event,
                            events,
                        );
                    }
                }
                // What the vehicle could touch or come near in this interval.
                self.near.clear();
                let near = &mut self.near;
                let active = &state.active;
                self.octree.query_aabb(&near_region, &mut self.ws, |i| {
                    let o = ObstacleRef::Static(i);
                    if find_active(active, o).is_some() {
                        near.push(o);
                    }
                });
                near.extend(active.iter().map(|a| a.obstacle).filter(|&o| {
                    matches!(o, ObstacleRef::Dynamic(_))
                        && view(scene, dynamic, o).aabb_enu_m.intersects(&near_region)
                }));
                near.sort_unstable();
                // savsim: a box that the vehicle could touch in this interval, or that is
                // within the near-miss band, is confirmed with its mesh.
                if cfg.mode == Mode::Adaptive {
                    for &o in &self.near {
                        let Ok(index) = state.active.binary_search_by_key(&o, |a| a.obstacle)
                        else {
                            continue;
                        };
                        let act = &mut state.active[index];
                        if act.collider != ColliderKind::Box {
                            continue;
                        }
                        let v = view(scene, dynamic, o);
                        let distance_m = v.aabb_enu_m.distance_to(position);
                        let obstacle_box = v.body(&mut self.meshes, ColliderKind::Box);
                        // The boxes' distance is at least the bounds' distance less the
                        // vehicle's radius: only closer ones need the exact test.
                        let near = distance_m - radius_m < band && {
                            report.narrow_tests += 1;
                            contact::distance_m(&vehicle_box_body.placed(), &obstacle_box.placed())
                                < band
                        };
                        let reason = if near {
                            Some("proximity")
                        } else if !v.aabb_enu_m.intersects(&swept_box) {
                            None
                        } else {
                            report.narrow_tests += 1;
                            let hit = match vehicle_pose_before {
                                Some(before) => sweep_bodies(
                                    &vehicle_box_body,
                                    before,
                                    vehicle_pose_now,
                                    &obstacle_box,
                                    v.previous,
                                    v.current,
                                ),
                                None => None,
                            };
                            hit.map(|_| "contact_check")
                        };
                        if let Some(reason) = reason {
                            swap(
                                act,
                                ColliderKind::Mesh,
                                t,
                                v.id,
                                act.beta,
                                distance_m,
                                reason,
                                &event,
                                events,
                            );
                        }
                    }
                }
                for act in &state.active {
                    match act.collider {
                        ColliderKind::Box => report.active_box += 1,
                        ColliderKind::Mesh => {
                            report.active_mesh += 1;
                            report.active_triangles +=
                                view(scene, dynamic, act.obstacle).geometry.triangle_count();
                        }
                        ColliderKind::None => {}
                    }
                }
                report.active_triangles += vehicle_geometry.triangle_count();
            }
            Mode::None => {}
        }

        // 6. Contacts and near misses against the active colliders.
        self.touching_now.clear();
        let contact_box = if report.swept {
            swept_box
        } else {
            vehicle_box_now
        };
        for &o in &self.near {
            let Some(act) = find_active(&state.active, o) else {
                continue;
            };
            let v = view(scene, dynamic, o);
            let near_box = v.aabb_enu_m.distance_to(position) < band + radius_m;
            if !(v.aabb_enu_m.intersects(&contact_box) || near_box) {
                continue;
            }
            // In adaptive mode only meshes count: a box that could touch became a mesh above.
            if cfg.mode == Mode::Adaptive && act.collider != ColliderKind::Mesh {
                continue;
            }
            let body = v.body(&mut self.meshes, act.collider);
            let mut touch = None;
            if v.aabb_enu_m.intersects(&contact_box)
                && !above_terrain(v.geometry, &v.current, &contact_box)
            {
                report.narrow_tests += 1;
                touch = match (report.swept, vehicle_pose_before) {
                    (true, Some(before)) => sweep_bodies(
                        &vehicle_body,
                        before,
                        vehicle_pose_now,
                        &body,
                        v.previous,
                        v.current,
                    )
                    .map(|h| Touch {
                        point_enu_m: h.point_enu_m,
                        normal_enu: h.normal_enu,
                        fraction: h.fraction,
                        swept: true,
                        holds_now: true,
                    }),
                    _ => {
                        let a = vehicle_body.placed();
                        let b = body.placed();
                        contact::intersects(&a, &b).then(|| {
                            let (point_enu_m, normal_enu) =
                                contact::contact_point(&a, &b).unwrap_or((position, DVec3::Z));
                            Touch {
                                point_enu_m,
                                normal_enu,
                                fraction: 1.0,
                                swept: false,
                                holds_now: true,
                            }
                        })
                    }
                };
                // No surfaces touch, but one solid may hold the other: the vehicle inside a
                // building or under terrain, or a small obstacle inside the vehicle's hull.
                let solid_overlap = || {
                    if act.collider != ColliderKind::Mesh {
                        return None;
                    }
                    if inside_solid(v.geometry, &v.current, position) {
                        return Some(position);
                    }
                    v.geometry
                        .a_surface_point()
                        .map(|p| v.current.position_enu_m + v.current.enu_from_body * p.as_dvec3())
                        .filter(|&p| inside_solid(vehicle_geometry, &vehicle_pose_now, p))
                };
                match &mut touch {
                    None => {
                        touch = solid_overlap().map(|point_enu_m| Touch {
                            point_enu_m,
                            normal_enu: DVec3::Z,
                            fraction: 1.0,
                            swept: false,
                            holds_now: true,
                        });
                    }
                    // A sweep touched: does the contact still hold at the sample? If not, it
                    // began and ended within the interval, and the next touch is a new one.
                    Some(hit) if hit.swept => {
                        report.narrow_tests += 1;
                        hit.holds_now = contact::intersects(&vehicle_body.placed(), &body.placed())
                            || solid_overlap().is_some();
                    }
                    Some(_) => {}
                }
            }
            match touch {
                Some(touch) => self.touching_now.push((act.obstacle, touch)),
                // Terrain is not a near miss: its closeness is the clearance (summary).
                None if near_box && !v.geometry.is_terrain() => {
                    report.narrow_tests += 1;
                    let d = contact::distance_m(&vehicle_body.placed(), &body.placed());
                    if d < band {
                        match state.near.iter_mut().find(|n| n.0 == act.obstacle) {
                            Some(n) if d < n.1 => {
                                n.1 = d;
                                n.2 = t;
                            }
                            Some(_) => {}
                            None => state.near.push((act.obstacle, d, t, false)),
                        }
                    }
                }
                None => {}
            }
        }
        // Collisions: contacts that were not there at the last tick.
        let t_before = previous.map_or(t, |p| p.t_s);
        for (o, touch) in &self.touching_now {
            if !state.touching.contains(o) {
                let v = view(scene, dynamic, *o);
                events.push(event(EventKind::Collision {
                    obstacle: v.id.to_owned(),
                    obstacle_kind: v.kind.name(),
                    point_enu_m: touch.point_enu_m.to_array(),
                    normal_enu: touch.normal_enu.to_array(),
                    time_of_impact: t_before + (t - t_before) * touch.fraction,
                    swept: touch.swept,
                }));
            }
        }
        state.touching.clear();
        state.touching.extend(
            self.touching_now
                .iter()
                .filter(|(_, touch)| touch.holds_now)
                .map(|(o, _)| *o),
        );
        // A near miss ends when the obstacle leaves the band; one that was touched meanwhile is
        // a collision, not a near miss.
        for (o, _) in &self.touching_now {
            match state.near.iter_mut().find(|n| n.0 == *o) {
                Some(n) => n.3 = true,
                None => state.near.push((*o, 0.0, t, true)),
            }
        }
        let mut i = 0;
        while i < state.near.len() {
            let (o, closest_m, closest_t, touched) = state.near[i];
            let v = view(scene, dynamic, o);
            if v.aabb_enu_m.distance_to(position) < band + radius_m {
                i += 1;
                continue;
            }
            state.near.swap_remove(i);
            if !touched {
                events.push(event(EventKind::NearMiss {
                    obstacle: v.id.to_owned(),
                    closest_m,
                    closest_t,
                }));
            }
        }
        report
    }
}

#[allow(clippy::too_many_arguments)]
fn swap(
    act: &mut Active,
    to: ColliderKind,
    t: f64,
    id: &str,
    beta: f64,
    distance_m: f64,
    reason: &'static str,
    event: &impl Fn(EventKind) -> Event,
    events: &mut Vec<Event>,
) {
    events.push(event(EventKind::ColliderSwap {
        obstacle: id.to_owned(),
        from: act.collider,
        to,
        beta,
        distance_m,
        reason,
    }));
    act.collider = to;
    act.since_t_s = t;
}

/// True when `region` lies entirely above a terrain patch's surface (a cheap, conservative
/// test that spares the exact query for a vehicle flying over terrain).
fn above_terrain(geometry: &Geometry, pose: &BodyPose, region: &Aabb64) -> bool {
    if !geometry.is_terrain() {
        return false;
    }
    // Terrain patches are placed without rotation.
    let min = region.min - pose.position_enu_m;
    let max = region.max - pose.position_enu_m;
    geometry
        .terrain_max_height_in(min.x as f32, min.y as f32, max.x as f32, max.y as f32)
        .is_some_and(|top| min.z > f64::from(top))
}

/// Height of `position` above the highest terrain patch under it (None: no terrain there).
fn terrain_clearance(
    octree: &Octree,
    ws: &mut OctreeWorkspace,
    scene: &Scene,
    position: DVec3,
) -> Option<f64> {
    let column = Aabb64::new(
        DVec3::new(position.x, position.y, f64::MIN / 4.0),
        DVec3::new(position.x, position.y, f64::MAX / 4.0),
    );
    let mut ground: Option<f64> = None;
    octree.query_aabb(&column, ws, |i| {
        if let Some(z) = scene.obstacles[i as usize].terrain_height_enu_m(position.x, position.y) {
            ground = Some(ground.map_or(z, |g| g.max(z)));
        }
    });
    ground.map(|g| position.z - g)
}

/// The active collider of `o` (the active list is sorted by obstacle).
fn find_active(active: &[Active], o: ObstacleRef) -> Option<Active> {
    active
        .binary_search_by_key(&o, |a| a.obstacle)
        .ok()
        .map(|i| active[i])
}

fn sweep_bodies(
    vehicle: &Body,
    vehicle_before: BodyPose,
    vehicle_now: BodyPose,
    obstacle: &Body,
    obstacle_before: BodyPose,
    obstacle_now: BodyPose,
) -> Option<SweepHit> {
    contact::sweep(
        &vehicle.at(vehicle_before.position_enu_m, vehicle_before.enu_from_body),
        &vehicle.at(vehicle_now.position_enu_m, vehicle_now.enu_from_body),
        &obstacle.at(
            obstacle_before.position_enu_m,
            obstacle_before.enu_from_body,
        ),
        &obstacle.at(obstacle_now.position_enu_m, obstacle_now.enu_from_body),
    )
}

/// True when `point` is inside the obstacle's solid (see [`Geometry::contains_local_point`]):
/// a vehicle inside a building or under terrain is in contact even where no surface touches it.
fn inside_solid(geometry: &Geometry, pose: &BodyPose, point: DVec3) -> bool {
    let local = pose.enu_from_body.inverse() * (point - pose.position_enu_m);
    geometry.contains_local_point(local.as_vec3())
}
