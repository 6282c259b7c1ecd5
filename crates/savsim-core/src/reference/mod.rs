//! The ground truth (`--mode reference`): dense sub-stepping of every interval with exact
//! intersection tests, sharing no code with the contact layer. It reads the scene's plain data
//! (each block's corners, a mesh's vertices, a terrain patch's heights) and builds its own
//! shapes ([`parts`]: a box per block, its own terrain triangulation and height grid); it
//! imports parry's intersection and distance primitives and glam, and of savsim only the data
//! types it is handed and hands back (samples, moving bodies, thresholds, events). No broad
//! phase (a scan of the scene's bounds), no shape cast (steps of at most 1 cm of relative
//! travel and 0.1 degree of turn, the first contact then bisected to well under a
//! millisecond), its own poses (linear position, spherical rotation), its own gap and
//! implausible-sample rules and its own episode rule (a collision is a step from not touching
//! to touching). Slow by design: the bench and the tests use it.
//!
//! Pure and synchronous; no I/O.

mod ground;
pub mod parts;

use std::collections::HashMap;
use std::sync::Arc;

use glam::DVec3;

use crate::collision::bodies::{DynamicBody, ObstacleRef, VehicleKey};
use crate::collision::config::CollisionConfig;
use crate::collision::events::{Event, EventKind};
use crate::scene::{Aabb64, Scene};
use crate::world::TrackSample;
use parts::{overlap, At, Parts};

/// Most travel between two sub-steps, metres.
pub const STEP_TRAVEL_M: f64 = 0.01;
/// Most turn between two sub-steps, radians (0.1 degree).
pub const STEP_TURN_RAD: f64 = 0.1 * std::f64::consts::PI / 180.0;
/// Sub-steps in one interval of one obstacle never exceed this (a 100 km jump at 1 cm); an
/// interval that needs more is stepped coarser and counted ([`Reference::capped`]).
pub const MAX_STEPS: u64 = 10_000_000;
/// Bisection rounds for the time of first contact (2^-30 of the interval).
const BISECTIONS: u32 = 30;

#[derive(Debug, Clone, Default)]
struct VehicleTruth {
    generation: u32,
    touching: Vec<ObstacleRef>,
    last_implausible: bool,
}

/// One interval of one vehicle, as the reference is handed it.
pub struct Interval<'a> {
    /// The scene.
    pub scene: &'a Scene,
    /// Thresholds (the gap and implausible-sample rules).
    pub cfg: &'a CollisionConfig,
    /// The vehicle.
    pub key: VehicleKey,
    /// Its sample before, if any.
    pub previous: Option<&'a TrackSample>,
    /// Its new sample.
    pub current: &'a TrackSample,
    /// The moving bodies over the interval.
    pub dynamic: &'a [DynamicBody],
}

/// The reference: shapes built on demand, per-vehicle contact state.
#[derive(Default)]
pub struct Reference {
    parts: Vec<Option<Arc<Parts>>>,
    vehicles: HashMap<(u16, u8), VehicleTruth>,
    /// Sub-steps tested over the run.
    pub steps: u64,
    /// Intervals that needed more than [`MAX_STEPS`] sub-steps and were stepped coarser: the
    /// answer for them is not the reference's (counted in the summary).
    pub capped: u64,
}

impl Clone for Reference {
    fn clone(&self) -> Self {
        Self {
            parts: self.parts.clone(),
            vehicles: self.vehicles.clone(),
            steps: self.steps,
            capped: self.capped,
        }
    }
}

impl std::fmt::Debug for Reference {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Reference")
            .field("steps", &self.steps)
            .field("capped", &self.capped)
            .finish_non_exhaustive()
    }
}

/// One obstacle over the interval.
struct Candidate {
    obstacle: ObstacleRef,
    parts: Arc<Parts>,
    before: At,
    now: At,
    /// Bounds over the whole interval, scene ENU metres.
    reach: Aabb64,
    id: Arc<str>,
    kind: &'static str,
}

/// Where a sample puts the vehicle.
fn at_sample(s: &TrackSample) -> At {
    At {
        position_enu_m: s.position_enu_m,
        rotation: s.attitude.enu_from_frd,
    }
}

impl Reference {
    fn parts(&mut self, index: usize, scene: &Scene) -> Arc<Parts> {
        if index >= self.parts.len() {
            self.parts.resize_with(index + 1, || None);
        }
        self.parts[index]
            .get_or_insert_with(|| Arc::new(Parts::of(&scene.geometries[index])))
            .clone()
    }

