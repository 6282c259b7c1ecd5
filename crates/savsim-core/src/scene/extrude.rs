//! A polygon with holes extruded between two heights: a closed triangle mesh (floor, roof and
//! walls, every triangle facing out), as an OSM building is modelled.

use glam::{DVec2, Vec3};

use crate::scene::geometry::{Geometry, GeometryError};

/// Twice the signed area of a ring (positive counter-clockwise).
fn signed_area2(ring: &[DVec2]) -> f64 {
    let n = ring.len();
    (0..n).map(|i| ring[i].perp_dot(ring[(i + 1) % n])).sum()
}

/// The prism over `outer` (with `holes`) from `base_m` to `top_m`, in the frame the rings are
/// given in (x east, y north, z up). Outer rings are taken counter-clockwise and holes
/// clockwise whatever their order as written.
///
/// ```
/// use glam::DVec2;
/// let square = [DVec2::new(0.0, 0.0), DVec2::new(10.0, 0.0), DVec2::new(10.0, 10.0), DVec2::new(0.0, 10.0)];
/// let g = savsim_core::scene::extrude::prism(&square, &[], 0.0, 5.0).unwrap();
/// // Floor and roof: 2 triangles each; 4 walls of 2.
/// assert_eq!(g.triangle_count(), 12);
/// ```
pub fn prism(
    outer: &[DVec2],
    holes: &[Vec<DVec2>],
    base_m: f64,
    top_m: f64,
) -> Result<Geometry, GeometryError> {
    let oriented = |ring: &[DVec2], ccw: bool| -> Vec<DVec2> {
        let mut r = ring.to_vec();
        if (signed_area2(&r) > 0.0) != ccw {
            r.reverse();
        }
        r
    };
    let mut rings = vec![oriented(outer, true)];
    rings.extend(holes.iter().map(|h| oriented(h, false)));
    // Flat: every ring's points in order, with the start of each hole.
    let flat: Vec<DVec2> = rings.iter().flatten().copied().collect();
    let mut hole_starts = Vec::new();
    let mut at = rings[0].len();
    for r in &rings[1..] {
        hole_starts.push(at);
        at += r.len();
    }
    let n = flat.len() as u32;
    let mut vertices: Vec<Vec3> = Vec::with_capacity(2 * flat.len());
    for z in [base_m, top_m] {
        vertices.extend(
            flat.iter()
                .map(|p| Vec3::new(p.x as f32, p.y as f32, z as f32)),
        );
    }
    let mut cap: Vec<usize> = Vec::new();
    earcut::Earcut::new().earcut(flat.iter().map(|p| [p.x, p.y]), &hole_starts, &mut cap);
    let mut triangles: Vec<[u32; 3]> = Vec::with_capacity(cap.len() / 3 * 2 + 2 * flat.len());
    for t in cap.chunks_exact(3) {
        let [a, b, c] = [t[0] as u32, t[1] as u32, t[2] as u32];
        let up = (flat[t[1]] - flat[t[0]]).perp_dot(flat[t[2]] - flat[t[0]]) > 0.0;
        // Roof facing up, floor facing down.
        let (roof, floor) = if up {
            ([a + n, b + n, c + n], [a, c, b])
        } else {
            ([a + n, c + n, b + n], [a, b, c])
        };
        triangles.push(roof);
        triangles.push(floor);
    }
    let mut start = 0u32;
    for r in &rings {
        let len = r.len() as u32;
        for i in 0..len {
            let (a, b) = (start + i, start + (i + 1) % len);
            // Counter-clockwise outer, clockwise holes: outward is to the right of a -> b.
            triangles.push([a, b, b + n]);
            triangles.push([a, b + n, a + n]);
        }
        start += len;
    }
    Geometry::mesh(vertices, triangles)
}
