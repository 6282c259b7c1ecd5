//! One run's result: its inputs as the manifest gave them, what happened (what savsim measured:
//! `runs::measured`), what it cost.

use serde::Serialize;

use crate::batch::manifest::Run;
use crate::codec::stats::IngestStats;
use crate::collision::digest::EventDigest;
use crate::daa::approach::Approaches;
use crate::pipeline::PipelineTotals;
use crate::runs::measured::Measured;

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
    /// What the run's collision pipeline and approaches found.
    #[serde(flatten)]
    pub measured: Measured,
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
        } else if self.measured.collisions > 0 {
            "collision"
        } else if self.measured.nmac {
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
            measured: Measured::default(),
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
        self.measured.record(totals, digest, approaches, t0_s);
        let (median_us, p99_us) = tick_costs.percentiles_us();
        self.tick_cost_us_median = median_us;
        self.tick_cost_us_p99 = p99_us;
    }

    /// Add an input's ingest counters.
    pub fn record_ingest(&mut self, stats: &IngestStats) {
        self.messages += stats.messages_total();
        self.bad_frames += stats.bad_frames();
        self.rejected += stats.rejected_total();
    }
}
