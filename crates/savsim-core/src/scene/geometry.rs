//! Obstacle geometry in its own frame: what a box collider and a mesh collider are made from.
//!
//! Geometry is kept as a cheap description (a cuboid, a union of blocks, a loaded mesh, a
//! terrain patch) and turned into triangles only when a mesh collider is first needed, so a
//! city of thousands of buildings costs memory only for what the flight comes near. Units are
//! metres; axes are the obstacle's East-North-Up axes before its yaw.

use std::sync::Arc;

use glam::Vec3;
use parry3d::bounding_volume::Aabb;
use parry3d::shape::{Cuboid, TriMesh, TriMeshFlags};

/// A grid of terrain heights, metres, shared by the patches cut from it.
#[derive(Debug, Clone, PartialEq)]
pub struct HeightGrid {
    /// Samples along x (east).
    pub nx: usize,
    /// Samples along y (north).
    pub ny: usize,
    /// Spacing of samples, metres.
    pub cell_m: f32,
    /// Heights row-major (`y * nx + x`), metres above the grid's base, relative to the
    /// patch obstacle's origin height.
    pub heights_m: Vec<f32>,
}

impl HeightGrid {
    /// Height at sample (ix, iy).
    pub fn at(&self, ix: usize, iy: usize) -> f32 {
        self.heights_m[iy * self.nx + ix]
    }
}

/// A rectangle of samples of a [`HeightGrid`], positioned so that sample (x0, y0) is at the
/// local origin.
#[derive(Debug, Clone, PartialEq)]
pub struct TerrainPatch {
    /// The grid.
    pub grid: Arc<HeightGrid>,
    /// First sample along x.
    pub x0: usize,
    /// First sample along y.
    pub y0: usize,
    /// Samples along x (at least 2).
    pub nx: usize,
    /// Samples along y (at least 2).
    pub ny: usize,
    /// Height subtracted from every sample (the patch obstacle's origin height), metres.
    pub base_m: f32,
}

/// A shape in its obstacle's frame, kept as a description until triangles are needed.
#[derive(Debug, Clone, PartialEq)]
pub enum GeometrySource {
    /// An axis-aligned box from `min` to `max`.
    Cuboid {
        /// Lower corner, metres.
        min: Vec3,
        /// Upper corner, metres.
        max: Vec3,
    },
    /// A union of axis-aligned blocks (towers, setbacks, L and U plans, bridges, spires).
    Blocks {
        /// Each block's lower and upper corner, metres.
        blocks: Arc<Vec<(Vec3, Vec3)>>,
        /// Facade tessellation: faces are split into cells no larger than this (metres), as a
        /// modelled building's facade is; 0 keeps two triangles per face.
        tessellate_m: f32,
    },
    /// Triangles loaded from a model file (already scaled and axis-converted), or extruded
    /// from a footprint.
    Mesh {
        /// Vertices, metres.
        vertices: Arc<Vec<Vec3>>,
        /// Triangles as vertex indices.
        indices: Arc<Vec<[u32; 3]>>,
        /// The triangles bound a solid ([`closed_outward`]): vertices welded, every edge
        /// shared by two triangles, faces outward. A closed mesh is a solid (inside is a
        /// contact, a ray from inside reads 0); an open one is a surface only.
        closed: bool,
    },
    /// Part of a terrain grid.
    Terrain(TerrainPatch),
}

/// A shape, its bounds and (on demand) its triangles.
#[derive(Debug, Clone, PartialEq)]
pub struct Geometry {
    /// The description.
    pub source: GeometrySource,
    /// Bounds in the obstacle frame, metres.
    pub local_aabb: Aabb,
}

/// Why a geometry cannot be used.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum GeometryError {
    /// No triangles, or none with area.
    #[error("the shape has no triangles with area")]
    Empty,
    /// A coordinate is NaN or infinite.
    #[error("a coordinate is not finite")]
    NonFinite,
    /// A triangle names a vertex that does not exist.
    #[error("triangle {triangle} uses vertex {vertex}, but there are only {vertices}")]
    BadIndex {
        /// Triangle number.
        triangle: usize,
        /// The index it uses.
        vertex: u32,
        /// Vertices available.
        vertices: usize,
    },
    /// A block or box with a negative or zero size.
    #[error("a box or block has a size that is not positive")]
    BadSize,
}

