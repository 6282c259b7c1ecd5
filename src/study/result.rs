//! One study row's result: its inputs, its outcome, what savsim measured (as a batch row
//! does), and what the autopilot did.

use serde::Serialize;

use crate::collision::digest::EventDigest;
use crate::runs::measured::Measured;
use crate::study::manifest::StudyRow;

/// Closest approach to an obstacle below this without a collision is a soft fail, metres (the
/// UAV Testing Competition's mark).
pub const SOFT_FAIL_M: f64 = 1.5;

/// How a row ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Outcome {
    /// It hit something.
    Collision,
    /// No collision; an NMAC with a moving body.
    Nmac,
    /// Neither; within [`SOFT_FAIL_M`] of an obstacle.
    SoftFail,
    /// None of those.
    Pass,
    /// The row could not be flown (bad input, a SITL that did not boot, hung or died).
    Error,
}

impl Outcome {
    /// Its name in the results.
    pub fn name(self) -> &'static str {
        match self {
            Outcome::Collision => "collision",
            Outcome::Nmac => "nmac",
            Outcome::SoftFail => "soft_fail",
            Outcome::Pass => "pass",
            Outcome::Error => "error",
        }
    }
}

/// The closest a row came to one obstacle (within the near-miss band, 10 m).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ObstacleApproach {
    /// The obstacle's id.
    pub obstacle: String,
    /// Least distance, metres (0 at a collision).
    pub closest_m: f64,
}

/// What the autopilot did, as it said over MAVLink.
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct AutopilotDid {
    /// The modes it entered, in order, by name (ArduCopter's).
    pub modes: Vec<String>,
    /// COLLISION messages it sent.
    pub collision_messages: u64,
    /// Its STATUSTEXT about avoidance (avoid, ADS-B, proximity, obstacle, fence), in order,
    /// repeats of the one before left out: the first 100.
    pub avoidance_texts: Vec<String>,
    /// Avoidance STATUSTEXTs past those 100, counted.
    pub avoidance_texts_not_kept: u64,
    /// When it first acted, seconds of its clock (from its boot): AVOID_ADSB
    /// entered (PX4: AUTO.RTL or AUTO.LAND, its traffic avoidance's answers), a COLLISION sent, or (proximity avoidance, which says nothing) its speed along
    /// the commanded velocity fell under half of it after reaching 80% of it.
    pub first_acted_t_s: Option<f64>,
    /// AUTOPILOT_VERSION: `major.minor.patch (git hash)`.
    pub version: Option<String>,
}

/// One vehicle of a row, as the `vehicles` column gives it: its times are on the row's clock
/// (the first vehicle's, from its boot).
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct VehicleResult {
    /// Its [`role`].
    pub role: String,
    /// Its MAVLink system id.
    pub system_id: u8,
    /// Its autopilot (`arducopter` or `px4`).
    pub autopilot: String,
    /// Its positions, as `track` (times on the row's clock).
    pub track: Option<String>,
    /// Legs of its plan flown to their end.
    pub legs_completed: u64,
    /// Whether every leg was.
    pub plan_completed: bool,
    /// What its autopilot did (`first_acted_t_s` on the row's clock).
    pub did: AutopilotDid,
    /// Seconds of its clock per wall second, as savsim fitted them from its positions'
    /// arrivals (measured).
    pub clock_speedup: f64,
    /// The largest drift of its clock from the row's (the first vehicle's), seconds
    /// (measured; 0 for the first).
    pub clock_skew_s: f64,
    /// With savsim's physics: its estimate of its position against the truth.
    pub estimate: Option<crate::lockstep::estimates::ErrorStats>,
}

/// The name of a row's vehicle `k` (from 0, in the manifest's order) in the results: `own`,
/// `intruder` (the second), `intruder3`, ... (the third and on, by their place in the row).
///
/// ```
/// use savsim::study::result::role;
/// assert_eq!([role(0), role(1), role(2)], ["own", "intruder", "intruder3"]);
/// ```
pub fn role(k: usize) -> String {
    match k {
        0 => "own".into(),
        1 => "intruder".into(),
        k => format!("intruder{}", k + 1),
    }
}

