//! Exact queries between placed shapes, computed in f32 about a local anchor.
//!
//! Scene positions are f64; parry works in f32. Every query subtracts an anchor (the first
//! body's position) in f64 before converting, so a vehicle 1000 km from the scene origin is
//! tested with millimetre precision, not the 6 cm that f32 has at 10^6 m.

use glam::{DQuat, DVec3, Vec3};
use parry3d::bounding_volume::BoundingVolume;
use parry3d::math::Pose;
use parry3d::math::{Real, Vector};
use parry3d::query::details::{
    distance_composite_shape_shape, distance_shape_composite_shape,
    distance_support_map_support_map,
};
use parry3d::query::{
    self, ClosestPoints, Contact, DefaultQueryDispatcher, NonlinearRigidMotion, QueryDispatcher,
    Ray, ShapeCastHit, ShapeCastOptions, ShapeDistance, ShapeIntersection, Unsupported,
};
use parry3d::shape::{Cuboid, Shape};

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
fn shape_distance(pos1: &Pose, g1: &dyn Shape, pos2: &Pose, g2: &dyn Shape) -> f32 {
    Dispatcher
        .distance(&pos1.inv_mul(pos2), g1, g2)
        .map_or(f32::MAX, |d| d.distance)
}

/// A shape placed in the scene.
#[derive(Clone, Copy)]
pub struct Placed<'a> {
    /// The shape, in its own frame.
    pub shape: &'a dyn Shape,
    /// Where the shape's frame origin is, scene ENU metres.
    pub position_enu_m: DVec3,
    /// Rotation from the shape's frame to ENU.
    pub enu_from_shape: DQuat,
    /// The point the body turns about, in the shape's frame (its reference point).
    pub pivot_local_m: Vec3,
}

impl std::fmt::Debug for Placed<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Placed")
            .field("position_enu_m", &self.position_enu_m)
            .field("enu_from_shape", &self.enu_from_shape)
            .finish_non_exhaustive()
    }
}

impl<'a> Placed<'a> {
    /// The same shape at another position and rotation of its body.
    pub fn moved(&self, position_enu_m: DVec3, enu_from_shape: DQuat) -> Placed<'a> {
        Placed {
            position_enu_m,
            enu_from_shape,
            ..*self
        }
    }

    /// Where the body's pivot is, scene ENU metres.
    fn pivot_enu_m(&self) -> DVec3 {
        self.position_enu_m + self.enu_from_shape * self.pivot_local_m.as_dvec3()
    }

    fn pose_about(&self, anchor: DVec3) -> Pose {
        Pose::from_parts(
            (self.position_enu_m - anchor).as_vec3(),
            self.enu_from_shape.as_quat().normalize(),
        )
    }
}

/// Where and when two bodies first touch during a sweep.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SweepHit {
    /// Fraction of the interval at first contact, in [0, 1].
    pub fraction: f64,
    /// Contact point, scene ENU metres.
    pub point_enu_m: DVec3,
    /// Contact normal (pointing out of the second body), ENU.
    pub normal_enu: DVec3,
}

/// True when the two placed shapes overlap or touch (within [`CONTACT_TOLERANCE_M`]).
pub fn intersects(a: &Placed<'_>, b: &Placed<'_>) -> bool {
    let anchor = a.position_enu_m;
    let (pa, pb) = (a.pose_about(anchor), b.pose_about(anchor));
    if query::intersection_test(&pa, a.shape, &pb, b.shape).is_ok_and(|i| i.intersecting) {
        return true;
    }
    let tolerance = tolerance_m(a.shape, b.shape);
    // Only shapes whose bounds come that close can touch within the tolerance.
    a.shape
        .compute_aabb(&pa)
        .loosened(tolerance)
        .intersects(&b.shape.compute_aabb(&pb))
        && shape_distance(&pa, a.shape, &pb, b.shape) <= tolerance
}

