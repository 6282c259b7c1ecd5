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
use smallvec::SmallVec;

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
    /// Triangles loaded from a model file (already scaled and axis-converted).
    Mesh {
        /// Vertices, metres.
        vertices: Arc<Vec<Vec3>>,
        /// Triangles as vertex indices.
        indices: Arc<Vec<[u32; 3]>>,
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
    /// use savsim::scene::geometry::Geometry;
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
    /// nothing usable is left: zero-area ones are dropped.
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
        Ok(Self {
            source: GeometrySource::Mesh {
                vertices: Arc::new(vertices),
                indices: Arc::new(indices),
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
    pub fn build_trimesh(&self) -> TriMesh {
        let (vertices, indices) = self.triangles();
        // Vertices and indices were validated at construction; a failure here is a bug.
        TriMesh::with_flags(vertices, indices, TriMeshFlags::empty())
            .expect("geometry validated at construction")
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
            GeometrySource::Mesh { vertices, indices } => indices
                .first()
                .and_then(|t| vertices.get(t[0] as usize))
                .copied(),
            GeometrySource::Terrain(_) => None,
        }
    }

    /// True when `p` (obstacle frame) is inside the solid: inside the box, inside a block, or
    /// under a terrain patch. Loaded meshes are surfaces only and contain nothing (a vehicle
    /// inside one is found when it crosses the surface).
    ///
    /// ```
    /// use savsim::scene::geometry::Geometry;
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
            GeometrySource::Mesh { .. } => false,
            GeometrySource::Terrain(_) => self.terrain_height_at(p.x, p.y).is_some_and(|h| p.z < h),
        }
    }

    /// The highest terrain sample of the cells that the local rectangle [x0, x1] x [y0, y1]
    /// touches: an upper bound of the surface there (None: not terrain, or outside it).
    pub fn terrain_max_height_in(&self, x0: f32, y0: f32, x1: f32, y1: f32) -> Option<f32> {
        let GeometrySource::Terrain(p) = &self.source else {
            return None;
        };
        let c = p.grid.cell_m;
        let clamp_x = |v: f32| ((v / c).floor().max(0.0) as usize).min(p.nx - 1);
        let clamp_y = |v: f32| ((v / c).floor().max(0.0) as usize).min(p.ny - 1);
        if x1 < 0.0 || y1 < 0.0 || x0 > (p.nx - 1) as f32 * c || y0 > (p.ny - 1) as f32 * c {
            return None;
        }
        let (ix0, ix1) = (clamp_x(x0), (clamp_x(x1) + 1).min(p.nx - 1));
        let (iy0, iy1) = (clamp_y(y0), (clamp_y(y1) + 1).min(p.ny - 1));
        let mut top = f32::NEG_INFINITY;
        for iy in iy0..=iy1 {
            for ix in ix0..=ix1 {
                top = top.max(p.grid.at(p.x0 + ix, p.y0 + iy) - p.base_m);
            }
        }
        Some(top)
    }

    /// True when a terrain patch's surface stays more than `h_m` away from the ball of radius
    /// `radius_m` about `centre` (local metres): every sample within `radius_m + h_m` of it
    /// horizontally is at least `radius_m + h_m` below it. A cheap lower bound of the gap
    /// (false: not terrain, or not proved).
    ///
    /// ```
    /// use savsim::scene::geometry::{Geometry, HeightGrid, TerrainPatch};
    /// use glam::Vec3;
    /// use std::sync::Arc;
    /// let grid = Arc::new(HeightGrid { nx: 3, ny: 3, cell_m: 10.0, heights_m: vec![0.0; 9] });
    /// let flat = Geometry::terrain(TerrainPatch { grid, x0: 0, y0: 0, nx: 3, ny: 3, base_m: 0.0 }).unwrap();
    /// assert!(flat.terrain_clear_by(Vec3::new(10.0, 10.0, 5.0), 1.0, 3.9));
    /// assert!(!flat.terrain_clear_by(Vec3::new(10.0, 10.0, 5.0), 1.0, 4.1));
    /// ```
    pub fn terrain_clear_by(&self, centre: Vec3, radius_m: f32, h_m: f32) -> bool {
        if !self.is_terrain() || h_m.is_nan() || h_m < 0.0 {
            return false;
        }
        let reach = radius_m + h_m;
        match self.terrain_surface_max_in(
            centre.x - reach,
            centre.y - reach,
            centre.x + reach,
            centre.y + reach,
        ) {
            Some(top) => top <= centre.z - reach,
            None => true,
        }
    }

    /// The highest point of a terrain patch's surface over the local rectangle [x0, x1] x
    /// [y0, y1] (clipped to the patch), exactly: the surface is linear on each triangle, so its
    /// maximum over the rectangle is at a grid sample inside it, at a corner, or where an edge
    /// of the rectangle crosses a grid line or a cell's diagonal. None: not terrain, or the
    /// rectangle misses the patch (or is too large to be worth it: use
    /// [`terrain_max_height_in`](Self::terrain_max_height_in)).
    pub fn terrain_surface_max_in(&self, x0: f32, y0: f32, x1: f32, y1: f32) -> Option<f32> {
        let GeometrySource::Terrain(p) = &self.source else {
            return None;
        };
        let c = p.grid.cell_m;
        let (w, h) = ((p.nx - 1) as f32 * c, (p.ny - 1) as f32 * c);
        let (x0, y0, x1, y1) = (x0.max(0.0), y0.max(0.0), x1.min(w), y1.min(h));
        if !(x0 <= x1 && y0 <= y1) {
            return None;
        }
        let cells = ((x1 - x0) / c).ceil() + ((y1 - y0) / c).ceil();
        if cells > 16.0 {
            return self.terrain_max_height_in(x0, y0, x1, y1);
        }
        let at = |x: f32, y: f32| surface_at(p, x / c, y / c);
        let mut top = at(x0, y0).max(at(x1, y0)).max(at(x0, y1)).max(at(x1, y1));
        // Samples inside.
        let (ix0, ix1) = ((x0 / c).ceil() as usize, (x1 / c).floor() as usize);
        let (iy0, iy1) = ((y0 / c).ceil() as usize, (y1 / c).floor() as usize);
        for iy in iy0..=iy1.min(p.ny - 1) {
            for ix in ix0..=ix1.min(p.nx - 1) {
                top = top.max(p.grid.at(p.x0 + ix, p.y0 + iy) - p.base_m);
            }
        }
        // The edges' crossings with grid lines and diagonals (x - y a multiple of the cell).
        let whole = |lo: f32, hi: f32| {
            let k0 = (lo / c).floor() as i64 + 1;
            let k1 = (hi / c).ceil() as i64 - 1;
            (k0..=k1).map(move |k| k as f32 * c)
        };
        for y in [y0, y1] {
            for x in whole(x0, x1) {
                top = top.max(at(x, y));
            }
            for d in whole(x0 - y, x1 - y) {
                top = top.max(at(d + y, y));
            }
        }
        for x in [x0, x1] {
            for y in whole(y0, y1) {
                top = top.max(at(x, y));
            }
            for d in whole(x - y1, x - y0) {
                top = top.max(at(x, x - d));
            }
        }
        Some(top)
    }

    /// True when the segment from `a` to `b` (local metres) lies over a terrain patch and more
    /// than `margin_m` below its surface all along (false: not terrain, or not proved). The
    /// surface along the segment is linear between the points where the segment crosses the
    /// grid's lines and the cells' diagonals, so those points and the ends decide.
    ///
    /// ```
    /// use savsim::scene::geometry::{Geometry, HeightGrid, TerrainPatch};
    /// use glam::Vec3;
    /// use std::sync::Arc;
    /// // A ridge along y = 10 between flat ground at 0 m.
    /// let heights = vec![0.0, 0.0, 0.0, 20.0, 20.0, 20.0, 0.0, 0.0, 0.0];
    /// let grid = Arc::new(HeightGrid { nx: 3, ny: 3, cell_m: 10.0, heights_m: heights });
    /// let ridge = Geometry::terrain(TerrainPatch { grid, x0: 0, y0: 0, nx: 3, ny: 3, base_m: 0.0 }).unwrap();
    /// // Inside the ridge along it: under all along.
    /// assert!(ridge.terrain_holds_segment(Vec3::new(1.0, 10.0, 5.0), Vec3::new(19.0, 10.0, 5.0), 0.01));
    /// // Across it at 5 m: under at the crest, above on the flat both sides.
    /// assert!(!ridge.terrain_holds_segment(Vec3::new(5.0, 1.0, 5.0), Vec3::new(5.0, 19.0, 5.0), 0.01));
    /// ```
    pub fn terrain_holds_segment(&self, a: Vec3, b: Vec3, margin_m: f32) -> bool {
        let GeometrySource::Terrain(p) = &self.source else {
            return false;
        };
        let c = p.grid.cell_m;
        let (ua, ub) = (a / c, b / c);
        let mut at: SmallVec<[f32; 32]> = SmallVec::new();
        at.push(0.0);
        at.push(1.0);
        // Where a coordinate w (linear in t from w0 to w1) crosses a whole number.
        let mut crossings = |w0: f32, w1: f32| -> bool {
            let (lo, hi) = (w0.min(w1), w0.max(w1));
            let mut k = lo.floor() + 1.0;
            while k < hi {
                if at.len() >= 64 {
                    return false;
                }
                at.push((k - w0) / (w1 - w0));
                k += 1.0;
            }
            true
        };
        if !(crossings(ua.x, ub.x) && crossings(ua.y, ub.y) && crossings(ua.x - ua.y, ub.x - ub.y))
        {
            return false;
        }
        at.iter().all(|&t| {
            let q = a.lerp(b, t);
            self.terrain_height_at(q.x, q.y)
                .is_some_and(|h| q.z < h - margin_m)
        })
    }

    /// The parts of the segment from `a` to `b` (local metres) that lie over a terrain patch
    /// and under its surface, as fractions of the segment, in order: exactly (the surface is
    /// linear between the points where the segment crosses the grid's lines and the cells'
    /// diagonals). `None` when this is not terrain or the segment crosses too many cells.
    ///
    /// ```
    /// use savsim::scene::geometry::{Geometry, HeightGrid, TerrainPatch};
    /// use glam::Vec3;
    /// use std::sync::Arc;
    /// // A ridge along y = 10, 20 m high, between flat ground at 0 m.
    /// let heights = vec![0.0, 0.0, 0.0, 20.0, 20.0, 20.0, 0.0, 0.0, 0.0];
    /// let grid = Arc::new(HeightGrid { nx: 3, ny: 3, cell_m: 10.0, heights_m: heights });
    /// let ridge = Geometry::terrain(TerrainPatch { grid, x0: 0, y0: 0, nx: 3, ny: 3, base_m: 0.0 }).unwrap();
    /// // Across the ridge at 10 m: under it from y = 5 to y = 15, a quarter to three quarters.
    /// let runs = ridge.terrain_under_runs(Vec3::new(5.0, -10.0, 10.0), Vec3::new(5.0, 30.0, 10.0)).unwrap();
    /// assert_eq!(runs.len(), 1);
    /// assert!((runs[0].0 - 0.375).abs() < 1e-6 && (runs[0].1 - 0.625).abs() < 1e-6, "{runs:?}");
    /// ```
    pub fn terrain_under_runs(&self, a: Vec3, b: Vec3) -> Option<SmallVec<[(f32, f32); 4]>> {
        let GeometrySource::Terrain(p) = &self.source else {
            return None;
        };
        let c = p.grid.cell_m;
        let (w, h) = ((p.nx - 1) as f32 * c, (p.ny - 1) as f32 * c);
        // The part of the segment over the patch (a slab clip in x and y).
        let (mut t0, mut t1) = (0.0f32, 1.0f32);
        for (o, d, hi) in [(a.x, b.x - a.x, w), (a.y, b.y - a.y, h)] {
            if d == 0.0 {
                if o < 0.0 || o > hi {
                    return Some(SmallVec::new());
                }
            } else {
                let (u, v) = ((0.0 - o) / d, (hi - o) / d);
                t0 = t0.max(u.min(v));
                t1 = t1.min(u.max(v));
            }
        }
        if t0 > t1 {
            return Some(SmallVec::new());
        }
        let (ua, ub) = (a / c, b / c);
        let mut at: SmallVec<[f32; 64]> = SmallVec::new();
        at.push(t0);
        at.push(t1);
        for (w0, w1) in [(ua.x, ub.x), (ua.y, ub.y), (ua.x - ua.y, ub.x - ub.y)] {
            let (lo, hi) = (w0.min(w1), w0.max(w1));
            let mut k = lo.floor() + 1.0;
            while k < hi {
                let t = (k - w0) / (w1 - w0);
                if t > t0 && t < t1 {
                    if at.len() >= 256 {
                        return None;
                    }
                    at.push(t);
                }
                k += 1.0;
            }
        }
        at.sort_unstable_by(f32::total_cmp);
        // Depth under the surface (positive: under), linear between breakpoints.
        let depth = |t: f32| {
            let q = a.lerp(b, t);
            surface_at(p, q.x / c, q.y / c) - q.z
        };
        let mut runs: SmallVec<[(f32, f32); 4]> = SmallVec::new();
        let mut push = |s: f32, e: f32| match runs.last_mut() {
            Some(last) if s <= last.1 => last.1 = last.1.max(e),
            _ => runs.push((s, e)),
        };
        for pair in at.windows(2) {
            let (s, e) = (pair[0], pair[1]);
            let (ds, de) = (depth(s), depth(e));
            match (ds > 0.0, de > 0.0) {
                (true, true) => push(s, e),
                (true, false) => push(s, s + (e - s) * ds / (ds - de)),
                (false, true) => push(s + (e - s) * ds / (ds - de), e),
                (false, false) => {}
            }
        }
        if at.len() == 2 && t0 == t1 && depth(t0) > 0.0 {
            push(t0, t1);
        }
        Some(runs)
    }

    /// True for a terrain patch.
    pub fn is_terrain(&self) -> bool {
        matches!(self.source, GeometrySource::Terrain(_))
    }

    /// Height of a terrain patch's surface at local (x, y), if this is terrain and the point
    /// lies over it.
    pub fn terrain_height_at(&self, x_m: f32, y_m: f32) -> Option<f32> {
        let GeometrySource::Terrain(p) = &self.source else {
            return None;
        };
        let (fx, fy) = (x_m / p.grid.cell_m, y_m / p.grid.cell_m);
        if !(fx >= 0.0 && fy >= 0.0 && fx <= (p.nx - 1) as f32 && fy <= (p.ny - 1) as f32) {
            return None;
        }
        Some(surface_at(p, fx, fy))
    }
}

/// The surface of patch `p` at grid coordinates (`fx`, `fy`) (in cells), clamped to the patch.
fn surface_at(p: &TerrainPatch, fx: f32, fy: f32) -> f32 {
    let (fx, fy) = (
        fx.clamp(0.0, (p.nx - 1) as f32),
        fy.clamp(0.0, (p.ny - 1) as f32),
    );
    let (ix, iy) = ((fx as usize).min(p.nx - 2), (fy as usize).min(p.ny - 2));
    let (u, v) = (fx - ix as f32, fy - iy as f32);
    let h = |dx: usize, dy: usize| p.grid.at(p.x0 + ix + dx, p.y0 + iy + dy) - p.base_m;
    // The same split as the triangles: (a, b, d) below the diagonal, (a, d, c) above.
    if u >= v {
        h(0, 0) + u * (h(1, 0) - h(0, 0)) + v * (h(1, 1) - h(1, 0))
    } else {
        h(0, 0) + v * (h(0, 1) - h(0, 0)) + u * (h(1, 1) - h(0, 1))
    }
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
