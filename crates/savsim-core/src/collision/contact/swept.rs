//! The contact layer's `exact` strategy: over one interval, every obstacle the swept vehicle
//! can reach, as its exact shape, swept between the two samples (parry's shape cast; screw
//! motion when a body turns). Before a sweep, two exact shortcuts: a contact that held at the
//! last sample with the vehicle's reference point in one convex part of the obstacle (or
//! under a terrain patch) all along held all through (convexity); and two bodies whose gaps at
//! the two ends add up to more than the gap can close in the interval cannot have touched in
//! it (the gap is 1-Lipschitz in time at the rate [`queries::closing_bound_m`] bounds; for
//! terrain, read off the height grid). Neither guesses: each is a proof, and anything it cannot
//! prove is swept, every span of contact found (`collision::contact::spans`).
//!
//! Pure and synchronous; imports no I/O, no tokio, no rerun.

use glam::DVec3;
use smallvec::SmallVec;

use crate::collision::bodies::{BodyPose, ObstacleRef};
use crate::collision::contact::queries;
use crate::collision::contact::{above_terrain, solid_overlap, Before, Contacts, Motion, Touch};
use crate::collision::meshes::MeshCache;
use crate::collision::placed::{inside_solid, Body};
use crate::collision::view::{view, ObstacleView, World};
use crate::scene::geometry::{Geometry, GeometrySource};
use crate::scene::Aabb64;

/// Slack added to the gap test for the f32 rounding of distances near the anchor, metres.
const GAP_SLACK_M: f64 = 1e-3;

/// A contact held through an interval is proved only for a reference point this far inside a
/// part, metres (f32 shapes, f64 poses).
const INSIDE_MARGIN_M: f64 = 1e-3;

impl Contacts {
    /// The exact strategy over an interval: every reachable obstacle's exact shape, swept.
    /// Returns the exact tests run.
    pub(crate) fn swept(
        &mut self,
        world: &World<'_>,
        meshes: &mut MeshCache,
        band_m: f64,
        motion: &Motion,
        before: Before<'_>,
    ) -> usize {
        let Some(pose_before) = motion.before else {
            return 0;
        };
        let vehicle_geometry = &world.scene.geometries[motion.geometry_index];
        let vehicle = world.shapes.body(
            motion.geometry_index,
            vehicle_geometry,
            meshes,
            motion.now,
            false,
        );
        let interval = Interval {
            world,
            vehicle: &vehicle,
            vehicle_geometry,
            // A contact held all through needs a point of the vehicle that moves in a
            // straight line: its reference point (the screw motion's pivot), if the vehicle
            // holds it.
            holds_own_reference: vehicle_geometry.contains_local_point(glam::Vec3::ZERO),
            reach: motion.swept_box(),
            pose_before,
            band_m,
            motion,
            before,
        };
        let mut tests = 0;
        for k in 0..self.candidates.len() {
            let o = self.candidates[k];
            tests += self.sweep_candidate(&interval, meshes, o);
        }
        self.gaps.sort_unstable_by_key(|g| g.0);
        tests
    }

    /// One candidate over the interval: a contact held all through, contacts swept, or its gap
    /// (kept for the next interval when static; a near miss when within the band). Returns the
    /// exact tests run.
    fn sweep_candidate(
        &mut self,
        s: &Interval<'_>,
        meshes: &mut MeshCache,
        o: ObstacleRef,
    ) -> usize {
        let world = s.world;
        let Some(v) = view(world.scene, world.dynamic, o) else {
            return 0;
        };
        let (p0, p1) = (s.pose_before.position_enu_m, s.motion.now.position_enu_m);
        let r = s.motion.radius_m;
        let near_box = v.aabb_enu_m.distance_to(p1) < s.band_m + r;
        let moved_m = v.current.position_enu_m.distance(v.previous.position_enu_m);
        let could_touch =
            v.aabb_enu_m.inflated(moved_m).intersects(&s.reach) && !above_terrain(&v, &s.reach);
        let near_miss_candidate = near_box && !v.geometry.is_terrain();
        if !(could_touch || near_miss_candidate) {
            return 0;
        }
        let body = world
            .shapes
            .body(v.geometry_index, v.geometry, meshes, v.current, true);
        let mut tests = 0;
        let mut gap_now: Option<f64> = None;
        if could_touch {
            let was_touching = s.before.touching.contains(&o);
            if was_touching
                && s.holds_own_reference
                && matches!(o, ObstacleRef::Static(_))
                && held_throughout(v.geometry, &v.current, p0, p1)
            {
                self.touching.push((
                    o,
                    Touch {
                        point_enu_m: p1,
                        normal_enu: DVec3::Z,
                        fraction: 0.0,
                        swept: true,
                        holds_now: true,
                    },
                ));
                return 0;
            }
            let proof = s.apart(o, &v, &body);
            tests += proof.tests;
            gap_now = proof.gap_now_m;
            if !proof.apart {
                tests += 2;
                let touches = sweep_touches(
                    s.vehicle,
                    s.motion,
                    &body,
                    &v,
                    s.vehicle_geometry,
                    was_touching,
                );
                if !touches.is_empty() {
                    let holds = touches.iter().any(|t| t.holds_now);
                    self.touching.extend(touches.into_iter().map(|t| (o, t)));
                    if holds && matches!(o, ObstacleRef::Static(_)) {
                        self.gaps.push((o, 0.0));
                    }
                    return tests;
                }
            }
        }
        let gap = match gap_now {
            Some(d) => d,
            None if near_miss_candidate => {
                tests += 1;
                queries::distance_m(&s.vehicle.placed(), &body.placed())
            }
            None => return tests,
        };
        if matches!(o, ObstacleRef::Static(_)) {
            self.gaps.push((o, gap));
        }
        if near_miss_candidate && gap < s.band_m {
            self.near.push((o, gap));
        }
        tests
    }
}

