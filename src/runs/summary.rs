//! What a directory of shards adds up to, for `batch summarize` and `study summarize` alike:
//! per variant, how many rows ended each way and the weighted collision, NMAC and
//! loss-of-well-clear rates; per variant against the nominal one, the risk ratios over the pairs
//! flown under both (`savsim_core::daa::ratios`: percentile-bootstrap intervals, undefined
//! resamples unbounded, a repeated pair as the share of its flights). Rows that failed are
//! counted (`error`) and left out of the rates.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use arrow_array::{Array, BooleanArray, Float64Array, RecordBatch, UInt64Array};
use serde_json::json;

use crate::error::Result;
use crate::runs::table::{column, for_each_batch};

use crate::daa::ratios::{
    rates, ratios, Estimate, Outcome, VariantRates, VariantRatios, RESAMPLES,
};

/// Which risk ratio `--converge-on` judges.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum Ratio {
    /// P(NMAC | variant) / P(NMAC | nominal).
    Nmac,
    /// The same for loss of well clear.
    Lowc,
    /// The same for collisions.
    Collision,
}

impl Ratio {
    /// The ratios judged unless `--converge-on` says otherwise.
    pub const DEFAULT: [Ratio; 2] = [Ratio::Nmac, Ratio::Lowc];
    /// Every ratio, in the order reports give them.
    pub const ALL: [Ratio; 3] = [Ratio::Collision, Ratio::Nmac, Ratio::Lowc];

    /// Its name and its estimate in `r`.
    pub fn of(self, r: &VariantRatios) -> (&'static str, &Estimate) {
        match self {
            Ratio::Nmac => ("NMAC", &r.nmac_ratio),
            Ratio::Lowc => ("LoWC", &r.lowc_ratio),
            Ratio::Collision => ("collision", &r.collision_ratio),
        }
    }
}

/// One row as a report shows it: who it is, how it ended, what it measured (`None` where the
/// shard has no such column or the row no value).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct RowView {
    /// The row's index in its manifest.
    pub index: u64,
    /// `row_id` (study) or `run_id` (batch).
    pub id: String,
    /// The variant (`nominal` when the row names none).
    pub variant: String,
    /// The pair (the row's id when it names none).
    pub pair: String,
    /// How it ended: `collision`, `nmac`, `soft_fail`, `pass` or `error`.
    pub ended: String,
    /// Closest approach to traffic, metres.
    pub cpa_m: Option<f64>,
    /// Closest approach to a scene obstacle, metres.
    pub closest_obstacle_m: Option<f64>,
    /// When the autopilot first acted (study), seconds on the row's timeline.
    pub first_acted_t_s: Option<f64>,
    /// Simulated seconds per wall-clock second (study).
    pub achieved_speedup: Option<f64>,
    /// Wall-clock seconds the row took.
    pub wall_s: Option<f64>,
    /// Why it failed, for `error` rows.
    pub error: Option<String>,
    /// The autopilot's version, as it told it (study).
    pub autopilot_version: Option<String>,
    /// The scene file the row named (study).
    pub scene: Option<String>,
    /// The vehicle's track, `t_s e_m n_m u_m; ...` (study).
    pub vehicle_track: Option<String>,
    /// The intruder's track as the row gave it (study).
    pub intruder: Option<String>,
    /// When the closest approach to traffic happened, seconds on the row's timeline.
    pub cpa_t_s: Option<f64>,
    /// When the first collision happened, seconds on the row's timeline.
    pub first_collision_t_s: Option<f64>,
}

impl RowView {
    /// Whether the row is worth a look: it did not pass in a variant other than `nominal`,
    /// or passed in `nominal` (where the event was meant to happen), or failed to run.
    pub fn worth_a_look(&self, nominal: &str) -> bool {
        (self.variant == nominal) == (self.ended == "pass") || self.ended == "error"
    }
}

/// The rows of a directory of shards, as the summary needs them.
#[derive(Debug, Default)]
pub struct Summary {
    /// Rows that ran.
    pub outcomes: Vec<Outcome>,
    /// Every row read, in file and row order.
    pub rows: Vec<RowView>,
    /// Per variant: how many rows ended each way (`collision`, `nmac`, `pass`, `error`, and
    /// the command's own: `soft_fail`).
    pub counts: BTreeMap<String, BTreeMap<String, u64>>,
    /// The shard files read.
    pub files: Vec<PathBuf>,
}

impl Summary {
    /// Take one row and (when it ran) its outcome.
    pub fn add(&mut self, row: RowView, outcome: Option<Outcome>) {
        *self
            .counts
            .entry(row.variant.clone())
            .or_default()
            .entry(row.ended.clone())
            .or_default() += 1;
        self.outcomes.extend(outcome);
        self.rows.push(row);
    }