/// Distance between the two placed shapes, metres (0 when they touch).
pub fn distance_m(a: &Placed<'_>, b: &Placed<'_>) -> f64 {
    let anchor = a.position_enu_m;
    let d = shape_distance(
        &a.pose_about(anchor),
        a.shape,
        &b.pose_about(anchor),
        b.shape,
    );
    if d == f32::MAX {
        f64::INFINITY
    } else {
        f64::from(d)
    }
}

/// A contact point and normal of two overlapping shapes (normal out of `b`).
pub fn contact_point(a: &Placed<'_>, b: &Placed<'_>) -> Option<(DVec3, DVec3)> {
    let anchor = a.position_enu_m;
    let pa = a.pose_about(anchor);
    let pb = b.pose_about(anchor);
    let c = query::contact(&pa, a.shape, &pb, b.shape, 0.0).ok()??;
    Some((
        anchor + c.point2.as_dvec3(),
        (-c.normal1.as_dvec3()).normalize_or_zero(),
    ))
}

/// The screw motion from `from` to `to`: the pivot (the body's reference point) moves in a
/// straight line while the body turns about it at a constant rate.
fn motion(anchor: DVec3, from: &Placed<'_>, to: &Placed<'_>) -> NonlinearRigidMotion {
    let delta = rotation_between(from, to);
    NonlinearRigidMotion::new(
        from.pose_about(anchor),
        from.pivot_local_m,
        (to.pivot_enu_m() - from.pivot_enu_m()).as_vec3(),
        delta.to_scaled_axis().as_vec3(),
    )
}

/// Rotations smaller than this over one interval (radians) are swept as pure translations.
const LINEAR_SWEEP_MAX_ROTATION_RAD: f64 = 1e-4;

fn rotation_between(from: &Placed<'_>, to: &Placed<'_>) -> DQuat {
    let delta = to.enu_from_shape * from.enu_from_shape.inverse();
    if delta.w < 0.0 {
        -delta
    } else {
        delta
    }
}

/// Two shapes this close count as touching, metres (plus the f32 resolution of the larger
/// shape's coordinates): the same rule at every query, so that "resting exactly on a roof"
/// is contact and a millimetre above is not.
pub const CONTACT_TOLERANCE_M: f64 = 1e-4;

/// Casts restarted after a hit that an exact distance query does not confirm (parry's
/// conservative advancement can stop short of a contact on a near-grazing pass, and lose
/// precision on very large triangles).
const MAX_RECASTS: usize = 64;

/// The contact tolerance for two shapes: [`CONTACT_TOLERANCE_M`], grown with the shapes' size
/// where f32 loses it (a 10 km mesh has vertices 5 km from the anchor).
fn tolerance_m(a: &dyn Shape, b: &dyn Shape) -> f32 {
    // Only triangle meshes reach sizes where f32 matters (boxes and blocks are tested part by
    // part, in the frame of the part).
    let size = |s: &dyn Shape| {
        s.as_trimesh()
            .map_or(0.0, |m| m.local_aabb().half_extents().length())
    };
    CONTACT_TOLERANCE_M as f32 + 1e-6 * size(a).max(size(b))
}

