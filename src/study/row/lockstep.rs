//! A row flown in lockstep (`physics = savsim`): savsim's dynamics fly every vehicle, each
//! autopilot (ArduCopter through its JSON backend) waits for savsim's clock, the pilots fly
//! their plans on that clock, and the world gets the truth with no network between.

use super::check::{check, check_companion, Checked, Flier};
use super::fly::{fly_vehicle, wall_limit_error};
use super::ids::INSTANCE_OFFSET;
use super::record::{record, record_other, FlownBy};
use super::session::{home_of, row_folder, scene_for, session_for};
use super::{input, RowError, Setup, FEED_HZ};
use std::path::Path;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use glam::DVec3;
use savsim_core::dynamics::Frame;

use crate::companion::slot::Slot;
use crate::geo::LocalTangentPlane;
use crate::lockstep::driver::{run_timed, Lockstepped, LoopConfig, LoopTimes};
use crate::lockstep::physics::{frame_named, step_us, wind_ned_mps};
use crate::lockstep::pin::Pinned;
use crate::lockstep::vehicle::SimVehicle;
use crate::scene::Scene;
use crate::study::manifest::StudyRow;
use crate::study::pilot::{Pilot, PilotError};
use crate::study::result::StudyResult;
use crate::study::sitl::{Sitl, Start};
use crate::study::sitl_lockstep::{
    frame_params, start_lockstepped, start_lockstepped_px4, Serial1,
};
use crate::world::SenderId;

/// The most vehicles a lockstep row may fly.
pub const MAX_LOCKSTEP_VEHICLES: usize = 32;
/// The physics step when a row names none, milliseconds: one step per ArduCopter loop (400
/// Hz); 4 for PX4 alone (its IMU at 250 Hz, `IMU_INTEG_RATE`); 2 when both fly (above
/// ArduCopter's loop rate, two samples to PX4's integration).
pub const DEFAULT_STEP_MS: f64 = 2.5;

/// A lockstep row's physics columns, checked.
struct Physics {
    /// The row's `frame`, when it names one (for every vehicle).
    frame: Option<(String, Frame)>,
    step_us: u64,
    wind_ned_mps: DVec3,
}

impl Physics {
    /// The frame (its name and itself) a vehicle flies: the row's, else its autopilot's.
    fn frame_for(&self, px4: bool) -> (String, Frame) {
        self.frame.clone().unwrap_or_else(|| {
            let (name, frame) = savsim_core::dynamics::presets::default_for(px4);
            (name.to_string(), frame)
        })
    }
}

fn check_physics(row: &StudyRow, checked: &Checked) -> Result<Physics, RowError> {
    let fliers: Vec<&Flier> = std::iter::once(&checked.own)
        .chain(&checked.others)
        .collect();
    if fliers.len() > MAX_LOCKSTEP_VEHICLES {
        return Err(input(
            "intruder_autopilot",
            format!(
                "{} vehicles: a lockstep row flies at most {MAX_LOCKSTEP_VEHICLES}",
                fliers.len()
            ),
        ));
    }
    let frame = row
        .frame
        .as_deref()
        .filter(|f| !f.trim().is_empty())
        .map(|name| {
            frame_named(name)
                .map(|f| (name.to_string(), f))
                .map_err(|e| input("frame", e.to_string()))
        })
        .transpose()?;
    let (px4, arducopter) = (fliers.iter().any(|f| f.px4), fliers.iter().any(|f| !f.px4));
    let default_step_ms = match (px4, arducopter) {
        (true, true) => 2.0,
        (true, false) => 4.0,
        _ => DEFAULT_STEP_MS,
    };
    let step_us = step_us(row.step_ms.unwrap_or(default_step_ms))
        .map_err(|e| input("step_ms", e.to_string()))?;
    let wind_ned_mps = match row.wind.as_deref().filter(|w| !w.trim().is_empty()) {
        None => DVec3::ZERO,
        Some(text) => wind_ned_mps(text).map_err(|e| input("wind", e.to_string()))?,
    };
    Ok(Physics {
        frame,
        step_us,
        wind_ned_mps,
    })
}