    /// One interval of one vehicle; events are appended.
    pub fn step(&mut self, i: &Interval<'_>, events: &mut Vec<Event>) {
        let (t, current) = (i.current.t_s, i.current);
        let event = |kind: EventKind| Event {
            t,
            time_boot_ms: current.time_boot_ms,
            vehicle: i.key.vehicle,
            compid: i.key.component_id,
            kind,
        };
        let slot = (i.key.vehicle, i.key.component_id);
        let mut state = self
            .vehicles
            .remove(&slot)
            .filter(|s| s.generation == i.key.generation)
            .unwrap_or_else(|| VehicleTruth {
                generation: i.key.generation,
                ..VehicleTruth::default()
            });
        let mut previous = match i.previous {
            Some(p) if t - p.t_s > i.cfg.max_gap_s => {
                events.push(event(EventKind::TelemetryGap {
                    gap_s: t - p.t_s,
                    moved_m: current.position_enu_m.distance(p.position_enu_m),
                }));
                None
            }
            Some(p) if t > p.t_s => Some(p),
            _ => None,
        };
        let implausible = self
            .ground_under(i.scene, current.position_enu_m)
            .is_some_and(|g| current.position_enu_m.z < g - i.cfg.max_below_terrain_m);
        if std::mem::replace(&mut state.last_implausible, implausible) {
            previous = None;
        }
        if !implausible {
            let touching = self.interval(i, previous, &event, &state.touching, events);
            state.touching = touching;
        }
        self.vehicles.insert(slot, state);
    }

    /// The highest terrain surface under (east, north), scanning every terrain patch.
    fn ground_under(&mut self, scene: &Scene, p: DVec3) -> Option<f64> {
        let mut top: Option<f64> = None;
        for o in scene.obstacles.iter() {
            let b = &o.aabb_enu_m;
            if !(b.min.x <= p.x && p.x <= b.max.x && b.min.y <= p.y && p.y <= b.max.y) {
                continue;
            }
            let parts = self.parts(o.geometry_index, scene);
            let Some(ground) = parts.ground() else {
                continue;
            };
            // Terrain patches are placed unrotated.
            let local = p - o.placement.position_enu_m;
            if let Some(h) = ground.height_at(local.x, local.y) {
                let z = o.placement.position_enu_m.z + h;
                top = Some(top.map_or(z, |t| t.max(z)));
            }
        }
        top
    }

    /// The obstacles the vehicle may reach over the interval.
    fn candidates(&mut self, i: &Interval<'_>, region: &Aabb64, swept: bool) -> Vec<Candidate> {
        let mut out = Vec::new();
        for (k, o) in i.scene.obstacles.iter().enumerate() {
            if o.aabb_enu_m.intersects(region) {
                let at = At {
                    position_enu_m: o.placement.position_enu_m,
                    rotation: o.placement.enu_from_local,
                };
                out.push(Candidate {
                    obstacle: ObstacleRef::Static(k as u32),
                    parts: self.parts(o.geometry_index, i.scene),
                    before: at,
                    now: at,
                    reach: o.aabb_enu_m,
                    id: Arc::from(o.id.as_str()),
                    kind: o.kind.name(),
                });
            }
        }
        for d in i.dynamic.iter().filter(|d| d.key.source != i.key.source()) {
            let parts = self.parts(d.geometry_index, i.scene);
            let r = parts.radius_m();
            let pose = |p: &crate::collision::bodies::BodyPose| At {
                position_enu_m: p.position_enu_m,
                rotation: p.enu_from_body,
            };
            let (b, n) = if swept {
                (pose(&d.previous), pose(&d.current))
            } else {
                (pose(&d.current), pose(&d.current))
            };
            let reach = Aabb64::around(n.position_enu_m, DVec3::splat(r))
                .union(Aabb64::around(b.position_enu_m, DVec3::splat(r)));
            if reach.intersects(region) {
                out.push(Candidate {
                    obstacle: ObstacleRef::Dynamic(d.key),
                    parts,
                    before: b,
                    now: n,
                    reach,
                    id: d.id.clone(),
                    kind: d.kind.name(),
                });
            }
        }
        out
    }

