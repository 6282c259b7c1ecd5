//! `savsim study summarize DIR`: per variant the outcome counts and the weighted collision,
//! NMAC and loss-of-well-clear rates; each variant against the nominal one over the pairs
//! flown under both (the risk ratios), with 95% percentile-bootstrap intervals over pairs
//! (savsim_core::daa::ratios); rows whose `outcome` is `error` are left out and counted.

use std::path::Path;

use arrow_array::{Float64Array, RecordBatch, StringArray, UInt64Array};

use crate::error::Result;
use crate::runs::summary::{OutcomeColumns, RowView, Summary};
use crate::runs::table::{column, float_at, optional, text_at, text_or};

/// Read every `*.parquet` in `dir`.
pub fn read_dir(dir: &Path) -> Result<Summary> {
    crate::runs::summary::read_dir(dir, read_batch)
}

fn read_batch(batch: &RecordBatch, path: &Path, all: &mut Summary) -> Result<()> {
    let strings = |name: &str| column::<StringArray>(batch, name, path);
    let (row_id, variant, pair, outcome) = (
        strings("row_id")?,
        strings("variant")?,
        strings("pair")?,
        strings("outcome")?,
    );
    let outcomes = OutcomeColumns::of(batch, path)?;
    let number = |name: &str| optional::<Float64Array>(batch, name);
    let (cpa, obstacle, acted, speedup, wall) = (
        number("cpa_m"),
        number("closest_obstacle_m"),
        number("first_acted_t_s"),
        number("achieved_speedup"),
        number("wall_s"),
    );
    let text = |name: &str| optional::<StringArray>(batch, name);
    let (error, version) = (text("error"), text("autopilot_version"));
    let (scene, track, intruder) = (text("scene"), text("vehicle_track"), text("intruder"));
    // A second autopilot's track where the intruder was flown, not scripted.
    let flown_intruder = text("intruder_track");
    let (cpa_t, collision_t) = (number("cpa_t_s"), number("first_collision_t_s"));
    let index = column::<UInt64Array>(batch, "index", path)?;
    for i in 0..batch.num_rows() {
        let row = RowView {
            index: index.value(i),
            id: row_id.value(i).to_string(),
            variant: text_or(variant, i, "nominal"),
            pair: text_or(pair, i, row_id.value(i)),
            ended: text_or(outcome, i, "error"),
            cpa_m: float_at(cpa, i),
            closest_obstacle_m: float_at(obstacle, i),
            first_acted_t_s: float_at(acted, i),
            achieved_speedup: float_at(speedup, i),
            wall_s: float_at(wall, i),
            error: text_at(error, i),
            autopilot_version: text_at(version, i),
            scene: text_at(scene, i),
            vehicle_track: text_at(track, i),
            intruder: text_at(intruder, i).or_else(|| text_at(flown_intruder, i)),
            cpa_t_s: float_at(cpa_t, i),
            first_collision_t_s: float_at(collision_t, i),
        };
        let flew = (row.ended != "error").then(|| outcomes.at(&row, i));
        all.add(row, flew);
    }
    Ok(())
}