/// The system id of a lockstep row's vehicle `k` (from 0): `k + 1`.
fn lockstep_id(k: usize) -> SenderId {
    SenderId {
        system_id: (k + 1) as u8,
        component_id: 1,
    }
}

/// One vehicle of a lockstep row, started: its SITL, its place in the loop, its pilot.
struct Started {
    sitl: Sitl,
    lockstepped: Lockstepped,
    pilot: Pilot,
}

fn start_vehicle(
    setup: &Setup,
    (flier, k, instance): (&Flier, usize, u16),
    physics: &Physics,
    (scene, plane, dir): (&Scene, LocalTangentPlane, &Path),
) -> Result<Started, RowError> {
    let id = lockstep_id(k);
    let (frame_name, frame) = physics.frame_for(flier.px4);
    let mut params = flier.params.clone();
    params.retain(|(name, _)| name != "SYSID_THISMAV" && name != "MAV_SYS_ID");
    let home = home_of(scene, flier.home_en_m);
    let vehicle = SimVehicle::landed(
        id,
        frame,
        (home, plane.enu_m_from_geodetic(&home)),
        0.0,
        physics.wind_ned_mps,
    );
    let mut start = Start {
        instance,
        home,
        home_yaw_deg: 0.0,
        speedup: 1.0,
        serial0: "",
        params: &[],
        dir,
    };
    let (sitl, mut lockstepped, pilot_port) = if flier.px4 {
        let px4 = setup.px4.as_ref().ok_or(RowError::NoAutopilot {
            autopilot: "PX4",
            flag: "px4",
            variable: "SAVSIM_PX4",
        })?;
        if let Some(up_m) = crate::study::pilot::fly::takeoff_m(&flier.legs) {
            params.push(("MIS_TAKEOFF_ALT".into(), up_m));
        }
        start.params = &params;
        let (sitl, lockstepped, pilot) =
            start_lockstepped_px4(px4, &start, vehicle, (id.system_id, plane))?;
        (sitl, lockstepped, Some(pilot))
    } else {
        let arducopter = setup.arducopter.as_ref().ok_or(RowError::NoAutopilot {
            autopilot: "ArduCopter",
            flag: "arducopter",
            variable: "SAVSIM_ARDUCOPTER",
        })?;
        params.push(("SYSID_THISMAV".into(), f64::from(id.system_id)));
        frame_params(&frame_name, &mut params);
        start.params = &params;
        start_lockstepped(arducopter, &start, vehicle, Serial1::Pilot)?
    };
    let (pilot, inbox) = Pilot::lockstep(id, plane);
    let pilot_port = pilot_port.ok_or(RowError::NoLinkPort)?;
    lockstepped.pilot = Some((pilot_port, Box::new(inbox)));
    Ok(Started {
        sitl,
        lockstepped,
        pilot,
    })
}

