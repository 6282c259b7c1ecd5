//! One study row, end to end: its inputs checked, its scene (with its intruder) loaded, its
//! SITL started on its own instance and folder, savsim's session on SITL's SERIAL0 with the
//! row's feed, the pilot flying the plan on SERIAL1, and everything stopped at the end. Any
//! failure (a bad column, a SITL that does not boot, hangs or dies, even a bug) becomes the
//! row's `error`; the study goes on.

use std::panic::AssertUnwindSafe;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use crate::collision::approach::Approaches;
use crate::daa::well_clear::Volume;
use crate::feed::{FeedConfig, FeedKinds};
use crate::geo::{Geodetic, LocalTangentPlane};
use crate::ingest::address::ConnectAddress;
use crate::ingest::live::Link;
use crate::ingest::notes::{arducopter_mode_name, px4_mode_name};
use crate::ingest::stats::SenderId;
use crate::live::{run_links, Flag, LiveOptions, LiveRun};
use crate::pipeline::CollisionConfig;
use crate::runs::recordings::RowChoice;
use crate::runs::scenes::{SceneCache, SceneLookup};
use crate::scene::{Kind, Scene, Waypoint};
use crate::session::Session;
use crate::study::fly::{fly, fly_px4, Flown};
use crate::study::manifest::StudyRow;
use crate::study::pace::Pace;
use crate::study::pilot::{mode, Heard, Pilot, PilotError, RowClock};
use crate::study::plan::{self, Leg, PlanError};
use crate::study::result::{AutopilotDid, Outcome, StudyResult, VehicleResult};
use crate::study::sitl::{
    px4_autopilot, px4_gcs_port, px4_onboard_ports, ArduCopter, Px4, Sitl, Start,
};
use savsim_core::bounds::{MAX_DURATION_S, MAX_ENU_M};

/// A row's default length, seconds of the vehicle's clock.
pub const DEFAULT_DURATION_S: f64 = 120.0;
/// The speedups a row may ask of SITL.
pub const SPEEDUP_RANGE: (f64, f64) = (0.1, 1000.0);
/// The feed's rate in a study, Hz of the vehicle's clock, and the rate positions are asked for
/// on the session's link (the feed is cast at each position). ArduCopter stops a copter at 5-8
/// m/s within a frame or two of seeing the obstacle closer than its margin: at 20 Hz a frame is
/// 0.25-0.4 m of travel, at 50 Hz 0.1-0.16 m.
pub const FEED_HZ: f64 = 50.0;
/// A row's vehicle `k` (from 0) runs on SITL instance `instance + k x INSTANCE_OFFSET` (its
/// own ports): past the instances `--jobs` can take.
pub const INSTANCE_OFFSET: u16 = crate::study::command::MAX_JOBS as u16;
/// The most vehicles a row may fly: PX4 SITL's system id is its instance + 1, so a third
/// vehicle's (instance under `3 x INSTANCE_OFFSET`) is at most 192, and a fourth's would not
/// fit in MAVLink's 255 beside the ArduCopters' ([`arducopter_sysid`]).
pub const MAX_VEHICLES: usize = 3;
/// The SYSID_THISMAV of a row's vehicle `k` (from 1) after its first when it is an
/// ArduCopter: 200 + k (201 for the second). No PX4 vehicle of a row has it (PX4 SITL's system
/// id is its instance + 1, at most `MAX_VEHICLES x INSTANCE_OFFSET`).
pub fn arducopter_sysid(k: usize) -> u8 {
    200 + k.min(MAX_VEHICLES) as u8
}
/// The largest drift allowed between the clocks of a row's vehicles, seconds: beyond it
/// the row is an error. Each vehicle is placed in the world where it was when it sent its
/// position, whatever its clock; but a clock ahead by 0.2 s has flown its physics 0.2 s
/// further: two copters closing at 2 x 12 m/s (the fastest `study gen --equipage` draws) then
/// meet up to 4.8 m off the encounter drawn (docs/study.md, "Several autopilots").
pub const MAX_CLOCK_SKEW_S: f64 = 0.2;

/// The identity of a row's vehicle `k` (from 0): ArduCopter SITL's default SYSID_THISMAV 1
/// for the first (whatever its instance), [`arducopter_sysid`] for the others; PX4 SITL sets
/// MAV_SYS_ID to its instance + 1. Component 1, the autopilot.
fn autopilot_id(px4: bool, instance: u16, k: usize) -> SenderId {
    if px4 {
        px4_autopilot(instance)
    } else {
        SenderId {
            system_id: if k == 0 { 1 } else { arducopter_sysid(k) },
            component_id: 1,
        }
    }
}

