//! One study row, end to end: its inputs checked, its scene (with its intruder) loaded, its
//! SITL started on its own instance and folder, savsim's session on SITL's SERIAL0 with the
//! row's feed, the pilot flying the plan on SERIAL1, and everything stopped at the end. Any
//! failure (a bad column, a SITL that does not boot, hangs or dies, even a bug) becomes the
//! row's `error`; the study goes on.

mod check;
mod fly;
pub mod ids;
mod lockstep;
mod record;
mod session;
mod vehicles;

pub use check::HomeError;
use fly::fly_row;
pub use ids::{arducopter_sysid, INSTANCE_OFFSET, MAX_JOBS, MAX_VEHICLES};
pub use session::{home_of as home_on_ground, RECORDING};

use std::panic::AssertUnwindSafe;
use std::path::PathBuf;
use std::sync::atomic::AtomicBool;
use std::sync::Arc;
use std::time::Instant;

use crate::runs::recordings::RowChoice;
use crate::runs::scenes::{SceneCache, SceneLookup};
use crate::scene::Scene;
use crate::study::manifest::StudyRow;
use crate::study::pilot::PilotError;
use crate::study::plan::PlanError;
use crate::study::result::{Outcome, StudyResult};
use crate::study::sitl::{ArduCopter, Px4};

/// A row's default length, seconds of the vehicle's clock.
pub const DEFAULT_DURATION_S: f64 = 120.0;
/// The speedups a row may ask of SITL.
pub const SPEEDUP_RANGE: (f64, f64) = (0.1, 1000.0);
/// The feed's rate in a study, Hz of the vehicle's clock, and the rate positions are asked for
/// on the session's link (the feed is cast at each position). ArduCopter stops a copter at 5-8
/// m/s within a frame or two of seeing the obstacle closer than its margin: at 20 Hz a frame is
/// 0.25-0.4 m of travel, at 50 Hz 0.1-0.16 m.
pub const FEED_HZ: f64 = 50.0;
/// The largest drift allowed between the clocks of a row's vehicles, seconds: beyond it
/// the row is an error. Each vehicle is placed in the world where it was when it sent its
/// position, whatever its clock; but a clock ahead by 0.2 s has flown its physics 0.2 s
/// further: two copters closing at 2 x 12 m/s (the fastest `study gen --equipage` draws) then
/// meet up to 4.8 m off the encounter drawn (docs/study.md, "Several autopilots").
pub const MAX_CLOCK_SKEW_S: f64 = 0.2;

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
    /// A column of parameters (`params`, `intruder_params`).
    #[error("{column}: {source}")]
    Params {
        /// The column.
        column: &'static str,
        /// What is wrong.
        source: crate::study::plan::ParamError,
    },
    /// A vehicle's home (`intruder_home`).
    #[error("{column}: {source}")]
    Home {
        /// The column.
        column: &'static str,
        /// What is wrong.
        source: check::HomeError,
    },
    /// The row's scene did not load.
    #[error("scene: {0}")]
    Scene(SceneLookup),
    /// The autopilot's binary is not there: which, and the flag and variable that name it.
    #[error("no {autopilot} SITL: give --{flag} PATH or set {variable}")]
    NoAutopilot {
        /// `ArduCopter` or `PX4`.
        autopilot: &'static str,
        /// Its flag.
        flag: &'static str,
        /// Its environment variable.
        variable: &'static str,
    },
    /// SITL could not start.
    #[error("SITL: start {}: {source}", binary.display())]
    SitlStart {
        /// The binary.
        binary: PathBuf,
        /// What the system said.
        source: std::io::Error,
    },
    /// PX4 SITL could not start.
    #[error("SITL: {0}")]
    Px4Start(#[from] crate::study::sitl::Px4StartError),
    /// SITL ended by itself: its status and the end of its log.
    #[error("SITL: ended by itself ({status}): {log}")]
    SitlEnded {
        /// How it ended.
        status: std::process::ExitStatus,
        /// Its log's last lines.
        log: String,
    },
    /// The pilot.
    #[error("{0}")]
    Pilot(#[from] PilotError),
    /// savsim's side (the scene, the session, the link).
    #[error("savsim: {0}")]
    Savsim(#[from] crate::error::Error),
    /// The row's network runtime could not start.
    #[error("savsim: start the network runtime: {0}")]
    Runtime(std::io::Error),
    /// A folder of the row's could not be made.
    #[error("savsim: {}: {source}", path.display())]
    Folder {
        /// The folder.
        path: PathBuf,
        /// What the system said.
        source: std::io::Error,
    },
    /// The row's session thread could not start, or failed.
    #[error("savsim: the session thread failed")]
    SessionThread,
    /// The row's UDP link has no port.
    #[error("savsim: the row's UDP link has no port")]
    NoLinkPort,
    /// No vehicle of the row flew.
    #[error("savsim: no vehicle flew")]
    NoVehicle,
    /// A signal stopped the study.
    #[error("savsim: stopped by a signal")]
    Stopped,
    /// The row's companion.
    #[error("{0}")]
    Companion(#[from] crate::companion::link::CompanionError),
    /// The row's companion, beside SITL's own physics (its error, said).
    #[error("{0}")]
    Planner(String),
    /// A lockstep row's ports or SITL.
    #[error("savsim: lockstep: {0}")]
    Lockstep(#[from] crate::study::sitl_lockstep::LockstepStartError),
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

/// Fly row `index` on SITL instance `instance`.
pub fn run_row(index: usize, row: &StudyRow, instance: u16, setup: &Setup) -> StudyResult {
    let started = Instant::now();
    let mut result = StudyResult::of_inputs(index, row);
    let flown = std::panic::catch_unwind(AssertUnwindSafe(|| {
        match row.physics.as_deref().map(str::trim) {
            None | Some("" | "autopilot") => fly_row(row, instance, setup, &mut result),
            Some("savsim") => lockstep::fly_lockstep_row(row, instance, setup, &mut result),
            Some(other) => Err(input(
                "physics",
                format!("{other:?}: give autopilot or savsim"),
            )),
        }
    }));
    let error = match flown {
        Ok(Ok(())) => None,
        Ok(Err(e)) => Some(e.to_string()),
        Err(panic) => Some(format!(
            "savsim failed on this row (a bug; please report it): {}",
            crate::runs::panic_message(&*panic)
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

#[cfg(test)]
mod tests {
    use super::check::{check_others, Flier};
    use super::ids::autopilot_id;
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
