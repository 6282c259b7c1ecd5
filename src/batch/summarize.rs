//! `savsim batch summarize DIR`: a results directory's shards read into a
//! [`Summary`]. A row ended with an `error`, a `collision`
//! (any), an `nmac`, else `pass`; the rates and ratios count NMAC, loss of well clear and
//! collisions.

use std::path::Path;

use arrow_array::{Array, Float64Array, RecordBatch, StringArray, UInt64Array};

use crate::error::Result;
use crate::runs::summary::{OutcomeColumns, RowView, Summary};
use crate::runs::table::{column, float_at, optional, text_or};

/// Read every `*.parquet` in `dir`.
pub fn read_dir(dir: &Path) -> Result<Summary> {
    crate::runs::summary::read_dir(dir, read_batch)
}

fn read_batch(batch: &RecordBatch, path: &Path, all: &mut Summary) -> Result<()> {
    let strings = |name: &str| column::<StringArray>(batch, name, path);
    let (run_id, variant, pair, error) = (
        strings("run_id")?,
        strings("variant")?,
        strings("pair")?,
        strings("error")?,
    );
    let outcomes = OutcomeColumns::of(batch, path)?;
    let number = |name: &str| optional::<Float64Array>(batch, name);
    let (cpa, near_miss, wall) = (
        number("cpa_m"),
        number("closest_near_miss_m"),
        number("wall_s"),
    );
    let index = column::<UInt64Array>(batch, "index", path)?;
    for i in 0..batch.num_rows() {
        let mut row = RowView {
            index: index.value(i),
            id: run_id.value(i).to_string(),
            variant: text_or(variant, i, "nominal"),
            pair: text_or(pair, i, run_id.value(i)),
            ended: "error".into(),
            cpa_m: float_at(cpa, i),
            closest_obstacle_m: float_at(near_miss, i),
            wall_s: float_at(wall, i),
            error: error.is_valid(i).then(|| error.value(i).to_string()),
            ..RowView::default()
        };
        if row.error.is_some() {
            all.add(row, None);
            continue;
        }
        let outcome = outcomes.at(&row, i);
        row.ended = if outcome.collision {
            "collision"
        } else if outcome.nmac {
            "nmac"
        } else {
            "pass"
        }
        .into();
        all.add(row, Some(outcome));
    }
    Ok(())
}