/// Why a row could not be flown.
#[derive(Debug, thiserror::Error)]
pub enum RowError {
    /// A column's value.
    #[error("{column}: {why}")]
    Input {
        /// The column.
        column: &'static str,
        /// What is wrong.
        why: String,
    },
    /// The plan.
    #[error(transparent)]
    Plan(#[from] PlanError),
    /// The row's scene did not load.
    #[error("scene: {0}")]
    Scene(SceneLookup),
    /// The autopilot's binary is not there.
    #[error("{0}")]
    NoAutopilot(String),
    /// SITL could not start, or ended by itself.
    #[error("SITL: {0}")]
    Sitl(String),
    /// The pilot.
    #[error("{0}")]
    Pilot(#[from] PilotError),
    /// savsim's side (the scene, the session, the link).
    #[error("savsim: {0}")]
    Savsim(String),
    /// The clocks of the row's vehicles drifted apart by more than [`MAX_CLOCK_SKEW_S`]:
    /// where each was at a given moment is not known well enough.
    #[error(
        "the vehicles' clocks drifted {skew_s:.3} s apart (at most {MAX_CLOCK_SKEW_S} s): \
         not judged"
    )]
    ClockSkew {
        /// The largest drift, seconds.
        skew_s: f64,
    },
    /// The row's wall-clock limit passed before its plan or its time on the vehicle's clock
    /// ended (SITL ran far below its speedup): what it flew is not judged.
    #[error(
        "the wall-clock limit ({limit_s:.0} s) passed at {flown_s:.1} s of the vehicle's clock \
         of the row's {duration_s} s (SITL ran at about {achieved:.2}x, asked {speedup}x): \
         not judged"
    )]
    WallLimit {
        /// The limit, wall seconds.
        limit_s: f64,
        /// How far the vehicle's clock got, seconds.
        flown_s: f64,
        /// The row's duration, seconds of the vehicle's clock.
        duration_s: f64,
        /// The vehicle's clock over the wall clock while it flew.
        achieved: f64,
        /// The speedup asked.
        speedup: f64,
    },
}

fn input(column: &'static str, why: impl Into<String>) -> RowError {
    RowError::Input {
        column,
        why: why.into(),
    }
}

/// What every row of a study shares.
pub struct Setup {
    /// ArduCopter SITL, when given.
    pub arducopter: Option<ArduCopter>,
    /// PX4 SITL (SIH), when given.
    pub px4: Option<Px4>,
    /// The speedup for rows that name none.
    pub speedup: f64,
    /// Where each row's SITL folder is made (`DIR/work/<row id>`).
    pub work: PathBuf,
    /// Raised by a signal: every row stops and its SITL with it.
    pub stop: Arc<AtomicBool>,
    /// Record every frame the feed sends a row's vehicle to `feed.tlog` in the row's folder
    /// (`--keep-work` keeps it). Default false.
    pub record_feed: bool,
    /// Rows recorded for the rerun viewer, each to [`RECORDING`] in its folder (`--rerun-rows`).
    pub record_rows: Option<RowChoice>,
    scenes: SceneCache,
}

impl Setup {
    /// The setup for `rows`: each scene they name loaded once.
    pub fn new(
        rows: &[StudyRow],
        autopilots: (Option<ArduCopter>, Option<Px4>),
        speedup: f64,
        work: PathBuf,
        stop: Arc<AtomicBool>,
    ) -> Self {
        Setup {
            arducopter: autopilots.0,
            px4: autopilots.1,
            speedup,
            work,
            stop,
            record_feed: false,
            record_rows: None,
            scenes: SceneCache::load(rows.iter().filter_map(|r| r.scene.as_deref())),
        }
    }

    fn scene(&self, path: Option<&str>) -> Result<Arc<Scene>, RowError> {
        self.scenes.get(path).map_err(RowError::Scene)
    }
}

/// One vehicle of a row: its autopilot, plan and parameters, checked.
#[derive(Debug, Clone)]
struct Flier {
    px4: bool,
    legs: Vec<Leg>,
    params: Vec<(String, f64)>,
    /// Home, scene ENU metres east and north (on the scene's ground there).
    home_en_m: [f64; 2],
}

/// A row's columns, checked.
struct Checked {
    own: Flier,
    /// The vehicles after the first, in the manifest's order.
    others: Vec<Flier>,
    feed: Option<FeedKinds>,
    intruder: Option<(Kind, Vec<Waypoint>)>,
    duration_s: f64,
    speedup: f64,
    stop_on_collision: bool,
}

/// Whether `name` (of `column`) is PX4.
fn is_px4(column: &'static str, name: &str) -> Result<bool, RowError> {
    match name {
        "arducopter" => Ok(false),
        "px4" => Ok(true),
        other => Err(input(column, format!("{other:?}: give arducopter or px4"))),
    }
}

/// The row's vehicles after its first (`intruder_autopilot` and its columns): one for each
/// name in `intruder_autopilot`, separated by `|` (`arducopter|px4`); `intruder_plan`,
/// `intruder_params` and `intruder_home` give one entry for every vehicle, or one for all.
fn check_others(row: &StudyRow) -> Result<Vec<Flier>, RowError> {
    fn given(v: &Option<String>) -> Option<&str> {
        v.as_deref().filter(|t| !t.trim().is_empty())
    }
    let Some(autopilots) = given(&row.intruder_autopilot) else {
        if given(&row.intruder_plan).is_some() || given(&row.intruder_params).is_some() {
            return Err(input(
                "intruder_autopilot",
                "intruder_plan and intruder_params are for a second autopilot: name it",
            ));
        }
        return Ok(Vec::new());
    };
    if given(&row.intruder).is_some() {
        return Err(input(
            "intruder_autopilot",
            "give a scripted intruder or an autopilot, not both",
        ));
    }
    let autopilots: Vec<&str> = autopilots.split('|').map(str::trim).collect();
    if autopilots.len() >= MAX_VEHICLES {
        return Err(input(
            "intruder_autopilot",
            format!(
                "{} vehicles after the first: a row flies at most {MAX_VEHICLES} in all",
                autopilots.len()
            ),
        ));
    }
    let n = autopilots.len();
    let plans = per_vehicle("intruder_plan", given(&row.intruder_plan), n)?;
    let params = per_vehicle("intruder_params", given(&row.intruder_params), n)?;
    let homes = per_vehicle("intruder_home", given(&row.intruder_home), n)?;
    let mut others = Vec::with_capacity(n);
    for (k, autopilot) in autopilots.into_iter().enumerate() {
        others.push(check_other(
            k + 1,
            autopilot,
            [plans[k], params[k], homes[k]],
        )?);
    }
    Ok(others)
}