/// First contact of body `a` moving from `a0` to `a1` with body `b` moving from `b0` to `b1`
/// over one interval (screw motion: linear translation, constant rotation rate; a pure
/// translation when neither body turns). Bodies that already touch at the start give a hit at
/// fraction 0. Every hit is confirmed by an exact distance query at its poses; an unconfirmed
/// one restarts the cast past it, by no more than the bodies could close in the meantime.
pub fn sweep(
    a0: &Placed<'_>,
    a1: &Placed<'_>,
    b0: &Placed<'_>,
    b1: &Placed<'_>,
) -> Option<SweepHit> {
    let anchor = a0.position_enu_m;
    // Already touching at the start: an exact test (a cast from inside can lose the contact on
    // very large triangles).
    if intersects(a0, b0) {
        let (point_enu_m, normal_enu) = contact_point(a0, b0).unwrap_or((anchor, DVec3::Z));
        return Some(SweepHit {
            fraction: 0.0,
            point_enu_m,
            normal_enu,
        });
    }
    let turning = |from: &Placed<'_>, to: &Placed<'_>| {
        rotation_between(from, to).to_scaled_axis().length() > LINEAR_SWEEP_MAX_ROTATION_RAD
    };
    let ma = motion(anchor, a0, a1);
    let mb = motion(anchor, b0, b1);
    let linear = !turning(a0, a1) && !turning(b0, b1);
    let tolerance = tolerance_m(a0.shape, b0.shape);
    // How fast the gap can close, metres per interval: relative travel plus the turn of the
    // farthest point of each shape.
    let reach = |s: &dyn Shape| {
        s.compute_local_aabb()
            .maxs
            .abs()
            .max(s.compute_local_aabb().mins.abs())
            .length()
    };
    let closing = (mb.linvel - ma.linvel).length()
        + ma.angvel.length() * (reach(a0.shape) + a0.pivot_local_m.length())
        + mb.angvel.length() * (reach(b0.shape) + b0.pivot_local_m.length());
    let gap_at = |t: f32| {
        shape_distance(
            &ma.position_at_time(t),
            a0.shape,
            &mb.position_at_time(t),
            b0.shape,
        )
    };
    // The first touching time between a time known to be clear and one known to touch.
    let first_touch = |mut clear: f32, mut touching: f32| {
        for _ in 0..24 {
            let mid = 0.5 * (clear + touching);
            if gap_at(mid) <= tolerance {
                touching = mid;
            } else {
                clear = mid;
            }
        }
        touching
    };
    let hit_at = |toi: f32, witness: Option<&ShapeCastHit>| {
        let (pose_a, pose_b) = (ma.position_at_time(toi), mb.position_at_time(toi));
        // The contact at the confirmed poses (a cast that stopped in penetration reports no
        // witness of its own).
        let (point_enu_m, normal_enu) = match (
            query::contact(&pose_a, a0.shape, &pose_b, b0.shape, tolerance),
            witness,
        ) {
            (Ok(Some(c)), _) => (
                anchor + c.point2.as_dvec3(),
                (-c.normal1.as_dvec3()).normalize_or_zero(),
            ),
            (_, Some(hit)) => (
                anchor + (pose_b * hit.witness2).as_dvec3(),
                (pose_b.rotation * hit.normal2)
                    .as_dvec3()
                    .normalize_or_zero(),
            ),
            _ => (anchor + pose_a.translation.as_dvec3(), DVec3::Z),
        };
        SweepHit {
            fraction: f64::from(toi),
            point_enu_m,
            normal_enu,
        }
    };
    // `start` is always a time known to be clear.
    let mut start = 0.0f32;
    for _ in 0..MAX_RECASTS {
        let cast = if linear {
            let pa = ma.position_at_time(start);
            let pb = mb.position_at_time(start);
            let options = ShapeCastOptions {
                max_time_of_impact: 1.0 - start,
                stop_at_penetration: true,
                ..ShapeCastOptions::default()
            };
            query::cast_shapes(&pa, ma.linvel, a0.shape, &pb, mb.linvel, b0.shape, options)
                .ok()
                .flatten()
                .map(|hit| hit.transform_toi(start))
        } else {
            query::cast_shapes_nonlinear(&ma, a0.shape, &mb, b0.shape, start, 1.0, true)
                .ok()
                .flatten()
        };
        let Some(hit) = cast else { break };
        let toi = hit.time_of_impact.clamp(0.0, 1.0);
        let gap = gap_at(toi);
        if gap <= tolerance {
            // A linear cast's time is exact; conservative advancement can stop past the touch.
            let toi = if linear { toi } else { first_touch(start, toi) };
            return Some(hit_at(toi, Some(&hit)));
        }
        // Not touching there: no contact can come sooner than the gap closes.
        let advance = if closing > 0.0 { gap / closing } else { 1.0 };
        start = toi + advance.max(1e-5);
        if start >= 1.0 {
            break;
        }
    }
    // The cast found nothing (or gave up): a contact that holds at the end of the interval
    // still began in it. Its start is bisected on the exact overlap test (distances lose
    // precision against very large triangles); a touch only within the tolerance is at the end.
    if gap_at(1.0) > tolerance {
        return None;
    }
    let overlaps_at = |t: f32| {
        query::intersection_test(
            &ma.position_at_time(t),
            a0.shape,
            &mb.position_at_time(t),
            b0.shape,
        )
        .is_ok_and(|i| i.intersecting)
    };
    let mut toi = 1.0f32;
    if overlaps_at(1.0) {
        let mut clear = start.min(1.0);
        for _ in 0..24 {
            let mid = 0.5 * (clear + toi);
            if overlaps_at(mid) {
                toi = mid;
            } else {
                clear = mid;
            }
        }
    }
    Some(hit_at(toi, None))
}

