//! Where in the scene the flights go: obstacles nearest the centre, towers' faces, clear
//! street lines, lines through concave obstacles that clear their blocks by a chosen gap, and
//! the thinnest obstacle near the centre. Each answer is found in the scene's own boxes and
//! blocks; none depends on a flight.

use glam::{DQuat, DVec3};

use crate::scene::geometry::GeometrySource;
use crate::scene::{Aabb64, Scene};

/// Axis-aligned blocks of a static obstacle, scene ENU metres (None when it is rotated or not
/// made of boxes).
pub(super) fn enu_blocks(scene: &Scene, index: usize) -> Option<Vec<Aabb64>> {
    let o = &scene.obstacles[index];
    if o.placement.enu_from_local.angle_between(DQuat::IDENTITY) > 1e-9 {
        return None;
    }
    let at = |min: glam::Vec3, max: glam::Vec3| {
        Aabb64::new(
            o.placement.position_enu_m + min.as_dvec3(),
            o.placement.position_enu_m + max.as_dvec3(),
        )
    };
    match &o.geometry.source {
        GeometrySource::Cuboid { min, max } => Some(vec![at(*min, *max)]),
        GeometrySource::Blocks { blocks, .. } => {
            Some(blocks.iter().map(|(min, max)| at(*min, *max)).collect())
        }
        _ => None,
    }
}

/// Static obstacles other than terrain, nearest the scene's centre first.
pub(super) fn by_distance(scene: &Scene, centre: DVec3) -> Vec<usize> {
    let mut order: Vec<usize> = (0..scene.obstacles.len())
        .filter(|&i| !scene.obstacles[i].geometry.is_terrain())
        .collect();
    let key = |i: &usize| {
        let c = scene.obstacles[*i].aabb_enu_m.centre();
        ((c.x - centre.x).hypot(c.y - centre.y) * 1000.0) as i64
    };
    order.sort_by_key(|i| (key(i), *i));
    order
}

/// The gap between two axis-aligned rectangles in one plane (0 when they overlap).
fn rect_gap(a: [f64; 4], b: [f64; 4]) -> f64 {
    let gx = (b[0] - a[2]).max(a[0] - b[2]).max(0.0);
    let gy = (b[1] - a[3]).max(a[1] - b[3]).max(0.0);
    gx.hypot(gy)
}

/// Offset (across the line) of a clear line `agl` metres up through `centre`, along x or y,
/// `half` each way, at least `margin_m` from every obstacle's box.
pub(super) fn clear_line(
    scene: &Scene,
    centre: DVec3,
    along_x: bool,
    agl_m: f64,
    half: f64,
    margin_m: f64,
) -> Option<f64> {
    (0..400)
        .map(|k| if k % 2 == 0 { k / 2 } else { -(k / 2 + 1) })
        .find_map(|k| {
            let offset = f64::from(k) * 2.0;
            let (a, b) = street_ends(centre, along_x, offset, half, agl_m);
            let path = Aabb64::new(a.min(b), a.max(b)).inflated(margin_m);
            (!scene
                .obstacles
                .iter()
                .any(|o| o.aabb_enu_m.intersects(&path)))
            .then_some(offset)
        })
}

/// The ends of a street line `offset` metres across the centre line, along x or y, `half`
/// each way from `centre`, at height `agl_m` (scenes without terrain).
pub(super) fn street_ends(
    centre: DVec3,
    along_x: bool,
    offset: f64,
    half: f64,
    agl_m: f64,
) -> (DVec3, DVec3) {
    if along_x {
        (
            DVec3::new(centre.x - half, centre.y + offset, agl_m),
            DVec3::new(centre.x + half, centre.y + offset, agl_m),
        )
    } else {
        (
            DVec3::new(centre.x + offset, centre.y - half, agl_m),
            DVec3::new(centre.x + offset, centre.y + half, agl_m),
        )
    }
}

/// A level line through obstacle `i`'s bounding box, along x or y, that clears its blocks by
/// about `target_m` (the vehicle's half extents `(side, up)` included): the obstacle nearest
/// the centre with such a line, not in `used`. Returns the obstacle, the line's ends and the
/// clearance.
pub(super) fn concave_pass(
    scene: &Scene,
    order: &[usize],
    target_m: f64,
    vehicle_half_m: (f64, f64),
    used: &[usize],
) -> Option<(usize, DVec3, DVec3, f64)> {
    for &i in order.iter().take(400) {
        if used.contains(&i) {
            continue;
        }
        let Some(blocks) = enu_blocks(scene, i) else {
            continue;
        };
        if blocks.len() < 2 {
            continue;
        }
        let bb = scene.obstacles[i].aabb_enu_m;
        for along_x in [false, true] {
            // The cross-section: (across, up).
            let across = |b: &Aabb64| {
                if along_x {
                    (b.min.y, b.max.y)
                } else {
                    (b.min.x, b.max.x)
                }
            };
            let (lo, hi) = across(&bb);
            let mut best: Option<(f64, f64, f64)> = None;
            let mut u = lo + 0.25;
            while u < hi {
                let mut z = bb.min.z + vehicle_half_m.1 + 0.25;
                while z < bb.max.z - vehicle_half_m.1 {
                    let me = [
                        u - vehicle_half_m.0,
                        z - vehicle_half_m.1,
                        u + vehicle_half_m.0,
                        z + vehicle_half_m.1,
                    ];
                    let clearance = blocks
                        .iter()
                        .map(|b| {
                            let (a0, a1) = across(b);
                            rect_gap(me, [a0, b.min.z, a1, b.max.z])
                        })
                        .fold(f64::INFINITY, f64::min);
                    if (clearance - target_m).abs() < 0.3
                        && best.is_none_or(|(c, _, _)| {
                            (clearance - target_m).abs() < (c - target_m).abs()
                        })
                    {
                        best = Some((clearance, u, z));
                    }
                    z += 0.5;
                }
                u += 0.5;
            }
            if let Some((clearance, u, z)) = best {
                let (a, b) = if along_x {
                    (
                        DVec3::new(bb.min.x - 15.0, u, z),
                        DVec3::new(bb.max.x + 15.0, u, z),
                    )
                } else {
                    (
                        DVec3::new(u, bb.min.y - 15.0, z),
                        DVec3::new(u, bb.max.y + 15.0, z),
                    )
                };
                return Some((i, a, b, clearance));
            }
        }
    }
    None
}

/// A level line through the middle of the thinnest obstacle (horizontally) among the 200 nearest
/// the centre, across its thin side.
pub(super) fn thin_pass(scene: &Scene, order: &[usize]) -> Option<(usize, DVec3, DVec3)> {
    let i = order.iter().take(200).copied().min_by(|&a, &b| {
        let thin = |i: usize| {
            let s = scene.obstacles[i].aabb_enu_m.max - scene.obstacles[i].aabb_enu_m.min;
            s.x.min(s.y)
        };
        thin(a).total_cmp(&thin(b)).then(a.cmp(&b))
    })?;
    let b = scene.obstacles[i].aabb_enu_m;
    let c = b.centre();
    let size = b.max - b.min;
    let (a, e) = if size.x < size.y {
        (
            DVec3::new(b.min.x - 100.0, c.y, c.z),
            DVec3::new(b.max.x + 100.0, c.y, c.z),
        )
    } else {
        (
            DVec3::new(c.x, b.min.y - 100.0, c.z),
            DVec3::new(c.x, b.max.y + 100.0, c.z),
        )
    };
    Some((i, a, e))
}