/// Fly `row` in lockstep on SITL instances from `instance` (vehicle `k` on `instance + k x
/// INSTANCE_OFFSET`).
pub(super) fn fly_lockstep_row(
    row: &StudyRow,
    instance: u16,
    setup: &Setup,
    result: &mut StudyResult,
) -> Result<(), RowError> {
    let checked = check(row, setup.speedup)?;
    let physics = check_physics(row, &checked)?;
    let companion = check_companion(row)?;
    result.frame = Some(physics.frame_for(checked.own.px4).0);
    result.step_ms = Some(physics.step_us as f64 / 1000.0);
    result.speedup = row.speedup.unwrap_or(0.0);
    let scene = scene_for(row, &checked, setup)?;
    let fliers: Vec<&Flier> = std::iter::once(&checked.own)
        .chain(&checked.others)
        .collect();
    // One ArduCopter and savsim take turns: on one core the turn hands over without waking
    // another (twice the speed on a quiet machine; lockstep::pin). Several autopilots compute
    // at once, and PX4 runs threads of its own: left to every core.
    let one_arducopter = fliers.len() == 1 && !checked.own.px4;
    let _pinned = one_arducopter.then(|| Pinned::to_core(usize::from(instance)));
    let ids: Vec<SenderId> = (0..fliers.len()).map(lockstep_id).collect();
    let mut session = session_for(row, result.sensor_seed, scene.clone(), checked.feed, ids[0])?;
    session.set_truth_fed(ids.clone());
    if companion.is_some() {
        session.keep_companion_inputs();
    }
    let dir = row_folder(&mut session, setup, result)?;
    let plane = LocalTangentPlane::new(scene.origin);
    let mut started = Vec::with_capacity(fliers.len());
    for (k, flier) in fliers.iter().enumerate() {
        let folder = match k {
            0 => dir.clone(),
            k => dir.join(format!("vehicle-{}", k + 1)),
        };
        let at = instance + k as u16 * INSTANCE_OFFSET;
        started.push(start_vehicle(
            setup,
            (flier, k, at),
            &physics,
            (&scene, plane, &folder),
        )?);
    }
    if let (Some(config), Some(own)) = (&companion, started.first_mut()) {
        let devices: Vec<String> = session.sensor_names();
        let at = (dir.as_path(), setup.stop.as_ref());
        let slot = Slot::start(config, (ids[0], checked.own.px4), at, &devices)?;
        own.pilot.companion_intent = Some(slot.intent());
        own.lockstepped.companion = Some(slot);
    }
    result.system_id = Some(ids[0].system_id);
    let config = LoopConfig {
        step_us: physics.step_us,
        truth_every_us: (1e6 / FEED_HZ).round() as u64,
        // The row's own speedup caps its pace; without one, as fast as the autopilots go
        // (`--speedup` is a pace for SITL's own physics).
        real_time: row.speedup,
        silence: Duration::from_secs(20),
        end_us: Some(((checked.duration_s + 5.0) * 1e6) as u64),
        stop_on_collision: checked.stop_on_collision,
        end_with_first_pilot: true,
    };
    let flown = fly_started(started, &checked, &config, setup, (&scene, &mut session));
    let mut flights = flown.flights.into_iter();
    let (own, heard, _) = flights.next().ok_or(RowError::NoVehicle)??;
    // The row's time ran out before its autopilot could arm (it never had a position, or
    // refused): not a flight to judge.
    let takes_off = checked
        .own
        .legs
        .iter()
        .any(|l| matches!(l, crate::study::plan::Leg::Takeoff { .. }));
    if takes_off && own.armed_t_s.is_none() && !setup.stop.load(Ordering::Relaxed) {
        return Err(RowError::Pilot(PilotError::NoArm {
            waited_s: checked.duration_s,
            texts: heard.last_texts(),
        }));
    }
    if flown.wall_limited {
        return Err(wall_limit_error(
            &own,
            flown.started,
            flown.wall_limit,
            &checked,
        ));
    }
    for ((by, flier), id) in flights.zip(&checked.others).zip(&ids[1..]) {
        record_other(result, &session, *id, &by?, flier);
    }
    for (other, e) in result.others.iter_mut().zip(flown.estimates.iter().skip(1)) {
        other.estimate = Some(*e);
    }
    result.estimate = flown.estimates.first().copied();
    result.lockstep_times = Some(flown.times);
    if let Some(c) = &flown.companion {
        result.record_companion(c);
    }
    result.clock_skew_s = (!result.others.is_empty()).then_some(0.0);
    record(
        result,
        &dir,
        &mut session,
        (&own, &heard),
        checked.own.px4,
        checked.own.legs.len(),
    )
}

/// What a lockstep row's loop and pilots did.
struct LockstepFlown {
    /// Each vehicle's flight, in order (the loop's error, or its SITL's end, for all when the
    /// loop failed).
    flights: Vec<Result<FlownBy, RowError>>,
    /// Each vehicle's estimate against the truth.
    estimates: Vec<crate::lockstep::estimates::ErrorStats>,
    /// Where the loop's wall time went.
    times: LoopTimes,
    /// What the first vehicle's companion did.
    companion: Option<crate::companion::slot::CompanionCounts>,
    /// The row's wall-clock limit stopped it.
    wall_limited: bool,
    started: Instant,
    wall_limit: Duration,
}

