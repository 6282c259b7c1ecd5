//! `savsim study summarize DIR`: per variant the outcome counts and the weighted collision,
//! NMAC and loss-of-well-clear rates; each variant against the nominal one over the pairs
//! flown under both (the risk ratios), with 95% percentile-bootstrap intervals over pairs
//! (savsim_core::daa::ratios); rows whose `outcome` is `error` are left out and counted.

use std::path::Path;

use arrow_array::{Array, BooleanArray, Float64Array, RecordBatch, StringArray, UInt64Array};

use crate::daa::ratios::Outcome;
use crate::error::Result;
use crate::runs::summary::Summary;
use crate::runs::table::{column, for_each_batch, text_or};

/// Read every `*.parquet` in `dir`.
pub fn read_dir(dir: &Path) -> Result<Summary> {
    let mut all = Summary::default();
    all.files = for_each_batch(dir, |batch, path| read_batch(batch, path, &mut all))?;
    Ok(all)
}

fn read_batch(batch: &RecordBatch, path: &Path, all: &mut Summary) -> Result<()> {
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
        let variant = text_or(variant, i, "nominal");
        let ended = text_or(outcome, i, "error");
        let flew = (ended != "error").then(|| Outcome {
            pair: text_or(pair, i, row_id.value(i)),
            variant: variant.clone(),
            weight: if w.is_valid(i) { w.value(i) } else { 1.0 },
            nmac: nmac.value(i),
            lowc: lowc.value(i),
            collision: collisions.value(i) > 0,
        });
        all.add(&variant, &ended, flew);
    }
    Ok(())
}
