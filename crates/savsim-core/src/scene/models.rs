//! Built-in models, made of blocks, in a body Forward-Right-Down frame centred on the body's
//! reference point (metres). Their boxes and meshes differ on purpose: a quadcopter's arms
//! leave most of its box empty, an airliner's wings most of its own.

use glam::Vec3;

use crate::scene::geometry::{Geometry, GeometryError};
use crate::scene::Kind;

/// Names accepted by `model = "..."` in scene files.
pub const MODEL_NAMES: [&str; 6] = ["quad", "a320", "b737", "balloon", "airship", "fixed_wing"];

fn block(centre: [f32; 3], size: [f32; 3]) -> (Vec3, Vec3) {
    let (c, h) = (Vec3::from(centre), Vec3::from(size) * 0.5);
    (c - h, c + h)
}

/// The default vehicle: a "+" quadcopter of 0.5 m motor-to-motor span, 0.62 m over the rotors.
///
/// ```
/// use savsim_core::scene::models::quad;
/// let q = quad();
/// let size = q.local_aabb.maxs - q.local_aabb.mins;
/// assert!((size.x - 0.62).abs() < 1e-6 && (size.y - 0.62).abs() < 1e-6);
/// ```
pub fn quad() -> Geometry {
    let mut blocks = vec![
        block([0.0, 0.0, 0.0], [0.14, 0.14, 0.06]),
        block([0.0, 0.0, 0.0], [0.5, 0.03, 0.02]),
        block([0.0, 0.0, 0.0], [0.03, 0.5, 0.02]),
    ];
    for (x, y) in [(0.25, 0.0), (-0.25, 0.0), (0.0, 0.25), (0.0, -0.25)] {
        blocks.push(block([x, y, -0.03], [0.12, 0.12, 0.01]));
    }
    Geometry::blocks(blocks, 0.0).expect("static model")
}

/// An airliner of the given length, wingspan and fuselage diameter.
fn airliner(length_m: f32, span_m: f32, fuselage_m: f32) -> Geometry {
    let blocks = vec![
        block([0.0, 0.0, 0.0], [length_m, fuselage_m, fuselage_m]),
        block(
            [-0.05 * length_m, 0.0, 0.3 * fuselage_m],
            [0.15 * length_m, span_m, 0.4],
        ),
        block(
            [-0.45 * length_m, 0.0, 0.0],
            [0.08 * length_m, 0.35 * span_m, 0.3],
        ),
        block(
            [-0.45 * length_m, 0.0, -fuselage_m],
            [0.1 * length_m, 0.3, 1.6 * fuselage_m],
        ),
    ];
    Geometry::blocks(blocks, 2.0).expect("static model")
}

/// A small fixed-wing UAV: 1.2 m long, 2 m span.
fn fixed_wing() -> Geometry {
    let blocks = vec![
        block([0.0, 0.0, 0.0], [1.2, 0.12, 0.12]),
        block([0.05, 0.0, -0.04], [0.25, 2.0, 0.02]),
        block([-0.5, 0.0, 0.0], [0.12, 0.5, 0.01]),
        block([-0.5, 0.0, -0.1], [0.12, 0.01, 0.2]),
    ];
    Geometry::blocks(blocks, 0.0).expect("static model")
}

/// A body of revolution about `axis` (0 = x, 2 = z) approximated by `slices` stacked
/// cross-shaped blocks; `radius_at(u)` for u in [-1, 1].
fn revolved(
    length_m: f32,
    axis: usize,
    slices: usize,
    radius_at: impl Fn(f32) -> f32,
) -> Vec<(Vec3, Vec3)> {
    let mut blocks = Vec::new();
    for k in 0..slices {
        let u = -1.0 + (2 * k + 1) as f32 / slices as f32;
        let r = radius_at(u);
        if r <= 0.0 {
            continue;
        }
        let along = u * 0.5 * length_m;
        let thick = length_m / slices as f32;
        for (a, b) in [
            (2.0 * r, 2.0 * r * 0.42),
            (2.0 * r * 0.42, 2.0 * r),
            (2.0 * r * 0.8, 2.0 * r * 0.8),
        ] {
            let (centre, size) = if axis == 0 {
                ([along, 0.0, 0.0], [thick, a, b])
            } else {
                ([0.0, 0.0, along], [a, b, thick])
            };
            blocks.push(block(centre, size));
        }
    }
    blocks
}

/// A hot-air balloon: an 18 m envelope over a basket (z down: the basket is at +z).
fn balloon() -> Geometry {
    let mut blocks = revolved(20.0, 2, 10, |u| 9.0 * (1.0 - u * u).max(0.0).sqrt());
    blocks.push(block([0.0, 0.0, 13.0], [1.5, 1.5, 1.2]));
    Geometry::blocks(blocks, 1.0).expect("static model")
}

/// An airship: a 75 m by 15 m ellipsoid with fins.
fn airship() -> Geometry {
    let mut blocks = revolved(75.0, 0, 15, |u| 7.5 * (1.0 - u * u).max(0.0).sqrt());
    blocks.push(block([-32.0, 0.0, 0.0], [8.0, 16.0, 0.3]));
    blocks.push(block([-32.0, 0.0, 0.0], [8.0, 0.3, 16.0]));
    Geometry::blocks(blocks, 2.0).expect("static model")
}

/// A built-in model by name (see [`MODEL_NAMES`]).
pub fn by_name(name: &str) -> Option<Geometry> {
    Some(match name {
        "quad" => quad(),
        "a320" => airliner(37.6, 34.1, 3.95),
        "b737" => airliner(39.5, 35.8, 3.76),
        "balloon" => balloon(),
        "airship" => airship(),
        "fixed_wing" => fixed_wing(),
        _ => return None,
    })
}

/// The model used for a dynamic obstacle of `kind` that declares none.
pub fn for_kind(kind: Kind) -> Result<Geometry, GeometryError> {
    Ok(match kind {
        Kind::A320 => airliner(37.6, 34.1, 3.95),
        Kind::B737 => airliner(39.5, 35.8, 3.76),
        Kind::Dji => quad(),
        Kind::Airship => airship(),
        Kind::Balloon => balloon(),
        // Static kinds moving (unusual): a 10 m cube.
        Kind::Building | Kind::Mountain | Kind::Tree => {
            Geometry::cuboid(Vec3::splat(-5.0), Vec3::splat(5.0))?
        }
    })
}
