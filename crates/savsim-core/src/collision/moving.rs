//! The moving bodies of a tick (other vehicles, ADS-B traffic, scripted tracks) and their broad
//! phase. The caller fills a [`MovingBodies`] once per world step (a session per tick, the
//! bench's swarm once for all its vehicles' ticks at one instant); what the stages need of it
//! is derived once, on first use, and shared by every tick that reads it: each body's box at
//! its pose, a key index, and, once many queries have asked about more than a few bodies,
//! parry's `Bvh` over the spheres each can reach in the interval. A tick then touches the
//! bodies near it, not all of them; a set that is read only a few times (a session's tick)
//! is scanned instead of paying for an index it would hardly use.
//!
//! Pure and synchronous; imports no I/O.

use std::cell::{Cell, OnceCell};

use parry3d::bounding_volume::Aabb;
use parry3d::partitioning::{Bvh, BvhBuildStrategy};

use crate::collision::bodies::{radius_m, BodyKey, DynamicBody};
use crate::scene::{Aabb64, Placement, Scene};

/// Above this many bodies, region queries go through a `Bvh` instead of a scan...
const INDEX_ABOVE: usize = 24;
/// ...once this many queries have been scanned: the point past which building the `Bvh` pays
/// for itself (docs/performance.md, "Live fleets").
const SCANS_BEFORE_INDEX: u32 = 8;

/// The moving bodies of one tick.
///
/// ```
/// use savsim_core::collision::moving::MovingBodies;
/// let mut moving = MovingBodies::default();
/// assert!(moving.is_empty());
/// moving.clear();
/// assert_eq!(moving.as_slice().len(), 0);
/// ```
#[derive(Debug, Clone, Default)]
pub struct MovingBodies {
    bodies: Vec<DynamicBody>,
    /// What the stages need, derived on first use (reset by every change).
    derived: OnceCell<Derived>,
}

#[derive(Debug, Clone)]
struct Derived {
    /// The bodies' keys, sorted, and each one's body index (for a binary search that stays
    /// in one array).
    keys: Vec<BodyKey>,
    by_key: Vec<u32>,
    /// Each body's place in key order (the inverse of `by_key`).
    rank: Vec<u32>,
    /// Each body's box at its current pose, scene ENU metres, computed when first asked
    /// (most bodies near a tick are only ever distance-tested).
    aabbs: Vec<Cell<Option<Aabb64>>>,
    /// Radius of the sphere about each body's current position that holds it over the
    /// interval (its model's radius plus how far it moved), metres.
    reach_m: Vec<f64>,
    /// The fastest body's speed, m/s (a query's lead time grows its region by this much).
    max_speed_mps: f64,
    /// Region queries answered so far.
    queries: Cell<u32>,
    /// The `Bvh` over the reach spheres' boxes, built on the query that passes
    /// `SCANS_BEFORE_INDEX` (many bodies only).
    index: OnceCell<Bvh>,
}

impl From<Vec<DynamicBody>> for MovingBodies {
    fn from(bodies: Vec<DynamicBody>) -> Self {
        Self {
            bodies,
            derived: OnceCell::new(),
        }
    }
}

impl MovingBodies {
    /// Forget every body (keeps the buffer).
    pub fn clear(&mut self) {
        self.bodies.clear();
        self.derived = OnceCell::new();
    }

    /// Add a body.
    pub fn push(&mut self, body: DynamicBody) {
        self.bodies.push(body);
        self.derived = OnceCell::new();
    }

    /// Add bodies.
    pub fn extend(&mut self, bodies: impl IntoIterator<Item = DynamicBody>) {
        self.bodies.extend(bodies);
        self.derived = OnceCell::new();
    }

    /// The bodies, in the order they were added.
    pub fn as_slice(&self) -> &[DynamicBody] {
        &self.bodies
    }

    /// Number of bodies.
    pub fn len(&self) -> usize {
        self.bodies.len()
    }

    /// True when there are none.
    pub fn is_empty(&self) -> bool {
        self.bodies.is_empty()
    }

    fn derived(&self, scene: &Scene) -> &Derived {
        self.derived
            .get_or_init(|| Derived::of(scene, &self.bodies))
    }

    /// The index of the body with `key`, if it is here (a key not here is a track that ended).
    pub(crate) fn find(&self, scene: &Scene, key: BodyKey) -> Option<usize> {
        let d = self.derived(scene);
        d.keys
            .binary_search(&key)
            .ok()
            .map(|k| d.by_key[k] as usize)
    }

    /// Where body `i`'s key is in key order.
    pub(crate) fn rank(&self, scene: &Scene, i: usize) -> u32 {
        self.derived(scene).rank[i]
    }

