//! A ray against a terrain's `HeightField`, exactly: the cells under the ray walked in order
//! (a 2D DDA over the grid), each cell's two triangles (parry's own, `triangles_at`) tested,
//! in f64. parry 0.31's height-field ray cast misses rays that are vertical or nearly so (a
//! rangefinder's), so savsim's dispatcher casts here. A ray that starts under the surface is
//! inside the terrain: distance 0.
//!
//! Pure; no I/O.

use glam::DVec3;
use parry3d::shape::{HeightField, Triangle};

/// Nearest hit of the ray `origin + t dir` (field frame: x and z across, y up; `dir` unit),
/// `0 <= t <= max_t`, on `field`'s surface, or 0 when `origin` is under it.
///
/// ```
/// use glam::{DVec3, Vec3};
/// use parry3d::shape::HeightField;
/// use parry3d::utils::Array2;
/// use savsim_core::collision::contact::ray_height_field::cast;
/// // A flat 100 m square at height 2, and a ray straight down from 30 m.
/// let field = HeightField::new(Array2::repeat(3, 3, 2.0), Vec3::new(100.0, 1.0, 100.0));
/// let down = cast(&field, DVec3::new(10.0, 30.0, -5.0), DVec3::NEG_Y, 40.0);
/// assert!((down.unwrap() - 28.0).abs() < 1e-5);
/// assert_eq!(cast(&field, DVec3::new(0.0, 1.0, 0.0), DVec3::X, 40.0), Some(0.0));
/// assert_eq!(cast(&field, DVec3::new(0.0, 30.0, 0.0), DVec3::Y, 40.0), None);
/// ```
pub fn cast(field: &HeightField, origin: DVec3, dir: DVec3, max_t: f64) -> Option<f64> {
    let grid = Grid::of(field);
    if grid.under_surface(field, origin) {
        return Some(0.0);
    }
    let (t_in, t_out) = grid.clip(origin, dir, max_t)?;
    let mut best: Option<f64> = None;
    grid.walk(origin, dir, t_in, t_out, |i, j, t_enter| {
        if best.is_some_and(|b| b < t_enter) {
            return false;
        }
        let (a, b) = field.triangles_at(i, j);
        for tri in [a, b].into_iter().flatten() {
            if let Some(t) = ray_triangle(origin, dir, &tri).filter(|&t| t <= max_t) {
                best = Some(best.map_or(t, |b: f64| b.min(t)));
            }
        }
        true
    });
    best
}

/// The grid of cells of a field in its frame.
struct Grid {
    rows: usize,
    cols: usize,
    x0: f64,
    z0: f64,
    cell_x: f64,
    cell_z: f64,
    y_min: f64,
    y_max: f64,
}

impl Grid {
    fn of(field: &HeightField) -> Self {
        let scale = field.scale().as_dvec3();
        // parry counts cells: `nrows` is one less than the rows of heights.
        let (rows, cols) = (field.nrows(), field.ncols());
        let aabb = field.local_aabb();
        Self {
            rows,
            cols,
            x0: -0.5 * scale.x,
            z0: -0.5 * scale.z,
            cell_x: scale.x / cols.max(1) as f64,
            cell_z: scale.z / rows.max(1) as f64,
            y_min: f64::from(aabb.mins.y),
            y_max: f64::from(aabb.maxs.y),
        }
    }

    /// The cell under (x, z), if any.
    fn cell(&self, x: f64, z: f64) -> Option<(usize, usize)> {
        let u = (x - self.x0) / self.cell_x;
        let v = (z - self.z0) / self.cell_z;
        let inside = (0.0..=self.cols as f64).contains(&u) && (0.0..=self.rows as f64).contains(&v);
        inside.then(|| {
            (
                (v as usize).min(self.rows - 1),
                (u as usize).min(self.cols - 1),
            )
        })
    }

    /// True when `p` is over the field's footprint and below its surface there.
    fn under_surface(&self, field: &HeightField, p: DVec3) -> bool {
        let Some((i, j)) = self.cell(p.x, p.z) else {
            return false;
        };
        if p.y > self.y_max {
            return false;
        }
        let (a, b) = field.triangles_at(i, j);
        [a, b]
            .into_iter()
            .flatten()
            .any(|tri| ray_triangle(p, DVec3::Y, &tri).is_some())
    }

