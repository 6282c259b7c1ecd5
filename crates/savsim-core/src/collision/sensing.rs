//! The sensing layer: the paper's algorithm (Li et al. 2019) as what the vehicle perceives.
//! Octree node, six body-axis rays, beta from the AHP weights, and the box <-> mesh state with
//! its swaps and hold. In `exact` mode it runs at the sensor rate and never decides a contact;
//! its threat decides which triangle meshes are made resident before a contact could need
//! them. In `paper` mode its colliders are what contacts are tested against.
//!
//! Pure and synchronous; imports no I/O, no tokio, no rerun.

use glam::DVec3;

use crate::collision::bodies::{view, Body, ObstacleRef, World};
use crate::collision::config::CollisionConfig;
use crate::collision::contact;
use crate::collision::events::{Event, EventKind};
use crate::collision::meshes::MeshCache;
use crate::collision::octree::NodeId;
use crate::collision::shapes::ExactShapes;
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
        crate::collision::swaps::rate_and_swap(f, meshes, state, events);
        if rules == Rules::Sensor && world.shapes.has_meshes() {
            crate::collision::swaps::make_resident_ahead(f, meshes, state);
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
            cfg,
            rules,
            current,
            event,
        } = *f;
        let (scene, dynamic, octree) = (world.scene, world.dynamic, world.octree);
        let t = current.t_s;
        let position = current.position_enu_m;
        let node = octree.leaf_at(position);
        let required = match rules {
            Rules::Sensor => {
                let speed = current.velocity_enu_mps.length();
                let reach = cfg.ray_length_m.max(speed * cfg.look_ahead_s);
                Aabb64::around(position, DVec3::splat(reach))
            }
            Rules::Paper => node.map_or(Aabb64::around(position, DVec3::ONE), |n| {
                octree.node_aabb(n)
            }),
        };
        let hold = f.hold_s();
        // Static obstacles are queried with a margin and the answer reused while the required
        // region stays inside it (and the node is the same). Moving ones are re-checked.
        let reuse_static = state.node == node
            && state
                .queried
                .is_some_and(|q| q.contains(required.min) && q.contains(required.max));
        let any_dynamic = !dynamic.is_empty()
            || state
                .active
                .iter()
                .any(|a| matches!(a.obstacle, ObstacleRef::Dynamic(_)));
        if reuse_static && !any_dynamic {
            return;
        }
        let region = match state.queried {
            Some(q) if reuse_static => q,
            _ if rules == Rules::Sensor => {
                let margin = (0.25 * (required.max.x - required.min.x)).max(10.0);
                required.inflated(margin)
            }
            _ => required,
        };
        state.queried = Some(region);
        self.desired.clear();
        // Sorted as plain numbers (static indices, then moving bodies' key ranks), which is
        // the order of their `ObstacleRef`s.
        let numbers = &mut self.numbers;
        numbers.clear();
        // With the static answer reused, only the moving bodies (the tail of the sorted active
        // list) are merged again.
        let from = if reuse_static {
            state
                .active
                .partition_point(|a| matches!(a.obstacle, ObstacleRef::Static(_)))
        } else {
            0
        };
        if !reuse_static {
            if let Some(node) = node {
                numbers.extend_from_slice(octree.leaf_items(node));
            }
            if rules == Rules::Sensor {
                world.statics.query_aabb(&region, |i| numbers.push(i));
            }
            numbers.sort_unstable();
            numbers.dedup();
            self.desired
                .extend(numbers.iter().map(|&i| ObstacleRef::Static(i)));
            numbers.clear();
        }
        let lead_s = if rules == Rules::Sensor {
            cfg.look_ahead_s
        } else {
            0.0
        };
        world.moving_near(&region, lead_s, |i, d| {
            let lead = d.speed_mps * lead_s;
            if dynamic.aabb(scene, i).inflated(lead).intersects(&region) {
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
        state.node = node;
        // Merge the active list (sorted) from `from` on with the desired one.
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
                    let act = state.active[a];
                    a += 1;
                    let Some(v) = view(scene, dynamic, act.obstacle) else {
                        continue; // its track ended: nothing to report
                    };
                    let distance_m = v.aabb_enu_m.distance_to(position);
                    let keep = act.collider == ColliderKind::Mesh
                        && match rules {
                            Rules::Paper => t - act.since_t_s < hold,
                            // A mesh stays resident until it is far (the paper's 800 m rule,
                            // applied in `rate_and_swap`), not merely out of reach.
                            Rules::Sensor => true,
                        };
                    if keep {
                        self.merged.push(act);
                    } else if rules == Rules::Paper {
                        events.push(event(EventKind::ColliderSwap {
                            obstacle: v.id.to_owned(),
                            from: act.collider,
                            to: ColliderKind::None,
                            beta: act.beta,
                            distance_m,
                            reason: "left",
                        }));
                    }
                }
                (_, Some(y)) => {
                    d += 1;
                    let Some(v) = view(scene, dynamic, y) else {
                        continue;
                    };
                    if rules == Rules::Paper {
                        events.push(event(EventKind::ColliderSwap {
                            obstacle: v.id.to_owned(),
                            from: ColliderKind::None,
                            to: ColliderKind::Box,
                            beta: 0.0,
                            distance_m: v.aabb_enu_m.distance_to(position),
                            reason: "node",
                        }));
                    }
                    self.merged.push(Active {
                        obstacle: y,
                        collider: ColliderKind::Box,
                        since_t_s: t,
                        beta: 0.0,
                    });
                }
                _ => break,
            }
        }
        state.active.truncate(from);
        state.active.extend_from_slice(&self.merged);
    }

    /// Step 3: six rays along the body axes against the active colliders: static ones front to
    /// back through the static `Bvh` (stopping at the nearest hit), moving ones by a scan.
    fn cast_rays(
        &mut self,
        f: &Frame<'_>,
        meshes: &mut MeshCache,
        state: &mut SensingState,
        counts: &mut FrameCounts,
    ) {
        let Frame {
            world,
            cfg,
            rules,
            current,
            ..
        } = *f;
        let (scene, dynamic) = (world.scene, world.dynamic);
        let position = current.position_enu_m;
        // The moving bodies with a collider (the sorted active list's tail) that a ray can
        // reach, with their boxes, looked up once for the six rays.
        self.moving.clear();
        let first_moving = state
            .active
            .partition_point(|a| matches!(a.obstacle, ObstacleRef::Static(_)));
        self.moving.extend(
            state.active[first_moving..]
                .iter()
                .filter_map(|a| Some((a.obstacle, view(scene, dynamic, a.obstacle)?.aabb_enu_m)))
                .filter(|(_, aabb)| aabb.distance_to(position) <= cfg.ray_length_m),
        );
        let moving = &self.moving;
        let fan = cfg.sensor_fan;
        state.rays.resize(fan.len(), (DVec3::ZERO, None));
        for k in 0..fan.len() {
            let dir = fan.direction_enu(k, current.attitude.enu_from_frd);
            let active = &state.active;
            let mut tests = 0;
            // `bounds_checked`: the caller already knows the ray meets the obstacle's bounds.
            let mut ray_test = |o: ObstacleRef, limit: f64, bounds_checked: bool| {
                let i = active.binary_search_by_key(&o, |a| a.obstacle).ok()?;
                let act = active[i];
                let v = view(scene, dynamic, o)?;
                if !bounds_checked && !v.aabb_enu_m.ray_hits(position, dir, limit) {
                    return None;
                }
                tests += 1;
                // A mesh collider whose mesh the budget did not keep is seen as its box.
                let unbuilt = rules == Rules::Sensor
                    && ExactShapes::needs_mesh(v.geometry)
                    && meshes.built(v.geometry_index).is_none();
                if act.collider == ColliderKind::Box || unbuilt {
                    // A box collider is an oriented box: a slab test in its frame.
                    let (cuboid, centre) = v.geometry.box_collider();
                    let to_local = v.current.enu_from_body.inverse();
                    let origin =
                        to_local * (position - v.current.position_enu_m) - centre.as_dvec3();
                    let half = cuboid.half_extents.as_dvec3();
                    return Aabb64::new(-half, half).ray_entry(origin, to_local * dir, limit);
                }
                let body = match rules {
                    Rules::Paper => Body::new(
                        crate::collision::bodies::Holder::Mesh(
                            meshes.get(v.geometry_index, v.geometry),
                        ),
                        v.current,
                    ),
                    Rules::Sensor => {
                        world
                            .shapes
                            .body(v.geometry_index, v.geometry, meshes, v.current, false)
                    }
                };
                contact::ray_distance_m(position, dir, limit, &body.placed())
            };
            // The obstacle this ray hit last frame usually still is the nearest: its distance
            // bounds the walk (same answer, far fewer nodes).
            let seed = state.rays[k]
                .1
                .and_then(|h| Some((h.obstacle, ray_test(h.obstacle, cfg.ray_length_m, false)?)));
            let seed_static = seed.filter(|(o, _)| matches!(o, ObstacleRef::Static(_)));
            let mut best = world
                .statics
                .cast_ray(
                    position,
                    dir,
                    seed_static.map_or(cfg.ray_length_m, |s| s.1),
                    |i, limit| ray_test(ObstacleRef::Static(i), limit, true),
                )
                .map(|(i, d)| (ObstacleRef::Static(i), d))
                .or(seed_static);
            for &(o, aabb) in moving {
                let limit = best.map_or(cfg.ray_length_m, |b| b.1);
                if !aabb.ray_hits(position, dir, limit) {
                    continue;
                }
                if let Some(d) = ray_test(o, limit, true).filter(|&d| d < limit) {
                    best = Some((o, d));
                }
            }
            counts.ray_tests += tests;
            state.rays[k] = (
                dir,
                best.map(|(obstacle, d)| RayHit {
                    obstacle,
                    distance_m: d,
                    point_enu_m: position + dir * d,
                }),
            );
        }
    }
}
