//! The ground truth (`--mode reference`): dense sub-stepping of every interval with exact
//! intersection tests. It shares no code with the contact layer: no octree (a linear scan of
//! the scene's bounds), no shape cast (steps of at most 1 cm of relative travel and 0.1 degree
//! of turn, the first contact then bisected to well under a millisecond), its own shapes (each
//! block its own parry `Cuboid`, meshes built here from the scene's triangles), its own poses
//! (linear position, spherical rotation) and its own episode rule (a collision is a step from
//! not touching to touching). Slow by design: the bench and the tests use it.
//!
//! Pure and synchronous; imports no I/O, no tokio, no rerun.

use std::collections::HashMap;
use std::sync::Arc;

use glam::{DQuat, DVec3, Vec3};
use parry3d::bounding_volume::BoundingVolume;
use parry3d::math::Pose;
use parry3d::query;
use parry3d::shape::{Cuboid, Shape, TriMesh};

use crate::collision::bodies::{self, BodyPose, DynamicBody, ObstacleRef, VehicleKey};
use crate::collision::config::CollisionConfig;
use crate::collision::episodes::sweepable_from;
use crate::collision::events::{Event, EventKind};
use crate::scene::geometry::{Geometry, GeometrySource};
use crate::scene::{Aabb64, Scene};
use crate::world::TrackSample;

/// Most travel between two sub-steps, metres.
pub const STEP_TRAVEL_M: f64 = 0.01;
/// Most turn between two sub-steps, radians (0.1 degree).
pub const STEP_TURN_RAD: f64 = 0.1 * std::f64::consts::PI / 180.0;
/// Sub-steps in one interval never exceed this (a 20 km jump at 1 cm).
const MAX_STEPS: u64 = 2_000_000;
/// Bisection rounds for the time of first contact (2^-30 of the interval).
const BISECTIONS: u32 = 30;

/// A shape as the reference sees it: solids as separate cuboids, surfaces as triangles.
enum Parts {
    /// Cuboids (centre in the body frame, half extents): solid.
    Solids(Vec<(Vec3, Cuboid)>),
    /// A triangle surface (loaded meshes, terrain).
    Surface(Box<TriMesh>),
}

fn parts_of(geometry: &Geometry) -> Parts {
    let cuboid = |min: Vec3, max: Vec3| {
        (
            (min + max) * 0.5,
            Cuboid::new(((max - min) * 0.5).max(Vec3::splat(1e-4))),
        )
    };
    match &geometry.source {
        GeometrySource::Cuboid { min, max } => Parts::Solids(vec![cuboid(*min, *max)]),
        GeometrySource::Blocks { blocks, .. } => {
            Parts::Solids(blocks.iter().map(|(a, b)| cuboid(*a, *b)).collect())
        }
        GeometrySource::Mesh { .. } | GeometrySource::Terrain(_) => {
            let (vertices, indices) = geometry.triangles();
            match TriMesh::new(vertices, indices) {
                Ok(mesh) => Parts::Surface(Box::new(mesh)),
                Err(_) => Parts::Solids(Vec::new()),
            }
        }
    }
}

impl Parts {
    fn each(&self, mut f: impl FnMut(Vec3, &dyn Shape) -> bool) -> bool {
        match self {
            Parts::Solids(cuboids) => cuboids.iter().any(|(c, s)| f(*c, s)),
            Parts::Surface(mesh) => f(Vec3::ZERO, mesh.as_ref()),
        }
    }
}

#[derive(Debug, Clone, Default)]
struct VehicleTruth {
    generation: u32,
    touching: Vec<ObstacleRef>,
    last_implausible: bool,
}

/// The reference: shapes built on demand, per-vehicle contact state.
#[derive(Clone, Default)]
pub struct Reference {
    parts: Vec<Option<Arc<Parts>>>,
    vehicles: HashMap<(u16, u8), VehicleTruth>,
    /// Sub-steps tested over the run.
    pub steps: u64,
}

impl std::fmt::Debug for Reference {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Reference")
            .field("steps", &self.steps)
            .finish_non_exhaustive()
    }
}

/// Where a body is at fraction `u` of an interval: linear position, spherical rotation.
fn pose_at(before: BodyPose, now: BodyPose, u: f64) -> BodyPose {
    BodyPose {
        position_enu_m: before.position_enu_m.lerp(now.position_enu_m, u),
        enu_from_body: before.enu_from_body.slerp(now.enu_from_body, u),
    }
}

fn turn_rad(a: DQuat, b: DQuat) -> f64 {
    let d = a.dot(b).abs().min(1.0);
    2.0 * d.acos()
}

/// One obstacle over the interval.
struct Candidate {
    obstacle: ObstacleRef,
    geometry_index: usize,
    before: BodyPose,
    now: BodyPose,
    /// Bounds over the whole interval, scene ENU metres.
    reach: Aabb64,
    terrain: bool,
    id: Arc<str>,
    kind: &'static str,
}

