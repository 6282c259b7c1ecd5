//! The contact layer: what the vehicle touched in one interval, and how close it came to what it
//! did not touch. One strategy per mode:
//!
//! - `exact`: every obstacle the swept vehicle can reach (the octree for static obstacles, a
//!   scan of the tick's moving bodies), as its exact shape, swept between the two samples
//!   (parry's shape cast; screw motion when a body turns). The truth savsim reports.
//! - `box`, `mesh`: every obstacle near the vehicle as a box or a triangle mesh, at the sample.
//! - `paper`: the sensing layer's colliders (box or mesh, as the paper's state holds), at the
//!   sample.
//!
//! Pure and synchronous; imports no I/O, no tokio, no rerun.

use glam::DVec3;
use smallvec::SmallVec;

use crate::collision::bodies::{
    inside_solid, may_reach, view, view_dynamic, Body, BodyPose, Holder, ObstacleRef, ObstacleView,
    World,
};
use crate::collision::config::Mode;
use crate::collision::contact::{self, SweepHit};
use crate::collision::meshes::MeshCache;
use crate::collision::octree::OctreeWorkspace;
use crate::collision::sensing::SensingState;
use crate::collision::ColliderKind;
use crate::scene::geometry::Geometry;
use crate::scene::Aabb64;

/// A contact found in this interval.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Touch {
    pub point_enu_m: DVec3,
    pub normal_enu: DVec3,
    /// Fraction of the interval at first contact (1 at the sample).
    pub fraction: f64,
    pub swept: bool,
    /// Still in contact at the sample (a sweep can touch and leave within the interval).
    pub holds_now: bool,
}

/// The vehicle over one interval.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Motion {
    /// Pose at the previous sample, when this interval is swept.
    pub before: Option<BodyPose>,
    /// Pose at the sample.
    pub now: BodyPose,
    /// The vehicle's model, an index into `Scene::geometries`.
    pub geometry_index: usize,
    /// Radius of the sphere about its reference point that holds the model, metres.
    pub radius_m: f64,
}

impl Motion {
    fn box_now(&self) -> Aabb64 {
        Aabb64::around(self.now.position_enu_m, DVec3::splat(self.radius_m))
    }

    /// The box the vehicle sweeps in this interval.
    pub fn swept_box(&self) -> Aabb64 {
        let start = self
            .before
            .map_or(self.now.position_enu_m, |b| b.position_enu_m);
        self.box_now()
            .union(Aabb64::around(start, DVec3::splat(self.radius_m)))
    }
}

/// The contact layer's scratch buffers and this interval's results.
#[derive(Debug, Clone, Default)]
pub(crate) struct Contacts {
    ws: OctreeWorkspace,
    candidates: Vec<ObstacleRef>,
    /// Obstacles touched in this interval.
    pub touching: Vec<(ObstacleRef, Touch)>,
    /// Obstacles within the near-miss band and not touched: exact distance, metres.
    pub near: Vec<(ObstacleRef, f64)>,
}