/// Run the loop on a thread of its own and every pilot on its own (the first on this one)
/// until the first vehicle's plan or time is done, a collision ends the row, the caller stops,
/// or the wall-clock limit passes; every SITL stopped.
fn fly_started(
    started: Vec<Started>,
    checked: &Checked,
    config: &LoopConfig,
    setup: &Setup,
    (scene, session): (&Scene, &mut crate::session::Session),
) -> LockstepFlown {
    let mut sitls = Vec::with_capacity(started.len());
    let mut lockstepped = Vec::with_capacity(started.len());
    let mut pilots = Vec::with_capacity(started.len());
    for s in started {
        sitls.push(s.sitl);
        lockstepped.push(s.lockstepped);
        pilots.push(s.pilot);
    }
    // Boot and the row's time, as fast as the machine goes, at worst 5x slower than real time.
    let wall_limit = Duration::from_secs_f64(5.0 * checked.duration_s + 120.0);
    let begun = Instant::now();
    let loop_done = AtomicBool::new(false);
    let wall_limited = AtomicBool::new(false);
    let mut times = LoopTimes::default();
    let (ended, flights) = std::thread::scope(|scope| {
        let physics = std::thread::Builder::new()
            .name("savsim-lockstep".into())
            .spawn_scoped(scope, || {
                let stop = |_: u64| {
                    let late = begun.elapsed() > wall_limit;
                    wall_limited.store(late, Ordering::Relaxed);
                    setup.stop.load(Ordering::Relaxed) || late
                };
                let ended = run_timed(&mut lockstepped, scene, session, config, &stop, &mut times);
                loop_done.store(true, Ordering::Relaxed);
                ended
            });
        let stop = || setup.stop.load(Ordering::Relaxed) || loop_done.load(Ordering::Relaxed);
        let flights = fly_pilots(pilots, checked, &stop);
        let ended = match physics {
            Ok(handle) => handle.join().map_err(|_| RowError::SessionThread),
            Err(_) => Err(RowError::SessionThread),
        };
        (ended, flights)
    });
    let estimates = lockstepped.iter().map(|v| v.estimates.stats()).collect();
    let companion = lockstepped
        .first()
        .and_then(|v| v.companion.as_ref())
        .map(|c| c.counts.clone());
    let failed = match ended {
        Ok(Ok(_)) => None,
        Ok(Err(e)) => Some(e.to_string()),
        Err(e) => Some(e.to_string()),
    };
    let flights = flights
        .into_iter()
        .zip(&mut sitls)
        .map(|(flight, sitl)| match (&failed, sitl.exited()) {
            (Some(_), Some(status)) => Err(RowError::SitlEnded {
                status,
                log: sitl.log_tail(5),
            }),
            (Some(why), None) => Err(RowError::Savsim(crate::error::Error::Runtime(why.clone()))),
            (None, _) => flight.map_err(RowError::Pilot),
        })
        .collect();
    LockstepFlown {
        flights,
        estimates,
        times,
        companion,
        wall_limited: wall_limited.load(Ordering::Relaxed),
        started: begun,
        wall_limit,
    }
}

/// Fly each pilot's plan, the others on threads of their own (the first's end, its pilot
/// gone, ends the loop at that step).
fn fly_pilots(
    pilots: Vec<Pilot>,
    checked: &Checked,
    stop: &(dyn Fn() -> bool + Sync),
) -> Vec<Result<FlownBy, PilotError>> {
    let mut pilots = pilots.into_iter();
    let Some(own) = pilots.next() else {
        return Vec::new();
    };
    std::thread::scope(|scope| {
        let others: Vec<_> = pilots
            .zip(&checked.others)
            .map(|(pilot, flier)| {
                scope.spawn(move || fly_vehicle(pilot, flier, flier.px4, checked.duration_s, stop))
            })
            .collect();
        let own = fly_vehicle(own, &checked.own, checked.own.px4, checked.duration_s, stop);
        let joined = others.into_iter().map(|h| {
            h.join()
                .unwrap_or_else(|_| Err(PilotError::Send("a vehicle's pilot failed".into())))
        });
        std::iter::once(own).chain(joined).collect()
    })
}
