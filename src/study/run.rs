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
use crate::study::result::{AutopilotDid, Outcome, SecondVehicle, StudyResult};
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
/// A row's second vehicle runs on SITL instance `instance + SECOND_INSTANCE_OFFSET` (its own
/// ports): past the instances `--jobs` can take.
pub const SECOND_INSTANCE_OFFSET: u16 = crate::study::command::MAX_JOBS as u16;
/// A second ArduCopter's SYSID_THISMAV: no PX4 instance of a study has it (PX4 SITL's system id
/// is its instance + 1, at most 2 x `MAX_JOBS`).
pub const SECOND_ARDUCOPTER_SYSID: u8 = 201;
/// The largest drift allowed between the clocks of a row's two vehicles, seconds: beyond it
/// the row is an error. Each vehicle is placed in the world where it was when it sent its
/// position, whatever its clock; but a clock ahead by 0.2 s has flown its physics 0.2 s
/// further: two copters closing at 2 x 12 m/s (the fastest `study gen --equipage` draws) then
/// meet up to 4.8 m off the encounter drawn (docs/study.md, "Two autopilots").
pub const MAX_CLOCK_SKEW_S: f64 = 0.2;

/// The autopilot's identity: ArduCopter SITL's default SYSID_THISMAV 1 (whatever its
/// instance; a row's second ArduCopter [`SECOND_ARDUCOPTER_SYSID`]); PX4 SITL sets MAV_SYS_ID
/// to its instance + 1. Component 1, the autopilot.
fn autopilot_id(px4: bool, instance: u16, second: bool) -> SenderId {
    if px4 {
        px4_autopilot(instance)
    } else {
        SenderId {
            system_id: if second { SECOND_ARDUCOPTER_SYSID } else { 1 },
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
    /// The clocks of the row's two vehicles drifted apart by more than
    /// [`MAX_CLOCK_SKEW_S`]: where each was at a given moment is not known well enough.
    #[error(
        "the two vehicles' clocks drifted {skew_s:.3} s apart (at most {MAX_CLOCK_SKEW_S} s): \
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
    second: Option<Flier>,
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

/// The row's second vehicle (`intruder_autopilot` and its columns), when it has one.
fn check_second(row: &StudyRow) -> Result<Option<Flier>, RowError> {
    fn given(v: &Option<String>) -> Option<&str> {
        v.as_deref().filter(|t| !t.trim().is_empty())
    }
    let Some(autopilot) = given(&row.intruder_autopilot) else {
        if given(&row.intruder_plan).is_some() || given(&row.intruder_params).is_some() {
            return Err(input(
                "intruder_autopilot",
                "intruder_plan and intruder_params are for a second autopilot: name it",
            ));
        }
        return Ok(None);
    };
    if given(&row.intruder).is_some() {
        return Err(input(
            "intruder_autopilot",
            "give a scripted intruder or an autopilot, not both",
        ));
    }
    let px4 = is_px4("intruder_autopilot", autopilot)?;
    let legs = plan::parse(given(&row.intruder_plan).unwrap_or_default())
        .map_err(|e| input("intruder_plan", e.to_string()))?;
    let mut params = plan::parse_params(given(&row.intruder_params).unwrap_or_default())
        .map_err(|why| input("intruder_params", why))?;
    if !px4 {
        // Last, so that it holds over the row's own: the session tells the two apart by it.
        params.push(("SYSID_THISMAV".into(), f64::from(SECOND_ARDUCOPTER_SYSID)));
    }
    let home_en_m = match given(&row.intruder_home) {
        None => [0.0, 0.0],
        Some(text) => parse_home(text).map_err(|why| input("intruder_home", why))?,
    };
    Ok(Some(Flier {
        px4,
        legs,
        params,
        home_en_m,
    }))
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
    let second = check_second(row)?;
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
        second,
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
/// from its sensors.
fn session_for(
    row: &StudyRow,
    scene: Arc<Scene>,
    feed: Option<FeedKinds>,
    own: SenderId,
) -> Result<Session, RowError> {
    let savsim = |e: crate::error::Error| RowError::Savsim(e.to_string());
    let sensors = crate::feed::sensors_for(row.sensors.as_deref(), Some(&scene))
        .map_err(|e| input("sensors", e.to_string()))?;
    let mut session =
        Session::new(Some(scene), CollisionConfig::default(), None).map_err(savsim)?;
    // The row's clock is its first vehicle's; a second one's is mapped onto it.
    session.use_vehicle_clock_of(Some(own.system_id));
    session.set_approaches(Approaches::with_volume(Some(Volume::SMALL_UAS)));
    if let Some(kinds) = feed {
        session
            .start_feed(FeedConfig {
                kinds,
                hz: FEED_HZ,
                sensors,
                sensor_seed: row.sensor_seed.or(row.seed).unwrap_or(1),
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
    let own_id = autopilot_id(checked.own.px4, instance, false);
    let mut session = session_for(row, scene.clone(), checked.feed, own_id)?;
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
    // The second vehicle also stops when the first is done.
    let second_stop = || stop() || own_done.load(Ordering::Relaxed);
    // Every exit from here on, `?` included, stops and joins the session thread (its drop).
    let mut pilots = Vec::new();
    for v in &mut vehicles {
        pilots.push(connect_pilot(v, plane, &setup.stop)?);
    }
    let flights = fly_all(
        pilots,
        &vehicles,
        &checked,
        (&stop, &second_stop),
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
    let second = flown_all
        .next()
        .zip(checked.second.as_ref())
        .zip(ids.get(1));
    if let Some((((flown, heard, offset_s), flier), id)) = second {
        record_second(result, &run, *id, (&flown, &heard, offset_s), flier);
    }
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

/// The row's vehicles started: the first on `instance` in `dir`, a second (if any) on
/// `instance + SECOND_INSTANCE_OFFSET` in `dir/second`.
fn start_vehicles(
    runtime: &tokio::runtime::Runtime,
    setup: &Setup,
    checked: &Checked,
    (instance, scene, dir): (u16, &Scene, &Path),
) -> Result<Vec<Vehicle>, RowError> {
    let speedup = checked.speedup;
    let mut vehicles = vec![Vehicle::start(
        runtime,
        setup,
        (&checked.own, instance, speedup),
        scene,
        dir,
    )?];
    if let Some(second) = &checked.second {
        let at = instance + SECOND_INSTANCE_OFFSET;
        let dir = dir.join("second");
        vehicles.push(Vehicle::start(
            runtime,
            setup,
            (second, at, speedup),
            scene,
            &dir,
        )?);
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
    /// Start `flier`'s SITL on `instance` at `speedup` in `dir`, at its home.
    fn start(
        runtime: &tokio::runtime::Runtime,
        setup: &Setup,
        (flier, instance, speedup): (&Flier, u16, f64),
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
        let second = instance >= SECOND_INSTANCE_OFFSET;
        Ok(Vehicle {
            sitl,
            id: autopilot_id(flier.px4, instance, second),
            px4: flier.px4,
            instance,
            link: Some(link),
        })
    }
}

/// What one vehicle flew: how far, what it said, and the row's clock less its own (s).
type FlownBy = (Flown, Heard, f64);

/// Fly each vehicle's plan with its pilot, the second (if any) on a thread of its own timed
/// by the first's clock; each vehicle's outcome, in order.
fn fly_all(
    pilots: Vec<Result<Pilot, PilotError>>,
    vehicles: &[Vehicle],
    checked: &Checked,
    (stop, second_stop): (&(dyn Fn() -> bool + Sync), &(dyn Fn() -> bool + Sync)),
    own_done: &AtomicBool,
) -> Vec<Result<FlownBy, PilotError>> {
    let mut pilots = pilots.into_iter();
    let Some(mut own_pilot) = pilots.next() else {
        return Vec::new();
    };
    let mut second_pilot = pilots.next();
    let reference = own_pilot.as_ref().ok().map(|p| p.heard.clone());
    pace(
        &mut own_pilot,
        second_pilot.as_mut(),
        vehicles,
        checked.speedup,
    );
    std::thread::scope(|scope| {
        let second = second_pilot
            .zip(checked.second.as_ref())
            .map(|(pilot, flier)| {
                let px4 = vehicles.get(1).is_some_and(|v| v.px4);
                let clock = reference.clone().map(|reference| RowClock {
                    reference,
                    speedup: checked.speedup,
                });
                scope.spawn(move || {
                    let mut pilot = pilot?;
                    pilot.row_clock = clock;
                    fly_vehicle(pilot, flier, px4, checked.duration_s, second_stop)
                })
            });
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
        let joined = second.map(|h| {
            h.join()
                .unwrap_or_else(|_| Err(PilotError::Send("the second pilot failed".into())))
        });
        std::iter::once(own).chain(joined).collect()
    })
}

/// In a row of two: an ArduCopter's speedup kept to the other's clock ([`crate::study::pace`]):
/// the second's when it is an ArduCopter, else the first's when it is one.
fn pace(
    own: &mut Result<Pilot, PilotError>,
    second: Option<&mut Result<Pilot, PilotError>>,
    vehicles: &[Vehicle],
    speedup: f64,
) {
    let (Ok(own), Some(Ok(second))) = (own, second) else {
        return;
    };
    let px4 = |k: usize| vehicles.get(k).is_none_or(|v| v.px4);
    if !px4(1) {
        second.pace = Some(Pace::new(own.heard.clone(), speedup));
    } else if !px4(0) {
        own.pace = Some(Pace::new(second.heard.clone(), speedup));
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

/// The second vehicle's part of the row, and the skew between the two clocks.
fn record_second(
    result: &mut StudyResult,
    run: &LiveRun,
    id: SenderId,
    (flown, heard, offset_s): (&Flown, &Heard, f64),
    flier: &Flier,
) {
    let mut did = did(heard, flown, flier.px4);
    did.first_acted_t_s = did.first_acted_t_s.map(|t| t + offset_s);
    result.second = Some(SecondVehicle {
        system_id: id.system_id,
        track: heard.track_text_shifted(offset_s),
        legs_completed: flown.legs_completed as u64,
        plan_completed: flown.legs_completed == flier.legs.len(),
        did,
        clock_speedup: 0.0,
    });
    let seen = &run.session.world().seen;
    let speedup = |id: &SenderId| seen.get(id).map_or(0.0, |s| s.clock_speedup);
    let skew_s = seen.get(&id).map_or(0.0, |s| s.clock_skew_s);
    if let Some(second) = result.second.as_mut() {
        second.clock_speedup = speedup(&id);
    }
    result.clock_speedup = run
        .session
        .world()
        .timeline_reference()
        .map(|r| speedup(&r));
    result.clock_skew_s = Some(skew_s);
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
