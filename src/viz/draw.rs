//! How things look: colours, and scene shapes turned into rerun archetypes in the logged
//! (viz-offset) frame.

use glam::{DQuat, DVec3, Vec3};
use rerun::components::FillMode;
use rerun::{Boxes3D, Color};

use crate::pipeline::BodyPose;
use crate::scene::geometry::Geometry;
use crate::scene::{Aabb64, Kind, Scene};

/// Colour of a kind of obstacle.
pub fn kind_color(kind: Kind) -> Color {
    match kind {
        Kind::Building => Color::from_rgb(150, 150, 160),
        Kind::Mountain => Color::from_rgb(120, 100, 70),
        Kind::Tree => Color::from_rgb(40, 140, 60),
        Kind::A320 | Kind::B737 => Color::from_rgb(230, 230, 240),
        Kind::Dji => Color::from_rgb(60, 60, 60),
        Kind::Airship | Kind::Balloon => Color::from_rgb(230, 120, 40),
    }
}

/// A colour with some transparency: for solid things the vehicle may be inside of.
pub fn see_through(c: Color, alpha: u8) -> Color {
    let [r, g, b, _] = c.to_array();
    Color::from_unmultiplied_rgba(r, g, b, alpha)
}

/// Colour of a collider by its beta: blue (0) through yellow (50, the mesh threshold) to red
/// (100 and more).
pub fn beta_color(beta: f64) -> Color {
    let u = (beta / 100.0).clamp(0.0, 1.0) as f32;
    let (r, g, b) = if u < 0.5 {
        let v = u * 2.0;
        (v, v, 1.0 - v)
    } else {
        let v = (u - 0.5) * 2.0;
        (1.0, 1.0 - v, 0.0)
    };
    Color::from_rgb((r * 255.0) as u8, (g * 255.0) as u8, (b * 255.0) as u8)
}

/// The offset subtracted from scene ENU positions before they become f32: zero near the
/// origin, else the scene's centre rounded to a kilometre.
pub fn viz_offset(scene: &Scene) -> DVec3 {
    let centre = if scene.obstacles.is_empty() {
        DVec3::ZERO
    } else {
        scene.bounds_enu_m().centre()
    };
    if centre.length() < 10_000.0 {
        DVec3::ZERO
    } else {
        (centre / 1000.0).round() * 1000.0
    }
}

/// Boxes, shifted by the viz offset, drawn as `fill`.
pub fn boxes_of(
    offset: DVec3,
    fill: FillMode,
    items: impl Iterator<Item = (LocalBox, Color)>,
) -> Boxes3D {
    let mut centres = Vec::new();
    let mut halves = Vec::new();
    let mut rotations = Vec::new();
    let mut colors = Vec::new();
    for (b, c) in items {
        centres.push(local(offset, b.centre_enu_m).to_array());
        halves.push(b.half_m.to_array());
        let q = b.rotation.as_quat();
        rotations.push(rerun::Quaternion::from_xyzw([q.x, q.y, q.z, q.w]));
        colors.push(c);
    }
    Boxes3D::from_centers_and_half_sizes(centres, halves)
        .with_quaternions(rotations)
        .with_colors(colors)
        .with_fill_mode(fill)
        // Thin lines (3 cm): an edge that passes by the chase eye stays a line.
        .with_radii([0.03])
}

/// A box in the scene: centre, half sizes, rotation.
pub struct LocalBox {
    /// Centre, scene ENU metres.
    pub centre_enu_m: DVec3,
    /// Half sizes, metres.
    pub half_m: Vec3,
    /// Rotation, ENU from the box's axes.
    pub rotation: DQuat,
}

impl LocalBox {
    /// An axis-aligned box.
    pub fn aligned(b: &Aabb64) -> Self {
        Self {
            centre_enu_m: b.centre(),
            half_m: ((b.max - b.min) * 0.5).as_vec3(),
            rotation: DQuat::IDENTITY,
        }
    }
}

/// A scene ENU position in the logged frame.
pub fn local(offset: DVec3, p: DVec3) -> Vec3 {
    (p - offset).as_vec3()
}

/// An obstacle's box collider at `pose`.
pub fn box_of_geometry(geometry: &Geometry, pose: &BodyPose) -> LocalBox {
    let (cuboid, centre) = geometry.box_collider();
    LocalBox {
        centre_enu_m: pose.position_enu_m + pose.enu_from_body * centre.as_dvec3(),
        half_m: cuboid.half_extents,
        rotation: pose.enu_from_body,
    }
}

/// Where a static obstacle is.
pub fn pose_of_static(scene: &Scene, i: u32) -> BodyPose {
    let o = &scene.obstacles[i as usize];
    BodyPose {
        position_enu_m: o.placement.position_enu_m,
        enu_from_body: o.placement.enu_from_local,
    }
}
