//! One run's result: its inputs as the manifest gave them, what happened, what it cost.

use serde::Serialize;

use crate::batch::manifest::Run;
use crate::collision::approach::Approaches;
use crate::collision::digest::EventDigest;
use crate::ingest::stats::IngestStats;
use crate::pipeline::PipelineTotals;

/// The closest approach of one vehicle to one moving body.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ApproachRow {
    /// The vehicle (MAVLink system id; 1 for an encounter's ownship).
    pub vehicle: u8,
    /// The other track's id (`intruder`, `vehicle:2`, `icao:4840D6`, a scene's track).
    pub track: String,
    /// Least separation of the two reference points, metres.
    pub distance_m: f64,
    /// Horizontal separation then, metres.
    pub horizontal_m: f64,
    /// Vertical separation then (other above the vehicle positive), metres.
    pub vertical_m: f64,
    /// When, seconds after the run's start.
    pub t_s: f64,
    /// Ever within 500 ft horizontally and 100 ft vertically at once.
    pub nmac: bool,
    /// Well clear with this track ever lost (false when it is not judged).
    pub lowc: bool,
}

/// One row of the results table. Every field but the three measured costs
/// (`tick_cost_us_median`, `tick_cost_us_p99`, `wall_s`) is the same on every run of the same
/// manifest, whatever the jobs, the sharding, or the caller (CLI or Python).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct RunRow {
    /// The row's position in the manifest (from 0).
    pub index: u64,
    /// The run's id.
    pub run_id: String,
    /// `tlog` or `encounter` (empty when the row says neither).
    pub kind: String,
    /// The run as the manifest gave it (paths anchored to the manifest's directory).
    pub inputs: Run,
    /// The seed its sensor errors were drawn with ([`Run::sensor_seed_or`]).
    pub sensor_seed: u64,
    /// Collision mode, resolved (`exact` when the row names none).
    pub mode: String,
    /// Why the run failed (then the results below are empty).
    pub error: Option<String>,
    /// Collision ticks (vehicle samples).
    pub ticks: u64,
    /// Collisions reported.
    pub collisions: u64,
    /// Time of impact of the first, seconds after the start.
    pub first_collision_t_s: Option<f64>,
    /// What it hit.
    pub first_collision_obstacle: Option<String>,
    /// Near misses reported.
    pub near_misses: u64,
    /// The closest of them, metres.
    pub closest_near_miss_m: Option<f64>,
    /// Any NMAC with any moving body.
    pub nmac: bool,
    /// The closest approach to any moving body, metres.
    pub cpa_m: Option<f64>,
    /// Its horizontal part.
    pub cpa_horizontal_m: Option<f64>,
    /// Its vertical part.
    pub cpa_vertical_m: Option<f64>,
    /// Its time, seconds after the start.
    pub cpa_t_s: Option<f64>,
    /// The body it was with.
    pub cpa_track: Option<String>,
    /// The closest approach to each moving body.
    pub approaches: Vec<ApproachRow>,
    /// Any loss of well clear with any moving body (the volume the run judged with; small UAS,
    /// 2000 ft / 250 ft, by default).
    pub lowc: bool,
    /// When the first began, seconds after the start.
    pub lowc_first_t_s: Option<f64>,
    /// Total time without well clear, over every moving body, seconds.
    pub lowc_duration_s: f64,
    /// Least modified tau seen while closing with any moving body, seconds.
    pub min_taumod_s: Option<f64>,
    /// Least horizontal separation within a loss of well clear, metres.
    pub lowc_min_horizontal_m: Option<f64>,
    /// Least vertical separation within a loss of well clear, metres.
    pub lowc_min_vertical_m: Option<f64>,
    /// MAVLink messages read (tlog inputs).
    pub messages: u64,
    /// Frames rejected by CRC, unknown id or flags.
    pub bad_frames: u64,
    /// Decoded values rejected as implausible.
    pub rejected: u64,
    /// Median tick cost, microseconds (measured: varies run to run).
    pub tick_cost_us_median: f64,
    /// 99th percentile tick cost, microseconds (measured).
    pub tick_cost_us_p99: f64,
    /// Wall time of the run, seconds (measured).
    pub wall_s: f64,
    /// Alerting on the sensed states (rows with `daa_conf`).
    pub sensed: Option<crate::batch::sensed::SensedAlerting>,
}

