//! The moving bodies of one vehicle's tick: the scene's scripted tracks, and the other
//! vehicles and traffic within the range the tick can need, found through the world's index
//! (no scan of every track).
//!
//! The range a body is taken within (its *watch range*, from the vehicle's interval to the
//! body's, both as boxes) is the largest of what any stage of the tick can use. Two reaches
//! make it up. The *approach reach*: the contact layer's near-miss band, NMAC, the well-clear
//! volume's DTHR + TTHR x closing speed, the separation minimum, and the feed's ADS-B radius,
//! COLLISION horizon and sensor range; closest approaches, well clear and separation are
//! judged within it. The *sensing reach*, only at ticks with a sensing frame: its region and
//! look-ahead, and where a mesh is made (`mesh_within_m`). Both grow by the models' radii. At
//! a sensing tick the bodies the vehicle's sensing layer holds a collider for are taken too,
//! wherever they are: it turns a far mesh back into a box (`box_beyond_m`, 800 m) and drops
//! what leaves its region, and it does so only for a body it is given (the reach itself held
//! `box_beyond_m` before: with the defaults and two bodies at 8 m/s, 849 m instead of 509 m).
//! A body beyond a tick's range and not held can change nothing the tick computes, so leaving
//! it out changes no answer: with `--sensor-hz` below the vehicles' position rate, most ticks take only the
//! bodies within the approach reach (a drone-show block: some 150 of its 1000 vehicles).

use std::sync::Arc;

use glam::DVec3;
use savsim_core::collision::sensing::SensingState;

use crate::collision::bodies::radius_m;
use crate::daa::well_clear::{Volume, FT_M};
use crate::feed::FeedConfig;
use crate::pipeline::{
    BodyKey, BodyPose, BodySource, CollisionConfig, DynamicBody, MovingBodies, ObstacleRef,
};
use crate::scene::{Aabb64, DynamicSource, Kind, Scene};
use crate::world::SenderId;
use crate::world::{Track, TrackSample, WorldStore, PREDICT_MAX_S};

/// NMAC's horizontal threshold (500 ft), metres: the widest NMAC reaches.
const NMAC_M: f64 = 500.0 * FT_M;

/// What decides how far a vehicle's tick looks for moving bodies.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Watch {
    /// The pipeline's settings.
    pub collision: CollisionConfig,
    /// The well-clear volume judged, if any.
    pub volume: Option<Volume>,
    /// The separation minimum judged, if any, metres.
    pub separation_m: Option<f64>,
    /// The feed's ADS-B radius, COLLISION reach and horizon, and sensor range, when on.
    pub feed: Option<(f64, f64, f64, f64)>,
    /// The largest radius of any model a moving body or vehicle can have, metres.
    pub max_model_radius_m: f64,
}

/// The largest radius of any model a moving body or a vehicle can have in `scene`, metres.
pub(crate) fn max_model_radius_m(scene: &Scene) -> f64 {
    let models = scene
        .vehicle_models
        .iter()
        .map(|(_, g)| *g)
        .chain(scene.kind_models.iter().map(|(_, g)| *g))
        .chain(scene.dynamic.iter().map(|d| d.geometry_index))
        .chain([0]);
    models.map(|g| model_radius_m(scene, g)).fold(0.0, f64::max)
}

impl Watch {
    /// The feed's part of the watch: its ADS-B radius, COLLISION reach and horizon, and
    /// sensor range.
    pub(crate) fn feed_of(feed: &FeedConfig) -> (f64, f64, f64, f64) {
        (
            feed.adsb_radius_m,
            feed.collision_horizontal_m,
            feed.collision_horizon_s,
            feed.range.max_m,
        )
    }

    /// How far apart (box to box) a vehicle at `own_mps` and a body at `body_mps` can be and
    /// still matter to closest approaches, NMAC, well clear, contacts or the feed, metres, not
    /// counting their models' size.
    fn approach_range_m(&self, own_mps: f64, body_mps: f64) -> f64 {
        let c = &self.collision;
        let closing_mps = own_mps + body_mps;
        let contact = c.near_miss_m + closing_mps * c.look_ahead_s;
        let well_clear = self
            .volume
            .map_or(0.0, |v| v.dthr_m + v.tthr_s * closing_mps);
        let feed = self.feed.map_or(0.0, |(adsb, h, horizon, sensor)| {
            adsb.max(h + horizon * closing_mps).max(sensor)
        });
        // The boxes cover the interval's motion: within the minimum of them is all that can
        // come under it.
        let separation = self.separation_m.unwrap_or(0.0);
        contact
            .max(well_clear)
            .max(feed)
            .max(separation)
            .max(NMAC_M)
            + 1.0
    }

