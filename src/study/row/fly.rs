//! A row flown: every vehicle's pilot flies its plan on its own thread, each ArduCopter paced
//! to the row's clock, until the row's time is up, a collision ends it, or the caller stops.

use super::check::{check, check_companion, Checked, Flier};
use super::ids::autopilot_id;
use super::record::{record, record_clocks, record_live, record_other, FlownBy};
use super::session::{row_folder, scene_for, session_for, SessionThread};
use super::vehicles::{connect_pilot, start_vehicles, Vehicle};
use super::{RowError, Setup, FEED_HZ, MAX_CLOCK_SKEW_S};
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use crate::companion::slot::Intent;
use crate::geo::LocalTangentPlane;
use crate::live::{CompanionOptions, Flag, LiveOptions};
use crate::study::manifest::StudyRow;
use crate::study::pilot::fly::{fly, fly_px4, Flown};
use crate::study::pilot::heard::RowClock;
use crate::study::pilot::pace::Pace;
use crate::study::pilot::{Pilot, PilotError};
use crate::study::result::StudyResult;
use crate::world::SenderId;

pub(super) fn fly_row(
    row: &StudyRow,
    instance: u16,
    setup: &Setup,
    result: &mut StudyResult,
) -> Result<(), RowError> {
    let checked = check(row, setup.speedup)?;
    let companion = check_companion(row)?;
    result.speedup = checked.speedup;
    let scene = scene_for(row, &checked, setup)?;
    let own_id = autopilot_id(checked.own.px4, instance, 0);
    let mut session = session_for(row, result.sensor_seed, scene.clone(), checked.feed, own_id)?;
    let runtime = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(1)
        .enable_all()
        .build()
        .map_err(RowError::Runtime)?;
    let dir = row_folder(&mut session, setup, result)?;
    let mut vehicles = start_vehicles(&runtime, setup, &checked, (instance, &scene, &dir))?;
    result.system_id = Some(own_id.system_id);
    // The wall limit: the row's time at its speedup, twice over, and a minute for boot.
    let wall_limit = Duration::from_secs_f64(2.0 * checked.duration_s / checked.speedup + 60.0);
    let collided = Flag::default();
    let failed = Flag::default();
    let intent = Intent::default();
    let flown_by_companion = companion.is_some();
    let options = LiveOptions {
        companion: companion.map(|config| CompanionOptions {
            config,
            target_system_id: own_id.system_id,
            px4: checked.own.px4,
            dir: dir.clone(),
            intent: intent.clone(),
        }),
        duration: Some(wall_limit),
        rate_hz: FEED_HZ,
        collided: Some(collided.clone()),
        failed: Some(failed.clone()),
        feed_out: (setup.record_feed && checked.feed.is_some()).then(|| dir.join("feed.tlog")),
        ..LiveOptions::default()
    };
    let links = vehicles.iter_mut().filter_map(|v| v.link.take()).collect();
    let live = SessionThread::spawn(runtime, links, options, session)?;
    let plane = LocalTangentPlane::new(scene.origin);
    let started = Instant::now();
    let own_done = AtomicBool::new(false);
    // A session that ended on an error (its companion failed) ends the row: what it says is
    // the row's error.
    let stop = || {
        setup.stop.load(Ordering::Relaxed)
            || failed.is_raised()
            || (checked.stop_on_collision && collided.is_raised())
            || started.elapsed() > wall_limit
    };
    // The other vehicles also stop when the first is done.
    let others_stop = || stop() || own_done.load(Ordering::Relaxed);
    // Every exit from here on, `?` included, stops and joins the session thread (its drop).
    let mut pilots = Vec::new();
    for v in &mut vehicles {
        pilots.push(connect_pilot(v, plane, &setup.stop)?);
    }
    if let (true, Some(Ok(own))) = (flown_by_companion, pilots.first_mut()) {
        own.companion_intent = Some(intent);
    }
    let flights = fly_all(
        pilots,
        &vehicles,
        &checked,
        (&stop, &others_stop),
        &own_done,
    );
    let run = live.finish()?;
    let ids: Vec<SenderId> = vehicles.iter().map(|v| v.id).collect();
    let mut flown_all = flown_by_each(vehicles, flights)?.into_iter();
    let (flown, heard, _) = flown_all.next().ok_or(RowError::NoVehicle)?;
    // Stopped by the wall limit alone (no signal, no collision): the row flew only part of its
    // time, and what it flew is not judged as if it were all of it.
    let cut_short = flown.stopped
        && !setup.stop.load(Ordering::Relaxed)
        && !collided.is_raised()
        && started.elapsed() > wall_limit;
    if cut_short {
        return Err(wall_limit_error(&flown, started, wall_limit, &checked));
    }
    let mut run = run;
    if let Some(c) = &run.companion {
        result.record_companion(c);
        result.companion_skipped = Some(c.skipped);
    }
    for ((by, flier), id) in flown_all.zip(&checked.others).zip(&ids[1..]) {
        record_other(result, &run.session, *id, &by, flier);
    }
    record_clocks(result, &run.session);
    record_live(result, &mut run)?;
    record(
        result,
        &dir,
        &mut run.session,
        (&flown, &heard),
        checked.own.px4,
        checked.own.legs.len(),
    )?;
    // What was measured is kept; the row is not judged.
    match result.clock_skew_s {
        Some(skew_s) if skew_s > MAX_CLOCK_SKEW_S => Err(RowError::ClockSkew { skew_s }),
        _ => Ok(()),
    }
}

