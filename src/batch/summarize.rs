//! `savsim batch summarize DIR`: a results directory's shards read into a
//! [`Summary`]. A row ended with an `error`, a `collision`
//! (any), an `nmac`, else `pass`; the rates and ratios count NMAC, loss of well clear and
//! collisions.

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
    let bools = |name: &str| column::<BooleanArray>(batch, name, path);
    let (run_id, variant, pair, error) = (
        strings("run_id")?,
        strings("variant")?,
        strings("pair")?,
        strings("error")?,
    );
    let w = column::<Float64Array>(batch, "w", path)?;
    let (nmac, lowc) = (bools("nmac")?, bools("lowc")?);
    let collisions = column::<UInt64Array>(batch, "collisions", path)?;
    for i in 0..batch.num_rows() {
        let variant = text_or(variant, i, "nominal");
        if error.is_valid(i) {
            all.add(&variant, "error", None);
            continue;
        }
        let outcome = Outcome {
            pair: text_or(pair, i, run_id.value(i)),
            variant: variant.clone(),
            weight: if w.is_valid(i) { w.value(i) } else { 1.0 },
            nmac: nmac.value(i),
            lowc: lowc.value(i),
            collision: collisions.value(i) > 0,
        };
        let ended = if outcome.collision {
            "collision"
        } else if outcome.nmac {
            "nmac"
        } else {
            "pass"
        };
        all.add(&variant, ended, Some(outcome));
    }
    Ok(())
}