impl Contacts {
    /// Test one interval of the vehicle in `mode` (`sensing` holds the paper's colliders).
    /// Returns the exact tests run.
    #[allow(clippy::too_many_arguments)]
    pub fn run(
        &mut self,
        world: &World<'_>,
        meshes: &mut MeshCache,
        mode: Mode,
        band_m: f64,
        sensing: &SensingState,
        motion: &Motion,
    ) -> usize {
        self.touching.clear();
        self.near.clear();
        self.candidates.clear();
        let swept = mode == Mode::Exact && motion.before.is_some();
        let reach = if swept {
            motion.swept_box()
        } else {
            motion.box_now()
        };
        let query = reach.inflated(band_m);
        let candidates = &mut self.candidates;
        world.octree.query_aabb(&query, &mut self.ws, |i| {
            candidates.push(ObstacleRef::Static(i))
        });
        for d in world.dynamic {
            if !may_reach(world, d, &query, 0.0) {
                continue;
            }
            let size = d.current.position_enu_m.distance(d.previous.position_enu_m);
            let Some(v) = view_dynamic(world.scene, d) else {
                continue;
            };
            if v.aabb_enu_m.inflated(size).intersects(&query) {
                candidates.push(ObstacleRef::Dynamic(d.key));
            }
        }
        let vehicle_geometry = &world.scene.geometries[motion.geometry_index];
        let vehicle = match mode {
            Mode::Box => Body::boxed(vehicle_geometry, motion.now),
            Mode::Exact => world.shapes.body(
                motion.geometry_index,
                vehicle_geometry,
                meshes,
                motion.now,
                false,
            ),
            _ => Body::new(
                Holder::Mesh(meshes.get(motion.geometry_index, vehicle_geometry)),
                motion.now,
            ),
        };
        let mut tests = 0;
        for k in 0..self.candidates.len() {
            let o = self.candidates[k];
            let Some(v) = view(world.scene, world.dynamic, o) else {
                continue;
            };
            let collider = match mode {
                Mode::Box => ColliderKind::Box,
                Mode::Paper => match sensing.collider_of(o) {
                    Some(c) => c,
                    None => continue,
                },
                _ => ColliderKind::Mesh,
            };
            let near_box =
                v.aabb_enu_m.distance_to(motion.now.position_enu_m) < band_m + motion.radius_m;
            // A moving obstacle's bounds over the interval: now, grown by how far it moved.
            let moved_m = if swept {
                v.current.position_enu_m.distance(v.previous.position_enu_m)
            } else {
                0.0
            };
            let could_touch = v.aabb_enu_m.inflated(moved_m).intersects(&reach)
                && !above_terrain(v.geometry, &v.current, &reach);
            // Terrain is not a near miss: its closeness is the clearance (summary).
            let near_miss_candidate = near_box && !v.geometry.is_terrain();
            if !(could_touch || near_miss_candidate) {
                continue;
            }
            let body = match (mode, collider) {
                (Mode::Exact, _) => {
                    world
                        .shapes
                        .body(v.geometry_index, v.geometry, meshes, v.current, true)
                }
                (_, ColliderKind::Box) => Body::boxed(v.geometry, v.current),
                _ => Body::new(
                    Holder::Mesh(meshes.get(v.geometry_index, v.geometry)),
                    v.current,
                ),
            };
            let touches: SmallVec<[Touch; 2]> = if !could_touch {
                SmallVec::new()
            } else if swept {
                tests += 2;
                sweep_touches(&vehicle, motion, &body, &v, vehicle_geometry)
            } else {
                tests += 1;
                discrete_touch(&vehicle, motion, &body, &v, vehicle_geometry, mode)
                    .into_iter()
                    .collect()
            };
            match touches.first() {
                Some(_) => self
                    .touching
                    .extend(touches.into_iter().map(|touch| (o, touch))),
                None if near_miss_candidate => {
                    tests += 1;
                    let d = contact::distance_m(&vehicle.placed(), &body.placed());
                    if d < band_m {
                        self.near.push((o, d));
                    }
                }
                None => {}
            }
        }
        tests
    }
}

/// A contact at the sample: surfaces that touch, or one solid holding the other.
fn discrete_touch(
    vehicle: &Body,
    motion: &Motion,
    body: &Body,
    v: &ObstacleView<'_>,
    vehicle_geometry: &Geometry,
    mode: Mode,
) -> Option<Touch> {
    let (a, b) = (vehicle.placed(), body.placed());
    if contact::intersects(&a, &b) {
        let (point_enu_m, normal_enu) =
            contact::contact_point(&a, &b).unwrap_or((motion.now.position_enu_m, DVec3::Z));
        return Some(Touch {
            point_enu_m,
            normal_enu,
            fraction: 1.0,
            swept: false,
            holds_now: true,
        });
    }
    let point_enu_m = solid_overlap(motion, body, v, vehicle_geometry, mode)?;
    Some(Touch {
        point_enu_m,
        normal_enu: DVec3::Z,
        fraction: 1.0,
        swept: false,
        holds_now: true,
    })
}

