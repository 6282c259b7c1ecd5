//! Every span of contact within one interval, not only the first: a body's convex parts (a
//! compound's blocks, a mesh's or height field's triangles near the path) swept pair by pair, forwards for the
//! entry and backwards for the exit, and the spans joined. Costly; used where a first sweep
//! already found contact.

use glam::DVec3;
use parry3d::bounding_volume::BoundingVolume;

use crate::collision::contact::distance::CONTACT_TOLERANCE_M;
use crate::collision::contact::queries::{rotation_between, sweep, Placed};

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

/// Every contact of the interval, not only the first: the times (fractions) during which body
/// `a` (from `a0` to `a1`) touches body `b` (from `b0` to `b1`), as disjoint spans (entry,
/// exit) in order. Compounds are split into their convex parts, a triangle mesh or height
/// field into every triangle near the path (all of them: slow for a long path over a fine
/// mesh, never a guess); a pair of convex parts touches over one span, found
/// by a sweep forwards (entry) and one backwards (exit). `solid` are spans known otherwise
/// (terrain: the vehicle's reference point under the surface), joined in. Costly (two sweeps a
/// pair of parts): for intervals in which a first sweep already found contact, so that leaving
/// a wing of a building (or the ground) and entering the next within one interval is two
/// collisions.
pub fn contact_spans(
    a0: &Placed<'_>,
    a1: &Placed<'_>,
    b0: &Placed<'_>,
    b1: &Placed<'_>,
    solid: &[(f64, f64)],
) -> smallvec::SmallVec<[(f64, f64); 2]> {
    let (pa0, pa1) = (convex_parts(a0), convex_parts(a1));
    let anchor = a0.position_enu_m;
    let surface = b0.shape.as_trimesh().is_some() || b0.shape.as_heightfield().is_some();
    let mut spans = if surface {
        // The triangles near the path, in the surface's frame (at both ends of its motion).
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
        let mut triangles: Vec<parry3d::shape::Triangle> = Vec::new();
        if let Some(mesh) = b0.shape.as_trimesh() {
            triangles.extend(mesh.bvh().intersect_aabb(&query).map(|i| mesh.triangle(i)));
        } else if let Some(field) = b0.shape.as_heightfield() {
            field.map_elements_in_local_aabb(&query, &mut |_, t| triangles.push(*t));
        }
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
    } else {
        let (pb0, pb1) = (convex_parts(b0), convex_parts(b1));
        pair_spans(anchor, &pa0, &pa1, &pb0, &pb1)
    };
    spans.extend_from_slice(solid);
    spans.sort_by(|x, y| x.0.total_cmp(&y.0));
    let mut merged: smallvec::SmallVec<[(f64, f64); 2]> = smallvec::SmallVec::new();
    for (enter, exit) in spans {
        match merged.last_mut() {
            Some(last) if enter <= last.1 + 1e-9 => last.1 = last.1.max(exit),
            _ => merged.push((enter, exit)),
        }
    }
    let closed = b0
        .shape
        .as_trimesh()
        .is_some_and(|m| m.pseudo_normals_if_oriented().is_some());
    if closed {
        fill_inside(&mut merged, |u| {
            super::queries::intersects_at(a0, a1, b0, b1, u)
        });
    }
    merged
}

/// A closed mesh is a solid, but its spans come from its triangles: a vehicle that goes
/// through a wall and out of the far one within the interval crosses two triangles and is
/// inside between them. Each stretch between spans (and before the first, after the last)
/// where the vehicle is inside at its middle (no triangle is touched within it, so the middle
/// speaks for all of it) is contact: joined to its neighbours.
fn fill_inside(merged: &mut smallvec::SmallVec<[(f64, f64); 2]>, inside_at: impl Fn(f64) -> bool) {
    let mut bounds: smallvec::SmallVec<[f64; 6]> = smallvec::smallvec![0.0];
    for &(enter, exit) in merged.iter() {
        bounds.extend([enter, exit]);
    }
    bounds.push(1.0);
    let mut filled: smallvec::SmallVec<[(f64, f64); 2]> = smallvec::SmallVec::new();
    let mut push = |span: (f64, f64)| match filled.last_mut() {
        Some(last) if span.0 <= last.1 + 1e-9 => last.1 = last.1.max(span.1),
        _ => filled.push(span),
    };
    for (k, pair) in bounds.chunks(2).enumerate() {
        let (from, to) = (pair[0], pair[1]);
        if to > from + 1e-9 && inside_at(0.5 * (from + to)) {
            push((from, to));
        }
        if let Some(&span) = merged.get(k) {
            push(span);
        }
    }
    *merged = filled;
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
) -> smallvec::SmallVec<[(f64, f64); 8]> {
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
            let exit = sweep(a1, a0, b1, b0).map_or(enter, |back| 1.0 - back);
            spans.push((enter, exit.max(enter)));
        }
    }
    spans
}
