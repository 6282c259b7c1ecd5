//! savsim's query dispatcher: parry's, with two additions. The distance of two cuboids is
//! repaired (see `cuboid_distance`; compounds of blocks reach it for every pair of parts), and
//! terrain's `HeightField` answers the queries parry 0.31 leaves unsupported for it
//! (intersection, distance, nonlinear shape cast) triangle by triangle over the cells the other
//! shape can reach. A closed triangle mesh (built `ORIENTED`: `Geometry::build_trimesh`) is a
//! solid here: a shape inside it intersects it and is at distance 0 from it, so sweeps,
//! distances and contacts treat it as they treat a box. Every exact query of the contact layer
//! goes through here.

use parry3d::bounding_volume::{Aabb, BoundingVolume};
use parry3d::math::{Pose, Real, Vector};
use parry3d::query::details::{
    distance_composite_shape_shape, distance_shape_composite_shape,
    distance_support_map_support_map,
};
use parry3d::query::{
    self, ClosestPoints, Contact, DefaultQueryDispatcher, NonlinearRigidMotion, QueryDispatcher,
    ShapeCastHit, ShapeCastOptions, ShapeDistance, ShapeIntersection, Unsupported,
};
use parry3d::shape::{Cuboid, HeightField, Shape, Triangle};

/// Two shapes this close count as touching, metres (plus the f32 resolution of the larger
/// shape's coordinates): the same rule at every query, so that "resting exactly on a roof"
/// is contact and a millimetre above is not.
pub const CONTACT_TOLERANCE_M: f64 = 1e-4;

/// parry's default dispatcher, except for the distance of two cuboids ([`cuboid_distance`]),
/// which compounds of blocks reach for every pair of parts, and the queries of height fields.
pub(crate) struct Dispatcher;

/// A height field's distance to another shape is measured only this far, metres; farther is
/// reported as this (a lower bound: every use of a distance here needs no more).
pub const FIELD_DISTANCE_CAP_M: f32 = 5.0;

/// Call `f` with each triangle of `field` (in its frame) whose cell meets `region` (in its
/// frame); stop when `f` says so.
fn field_triangles(field: &HeightField, region: &Aabb, mut f: impl FnMut(&Triangle) -> bool) {
    let mut done = false;
    field.map_elements_in_local_aabb(region, &mut |_, triangle| {
        if !done {
            done = f(triangle);
        }
    });
}

/// The distance of two cuboids, robust to two failures of parry 0.31 seen on real sweeps: its
/// cuboid-cuboid routine (SAT and clipping) can report a separation for boxes that touch (an
/// edge of a turned box against a face), and GJK can report 0 for boxes a few millimetres
/// apart. Overlap is decided by the exact separating-axis test and GJK's distance is taken when
/// it is positive; where GJK wrongly says 0, the separating-axis test of one box grown by the
/// contact tolerance decides: touching (0), or farther than the tolerance (which is returned:
/// a lower bound, as conservative advancement needs).
fn cuboid_distance(pos12: &Pose, c1: &Cuboid, c2: &Cuboid) -> f32 {
    if query::details::intersection_test_cuboid_cuboid(pos12, c1, c2) {
        return 0.0;
    }
    let gjk = distance_support_map_support_map(pos12, c1, c2);
    if gjk > 0.0 {
        return gjk;
    }
    let tolerance = CONTACT_TOLERANCE_M as f32;
    let grown = Cuboid::new(c1.half_extents + Vector::splat(tolerance));
    if query::details::intersection_test_cuboid_cuboid(pos12, &grown, c2) {
        0.0
    } else {
        tolerance * 1.0001
    }
}

/// True when `outer` is a closed triangle mesh (with pseudo-normals) and `inner`, at `pos12`
/// in `outer`'s frame, has a point inside it: a point of `inner`'s surface (the projection of
/// its bounds' centre), so that a shape wholly inside is found; one partly inside crosses the
/// surface, which the surface queries find.
fn held(pos12: &Pose, outer: &dyn Shape, inner: &dyn Shape) -> bool {
    let Some(mesh) = outer
        .as_trimesh()
        .filter(|m| m.pseudo_normals_if_oriented().is_some())
    else {
        return false;
    };
    let centre = inner.compute_local_aabb().center();
    let probe = pos12.transform_point(inner.project_local_point(centre, false).point);
    super::inside_trimesh::inside(mesh, probe.as_dvec3())
}

/// Either shape holds the other inside a closed mesh.
fn either_held(pos12: &Pose, g1: &dyn Shape, g2: &dyn Shape) -> bool {
    held(pos12, g1, g2) || held(&pos12.inverse(), g2, g1)
}

