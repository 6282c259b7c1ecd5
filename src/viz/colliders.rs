//! A vehicle's colliders as the viewer draws them: four entities instead of one per obstacle
//! (hundreds of entities made hundreds of chunks, slow to write and to load), each logged only
//! when what it shows changes.
//!
//! - `colliders/boxes`: every box collider: thin blue wireframes. Changes when the vehicle's
//!   node does, or a collider is swapped.
//! - `colliders/seen`: the box colliders a ray sees, drawn over them in thicker wireframes
//!   coloured by beta (a handful; they change as the rays sweep).
//! - `colliders/meshes/{obstacle}`: each mesh collider (a mesh is large, so it is logged once,
//!   when it appears, see-through, in the colour of the beta that made it a mesh).
//! - `colliders/moving`: colliders of moving bodies (logged every tick they exist).
//!
//! Box colours are by beta in steps of 10, so a beta that wanders within a step logs nothing.

use glam::DVec3;
use rerun::components::FillMode;
use rerun::{Clear, Color, Mesh3D, RecordingStream, RecordingStreamResult};

use super::draw::{beta_color, box_of_geometry, boxes_of, local, pose_of_static, see_through};
use super::paths;
use crate::collision::ColliderKind;
use crate::observe::TickFrame;
use crate::pipeline::{BodyPose, ObstacleRef};
use crate::scene::geometry::Geometry;
use crate::scene::Scene;

/// What one of the four entities showed when last logged: (obstacle, beta step) in the order
/// of the frame (which lists colliders in a stable order).
type Shown = Vec<(ObstacleRef, u8)>;

/// The last logged state of one vehicle's collider entities.
#[derive(Default)]
pub struct ColliderView {
    /// Every collider as last seen: (obstacle, kind, beta step). Most ticks match it, and
    /// then nothing is logged or built.
    last: Vec<(ObstacleRef, ColliderKind, u8)>,
    boxes: Shown,
    seen: Shown,
    meshes: Vec<ObstacleRef>,
    moving: bool,
}

/// Beta in steps of ten (0 for "no ray sees it"), the colour's resolution.
fn step(beta: f64) -> u8 {
    if beta > 0.0 {
        1 + (beta / 10.0).clamp(0.0, 10.0) as u8
    } else {
        0
    }
}

fn step_color(step: u8) -> Color {
    beta_color(f64::from(step.saturating_sub(1)) * 10.0 + 5.0 * f64::from(step.min(1)))
}

fn placed<'s>(
    scene: &'s Scene,
    f: &'s TickFrame,
    o: ObstacleRef,
) -> Option<(&'s Geometry, BodyPose)> {
    match o {
        ObstacleRef::Static(i) => Some((
            &*scene.obstacles.get(i as usize)?.geometry,
            pose_of_static(scene, i),
        )),
        ObstacleRef::Dynamic(key) => f
            .dynamic
            .iter()
            .find(|d| d.0 == key)
            .map(|d| (&*scene.geometries[d.3], d.4)),
    }
}

/// An obstacle's id, as events and the scene file spell it.
pub fn obstacle_name<'s>(scene: &'s Scene, f: &'s TickFrame, o: ObstacleRef) -> Option<&'s str> {
    match o {
        ObstacleRef::Static(i) => scene.obstacles.get(i as usize).map(|s| s.id.as_str()),
        ObstacleRef::Dynamic(key) => f.dynamic.iter().find(|d| d.0 == key).map(|d| d.1.as_str()),
    }
}

impl ColliderView {
    /// Log what changed in this tick's colliders.
    pub fn log(
        &mut self,
        rec: &RecordingStream,
        scene: &Scene,
        offset: DVec3,
        f: &TickFrame,
    ) -> RecordingStreamResult<()> {
        let id = f.system_id;
        let unchanged = self.last.len() == f.colliders.len()
            && self
                .last
                .iter()
                .zip(&f.colliders)
                .all(|(a, b)| a.0 == b.0 && a.1 == b.1 && a.2 == step(b.2));
        if unchanged && !self.moving {
            return Ok(());
        }
        self.last.clear();
        self.last.extend(
            f.colliders
                .iter()
                .map(|&(o, kind, beta)| (o, kind, step(beta))),
        );
        let (mut boxes, mut seen, mut meshes, mut moving) =
            (Vec::new(), Vec::new(), Vec::new(), Vec::new());
        for &(o, kind, beta) in &f.colliders {
            let entry = (o, step(beta));
            match (o, kind) {
                (_, ColliderKind::None) => {}
                (ObstacleRef::Dynamic(_), _) => moving.push(entry),
                (_, ColliderKind::Mesh) => meshes.push(entry),
                (_, ColliderKind::Box) => {
                    boxes.push((o, 0));
                    if entry.1 > 0 {
                        seen.push(entry);
                    }
                }
            }
        }
        // Named by obstacle id, shown on hover.
        let wireframes = |shown: &Shown, radius_m: f32| {
            let items = shown.iter().filter_map(|&(o, s)| {
                let (geometry, pose) = placed(scene, f, o)?;
                Some((box_of_geometry(geometry, &pose), step_color(s)))
            });
            let names = shown
                .iter()
                .filter(|&&(o, _)| placed(scene, f, o).is_some());
            boxes_of(offset, FillMode::MajorWireframe, items)
                .with_radii([radius_m])
                .with_labels(names.map(|&(o, _)| obstacle_name(scene, f, o).unwrap_or_default()))
                .with_show_labels(false)
        };
        if boxes != self.boxes {
            rec.log(paths::colliders(id, "boxes"), &wireframes(&boxes, 0.03))?;
            self.boxes = boxes;
        }
        if seen != self.seen {
            rec.log(paths::colliders(id, "seen"), &wireframes(&seen, 0.08))?;
            self.seen = seen;
        }
        for &(o, s) in &meshes {
            if self.meshes.binary_search(&o).is_err() {
                if let (Some((geometry, pose)), Some(name)) =
                    (placed(scene, f, o), obstacle_name(scene, f, o))
                {
                    rec.log(
                        paths::mesh_collider(id, name),
                        &mesh_of(offset, geometry, &pose, step_color(s)),
                    )?;
                }
            }
        }
        let now: Vec<ObstacleRef> = meshes.iter().map(|m| m.0).collect();
        for &o in &self.meshes {
            if now.binary_search(&o).is_err() {
                if let Some(name) = obstacle_name(scene, f, o) {
                    rec.log(paths::mesh_collider(id, name), &Clear::flat())?;
                }
            }
        }
        self.meshes = now;
        if !moving.is_empty() {
            rec.log(paths::colliders(id, "moving"), &wireframes(&moving, 0.03))?;
        } else if self.moving {
            rec.log(paths::colliders(id, "moving"), &Clear::flat())?;
        }
        self.moving = !moving.is_empty();
        Ok(())
    }
}

/// An obstacle's triangles at `pose`, see-through (so that what is inside or behind it, the
/// vehicle, shows), in one colour.
fn mesh_of(offset: DVec3, geometry: &Geometry, pose: &BodyPose, color: Color) -> Mesh3D {
    let (vertices, triangles) = geometry.triangles();
    Mesh3D::new(vertices.iter().map(|v| {
        local(
            offset,
            pose.position_enu_m + pose.enu_from_body * v.as_dvec3(),
        )
        .to_array()
    }))
    .with_triangle_indices(
        triangles
            .into_iter()
            .map(|t| rerun::TriangleIndices(t.into())),
    )
    .with_albedo_factor(see_through(color, 50).0)
}