impl RunRow {
    /// How the row ended, as `batch summarize` counts it: `error`, `collision`, `nmac` or
    /// `pass`.
    pub fn ended(&self) -> &'static str {
        if self.error.is_some() {
            "error"
        } else if self.collisions > 0 {
            "collision"
        } else if self.nmac {
            "nmac"
        } else {
            "pass"
        }
    }

    /// A row with `run`'s inputs and no results yet.
    pub fn of_inputs(index: usize, run: &Run, mode: &str) -> Self {
        let kind = match (&run.tlog, &run.own, &run.daa) {
            (Some(_), _, _) => "tlog",
            (None, Some(_), _) | (None, None, Some(_)) => "encounter",
            (None, None, None) => "",
        };
        RunRow {
            index: index as u64,
            run_id: run.id_or(index),
            kind: kind.into(),
            inputs: run.clone(),
            sensor_seed: run.sensor_seed_or(index),
            mode: mode.into(),
            error: None,
            ticks: 0,
            collisions: 0,
            first_collision_t_s: None,
            first_collision_obstacle: None,
            near_misses: 0,
            closest_near_miss_m: None,
            nmac: false,
            cpa_m: None,
            cpa_horizontal_m: None,
            cpa_vertical_m: None,
            cpa_t_s: None,
            cpa_track: None,
            approaches: Vec::new(),
            lowc: false,
            lowc_first_t_s: None,
            lowc_duration_s: 0.0,
            min_taumod_s: None,
            lowc_min_horizontal_m: None,
            lowc_min_vertical_m: None,
            messages: 0,
            bad_frames: 0,
            rejected: 0,
            tick_cost_us_median: 0.0,
            tick_cost_us_p99: 0.0,
            wall_s: 0.0,
            sensed: None,
        }
    }

    /// Fill in what a run found: its pipeline's totals, what its events add up to, its
    /// closest approaches and its tick costs (nanoseconds); times become seconds after `t0_s`.
    pub fn record_run(
        &mut self,
        totals: &PipelineTotals,
        digest: &EventDigest,
        approaches: &Approaches,
        tick_costs: &crate::costs::TickCosts,
        t0_s: f64,
    ) {
        self.ticks = totals.ticks;
        self.collisions = totals.collisions;
        self.near_misses = totals.near_misses;
        if let Some((t, obstacle)) = digest.first_collision() {
            self.first_collision_t_s = Some(t - t0_s);
            self.first_collision_obstacle = Some(obstacle.to_owned());
        }
        self.closest_near_miss_m = digest.closest_near_miss_m();
        self.record_approaches(approaches, t0_s);
        self.record_well_clear(approaches, t0_s);
        let (median_us, p99_us) = tick_costs.percentiles_us();
        self.tick_cost_us_median = median_us;
        self.tick_cost_us_p99 = p99_us;
    }

    /// Every approach, the closest of them, and whether any was an NMAC.
    fn record_approaches(&mut self, approaches: &Approaches, t0_s: f64) {
        self.approaches = approaches
            .pairs()
            .into_iter()
            .map(|(vehicle, pair)| ApproachRow {
                vehicle,
                track: pair.id.to_string(),
                distance_m: pair.approach.distance_m,
                horizontal_m: pair.approach.horizontal_m,
                vertical_m: pair.approach.vertical_m,
                t_s: pair.approach.t_s - t0_s,
                nmac: pair.approach.nmac,
                lowc: !pair.well_clear.episodes.is_empty(),
            })
            .collect();
        self.nmac = self.approaches.iter().any(|a| a.nmac);
        // The closest; the first listed on a tie (the list is in a fixed order).
        let closest =
            self.approaches
                .iter()
                .reduce(|a, b| if b.distance_m < a.distance_m { b } else { a });
        if let Some(c) = closest {
            self.cpa_m = Some(c.distance_m);
            self.cpa_horizontal_m = Some(c.horizontal_m);
            self.cpa_vertical_m = Some(c.vertical_m);
            self.cpa_t_s = Some(c.t_s);
            self.cpa_track = Some(c.track.clone());
        }
    }

    /// Losses of well clear over every pair: whether any, the first, their total length, and
    /// the least modified tau and separations.
    fn record_well_clear(&mut self, approaches: &Approaches, t0_s: f64) {
        let pairs = approaches.pairs();
        let logs = || pairs.iter().map(|(_, pair)| &pair.well_clear);
        let episodes = || logs().flat_map(|l| l.episodes.iter());
        self.lowc = episodes().next().is_some();
        self.lowc_first_t_s = episodes().map(|e| e.start_t_s - t0_s).reduce(f64::min);
        self.lowc_duration_s = logs().map(|l| l.duration_s()).sum();
        self.min_taumod_s = logs().filter_map(|l| l.min_tau_mod_s).reduce(f64::min);
        self.lowc_min_horizontal_m = episodes().map(|e| e.min_horizontal_m).reduce(f64::min);
        self.lowc_min_vertical_m = episodes().map(|e| e.min_vertical_m).reduce(f64::min);
    }

    /// Add an input's ingest counters.
    pub fn record_ingest(&mut self, stats: &IngestStats) {
        self.messages += stats.messages_total();
        self.bad_frames += stats.bad_frames();
        self.rejected += stats.rejected_total();
    }
}