/// A column's entries for `n` vehicles: none given (each `""`), one for all, or one each
/// (separated by `|`).
fn per_vehicle<'a>(
    column: &'static str,
    text: Option<&'a str>,
    n: usize,
) -> Result<Vec<&'a str>, RowError> {
    let Some(text) = text else {
        return Ok(vec![""; n]);
    };
    let entries: Vec<&str> = text.split('|').map(str::trim).collect();
    match entries.len() {
        1 => Ok(vec![entries[0]; n]),
        k if k == n => Ok(entries),
        k => Err(input(
            column,
            format!("{k} entries for {n} vehicles: give one for all, or one each, separated by |"),
        )),
    }
}

/// The row's vehicle `k` (from 1) after its first: `autopilot`, and its plan, parameters and
/// home as given.
fn check_other(
    k: usize,
    autopilot: &str,
    [plan_text, params_text, home]: [&str; 3],
) -> Result<Flier, RowError> {
    let px4 = is_px4("intruder_autopilot", autopilot)?;
    let legs = plan::parse(plan_text).map_err(|e| input("intruder_plan", e.to_string()))?;
    let mut params =
        plan::parse_params(params_text).map_err(|why| input("intruder_params", why))?;
    if !px4 {
        // Last, so that it holds over the row's own: the session tells the vehicles apart by it.
        params.push(("SYSID_THISMAV".into(), f64::from(arducopter_sysid(k))));
    }
    let home_en_m = match home {
        "" => [0.0, 0.0],
        text => parse_home(text).map_err(|why| input("intruder_home", why))?,
    };
    Ok(Flier {
        px4,
        legs,
        params,
        home_en_m,
    })
}

/// `E N`: metres east and north of the scene's origin, within the scene's bounds.
fn parse_home(text: &str) -> Result<[f64; 2], String> {
    let numbers: Vec<f64> = text
        .split_whitespace()
        .map(|w| w.parse::<f64>().ok().filter(|v| v.is_finite()))
        .collect::<Option<_>>()
        .ok_or_else(|| format!("{text:?}: give E N in metres"))?;
    match numbers[..] {
        [e, n] if e.abs() <= MAX_ENU_M && n.abs() <= MAX_ENU_M => Ok([e, n]),
        _ => Err(format!(
            "{text:?}: give E N in metres, each within +/-{MAX_ENU_M}"
        )),
    }
}

fn check(row: &StudyRow, default_speedup: f64) -> Result<Checked, RowError> {
    let px4 = is_px4(
        "autopilot",
        row.autopilot.as_deref().unwrap_or("arducopter"),
    )?;
    let legs = plan::parse(row.plan.as_deref().unwrap_or_default())?;
    let params = plan::parse_params(row.params.as_deref().unwrap_or_default())
        .map_err(|why| input("params", why))?;
    let others = check_others(row)?;
    let feed = row
        .feed
        .as_deref()
        .filter(|f| !f.trim().is_empty())
        .map(|f| FeedKinds::parse(f).map_err(|e| input("feed", format!("{f}: {e}"))))
        .transpose()?;
    let kind = match row.intruder_kind.as_deref().filter(|k| !k.is_empty()) {
        None => Kind::Dji,
        Some(k) => Kind::from_name(k).ok_or_else(|| input("intruder_kind", format!("{k:?}")))?,
    };
    let intruder = row
        .intruder
        .as_deref()
        .filter(|t| !t.trim().is_empty())
        .map(|t| {
            crate::runs::waypoints::parse_waypoints(t)
                .map_err(|why| input("intruder", why.to_string()))
        })
        .transpose()?
        .map(|w| (kind, w));
    let duration_s = row.duration_s.unwrap_or(DEFAULT_DURATION_S);
    if !(duration_s > 0.0 && duration_s <= MAX_DURATION_S) {
        return Err(input(
            "duration_s",
            format!("{duration_s}: give more than 0 and at most {MAX_DURATION_S} s"),
        ));
    }
    let speedup = row.speedup.unwrap_or(default_speedup);
    if !(SPEEDUP_RANGE.0..=SPEEDUP_RANGE.1).contains(&speedup) {
        return Err(input(
            "speedup",
            format!("{speedup}: give {} to {}", SPEEDUP_RANGE.0, SPEEDUP_RANGE.1),
        ));
    }
    if let Some(w) = row.w.filter(|w| !(w.is_finite() && *w >= 0.0)) {
        return Err(input("w", format!("{w}: give a finite weight >= 0")));
    }
    Ok(Checked {
        own: Flier {
            px4,
            legs,
            params,
            home_en_m: [0.0, 0.0],
        },
        others,
        feed,
        intruder,
        duration_s,
        speedup,
        stop_on_collision: row.stop_on_collision.unwrap_or(true),
    })
}

