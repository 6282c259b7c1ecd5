//! An encounter: an ownship flying a track past an intruder flying another, over a scene or
//! open air, through the collision pipeline. The ownship is sampled at a fixed rate; the
//! intruder (and the scene's own scripted traffic) are moving bodies at each sample's times.

use std::path::Path;
use std::sync::Arc;
use std::time::Instant;

use glam::DVec3;

use crate::batch::error::{DaaTracksError, TrackError};
use crate::codec::stats::IngestStats;
use crate::codec::Ingestor;
use crate::collision::bodies::waypoint_pose;
use crate::collision::digest::EventDigest;
use crate::daa::approach::{Approaches, Passing};
use crate::geo::LocalTangentPlane;
use crate::logs::tlog::TlogReader;
use crate::pipeline::{DynamicBody, MovingBodies, Pipeline, VehicleKey};
use crate::scene::{DynamicSource, Kind, Scene, Waypoint};
use crate::world::SenderId;
use crate::world::{Attitude, TrackSample, WorldConfig, WorldStore, WorldUpdate};

/// The ownship's MAVLink system id in an encounter's results.
pub const OWNSHIP: u8 = 1;

/// An encounter, checked and ready to fly.
#[derive(Debug, Clone)]
pub struct Encounter {
    /// Ownship track (seconds from the start, scene ENU).
    pub own: Vec<Waypoint>,
    /// The intruders: each one's id in the results and its track.
    pub intruders: Vec<(Arc<str>, Vec<Waypoint>)>,
    /// The intruders' kind.
    pub intruder_kind: Kind,
    /// Ownship samples per second.
    pub rate_hz: f64,
    /// Length, seconds.
    pub duration_s: f64,
    /// The well-clear volume losses are judged with (`None`: not judged).
    pub well_clear: Option<crate::daa::well_clear::Volume>,
}

/// An encounter's optional alerting on sensed states.
pub type Sensed = Option<crate::batch::sensed::SensedDaa>;

/// What an encounter produced.
#[derive(Debug)]
pub struct Flown {
    /// The pipeline after the last sample (its totals).
    pub pipeline: Pipeline,
    /// What its events add up to (every event taken, as it happened).
    pub digest: EventDigest,
    /// Closest approaches, on the encounter's clock (0 at the start).
    pub approaches: Approaches,
    /// What the ticks cost.
    pub tick_costs: crate::costs::TickCosts,
}

/// The first vehicle's positions in a tlog as a track in `scene`'s ENU frame, its clock
/// starting at 0, with the file's ingest counters.
pub fn track_from_tlog(
    path: &Path,
    scene: &Scene,
) -> Result<(Vec<Waypoint>, IngestStats), TrackError> {
    let failed = |source| TrackError::Tlog {
        path: path.to_owned(),
        source,
    };
    let file = crate::files::open_stream(path).map_err(failed)?;
    let mut reader = TlogReader::new(std::io::BufReader::new(file));
    let mut ingestor = Ingestor::default();
    let mut world = WorldStore::new(scene.origin, WorldConfig::default());
    let mut first_sender = None;
    let mut first_t_s = None;
    let mut track: Vec<Waypoint> = Vec::new();
    loop {
        let record = reader.next_record(&mut ingestor.stats).map_err(failed)?;
        let Some(record) = record else { break };
        let t_s = ingestor
            .stats
            .observe_time(record.timestamp_us as f64 * 1e-6);
        let Some(decoded) = ingestor.frame(&record.frame) else {
            continue;
        };
        if let WorldUpdate::VehicleMoved(sender) = world.apply(t_s, decoded.sender, &decoded.report)
        {
            if *first_sender.get_or_insert(sender) != sender {
                continue;
            }
            let Some(s) = world.vehicle(&sender).and_then(|v| v.history.latest()) else {
                continue;
            };
            let t = s.t_s - *first_t_s.get_or_insert(s.t_s);
            if track.last().is_none_or(|w| t > w.t_s) {
                track.push(Waypoint {
                    t_s: t,
                    position_enu_m: s.position_enu_m.to_array(),
                });
            }
        }
    }
    if track.is_empty() {
        return Err(TrackError::NoPosition(path.to_owned()));
    }
    Ok((track, ingestor.stats))
}

/// Fly `encounter` over `scene` with `pipeline` (new, built for `scene`); `sensed` alerts on
/// the sensed states at each sample.
pub fn fly(
    scene: &Scene,
    mut pipeline: Pipeline,
    encounter: &Encounter,
    sensed: &mut Sensed,
) -> Flown {
    let plane = LocalTangentPlane::new(scene.origin);
    let mut events = Vec::new();
    let mut digest = EventDigest::default();
    let mut approaches = Approaches::with_volume(encounter.well_clear);
    let mut well_clear_changes = Vec::new();
    let n = (encounter.duration_s * encounter.rate_hz).round().max(0.0) as usize;
    let mut tick_costs = crate::costs::TickCosts::default();
    let mut bodies = MovingBodies::default();
    let mut previous: Option<TrackSample> = None;
    for i in 0..=n {
        let t_s = i as f64 / encounter.rate_hz;
        let current = ownship_sample(&plane, &encounter.own, t_s);
        let t_before = previous.map_or(t_s, |p| p.t_s);
        bodies.clear();
        for (index, d) in scene.dynamic.iter().enumerate() {
            if let DynamicSource::Waypoints(w) = &d.source {
                bodies.push(DynamicBody::on_track(
                    index as u32,
                    d.id.clone(),
                    d.kind,
                    d.threat,
                    d.geometry_index,
                    w,
                    (t_before, t_s),
                ));
            }
        }
        let kind = encounter.intruder_kind;
        for (k, (id, track)) in encounter.intruders.iter().enumerate() {
            bodies.push(DynamicBody::on_track(
                (scene.dynamic.len() + k) as u32,
                id.clone(),
                kind,
                scene.threat_of(kind),
                scene.kind_model(kind),
                track,
                (t_before, t_s),
            ));
        }
        approaches.observe(
            SenderId {
                system_id: OWNSHIP,
                component_id: 1,
            },
            previous.as_ref(),
            &current,
            bodies.as_slice().iter().map(Passing::from),
            &mut well_clear_changes,
        );
        let started = Instant::now();
        pipeline.step(
            scene,
            VehicleKey::new(u16::from(OWNSHIP)),
            previous.as_ref(),
            &current,
            &bodies,
            &mut events,
        );
        tick_costs.record(started.elapsed().as_nanos().min(u128::from(u64::MAX)) as u64);
        events.drain(..).for_each(|e| digest.take(&e));
        if let Some(daa) = sensed.as_mut() {
            sense(daa, &plane, encounter, &current, t_s);
        }
        previous = Some(current);
    }
    pipeline.finish(&mut events);
    events.drain(..).for_each(|e| digest.take(&e));
    Flown {
        pipeline,
        digest,
        approaches,
        tick_costs,
    }
}

