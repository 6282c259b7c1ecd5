//! The sensing layer's steps 4-5 (the paper's threat and collider rules): beta of what the
//! rays see, the box <-> mesh swap with its hold and its 800 m downgrade, and which meshes are
//! made resident ahead of the vehicle.
//!
//! Pure and synchronous; imports no I/O, no tokio, no rerun.

use crate::collision::bodies::ObstacleRef;
use crate::collision::contact::shapes::ExactShapes;
use crate::collision::events::{Event, EventKind};
use crate::collision::meshes::MeshCache;
use crate::collision::sensing::{Active, Frame, Rules, SensingState};
use crate::collision::view::view;
use crate::collision::ColliderKind;

/// Steps 4-5: the threat of what the rays see, and the box <-> mesh rule with the hold.
pub(crate) fn rate_and_swap(
    f: &Frame<'_>,
    meshes: &mut MeshCache,
    state: &mut SensingState,
    events: &mut Vec<Event>,
) {
    let Frame {
        world,
        cfg,
        rules,
        current,
        event,
    } = *f;
    let (scene, dynamic) = (world.scene, world.dynamic);
    let t = current.t_s;
    let position = current.position_enu_m;
    let forward = current.attitude.forward_enu();
    let hold = f.hold_s();
    // beta is this frame's: the largest over the rays that see the obstacle now.
    for act in state.active.iter_mut() {
        act.beta = 0.0;
    }
    for k in 0..state.rays.len() {
        let Some(hit) = state.rays[k].1 else { continue };
        let Ok(i) = state
            .active
            .binary_search_by_key(&hit.obstacle, |a| a.obstacle)
        else {
            continue;
        };
        let Some(v) = view(scene, dynamic, hit.obstacle) else {
            continue;
        };
        let act = &mut state.active[i];
        let angle_deg = forward
            .angle_between(hit.point_enu_m - position)
            .to_degrees();
        let beta = cfg.ahp.beta(v.threat, v.speed_mps, angle_deg);
        act.beta = act.beta.max(beta);
        if act.collider == ColliderKind::Box
            && beta > cfg.mesh_beta
            && hit.distance_m < cfg.mesh_within_m
        {
            // Residency: the mesh is built now, by the sensing layer, before a contact needs it
            // (the paper's collider in `paper`; within the budget for the sensor, which keeps
            // the box when there is no room).
            if rules == Rules::Paper {
                meshes.get(v.geometry_index, v.geometry);
            } else if ExactShapes::needs_mesh(v.geometry)
                && !meshes.prefetch(v.geometry_index, v.geometry)
            {
                continue;
            }
            let change = Swap {
                to: ColliderKind::Mesh,
                t,
                id: v.id,
                beta,
                distance_m: hit.distance_m,
                reason: "threat",
            };
            swap(act, change, event, events);
        }
    }
    let mut i = 0;
    while i < state.active.len() {
        let act = &mut state.active[i];
        i += 1;
        if act.collider != ColliderKind::Mesh || t - act.since_t_s < hold {
            continue;
        }
        let Some(v) = view(scene, dynamic, act.obstacle) else {
            continue;
        };
        let distance_m = v.aabb_enu_m.distance_to(position);
        if distance_m > cfg.box_beyond_m {
            let change = Swap {
                to: ColliderKind::Box,
                t,
                id: v.id,
                beta: act.beta,
                distance_m,
                reason: "far",
            };
            swap(act, change, event, events);
            if rules == Rules::Sensor {
                // Far: it leaves the sensor's set (its mesh becomes evictable).
                i -= 1;
                state.active.remove(i);
            }
        }
    }
}

/// Residency: the triangle meshes the contact layer may need before the next frames (loaded
/// meshes within the look-ahead reach) are asked for now, nearest first within the budget, so
/// that a contact rarely has to build one on the tick path.
pub(crate) fn make_resident_ahead(f: &Frame<'_>, meshes: &mut MeshCache, state: &SensingState) {
    let Frame {
        world,
        cfg,
        current,
        ..
    } = *f;
    let reach_m = current.velocity_enu_mps.length() * cfg.look_ahead_s + cfg.near_miss_m.max(1.0);
    // Nearest first, within the budget: what a contact needs soonest is resident first.
    let mut ahead: smallvec::SmallVec<[(f64, ObstacleRef); 16]> = state
        .active
        .iter()
        .filter_map(|act| {
            let v = view(world.scene, world.dynamic, act.obstacle)?;
            let d = v.aabb_enu_m.distance_to(current.position_enu_m);
            (ExactShapes::needs_mesh(v.geometry) && d <= reach_m).then_some((d, act.obstacle))
        })
        .collect();
    ahead.sort_unstable_by(|a, b| a.0.total_cmp(&b.0));
    for (_, o) in ahead {
        let Some(v) = view(world.scene, world.dynamic, o) else {
            continue;
        };
        if !meshes.prefetch(v.geometry_index, v.geometry) {
            break;
        }
    }
}

/// One collider change, as its event reports it.
struct Swap<'a> {
    to: ColliderKind,
    t: f64,
    id: &'a str,
    beta: f64,
    distance_m: f64,
    reason: &'static str,
}

fn swap(
    act: &mut Active,
    s: Swap<'_>,
    event: &dyn Fn(EventKind) -> Event,
    events: &mut Vec<Event>,
) {
    events.push(event(EventKind::ColliderSwap {
        obstacle: s.id.to_owned(),
        from: act.collider,
        to: s.to,
        beta: s.beta,
        distance_m: s.distance_m,
        reason: s.reason,
    }));
    act.collider = s.to;
    act.since_t_s = s.t;
}