    /// The part of the ray within the field's box (grown by a millimetre), within `max_t`.
    fn clip(&self, o: DVec3, d: DVec3, max_t: f64) -> Option<(f64, f64)> {
        let lo = DVec3::new(self.x0, self.y_min, self.z0) - 1e-3;
        let hi = DVec3::new(
            self.x0 + self.cell_x * self.cols as f64,
            self.y_max,
            self.z0 + self.cell_z * self.rows as f64,
        ) + 1e-3;
        let (mut t0, mut t1) = (0.0f64, max_t);
        for a in 0..3 {
            if d[a].abs() < 1e-15 {
                if o[a] < lo[a] || o[a] > hi[a] {
                    return None;
                }
                continue;
            }
            let (ta, tb) = ((lo[a] - o[a]) / d[a], (hi[a] - o[a]) / d[a]);
            t0 = t0.max(ta.min(tb));
            t1 = t1.min(ta.max(tb));
        }
        (t0 <= t1).then_some((t0, t1))
    }

    /// Call `visit(row, col, t_enter)` for each cell the ray's x-z projection crosses between
    /// `t_in` and `t_out`, in order, until it returns false.
    fn walk(
        &self,
        o: DVec3,
        d: DVec3,
        t_in: f64,
        t_out: f64,
        mut visit: impl FnMut(usize, usize, f64) -> bool,
    ) {
        let start = o + d * t_in;
        let clamp_u = |u: f64, n: usize| (u.max(0.0) as usize).min(n - 1);
        let mut j = clamp_u((start.x - self.x0) / self.cell_x, self.cols);
        let mut i = clamp_u((start.z - self.z0) / self.cell_z, self.rows);
        let axis = |pos: f64, dir: f64, origin: f64, cell: f64, index: usize| {
            if dir > 0.0 {
                (
                    (origin + (index + 1) as f64 * cell - pos) / dir,
                    cell / dir,
                    1isize,
                )
            } else if dir < 0.0 {
                (
                    (origin + index as f64 * cell - pos) / dir,
                    -cell / dir,
                    -1isize,
                )
            } else {
                (f64::INFINITY, f64::INFINITY, 0isize)
            }
        };
        let (mut next_x, step_tx, dj) = axis(o.x, d.x, self.x0, self.cell_x, j);
        let (mut next_z, step_tz, di) = axis(o.z, d.z, self.z0, self.cell_z, i);
        let mut t_enter = t_in;
        loop {
            if !visit(i, j, t_enter) {
                return;
            }
            let t_next = next_x.min(next_z);
            if t_next > t_out {
                return;
            }
            t_enter = t_next;
            if next_x <= next_z {
                next_x += step_tx;
                match j.checked_add_signed(dj).filter(|&n| n < self.cols) {
                    Some(n) => j = n,
                    None => return,
                }
            } else {
                next_z += step_tz;
                match i.checked_add_signed(di).filter(|&n| n < self.rows) {
                    Some(n) => i = n,
                    None => return,
                }
            }
        }
    }
}

/// The ray parameter where `o + t d` (t >= 0) meets the triangle, edges included.
fn ray_triangle(o: DVec3, d: DVec3, tri: &Triangle) -> Option<f64> {
    let (a, b, c) = (tri.a.as_dvec3(), tri.b.as_dvec3(), tri.c.as_dvec3());
    let (e1, e2) = (b - a, c - a);
    let p = d.cross(e2);
    let det = e1.dot(p);
    if det.abs() < 1e-12 {
        return None;
    }
    let s = o - a;
    let u = s.dot(p) / det;
    let q = s.cross(e1);
    let v = d.dot(q) / det;
    const EDGE: f64 = 1e-9;
    if u < -EDGE || v < -EDGE || u + v > 1.0 + EDGE {
        return None;
    }
    let t = e2.dot(q) / det;
    (t >= 0.0).then_some(t)
}
