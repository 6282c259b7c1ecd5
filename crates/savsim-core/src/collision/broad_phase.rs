//! The static broad phase: parry's `Bvh` over the static obstacles' boxes, built once. It
//! answers the contact layer's region queries and every ray (the sensing layer's, the feed's):
//! it only knows boxes and leaf ids; the exact test is the caller's closure. (The octree stays
//! for what the paper defines by it: the vehicle's node.)
//!
//! The tree is f32, the scene f64: every leaf is loosened by more than f32 rounds at its
//! coordinates, each answer is filtered again on the f64 box, and a ray is started where it
//! enters the scene's bounds, so a query far from the origin is as exact as one near it.
//! Queries do not allocate.
//!
//! Pure and synchronous; imports no I/O.

use std::cell::{Cell, RefCell};

use glam::DVec3;
use parry3d::bounding_volume::Aabb;
use parry3d::partitioning::{Bvh, BvhBuildStrategy};
use parry3d::query::Ray;

use crate::scene::{Aabb64, Scene};

/// How much an f64 box is grown when it becomes an f32 one, metres: a centimetre plus a few
/// f32 steps at its largest coordinate.
fn margin_m(b: &Aabb64) -> f64 {
    let largest = b.min.abs().max(b.max.abs()).max_element();
    0.01 + 4.0 * f64::from(f32::EPSILON) * largest
}

fn loose_f32(b: &Aabb64) -> Aabb {
    let m = margin_m(b);
    Aabb::new((b.min - m).as_vec3(), (b.max + m).as_vec3())
}

/// parry's `Bvh` over static boxes, with the f64 boxes beside it.
#[derive(Clone)]
pub struct StaticBroadPhase {
    bvh: Bvh,
    boxes: Vec<Aabb64>,
    bounds: Aabb64,
}

impl std::fmt::Debug for StaticBroadPhase {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("StaticBroadPhase")
            .field("objects", &self.boxes.len())
            .finish_non_exhaustive()
    }
}

impl StaticBroadPhase {
    /// Build over `boxes` (object `i` has box `boxes[i]`, scene ENU metres).
    ///
    /// ```
    /// use savsim_core::collision::broad_phase::StaticBroadPhase;
    /// use savsim_core::scene::Aabb64;
    /// use glam::DVec3;
    /// let boxes: Vec<Aabb64> = (0..100)
    ///     .map(|i| Aabb64::around(DVec3::new(i as f64 * 50.0, 0.0, 10.0), DVec3::splat(5.0)))
    ///     .collect();
    /// let index = StaticBroadPhase::build(&boxes);
    /// let mut hits = Vec::new();
    /// index.query_aabb(&Aabb64::around(DVec3::new(100.0, 0.0, 10.0), DVec3::splat(60.0)), |i| hits.push(i));
    /// hits.sort();
    /// assert_eq!(hits, vec![1, 2, 3]);
    /// ```
    pub fn build(boxes: &[Aabb64]) -> Self {
        let bvh = Bvh::from_iter(
            BvhBuildStrategy::Binned,
            boxes.iter().enumerate().map(|(i, b)| (i, loose_f32(b))),
        );
        Self {
            bvh,
            boxes: boxes.to_vec(),
            bounds: boxes.iter().fold(Aabb64::EMPTY, |a, b| a.union(*b)),
        }
    }

    /// The objects' boxes, by index.
    pub fn boxes(&self) -> &[Aabb64] {
        &self.boxes
    }

    /// Number of objects indexed.
    pub fn object_count(&self) -> usize {
        self.boxes.len()
    }

    /// Heap bytes held (the tree and the f64 boxes).
    pub fn memory_bytes(&self) -> usize {
        self.bvh.heap_memory_size() + self.boxes.capacity() * std::mem::size_of::<Aabb64>()
    }

    /// Call `visit` once for every object whose box intersects `query`.
    pub fn query_aabb(&self, query: &Aabb64, mut visit: impl FnMut(u32)) {
        if !query.intersects(&self.bounds) {
            return;
        }
        // Clipped to the scene first: a query may reach far (a column to the sky) and f32
        // would make it infinite.
        let clipped = Aabb64::new(
            query.min.max(self.bounds.min),
            query.max.min(self.bounds.max),
        );
        let loose = loose_f32(&clipped);
        for i in self.bvh.intersect_aabb(&loose) {
            if self.boxes[i as usize].intersects(query) {
                visit(i);
            }
        }
    }

    /// The nearest hit of the ray from `origin` along `dir` (unit) up to `max_m`: objects are
    /// offered nearest box first, with the distance to beat; `hit(object, limit_m)` returns
    /// the exact distance if the object is hit closer than `limit_m`. Returns the object and
    /// distance of the nearest hit.
    ///
    /// ```
    /// use savsim_core::collision::broad_phase::StaticBroadPhase;
    /// use savsim_core::scene::Aabb64;
    /// use glam::DVec3;
    /// let boxes: Vec<Aabb64> = (0..100)
    ///     .map(|i| Aabb64::around(DVec3::new(i as f64 * 50.0, 0.0, 0.0), DVec3::splat(5.0)))
    ///     .collect();
    /// let index = StaticBroadPhase::build(&boxes);
    /// let mut offered = 0;
    /// let best = index.cast_ray(DVec3::new(1000.0, 0.0, 0.0), DVec3::X, 500.0, |i, limit| {
    ///     offered += 1;
    ///     let t = boxes[i as usize].min.x - 1000.0;
    ///     (t >= 0.0 && t < limit).then_some(t)
    /// });
    /// assert_eq!(best, Some((21, 45.0)));
    /// assert!(offered < 3, "boxes beyond the first hit are not offered");
    /// ```
    pub fn cast_ray(
        &self,
        origin: DVec3,
        dir: DVec3,
        max_m: f64,
        hit: impl FnMut(u32, f64) -> Option<f64>,
    ) -> Option<(u32, f64)> {
        // Start where the ray enters the scene's bounds: small coordinates for the f32 tree.
        let start = self.bounds.inflated(1.0).ray_entry(origin, dir, max_m)?;
        let from = origin + dir * start;
        let best: Cell<Option<(u32, f64)>> = Cell::new(None);
        let hit = RefCell::new(hit);
        let ray = Ray::new(from.as_vec3(), dir.as_vec3());
        let reach = (max_m - start) as f32 + 0.02;
        let boxes = &self.boxes;
        self.bvh.cast_ray(&ray, reach.max(0.0), |i, _| {
            let limit = best.get().map_or(max_m, |b| b.1);
            boxes[i as usize].ray_entry(origin, dir, limit)?;
            let d = (hit.borrow_mut())(i, limit).filter(|&d| d < limit)?;
            best.set(Some((i, d)));
            // The tree's own cost is along the shifted ray, in f32.
            Some(((d - start) as f32).max(0.0))
        });
        best.get()
    }

    /// The highest terrain patch under `position` (an east-north column) and its surface's
    /// height there, ENU metres; `None` where no terrain lies.
    pub fn terrain_under(&self, scene: &Scene, position: DVec3) -> Option<(u32, f64)> {
        let column = Aabb64::new(
            DVec3::new(position.x, position.y, f64::MIN / 4.0),
            DVec3::new(position.x, position.y, f64::MAX / 4.0),
        );
        let mut ground: Option<(u32, f64)> = None;
        self.query_aabb(&column, |i| {
            let surface = scene.obstacles[i as usize].terrain_height_enu_m(position.x, position.y);
            if let Some(z) = surface.filter(|&z| ground.is_none_or(|g| z > g.1)) {
                ground = Some((i, z));
            }
        });
        ground
    }
}