/// The contacts in the interval (sweep), and whether the last still holds at the sample.
fn sweep_touches(
    vehicle: &Body,
    motion: &Motion,
    body: &Body,
    v: &ObstacleView<'_>,
    vehicle_geometry: &Geometry,
) -> SmallVec<[Touch; 2]> {
    let mut touches = SmallVec::new();
    let Some(before) = motion.before else {
        return touches;
    };
    let (a0, a1, b0, b1) = (
        vehicle.at(before),
        vehicle.at(motion.now),
        body.at(v.previous),
        body.at(v.current),
    );
    let mut hit: Option<SweepHit> = contact::sweep(&a0, &a1, &b0, &b1);
    // Terrain: the vehicle may have gone under this patch from its neighbour's ground (a
    // patch's mesh is open at its edges) before it touches this patch's surface.
    let under = |u: f64| {
        let p = before.position_enu_m.lerp(motion.now.position_enu_m, u);
        v.geometry.is_terrain() && inside_solid(v.geometry, &v.current, p)
    };
    let went_under = |upto: f64| contact::bisect_first(0.0, upto, 30, under);
    if let Some(h) = &mut hit {
        if h.fraction > 0.0 && !under(0.0) && under(h.fraction) {
            h.fraction = went_under(h.fraction);
        }
    }
    match hit {
        Some(h) => {
            let holds_now = contact::intersects(&vehicle.placed(), &body.placed())
                || solid_overlap(motion, body, v, vehicle_geometry, Mode::Exact).is_some();
            // A compound can be left and entered again within one interval (the wings of a
            // building at speed), and so can a surface when the vehicle travels more than its
            // size (the ground of a ridge): every span of contact is a contact.
            let travel_m = before.position_enu_m.distance(motion.now.position_enu_m);
            let spans = if vehicle.is_compound()
                || body.is_compound()
                || (body.is_surface() && travel_m > 2.0 * motion.radius_m)
            {
                crate::collision::spans::contact_spans(&a0, &a1, &b0, &b1, &under)
            } else {
                SmallVec::new()
            };
            if spans.len() > 1 {
                let last = spans.len() - 1;
                for (k, (start, _)) in spans.into_iter().enumerate() {
                    let fraction = if k == 0 && !under(0.0) && under(start.fraction) {
                        went_under(start.fraction)
                    } else {
                        start.fraction
                    };
                    touches.push(Touch {
                        point_enu_m: start.point_enu_m,
                        normal_enu: start.normal_enu,
                        fraction,
                        swept: true,
                        holds_now: holds_now && k == last,
                    });
                }
            } else {
                touches.push(Touch {
                    point_enu_m: h.point_enu_m,
                    normal_enu: h.normal_enu,
                    fraction: h.fraction,
                    swept: true,
                    holds_now,
                });
            }
            touches
        }
        // No surface crossed: still, the vehicle may have gone under terrain (from another
        // patch's ground: a patch's mesh is open at its edges) or sit under it. When the
        // reference point went under during the interval, bisect for when.
        None => {
            let Some(point_enu_m) = solid_overlap(motion, body, v, vehicle_geometry, Mode::Exact)
            else {
                return touches;
            };
            let (swept, fraction) = if under(0.0) {
                (false, 1.0)
            } else {
                (true, went_under(1.0))
            };
            touches.push(Touch {
                point_enu_m,
                normal_enu: DVec3::Z,
                fraction,
                swept,
                holds_now: true,
            });
            touches
        }
    }
}

/// One solid holds the other though no surfaces touch: the vehicle inside a building or under
/// terrain, or a small obstacle inside the vehicle's hull. Exact shapes of boxes and blocks are
/// solids already; only triangle meshes need this.
fn solid_overlap(
    motion: &Motion,
    body: &Body,
    v: &ObstacleView<'_>,
    vehicle_geometry: &Geometry,
    mode: Mode,
) -> Option<DVec3> {
    let position = motion.now.position_enu_m;
    if mode == Mode::Exact {
        // Terrain is the one triangle-mesh solid.
        return (v.geometry.is_terrain() && inside_solid(v.geometry, &v.current, position))
            .then_some(position);
    }
    if !body.is_surface() {
        return None;
    }
    if inside_solid(v.geometry, &v.current, position) {
        return Some(position);
    }
    v.geometry
        .a_surface_point()
        .map(|p| v.current.position_enu_m + v.current.enu_from_body * p.as_dvec3())
        .filter(|&p| inside_solid(vehicle_geometry, &motion.now, p))
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