/// Which of a row's vehicles acted first (by [`AutopilotDid::first_acted_t_s`] on the row's
/// clock, in the manifest's order): its [`role`]; `neither` when none did. A tie goes to the
/// vehicle listed first.
///
/// ```
/// use savsim::study::result::first_to_act;
/// assert_eq!(first_to_act(&[Some(3.0), Some(2.0)]), "intruder");
/// assert_eq!(first_to_act(&[Some(2.0), Some(2.0), None]), "own");
/// assert_eq!(first_to_act(&[None, None, Some(9.0)]), "intruder3");
/// assert_eq!(first_to_act(&[None, None]), "neither");
/// ```
pub fn first_to_act(acted_t_s: &[Option<f64>]) -> String {
    let first = acted_t_s
        .iter()
        .enumerate()
        .filter_map(|(k, t)| Some((k, (*t)?)))
        .reduce(|a, b| if b.1 < a.1 { b } else { a });
    first.map_or_else(|| "neither".into(), |(k, _)| role(k))
}

/// One row of a study's results.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct StudyResult {
    /// The row's position in the (expanded) manifest, from 0.
    pub index: u64,
    /// Its id.
    pub row_id: String,
    /// The row as the manifest gave it (the scene path anchored).
    pub inputs: StudyRow,
    /// The seed its sensor errors were drawn with ([`StudyRow::sensor_seed_or`]).
    pub sensor_seed: u64,
    /// The autopilot flown.
    pub autopilot: String,
    /// Its MAVLink system id, once the row's SITLs started.
    pub system_id: Option<u8>,
    /// The speedup asked of SITL.
    pub speedup: f64,
    /// How it ended.
    pub outcome: Outcome,
    /// Why it failed, when `outcome` is `error`.
    pub error: Option<String>,
    /// What savsim measured, as a batch row (collisions, near misses, NMAC, closest
    /// approaches to moving bodies, well clear), times in seconds of the vehicle's clock
    /// from its boot.
    pub measured: Measured,
    /// The closest approach to each obstacle within the near-miss band.
    pub obstacles: Vec<ObstacleApproach>,
    /// The closest of them, metres.
    pub closest_obstacle_m: Option<f64>,
    /// The vehicle's positions as it sent them, every half second of its clock and its last:
    /// `t_s e_m n_m u_m; ...` in the scene's frame, as an intruder's track is written.
    pub track: Option<String>,
    /// When it was armed (GUIDED), seconds of its clock: SITL's boot until then is time the
    /// row spends before its plan.
    pub armed_t_s: Option<f64>,
    /// Legs of the plan flown to their end.
    pub legs_completed: u64,
    /// Whether every leg was.
    pub plan_completed: bool,
    /// What the autopilot did.
    pub autopilot_did: AutopilotDid,
    /// Feed frames sent to the vehicle.
    pub feed_frames: u64,
    /// What the vehicle was told of other aircraft by its modelled sensors (all of them
    /// together; none with `ideal` sensors).
    pub told: crate::feed::Told,
    /// The position's datagram received -> its feed frame handed to the link, wall
    /// microseconds: 99th percentile and largest (measured). At speedup S a wall microsecond is
    /// S microseconds of the vehicle's clock: how stale its sensors were.
    pub feed_latency_p99_us: Option<u64>,
    /// The largest.
    pub feed_latency_max_us: Option<u64>,
    /// Seconds of the vehicle's clock (from its boot) at its last position.
    pub sim_s: f64,
    /// Wall seconds of the row, SITL's start and stop included (measured).
    pub wall_s: f64,
    /// `sim_s` over the wall seconds it took (measured).
    pub achieved_speedup: f64,
    /// The row's vehicles after its first, in the manifest's order, when it flies several
    /// autopilots.
    pub others: Vec<VehicleResult>,
    /// With several autopilots: seconds of the first vehicle's clock per wall second, as
    /// savsim fitted them from its positions' arrivals (measured).
    pub clock_speedup: Option<f64>,
    /// With several autopilots: the largest drift of another vehicle's clock from the row's
    /// (the first's) over the row, seconds (measured; the row is an error beyond
    /// [`crate::study::row::MAX_CLOCK_SKEW_S`]). 0 in lockstep: one clock for all.
    pub clock_skew_s: Option<f64>,
    /// Who flew the vehicles: `autopilot` (each SITL its own physics) or `savsim` (lockstep).
    pub physics: String,
    /// With savsim's physics: the frame flown.
    pub frame: Option<String>,
    /// With savsim's physics: the physics step, milliseconds.
    pub step_ms: Option<f64>,
    /// With savsim's physics: the first vehicle's estimate of its position against the truth
    /// (each GLOBAL_POSITION_INT it sent, at its instant).
    pub estimate: Option<crate::lockstep::estimates::ErrorStats>,
    /// With savsim's physics: where the row's wall time went (measured).
    pub lockstep_times: Option<crate::lockstep::driver::LoopTimes>,
    /// Frames its companion was handed (docs/companion.md).
    pub companion_calls: Option<u64>,
    /// Commands its companion sent.
    pub companion_commands: Option<u64>,
    /// The 99th percentile of the companion's round trips (frame out, commands back), wall
    /// milliseconds.
    pub companion_p99_ms: Option<f64>,
    /// Instants its companion was not handed a frame because it was still on the last (rows
    /// on SITL's own physics; none in lockstep, where every instant waits).
    pub companion_skipped: Option<u64>,
}

