//! The contact layer: what the vehicle touched in one interval, and how close it came to what it
//! did not touch. One strategy per mode, chosen once per tick:
//!
//! - `exact` (`collision::contact::swept`): every obstacle the swept vehicle can reach (the static
//!   `Bvh` for static obstacles, the moving bodies' broad phase), as its exact shape, swept
//!   between the two samples. The truth savsim reports.
//! - `box`, `mesh`, `paper` (`Contacts::discrete` with a `Colliders`): every obstacle near
//!   the vehicle as a box, a triangle mesh, or whatever collider the sensing layer holds, at the
//!   sample. `exact` without a previous sample is also discrete, with the exact shapes.
//!
//! Pure and synchronous; imports no I/O, no tokio, no rerun.
//!
//! - [`queries`]: exact f64-anchored queries between placed shapes (intersection, sweep with
//!   confirmation, the closing bound, ray).
//! - [`distance`]: savsim's query dispatcher: parry's, cuboid pairs repaired, height fields'
//!   missing queries added.
//! - [`shapes`]: the exact shapes (cuboids, compounds, height fields, meshes).
//! - [`ray_height_field`]: exact rays against terrain height fields.
//! - [`inside_trimesh`]: whether a point is inside a closed mesh (winding number along a ray).
//! - [`spans`]: every span of contact within an interval, part by part.
//! - [`swept`]: the `exact` strategy (proofs, then sweeps).

pub mod distance;
pub mod inside_trimesh;
pub mod queries;
pub mod ray_height_field;
pub mod shapes;
pub mod spans;
pub mod swept;

use glam::DVec3;

use crate::collision::bodies::{BodyPose, ObstacleRef};
use crate::collision::config::{CollisionConfig, Mode};
use crate::collision::meshes::MeshCache;
use crate::collision::placed::{inside_solid, Body, Holder};
use crate::collision::sensing::SensingState;
use crate::collision::view::{view, ObstacleView, World};
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

/// What the previous sample of the same vehicle track left: the obstacles it touched and the
/// exact gaps it measured (sorted by obstacle). Empty after a reset or a gap.
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct Before<'a> {
    pub touching: &'a [ObstacleRef],
    pub gaps: &'a [(ObstacleRef, f64)],
}

/// Which collider a discrete mode tests, for the vehicle and for each obstacle.
pub(crate) enum Colliders<'a> {
    /// Every body its enclosing box (`box`).
    Boxes,
    /// Every body its triangle mesh (`mesh`).
    Meshes,
    /// The vehicle a mesh, each obstacle what the sensing layer holds (`paper`).
    Paper(&'a SensingState),
    /// The exact shapes (`exact` at a sample it cannot sweep to).
    Exact,
}

impl Colliders<'_> {
    fn vehicle(&self, world: &World<'_>, meshes: &mut MeshCache, m: &Motion) -> Body {
        let g = &world.scene.geometries[m.geometry_index];
        match self {
            Colliders::Boxes => Body::boxed(g, m.now),
            Colliders::Exact => world.shapes.body(m.geometry_index, g, meshes, m.now, false),
            Colliders::Meshes | Colliders::Paper(_) => {
                Body::new(Holder::Mesh(meshes.get(m.geometry_index, g)), m.now)
            }
        }
    }

    /// The obstacle's collider, or `None` when it has none (the paper's state).
    fn obstacle(
        &self,
        world: &World<'_>,
        meshes: &mut MeshCache,
        o: ObstacleRef,
        v: &ObstacleView<'_>,
    ) -> Option<Body> {
        let kind = match self {
            Colliders::Boxes => ColliderKind::Box,
            Colliders::Meshes => ColliderKind::Mesh,
            Colliders::Paper(sensing) => sensing.collider_of(o)?,
            Colliders::Exact => {
                return Some(world.shapes.body(
                    v.geometry_index,
                    v.geometry,
                    meshes,
                    v.current,
                    true,
                ))
            }
        };
        match kind {
            ColliderKind::None => None,
            ColliderKind::Box => Some(Body::boxed(v.geometry, v.current)),
            ColliderKind::Mesh => Some(Body::new(
                Holder::Mesh(meshes.get(v.geometry_index, v.geometry)),
                v.current,
            )),
        }
    }
}

/// The contact layer's scratch buffers and this interval's results.
#[derive(Debug, Clone, Default)]
pub(crate) struct Contacts {
    /// This interval's candidates (the broad phase's answer).
    pub candidates: Vec<ObstacleRef>,
    /// Obstacles touched in this interval.
    pub touching: Vec<(ObstacleRef, Touch)>,
    /// Obstacles within the near-miss band and not touched: exact distance, metres.
    pub near: Vec<(ObstacleRef, f64)>,
    /// Exact gaps to static obstacles measured at this sample, sorted by obstacle: the next
    /// interval's `Before::gaps`.
    pub gaps: Vec<(ObstacleRef, f64)>,
}

