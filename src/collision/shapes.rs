//! The contact layer's exact shapes: a cuboid is its own box, a union of blocks a parry
//! `Compound` of cuboids (solid, cheap, built once at start-up), terrain and loaded meshes
//! triangle meshes from the [`MeshCache`]. Exact first, then cheap: a triangle mesh only for
//! what has no better shape.

use glam::{Quat, Vec3};
use parry3d::math::Pose;
use parry3d::shape::SharedShape;

use crate::collision::bodies::{Body, BodyPose, Holder};
use crate::collision::meshes::MeshCache;
use crate::scene::geometry::{Geometry, GeometrySource};

/// The solids built for block geometries, by geometry index.
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
    /// Build the solid of every block geometry (a few cuboids each: milliseconds for a city).
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
        matches!(
            geometry.source,
            GeometrySource::Mesh { .. } | GeometrySource::Terrain(_)
        )
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
            GeometrySource::Mesh { .. } | GeometrySource::Terrain(_) => {
                if for_contact && meshes.built(index).is_none() {
                    meshes.built_on_contact += 1;
                }
                Body::new(Holder::Mesh(meshes.get(index, geometry)), pose)
            }
        }
    }
}
