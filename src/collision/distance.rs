//! Distances between placed shapes, through parry with one repair: the distance of two cuboids
//! (see `cuboid_distance`). Compounds of blocks reach it for every pair of parts.

use parry3d::math::{Pose, Real, Vector};
use parry3d::query::details::{
    distance_composite_shape_shape, distance_shape_composite_shape,
    distance_support_map_support_map,
};
use parry3d::query::{
    self, ClosestPoints, Contact, DefaultQueryDispatcher, NonlinearRigidMotion, QueryDispatcher,
    ShapeCastHit, ShapeCastOptions, ShapeDistance, ShapeIntersection, Unsupported,
};
use parry3d::shape::{Cuboid, Shape};

use crate::collision::contact::CONTACT_TOLERANCE_M;

/// parry's default dispatcher, except for the distance of two cuboids ([`cuboid_distance`]),
/// which compounds of blocks reach for every pair of parts.
struct Dispatcher;

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

impl QueryDispatcher for Dispatcher {
    fn intersection_test(
        &self,
        pos12: &Pose,
        g1: &dyn Shape,
        g2: &dyn Shape,
    ) -> Result<ShapeIntersection, Unsupported> {
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
        DefaultQueryDispatcher.cast_shapes(pos12, local_vel12, g1, g2, options)
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

/// The distance of two posed shapes, metres (0 when they overlap).
pub fn shape_distance(pos1: &Pose, g1: &dyn Shape, pos2: &Pose, g2: &dyn Shape) -> f32 {
    Dispatcher
        .distance(&pos1.inv_mul(pos2), g1, g2)
        .map_or(f32::MAX, |d| d.distance)
}