/// Fly row `index` on SITL instance `instance`.
pub fn run_row(index: usize, row: &StudyRow, instance: u16, setup: &Setup) -> StudyResult {
    let started = Instant::now();
    let mut result = StudyResult::of_inputs(index, row);
    let flown = std::panic::catch_unwind(AssertUnwindSafe(|| {
        fly_row(row, instance, setup, &mut result)
    }));
    let error = match flown {
        Ok(Ok(())) => None,
        Ok(Err(e)) => Some(e.to_string()),
        Err(panic) => Some(format!(
            "savsim failed on this row (a bug; please report it): {}",
            crate::batch::run::panic_message(&*panic)
        )),
    };
    result.wall_s = started.elapsed().as_secs_f64();
    result.achieved_speedup = if result.wall_s > 0.0 {
        result.sim_s / result.wall_s
    } else {
        0.0
    };
    match error {
        Some(e) => {
            result.error = Some(e);
            result.outcome = Outcome::Error;
        }
        None => result.judge(),
    }
    result
}

/// The session for a row: its scene, on the vehicle's clock, small-UAS well clear, its feed
/// from its sensors, their errors drawn with `sensor_seed`.
fn session_for(
    row: &StudyRow,
    sensor_seed: u64,
    scene: Arc<Scene>,
    feed: Option<FeedKinds>,
    own: SenderId,
) -> Result<Session, RowError> {
    let savsim = |e: crate::error::Error| RowError::Savsim(e.to_string());
    let sensors = crate::feed::sensors_for(row.sensors.as_deref(), Some(&scene))
        .map_err(|e| input("sensors", e.to_string()))?;
    let mut session =
        Session::new(Some(scene), CollisionConfig::default(), None).map_err(savsim)?;
    // The row's clock is its first vehicle's; the others' are mapped onto it.
    session.use_vehicle_clock_of(Some(own.system_id));
    session.set_approaches(Approaches::with_volume(Some(Volume::SMALL_UAS)));
    if let Some(kinds) = feed {
        session
            .start_feed(FeedConfig {
                kinds,
                hz: FEED_HZ,
                sensors,
                sensor_seed,
                ..FeedConfig::default()
            })
            .map_err(savsim)?;
    }
    Ok(session)
}

/// The file in a row's folder its recording is written to while it flies.
pub const RECORDING: &str = "row.rrd";

/// Record the row's session for the rerun viewer, to [`RECORDING`] in `dir` (made).
#[cfg(feature = "viz")]
fn record_to(session: &mut Session, dir: &Path) -> Result<(), RowError> {
    let savsim = |e: crate::error::Error| RowError::Savsim(e.to_string());
    std::fs::create_dir_all(dir)
        .map_err(|e| RowError::Savsim(format!("{}: {e}", dir.display())))?;
    session.record_to_file(&dir.join(RECORDING)).map_err(savsim)
}

#[cfg(not(feature = "viz"))]
fn record_to(_: &mut Session, _: &Path) -> Result<(), RowError> {
    Err(RowError::Savsim(
        "--rerun-rows: this savsim was built without rerun (feature viz)".into(),
    ))
}

/// The row's scene, with its intruder as a scripted track `intruder`.
fn scene_for(row: &StudyRow, checked: &Checked, setup: &Setup) -> Result<Arc<Scene>, RowError> {
    let scene = setup.scene(row.scene.as_deref())?;
    let Some((kind, waypoints)) = &checked.intruder else {
        return Ok(scene);
    };
    let mut with = (*scene).clone();
    if !with.push_track("intruder", *kind, waypoints.clone()) {
        return Err(input(
            "intruder",
            "the scene has a track named intruder already",
        ));
    }
    Ok(Arc::new(with))
}

/// Home: `en_m` east and north of the scene's origin, on its ground there.
fn home_of(scene: &Scene, [e_m, n_m]: [f64; 2]) -> Geodetic {
    let ground_m = scene.ground_height_enu_m(e_m, n_m).unwrap_or(0.0);
    LocalTangentPlane::new(scene.origin).geodetic_from_enu_m(glam::DVec3::new(e_m, n_m, ground_m))
}

