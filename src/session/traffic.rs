//! The moving bodies of one vehicle's tick: the scene's scripted tracks, and the other
//! vehicles and traffic within the range the tick can need (session::watch), found through the
//! world's index (no scan of every track).
//!
//! A body is taken within the approach reach, and at a tick with a sensing frame within the
//! sensing neighbourhood, or when its box (within its model's sphere, grown by its speed over
//! the frame's lead) reaches the frame's region, or when the vehicle's sensing layer holds a
//! collider for it, wherever it is (the layer turns a far mesh back into a box, `box_beyond_m`,
//! and drops what leaves its region, only for a body it is given). A body beyond all of these
//! can change nothing the tick computes, so leaving it out changes no answer.
//!
//! Closest approaches, NMAC, well clear and separation judge reference points: a body within
//! the approach reach is given to them by its positions alone ([`Approached`]). Its whole
//! state at both ends of the interval (the attitude's interpolation, its box) is made only for
//! a body the pipeline can use: within the contact reach, reaching the frame's region, or held;
//! and for every body taken when the run counts every collider or is the reference (`box`,
//! `mesh`, `reference`), is drawn by the viewer or feeds the autopilot ([`Watch::pose_all`]).
//! With `--sensor-hz` below the vehicles' position rate, most ticks of a dense fleet pose only
//! the few bodies within the contact reach.

use std::sync::Arc;

use glam::DVec3;
use savsim_core::collision::sensing::SensingState;

use super::watch::{model_radius_m, Watch};
use crate::daa::approach::Passing;
use crate::pipeline::{BodyKey, BodyPose, BodySource, DynamicBody, MovingBodies};
use crate::scene::{Aabb64, DynamicSource, Kind, Scene};
use crate::world::SenderId;
use crate::world::{Track, TrackSample, WorldStore, PREDICT_MAX_S};

/// One vehicle's interval, as the tick sees it.
pub(crate) struct Interval<'a> {
    pub own: SenderId,
    pub previous: Option<&'a TrackSample>,
    pub current: &'a TrackSample,
    /// Receive time of the run's first vehicle sample (scripted tracks' zero).
    pub flight_start_t_s: f64,
    /// Whether the tick runs a sensing frame (`Pipeline::senses_at`).
    pub sensing: bool,
    /// Where the sensing frame desires moving bodies, and their lead into it, seconds
    /// (`Pipeline::sensing_region`), at a tick with a frame in a mode with a sensing layer.
    pub sensing_region: Option<(Aabb64, f64)>,
    /// The vehicle's sensing state before the tick, if it has one: the bodies it holds a
    /// collider for are taken at a sensing tick wherever they are.
    pub held: Option<&'a SensingState>,
}

impl Interval<'_> {
    /// Its start and end times (receive clock, seconds).
    fn times(&self) -> (f64, f64) {
        (self.previous.unwrap_or(self.current).t_s, self.current.t_s)
    }
}

/// The moving obstacles seen by vehicle `interval.own` over its interval: those the pipeline
/// can use into `out`, those within the approach reach into `approached` (the scene's tracks
/// are in both), each in the order of their keys (the scene's tracks, then the vehicles, then
/// the traffic, as [`BodyKey`] orders them). Ids are shared (`Arc<str>`).
pub(crate) fn fill_dynamic(
    into: Filling<'_>,
    scene: &Scene,
    world: &mut WorldStore,
    watch: &Watch,
    interval: &Interval<'_>,
) {
    let Filling { out, approached } = into;
    out.clear();
    approached.clear();
    let claims = fill_scripted(out, scene, world, interval);
    approached.extend((0..out.len()).map(Approached::Posed));
    let nearby = Filling {
        out: &mut *out,
        approached,
    };
    fill_nearby(nearby, scene, world, (watch, interval), &claims);
    debug_assert!(
        out.as_slice().is_sorted_by_key(|b| b.key),
        "bodies out of key order"
    );
}

/// Where a tick's moving bodies go: those the pipeline uses, and those within the approach
/// reach.
pub(crate) struct Filling<'a> {
    /// The bodies the pipeline uses, with their whole state.
    pub out: &'a mut MovingBodies,
    /// The bodies within the approach reach, by their positions.
    pub approached: &'a mut Vec<Approached>,
}

/// A body within a tick's approach reach: one the pipeline has too (its index in the tick's
/// bodies), or who it is and its positions at both ends of the interval.
#[derive(Debug, Clone)]
pub(crate) enum Approached {
    /// Body `i` of the pipeline's.
    Posed(usize),
    /// A body by its positions only.
    Placed {
        source: BodySource,
        id: Arc<str>,
        previous_enu_m: DVec3,
        current_enu_m: DVec3,
    },
}

