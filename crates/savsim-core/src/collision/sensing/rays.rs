//! Step 3 of a sensing frame: the fan's rays against the active colliders, each ray's
//! nearest hit.

use glam::DVec3;

use super::{Active, Frame, FrameCounts, RayHit, Rules, Sensing, SensingState};
use crate::collision::bodies::ObstacleRef;
use crate::collision::contact::queries;
use crate::collision::contact::shapes::ExactShapes;
use crate::collision::meshes::MeshCache;
use crate::collision::placed::Body;
use crate::collision::view::view;
use crate::collision::ColliderKind;
use crate::scene::Aabb64;

impl Sensing {
    /// Step 3: the fan's rays against the active colliders: static ones front to back through
    /// the static `Bvh` (stopping at the nearest hit), moving ones by a scan.
    pub(super) fn cast_rays(
        &mut self,
        f: &Frame<'_>,
        meshes: &mut MeshCache,
        state: &mut SensingState,
        counts: &mut FrameCounts,
    ) {
        self.reachable_moving(f, state);
        let fan = f.cfg.sensor_fan;
        let origin = f.current.position_enu_m;
        state.rays.resize(fan.len(), (DVec3::ZERO, None));
        for k in 0..fan.len() {
            let dir = fan.direction_enu(k, f.current.attitude.enu_from_frd);
            let mut ray = RayTests {
                f,
                meshes: &mut *meshes,
                active: &state.active,
                origin,
                dir,
                tests: 0,
            };
            let best = ray.nearest(state.rays[k].1, &self.moving);
            counts.ray_tests += ray.tests;
            state.rays[k] = (
                dir,
                best.map(|(obstacle, d)| RayHit {
                    obstacle,
                    distance_m: d,
                    point_enu_m: origin + dir * d,
                }),
            );
        }
    }

    /// The moving bodies with a collider (the sorted active list's tail) that a ray can reach,
    /// with their boxes, into `moving`: looked up once for the fan.
    fn reachable_moving(&mut self, f: &Frame<'_>, state: &SensingState) {
        let (scene, dynamic) = (f.world.scene, f.world.dynamic);
        let position = f.current.position_enu_m;
        self.moving.clear();
        let first_moving = state
            .active
            .partition_point(|a| matches!(a.obstacle, ObstacleRef::Static(_)));
        self.moving.extend(
            state.active[first_moving..]
                .iter()
                .filter_map(|a| Some((a.obstacle, view(scene, dynamic, a.obstacle)?.aabb_enu_m)))
                .filter(|(_, aabb)| aabb.distance_to(position) <= f.cfg.ray_length_m),
        );
    }
}

/// One ray's exact tests against the active colliders, counted in `tests`.
struct RayTests<'f, 'a> {
    f: &'f Frame<'a>,
    meshes: &'f mut MeshCache,
    /// The active colliders, sorted by obstacle.
    active: &'f [Active],
    origin: DVec3,
    /// ENU unit vector.
    dir: DVec3,
    tests: usize,
}

impl RayTests<'_, '_> {
    /// The nearest hit within the ray's length, metres. The obstacle the ray hit at the last
    /// frame (`last`) usually still is the nearest: its distance bounds the walk through the
    /// static `Bvh` (same answer, far fewer nodes); then the reachable moving bodies, by a scan.
    fn nearest(
        &mut self,
        last: Option<RayHit>,
        moving: &[(ObstacleRef, Aabb64)],
    ) -> Option<(ObstacleRef, f64)> {
        let (statics, length_m) = (self.f.world.statics, self.f.cfg.ray_length_m);
        let (origin, dir) = (self.origin, self.dir);
        let seed =
            last.and_then(|h| Some((h.obstacle, self.distance_to(h.obstacle, length_m, false)?)));
        let seed_static = seed.filter(|(o, _)| matches!(o, ObstacleRef::Static(_)));
        let mut best = statics
            .cast_ray(
                origin,
                dir,
                seed_static.map_or(length_m, |s| s.1),
                |i, limit| self.distance_to(ObstacleRef::Static(i), limit, true),
            )
            .map(|(i, d)| (ObstacleRef::Static(i), d))
            .or(seed_static);
        for &(o, aabb) in moving {
            let limit = best.map_or(length_m, |b| b.1);
            if !aabb.ray_hits(origin, dir, limit) {
                continue;
            }
            if let Some(d) = self.distance_to(o, limit, true).filter(|&d| d < limit) {
                best = Some((o, d));
            }
        }
        best
    }

    /// How far along the ray it meets `o`'s collider within `limit`, metres (`None`: not
    /// within it, or `o` has no collider). `bounds_checked`: the caller already knows the ray
    /// meets the obstacle's bounds.
    fn distance_to(&mut self, o: ObstacleRef, limit: f64, bounds_checked: bool) -> Option<f64> {
        let Frame { world, rules, .. } = *self.f;
        let (position, dir) = (self.origin, self.dir);
        let i = self.active.binary_search_by_key(&o, |a| a.obstacle).ok()?;
        let act = self.active[i];
        let v = view(world.scene, world.dynamic, o)?;
        if !bounds_checked && !v.aabb_enu_m.ray_hits(position, dir, limit) {
            return None;
        }
        self.tests += 1;
        // A mesh collider whose mesh the budget did not keep is seen as its box.
        let unbuilt = rules == Rules::Sensor
            && ExactShapes::needs_mesh(v.geometry)
            && self.meshes.built(v.geometry_index).is_none();
        if act.collider == ColliderKind::Box || unbuilt {
            // A box collider is an oriented box: a slab test in its frame.
            let (cuboid, centre) = v.geometry.box_collider();
            let to_local = v.current.enu_from_body.inverse();
            let origin = to_local * (position - v.current.position_enu_m) - centre.as_dvec3();
            let half = cuboid.half_extents.as_dvec3();
            return Aabb64::new(-half, half).ray_entry(origin, to_local * dir, limit);
        }
        let body = match rules {
            Rules::Paper => Body::new(
                crate::collision::placed::Holder::Mesh(
                    self.meshes.get(v.geometry_index, v.geometry),
                ),
                v.current,
            ),
            Rules::Sensor => {
                world
                    .shapes
                    .body(v.geometry_index, v.geometry, self.meshes, v.current, false)
            }
        };
        queries::ray_distance_m(position, dir, limit, &body.placed())
    }
}