fn fly_row(
    row: &StudyRow,
    instance: u16,
    setup: &Setup,
    result: &mut StudyResult,
) -> Result<(), RowError> {
    let checked = check(row, setup.speedup)?;
    result.speedup = checked.speedup;
    let scene = scene_for(row, &checked, setup)?;
    let own_id = autopilot_id(checked.own.px4, instance, 0);
    let mut session = session_for(row, result.sensor_seed, scene.clone(), checked.feed, own_id)?;
    let runtime = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(1)
        .enable_all()
        .build()
        .map_err(|e| RowError::Savsim(format!("start the network runtime: {e}")))?;
    let dir = setup
        .work
        .join(crate::runs::row_name(result.index, &result.row_id));
    if setup
        .record_rows
        .as_ref()
        .is_some_and(|c| c.records(&result.row_id))
    {
        record_to(&mut session, &dir)?;
    }
    let mut vehicles = start_vehicles(&runtime, setup, &checked, (instance, &scene, &dir))?;
    result.system_id = Some(own_id.system_id);
    // The wall limit: the row's time at its speedup, twice over, and a minute for boot.
    let wall_limit = Duration::from_secs_f64(2.0 * checked.duration_s / checked.speedup + 60.0);
    let collided = Flag::default();
    let options = LiveOptions {
        duration: Some(wall_limit),
        rate_hz: FEED_HZ,
        collided: Some(collided.clone()),
        feed_out: (setup.record_feed && checked.feed.is_some()).then(|| dir.join("feed.tlog")),
        ..LiveOptions::default()
    };
    let links = vehicles.iter_mut().filter_map(|v| v.link.take()).collect();
    let live = SessionThread::spawn(runtime, links, options, session)?;
    let plane = LocalTangentPlane::new(scene.origin);
    let started = Instant::now();
    let own_done = AtomicBool::new(false);
    let stop = || {
        setup.stop.load(Ordering::Relaxed)
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
    let (flown, heard, _) = flown_all
        .next()
        .ok_or_else(|| RowError::Savsim("no vehicle flew".into()))?;
    // Stopped by the wall limit alone (no signal, no collision): the row flew only part of its
    // time, and what it flew is not judged as if it were all of it.
    let cut_short = flown.stopped
        && !setup.stop.load(Ordering::Relaxed)
        && !collided.is_raised()
        && started.elapsed() > wall_limit;
    if cut_short {
        return Err(wall_limit_error(&flown, started, wall_limit, &checked));
    }
    for ((by, flier), id) in flown_all.zip(&checked.others).zip(&ids[1..]) {
        record_other(result, &run, *id, &by, flier);
    }
    record_clocks(result, &run);
    record(
        result,
        &dir,
        run,
        &flown,
        &heard,
        checked.own.px4,
        checked.own.legs.len(),
    )?;
    // What was measured is kept; the row is not judged.
    match result.clock_skew_s {
        Some(skew_s) if skew_s > MAX_CLOCK_SKEW_S => Err(RowError::ClockSkew { skew_s }),
        _ => Ok(()),
    }
}

/// The row's vehicles started: vehicle `k` (from 0) on `instance + k x INSTANCE_OFFSET`, the
/// first in `dir`, the others in `dir/vehicle-K` (K from 2).
fn start_vehicles(
    runtime: &tokio::runtime::Runtime,
    setup: &Setup,
    checked: &Checked,
    (instance, scene, dir): (u16, &Scene, &Path),
) -> Result<Vec<Vehicle>, RowError> {
    let fliers = std::iter::once(&checked.own).chain(&checked.others);
    let mut vehicles = Vec::with_capacity(1 + checked.others.len());
    for (k, flier) in fliers.enumerate() {
        let dir = match k {
            0 => dir.to_path_buf(),
            k => dir.join(format!("vehicle-{}", k + 1)),
        };
        let at = instance + k as u16 * INSTANCE_OFFSET;
        let start = (flier, k, at, checked.speedup);
        vehicles.push(Vehicle::start(runtime, setup, start, scene, &dir)?);
    }
    Ok(vehicles)
}

/// What each vehicle flew; the first failure, as SITL's when its SITL had ended. The SITLs
/// are stopped.
fn flown_by_each(
    vehicles: Vec<Vehicle>,
    flights: Vec<Result<FlownBy, PilotError>>,
) -> Result<Vec<FlownBy>, RowError> {
    vehicles
        .into_iter()
        .zip(flights)
        .map(|(mut v, flight)| {
            let exited = v.sitl.exited();
            flight.map_err(|e| match exited {
                Some(status) => RowError::Sitl(format!(
                    "ended by itself ({status}): {}",
                    v.sitl.log_tail(5)
                )),
                None => RowError::Pilot(e),
            })
        })
        .collect()
}

/// The error of a row its wall-clock limit cut short.
fn wall_limit_error(
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

/// One vehicle of a row: its SITL, its identity, and its link for the session until the
/// session takes it. Its SITL stops when it is dropped.
struct Vehicle {
    sitl: Sitl,
    id: SenderId,
    px4: bool,
    instance: u16,
    link: Option<Link>,
}

impl Vehicle {
    /// Start `flier`'s SITL (the row's vehicle `k`) on `instance` at `speedup` in `dir`, at its
    /// home.
    fn start(
        runtime: &tokio::runtime::Runtime,
        setup: &Setup,
        (flier, k, instance, speedup): (&Flier, usize, u16, f64),
        scene: &Scene,
        dir: &Path,
    ) -> Result<Self, RowError> {
        let start = Start {
            instance,
            home: home_of(scene, flier.home_en_m),
            home_yaw_deg: 0.0,
            speedup,
            serial0: "",
            params: &flier.params,
            dir,
        };
        let (link, sitl) = start_autopilot(runtime, setup, flier.px4, &start)?;
        Ok(Vehicle {
            sitl,
            id: autopilot_id(flier.px4, instance, k),
            px4: flier.px4,
            instance,
            link: Some(link),
        })
    }
}

/// What one vehicle flew: how far, what it said, and the row's clock less its own (s).
type FlownBy = (Flown, Heard, f64);

/// Fly each vehicle's plan with its pilot, the others on threads of their own timed by the
/// first's clock; each vehicle's outcome, in order.
fn fly_all(
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

/// In a row of several: each ArduCopter's speedup kept to one clock ([`crate::study::pace`]):
/// the first PX4's (PX4 SIH's pace cannot be set while it flies), else the first vehicle's.
fn pace(pilots: &mut [Result<Pilot, PilotError>], vehicles: &[Vehicle], speedup: f64) {
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
fn fly_vehicle(
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

/// A vehicle's part of the row after its first (`by`: what it flew and heard, and the row's
/// clock less its own).
fn record_other(
    result: &mut StudyResult,
    run: &LiveRun,
    id: SenderId,
    (flown, heard, offset_s): &FlownBy,
    flier: &Flier,
) {
    let mut did = did(heard, flown, flier.px4);
    did.first_acted_t_s = did.first_acted_t_s.map(|t| t + offset_s);
    let seen = run.session.world().seen.get(&id);
    result.others.push(VehicleResult {
        role: crate::study::result::role(result.others.len() + 1),
        system_id: id.system_id,
        autopilot: if flier.px4 { "px4" } else { "arducopter" }.into(),
        track: heard.track_text_shifted(*offset_s),
        legs_completed: flown.legs_completed as u64,
        plan_completed: flown.legs_completed == flier.legs.len(),
        did,
        clock_speedup: seen.map_or(0.0, |s| s.clock_speedup),
        clock_skew_s: seen.map_or(0.0, |s| s.clock_skew_s),
    });
}

/// In a row of several: the first vehicle's clock's speedup, and the largest skew of another's
/// from it.
fn record_clocks(result: &mut StudyResult, run: &LiveRun) {
    if result.others.is_empty() {
        return;
    }
    let world = run.session.world();
    result.clock_speedup = world
        .timeline_reference()
        .and_then(|r| world.seen.get(&r))
        .map(|s| s.clock_speedup);
    result.clock_skew_s = result
        .others
        .iter()
        .map(|o| o.clock_skew_s)
        .reduce(f64::max);
}

/// A row's session on its own thread (with the row's network runtime), stopped and joined
/// when dropped: no exit from a row leaves the thread, its runtime or its socket behind.
struct SessionThread {
    thread: Option<std::thread::JoinHandle<crate::error::Result<LiveRun>>>,
    shutdown: Arc<AtomicBool>,
}

impl SessionThread {
    fn spawn(
        runtime: tokio::runtime::Runtime,
        links: Vec<Link>,
        options: LiveOptions,
        session: Session,
    ) -> Result<Self, RowError> {
        let shutdown = Arc::new(AtomicBool::new(false));
        let thread = {
            let shutdown = shutdown.clone();
            std::thread::Builder::new()
                .name("savsim-study-session".into())
                .spawn(move || {
                    let handle = runtime.handle().clone();
                    let run = run_links(&handle, links, &options, session, None, shutdown);
                    drop(runtime);
                    run
                })
                .map_err(|e| RowError::Savsim(e.to_string()))?
        };
        Ok(Self {
            thread: Some(thread),
            shutdown,
        })
    }

    /// Stop the session and take its run.
    fn finish(mut self) -> Result<LiveRun, RowError> {
        self.shutdown.store(true, Ordering::Relaxed);
        let failed = || RowError::Savsim("the session thread failed".into());
        self.thread
            .take()
            .ok_or_else(failed)?
            .join()
            .map_err(|_| failed())?
            .map_err(|e| RowError::Savsim(e.to_string()))
    }
}

impl Drop for SessionThread {
    fn drop(&mut self) {
        self.shutdown.store(true, Ordering::Relaxed);
        if let Some(thread) = self.thread.take() {
            let _ = thread.join();
        }
    }
}

/// The row's link for savsim's session and its SITL, started. ArduCopter: savsim listens on a
/// port of its own and SITL's SERIAL0 sends to it. PX4: savsim sends to PX4's GCS link (PX4
/// then answers to savsim's address).
fn start_autopilot(
    runtime: &tokio::runtime::Runtime,
    setup: &Setup,
    px4: bool,
    start: &Start<'_>,
) -> Result<(Link, Sitl), RowError> {
    let savsim = |e: crate::error::Error| RowError::Savsim(e.to_string());
    let loopback = |port: u16| std::net::SocketAddr::from(([127, 0, 0, 1], port));
    if px4 {
        let px4 = setup.px4.as_ref().ok_or_else(|| {
            RowError::NoAutopilot("no PX4 SITL: give --px4 PATH or set SAVSIM_PX4".into())
        })?;
        let sitl = px4
            .start_at_home(start)
            .map_err(|e| RowError::Sitl(e.to_string()))?;
        let address = ConnectAddress::UdpOut(loopback(px4_gcs_port(start.instance)).into());
        let link = runtime.block_on(Link::open(&address)).map_err(savsim)?;
        return Ok((link, sitl));
    }
    let arducopter = setup.arducopter.as_ref().ok_or_else(|| {
        RowError::NoAutopilot(
            "no ArduCopter SITL: give --arducopter PATH or set SAVSIM_ARDUCOPTER".into(),
        )
    })?;
    let link = runtime
        .block_on(Link::open(&ConnectAddress::UdpIn(loopback(0).into())))
        .map_err(savsim)?;
    let port = link
        .local_addr()
        .map(|a| a.port())
        .ok_or_else(|| RowError::Savsim("the row's UDP link has no port".into()))?;
    let serial0 = format!("udpclient:127.0.0.1:{port}");
    let sitl = arducopter
        .start(&Start {
            serial0: &serial0,
            ..start.clone()
        })
        .map_err(|e| RowError::Sitl(format!("start {}: {e}", arducopter.binary.display())))?;
    Ok((link, sitl))
}

/// The pilot on the vehicle's port, within a minute; an error at once if SITL ends first or
/// a signal stops the study.
fn connect_pilot(
    vehicle: &mut Vehicle,
    plane: LocalTangentPlane,
    stop: &AtomicBool,
) -> Result<Result<Pilot, PilotError>, RowError> {
    if vehicle.px4 {
        // PX4's onboard link: the pilot listens where PX4 sends, and sends where it listens.
        let (listens, sends) = px4_onboard_ports(vehicle.instance);
        return Ok(Pilot::udp(sends, listens, vehicle.id, plane));
    }
    let sitl = &mut vehicle.sitl;
    let started = Instant::now();
    loop {
        if stop.load(Ordering::Relaxed) {
            return Err(RowError::Savsim("stopped by a signal".into()));
        }
        if let Some(status) = sitl.exited() {
            return Err(RowError::Sitl(format!(
                "ended by itself ({status}): {}",
                sitl.log_tail(3)
            )));
        }
        let within = Duration::from_millis(500);
        match Pilot::connect(sitl.pilot_port, vehicle.id, plane, within) {
            Ok(pilot) => return Ok(Ok(pilot)),
            Err(e) if started.elapsed() > Duration::from_secs(60) => return Ok(Err(e)),
            Err(_) => {}
        }
    }
}

/// Fill in what the session measured and what the autopilot did.
fn record(
    result: &mut StudyResult,
    dir: &Path,
    mut run: LiveRun,
    flown: &Flown,
    heard: &Heard,
    px4: bool,
    legs: usize,
) -> Result<(), RowError> {
    run.ended.map_err(|e| RowError::Savsim(e.to_string()))?;
    let feed_latency = run.report.feed.as_ref().and_then(|f| f.latency);
    result.feed_latency_p99_us = feed_latency.map(|l| l.p99_us);
    result.feed_latency_max_us = feed_latency.map(|l| l.max_us);
    run.session
        .finish()
        .map_err(|e| RowError::Savsim(e.to_string()))?;
    let session = &run.session;
    // The session's own summary beside SITL's files (kept with --keep-work).
    let _ = crate::session::write_json_atomic(
        &dir.join("summary.json"),
        &session.summary("study", &result.row_id),
    );
    if let Some(pipeline) = session.pipeline() {
        let t0_s = -session.elapsed_s(0.0).unwrap_or(0.0);
        result.measured.record_run(
            pipeline.totals(),
            session.digest(),
            session.approaches(),
            session.tick_costs(),
            t0_s,
        );
    }
    result.record_obstacles(session.digest());
    result.feed_frames = session
        .feed()
        .map_or(0, |f| f.counts().map(|(_, c)| c.frames).sum());
    if let Some(feed) = session.feed() {
        result.told = feed
            .told()
            .fold(crate::feed::Told::default(), |all, (_, _, t)| all.and(&t));
    }
    result.armed_t_s = flown.armed_t_s;
    result.legs_completed = flown.legs_completed as u64;
    result.plan_completed = flown.legs_completed == legs;
    result.sim_s = f64::from(flown.last_ms) / 1000.0;
    result.autopilot_did = did(heard, flown, px4);
    result.track = heard.track_text();
    Ok(())
}

/// What the autopilot did, from what it said.
fn did(heard: &Heard, flown: &Flown, px4: bool) -> AutopilotDid {
    let since = |ms: u32| f64::from(ms) / 1000.0;
    let avoid_mode = heard
        .modes
        .iter()
        .find(|(_, m)| *m == mode::AVOID_ADSB)
        .map(|(t, _)| since(*t));
    let collision = heard.first_collision_ms.map(since);
    let first_acted_t_s = [avoid_mode, collision, flown.slowed_t_s]
        .into_iter()
        .flatten()
        .reduce(f64::min);
    AutopilotDid {
        modes: heard
            .modes
            .iter()
            .map(|(_, m)| {
                if px4 {
                    px4_mode_name(*m)
                } else {
                    arducopter_mode_name(*m)
                }
            })
            .collect(),
        collision_messages: heard.collision_messages,
        avoidance_texts: heard.avoidance_texts.clone(),
        avoidance_texts_not_kept: heard.avoidance_texts_not_kept,
        first_acted_t_s,
        version: heard.version.clone(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The threads of this process whose name starts with `prefix` (names are cut at 15
    /// bytes by the kernel).
    fn threads_named(prefix: &str) -> usize {
        std::fs::read_dir("/proc/self/task")
            .map(|tasks| {
                tasks
                    .filter_map(|t| std::fs::read_to_string(t.ok()?.path().join("comm")).ok())
                    .filter(|name| name.starts_with(prefix))
                    .count()
            })
            .unwrap_or(0)
    }

    fn others_of(autopilots: &str, plans: &str, params: &str, homes: &str) -> Vec<Flier> {
        let some = |t: &str| (!t.is_empty()).then(|| t.to_string());
        let row = StudyRow {
            intruder_autopilot: some(autopilots),
            intruder_plan: some(plans),
            intruder_params: some(params),
            intruder_home: some(homes),
            ..StudyRow::default()
        };
        check_others(&row).unwrap_or_else(|e| panic!("{autopilots}: {e}"))
    }

    fn others_error(autopilots: &str, plans: &str, homes: &str) -> String {
        let row = StudyRow {
            intruder_autopilot: Some(autopilots.into()),
            intruder_plan: Some(plans.into()),
            intruder_home: Some(homes.into()),
            ..StudyRow::default()
        };
        check_others(&row)
            .err()
            .map(|e| e.to_string())
            .unwrap_or_default()
    }

    /// A row's vehicles after its first, one per name in `intruder_autopilot`: each column one
    /// entry for all or one each; each ArduCopter its own system id after the row's params.
    #[test]
    fn each_vehicle_after_the_first_takes_its_own_entry_or_the_one_for_all() {
        let two = others_of(
            "arducopter | px4",
            "takeoff 20|takeoff 30; hold 5",
            "AVD_ENABLE=1",
            "0 100|-50 0",
        );
        assert_eq!(two.len(), 2);
        assert!(!two[0].px4 && two[1].px4);
        assert_eq!((two[0].legs.len(), two[1].legs.len()), (1, 2));
        assert_eq!(
            (two[0].home_en_m, two[1].home_en_m),
            ([0.0, 100.0], [-50.0, 0.0])
        );
        // The one entry of params for both; the ArduCopter's system id last, PX4 none.
        assert_eq!(
            two[0].params,
            [
                ("AVD_ENABLE".to_string(), 1.0),
                ("SYSID_THISMAV".to_string(), 201.0)
            ]
        );
        assert_eq!(two[1].params, [("AVD_ENABLE".to_string(), 1.0)]);
        let both_copters = others_of("arducopter|arducopter", "takeoff 20", "", "");
        let sysids: Vec<f64> = both_copters
            .iter()
            .map(|f| f.params.last().unwrap().1)
            .collect();
        assert_eq!(sysids, [201.0, 202.0]);
        assert_eq!(both_copters[1].home_en_m, [0.0, 0.0]);
        // Counts that do not match, too many vehicles, a bad name: the column says so.
        let three_plans = others_error("arducopter|px4", "takeoff 1|takeoff 2|takeoff 3", "");
        assert!(
            three_plans.contains("intruder_plan: 3 entries for 2 vehicles"),
            "{three_plans}"
        );
        let homes = others_error("arducopter|px4", "takeoff 1", "0 0|1 1|2 2");
        assert!(homes.contains("intruder_home"), "{homes}");
        let four = others_error("arducopter|px4|arducopter", "takeoff 1", "");
        assert!(four.contains("at most 3 in all"), "{four}");
        let empty = others_error("arducopter|", "takeoff 1", "");
        assert!(empty.contains("intruder_autopilot: \"\""), "{empty}");
        // The identities a row of three gives: no two alike, whatever the job's instance.
        for instance in [0u16, 63] {
            for px4 in [
                [false, false, false],
                [true, true, true],
                [false, true, false],
            ] {
                let ids: std::collections::BTreeSet<u8> = (0..MAX_VEHICLES)
                    .map(|k| {
                        let at = instance + k as u16 * INSTANCE_OFFSET;
                        autopilot_id(px4[k], at, k).system_id
                    })
                    .collect();
                assert_eq!(ids.len(), MAX_VEHICLES, "{instance} {px4:?}");
            }
        }
    }

    /// 20 rows whose SITL dies at boot: each ends as an error row, and none leaves its session
    /// thread (with its runtime and socket) behind until its wall limit.
    #[test]
    #[cfg(target_os = "linux")]
    fn rows_whose_sitl_dies_at_boot_leave_no_session_thread() {
        use std::os::unix::fs::PermissionsExt;
        let dir = tempfile::tempdir().unwrap();
        let fake = dir.path().join("arducopter");
        std::fs::write(&fake, "#!/bin/sh\necho 'PANIC: no eeprom'\nexit 1\n").unwrap();
        std::fs::set_permissions(&fake, std::fs::Permissions::from_mode(0o755)).unwrap();
        let row = StudyRow {
            plan: Some("takeoff 10".into()),
            duration_s: Some(600.0),
            ..StudyRow::default()
        };
        let setup = Setup::new(
            std::slice::from_ref(&row),
            (
                Some(ArduCopter {
                    binary: fake,
                    defaults: Vec::new(),
                }),
                None,
            ),
            1.0,
            dir.path().join("work"),
            Arc::new(AtomicBool::new(false)),
        );
        let before = threads_named("savsim-study");
        for k in 0..20 {
            let result = run_row(k, &row, 40 + k as u16, &setup);
            assert_eq!(result.outcome, Outcome::Error, "{:?}", result.error);
            assert!(
                result
                    .error
                    .as_deref()
                    .unwrap_or("")
                    .contains("ended by itself"),
                "{:?}",
                result.error
            );
        }
        assert_eq!(threads_named("savsim-study"), before);
    }
}