impl Approached {
    /// It as closest approaches and well clear take it (`posed`: the pipeline's bodies).
    pub(crate) fn passing<'a>(&'a self, posed: &'a MovingBodies) -> Passing<'a> {
        match self {
            Self::Posed(i) => Passing::from(&posed.as_slice()[*i]),
            Self::Placed {
                source,
                id,
                previous_enu_m,
                current_enu_m,
            } => Passing {
                source: *source,
                id,
                previous_enu_m: *previous_enu_m,
                current_enu_m: *current_enu_m,
            },
        }
    }
}

/// The vehicles and aircraft the scene's tracks stand for (they are not traffic twice).
struct Claims {
    system_ids: [bool; 256],
    icao: smallvec::SmallVec<[u32; 8]>,
}

/// The scene's tracks (scripted, or standing for a vehicle or an aircraft) over the interval.
fn fill_scripted(
    out: &mut MovingBodies,
    scene: &Scene,
    world: &WorldStore,
    interval: &Interval<'_>,
) -> Claims {
    let mut claims = Claims {
        system_ids: [false; 256],
        icao: smallvec::SmallVec::new(),
    };
    let times = interval.times();
    for (index, d) in scene.dynamic.iter().enumerate() {
        let who = |generation| Identity {
            key: BodyKey {
                source: BodySource::Scripted(index as u32),
                generation,
            },
            id: &d.id,
            kind: d.kind,
            threat: d.threat,
            geometry_index: d.geometry_index,
        };
        let body = match &d.source {
            DynamicSource::Waypoints(w) => Some(DynamicBody::on_track(
                index as u32,
                d.id.clone(),
                d.kind,
                d.threat,
                d.geometry_index,
                w,
                (
                    times.0 - interval.flight_start_t_s,
                    times.1 - interval.flight_start_t_s,
                ),
            )),
            DynamicSource::SystemId(id) => {
                claims.system_ids[usize::from(*id)] = true;
                world
                    .vehicle_of_system(*id)
                    .filter(|_| *id != interval.own.system_id)
                    .and_then(|v| predicted(&v.history, who(v.generation), times))
            }
            DynamicSource::Icao(icao) => {
                claims.icao.push(*icao);
                world
                    .aircraft(*icao)
                    .and_then(|tr| predicted(&tr.history, who(tr.generation), times))
            }
        };
        out.extend(body);
    }
    claims
}

/// The other vehicles and the ADS-B traffic within the watch range of the interval: into
/// `out` those the pipeline uses, into `approached` those within the approach reach, in the
/// order of their keys (the order the world visits them in).
fn fill_nearby(
    into: Filling<'_>,
    scene: &Scene,
    world: &mut WorldStore,
    (watch, interval): (&Watch, &Interval<'_>),
    claims: &Claims,
) {
    let Filling { out, approached } = into;
    let current = interval.current;
    let before = interval.previous.unwrap_or(current);
    let times = interval.times();
    let own_box =
        Aabb64::new(before.position_enu_m, before.position_enu_m).including(current.position_enu_m);
    let own_mps = current.velocity_enu_mps.length();
    let own_radius_m = model_radius_m(scene, scene.vehicle_model(interval.own.system_id));
    let sensing = interval.sensing;
    let reach_m = watch.range_m(sensing, own_mps, world.max_speed_mps())
        + own_radius_m
        + watch.max_model_radius_m;
    let held = interval.held.filter(|_| sensing);
    let mut region = own_box.inflated(reach_m);
    let frame = interval.sensing_region.filter(|_| sensing);
    if let Some((r, lead_s)) = frame {
        let grown = r.inflated(watch.max_model_radius_m + world.max_speed_mps() * lead_s + 1.0);
        region = region.including(grown.min).including(grown.max);
    }
    if let Some(state) = held {
        region = held_positions(world, state).fold(region, |r, p| r.including(p));
    }
    // The held keys, walked beside the tracks (both in key order).
    let mut held_keys = held.map(|s| s.held_bodies().peekable());
    world.tracks_near(&region, times.0, times.1, |track| {
        let Some((who, history)) = identity_of(scene, track, interval.own, claims) else {
            return;
        };
        // Whether it is near from its positions alone: the whole state (the attitude's
        // interpolation) is made only for a body posed.
        let Some(((before_m, _), (now_m, now_mps))) = history
            .predict_motion(times.0, PREDICT_MAX_S)
            .zip(history.predict_motion(times.1, PREDICT_MAX_S))
        else {
            return;
        };
        let body_mps = now_mps.length();
        let body_box = Aabb64::new(before_m, before_m).including(now_m);
        let body_radius_m = model_radius_m(scene, who.geometry_index);
        let radii_m = own_radius_m + body_radius_m;
        let apart_m = own_box.distance_to_box(&body_box);
        let near = apart_m <= watch.approach_range_m(own_mps, body_mps) + radii_m;
        // What the sensing frame uses: a body it holds, or whose box (within its model's
        // sphere) grown by its lead reaches the frame's region.
        let framed = frame.is_some_and(|(r, lead_s)| {
            let half_m = body_radius_m + body_mps * lead_s + 1.0;
            Aabb64::around(now_m, DVec3::splat(half_m)).intersects(&r)
        });
        let mut held_here = || is_next_held(&mut held_keys, who.key);
        let within = near
            || framed
            || (sensing && apart_m <= watch.sensing_range_m(own_mps, body_mps) + radii_m);
        if !within && !held_here() {
            return;
        }
        let moved_m = now_m.distance(before_m);
        let posed = watch.pose_all
            || framed
            || apart_m <= watch.contact_range_m(own_mps, body_mps, moved_m) + radii_m
            || held_here();
        // Its whole state only where the pipeline uses it (the same `None` as the positions'
        // when the track has no sample).
        let body = if posed {
            let Some(body) = predicted(history, who, times) else {
                return;
            };
            Some(body)
        } else {
            None
        };
        if near {
            approached.push(match body {
                Some(_) => Approached::Posed(out.len()),
                None => Approached::Placed {
                    source: who.key.source,
                    id: who.id.clone(),
                    previous_enu_m: before_m,
                    current_enu_m: now_m,
                },
            });
        }
        out.extend(body);
    });
}

/// Whether `key` is among `held` (sorted keys, asked in key order: a cursor walks them).
fn is_next_held(
    held: &mut Option<std::iter::Peekable<impl Iterator<Item = BodyKey>>>,
    key: BodyKey,
) -> bool {
    let Some(keys) = held else {
        return false;
    };
    while keys.next_if(|k| *k < key).is_some() {}
    keys.peek() == Some(&key)
}

/// The newest positions of the other vehicles and aircraft `state` holds a collider for.
fn held_positions<'w>(
    world: &'w WorldStore,
    state: &'w SensingState,
) -> impl Iterator<Item = DVec3> + 'w {
    state.held_bodies().filter_map(|key| {
        let history = match key.source {
            BodySource::Vehicle {
                vehicle,
                component_id,
            } => {
                let id = SenderId {
                    system_id: u8::try_from(vehicle).ok()?,
                    component_id,
                };
                &world.vehicle(&id)?.history
            }
            BodySource::Traffic(icao) => &world.aircraft(icao)?.history,
            BodySource::Scripted(_) => return None,
        };
        history.latest().map(|s| s.position_enu_m)
    })
}