impl QueryDispatcher for Dispatcher {
    fn intersection_test(
        &self,
        pos12: &Pose,
        g1: &dyn Shape,
        g2: &dyn Shape,
    ) -> Result<ShapeIntersection, Unsupported> {
        if either_held(pos12, g1, g2) {
            return Ok(true.into());
        }
        let field_test = |pos12: &Pose, field: &HeightField, other: &dyn Shape| {
            let mut hit = false;
            field_triangles(field, &other.compute_aabb(pos12), |t| {
                hit = self
                    .intersection_test(pos12, t, other)
                    .is_ok_and(|i| i.intersecting);
                hit
            });
            Ok(hit.into())
        };
        if let Some(field) = g1.as_heightfield() {
            return field_test(pos12, field, g2);
        }
        if let Some(field) = g2.as_heightfield() {
            return field_test(&pos12.inverse(), field, g1);
        }
        DefaultQueryDispatcher.intersection_test(pos12, g1, g2)
    }

    fn distance(
        &self,
        pos12: &Pose,
        g1: &dyn Shape,
        g2: &dyn Shape,
    ) -> Result<ShapeDistance, Unsupported> {
        if let (Some(c1), Some(c2)) = (g1.as_cuboid(), g2.as_cuboid()) {
            return Ok(cuboid_distance(pos12, c1, c2).into());
        }
        if either_held(pos12, g1, g2) {
            return Ok(0.0.into());
        }
        let field_distance = |pos12: &Pose, field: &HeightField, other: &dyn Shape| {
            let mut best = FIELD_DISTANCE_CAP_M;
            let region = other.compute_aabb(pos12).loosened(FIELD_DISTANCE_CAP_M);
            field_triangles(field, &region, |t| {
                if let Ok(d) = self.distance(pos12, t, other) {
                    best = best.min(d.distance);
                }
                best <= 0.0
            });
            Ok(best.into())
        };
        if let Some(field) = g1.as_heightfield() {
            return field_distance(pos12, field, g2);
        }
        if let Some(field) = g2.as_heightfield() {
            return field_distance(&pos12.inverse(), field, g1);
        }
        if let Some(c1) = g1.as_composite_shape() {
            return Ok(distance_composite_shape_shape(self, pos12, c1, g2));
        }
        if let Some(c2) = g2.as_composite_shape() {
            return Ok(distance_shape_composite_shape(self, pos12, g1, c2));
        }
        DefaultQueryDispatcher.distance(pos12, g1, g2)
    }

    fn contact(
        &self,
        pos12: &Pose,
        g1: &dyn Shape,
        g2: &dyn Shape,
        prediction: Real,
    ) -> Result<Option<Contact>, Unsupported> {
        DefaultQueryDispatcher.contact(pos12, g1, g2, prediction)
    }

    fn closest_points(
        &self,
        pos12: &Pose,
        g1: &dyn Shape,
        g2: &dyn Shape,
        max_dist: Real,
    ) -> Result<ClosestPoints, Unsupported> {
        DefaultQueryDispatcher.closest_points(pos12, g1, g2, max_dist)
    }

    fn cast_shapes(
        &self,
        pos12: &Pose,
        local_vel12: Vector,
        g1: &dyn Shape,
        g2: &dyn Shape,
        options: ShapeCastOptions,
    ) -> Result<Option<ShapeCastHit>, Unsupported> {
        // A height field: every triangle of the cells the other shape's path reaches (parry's
        // own walks the cells under one ray from the other's centre, and can miss a cell the
        // other's side sweeps).
        let (field, field_from_other, vel_in_field, other) =
            match (g1.as_heightfield(), g2.as_heightfield()) {
                (Some(f), _) => (f, *pos12, local_vel12, g2),
                (None, Some(f)) => {
                    let inverse = pos12.inverse();
                    (f, inverse, inverse.rotation * -local_vel12, g1)
                }
                (None, None) => {
                    return DefaultQueryDispatcher.cast_shapes(pos12, local_vel12, g1, g2, options)
                }
            };
        let start = other.compute_aabb(&field_from_other);
        let travel = vel_in_field * options.max_time_of_impact;
        let end = Aabb::new(start.mins + travel, start.maxs + travel);
        let region = start.merged(&end).loosened(options.target_distance + 1e-3);
        // Each triangle sits where the field does: as the first shape, or in its frame.
        let field_first = g1.as_heightfield().is_some();
        earliest_over_triangles(field, &region, |t| {
            if field_first {
                self.cast_shapes(pos12, local_vel12, t, g2, options)
            } else {
                self.cast_shapes(pos12, local_vel12, g1, t, options)
            }
        })
    }

