//! Whether a point is inside a closed triangle mesh, by its winding number along one ray:
//! each triangle the ray crosses counts +1 where the ray leaves through it (its outward normal
//! along the ray) and -1 where it enters. A point inside one shell counts 1, inside two
//! overlapping shells 2, outside 0; two blocks stacked face to face (a lower block's roof
//! lying on an upper block's floor) cancel where they meet, whichever face is nearer. parry's
//! `contains_local_point` decides by the nearest face's pseudo-normal, which two coincident
//! faces of opposite sides leave to chance (the residency bench's false collisions).

use glam::DVec3;
use parry3d::bounding_volume::Aabb;
use parry3d::math::Vector;
use parry3d::shape::TriMesh;

/// The ray's direction: nearly up, tilted off every axis so that it meets no edge of a
/// building's axis-aligned faces exactly.
const RAY: DVec3 = DVec3::new(0.013_721, 0.007_919, 0.999_874);

/// True when `p` (the mesh's frame) is inside the closed mesh `mesh` (built oriented: every
/// normal outward).
///
/// ```
/// use parry3d::math::Vector;
/// use parry3d::shape::{TriMesh, TriMeshFlags};
/// use savsim_core::collision::contact::inside_trimesh::inside;
/// // A unit cube, faces outward.
/// let v: Vec<Vector> = (0..8)
///     .map(|k| Vector::new((k & 1) as f32, ((k >> 1) & 1) as f32, ((k >> 2) & 1) as f32))
///     .collect();
/// let faces = vec![
///     [0, 2, 1], [1, 2, 3], [4, 5, 6], [5, 7, 6], [0, 1, 4], [1, 5, 4],
///     [2, 6, 3], [3, 6, 7], [0, 4, 2], [2, 4, 6], [1, 3, 5], [3, 7, 5],
/// ];
/// let cube = TriMesh::with_flags(v, faces, TriMeshFlags::ORIENTED).unwrap();
/// assert!(inside(&cube, glam::DVec3::splat(0.5)));
/// assert!(!inside(&cube, glam::DVec3::new(0.5, 0.5, 1.5)));
/// ```
pub fn inside(mesh: &TriMesh, p: DVec3) -> bool {
    let bounds = mesh.local_aabb();
    let pf = p.as_vec3();
    if !bounds.contains_local_point(pf) {
        return false;
    }
    // The ray's reach inside the bounds: up to their top, drifting sideways by its tilt.
    let rise_m = f64::from(bounds.maxs.z) - p.z + 1.0;
    let end = p + RAY * (rise_m / RAY.z);
    let column = Aabb::new(
        Vector::new(pf.x.min(end.x as f32), pf.y.min(end.y as f32), pf.z) - Vector::splat(1e-3),
        Vector::new(pf.x.max(end.x as f32), pf.y.max(end.y as f32), end.z as f32)
            + Vector::splat(1e-3),
    );
    let winding: i32 = mesh
        .bvh()
        .intersect_aabb(&column)
        .map(|i| crossing(&mesh.triangle(i), p))
        .sum();
    winding > 0
}

/// +1 when the ray from `p` leaves through triangle `t`, -1 when it enters, 0 when it misses
/// (Moller-Trumbore, in f64).
fn crossing(t: &parry3d::shape::Triangle, p: DVec3) -> i32 {
    let [a, b, c] = [t.a, t.b, t.c].map(|v| v.as_dvec3());
    let (e1, e2) = (b - a, c - a);
    let h = RAY.cross(e2);
    let det = e1.dot(h);
    if det.abs() < 1e-12 {
        return 0;
    }
    let s = p - a;
    let u = s.dot(h) / det;
    if !(0.0..=1.0).contains(&u) {
        return 0;
    }
    let q = s.cross(e1);
    let v = RAY.dot(q) / det;
    if v < 0.0 || u + v > 1.0 {
        return 0;
    }
    if e2.dot(q) / det <= 0.0 {
        return 0;
    }
    // The normal e1 x e2 along the ray: leaving.
    if e1.cross(e2).dot(RAY) > 0.0 {
        1
    } else {
        -1
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use parry3d::shape::TriMeshFlags;

    /// A closed box from `lo` to `hi`, faces outward.
    fn cuboid(lo: [f32; 3], hi: [f32; 3], v: &mut Vec<Vector>, f: &mut Vec<[u32; 3]>) {
        let base = v.len() as u32;
        for k in 0..8 {
            let pick = |axis: usize| {
                if (k >> axis) & 1 == 1 {
                    hi[axis]
                } else {
                    lo[axis]
                }
            };
            v.push(Vector::new(pick(0), pick(1), pick(2)));
        }
        for [a, b, c] in [
            [0, 2, 1],
            [1, 2, 3],
            [4, 5, 6],
            [5, 7, 6],
            [0, 1, 4],
            [1, 5, 4],
            [2, 6, 3],
            [3, 6, 7],
            [0, 4, 2],
            [2, 4, 6],
            [1, 3, 5],
            [3, 7, 5],
        ] {
            f.push([base + a, base + b, base + c]);
        }
    }

    /// A building of two blocks stacked face to face (the upper one wider): every point in
    /// either block is inside, the seam included, and the air beside the lower block under
    /// the upper one's overhang is outside. parry's nearest-face test answers some of these
    /// wrong (the residency bench's b1932).
    #[test]
    fn stacked_blocks_are_inside_across_their_seam_and_the_overhang_is_not() {
        let (mut v, mut f) = (Vec::new(), Vec::new());
        cuboid([-12.7, -12.7, 0.0], [12.7, 12.7, 43.2], &mut v, &mut f);
        cuboid([-40.0, -40.0, 43.2], [40.0, 40.0, 98.9], &mut v, &mut f);
        let mesh = TriMesh::with_flags(v, f, TriMeshFlags::ORIENTED).unwrap();
        for z in [1.0, 40.0, 43.1, 43.2, 43.3, 60.0, 98.0] {
            for x in [-12.0, 0.0, 3.3, 12.6] {
                assert!(inside(&mesh, DVec3::new(x, 0.5, z)), "{x} {z}");
            }
        }
        for (x, z) in [
            (20.0, 40.0),
            (-30.0, 1.0),
            (0.0, 99.5),
            (50.0, 60.0),
            (0.0, -1.0),
        ] {
            assert!(!inside(&mesh, DVec3::new(x, 0.5, z)), "{x} {z}");
        }
        // Two shells overlapping: inside both counts 2, still inside.
        let (mut v, mut f) = (Vec::new(), Vec::new());
        cuboid([0.0; 3], [10.0; 3], &mut v, &mut f);
        cuboid([5.0; 3], [15.0; 3], &mut v, &mut f);
        let overlapping = TriMesh::with_flags(v, f, TriMeshFlags::ORIENTED).unwrap();
        assert!(inside(&overlapping, DVec3::splat(7.0)));
        assert!(inside(&overlapping, DVec3::splat(12.0)));
        assert!(!inside(&overlapping, DVec3::new(2.0, 12.0, 2.0)));
    }
}