impl Geometry {
    /// A box from `min` to `max`.
    pub fn cuboid(min: Vec3, max: Vec3) -> Result<Self, GeometryError> {
        check_finite(&[min, max])?;
        if (max - min).min_element() <= 0.0 {
            return Err(GeometryError::BadSize);
        }
        Ok(Self {
            source: GeometrySource::Cuboid { min, max },
            local_aabb: Aabb::new(min, max),
        })
    }

    /// A union of blocks.
    ///
    /// ```
    /// use savsim_core::scene::geometry::Geometry;
    /// use glam::Vec3;
    /// // An L-shaped building: its box is twice the volume of the solid.
    /// let l = Geometry::blocks(vec![
    ///     (Vec3::new(0.0, 0.0, 0.0), Vec3::new(20.0, 10.0, 30.0)),
    ///     (Vec3::new(0.0, 10.0, 0.0), Vec3::new(10.0, 20.0, 30.0)),
    /// ], 0.0).unwrap();
    /// assert_eq!(l.local_aabb.maxs, Vec3::new(20.0, 20.0, 30.0));
    /// assert_eq!(l.triangle_count(), 24);
    /// ```
    pub fn blocks(blocks: Vec<(Vec3, Vec3)>, tessellate_m: f32) -> Result<Self, GeometryError> {
        if blocks.is_empty() {
            return Err(GeometryError::Empty);
        }
        let mut aabb = Aabb::new_invalid();
        for (min, max) in &blocks {
            check_finite(&[*min, *max])?;
            if (*max - *min).min_element() <= 0.0 {
                return Err(GeometryError::BadSize);
            }
            aabb.take_point(*min);
            aabb.take_point(*max);
        }
        Ok(Self {
            source: GeometrySource::Blocks {
                blocks: Arc::new(blocks),
                tessellate_m: if tessellate_m.is_finite() {
                    tessellate_m.max(0.0)
                } else {
                    0.0
                },
            },
            local_aabb: aabb,
        })
    }

    /// Loaded triangles. Degenerate (zero-area) and out-of-range triangles are errors only when
    /// nothing usable is left: zero-area ones are dropped. Triangles that bound a solid
    /// ([`closed_outward`]) are kept welded and facing outward, and the mesh is `closed`.
    ///
    /// ```
    /// use savsim_core::scene::geometry::{Geometry, GeometrySource};
    /// use glam::Vec3;
    /// // A tetrahedron with its faces inward, each face with vertices of its own.
    /// let p = [Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::Z];
    /// let faces = [[0, 1, 2], [0, 3, 1], [0, 2, 3], [1, 3, 2]];
    /// let vertices: Vec<Vec3> = faces.iter().flat_map(|f| f.map(|i| p[i])).collect();
    /// let indices: Vec<[u32; 3]> = (0..4).map(|k| [3 * k, 3 * k + 1, 3 * k + 2]).collect();
    /// let solid = Geometry::mesh(vertices, indices.clone()).unwrap();
    /// assert!(matches!(solid.source, GeometrySource::Mesh { closed: true, .. }));
    /// assert!(solid.contains_local_point(Vec3::splat(0.2)));
    /// assert!(!solid.contains_local_point(Vec3::splat(0.5)));
    /// // Three faces of it: a surface, which holds nothing.
    /// let open = Geometry::mesh(p.to_vec(), vec![[0, 1, 2], [0, 3, 1], [0, 2, 3]]).unwrap();
    /// assert!(matches!(open.source, GeometrySource::Mesh { closed: false, .. }));
    /// assert!(!open.contains_local_point(Vec3::splat(0.2)));
    /// ```
    pub fn mesh(vertices: Vec<Vec3>, indices: Vec<[u32; 3]>) -> Result<Self, GeometryError> {
        check_finite(&vertices)?;
        let n = vertices.len();
        for (triangle, tri) in indices.iter().enumerate() {
            if let Some(&vertex) = tri.iter().find(|&&v| v as usize >= n) {
                return Err(GeometryError::BadIndex {
                    triangle,
                    vertex,
                    vertices: n,
                });
            }
        }
        let indices: Vec<[u32; 3]> = indices
            .into_iter()
            .filter(|t| {
                let (a, b, c) = (
                    vertices[t[0] as usize],
                    vertices[t[1] as usize],
                    vertices[t[2] as usize],
                );
                (b - a).cross(c - a).length_squared() > 0.0
            })
            .collect();
        if indices.is_empty() {
            return Err(GeometryError::Empty);
        }
        let mut aabb = Aabb::new_invalid();
        for t in &indices {
            for &v in t {
                aabb.take_point(vertices[v as usize]);
            }
        }
        let (vertices, indices, closed) = match closed_outward(&vertices, &indices) {
            Some((v, i)) => (v, i, true),
            None => (vertices, indices, false),
        };
        Ok(Self {
            source: GeometrySource::Mesh {
                vertices: Arc::new(vertices),
                indices: Arc::new(indices),
                closed,
            },
            local_aabb: aabb,
        })
    }