/// The convex parts of a placed shape: a compound's parts, or the shape itself.
fn convex_parts<'a>(p: &Placed<'a>) -> smallvec::SmallVec<[Placed<'a>; 8]> {
    match p.shape.as_compound() {
        Some(compound) => compound
            .shapes()
            .iter()
            .map(|(pose, part)| Placed {
                shape: part.as_ref(),
                position_enu_m: p.position_enu_m + p.enu_from_shape * pose.translation.as_dvec3(),
                enu_from_shape: p.enu_from_shape * pose.rotation.as_dquat(),
                // The body still turns about its own pivot: where it is in the part's frame.
                pivot_local_m: pose.inverse() * p.pivot_local_m,
            })
            .collect(),
        None => smallvec::smallvec![*p],
    }
}

/// Most triangles of a mesh tested for the spans of one interval (those nearest the path's
/// bounds come first in the mesh's BVH order; a path that meets more is rare and slow).
const MAX_SPAN_TRIANGLES: usize = 512;

/// Every contact of the interval, not only the first: the times (fractions) during which body
/// `a` (from `a0` to `a1`) touches body `b` (from `b0` to `b1`), as disjoint spans, each with
/// the hit that opens it. Compounds are split into their convex parts, a triangle mesh into
/// the triangles near the path; a pair of convex parts touches over one span, found by a sweep
/// forwards (entry) and one backwards (exit). Between two spans, `inside(fraction)` (terrain:
/// the vehicle under the surface) says whether the contact went on. Costly (two sweeps a pair
/// of parts): for intervals in which a first sweep already found contact, so that leaving a
/// wing of a building (or the ground) and entering the next within one interval is two
/// collisions.
pub fn contact_spans(
    a0: &Placed<'_>,
    a1: &Placed<'_>,
    b0: &Placed<'_>,
    b1: &Placed<'_>,
    inside: &dyn Fn(f64) -> bool,
) -> smallvec::SmallVec<[(SweepHit, f64); 2]> {
    let (pa0, pa1) = (convex_parts(a0), convex_parts(a1));
    let anchor = a0.position_enu_m;
    let mut spans = match b0.shape.as_trimesh() {
        Some(mesh) => {
            // The triangles near the path, in the mesh's frame (at both ends of its motion).
            let path = pa0
                .iter()
                .zip(&pa1)
                .map(|(p0, p1)| part_reach(anchor, p0, p1))
                .reduce(|x, y| x.merged(&y));
            let Some(path) = path else {
                return smallvec::SmallVec::new();
            };
            let near = |b: &Placed<'_>| path.transform_by(&b.pose_about(anchor).inverse());
            let query = near(b0).merged(&near(b1));
            let triangles: Vec<parry3d::shape::Triangle> = mesh
                .bvh()
                .intersect_aabb(&query)
                .take(MAX_SPAN_TRIANGLES)
                .map(|i| mesh.triangle(i))
                .collect();
            let as_parts = |b: &Placed<'_>| -> Vec<Placed<'_>> {
                triangles
                    .iter()
                    .map(|t| Placed {
                        shape: t,
                        position_enu_m: b.position_enu_m,
                        enu_from_shape: b.enu_from_shape,
                        pivot_local_m: b.pivot_local_m,
                    })
                    .collect()
            };
            let (pb0, pb1) = (as_parts(b0), as_parts(b1));
            pair_spans(anchor, &pa0, &pa1, &pb0, &pb1)
        }
        None => {
            let (pb0, pb1) = (convex_parts(b0), convex_parts(b1));
            pair_spans(anchor, &pa0, &pa1, &pb0, &pb1)
        }
    };
    spans.sort_by(|x, y| x.0.fraction.total_cmp(&y.0.fraction));
    let mut merged: smallvec::SmallVec<[(SweepHit, f64); 2]> = smallvec::SmallVec::new();
    for (hit, exit) in spans {
        match merged.last_mut() {
            Some(last)
                if hit.fraction <= last.1 + 1e-9 || inside(0.5 * (last.1 + hit.fraction)) =>
            {
                last.1 = last.1.max(exit)
            }
            _ => merged.push((hit, exit)),
        }
    }
    merged
}