impl Reference {
    fn parts(&mut self, index: usize, geometry: &Geometry) -> Arc<Parts> {
        if index >= self.parts.len() {
            self.parts.resize_with(index + 1, || None);
        }
        self.parts[index]
            .get_or_insert_with(|| Arc::new(parts_of(geometry)))
            .clone()
    }

    /// One interval of one vehicle; events are appended.
    #[allow(clippy::too_many_arguments)]
    pub fn step(
        &mut self,
        scene: &Scene,
        cfg: &CollisionConfig,
        key: VehicleKey,
        previous: Option<&TrackSample>,
        current: &TrackSample,
        dynamic: &[DynamicBody],
        events: &mut Vec<Event>,
    ) {
        let t = current.t_s;
        let event = |kind: EventKind| Event {
            t,
            time_boot_ms: current.time_boot_ms,
            vehicle: key.vehicle,
            compid: key.component_id,
            kind,
        };
        let mut state = self
            .vehicles
            .remove(&(key.vehicle, key.component_id))
            .filter(|s| s.generation == key.generation)
            .unwrap_or_else(|| VehicleTruth {
                generation: key.generation,
                ..VehicleTruth::default()
            });
        let mut previous = sweepable_from(previous, current, cfg.max_gap_s, &event, events);
        // Implausible: far below the terrain (found by a scan of the terrain patches).
        let ground = scene.ground_height_enu_m(current.position_enu_m.x, current.position_enu_m.y);
        let implausible =
            ground.is_some_and(|g| current.position_enu_m.z < g - cfg.max_below_terrain_m);
        if std::mem::replace(&mut state.last_implausible, implausible) {
            previous = None;
        }
        if implausible {
            self.vehicles.insert((key.vehicle, key.component_id), state);
            return;
        }
        let vehicle_index = scene.vehicle_model(u8::try_from(key.vehicle).unwrap_or(0));
        let vehicle_geometry = &scene.geometries[vehicle_index];
        let vehicle_parts = self.parts(vehicle_index, vehicle_geometry);
        let radius_m = bodies::radius_m(vehicle_geometry);
        let now = BodyPose::of(current);
        let before = previous.map_or(now, BodyPose::of);
        let t_before = previous.map_or(t, |p| p.t_s);
        let region = Aabb64::around(now.position_enu_m, DVec3::splat(radius_m))
            .union(Aabb64::around(
                before.position_enu_m,
                DVec3::splat(radius_m),
            ))
            .inflated(STEP_TRAVEL_M);
        let mut candidates = Vec::new();
        for (i, o) in scene.obstacles.iter().enumerate() {
            if o.aabb_enu_m.intersects(&region) {
                let pose = BodyPose {
                    position_enu_m: o.placement.position_enu_m,
                    enu_from_body: o.placement.enu_from_local,
                };
                candidates.push(Candidate {
                    obstacle: ObstacleRef::Static(i as u32),
                    geometry_index: o.geometry_index,
                    before: pose,
                    now: pose,
                    reach: o.aabb_enu_m,
                    terrain: o.geometry.is_terrain(),
                    id: Arc::from(o.id.as_str()),
                    kind: o.kind.name(),
                });
            }
        }
        for d in dynamic.iter().filter(|d| d.key.source != key.source()) {
            let g = &scene.geometries[d.geometry_index];
            let r = bodies::radius_m(g);
            let (b, n) = if previous.is_some() {
                (d.previous, d.current)
            } else {
                (d.current, d.current)
            };
            let reach = Aabb64::around(n.position_enu_m, DVec3::splat(r))
                .union(Aabb64::around(b.position_enu_m, DVec3::splat(r)));
            if reach.intersects(&region) {
                candidates.push(Candidate {
                    obstacle: ObstacleRef::Dynamic(d.key),
                    geometry_index: d.geometry_index,
                    before: b,
                    now: n,
                    reach,
                    terrain: false,
                    id: d.id.clone(),
                    kind: d.kind.name(),
                });
            }
        }
        let mut touching_now = Vec::new();
        for c in &candidates {
            let geometry = &scene.geometries[c.geometry_index];
            let parts = self.parts(c.geometry_index, geometry);
            let touches = |u: f64| {
                let v = pose_at(before, now, u);
                let o = pose_at(c.before, c.now, u);
                if c.reach.distance_to(v.position_enu_m) > radius_m {
                    return false;
                }
                if c.terrain {
                    // Terrain patches are placed unrotated: local = ENU less the origin.
                    let local = v.position_enu_m - o.position_enu_m;
                    if geometry
                        .terrain_height_at(local.x as f32, local.y as f32)
                        .is_some_and(|h| local.z < f64::from(h))
                    {
                        return true;
                    }
                    // Wholly above the highest sample under the vehicle: no contact.
                    let (lo, hi) = (local - radius_m, local + radius_m);
                    if geometry
                        .terrain_max_height_in(lo.x as f32, lo.y as f32, hi.x as f32, hi.y as f32)
                        .is_none_or(|top| lo.z > f64::from(top))
                    {
                        return false;
                    }
                }
                overlap(&vehicle_parts, v, &parts, o)
            };
            let was = state.touching.contains(&c.obstacle);
            let mut state_now = was;
            if previous.is_some() {
                let relative = ((now.position_enu_m - before.position_enu_m)
                    - (c.now.position_enu_m - c.before.position_enu_m))
                    .length();
                let turn = turn_rad(before.enu_from_body, now.enu_from_body)
                    .max(turn_rad(c.before.enu_from_body, c.now.enu_from_body));
                let n = ((relative / STEP_TRAVEL_M).max(turn / STEP_TURN_RAD).ceil() as u64)
                    .clamp(1, MAX_STEPS);
                self.steps += n;
                for k in 1..=n {
                    let u = k as f64 / n as f64;
                    let touching = touches(u);
                    if touching && !state_now {
                        // Bisect between the last free step and this one.
                        let (mut lo, mut hi) = ((k - 1) as f64 / n as f64, u);
                        for _ in 0..BISECTIONS {
                            let mid = 0.5 * (lo + hi);
                            if touches(mid) {
                                hi = mid;
                            } else {
                                lo = mid;
                            }
                        }
                        let at = pose_at(before, now, hi);
                        events.push(event(collision(c, at.position_enu_m, t_before, t, hi)));
                    }
                    state_now = touching;
                }
            } else {
                self.steps += 1;
                state_now = touches(1.0);
                if state_now && !was {
                    events.push(event(collision(c, now.position_enu_m, t, t, 1.0)));
                }
            }
            if state_now {
                touching_now.push(c.obstacle);
            }
        }
        state.touching = touching_now;
        self.vehicles.insert((key.vehicle, key.component_id), state);
    }
}