    /// Step the interval against every candidate; returns what is touched at its end.
    fn interval(
        &mut self,
        i: &Interval<'_>,
        previous: Option<&TrackSample>,
        event: &dyn Fn(EventKind) -> Event,
        was_touching: &[ObstacleRef],
        events: &mut Vec<Event>,
    ) -> Vec<ObstacleRef> {
        let t = i.current.t_s;
        let vehicle_index = i
            .scene
            .vehicle_model(u8::try_from(i.key.vehicle).unwrap_or(0));
        let vehicle = self.parts(vehicle_index, i.scene);
        let radius_m = vehicle.radius_m();
        let now = at_sample(i.current);
        let before = previous.map_or(now, at_sample);
        let t_before = previous.map_or(t, |p| p.t_s);
        let region = Aabb64::around(now.position_enu_m, DVec3::splat(radius_m))
            .union(Aabb64::around(
                before.position_enu_m,
                DVec3::splat(radius_m),
            ))
            .inflated(STEP_TRAVEL_M);
        let candidates = self.candidates(i, &region, previous.is_some());
        let mut touching_now = Vec::new();
        for c in &candidates {
            let touches = |u: f64| touches(&vehicle, radius_m, before.towards(now, u), c, u);
            let mut state_now = was_touching.contains(&c.obstacle);
            if previous.is_some() {
                let n = self.steps_for(before, now, c);
                for k in 1..=n {
                    let u = k as f64 / n as f64;
                    let touching = touches(u);
                    if touching && !state_now {
                        let hit = first_contact((k - 1) as f64 / n as f64, u, &touches);
                        let at = before.towards(now, hit);
                        events.push(event(collision(c, at.position_enu_m, t_before, t, hit)));
                    }
                    state_now = touching;
                }
            } else {
                self.steps += 1;
                let touching = touches(1.0);
                if touching && !state_now {
                    events.push(event(collision(c, now.position_enu_m, t, t, 1.0)));
                }
                state_now = touching;
            }
            if state_now {
                touching_now.push(c.obstacle);
            }
        }
        touching_now
    }

    /// Sub-steps for one candidate: at most 1 cm of relative travel and 0.1 degree of either
    /// body's turn each.
    fn steps_for(&mut self, before: At, now: At, c: &Candidate) -> u64 {
        let relative = ((now.position_enu_m - before.position_enu_m)
            - (c.now.position_enu_m - c.before.position_enu_m))
            .length();
        let turn = turn_rad(before, now).max(turn_rad(c.before, c.now));
        let wanted = (relative / STEP_TRAVEL_M).max(turn / STEP_TURN_RAD).ceil();
        let n = if wanted.is_finite() {
            wanted.max(1.0)
        } else {
            f64::MAX
        };
        if n > MAX_STEPS as f64 {
            self.capped += 1;
        }
        let n = (n as u64).clamp(1, MAX_STEPS);
        self.steps += n;
        n
    }
}

/// True when the vehicle at `v` touches candidate `c` at fraction `u` of the interval: the
/// reference point under the terrain, or any part overlapping.
fn touches(vehicle: &Parts, radius_m: f64, v: At, c: &Candidate, u: f64) -> bool {
    if c.reach.distance_to(v.position_enu_m) > radius_m {
        return false;
    }
    let o = c.before.towards(c.now, u);
    if let Some(ground) = c.parts.ground() {
        let local = v.position_enu_m - o.position_enu_m;
        if ground
            .height_at(local.x, local.y)
            .is_some_and(|h| local.z < h)
        {
            return true;
        }
        let lo = (local.x - radius_m, local.y - radius_m);
        let hi = (local.x + radius_m, local.y + radius_m);
        if ground
            .highest_in(lo, hi)
            .is_none_or(|top| local.z - radius_m > top)
        {
            return false;
        }
    }
    overlap(vehicle, v, &c.parts, o)
}

/// Bisect between a free fraction and a touching one: the first contact.
fn first_contact(mut free: f64, mut hit: f64, touches: &dyn Fn(f64) -> bool) -> f64 {
    for _ in 0..BISECTIONS {
        let mid = 0.5 * (free + hit);
        if touches(mid) {
            hit = mid;
        } else {
            free = mid;
        }
    }
    hit
}

fn turn_rad(a: At, b: At) -> f64 {
    2.0 * a.rotation.dot(b.rotation).abs().min(1.0).acos()
}

fn collision(c: &Candidate, point: DVec3, t_before: f64, t: f64, u: f64) -> EventKind {
    EventKind::Collision {
        obstacle: c.id.to_string(),
        obstacle_kind: c.kind,
        point_enu_m: point.to_array(),
        normal_enu: [0.0; 3],
        time_of_impact: t_before + (t - t_before) * u,
        swept: u < 1.0,
    }
}