/// One interval of the vehicle's motion, the same for every candidate.
struct Interval<'a> {
    world: &'a World<'a>,
    /// The vehicle's exact shape.
    vehicle: &'a Body,
    vehicle_geometry: &'a Geometry,
    /// The vehicle's model holds its own reference point.
    holds_own_reference: bool,
    /// The box the vehicle sweeps.
    reach: Aabb64,
    /// The vehicle's pose at the previous sample.
    pose_before: BodyPose,
    /// The near-miss band, metres.
    band_m: f64,
    motion: &'a Motion,
    before: Before<'a>,
}

/// Whether a candidate was proved apart over the interval, the exact gap at the sample if one
/// was measured for the proof, and the exact tests it took.
struct Proof {
    apart: bool,
    gap_now_m: Option<f64>,
    tests: usize,
}

impl Interval<'_> {
    /// The gap proof: the gaps at the two ends add up to more than the gap can close in the
    /// interval (lower bounds from boxes and spheres first, exact gaps only when needed; the
    /// last interval's exact gap reused), or, for terrain, the vehicle clear of the height grid
    /// by half of that at both ends. Never apart when the vehicle is under the terrain at
    /// either end.
    fn apart(&self, o: ObstacleRef, v: &ObstacleView<'_>, body: &Body) -> Proof {
        let (p0, p1) = (
            self.pose_before.position_enu_m,
            self.motion.now.position_enu_m,
        );
        let r = self.motion.radius_m;
        let mut proof = Proof {
            apart: false,
            gap_now_m: None,
            tests: 0,
        };
        let under_terrain = v.geometry.is_terrain()
            && (inside_solid(v.geometry, &v.current, p0)
                || inside_solid(v.geometry, &v.current, p1));
        if under_terrain {
            return proof;
        }
        let (a0, a1, b0, b1) = (
            self.vehicle.at(self.pose_before),
            self.vehicle.placed(),
            body.at(v.previous),
            body.placed(),
        );
        let closing = queries::closing_bound_m(&a0, &a1, &b0, &b1);
        let slack = 2.0 * f64::from(queries::tolerance_m(a0.shape, b0.shape)) + GAP_SLACK_M;
        // A gap parry could not measure (infinite) proves nothing.
        let beyond = |gaps: f64| gaps.is_finite() && gaps > closing + slack;
        // Terrain: half of that gap at each end, read off the height grid.
        let half_m = (0.5 * (closing + slack) * (1.0 + 1e-6) + 1e-6) as f32;
        let local = |p: DVec3| (p - v.current.position_enu_m).as_vec3();
        let clear = |p: DVec3| v.geometry.terrain_clear_by(local(p), r as f32, half_m);
        // Lower bounds first (boxes and spheres), exact gaps only when needed.
        let lower0 = match o {
            ObstacleRef::Static(_) => v.aabb_enu_m.distance_to(p0) - r,
            ObstacleRef::Dynamic(_) => {
                p0.distance(v.previous.position_enu_m)
                    - r
                    - crate::collision::bodies::radius_m(v.geometry)
            }
        };
        let lower1 = v.aabb_enu_m.distance_to(p1) - r;
        if beyond(lower0 + lower1) || (clear(p0) && clear(p1)) {
            proof.apart = true;
            return proof;
        }
        proof.tests += 1;
        let d1 = queries::distance_m(&a1, &b1);
        proof.gap_now_m = Some(d1);
        if beyond(lower0 + d1) {
            proof.apart = true;
            return proof;
        }
        let cached = self
            .before
            .gaps
            .binary_search_by_key(&o, |g| g.0)
            .ok()
            .map(|i| self.before.gaps[i].1);
        let d0 = cached.unwrap_or_else(|| {
            proof.tests += 1;
            queries::distance_m(&a0, &b0)
        });
        proof.apart = beyond(d0 + d1);
        proof
    }
}

