//! The mesh cache: a triangle-mesh collider is built the first time any obstacle using that
//! geometry needs one, then shared. What was built is what the flight touched.

use std::sync::Arc;
use std::time::{Duration, Instant};

use parry3d::shape::TriMesh;

use crate::scene::geometry::Geometry;

/// Built meshes by geometry index.
#[derive(Debug, Default)]
pub struct MeshCache {
    meshes: Vec<Option<Arc<TriMesh>>>,
    /// Meshes built so far.
    pub built: usize,
    /// Triangles in the built meshes.
    pub triangles: usize,
    /// Estimated heap bytes of the built meshes (vertices, indices and BVH).
    pub bytes: usize,
    /// Time spent building.
    pub build_time: Duration,
}

/// Estimated heap bytes of a parry `TriMesh` with this many vertices and triangles: 12 B per
/// vertex, 12 B per triangle of indices, about 2 BVH nodes of 32 B per triangle.
pub fn trimesh_bytes(vertices: usize, triangles: usize) -> usize {
    12 * vertices + 12 * triangles + 64 * triangles
}

impl MeshCache {
    /// A cache for `geometries` geometries.
    pub fn new(geometries: usize) -> Self {
        Self {
            meshes: vec![None; geometries],
            ..Self::default()
        }
    }

    /// The mesh of geometry `index`, built now if it never was.
    pub fn get(&mut self, index: usize, geometry: &Geometry) -> Arc<TriMesh> {
        if index >= self.meshes.len() {
            self.meshes.resize(index + 1, None);
        }
        if let Some(mesh) = &self.meshes[index] {
            return mesh.clone();
        }
        let started = Instant::now();
        let mesh = Arc::new(geometry.build_trimesh());
        self.build_time += started.elapsed();
        self.built += 1;
        self.triangles += mesh.num_triangles();
        self.bytes += trimesh_bytes(mesh.vertices().len(), mesh.num_triangles());
        self.meshes[index] = Some(mesh.clone());
        mesh
    }

    /// The mesh of geometry `index` if it was built.
    pub fn built(&self, index: usize) -> Option<&Arc<TriMesh>> {
        self.meshes.get(index).and_then(Option::as_ref)
    }
}