    /// Rows that failed (`error`), in every variant.
    pub fn failed(&self) -> u64 {
        self.counts.values().filter_map(|c| c.get("error")).sum()
    }

    /// The summary as JSON: `files`, `rows` (that ran), `failed`, `nominal`, `interval`,
    /// `outcomes` (counts per variant), `variants` (rates), `ratios` (against `nominal`; a
    /// null bound is unbounded).
    pub fn json(&self, nominal: &str) -> serde_json::Value {
        json!({
            "files": self.files.len(),
            "rows": self.outcomes.len(),
            "failed": self.failed(),
            "nominal": nominal,
            "interval": format!("95% percentile bootstrap over pairs, {RESAMPLES} resamples"),
            "outcomes": self.counts,
            "variants": rates(&self.outcomes),
            "ratios": ratios(&self.outcomes, nominal),
        })
    }

    /// Print the summary: JSON (`json`) or text.
    pub fn print(&self, nominal: &str, json: bool) {
        if json {
            let value = serde_json::to_string_pretty(&self.json(nominal)).unwrap_or_default();
            println!("{value}");
        } else {
            print!("{}", self.text(nominal, 3));
        }
    }

    /// The summary for a person at a terminal, numbers to `decimals` places.
    pub fn text(&self, nominal: &str, decimals: usize) -> String {
        let (rates, ratios) = (rates(&self.outcomes), ratios(&self.outcomes, nominal));
        self.text_of(&rates, &ratios, nominal, decimals)
    }

    /// [`Summary::text`] from rates and ratios already computed (the bootstrap is the cost).
    pub fn text_of(
        &self,
        rates: &[VariantRates],
        ratios: &[VariantRatios],
        nominal: &str,
        decimals: usize,
    ) -> String {
        let e = |x: &crate::daa::ratios::Estimate| x.text(decimals);
        let mut text = format!(
            "{} rows ran, {} failed (left out), from {} files; 95% intervals: bootstrap over pairs\n",
            self.outcomes.len(),
            self.failed(),
            self.files.len()
        );
        for (variant, counts) in &self.counts {
            let list: Vec<String> = counts.iter().map(|(k, n)| format!("{k} {n}")).collect();
            text += &format!("  {variant:<12} {}\n", list.join(", "));
        }
        for r in rates {
            text += &format!(
                "  {:<12} collision rate {}   NMAC rate {}   LoWC rate {}\n",
                r.variant,
                e(&r.collision_rate),
                e(&r.nmac_rate),
                e(&r.lowc_rate)
            );
        }
        for r in ratios {
            text += &format!(
                "  {} / {nominal}: {} pairs   collision ratio {}   NMAC ratio {}   LoWC ratio {}\n",
                r.variant,
                r.pairs,
                e(&r.collision_ratio),
                e(&r.nmac_ratio),
                e(&r.lowc_ratio)
            );
        }
        text
    }
}
/// Every `*.parquet` of `dir`, each record batch read into one summary by `read_batch` (a
/// command's own columns).
pub fn read_dir(
    dir: &Path,
    mut read_batch: impl FnMut(&RecordBatch, &Path, &mut Summary) -> Result<()>,
) -> Result<Summary> {
    let mut all = Summary::default();
    all.files = for_each_batch(dir, |batch, path| read_batch(batch, path, &mut all))?;
    Ok(all)
}

/// The columns a row's outcome is read from, the same in batch and study results: `w`, `nmac`,
/// `lowc`, `collisions`.
pub struct OutcomeColumns<'a> {
    w: &'a Float64Array,
    nmac: &'a BooleanArray,
    lowc: &'a BooleanArray,
    collisions: &'a UInt64Array,
}

impl<'a> OutcomeColumns<'a> {
    /// The columns of `batch` (read from `path`); an error names a missing one.
    pub fn of(batch: &'a RecordBatch, path: &Path) -> Result<Self> {
        Ok(Self {
            w: column::<Float64Array>(batch, "w", path)?,
            nmac: column::<BooleanArray>(batch, "nmac", path)?,
            lowc: column::<BooleanArray>(batch, "lowc", path)?,
            collisions: column::<UInt64Array>(batch, "collisions", path)?,
        })
    }

    /// Row `i`'s outcome, for the pair and variant `row` names (weight 1 when it has none).
    pub fn at(&self, row: &RowView, i: usize) -> Outcome {
        Outcome {
            pair: row.pair.clone(),
            variant: row.variant.clone(),
            weight: if self.w.is_valid(i) {
                self.w.value(i)
            } else {
                1.0
            },
            nmac: self.nmac.value(i),
            lowc: self.lowc.value(i),
            collision: self.collisions.value(i) > 0,
        }
    }
}
