//! The sensing layer: the paper's algorithm (Li et al. 2019) as what the vehicle perceives.
//! Octree node, six body-axis rays, beta from the AHP weights, and the box <-> mesh state with
//! its swaps and hold. In `exact` mode it runs at the sensor rate and never decides a contact;
//! its threat decides which triangle meshes are made resident before a contact could need
//! them. In `paper` mode its colliders are what contacts are tested against.
//!
//! A frame: activation (steps 1-2, here), the rays (step 3, `rays`), then rating and swaps
//! ([`swaps`]), beta from [`threat`]; the nodes are the static scene's [`octree`].
//!
//! Pure and synchronous; imports no I/O, no tokio, no rerun.

pub mod octree;
mod rays;
pub mod swaps;
pub mod threat;

use glam::DVec3;

use crate::collision::bodies::{BodyKey, ObstacleRef};
use crate::collision::config::CollisionConfig;
use crate::collision::events::{Event, EventKind};
use crate::collision::meshes::MeshCache;
use crate::collision::sensing::octree::{NodeId, Octree};
use crate::collision::view::{view, World};
use crate::collision::ColliderKind;
use crate::scene::Aabb64;
use crate::world::TrackSample;

/// The nearest hit of one ray.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RayHit {
    /// What it hit.
    pub obstacle: ObstacleRef,
    /// How far, metres.
    pub distance_m: f64,
    /// Where, scene ENU metres.
    pub point_enu_m: DVec3,
}

/// Which rules the layer follows.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Rules {
    /// The paper as written: the node's obstacles only, no hold, every activation reported.
    Paper,
    /// savsim's sensor: the node plus the rays' reach, the hold, swaps reported only for what
    /// the rays (threat) and distance (far) changed; rays test meshes as exact shapes.
    Sensor,
}

#[derive(Debug, Clone, Copy)]
pub(crate) struct Active {
    pub obstacle: ObstacleRef,
    pub collider: ColliderKind,
    pub since_t_s: f64,
    pub beta: f64,
}

/// What one vehicle perceives, kept across frames.
#[derive(Debug, Clone, Default)]
pub struct SensingState {
    node: Option<NodeId>,
    /// The region the static obstacles were last queried for.
    queried: Option<Aabb64>,
    pub(crate) active: Vec<Active>,
    /// The rays at the last frame, in the order of the fan (`CollisionConfig::sensor_fan`):
    /// direction (ENU unit vector) and nearest hit.
    pub rays: Vec<(DVec3, Option<RayHit>)>,
    /// Time of the last frame, seconds.
    pub(crate) last_frame_t_s: Option<f64>,
    /// What the last frame counted (the colliders change only at frames).
    pub(crate) counts: FrameCounts,
}

impl SensingState {
    /// The octree leaf the vehicle was in at the last frame.
    pub fn node(&self) -> Option<NodeId> {
        self.node
    }

    /// Obstacles with a collider, which one, and their beta at the last frame.
    pub fn colliders(&self) -> impl Iterator<Item = (ObstacleRef, ColliderKind, f64)> + '_ {
        self.active.iter().map(|a| (a.obstacle, a.collider, a.beta))
    }

    /// The moving bodies it holds a collider for (the tail of its list, sorted by obstacle).
    pub fn held_bodies(&self) -> impl Iterator<Item = BodyKey> + '_ {
        let from = self
            .active
            .partition_point(|a| matches!(a.obstacle, ObstacleRef::Static(_)));
        self.active[from..].iter().filter_map(|a| match a.obstacle {
            ObstacleRef::Dynamic(key) => Some(key),
            ObstacleRef::Static(_) => None,
        })
    }

    /// The collider the sensing layer holds for `o` (the active list is sorted by obstacle).
    pub(crate) fn collider_of(&self, o: ObstacleRef) -> Option<ColliderKind> {
        self.active
            .binary_search_by_key(&o, |a| a.obstacle)
            .ok()
            .map(|i| self.active[i].collider)
    }
}

/// What a frame did.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub(crate) struct FrameCounts {
    pub active_box: usize,
    pub active_mesh: usize,
    pub active_triangles: usize,
    pub ray_tests: usize,
}

/// What one frame looks at: the world, the settings, the rules, the vehicle's sample, and how
/// an event is stamped.
#[derive(Clone, Copy)]
pub(crate) struct Frame<'a> {
    pub world: &'a World<'a>,
    pub cfg: &'a CollisionConfig,
    pub rules: Rules,
    pub current: &'a TrackSample,
    pub event: &'a dyn Fn(EventKind) -> Event,
}

impl Frame<'_> {
    /// Least time a mesh is held before a downgrade, seconds: none in the paper.
    pub(crate) fn hold_s(&self) -> f64 {
        match self.rules {
            Rules::Paper => 0.0,
            Rules::Sensor => self.cfg.hold_s,
        }
    }
}

