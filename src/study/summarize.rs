//! `savsim study summarize DIR`: per variant the outcome counts and the weighted collision,
//! NMAC and loss-of-well-clear rates; each variant against the nominal one over the pairs
//! flown under both (the risk ratios), with 95% percentile-bootstrap intervals over pairs
//! (savsim_core::daa::ratios); rows whose `outcome` is `error` are left out and counted.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use arrow_array::{Array, BooleanArray, Float64Array, RecordBatch, StringArray, UInt64Array};
use serde_json::json;

use crate::batch::summarize::{column, for_each_batch};
use crate::daa::ratios::{rates, ratios, Estimate, Outcome};
use crate::error::Result;

/// What a study's shards hold.
#[derive(Debug, Default)]
pub struct StudyOutcomes {
    /// Rows that flew.
    pub outcomes: Vec<Outcome>,
    /// Per variant: how many rows ended each way (`pass`, `soft_fail`, `collision`, `nmac`,
    /// `error`).
    pub counts: BTreeMap<String, BTreeMap<String, u64>>,
    /// The shard files read.
    pub files: Vec<PathBuf>,
}

/// Read every `*.parquet` in `dir`.
pub fn read_dir(dir: &Path) -> Result<StudyOutcomes> {
    let mut all = StudyOutcomes::default();
    all.files = for_each_batch(dir, |batch, path| read_batch(batch, path, &mut all))?;
    Ok(all)
}

fn read_batch(batch: &RecordBatch, path: &Path, all: &mut StudyOutcomes) -> Result<()> {
    let strings = |name: &str| column::<StringArray>(batch, name, path);
    let (row_id, variant, pair, outcome) = (
        strings("row_id")?,
        strings("variant")?,
        strings("pair")?,
        strings("outcome")?,
    );
    let w = column::<Float64Array>(batch, "w", path)?;
    let (nmac, lowc) = (
        column::<BooleanArray>(batch, "nmac", path)?,
        column::<BooleanArray>(batch, "lowc", path)?,
    );
    let collisions = column::<UInt64Array>(batch, "collisions", path)?;
    for i in 0..batch.num_rows() {
        let text = |a: &StringArray, default: &str| {
            if a.is_valid(i) {
                a.value(i).to_string()
            } else {
                default.to_string()
            }
        };
        let variant = text(variant, "nominal");
        let ended = text(outcome, "error");
        *all.counts
            .entry(variant.clone())
            .or_default()
            .entry(ended.clone())
            .or_default() += 1;
        if ended == "error" {
            continue;
        }
        all.outcomes.push(Outcome {
            pair: text(pair, row_id.value(i)),
            variant,
            weight: if w.is_valid(i) { w.value(i) } else { 1.0 },
            nmac: nmac.value(i),
            lowc: lowc.value(i),
            collision: collisions.value(i) > 0,
        });
    }
    Ok(())
}

/// The summary as JSON.
pub fn summary_json(all: &StudyOutcomes, nominal: &str) -> serde_json::Value {
    json!({
        "files": all.files.len(),
        "rows": all.outcomes.len(),
        "nominal": nominal,
        "interval": format!("95% percentile bootstrap over pairs, {} resamples", crate::daa::ratios::RESAMPLES),
        "outcomes": all.counts,
        "variants": rates(&all.outcomes),
        "ratios": ratios(&all.outcomes, nominal),
    })
}

/// The summary for a person at a terminal.
pub fn summary_text(all: &StudyOutcomes, nominal: &str) -> String {
    let e = |x: &Estimate| x.text(3);
    let mut text = format!(
        "{} rows flown, from {} files; 95% intervals: bootstrap over pairs\n",
        all.outcomes.len(),
        all.files.len()
    );
    for (variant, counts) in &all.counts {
        let list: Vec<String> = counts.iter().map(|(k, n)| format!("{k} {n}")).collect();
        text += &format!("  {variant:<12} {}\n", list.join(", "));
    }
    for r in rates(&all.outcomes) {
        text += &format!(
            "  {:<12} collision rate {}   NMAC rate {}   LoWC rate {}\n",
            r.variant,
            e(&r.collision_rate),
            e(&r.nmac_rate),
            e(&r.lowc_rate)
        );
    }
    for r in ratios(&all.outcomes, nominal) {
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
