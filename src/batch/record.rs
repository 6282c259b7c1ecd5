//! `savsim batch ... --rerun-rows`: a row as a rerun recording, made after the row ran (so
//! that `failed` keeps only the rows worth a look, and the rows not kept cost nothing). The
//! row is flown a second time through a session that records it: a tlog row replayed again;
//! an encounter row's ownship sent to the session as the positions and attitudes its track
//! gives at the row's rate, on the vehicle's clock, its intruders as the scene's scripted
//! traffic. The row's results are its first flight's; the recording shows the same samples.

use std::path::Path;
use std::sync::atomic::AtomicBool;
use std::sync::Arc;

use glam::DVec3;

use crate::batch::encounter::{ownship_sample, Encounter, OWNSHIP};
use crate::batch::error::RowError;
use crate::batch::manifest::Run;
use crate::batch::row::RunRow;
use crate::batch::run::{mode_of, prepare, well_clear, Flight, Scenes};
use crate::codec::decode::{AttitudeReport, PositionReport, Report};
use crate::daa::approach::Approaches;
use crate::geo::LocalTangentPlane;
use crate::pipeline::Pipeline;
use crate::replay::{replay, Speed};
use crate::runs::recordings::{keep, recording_path, RowChoice};
use crate::scene::Scene;
use crate::session::Session;
use crate::world::SenderId;

/// Which rows `--rerun-rows` records, and where.
#[derive(Debug, Clone, Copy)]
pub struct Recorder<'a> {
    /// Which rows.
    pub choice: &'a RowChoice,
    /// The results directory (recordings go to its `rows/`).
    pub out: &'a Path,
    /// The variant the others are compared with (for `failed`).
    pub nominal: &'a str,
}

impl Recorder<'_> {
    /// Record `row` (the result of `run`) when the choice keeps it: what was done, for a
    /// person (`None` when it is not kept).
    pub fn after(&self, run: &Run, row: &RunRow, scenes: &Scenes) -> Option<String> {
        // A row that names no variant is not compared with anything: worth a look when it
        // did not pass.
        let variant = run.variant.as_deref().unwrap_or("");
        if !self
            .choice
            .keeps(&row.run_id, variant, row.ended(), self.nominal)
        {
            return None;
        }
        let kept = recording_path(self.out, row.index, &row.run_id);
        let part = kept.with_extension("rrd.part");
        let made = kept
            .parent()
            .map_or(Ok(()), std::fs::create_dir_all)
            .map_err(|source| RowError::RecordingFile {
                path: self.out.to_path_buf(),
                source,
            })
            .and_then(|()| record(row.index as usize, run, scenes, &part))
            .and_then(|()| {
                keep(&part, self.out, row.index, &row.run_id).map_err(|source| {
                    RowError::RecordingFile {
                        path: kept.clone(),
                        source,
                    }
                })
            });
        Some(match made {
            Ok(path) => format!("batch: {}: recording {}", row.run_id, path.display()),
            Err(e) => {
                let _ = std::fs::remove_file(&part);
                format!("batch: {}: the recording was not made: {e}", row.run_id)
            }
        })
    }
}

/// Record row `run` (row `index` of its manifest) to `path`.
pub fn record(index: usize, run: &Run, scenes: &Scenes, path: &Path) -> Result<(), RowError> {
    let mode = mode_of(run)?;
    let mut scratch = RunRow::of_inputs(index, run, mode.name());
    let (scene, pipeline, flight) = prepare(run, mode, scenes, &mut scratch)?;
    let session = match flight {
        Flight::Tlog(tlog) => {
            let mut session = recording_session(scene, pipeline, well_clear(run)?, path)?;
            let never = AtomicBool::new(false);
            replay(&tlog, Speed::Max, false, None, &mut session, &never)?;
            session
        }
        Flight::Encounter(encounter) => fly_recorded(&scene, pipeline, &encounter, path)?,
    };
    let mut session = session;
    session.finish()?;
    Ok(())
}