    /// As [`Self::approach_range_m`], at a tick with a sensing frame: also its region and
    /// look-ahead and the collider swaps' reach.
    fn sensing_range_m(&self, own_mps: f64, body_mps: f64) -> f64 {
        let c = &self.collision;
        let sensed = 1.5 * c.ray_length_m.max(own_mps * c.look_ahead_s) + 10.0;
        let swaps = sensed.max(c.mesh_within_m) + (own_mps + body_mps) * c.look_ahead_s;
        (swaps + 1.0).max(self.approach_range_m(own_mps, body_mps))
    }

    /// The tick's range: with or without its sensing frame.
    fn range_m(&self, sensing: bool, own_mps: f64, body_mps: f64) -> f64 {
        if sensing {
            self.sensing_range_m(own_mps, body_mps)
        } else {
            self.approach_range_m(own_mps, body_mps)
        }
    }
}

/// One vehicle's interval, as the tick sees it.
pub(crate) struct Interval<'a> {
    pub own: SenderId,
    pub previous: Option<&'a TrackSample>,
    pub current: &'a TrackSample,
    /// Receive time of the run's first vehicle sample (scripted tracks' zero).
    pub flight_start_t_s: f64,
    /// Whether the tick runs a sensing frame (`Pipeline::senses_at`).
    pub sensing: bool,
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

/// The moving obstacles seen by vehicle `interval.own` over its interval, into `out`, in the
/// order of their keys (the scene's tracks, then the vehicles, then the traffic, as
/// [`BodyKey`] orders them); `approached[i]` says whether `out`'s body `i` is within the
/// approach reach (the scene's tracks always are). Ids are shared (`Arc<str>`).
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
    approached.resize(out.len(), true);
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

/// Where a tick's moving bodies go: the bodies, and beside each whether it is within the
/// approach reach.
pub(crate) struct Filling<'a> {
    /// The bodies.
    pub out: &'a mut MovingBodies,
    /// Whether `out`'s body `i` is within the approach reach.
    pub approached: &'a mut Vec<bool>,
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

/// The other vehicles and the ADS-B traffic within the watch range of the interval, into
/// `out` (and whether each is within the approach reach, into `approached`), in the order of
/// their keys (the order the world visits them in).
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
    if let Some(state) = held {
        region = held_positions(world, state).fold(region, |r, p| r.including(p));
    }
    let holds = |key: BodyKey| held.is_some_and(|s| s.holds(ObstacleRef::Dynamic(key)));
    world.tracks_near(&region, times.0, times.1, |track| {
        let Some((who, history)) = identity_of(scene, track, interval.own, claims) else {
            return;
        };
        // Whether it is near from its positions alone: the whole state (the attitude's
        // interpolation) is made only for a body taken.
        let Some(((before_m, _), (now_m, now_mps))) = history
            .predict_motion(times.0, PREDICT_MAX_S)
            .zip(history.predict_motion(times.1, PREDICT_MAX_S))
        else {
            return;
        };
        let body_mps = now_mps.length();
        let body_box = Aabb64::new(before_m, before_m).including(now_m);
        let radii_m = own_radius_m + model_radius_m(scene, who.geometry_index);
        let apart_m = own_box.distance_to_box(&body_box);
        let near = apart_m <= watch.approach_range_m(own_mps, body_mps) + radii_m;
        let taken = near
            || (sensing
                && (apart_m <= watch.sensing_range_m(own_mps, body_mps) + radii_m
                    || holds(who.key)));
        if !taken {
            return;
        }
        if let Some(body) = predicted(history, who, times) {
            out.push(body);
            approached.push(near);
        }
    });
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

/// The radius of geometry `index` (0 when the scene has none such), metres.
fn model_radius_m(scene: &Scene, index: usize) -> f64 {
    scene.geometries.get(index).map_or(0.0, |g| radius_m(g))
}

/// Who a moving body is.
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