fn collision(c: &Candidate, point: DVec3, t_before: f64, t: f64, u: f64) -> EventKind {
    EventKind::Collision {
        obstacle: c.id.to_string(),
        obstacle_kind: c.kind,
        point_enu_m: point.to_array(),
        normal_enu: [0.0; 3],
        time_of_impact: t_before + (t - t_before) * u,
        swept: u < 1.0,
    }
}

/// True when any part of `a` at `pa` overlaps any part of `b` at `pb` (poses taken about
/// `pa`'s position in f64, then f32).
fn overlap(a: &Parts, pa: BodyPose, b: &Parts, pb: BodyPose) -> bool {
    let anchor = pa.position_enu_m;
    let pose = |p: BodyPose, centre: Vec3| {
        Pose::from_parts(
            (p.position_enu_m + p.enu_from_body * centre.as_dvec3() - anchor).as_vec3(),
            p.enu_from_body.as_quat().normalize(),
        )
    };
    a.each(|ca, sa| {
        let poa = pose(pa, ca);
        b.each(|cb, sb| {
            let pob = pose(pb, cb);
            if query::intersection_test(&poa, sa, &pob, sb).is_ok_and(|i| i.intersecting) {
                return true;
            }
            // Touching counts: within 0.1 mm, plus the f32 resolution of a large triangle mesh.
            let size = |s: &dyn Shape| {
                s.as_trimesh()
                    .map_or(0.0, |m| m.local_aabb().half_extents().length())
            };
            let touch_m = 1e-4 + 1e-6 * size(sa).max(size(sb));
            sa.compute_aabb(&poa)
                .loosened(touch_m)
                .intersects(&sb.compute_aabb(&pob))
                && part_distance(&poa, sa, &pob, sb, touch_m) <= touch_m
        })
    })
}

/// Distance of two parts, anything through parry's dispatcher except two cuboids: parry 0.31's
/// cuboid-cuboid routine can report a separation for touching boxes and its GJK can report 0
/// for boxes millimetres apart, so the separating-axis test decides overlap, GJK's positive
/// distance is taken, and where GJK says 0 the separating-axis test of one box grown by
/// `touch_m` decides between touching (0) and not (`touch_m` and a little).
fn part_distance(pa: &Pose, a: &dyn Shape, pb: &Pose, b: &dyn Shape, touch_m: f32) -> f32 {
    match (a.as_cuboid(), b.as_cuboid()) {
        (Some(ca), Some(cb)) => {
            let pos12 = pa.inv_mul(pb);
            if query::details::intersection_test_cuboid_cuboid(&pos12, ca, cb) {
                return 0.0;
            }
            match query::details::distance_support_map_support_map(&pos12, ca, cb) {
                d if d > 0.0 => d,
                _ => {
                    let grown = Cuboid::new(ca.half_extents + Vec3::splat(touch_m));
                    if query::details::intersection_test_cuboid_cuboid(&pos12, &grown, cb) {
                        0.0
                    } else {
                        touch_m * 1.0001
                    }
                }
            }
        }
        _ => query::distance(pa, a, pb, b).map_or(f32::MAX, |d| d.distance),
    }
}
