//! Queries of a terrain patch's surface, in the patch's frame (local metres): its height at a
//! point, bounds and the exact maximum over a rectangle, and the parts of a segment under it.
//! The surface is the patch's triangles (each cell split along the diagonal from its lower
//! left to its upper right sample), linear on each, so every answer here is exact, or a
//! bound that says which way it errs.

use glam::Vec3;
use smallvec::SmallVec;

use crate::scene::geometry::{Geometry, GeometrySource, TerrainPatch};

/// Most grid-line and diagonal crossings [`Geometry::terrain_under_runs`] walks for one
/// segment (its list of crossings is bounded by this).
pub const MAX_UNDER_CROSSINGS: usize = 1 << 16;

impl Geometry {
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
    /// use savsim_core::scene::geometry::{Geometry, HeightGrid, TerrainPatch};
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
    /// use savsim_core::scene::geometry::{Geometry, HeightGrid, TerrainPatch};
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
    /// diagonals). `None` when this is not terrain or the segment crosses more than
    /// [`MAX_UNDER_CROSSINGS`] grid lines (at 1 m cells, more than 20 km in one interval, which
    /// the gap rules end first).
    ///
    /// ```
    /// use savsim_core::scene::geometry::{Geometry, HeightGrid, TerrainPatch};
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
                    if at.len() >= MAX_UNDER_CROSSINGS {
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