/// A convex part's bounds over the interval (about `anchor`; a turning part's bounds at the two
/// ends, grown by how far its corners can swing in between).
fn part_reach(anchor: DVec3, p0: &Placed<'_>, p1: &Placed<'_>) -> parry3d::bounding_volume::Aabb {
    let (b0, b1) = (
        p0.shape.compute_aabb(&p0.pose_about(anchor)),
        p1.shape.compute_aabb(&p1.pose_about(anchor)),
    );
    let swing = rotation_between(p0, p1).to_scaled_axis().length() as f32
        * (b0.half_extents().length() + p0.pivot_local_m.length());
    b0.merged(&b1).loosened(swing + CONTACT_TOLERANCE_M as f32)
}

/// The span of contact of every pair of convex parts whose bounds over the interval meet.
fn pair_spans(
    anchor: DVec3,
    pa0: &[Placed<'_>],
    pa1: &[Placed<'_>],
    pb0: &[Placed<'_>],
    pb1: &[Placed<'_>],
) -> smallvec::SmallVec<[(SweepHit, f64); 8]> {
    let reach_a: smallvec::SmallVec<[_; 8]> = pa0
        .iter()
        .zip(pa1)
        .map(|(p0, p1)| part_reach(anchor, p0, p1))
        .collect();
    let mut spans = smallvec::SmallVec::new();
    for (j, (b0, b1)) in pb0.iter().zip(pb1).enumerate() {
        let reach_b = part_reach(anchor, b0, b1);
        for (i, (a0, a1)) in pa0.iter().zip(pa1).enumerate() {
            if !reach_a[i].intersects(&reach_b) {
                continue;
            }
            let Some(enter) = sweep(a0, a1, &pb0[j], &pb1[j]) else {
                continue;
            };
            let exit = sweep(a1, a0, b1, b0).map_or(enter.fraction, |back| 1.0 - back.fraction);
            spans.push((enter, exit.max(enter.fraction)));
        }
    }
    spans
}

/// A time of impact found from `start` on, as a fraction of the whole interval.
trait FromStart {
    fn transform_toi(self, start: f32) -> Self;
}

impl FromStart for parry3d::query::ShapeCastHit {
    fn transform_toi(mut self, start: f32) -> Self {
        self.time_of_impact += start;
        self
    }
}

/// Distance along a ray from `origin_enu_m` in direction `dir_enu` (normalised here; a zero or
/// non-finite direction hits nothing) to the placed shape, up to `max_m`.
pub fn ray_distance_m(
    origin_enu_m: DVec3,
    dir_enu: DVec3,
    max_m: f64,
    b: &Placed<'_>,
) -> Option<f64> {
    let dir_enu = dir_enu.try_normalize()?;
    if !(origin_enu_m.is_finite() && max_m >= 0.0) {
        return None;
    }
    let anchor = origin_enu_m;
    let ray = Ray::new(Vec3::ZERO, dir_enu.as_vec3());
    b.shape
        .cast_ray(&b.pose_about(anchor), &ray, max_m as f32, true)
        .map(f64::from)
}
