//! `savsim batch summarize DIR`: weighted NMAC and loss-of-well-clear rates per variant, and
//! each variant's risk ratios against the nominal one over the pairs flown under both, with
//! 95% bootstrap intervals (savsim_core::daa::ratios), from the shards' Parquet files.

use std::fs::File;
use std::path::{Path, PathBuf};

use arrow_array::{Array, BooleanArray, Float64Array, RecordBatch, StringArray};
use parquet::arrow::arrow_reader::ParquetRecordBatchReaderBuilder;
use serde_json::json;

use crate::daa::ratios::{rates, ratios, Estimate, Outcome};
use crate::error::{Error, Result};

/// What the shards of a directory hold, for summarizing.
#[derive(Debug, Default)]
pub struct Outcomes {
    /// Rows that ran.
    pub outcomes: Vec<Outcome>,
    /// Rows that failed (left out).
    pub failed: usize,
    /// The shard files read.
    pub files: Vec<PathBuf>,
}

/// Read every `*.parquet` in `dir`.
pub fn read_dir(dir: &Path) -> Result<Outcomes> {
    let mut all = Outcomes::default();
    all.files = for_each_batch(dir, |batch, path| read_batch(batch, path, &mut all))?;
    Ok(all)
}

/// Call `f` on every record batch of every `*.parquet` file in `dir` (in name order); the
/// files read. No such file is an error.
pub(crate) fn for_each_batch(
    dir: &Path,
    mut f: impl FnMut(&RecordBatch, &Path) -> Result<()>,
) -> Result<Vec<PathBuf>> {
    let mut files: Vec<PathBuf> = std::fs::read_dir(dir)
        .map_err(|e| Error::file(dir, e))?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|x| x == "parquet"))
        .collect();
    files.sort();
    if files.is_empty() {
        return Err(Error::Usage(format!(
            "{}: no .parquet shard files in it",
            dir.display()
        )));
    }
    for path in &files {
        let bad = |e: parquet::errors::ParquetError| Error::file(path, std::io::Error::other(e));
        let file = File::open(path).map_err(|e| Error::file(path, e))?;
        let reader = ParquetRecordBatchReaderBuilder::try_new(file)
            .map_err(bad)?
            .build()
            .map_err(bad)?;
        for batch in reader {
            let batch = batch.map_err(|e| Error::file(path, std::io::Error::other(e)))?;
            f(&batch, path)?;
        }
    }
    Ok(files)
}

/// Column `name` of `batch` as an array of type `T`; an error naming it when it is missing or
/// of another type.
pub(crate) fn column<'a, T: 'static>(
    batch: &'a RecordBatch,
    name: &str,
    path: &Path,
) -> Result<&'a T> {
    batch
        .column_by_name(name)
        .and_then(|c| c.as_any().downcast_ref::<T>())
        .ok_or_else(|| Error::Usage(format!("{}: no column {name} of its type", path.display())))
}

fn read_batch(batch: &RecordBatch, path: &Path, all: &mut Outcomes) -> Result<()> {
    let strings = |name: &str| column::<StringArray>(batch, name, path);
    let bools = |name: &str| column::<BooleanArray>(batch, name, path);
    let (run_id, variant, pair, error) = (
        strings("run_id")?,
        strings("variant")?,
        strings("pair")?,
        strings("error")?,
    );
    let w = column::<Float64Array>(batch, "w", path)?;
    let (nmac, lowc) = (bools("nmac")?, bools("lowc")?);
    let collisions = column::<arrow_array::UInt64Array>(batch, "collisions", path)?;
    for i in 0..batch.num_rows() {
        if error.is_valid(i) {
            all.failed += 1;
            continue;
        }
        let text = |a: &StringArray, default: &str| {
            if a.is_valid(i) {
                a.value(i).to_string()
            } else {
                default.to_string()
            }
        };
        all.outcomes.push(Outcome {
            pair: text(pair, run_id.value(i)),
            variant: text(variant, "nominal"),
            weight: if w.is_valid(i) { w.value(i) } else { 1.0 },
            nmac: nmac.value(i),
            lowc: lowc.value(i),
            collision: collisions.value(i) > 0,
        });
    }
    Ok(())
}

/// The summary as JSON: rates per variant, ratios against `nominal`.
pub fn summary_json(all: &Outcomes, nominal: &str) -> serde_json::Value {
    json!({
        "files": all.files.len(),
        "runs": all.outcomes.len(),
        "failed": all.failed,
        "nominal": nominal,
        "interval": format!("95% percentile bootstrap over pairs, {} resamples", crate::daa::ratios::RESAMPLES),
        "variants": rates(&all.outcomes),
        "ratios": ratios(&all.outcomes, nominal),
    })
}

/// The summary for a person at a terminal.
pub fn summary_text(all: &Outcomes, nominal: &str) -> String {
    let e = |x: &Estimate| x.text(4);
    let mut text = format!(
        "{} runs from {} files ({} failed, left out); 95% intervals: bootstrap over pairs\n",
        all.outcomes.len(),
        all.files.len(),
        all.failed
    );
    for r in rates(&all.outcomes) {
        text += &format!(
            "  {:<12} {:>7} runs   NMAC rate {}   LoWC rate {}\n",
            r.variant,
            r.encounters,
            e(&r.nmac_rate),
            e(&r.lowc_rate)
        );
    }
    for r in ratios(&all.outcomes, nominal) {
        text += &format!(
            "  {} / {nominal}: {} pairs   NMAC ratio {}   LoWC ratio {}\n",
            r.variant,
            r.pairs,
            e(&r.nmac_ratio),
            e(&r.lowc_ratio)
        );
    }
    text
}