    /// The key at `rank` in key order.
    pub(crate) fn key_at_rank(&self, scene: &Scene, rank: u32) -> BodyKey {
        self.derived(scene).keys[rank as usize]
    }

    /// Body `i`'s box at its current pose (empty for a model the scene does not have).
    pub(crate) fn aabb(&self, scene: &Scene, i: usize) -> Aabb64 {
        let cell = &self.derived(scene).aabbs[i];
        cell.get().unwrap_or_else(|| {
            let b = &self.bodies[i];
            let aabb = scene
                .geometries
                .get(b.geometry_index)
                .map_or(Aabb64::EMPTY, |g| {
                    Placement {
                        position_enu_m: b.current.position_enu_m,
                        enu_from_local: b.current.enu_from_body,
                    }
                    .enu_aabb(&g.local_aabb)
                });
            cell.set(Some(aabb));
            aabb
        })
    }

    /// Body `i`.
    pub(crate) fn get(&self, i: usize) -> &DynamicBody {
        &self.bodies[i]
    }

    /// Call `visit(index, body)` for every body that may come within `lead_s` seconds of its
    /// speed of `region` in this interval (a sphere test: its model's radius plus how far it
    /// moved, about where it is now). Bodies of a model the scene does not have are skipped.
    pub(crate) fn near(
        &self,
        scene: &Scene,
        region: &Aabb64,
        lead_s: f64,
        mut visit: impl FnMut(usize, &DynamicBody),
    ) {
        let d = self.derived(scene);
        let mut consider = |i: usize| {
            let body = &self.bodies[i];
            let lead_m = body.speed_mps * lead_s;
            if d.reach_m[i].is_finite()
                && region.distance_to(body.current.position_enu_m) <= d.reach_m[i] + lead_m
            {
                visit(i, body);
            }
        };
        match d.index_for_query(&self.bodies) {
            None => (0..self.bodies.len()).for_each(consider),
            Some(bvh) => {
                let grown = region.inflated(d.max_speed_mps * lead_s + 0.01);
                let query = Aabb::new(grown.min.as_vec3(), grown.max.as_vec3());
                for i in bvh.intersect_aabb(&query) {
                    consider(i as usize);
                }
            }
        }
    }
}

impl Derived {
    fn of(scene: &Scene, bodies: &[DynamicBody]) -> Self {
        let mut by_key: Vec<u32> = (0..bodies.len() as u32).collect();
        by_key.sort_unstable_by_key(|&i| bodies[i as usize].key);
        let keys = by_key.iter().map(|&i| bodies[i as usize].key).collect();
        let mut rank = vec![0; bodies.len()];
        for (r, &i) in by_key.iter().enumerate() {
            rank[i as usize] = r as u32;
        }
        let aabbs = vec![Cell::new(None); bodies.len()];
        let reach_m = bodies
            .iter()
            .map(|b| match scene.geometries.get(b.geometry_index) {
                Some(g) => {
                    radius_m(g) + b.current.position_enu_m.distance(b.previous.position_enu_m)
                }
                None => f64::INFINITY,
            })
            .collect();
        let max_speed_mps = bodies
            .iter()
            .map(|b| b.speed_mps)
            .filter(|s| s.is_finite())
            .fold(0.0, f64::max);
        Self {
            keys,
            by_key,
            rank,
            aabbs,
            reach_m,
            max_speed_mps,
            queries: Cell::new(0),
            index: OnceCell::new(),
        }
    }

    /// Count a query; the `Bvh` to answer it with, if one is worth having by now.
    fn index_for_query(&self, bodies: &[DynamicBody]) -> Option<&Bvh> {
        let asked = self.queries.get().saturating_add(1);
        self.queries.set(asked);
        (bodies.len() > INDEX_ABOVE && asked > SCANS_BEFORE_INDEX)
            .then(|| self.index.get_or_init(|| self.build_index(bodies)))
    }

    /// The `Bvh` over the boxes of the spheres the bodies can reach in the interval.
    fn build_index(&self, bodies: &[DynamicBody]) -> Bvh {
        Bvh::from_iter(
            BvhBuildStrategy::Binned,
            bodies
                .iter()
                .zip(&self.reach_m)
                .enumerate()
                .filter(|(_, (_, r))| r.is_finite())
                .map(|(i, (b, r))| {
                    // Grown by a centimetre and f32's steps at its coordinates.
                    let p = b.current.position_enu_m;
                    let r = r + 0.01 + 4.0 * f64::from(f32::EPSILON) * p.abs().max_element();
                    let sphere = Aabb64::around(p, glam::DVec3::splat(r));
                    (i, Aabb::new(sphere.min.as_vec3(), sphere.max.as_vec3()))
                }),
        )
    }
}