    /// A terrain patch.
    pub fn terrain(patch: TerrainPatch) -> Result<Self, GeometryError> {
        if patch.nx < 2 || patch.ny < 2 {
            return Err(GeometryError::Empty);
        }
        let mut aabb = Aabb::new_invalid();
        for iy in patch.y0..patch.y0 + patch.ny {
            for ix in patch.x0..patch.x0 + patch.nx {
                let h = patch.grid.at(ix, iy) - patch.base_m;
                if !h.is_finite() {
                    return Err(GeometryError::NonFinite);
                }
                let x = (ix - patch.x0) as f32 * patch.grid.cell_m;
                let y = (iy - patch.y0) as f32 * patch.grid.cell_m;
                aabb.take_point(Vec3::new(x, y, h));
            }
        }
        Ok(Self {
            source: GeometrySource::Terrain(patch),
            local_aabb: aabb,
        })
    }

    /// The box collider: the cuboid enclosing the geometry, and its centre in the obstacle frame.
    pub fn box_collider(&self) -> (Cuboid, Vec3) {
        let half = self.local_aabb.half_extents().max(Vec3::splat(1e-3));
        (Cuboid::new(half), self.local_aabb.center())
    }

    /// Triangles the mesh collider will have (without building it).
    pub fn triangle_count(&self) -> usize {
        match &self.source {
            GeometrySource::Cuboid { .. } => 12,
            GeometrySource::Blocks {
                blocks,
                tessellate_m,
            } => blocks
                .iter()
                .map(|(min, max)| box_triangle_count(*max - *min, *tessellate_m))
                .sum(),
            GeometrySource::Mesh { indices, .. } => indices.len(),
            GeometrySource::Terrain(p) => 2 * (p.nx - 1) * (p.ny - 1),
        }
    }

    /// Build the triangle-mesh collider (the expensive step; the caller caches the result).
    /// A closed mesh is built `ORIENTED` (with pseudo-normals): parry then answers whether a
    /// point is inside it.
    pub fn build_trimesh(&self) -> TriMesh {
        let (vertices, indices) = self.triangles();
        let flags = if self.is_closed_mesh() {
            TriMeshFlags::ORIENTED
        } else {
            TriMeshFlags::empty()
        };
        // Vertices and indices were validated at construction; a failure here is a bug.
        TriMesh::with_flags(vertices, indices, flags).expect("geometry validated at construction")
    }

    /// True for a closed triangle mesh (a solid's boundary).
    pub fn is_closed_mesh(&self) -> bool {
        matches!(self.source, GeometrySource::Mesh { closed: true, .. })
    }

    /// The triangles of the geometry.
    pub fn triangles(&self) -> (Vec<Vec3>, Vec<[u32; 3]>) {
        let mut vertices = Vec::new();
        let mut indices = Vec::new();
        match &self.source {
            GeometrySource::Cuboid { min, max } => {
                push_box(&mut vertices, &mut indices, *min, *max, 0.0)
            }
            GeometrySource::Blocks {
                blocks,
                tessellate_m,
            } => {
                for (min, max) in blocks.iter() {
                    push_box(&mut vertices, &mut indices, *min, *max, *tessellate_m);
                }
            }
            GeometrySource::Mesh {
                vertices: v,
                indices: i,
                ..
            } => {
                vertices.extend_from_slice(v);
                indices.extend_from_slice(i);
            }
            GeometrySource::Terrain(p) => {
                for iy in 0..p.ny {
                    for ix in 0..p.nx {
                        vertices.push(Vec3::new(
                            ix as f32 * p.grid.cell_m,
                            iy as f32 * p.grid.cell_m,
                            p.grid.at(p.x0 + ix, p.y0 + iy) - p.base_m,
                        ));
                    }
                }
                let nx = p.nx as u32;
                for iy in 0..p.ny as u32 - 1 {
                    for ix in 0..nx - 1 {
                        let a = iy * nx + ix;
                        let (b, c, d) = (a + 1, a + nx, a + nx + 1);
                        indices.push([a, b, d]);
                        indices.push([a, d, c]);
                    }
                }
            }
        }
        (vertices, indices)
    }