    fn cast_shapes_nonlinear(
        &self,
        motion1: &NonlinearRigidMotion,
        g1: &dyn Shape,
        motion2: &NonlinearRigidMotion,
        g2: &dyn Shape,
        start_time: Real,
        end_time: Real,
        stop_at_penetration: bool,
    ) -> Result<Option<ShapeCastHit>, Unsupported> {
        if g1.as_heightfield().is_some() || g2.as_heightfield().is_some() {
            return self.cast_field_nonlinear(
                motion1,
                g1,
                motion2,
                g2,
                (start_time, end_time),
                stop_at_penetration,
            );
        }
        DefaultQueryDispatcher.cast_shapes_nonlinear(
            motion1,
            g1,
            motion2,
            g2,
            start_time,
            end_time,
            stop_at_penetration,
        )
    }
}

impl Dispatcher {
    /// A nonlinear cast with a height field on one side: every triangle of the cells the other
    /// shape's swept bounds reach, cast in turn; the first hit wins.
    fn cast_field_nonlinear(
        &self,
        motion1: &NonlinearRigidMotion,
        g1: &dyn Shape,
        motion2: &NonlinearRigidMotion,
        g2: &dyn Shape,
        (start, end): (Real, Real),
        stop_at_penetration: bool,
    ) -> Result<Option<ShapeCastHit>, Unsupported> {
        let field_first = g1.as_heightfield().is_some();
        let (field, mf, other, mo) = match (g1.as_heightfield(), g2.as_heightfield()) {
            (Some(f), _) => (f, motion1, g2, motion2),
            (None, Some(f)) => (f, motion2, g1, motion1),
            (None, None) => return Err(Unsupported),
        };
        // The other shape's bounds in the field's frame at both ends, grown by how far any of
        // its points can stray from the straight line between (its turn about its pivot, and
        // the field's own turn at the other's distance).
        let span = end - start;
        let local = other.compute_local_aabb();
        let reach = (local.maxs - mo.local_center)
            .abs()
            .max((local.mins - mo.local_center).abs())
            .length();
        let at = |t: Real| mf.position_at_time(t).inv_mul(&mo.position_at_time(t));
        let (p0, p1) = (at(start), at(end));
        let field_reach = field.root_aabb().half_extents().length() + p0.translation.length();
        // (A translation sweeps the hull of the two ends' bounds: their merge holds it.)
        let swing =
            span * (mo.angvel.length() * reach + mf.angvel.length() * (field_reach + reach));
        let region = other
            .compute_aabb(&p0)
            .merged(&other.compute_aabb(&p1))
            .loosened(swing + 1e-3);
        earliest_over_triangles(field, &region, |t| {
            if field_first {
                self.cast_shapes_nonlinear(mf, t, mo, other, start, end, stop_at_penetration)
            } else {
                self.cast_shapes_nonlinear(mo, other, mf, t, start, end, stop_at_penetration)
            }
        })
    }
}

/// The earliest hit of `cast` over the field's triangles within `region` (the first error
/// stops the walk and is returned).
fn earliest_over_triangles(
    field: &HeightField,
    region: &Aabb,
    mut cast: impl FnMut(&Triangle) -> Result<Option<ShapeCastHit>, Unsupported>,
) -> Result<Option<ShapeCastHit>, Unsupported> {
    let mut best: Option<ShapeCastHit> = None;
    let mut result = Ok(());
    field_triangles(field, region, |t| {
        match cast(t) {
            Ok(Some(h)) if best.is_none_or(|b| h.time_of_impact < b.time_of_impact) => {
                best = Some(h)
            }
            Ok(_) => {}
            Err(e) => result = Err(e),
        }
        result.is_err()
    });
    result.map(|()| best)
}

/// True when the two posed shapes overlap.
pub fn shapes_intersect(pos1: &Pose, g1: &dyn Shape, pos2: &Pose, g2: &dyn Shape) -> bool {
    Dispatcher
        .intersection_test(&pos1.inv_mul(pos2), g1, g2)
        .is_ok_and(|i| i.intersecting)
}

/// The distance of two posed shapes, metres (0 when they overlap).
pub fn shape_distance(pos1: &Pose, g1: &dyn Shape, pos2: &Pose, g2: &dyn Shape) -> f32 {
    Dispatcher
        .distance(&pos1.inv_mul(pos2), g1, g2)
        .map_or(f32::MAX, |d| d.distance)
}