/// The layer's scratch buffers; the state comes in per vehicle.
#[derive(Debug, Clone, Default)]
pub(crate) struct Sensing {
    desired: Vec<ObstacleRef>,
    numbers: Vec<u32>,
    merged: Vec<Active>,
    /// The moving bodies with a collider and their boxes, for this frame's rays.
    moving: Vec<(ObstacleRef, Aabb64)>,
}

impl Sensing {
    /// One sensing frame for a vehicle at `f.current`. Swaps are pushed to `events`.
    pub fn frame(
        &mut self,
        f: &Frame<'_>,
        meshes: &mut MeshCache,
        state: &mut SensingState,
        events: &mut Vec<Event>,
    ) -> FrameCounts {
        let Frame {
            world,
            rules,
            current,
            ..
        } = *f;
        let t = current.t_s;
        state.last_frame_t_s = Some(t);
        let mut counts = FrameCounts::default();
        self.activate(f, state, events);
        self.cast_rays(f, meshes, state, &mut counts);
        crate::collision::sensing::swaps::rate_and_swap(f, meshes, state, events);
        if rules == Rules::Sensor && world.shapes.has_meshes() {
            crate::collision::sensing::swaps::make_resident_ahead(f, meshes, state);
        }
        for act in &state.active {
            match act.collider {
                ColliderKind::Box => counts.active_box += 1,
                ColliderKind::Mesh => {
                    let Some(v) = view(world.scene, world.dynamic, act.obstacle) else {
                        continue;
                    };
                    counts.active_mesh += 1;
                    counts.active_triangles += v.geometry.triangle_count();
                    meshes.touch(v.geometry_index);
                }
                ColliderKind::None => {}
            }
        }
        state.counts = counts;
        counts
    }

    /// Steps 1-2: which obstacles have colliders. The paper: the node's. The sensor: the node's
    /// and what the rays or the look-ahead can reach; meshes stay until they are far.
    fn activate(&mut self, f: &Frame<'_>, state: &mut SensingState, events: &mut Vec<Event>) {
        let Frame {
            world,
            rules,
            current,
            ..
        } = *f;
        let Look {
            node,
            region,
            reuse_static,
        } = look(world.octree, f.cfg, rules, state, current);
        let any_dynamic = !world.dynamic.is_empty()
            || state
                .active
                .iter()
                .any(|a| matches!(a.obstacle, ObstacleRef::Dynamic(_)));
        if reuse_static && !any_dynamic {
            return;
        }
        state.queried = Some(region);
        self.desired.clear();
        // With the static answer reused, only the moving bodies (the tail of the sorted active
        // list) are merged again.
        let from = if reuse_static {
            state
                .active
                .partition_point(|a| matches!(a.obstacle, ObstacleRef::Static(_)))
        } else {
            self.desire_statics(f, node, &region);
            0
        };
        self.desire_moving(f, &region);
        state.node = node;
        self.merge_desired(f, state, from, events);
    }

    /// The static obstacles of the node (and, for the sensor, of `region`) into `desired`,
    /// sorted by index (the order of their `ObstacleRef`s).
    fn desire_statics(&mut self, f: &Frame<'_>, node: Option<NodeId>, region: &Aabb64) {
        let world = f.world;
        let numbers = &mut self.numbers;
        numbers.clear();
        if let Some(node) = node {
            numbers.extend_from_slice(world.octree.leaf_items(node));
        }
        if f.rules == Rules::Sensor {
            world.statics.query_aabb(region, |i| numbers.push(i));
        }
        numbers.sort_unstable();
        numbers.dedup();
        self.desired
            .extend(numbers.iter().map(|&i| ObstacleRef::Static(i)));
    }

    /// The moving bodies that reach `region` (for the sensor, within the look-ahead) after the
    /// statics in `desired`, sorted by key rank (the order of their `ObstacleRef`s).
    fn desire_moving(&mut self, f: &Frame<'_>, region: &Aabb64) {
        let (scene, dynamic) = (f.world.scene, f.world.dynamic);
        let lead_s = moving_lead_s(f.cfg, f.rules);
        let numbers = &mut self.numbers;
        numbers.clear();
        f.world.moving_near(region, lead_s, |i, d| {
            let lead = d.speed_mps * lead_s;
            if dynamic.aabb(scene, i).inflated(lead).intersects(region) {
                numbers.push(dynamic.rank(scene, i));
            }
        });
        numbers.sort_unstable();
        numbers.dedup();
        self.desired.extend(
            numbers
                .iter()
                .map(|&r| ObstacleRef::Dynamic(dynamic.key_at_rank(scene, r))),
        );
    }