/// True when the reference point is (by a margin) inside one convex part (the box, or one
/// block) of a static solid at both `p0` and `p1`, or under a terrain patch's surface all
/// along the segment between them: the vehicle's reference point on its screw motion (that
/// segment) is then inside the solid all through.
fn held_throughout(geometry: &Geometry, pose: &BodyPose, p0: DVec3, p1: DVec3) -> bool {
    let to_local = |p: DVec3| pose.enu_from_body.inverse() * (p - pose.position_enu_m);
    let (l0, l1) = (to_local(p0), to_local(p1));
    let holds_both = |min: glam::Vec3, max: glam::Vec3| {
        let b = Aabb64::new(
            min.as_dvec3() + INSIDE_MARGIN_M,
            max.as_dvec3() - INSIDE_MARGIN_M,
        );
        b.contains(l0) && b.contains(l1)
    };
    match &geometry.source {
        GeometrySource::Cuboid { min, max } => holds_both(*min, *max),
        GeometrySource::Blocks { blocks, .. } => blocks.iter().any(|(a, b)| holds_both(*a, *b)),
        // Terrain is placed without rotation; under its surface all along the segment.
        GeometrySource::Terrain(_) => {
            geometry.terrain_holds_segment(l0.as_vec3(), l1.as_vec3(), INSIDE_MARGIN_M as f32)
        }
        GeometrySource::Mesh { .. } => false,
    }
}

/// The contacts in the interval (sweep), and whether the last still holds at the sample.
/// Where a contact is, is found only for a contact that will be reported: every one but a
/// first contact that held since the last sample (`was_touching`).
fn sweep_touches(
    vehicle: &Body,
    motion: &Motion,
    body: &Body,
    v: &ObstacleView<'_>,
    vehicle_geometry: &Geometry,
    was_touching: bool,
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
    let (p0, p1) = (before.position_enu_m, motion.now.position_enu_m);
    // Terrain: when the reference point is under this patch (a patch's surface is open at its
    // edges: the vehicle may go under it from its neighbour's ground without touching it).
    let under: SmallVec<[(f64, f64); 4]> = if v.geometry.is_terrain() {
        let local = |p: DVec3| (p - v.current.position_enu_m).as_vec3();
        match v.geometry.terrain_under_runs(local(p0), local(p1)) {
            Some(runs) => runs
                .iter()
                .map(|&(s, e)| (f64::from(s), f64::from(e)))
                .collect(),
            // Too many cells to walk: whether it is under at the two samples.
            None => [0.0, 1.0]
                .into_iter()
                .filter(|&u| inside_solid(v.geometry, &v.current, p0.lerp(p1, u)))
                .map(|u| (u, u))
                .collect(),
        }
    } else {
        SmallVec::new()
    };
    let first = queries::sweep(&a0, &a1, &b0, &b1);
    let first = match (first, under.first()) {
        (Some(f), Some(r)) => Some(f.min(r.0)),
        (f, r) => f.or(r.map(|r| r.0)),
    };
    let Some(first) = first else {
        return touches;
    };
    let holds_now = queries::intersects(&vehicle.placed(), &body.placed())
        || solid_overlap(motion, body, v, vehicle_geometry).is_some();
    // A compound can be left and entered again within one interval (the wings of a building
    // at speed), and so can a surface when the vehicle travels more than its size (the ground
    // of a ridge), or goes under it (from a neighbour's ground): every span of contact is a
    // contact.
    let travel_m = p0.distance(p1);
    let spans = if vehicle.is_compound()
        || body.is_compound()
        || (body.is_surface() && travel_m > 2.0 * motion.radius_m)
        || !under.is_empty()
    {
        crate::collision::contact::spans::contact_spans(&a0, &a1, &b0, &b1, &under)
    } else {
        SmallVec::new()
    };
    let starts: SmallVec<[f64; 2]> = if spans.len() > 1 {
        spans.iter().map(|s| s.0).collect()
    } else {
        smallvec::smallvec![first]
    };
    let last = starts.len() - 1;
    for (k, fraction) in starts.into_iter().enumerate() {
        let (point_enu_m, normal_enu) = if k == 0 && was_touching {
            (p1, DVec3::Z)
        } else if under.iter().any(|r| r.0 == fraction) {
            // Went under the patch: the reference point is where it did.
            (p0.lerp(p1, fraction), DVec3::Z)
        } else {
            queries::locate(&a0, &a1, &b0, &b1, fraction)
        };
        touches.push(Touch {
            point_enu_m,
            normal_enu,
            fraction,
            swept: fraction > 0.0 || !under.first().is_some_and(|r| r.0 == 0.0),
            holds_now: holds_now && k == last,
        });
    }
    touches
}
