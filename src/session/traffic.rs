//! The moving bodies of one vehicle's tick: the scene's scripted tracks, and the other
//! vehicles and traffic within the range the tick can need, found through the world's index
//! (no scan of every track).
//!
//! The range a body is taken within (its *watch range*, from the vehicle's interval to the
//! body's, both as boxes) is the largest of what any stage can use: the sensing region and its
//! look-ahead, the collider swaps' `box_beyond_m`, the near-miss band, NMAC, the well-clear
//! volume's DTHR + TTHR x closing speed, and the feed's ADS-B radius, COLLISION horizon and
//! sensor range; plus both models' radii. A body beyond it can change nothing the tick
//! computes, so leaving it out changes no answer.

use std::sync::Arc;

use crate::collision::bodies::radius_m;
use crate::collision::pipeline::{
    BodyKey, BodyPose, BodySource, CollisionConfig, DynamicBody, MovingBodies,
};
use crate::daa::well_clear::{Volume, FT_M};
use crate::feed::FeedConfig;
use crate::scene::{Aabb64, DynamicSource, Kind, Scene};
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
    models
        .filter_map(|g| scene.geometries.get(g))
        .map(|g| radius_m(g))
        .fold(0.0, f64::max)
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
    /// still matter to the tick, metres, not counting their models' size.
    fn range_m(&self, own_mps: f64, body_mps: f64) -> f64 {
        let c = &self.collision;
        let closing_mps = own_mps + body_mps;
        let sensed = 1.5 * c.ray_length_m.max(own_mps * c.look_ahead_s) + 10.0;
        let pipeline = sensed
            .max(c.box_beyond_m)
            .max(c.mesh_within_m)
            .max(c.near_miss_m)
            + closing_mps * c.look_ahead_s;
        let well_clear = self
            .volume
            .map_or(0.0, |v| v.dthr_m + v.tthr_s * closing_mps);
        let feed = self.feed.map_or(0.0, |(adsb, h, horizon, sensor)| {
            adsb.max(h + horizon * closing_mps).max(sensor)
        });
        pipeline.max(well_clear).max(feed).max(NMAC_M) + 1.0
    }
}

/// One vehicle's interval, as the tick sees it.
pub(crate) struct Interval<'a> {
    pub own: crate::ingest::stats::SenderId,
    pub previous: Option<&'a TrackSample>,
    pub current: &'a TrackSample,
    /// Receive time of the run's first vehicle sample (scripted tracks' zero).
    pub flight_start_t_s: f64,
}

/// The moving obstacles seen by vehicle `interval.own` over its interval, into `out`. Ids are
/// shared (`Arc<str>`).
pub(crate) fn fill_dynamic(
    out: &mut MovingBodies,
    found: &mut Vec<DynamicBody>,
    scene: &Scene,
    world: &mut WorldStore,
    watch: &Watch,
    interval: &Interval<'_>,
) {
    out.clear();
    let (own, current) = (interval.own, interval.current);
    let before = interval.previous.unwrap_or(current);
    let (t_before, t_now) = (before.t_s, current.t_s);
    let own_box =
        Aabb64::new(before.position_enu_m, before.position_enu_m).including(current.position_enu_m);
    let own_mps = current.velocity_enu_mps.length();
    let own_radius_m = scene
        .geometries
        .get(scene.vehicle_model(own.system_id))
        .map_or(0.0, |g| radius_m(g));
    let mut claimed_sysids = [false; 256];
    let mut claimed_icao: smallvec::SmallVec<[u32; 8]> = smallvec::SmallVec::new();
    for (index, d) in scene.dynamic.iter().enumerate() {
        match &d.source {
            DynamicSource::Waypoints(w) => out.push(DynamicBody::on_track(
                index as u32,
                d.id.clone(),
                d.kind,
                d.threat,
                d.geometry_index,
                w,
                (
                    t_before - interval.flight_start_t_s,
                    t_now - interval.flight_start_t_s,
                ),
            )),
            DynamicSource::SystemId(id) => {
                claimed_sysids[usize::from(*id)] = true;
                let history = world
                    .vehicle_of_system(*id)
                    .filter(|_| *id != own.system_id)
                    .map(|v| (&v.history, v.generation));
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
                if let Some(b) = history.and_then(|(h, g)| predicted(h, who(g), (t_before, t_now)))
                {
                    out.push(b);
                }
            }
            DynamicSource::Icao(icao) => {
                claimed_icao.push(*icao);
                let found = world.traffic.get(icao).and_then(|tr| {
                    let who = Identity {
                        key: BodyKey {
                            source: BodySource::Scripted(index as u32),
                            generation: tr.generation,
                        },
                        id: &d.id,
                        kind: d.kind,
                        threat: d.threat,
                        geometry_index: d.geometry_index,
                    };
                    predicted(&tr.history, who, (t_before, t_now))
                });
                out.extend(found);
            }
        }
    }
    // Other MAVLink vehicles and ADS-B traffic within the watch range.
    let reach_m =
        watch.range_m(own_mps, world.max_speed_mps()) + own_radius_m + watch.max_model_radius_m;
    let region = own_box.inflated(reach_m);
    found.clear();
    world.tracks_near(&region, t_before, t_now, |track| {
        let body = match track {
            Track::Vehicle(v) => {
                if v.id.system_id == own.system_id || claimed_sysids[usize::from(v.id.system_id)] {
                    return;
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
                predicted(&v.history, who, (t_before, t_now))
            }
            Track::Traffic(tr) => {
                if claimed_icao.contains(&tr.icao_address) {
                    return;
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
                predicted(&tr.history, who, (t_before, t_now))
            }
        };
        let Some(body) = body else { return };
        let body_box = Aabb64::new(body.previous.position_enu_m, body.previous.position_enu_m)
            .including(body.current.position_enu_m);
        let body_radius_m = scene
            .geometries
            .get(body.geometry_index)
            .map_or(0.0, |g| radius_m(g));
        let within_m = watch.range_m(own_mps, body.speed_mps) + own_radius_m + body_radius_m;
        if own_box.distance_to_box(&body_box) <= within_m {
            found.push(body);
        }
    });
    // In the order of their keys, whatever order the index found them in.
    found.sort_unstable_by_key(|b| b.key);
    out.extend(found.drain(..));
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