    /// A point on the shape's surface, in its frame (none for terrain): a corner of its box or
    /// first block, or its first triangle's first vertex. If this point is inside another solid,
    /// the two touch or one holds the other.
    pub fn a_surface_point(&self) -> Option<Vec3> {
        match &self.source {
            GeometrySource::Cuboid { min, .. } => Some(*min),
            GeometrySource::Blocks { blocks, .. } => blocks.first().map(|b| b.0),
            GeometrySource::Mesh {
                vertices, indices, ..
            } => indices
                .first()
                .and_then(|t| vertices.get(t[0] as usize))
                .copied(),
            GeometrySource::Terrain(_) => None,
        }
    }

    /// True when `p` (obstacle frame) is inside the solid: inside the box, inside a block,
    /// inside a closed mesh (the parity of a ray's crossings, O(triangles): a built collider
    /// answers faster), or under a terrain patch. An open mesh is a surface and contains
    /// nothing (a vehicle inside one is found when it crosses the surface).
    ///
    /// ```
    /// use savsim_core::scene::geometry::Geometry;
    /// use glam::Vec3;
    /// let g = Geometry::blocks(vec![(Vec3::ZERO, Vec3::splat(10.0))], 0.0).unwrap();
    /// assert!(g.contains_local_point(Vec3::splat(5.0)));
    /// assert!(!g.contains_local_point(Vec3::splat(11.0)));
    /// ```
    pub fn contains_local_point(&self, p: Vec3) -> bool {
        let inside = |min: Vec3, max: Vec3| min.cmple(p).all() && p.cmple(max).all();
        match &self.source {
            GeometrySource::Cuboid { min, max } => inside(*min, *max),
            GeometrySource::Blocks { blocks, .. } => blocks.iter().any(|(a, b)| inside(*a, *b)),
            GeometrySource::Mesh {
                vertices,
                indices,
                closed: true,
            } => {
                let (min, max) = (self.local_aabb.mins, self.local_aabb.maxs);
                min.cmple(p).all() && p.cmple(max).all() && crossings_odd(vertices, indices, p)
            }
            GeometrySource::Mesh { closed: false, .. } => false,
            GeometrySource::Terrain(_) => self.terrain_height_at(p.x, p.y).is_some_and(|h| p.z < h),
        }
    }

    /// True for a terrain patch.
    pub fn is_terrain(&self) -> bool {
        matches!(self.source, GeometrySource::Terrain(_))
    }
}

/// Triangles that bound a solid, welded and facing outward; `None` when they do not. After
/// welding vertices at equal positions, every directed edge must be used by exactly one
/// triangle and its reverse by exactly one other (a closed, consistently oriented surface);
/// faces then turn outward where the signed volume says they turn in.
pub fn closed_outward(
    vertices: &[Vec3],
    indices: &[[u32; 3]],
) -> Option<(Vec<Vec3>, Vec<[u32; 3]>)> {
    use std::collections::HashMap;
    let mut welded: Vec<Vec3> = Vec::new();
    let mut at: HashMap<[u32; 3], u32> = HashMap::new();
    let remap: Vec<u32> = vertices
        .iter()
        .map(|v| {
            // -0.0 and 0.0 are one position.
            let key = (*v + Vec3::ZERO).to_array().map(f32::to_bits);
            *at.entry(key).or_insert_with(|| {
                welded.push(*v);
                (welded.len() - 1) as u32
            })
        })
        .collect();
    let mut triangles: Vec<[u32; 3]> = indices
        .iter()
        .map(|t| t.map(|i| remap[i as usize]))
        .collect();
    let mut edges: HashMap<(u32, u32), u32> = HashMap::with_capacity(3 * triangles.len());
    for t in &triangles {
        for k in 0..3 {
            let edge = (t[k], t[(k + 1) % 3]);
            if edge.0 == edge.1 {
                return None;
            }
            *edges.entry(edge).or_insert(0) += 1;
        }
    }
    let paired = edges
        .iter()
        .all(|(&(a, b), &n)| n == 1 && edges.get(&(b, a)) == Some(&1));
    if !paired {
        return None;
    }
    let volume: f64 = triangles
        .iter()
        .map(|t| {
            let [a, b, c] = t.map(|i| welded[i as usize].as_dvec3());
            a.dot(b.cross(c))
        })
        .sum();
    if volume < 0.0 {
        triangles.iter_mut().for_each(|t| t.swap(1, 2));
    }
    Some((welded, triangles))
}

