//! The reference's own terrain surface, from a patch's height grid: two triangles per cell,
//! split along its south-west to north-east diagonal (scenes/README.md), heights in f64.
//! Written here, not taken from the scene or the contact layer, so that a mistake in either
//! shows against it.

use crate::scene::geometry::TerrainPatch;

/// Two shapes closer than this touch, metres (0.1 mm; two boxes are tested on their 15
/// separating axes, where a corner-to-corner gap may be up to 1.7 times this).
pub const TOUCH_M: f64 = 1e-4;

/// A terrain patch's grid in its own frame: sample (i, j) at (i cell, j cell), heights above
/// the patch's origin.
#[derive(Debug, Clone)]
pub(super) struct Ground {
    nx: usize,
    ny: usize,
    cell_m: f64,
    heights_m: Vec<f64>,
}

impl Ground {
    pub(super) fn of(p: &TerrainPatch) -> Self {
        let mut heights_m = Vec::with_capacity(p.nx * p.ny);
        for j in 0..p.ny {
            for i in 0..p.nx {
                let h = p.grid.heights_m[(p.y0 + j) * p.grid.nx + p.x0 + i];
                heights_m.push(f64::from(h) - f64::from(p.base_m));
            }
        }
        Self {
            nx: p.nx,
            ny: p.ny,
            cell_m: f64::from(p.grid.cell_m),
            heights_m,
        }
    }

    fn h(&self, i: usize, j: usize) -> f64 {
        self.heights_m[j * self.nx + i]
    }

    /// The surface's height at local (x, y), if the point is over the patch (its edges
    /// included, within `TOUCH_M`: a point on the seam of two patches
    /// is over both).
    pub(super) fn height_at(&self, x: f64, y: f64) -> Option<f64> {
        let edge = TOUCH_M / self.cell_m;
        let (wx, wy) = ((self.nx - 1) as f64, (self.ny - 1) as f64);
        let (fx, fy) = (x / self.cell_m, y / self.cell_m);
        if !(-edge..=wx + edge).contains(&fx) || !(-edge..=wy + edge).contains(&fy) {
            return None;
        }
        let (fx, fy) = (fx.clamp(0.0, wx), fy.clamp(0.0, wy));
        let (i, j) = (
            (fx as usize).min(self.nx - 2),
            (fy as usize).min(self.ny - 2),
        );
        let (u, v) = (fx - i as f64, fy - j as f64);
        let (sw, se, nw, ne) = (
            self.h(i, j),
            self.h(i + 1, j),
            self.h(i, j + 1),
            self.h(i + 1, j + 1),
        );
        // South-east of the diagonal: the triangle (sw, se, ne); north-west: (sw, ne, nw).
        Some(if u >= v {
            sw + u * (se - sw) + v * (ne - se)
        } else {
            sw + v * (nw - sw) + u * (ne - nw)
        })
    }

    /// The highest sample of the cells the rectangle touches (the surface is flat within each
    /// triangle, so no point of it over the rectangle is higher); `None` off the patch.
    pub(super) fn highest_in(&self, (x0, y0): (f64, f64), (x1, y1): (f64, f64)) -> Option<f64> {
        let cell = |v: f64, n: usize| ((v / self.cell_m).floor().max(0.0) as usize).min(n - 1);
        let (wx, wy) = (
            (self.nx - 1) as f64 * self.cell_m,
            (self.ny - 1) as f64 * self.cell_m,
        );
        if x1 < 0.0 || y1 < 0.0 || x0 > wx || y0 > wy {
            return None;
        }
        let (i0, i1) = (cell(x0, self.nx), (cell(x1, self.nx) + 1).min(self.nx - 1));
        let (j0, j1) = (cell(y0, self.ny), (cell(y1, self.ny) + 1).min(self.ny - 1));
        let mut top = f64::NEG_INFINITY;
        for j in j0..=j1 {
            for i in i0..=i1 {
                top = top.max(self.h(i, j));
            }
        }
        Some(top)
    }

    /// The surface's triangles, local metres.
    pub(super) fn triangles(&self) -> (Vec<glam::Vec3>, Vec<[u32; 3]>) {
        let mut vertices = Vec::with_capacity(self.nx * self.ny);
        for j in 0..self.ny {
            for i in 0..self.nx {
                let (x, y) = (i as f64 * self.cell_m, j as f64 * self.cell_m);
                vertices.push(glam::DVec3::new(x, y, self.h(i, j)).as_vec3());
            }
        }
        let at = |i: usize, j: usize| (j * self.nx + i) as u32;
        let mut indices = Vec::with_capacity(2 * (self.nx - 1) * (self.ny - 1));
        for j in 0..self.ny - 1 {
            for i in 0..self.nx - 1 {
                let (sw, se, nw, ne) = (at(i, j), at(i + 1, j), at(i, j + 1), at(i + 1, j + 1));
                indices.push([sw, se, ne]);
                indices.push([sw, ne, nw]);
            }
        }
        (vertices, indices)
    }
}