/// A session over `scene` recording to `path`, well clear judged with `volume`.
fn recording_session(
    scene: Arc<Scene>,
    pipeline: Pipeline,
    volume: Option<crate::daa::well_clear::Volume>,
    path: &Path,
) -> Result<Session, RowError> {
    let mut session = Session::with_pipeline(scene, pipeline, None)?;
    session.set_approaches(Approaches::with_volume(volume));
    crate::runs::recordings::record_to(&mut session, path)?;
    Ok(session)
}

/// The encounter flown through a recording session: its intruders pushed onto the scene as
/// scripted tracks, its ownship's samples sent as reports on the vehicle's clock.
fn fly_recorded(
    scene: &Scene,
    pipeline: Pipeline,
    encounter: &Encounter,
    path: &Path,
) -> Result<Session, RowError> {
    let mut with = scene.clone();
    for (id, track) in &encounter.intruders {
        if !with.push_track(id, encounter.intruder_kind, track.clone()) {
            return Err(RowError::RecordingTrack(id.to_string()));
        }
    }
    let mut session = Session::with_pipeline(Arc::new(with), pipeline, None)?;
    session.use_vehicle_clock();
    session.set_approaches(Approaches::with_volume(encounter.well_clear));
    crate::runs::recordings::record_to(&mut session, path)?;
    let plane = LocalTangentPlane::new(scene.origin);
    let sender = SenderId {
        system_id: OWNSHIP,
        component_id: 1,
    };
    let n = (encounter.duration_s * encounter.rate_hz).round().max(0.0) as usize;
    for i in 0..=n {
        let t_s = i as f64 / encounter.rate_hz;
        for report in reports_at(&plane, &encounter.own, t_s) {
            session.on_report(t_s, sender, &report)?;
        }
    }
    Ok(session)
}

/// The ownship at `t_s` of its track as an autopilot reports it: ATTITUDE, then
/// GLOBAL_POSITION_INT (the position makes the tick, with the attitude already known).
fn reports_at(plane: &LocalTangentPlane, own: &[crate::scene::Waypoint], t_s: f64) -> [Report; 2] {
    let s = ownship_sample(plane, own, t_s);
    let [roll_rad, pitch_rad, yaw_rad] = s.attitude.euler_ned_rad(plane, &s.position);
    let v = s.velocity_enu_mps;
    let forward = s.attitude.forward_enu();
    [
        Report::Attitude(AttitudeReport {
            time_boot_ms: s.time_boot_ms,
            roll_rad,
            pitch_rad,
            yaw_rad,
            body_rates_radps: DVec3::ZERO,
        }),
        Report::Position(PositionReport {
            time_boot_ms: s.time_boot_ms,
            position: s.position,
            relative_alt_m: s.position_enu_m.z,
            velocity_ned_mps: DVec3::new(v.y, v.x, -v.z),
            heading_deg: Some(forward.x.atan2(forward.y).to_degrees().rem_euclid(360.0)),
        }),
    ]
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::Waypoint;

    #[test]
    fn the_reports_give_back_the_tracks_pose() {
        let plane = LocalTangentPlane::new(crate::geo::Geodetic::new(47.0, 8.0, 400.0));
        let own = [
            Waypoint {
                t_s: 0.0,
                position_enu_m: [0.0, 0.0, 50.0],
            },
            Waypoint {
                t_s: 10.0,
                position_enu_m: [100.0, 100.0, 60.0],
            },
        ];
        let s = ownship_sample(&plane, &own, 5.0);
        let [Report::Attitude(a), Report::Position(p)] = reports_at(&plane, &own, 5.0) else {
            panic!("an attitude, then a position");
        };
        let back = crate::world::Attitude::from_euler_ned(
            &plane,
            &p.position,
            a.roll_rad,
            a.pitch_rad,
            a.yaw_rad,
            a.time_boot_ms,
        );
        assert!(back.enu_from_frd.angle_between(s.attitude.enu_from_frd) < 1e-9);
        // North-east: heading 45 degrees.
        assert!((p.heading_deg.unwrap() - 45.0).abs() < 1e-6, "{p:?}");
        assert!((p.velocity_ned_mps - DVec3::new(10.0, 10.0, -1.0)).length() < 1e-9);
        assert_eq!(p.time_boot_ms, 5000);
    }
}
