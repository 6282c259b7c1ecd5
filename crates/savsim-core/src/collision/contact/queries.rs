//! Exact queries between placed shapes, computed in f32 about a local anchor.
//!
//! Scene positions are f64; parry works in f32. Every query subtracts an anchor (the first
//! body's position) in f64 before converting, so a vehicle 1000 km from the scene origin is
//! tested with millimetre precision, not the 6 cm that f32 has at 10^6 m.

use glam::{DQuat, DVec3, Vec3};
use parry3d::bounding_volume::BoundingVolume;
use parry3d::math::Pose;
use parry3d::query::{self, NonlinearRigidMotion, Ray, ShapeCastOptions};
use parry3d::shape::Shape;

use crate::collision::contact::distance::{
    shape_distance, shapes_intersect, Dispatcher, CONTACT_TOLERANCE_M,
};
use parry3d::query::QueryDispatcher;

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
    pub(crate) fn pivot_enu_m(&self) -> DVec3 {
        self.position_enu_m + self.enu_from_shape * self.pivot_local_m.as_dvec3()
    }

    pub(crate) fn pose_about(&self, anchor: DVec3) -> Pose {
        Pose::from_parts(
            (self.position_enu_m - anchor).as_vec3(),
            self.enu_from_shape.as_quat().normalize(),
        )
    }
}

