//! The contact layer's exact shapes: a cuboid is its own box, a union of blocks a parry
//! `Compound` of cuboids (solid, cheap, built once at start-up), a terrain patch a parry
//! `HeightField` (built once at start-up from its heights: a copy of them), loaded meshes
//! triangle meshes from the [`MeshCache`]. Exact first, then cheap: a triangle mesh only for
//! what has no better shape.

use glam::{Quat, Vec3};
use parry3d::math::Pose;
use parry3d::shape::{HeightField, SharedShape};
use parry3d::utils::Array2;

use crate::collision::bodies::BodyPose;
use crate::collision::meshes::MeshCache;
use crate::collision::placed::{Body, Holder};
use crate::scene::geometry::{Geometry, GeometrySource, TerrainPatch};

/// The solids built for block geometries and the height fields for terrain patches, by
/// geometry index.
#[derive(Clone, Default)]
pub struct ExactShapes {
    solids: Vec<Option<SharedShape>>,
    /// Some geometry's exact shape is a triangle mesh (terrain, a loaded mesh).
    has_meshes: bool,
}

impl std::fmt::Debug for ExactShapes {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ExactShapes")
            .field(
                "solids",
                &self.solids.iter().filter(|s| s.is_some()).count(),
            )
            .finish()
    }
}

impl ExactShapes {
    /// Build the solid of every block geometry (a few cuboids each: milliseconds for a city)
    /// and the height field of every terrain patch.
    pub fn new(geometries: &[std::sync::Arc<Geometry>]) -> Self {
        let solids = geometries
            .iter()
            .map(|g| match &g.source {
                GeometrySource::Blocks { blocks, .. } => Some(SharedShape::compound(
                    blocks
                        .iter()
                        .map(|(min, max)| {
                            let half = ((*max - *min) * 0.5).max(Vec3::splat(1e-4));
                            (
                                Pose::from_parts((*min + *max) * 0.5, Quat::IDENTITY),
                                SharedShape::cuboid(half.x, half.y, half.z),
                            )
                        })
                        .collect(),
                )),
                GeometrySource::Terrain(patch) => Some(height_field(patch)),
                _ => None,
            })
            .collect();
        let has_meshes = geometries.iter().any(|g| Self::needs_mesh(g));
        Self { solids, has_meshes }
    }

    /// True when some geometry's exact shape is a triangle mesh.
    pub(crate) fn has_meshes(&self) -> bool {
        self.has_meshes
    }

    /// True when geometry `index`'s exact shape is a triangle mesh (built on demand).
    pub(crate) fn needs_mesh(geometry: &Geometry) -> bool {
        matches!(geometry.source, GeometrySource::Mesh { .. })
    }

    /// The exact shape of geometry `index` at `pose`. A mesh not held yet is built (and counted
    /// as built on contact when `for_contact`: the sensing layer had not made it resident).
    pub(crate) fn body(
        &self,
        index: usize,
        geometry: &Geometry,
        meshes: &mut MeshCache,
        pose: BodyPose,
        for_contact: bool,
    ) -> Body {
        match &geometry.source {
            GeometrySource::Cuboid { .. } => Body::boxed(geometry, pose),
            GeometrySource::Blocks { .. } => {
                match self.solids.get(index).and_then(Option::as_ref) {
                    Some(solid) => Body::new(Holder::Solid(solid.clone()), pose),
                    None => Body::new(Holder::Mesh(meshes.get(index, geometry)), pose),
                }
            }
            GeometrySource::Terrain(_) => match self.solids.get(index).and_then(Option::as_ref) {
                Some(field) => Body::field(field.clone(), geometry, pose),
                None => Body::new(Holder::Mesh(meshes.get(index, geometry)), pose),
            },
            GeometrySource::Mesh { .. } => {
                if for_contact && !meshes.held_or_requested(index) {
                    meshes.count_built_on_contact();
                }
                Body::new(Holder::Mesh(meshes.get(index, geometry)), pose)
            }
        }
    }
}

/// A terrain patch as a parry `HeightField` in the field's frame (y up, x east, rows along z,
/// which is south: see `bodies::field_rotation`), centred on the patch. Its cells split along
/// the same diagonal as the patch's triangles (parry's default subdivision in that frame).
fn height_field(p: &TerrainPatch) -> SharedShape {
    let c = p.grid.cell_m;
    let heights = Array2::from_fn(p.ny, p.nx, |i, j| {
        p.grid.at(p.x0 + j, p.y0 + (p.ny - 1 - i)) - p.base_m
    });
    let scale = Vec3::new((p.nx - 1) as f32 * c, 1.0, (p.ny - 1) as f32 * c);
    SharedShape::new(HeightField::new(heights, scale))
}