/// One sample of alerting on sensed states: the intruders' truth at `t_s`.
fn sense(
    daa: &mut crate::batch::sensed::SensedDaa,
    plane: &LocalTangentPlane,
    encounter: &Encounter,
    current: &TrackSample,
    t_s: f64,
) {
    let truths: smallvec::SmallVec<[crate::batch::sensed::Truth; 4]> = encounter
        .intruders
        .iter()
        .enumerate()
        .map(|(index, (_, track))| {
            let (pose, velocity_enu_mps) = waypoint_pose(track, t_s);
            let p = pose.position_enu_m;
            crate::batch::sensed::Truth {
                index,
                target: crate::sensors::surveillance::Target {
                    key: index as u64 + 1,
                    position_enu_m: p,
                    velocity_enu_mps,
                    altitude_m: plane.geodetic_from_enu_m(p).alt_m,
                },
            }
        })
        .collect();
    let own = crate::batch::sensed::own_of(
        current.position_enu_m,
        current.velocity_enu_mps,
        current.attitude.enu_from_frd,
    );
    daa.step(t_s, &own, &truths);
}

/// The ownship on its track at `t_s`: level, nose along its course.
pub(crate) fn ownship_sample(
    plane: &LocalTangentPlane,
    track: &[Waypoint],
    t_s: f64,
) -> TrackSample {
    let (pose, velocity_enu_mps) = waypoint_pose(track, t_s);
    let time_boot_ms = (t_s * 1000.0).round() as u32;
    TrackSample {
        t_s,
        time_boot_ms,
        position: plane.geodetic_from_enu_m(pose.position_enu_m),
        position_enu_m: pose.position_enu_m,
        velocity_enu_mps,
        attitude: Attitude {
            time_boot_ms,
            enu_from_frd: pose.enu_from_body,
            body_rates_radps: DVec3::ZERO,
        },
    }
}

/// A DAIDALUS state file as an encounter's tracks: the first aircraft of each time is the
/// ownship, every other a named intruder; times from the first step; geodetic states placed
/// in the scene's ENU frame by WGS84 (their altitude as the height), Euclidean ones as ENU
/// metres from the scene's origin. Each track's velocity columns are not used: the track is
/// linear between its states, as any waypoint track.
pub fn tracks_from_daa(path: &Path, scene: &Scene) -> Result<DaaTracks, DaaTracksError> {
    let text = crate::daa_csv::read(path).map_err(|e| DaaTracksError::Read(Box::new(e)))?;
    let steps = crate::daa::scenario::parse(&text).map_err(|source| DaaTracksError::Parse {
        path: path.to_owned(),
        source,
    })?;
    let plane = LocalTangentPlane::new(scene.origin);
    let t0 = steps.first().map_or(0.0, |s| s.time_s);
    let mut own: Vec<Waypoint> = Vec::new();
    let mut intruders: Vec<(Arc<str>, Vec<Waypoint>)> = Vec::new();
    for step in &steps {
        let t_s = step.time_s - t0;
        for (k, state) in step.aircraft.iter().enumerate() {
            let position_enu_m = match state.position {
                crate::daa::scenario::Position::Geodetic {
                    lat_deg,
                    lon_deg,
                    alt_m,
                } => plane.enu_m_from_geodetic(&crate::geo::Geodetic {
                    lat_deg,
                    lon_deg,
                    alt_m,
                }),
                crate::daa::scenario::Position::Euclidean(p) => p,
            };
            let track = if k == 0 {
                &mut own
            } else {
                let at = match intruders.iter().position(|(id, _)| **id == *state.name) {
                    Some(at) => at,
                    None => {
                        intruders.push((Arc::from(state.name.as_str()), Vec::new()));
                        intruders.len() - 1
                    }
                };
                &mut intruders[at].1
            };
            // Times strictly increasing (a repeated time keeps its first state).
            if track.last().is_none_or(|w| t_s > w.t_s) {
                track.push(Waypoint {
                    t_s,
                    position_enu_m: position_enu_m.to_array(),
                });
            }
        }
    }
    if own.is_empty() || intruders.is_empty() {
        return Err(DaaTracksError::NoPair(path.to_owned()));
    }
    Ok(DaaTracks { own, intruders })
}

/// The tracks of a DAIDALUS state file.
#[derive(Debug, Clone)]
pub struct DaaTracks {
    /// The ownship's.
    pub own: Vec<Waypoint>,
    /// Each intruder's, by name.
    pub intruders: Vec<(Arc<str>, Vec<Waypoint>)>,
}