    /// Merge the active list (sorted) from `from` on with `desired`: what both hold stays as it
    /// is, what only the active list holds leaves (or stays, a mesh), what only `desired` holds
    /// enters as a box.
    fn merge_desired(
        &mut self,
        f: &Frame<'_>,
        state: &mut SensingState,
        from: usize,
        events: &mut Vec<Event>,
    ) {
        self.merged.clear();
        let (mut a, mut d) = (from, 0);
        while a < state.active.len() || d < self.desired.len() {
            let next_active = state.active.get(a).map(|x| x.obstacle);
            let next_desired = self.desired.get(d).copied();
            match (next_active, next_desired) {
                (Some(x), Some(y)) if x == y => {
                    self.merged.push(state.active[a]);
                    a += 1;
                    d += 1;
                }
                (Some(x), y) if y.is_none_or(|y| x < y) => {
                    self.merged.extend(leaving(f, state.active[a], events));
                    a += 1;
                }
                (_, Some(y)) => {
                    self.merged.extend(entering(f, y, events));
                    d += 1;
                }
                _ => break,
            }
        }
        state.active.truncate(from);
        state.active.extend_from_slice(&self.merged);
    }
}

/// The region whose obstacles must have colliders: the paper's node (a 2 m box where there is
/// none), or for the sensor the rays' reach or the look-ahead at the vehicle's speed, whichever
/// is longer, around the vehicle.
fn required_region(
    (octree, cfg): (&Octree, &CollisionConfig),
    rules: Rules,
    current: &TrackSample,
    node: Option<NodeId>,
) -> Aabb64 {
    let position = current.position_enu_m;
    match rules {
        Rules::Sensor => {
            let speed = current.velocity_enu_mps.length();
            let reach = cfg.ray_length_m.max(speed * cfg.look_ahead_s);
            Aabb64::around(position, DVec3::splat(reach))
        }
        Rules::Paper => node.map_or(Aabb64::around(position, DVec3::ONE), |n| {
            octree.node_aabb(n)
        }),
    }
}

/// Where a frame looks: the octree leaf the vehicle is in, the region its obstacles are
/// desired in, and whether the static obstacles' last answer is reused.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Look {
    pub node: Option<NodeId>,
    pub region: Aabb64,
    pub reuse_static: bool,
}

/// Where a frame at `current` under `rules` looks, after `state`'s last frame. Static
/// obstacles are queried with a margin and the answer reused while the required region stays
/// inside it (and the node is the same); the moving ones are checked against the same region.
pub(crate) fn look(
    octree: &Octree,
    cfg: &CollisionConfig,
    rules: Rules,
    state: &SensingState,
    current: &TrackSample,
) -> Look {
    let node = octree.leaf_at(current.position_enu_m);
    let required = required_region((octree, cfg), rules, current, node);
    let reuse_static = state.node == node
        && state
            .queried
            .is_some_and(|q| q.contains(required.min) && q.contains(required.max));
    let region = match state.queried {
        Some(q) if reuse_static => q,
        _ if rules == Rules::Sensor => {
            let margin = (0.25 * (required.max.x - required.min.x)).max(10.0);
            required.inflated(margin)
        }
        _ => required,
    };
    Look {
        node,
        region,
        reuse_static,
    }
}

/// How far ahead a moving body's speed carries it into a frame's region under `rules`,
/// seconds: the look-ahead for the sensor, none in the paper.
pub(crate) fn moving_lead_s(cfg: &CollisionConfig, rules: Rules) -> f64 {
    if rules == Rules::Sensor {
        cfg.look_ahead_s
    } else {
        0.0
    }
}

/// An obstacle with a collider that is no longer desired: kept if it is a mesh (held for
/// `hold_s` in the paper; for the sensor until it is far, the paper's 800 m rule applied in
/// `rate_and_swap`), else dropped, which the paper reports. `None` when dropped, or when its
/// track ended (nothing to report).
fn leaving(f: &Frame<'_>, act: Active, events: &mut Vec<Event>) -> Option<Active> {
    let v = view(f.world.scene, f.world.dynamic, act.obstacle)?;
    let position = f.current.position_enu_m;
    let keep = act.collider == ColliderKind::Mesh
        && match f.rules {
            Rules::Paper => f.current.t_s - act.since_t_s < f.hold_s(),
            Rules::Sensor => true,
        };
    if keep {
        return Some(act);
    }
    if f.rules == Rules::Paper {
        events.push((f.event)(EventKind::ColliderSwap {
            obstacle: v.id.to_owned(),
            from: act.collider,
            to: ColliderKind::None,
            beta: act.beta,
            distance_m: v.aabb_enu_m.distance_to(position),
            reason: "left",
        }));
    }
    None
}

/// A desired obstacle without a collider: a box from now on (the paper reports it). `None`
/// when its track ended.
fn entering(f: &Frame<'_>, obstacle: ObstacleRef, events: &mut Vec<Event>) -> Option<Active> {
    let v = view(f.world.scene, f.world.dynamic, obstacle)?;
    if f.rules == Rules::Paper {
        events.push((f.event)(EventKind::ColliderSwap {
            obstacle: v.id.to_owned(),
            from: ColliderKind::None,
            to: ColliderKind::Box,
            beta: 0.0,
            distance_m: v.aabb_enu_m.distance_to(f.current.position_enu_m),
            reason: "node",
        }));
    }
    Some(Active {
        obstacle,
        collider: ColliderKind::Box,
        since_t_s: f.current.t_s,
        beta: 0.0,
    })
}