impl Contacts {
    /// Test one interval of the vehicle in `cfg.mode`, reporting gaps within
    /// `cfg.near_miss_m` (`sensing` holds the paper's colliders, `before` what the previous
    /// sample left). Returns the exact tests run.
    pub fn run(
        &mut self,
        world: &World<'_>,
        meshes: &mut MeshCache,
        cfg: &CollisionConfig,
        sensing: &SensingState,
        motion: &Motion,
        before: Before<'_>,
    ) -> usize {
        let (mode, band_m) = (cfg.mode, cfg.near_miss_m);
        self.touching.clear();
        self.near.clear();
        self.gaps.clear();
        let colliders = match mode {
            Mode::Exact if motion.before.is_some() => {
                self.gather(world, &motion.swept_box().inflated(band_m));
                return self.swept(world, meshes, band_m, motion, before);
            }
            Mode::Exact => Colliders::Exact,
            Mode::Box => Colliders::Boxes,
            Mode::Mesh => Colliders::Meshes,
            Mode::Paper => Colliders::Paper(sensing),
            Mode::None | Mode::Reference => return 0,
        };
        self.gather(world, &motion.box_now().inflated(band_m));
        self.discrete(world, meshes, band_m, motion, &colliders)
    }

    /// The candidates: static obstacles whose box meets `query`, moving bodies whose bounds
    /// over the interval do.
    fn gather(&mut self, world: &World<'_>, query: &Aabb64) {
        self.candidates.clear();
        let candidates = &mut self.candidates;
        world
            .statics
            .query_aabb(query, |i| candidates.push(ObstacleRef::Static(i)));
        world.moving_near(query, 0.0, |i, d| {
            let size = d.current.position_enu_m.distance(d.previous.position_enu_m);
            if world
                .dynamic
                .aabb(world.scene, i)
                .inflated(size)
                .intersects(query)
            {
                candidates.push(ObstacleRef::Dynamic(d.key));
            }
        });
    }

    /// The discrete strategies: contact and distance at the sample.
    fn discrete(
        &mut self,
        world: &World<'_>,
        meshes: &mut MeshCache,
        band_m: f64,
        motion: &Motion,
        colliders: &Colliders<'_>,
    ) -> usize {
        let vehicle_geometry = &world.scene.geometries[motion.geometry_index];
        let vehicle = colliders.vehicle(world, meshes, motion);
        let reach = motion.box_now();
        let mut tests = 0;
        for k in 0..self.candidates.len() {
            let o = self.candidates[k];
            let Some(v) = view(world.scene, world.dynamic, o) else {
                continue;
            };
            let near_box =
                v.aabb_enu_m.distance_to(motion.now.position_enu_m) < band_m + motion.radius_m;
            let could_touch = v.aabb_enu_m.intersects(&reach) && !above_terrain(&v, &reach);
            // Terrain is not a near miss: its closeness is the clearance (summary).
            let near_miss_candidate = near_box && !v.geometry.is_terrain();
            if !(could_touch || near_miss_candidate) {
                continue;
            }
            let Some(body) = colliders.obstacle(world, meshes, o, &v) else {
                continue;
            };
            if could_touch {
                tests += 1;
                if let Some(touch) = discrete_touch(&vehicle, motion, &body, &v, vehicle_geometry) {
                    self.touching.push((o, touch));
                    continue;
                }
            }
            if near_miss_candidate {
                tests += 1;
                let d = queries::distance_m(&vehicle.placed(), &body.placed());
                if d < band_m {
                    self.near.push((o, d));
                }
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
) -> Option<Touch> {
    let (a, b) = (vehicle.placed(), body.placed());
    let point_enu_m = if queries::intersects(&a, &b) {
        let (point_enu_m, normal_enu) =
            queries::contact_point(&a, &b).unwrap_or((motion.now.position_enu_m, DVec3::Z));
        return Some(Touch {
            point_enu_m,
            normal_enu,
            fraction: 1.0,
            swept: false,
            holds_now: true,
        });
    } else {
        solid_overlap(motion, body, v, vehicle_geometry)?
    };
    Some(Touch {
        point_enu_m,
        normal_enu: DVec3::Z,
        fraction: 1.0,
        swept: false,
        holds_now: true,
    })
}

/// One solid holds the other though no surfaces touch: the vehicle under terrain, or a
/// surface-meshed obstacle inside the vehicle's solid. Exact shapes of boxes and blocks are
/// solids already, and so are closed meshes (the query dispatcher, `collision::contact::distance`, finds
/// a body inside one); open meshes and terrain need this.
pub(crate) fn solid_overlap(
    motion: &Motion,
    body: &Body,
    v: &ObstacleView<'_>,
    vehicle_geometry: &Geometry,
) -> Option<DVec3> {
    if !body.is_surface() || v.geometry.is_closed_mesh() {
        return None;
    }
    let position = motion.now.position_enu_m;
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
pub(crate) fn above_terrain(v: &ObstacleView<'_>, region: &Aabb64) -> bool {
    if !v.geometry.is_terrain() {
        return false;
    }
    // Terrain patches are placed without rotation.
    let min = region.min - v.current.position_enu_m;
    let max = region.max - v.current.position_enu_m;
    v.geometry
        .terrain_max_height_in(min.x as f32, min.y as f32, max.x as f32, max.y as f32)
        .is_some_and(|top| min.z > f64::from(top))
}