/// What each vehicle flew; the first failure, as SITL's when its SITL had ended. The SITLs
/// are stopped.
pub(super) fn flown_by_each(
    vehicles: Vec<Vehicle>,
    flights: Vec<Result<FlownBy, PilotError>>,
) -> Result<Vec<FlownBy>, RowError> {
    vehicles
        .into_iter()
        .zip(flights)
        .map(|(mut v, flight)| {
            let exited = v.sitl.exited();
            flight.map_err(|e| match exited {
                Some(status) => RowError::SitlEnded {
                    status,
                    log: v.sitl.log_tail(5),
                },
                None => RowError::Pilot(e),
            })
        })
        .collect()
}

/// The error of a row its wall-clock limit cut short.
pub(super) fn wall_limit_error(
    flown: &Flown,
    started: Instant,
    wall_limit: Duration,
    checked: &Checked,
) -> RowError {
    let flown_s = f64::from(flown.last_ms) / 1000.0;
    RowError::WallLimit {
        limit_s: wall_limit.as_secs_f64(),
        flown_s,
        duration_s: checked.duration_s,
        achieved: flown_s / started.elapsed().as_secs_f64(),
        speedup: checked.speedup,
    }
}

/// Fly each vehicle's plan with its pilot, the others on threads of their own timed by the
/// first's clock; each vehicle's outcome, in order.
pub(super) fn fly_all(
    mut pilots: Vec<Result<Pilot, PilotError>>,
    vehicles: &[Vehicle],
    checked: &Checked,
    (stop, others_stop): (&(dyn Fn() -> bool + Sync), &(dyn Fn() -> bool + Sync)),
    own_done: &AtomicBool,
) -> Vec<Result<FlownBy, PilotError>> {
    pace(&mut pilots, vehicles, checked.speedup);
    let mut pilots = pilots.into_iter();
    let Some(own_pilot) = pilots.next() else {
        return Vec::new();
    };
    let reference = own_pilot.as_ref().ok().map(|p| p.heard.clone());
    std::thread::scope(|scope| {
        let others: Vec<_> = pilots
            .zip(&checked.others)
            .zip(vehicles.iter().skip(1))
            .map(|((pilot, flier), vehicle)| {
                let clock = reference.clone().map(|reference| RowClock {
                    reference,
                    speedup: checked.speedup,
                });
                let px4 = vehicle.px4;
                scope.spawn(move || {
                    let mut pilot = pilot?;
                    pilot.row_clock = clock;
                    fly_vehicle(pilot, flier, px4, checked.duration_s, others_stop)
                })
            })
            .collect();
        let own = own_pilot.and_then(|pilot| {
            fly_vehicle(
                pilot,
                &checked.own,
                checked.own.px4,
                checked.duration_s,
                stop,
            )
        });
        own_done.store(true, Ordering::Relaxed);
        let joined = others.into_iter().map(|h| {
            h.join()
                .unwrap_or_else(|_| Err(PilotError::Send("a vehicle's pilot failed".into())))
        });
        std::iter::once(own).chain(joined).collect()
    })
}

/// In a row of several: each ArduCopter's speedup kept to one clock ([`crate::study::pilot::pace`]):
/// the first PX4's (PX4 SIH's pace cannot be set while it flies), else the first vehicle's.
pub(super) fn pace(pilots: &mut [Result<Pilot, PilotError>], vehicles: &[Vehicle], speedup: f64) {
    if pilots.len() < 2 {
        return;
    }
    let reference = vehicles.iter().position(|v| v.px4).unwrap_or(0);
    let Some(Ok(heard)) = pilots
        .get(reference)
        .map(|p| p.as_ref().map(|p| p.heard.clone()))
    else {
        return;
    };
    for (k, pilot) in pilots.iter_mut().enumerate() {
        let arducopter = vehicles.get(k).is_some_and(|v| !v.px4);
        if let (true, true, Ok(pilot)) = (k != reference, arducopter, pilot) {
            pilot.pace = Some(Pace::new(heard.clone(), speedup));
        }
    }
}

/// Fly `flier`'s plan with `pilot` until `duration_s` of its clock or `stop`.
pub(super) fn fly_vehicle(
    mut pilot: Pilot,
    flier: &Flier,
    px4: bool,
    duration_s: f64,
    stop: &dyn Fn() -> bool,
) -> Result<FlownBy, PilotError> {
    let flown = if px4 {
        fly_px4(&mut pilot, &flier.legs, &flier.params, duration_s, stop)
    } else {
        fly(&mut pilot, &flier.legs, duration_s, stop)
    }?;
    Ok((flown, pilot.heard(), pilot.row_offset_s))
}