impl StudyResult {
    /// What the row's companion did.
    pub fn record_companion(&mut self, c: &crate::companion::slot::CompanionCounts) {
        self.companion_calls = Some(c.calls);
        self.companion_commands = Some(c.commands);
        self.companion_p99_ms = c.p99_ms();
    }

    /// A result with `row`'s inputs and nothing flown yet.
    pub fn of_inputs(index: usize, row: &StudyRow) -> Self {
        StudyResult {
            index: index as u64,
            row_id: row.id_or(index),
            inputs: row.clone(),
            sensor_seed: row.sensor_seed_or(index),
            autopilot: row.autopilot.clone().unwrap_or_else(|| "arducopter".into()),
            system_id: None,
            speedup: 0.0,
            outcome: Outcome::Error,
            error: None,
            measured: Measured::default(),
            obstacles: Vec::new(),
            closest_obstacle_m: None,
            track: None,
            armed_t_s: None,
            legs_completed: 0,
            plan_completed: false,
            autopilot_did: AutopilotDid::default(),
            told: crate::feed::Told::default(),
            feed_frames: 0,
            feed_latency_p99_us: None,
            feed_latency_max_us: None,
            sim_s: 0.0,
            wall_s: 0.0,
            achieved_speedup: 0.0,
            others: Vec::new(),
            clock_speedup: None,
            clock_skew_s: None,
            physics: row.physics.clone().unwrap_or_else(|| "autopilot".into()),
            frame: None,
            step_ms: None,
            estimate: None,
            lockstep_times: None,
            companion_calls: None,
            companion_commands: None,
            companion_p99_ms: None,
            companion_skipped: None,
        }
    }

    /// Every vehicle the row flew, the first and [`Self::others`] (none when its SITLs did not
    /// all start).
    pub fn vehicles(&self) -> Vec<VehicleResult> {
        let Some(system_id) = self.system_id else {
            return Vec::new();
        };
        let own = VehicleResult {
            role: role(0),
            system_id,
            autopilot: self.autopilot.clone(),
            track: self.track.clone(),
            legs_completed: self.legs_completed,
            plan_completed: self.plan_completed,
            did: self.autopilot_did.clone(),
            clock_speedup: self.clock_speedup.unwrap_or(0.0),
            clock_skew_s: 0.0,
            estimate: self.estimate,
        };
        std::iter::once(own)
            .chain(self.others.iter().cloned())
            .collect()
    }

    /// With several autopilots, which acted first ([`first_to_act`]).
    pub fn first_to_act(&self) -> Option<String> {
        if self.others.is_empty() {
            return None;
        }
        let acted: Vec<Option<f64>> = std::iter::once(self.autopilot_did.first_acted_t_s)
            .chain(self.others.iter().map(|o| o.did.first_acted_t_s))
            .collect();
        Some(first_to_act(&acted))
    }

    /// The closest approach to each obstacle, from every collision (0 m) and near miss of
    /// the run.
    pub fn record_obstacles(&mut self, digest: &EventDigest) {
        self.obstacles = digest
            .closest_by_obstacle()
            .map(|(obstacle, closest_m)| ObstacleApproach {
                obstacle: obstacle.to_owned(),
                closest_m,
            })
            .collect();
        self.closest_obstacle_m = self.obstacles.iter().map(|c| c.closest_m).reduce(f64::min);
    }

    /// The outcome of a row that flew: collision, else NMAC, else soft fail, else pass.
    pub fn judge(&mut self) {
        self.outcome = if self.measured.collisions > 0 {
            Outcome::Collision
        } else if self.measured.nmac {
            Outcome::Nmac
        } else if self.closest_obstacle_m.is_some_and(|m| m < SOFT_FAIL_M) {
            Outcome::SoftFail
        } else {
            Outcome::Pass
        };
    }
}