/// Who a track is as a moving body, and its history: `None` for the vehicle itself or a track
/// the scene's tracks claim.
fn identity_of<'t>(
    scene: &Scene,
    track: Track<'t>,
    own: SenderId,
    claims: &Claims,
) -> Option<(Identity<'t>, &'t crate::world::History)> {
    match track {
        Track::Vehicle(v) => {
            if v.id.system_id == own.system_id || claims.system_ids[usize::from(v.id.system_id)] {
                return None;
            }
            let who = Identity {
                key: BodyKey {
                    source: BodySource::Vehicle {
                        vehicle: u16::from(v.id.system_id),
                        component_id: v.id.component_id,
                    },
                    generation: v.generation,
                },
                id: &v.label,
                kind: Kind::Dji,
                threat: scene.threat_of(Kind::Dji),
                geometry_index: scene.vehicle_model(v.id.system_id),
            };
            Some((who, &v.history))
        }
        Track::Traffic(tr) => {
            if claims.icao.contains(&tr.icao_address) {
                return None;
            }
            let kind = Kind::from_adsb_emitter(tr.emitter_type);
            let who = Identity {
                key: BodyKey {
                    source: BodySource::Traffic(tr.icao_address),
                    generation: tr.generation,
                },
                id: &tr.label,
                kind,
                threat: scene.threat_of(kind),
                geometry_index: scene.kind_model(kind),
            };
            Some((who, &tr.history))
        }
    }
}

/// Who a moving body is.
#[derive(Clone, Copy)]
struct Identity<'a> {
    key: BodyKey,
    id: &'a Arc<str>,
    kind: Kind,
    threat: f64,
    geometry_index: usize,
}

/// `who` at its predicted poses at both ends of `interval`, if its track has a sample.
fn predicted(
    history: &crate::world::History,
    who: Identity<'_>,
    (t_before, t_now): (f64, f64),
) -> Option<DynamicBody> {
    let before = history.predict(t_before, PREDICT_MAX_S)?;
    let now = history.predict(t_now, PREDICT_MAX_S)?;
    Some(DynamicBody {
        key: who.key,
        id: who.id.clone(),
        kind: who.kind,
        threat: who.threat,
        geometry_index: who.geometry_index,
        previous: BodyPose::of(&before),
        current: BodyPose::of(&now),
        speed_mps: now.velocity_enu_mps.length(),
    })
}
