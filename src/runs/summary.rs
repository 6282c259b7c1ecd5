//! What a directory of shards adds up to, for `batch summarize` and `study summarize` alike:
//! per variant, how many rows ended each way and the weighted collision, NMAC and
//! loss-of-well-clear rates; per variant against the nominal one, the risk ratios over the pairs
//! flown under both (`savsim_core::daa::ratios`: percentile-bootstrap intervals, undefined
//! resamples unbounded, a repeated pair as the share of its flights). Rows that failed are
//! counted (`error`) and left out of the rates.

use std::collections::BTreeMap;
use std::path::PathBuf;

use serde_json::json;

use crate::daa::ratios::{rates, ratios, Outcome, RESAMPLES};

/// The rows of a directory of shards, as the summary needs them.
#[derive(Debug, Default)]
pub struct Summary {
    /// Rows that ran.
    pub outcomes: Vec<Outcome>,
    /// Per variant: how many rows ended each way (`collision`, `nmac`, `pass`, `error`, and
    /// the command's own: `soft_fail`).
    pub counts: BTreeMap<String, BTreeMap<String, u64>>,
    /// The shard files read.
    pub files: Vec<PathBuf>,
}

impl Summary {
    /// Take one row: its variant, how it ended, and (when it ran) its outcome.
    pub fn add(&mut self, variant: &str, ended: &str, outcome: Option<Outcome>) {
        *self
            .counts
            .entry(variant.to_owned())
            .or_default()
            .entry(ended.to_owned())
            .or_default() += 1;
        self.outcomes.extend(outcome);
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
        for r in rates(&self.outcomes) {
            text += &format!(
                "  {:<12} collision rate {}   NMAC rate {}   LoWC rate {}\n",
                r.variant,
                e(&r.collision_rate),
                e(&r.nmac_rate),
                e(&r.lowc_rate)
            );
        }
        for r in ratios(&self.outcomes, nominal) {
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