/// Whether a ray from `p` crosses the triangles an odd number of times (Moller-Trumbore in
/// f64, along a direction skewed off the axes so that it misses edges and vertices of
/// axis-aligned models).
fn crossings_odd(vertices: &[Vec3], indices: &[[u32; 3]], p: Vec3) -> bool {
    let o = p.as_dvec3();
    let d = glam::DVec3::new(0.5773, 0.5774, 0.5775).normalize_or_zero();
    let crosses = |t: &[u32; 3]| {
        let [a, b, c] = t.map(|i| vertices[i as usize].as_dvec3());
        let (e1, e2) = (b - a, c - a);
        let q = d.cross(e2);
        let det = e1.dot(q);
        if det.abs() < 1e-15 {
            return false;
        }
        let s = o - a;
        let u = s.dot(q) / det;
        let r = s.cross(e1);
        let v = d.dot(r) / det;
        u >= 0.0 && v >= 0.0 && u + v <= 1.0 && e2.dot(r) / det > 0.0
    };
    indices.iter().filter(|t| crosses(t)).count() % 2 == 1
}

/// Estimated heap bytes of a parry `TriMesh` with this many vertices and triangles: 12 B per
/// vertex, 12 B per triangle of indices, about 2 BVH nodes of 32 B per triangle.
pub fn trimesh_bytes(vertices: usize, triangles: usize) -> usize {
    12 * vertices + 12 * triangles + 64 * triangles
}

fn check_finite(points: &[Vec3]) -> Result<(), GeometryError> {
    if points.iter().all(|p| p.is_finite()) {
        Ok(())
    } else {
        Err(GeometryError::NonFinite)
    }
}

fn cells(extent_m: f32, tessellate_m: f32) -> usize {
    if tessellate_m > 0.0 {
        ((extent_m / tessellate_m).ceil() as usize).clamp(1, 4096)
    } else {
        1
    }
}

fn box_triangle_count(size: Vec3, tessellate_m: f32) -> usize {
    let (nx, ny, nz) = (
        cells(size.x, tessellate_m),
        cells(size.y, tessellate_m),
        cells(size.z, tessellate_m),
    );
    4 * (nx * ny + ny * nz + nx * nz)
}

/// Append a closed, outward-facing box whose faces are split into cells.
fn push_box(
    vertices: &mut Vec<Vec3>,
    indices: &mut Vec<[u32; 3]>,
    min: Vec3,
    max: Vec3,
    tessellate_m: f32,
) {
    let size = max - min;
    let n = [
        cells(size.x, tessellate_m),
        cells(size.y, tessellate_m),
        cells(size.z, tessellate_m),
    ];
    // Each face: a fixed axis and value, two in-plane axes ordered so that u x v points out.
    for axis in 0..3 {
        let (u_axis, v_axis) = ((axis + 1) % 3, (axis + 2) % 3);
        for (value, outward) in [(min[axis], false), (max[axis], true)] {
            let (nu, nv) = (n[u_axis], n[v_axis]);
            let base = vertices.len() as u32;
            for j in 0..=nv {
                for i in 0..=nu {
                    let mut p = Vec3::ZERO;
                    p[axis] = value;
                    p[u_axis] = min[u_axis] + size[u_axis] * i as f32 / nu as f32;
                    p[v_axis] = min[v_axis] + size[v_axis] * j as f32 / nv as f32;
                    vertices.push(p);
                }
            }
            let row = nu as u32 + 1;
            for j in 0..nv as u32 {
                for i in 0..nu as u32 {
                    let a = base + j * row + i;
                    let (b, c, d) = (a + 1, a + row, a + row + 1);
                    if outward {
                        indices.push([a, b, d]);
                        indices.push([a, d, c]);
                    } else {
                        indices.push([a, d, b]);
                        indices.push([a, c, d]);
                    }
                }
            }
        }
    }
}