/// True when the two placed shapes overlap or touch (within [`CONTACT_TOLERANCE_M`]).
pub fn intersects(a: &Placed<'_>, b: &Placed<'_>) -> bool {
    let anchor = a.position_enu_m;
    let (pa, pb) = (a.pose_about(anchor), b.pose_about(anchor));
    if shapes_intersect(&pa, a.shape, &pb, b.shape) {
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

pub(crate) fn rotation_between(from: &Placed<'_>, to: &Placed<'_>) -> DQuat {
    let delta = to.enu_from_shape * from.enu_from_shape.inverse();
    if delta.w < 0.0 {
        -delta
    } else {
        delta
    }
}

/// Casts restarted after a hit that an exact distance query does not confirm (parry's
/// conservative advancement can stop short of a contact on a near-grazing pass, and lose
/// precision on very large triangles); past them, [`advance_on_distance`] takes the rest of
/// the interval.
const MAX_RECASTS: usize = 64;

/// The contact tolerance for two shapes: [`CONTACT_TOLERANCE_M`], grown with the shapes' size
/// where f32 loses it (a 10 km mesh has vertices 5 km from the anchor).
pub(crate) fn tolerance_m(a: &dyn Shape, b: &dyn Shape) -> f32 {
    // Only triangle meshes reach sizes where f32 matters (boxes and blocks are tested part by
    // part, in the frame of the part).
    let size = |s: &dyn Shape| match (s.as_trimesh(), s.as_heightfield()) {
        (Some(m), _) => m.local_aabb().half_extents().length(),
        (_, Some(f)) => f.root_aabb().half_extents().length(),
        _ => 0.0,
    };
    CONTACT_TOLERANCE_M as f32 + 1e-6 * size(a).max(size(b))
}

/// How far the gap between body `a` (from `a0` to `a1`) and body `b` (from `b0` to `b1`) can
/// close over the interval, metres: their relative travel plus how far the farthest point of
/// each can swing about its pivot (screw motion). The gap at fraction `u` is at least the gap
/// at the start minus `u` times this, and at least the gap at the end minus `1 - u` times it.
pub fn closing_bound_m(a0: &Placed<'_>, a1: &Placed<'_>, b0: &Placed<'_>, b1: &Placed<'_>) -> f64 {
    let reach = |p: &Placed<'_>| {
        let local = p.shape.compute_local_aabb();
        f64::from(local.maxs.abs().max(local.mins.abs()).length() + p.pivot_local_m.length())
    };
    let travel = (b1.pivot_enu_m() - b0.pivot_enu_m()) - (a1.pivot_enu_m() - a0.pivot_enu_m());
    travel.length()
        + rotation_between(a0, a1).to_scaled_axis().length() * reach(a0)
        + rotation_between(b0, b1).to_scaled_axis().length() * reach(b0)
}

/// Where two bodies touch at fraction `fraction` of the interval: the contact point (scene ENU
/// metres) and normal (out of `b`), at the screw-motion poses of that instant. For an event's
/// report; the sweep itself only finds the time.
pub fn locate(
    a0: &Placed<'_>,
    a1: &Placed<'_>,
    b0: &Placed<'_>,
    b1: &Placed<'_>,
    fraction: f64,
) -> (DVec3, DVec3) {
    let anchor = a0.position_enu_m;
    let (ma, mb) = (motion(anchor, a0, a1), motion(anchor, b0, b1));
    let t = fraction.clamp(0.0, 1.0) as f32;
    let (pose_a, pose_b) = (ma.position_at_time(t), mb.position_at_time(t));
    let tolerance = tolerance_m(a0.shape, b0.shape);
    match query::contact(&pose_a, a0.shape, &pose_b, b0.shape, 2.0 * tolerance) {
        Ok(Some(c)) => (
            anchor + c.point2.as_dvec3(),
            (-c.normal1.as_dvec3()).normalize_or_zero(),
        ),
        _ => (anchor + pose_a.translation.as_dvec3(), DVec3::Z),
    }
}

/// Whether the two bodies touch at fraction `fraction` of the interval (their screw-motion
/// poses of that instant; a body inside a closed mesh touches it).
pub fn intersects_at(
    a0: &Placed<'_>,
    a1: &Placed<'_>,
    b0: &Placed<'_>,
    b1: &Placed<'_>,
    fraction: f64,
) -> bool {
    let anchor = a0.position_enu_m;
    let (ma, mb) = (motion(anchor, a0, a1), motion(anchor, b0, b1));
    let t = fraction.clamp(0.0, 1.0) as f32;
    shapes_intersect(
        &ma.position_at_time(t),
        a0.shape,
        &mb.position_at_time(t),
        b0.shape,
    )
}

/// When body `a` moving from `a0` to `a1` first touches body `b` moving from `b0` to `b1` over
/// one interval: the fraction of the interval, in [0, 1] (screw motion: linear translation,
/// constant rotation rate; a pure translation when neither body turns). Bodies that already
/// touch at the start give 0. Every hit is confirmed by an exact distance query at its poses;
/// an unconfirmed one restarts the cast past it, by no more than the bodies could close in the
/// meantime. Where they touch is [`locate`]'s.
pub fn sweep(a0: &Placed<'_>, a1: &Placed<'_>, b0: &Placed<'_>, b1: &Placed<'_>) -> Option<f64> {
    let anchor = a0.position_enu_m;
    // Already touching at the start: an exact test (a cast from inside can lose the contact on
    // very large triangles).
    if intersects(a0, b0) {
        return Some(0.0);
    }
    let turning = |from: &Placed<'_>, to: &Placed<'_>| {
        rotation_between(from, to).to_scaled_axis().length() > LINEAR_SWEEP_MAX_ROTATION_RAD
    };
    let ma = motion(anchor, a0, a1);
    let mb = motion(anchor, b0, b1);
    let linear = !turning(a0, a1) && !turning(b0, b1);
    let tolerance = tolerance_m(a0.shape, b0.shape);
    // How fast the gap can close, metres per interval.
    let closing = closing_bound_m(a0, a1, b0, b1) as f32;
    let poses_at = |t: f32| (ma.position_at_time(t), mb.position_at_time(t));
    let gap_at = |t: f32| {
        let (pa, pb) = poses_at(t);
        shape_distance(&pa, a0.shape, &pb, b0.shape)
    };
    // `start` is always a time known to be clear.
    let mut start = 0.0f32;
    let mut casts = 0;
    while start < 1.0 {
        if casts == MAX_RECASTS {
            // A long grazing pass: the rest by conservative advancement on exact distances.
            if let Some(toi) = advance_on_distance(start, closing, tolerance, &gap_at) {
                return Some(f64::from(toi));
            }
            break;
        }
        casts += 1;
        let cast = if linear {
            let pa = ma.position_at_time(start);
            let pb = mb.position_at_time(start);
            let options = ShapeCastOptions {
                max_time_of_impact: 1.0 - start,
                stop_at_penetration: true,
                ..ShapeCastOptions::default()
            };
            Dispatcher
                .cast_shapes(
                    &pa.inv_mul(&pb),
                    pa.rotation.inverse() * (mb.linvel - ma.linvel),
                    a0.shape,
                    b0.shape,
                    options,
                )
                .ok()
                .flatten()
                .map(|hit| hit.time_of_impact + start)
        } else {
            Dispatcher
                .cast_shapes_nonlinear(&ma, a0.shape, &mb, b0.shape, start, 1.0, true)
                .ok()
                .flatten()
                .map(|hit| hit.time_of_impact)
        };
        let Some(toi) = cast else { break };
        let toi = toi.clamp(0.0, 1.0);
        let gap = gap_at(toi);
        if gap <= tolerance {
            // A linear cast's time is exact; conservative advancement can stop past the touch.
            let toi = if linear {
                toi
            } else {
                bisect_first(start, toi, 24, |t| gap_at(t) <= tolerance)
            };
            return Some(f64::from(toi));
        }
        // Not touching there: no contact can come sooner than the gap closes.
        let advance = if closing > 0.0 { gap / closing } else { 1.0 };
        start = toi + advance.max(MIN_ADVANCE);
    }
    // The cast found nothing (or gave up): a contact that holds at the end of the interval
    // still began in it. Its start is bisected on the exact overlap test (distances lose
    // precision against very large triangles); a touch only within the tolerance is at the end.
    if gap_at(1.0) > tolerance {
        return None;
    }
    let overlaps_at = |t: f32| {
        let (pa, pb) = poses_at(t);
        shapes_intersect(&pa, a0.shape, &pb, b0.shape)
    };
    let toi = if overlaps_at(1.0) {
        bisect_first(start.min(1.0), 1.0, 24, overlaps_at)
    } else {
        1.0
    };
    Some(f64::from(toi))
}

/// The smallest step (a fraction of the interval) an advancement takes: at most 10^5 steps an
/// interval; a touch closer than this step times the closing distance is within the tolerance
/// of any body the size of a vehicle.
const MIN_ADVANCE: f32 = 1e-5;

/// Conservative advancement from `start` (known clear): each step as long as the gap cannot
/// close in it (gap over the closing bound), with exact distances; the first time the gap is
/// within `tolerance`, bisected, or `None` if none comes before the end.
fn advance_on_distance(
    start: f32,
    closing: f32,
    tolerance: f32,
    gap_at: &impl Fn(f32) -> f32,
) -> Option<f32> {
    let (mut clear, mut t) = (start, start);
    loop {
        let gap = gap_at(t);
        if gap <= tolerance {
            return Some(bisect_first(clear, t, 24, |u| gap_at(u) <= tolerance));
        }
        if t >= 1.0 {
            return None;
        }
        clear = t;
        let step = if closing > 0.0 { gap / closing } else { 1.0 };
        t = (t + step.max(MIN_ADVANCE)).min(1.0);
    }
}

/// The first instant at which `holds` becomes true, between `clear` (false there) and `hit`
/// (true there), by `rounds` halvings of the span (one change between them assumed).
pub(crate) fn bisect_first<T: num_traits::Float>(
    mut clear: T,
    mut hit: T,
    rounds: u32,
    holds: impl Fn(T) -> bool,
) -> T {
    let two = T::one() + T::one();
    for _ in 0..rounds {
        let mid = (clear + hit) / two;
        if holds(mid) {
            hit = mid;
        } else {
            clear = mid;
        }
    }
    hit
}

/// Where a ray from `o` along `d` (in a box's frame) enters the box of half extents `h`
/// centred on the frame's origin, within `max_m`; 0 from inside (a solid). The slab test in
/// f64.
fn ray_cuboid(o: DVec3, d: DVec3, h: DVec3, max_m: f64) -> Option<f64> {
    let (mut t0, mut t1) = (0.0f64, max_m);
    for a in 0..3 {
        if d[a] == 0.0 {
            if o[a].abs() > h[a] {
                return None;
            }
            continue;
        }
        let (mut ta, mut tb) = ((-h[a] - o[a]) / d[a], (h[a] - o[a]) / d[a]);
        if ta > tb {
            std::mem::swap(&mut ta, &mut tb);
        }
        t0 = t0.max(ta);
        t1 = t1.min(tb);
        if t0 > t1 {
            return None;
        }
    }
    Some(t0)
}

/// Distance along a ray from `origin_enu_m` in direction `dir_enu` (normalised here; a zero or
/// non-finite direction hits nothing) to the placed shape, up to `max_m`. From inside a solid
/// (a box, a compound, a closed mesh) the distance is 0.
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
    if let Some(field) = b.shape.as_heightfield() {
        // parry's height-field cast misses near-vertical rays: savsim's own, in f64.
        let to_shape = b.enu_from_shape.inverse();
        let origin = to_shape * (origin_enu_m - b.position_enu_m);
        return crate::collision::contact::ray_height_field::cast(
            field,
            origin,
            to_shape * dir_enu,
            max_m,
        );
    }
    if let Some(cuboid) = b.shape.as_cuboid() {
        // A box in f64 (parry's cast is f32: micrometres off at metres).
        let to_shape = b.enu_from_shape.inverse();
        return ray_cuboid(
            to_shape * (origin_enu_m - b.position_enu_m),
            to_shape * dir_enu,
            cuboid.half_extents.as_dvec3(),
            max_m,
        );
    }
    let anchor = origin_enu_m;
    if let Some(mesh) = b
        .shape
        .as_trimesh()
        .filter(|m| m.pseudo_normals_if_oriented().is_some())
    {
        let local = b.enu_from_shape.inverse() * (origin_enu_m - b.position_enu_m);
        if super::inside_trimesh::inside(mesh, local) {
            return Some(0.0);
        }
    }
    let ray = Ray::new(Vec3::ZERO, dir_enu.as_vec3());
    b.shape
        .cast_ray(&b.pose_about(anchor), &ray, max_m as f32, true)
        .map(f64::from)
}
