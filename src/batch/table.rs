//! Results as an Arrow table and a Parquet file (snappy), one row per run, in manifest order.
//! `approaches` is a list of structs (one per pair of tracks); every other column is flat,
//! so `SELECT ... FROM 'out/*.parquet'` in DuckDB or `pyarrow.parquet.read_table` reads it
//! as it is.

use std::path::Path;

use arrow_array::RecordBatch;

use crate::batch::row::RunRow;
use crate::error::Result;
use crate::runs::measured::{
    approaches_column, contact_columns, cpa_columns, lowc_columns, Columns, Measured,
};
use crate::runs::table::{bools, counts, floats, strings, Settings};

/// The results as one Arrow record batch (an empty batch with the full schema when there are
/// no rows). Every batch has the same schema, whatever its rows hold.
pub fn record_batch(rows: &[RunRow]) -> RecordBatch {
    let mut columns = input_columns(rows);
    columns.extend(result_columns(rows));
    columns.extend(sensed_columns(rows));
    crate::runs::table::record_batch(columns, nullable)
}

/// The row as the manifest gave it.
fn input_columns(rows: &[RunRow]) -> Columns {
    vec![
        ("index", counts(rows, |r| Some(r.index))),
        ("run_id", strings(rows, |r| Some(r.run_id.as_str()))),
        ("kind", strings(rows, |r| Some(r.kind.as_str()))),
        ("tlog", strings(rows, |r| r.inputs.tlog.as_deref())),
        ("daa", strings(rows, |r| r.inputs.daa.as_deref())),
        ("scene", strings(rows, |r| r.inputs.scene.as_deref())),
        ("mode", strings(rows, |r| Some(r.mode.as_str()))),
        ("own", strings(rows, |r| r.inputs.own.as_deref())),
        ("intruder", strings(rows, |r| r.inputs.intruder.as_deref())),
        (
            "intruder_kind",
            strings(rows, |r| r.inputs.intruder_kind.as_deref()),
        ),
        ("rate_hz", floats(rows, |r| r.inputs.rate_hz)),
        ("duration_s", floats(rows, |r| r.inputs.duration_s)),
        ("expect_cpa_m", floats(rows, |r| r.inputs.expect_cpa_m)),
        (
            "expect_cpa_horizontal_m",
            floats(rows, |r| r.inputs.expect_cpa_horizontal_m),
        ),
        (
            "expect_cpa_vertical_m",
            floats(rows, |r| r.inputs.expect_cpa_vertical_m),
        ),
        ("expect_cpa_t_s", floats(rows, |r| r.inputs.expect_cpa_t_s)),
        (
            "well_clear",
            strings(rows, |r| r.inputs.well_clear.as_deref()),
        ),
        ("variant", strings(rows, |r| r.inputs.variant.as_deref())),
        ("pair", strings(rows, |r| r.inputs.pair.as_deref())),
        ("w", floats(rows, |r| r.inputs.w)),
        ("expect_nmac", bools(rows, |r| r.inputs.expect_nmac)),
        ("seed", counts(rows, |r| r.inputs.seed)),
    ]
}

/// What the run found: contacts, approaches, well clear, ingest counts, costs.
fn result_columns(rows: &[RunRow]) -> Columns {
    let mut columns = vec![
        ("error", strings(rows, |r| r.error.as_deref())),
        ("ticks", counts(rows, |r| Some(r.measured.ticks))),
    ];
    fn m(r: &RunRow) -> &Measured {
        &r.measured
    }
    columns.extend(contact_columns(rows, m));
    columns.push((
        "closest_near_miss_m",
        floats(rows, |r| r.measured.closest_near_miss_m),
    ));
    columns.extend(cpa_columns(rows, m));
    columns.push(approaches_column(rows, m));
    columns.extend(lowc_columns(rows, m));
    columns.extend([
        (
            "lowc_min_horizontal_m",
            floats(rows, |r| r.measured.lowc_min_horizontal_m),
        ),
        (
            "lowc_min_vertical_m",
            floats(rows, |r| r.measured.lowc_min_vertical_m),
        ),
        ("messages", counts(rows, |r| Some(r.messages))),
        ("bad_frames", counts(rows, |r| Some(r.bad_frames))),
        ("rejected", counts(rows, |r| Some(r.rejected))),
        (
            "tick_cost_us_median",
            floats(rows, |r| Some(r.tick_cost_us_median)),
        ),
        (
            "tick_cost_us_p99",
            floats(rows, |r| Some(r.tick_cost_us_p99)),
        ),
        ("wall_s", floats(rows, |r| Some(r.wall_s))),
    ]);
    columns
}

/// The DAA system's alerting on the sensed states (with `daa_conf`).
fn sensed_columns(rows: &[RunRow]) -> Columns {
    vec![
        ("sensors", strings(rows, |r| r.inputs.sensors.as_deref())),
        ("sensor_seed", counts(rows, |r| Some(r.sensor_seed))),
        ("daa_conf", strings(rows, |r| r.inputs.daa_conf.as_deref())),
        (
            "alert_max_level",
            counts(rows, |r| {
                r.sensed.as_ref().map(|s| s.max_level.max(0) as u64)
            }),
        ),
        ("first_alert_1_t_s", floats(rows, |r| first_level(r, 0))),
        ("first_alert_2_t_s", floats(rows, |r| first_level(r, 1))),
        ("first_alert_3_t_s", floats(rows, |r| first_level(r, 2))),
        (
            "sensed_first_detection_t_s",
            floats(rows, |r| {
                r.sensed.as_ref().and_then(|s| s.first_detection_t_s)
            }),
        ),
        (
            "sensed_closest_m",
            floats(rows, |r| r.sensed.as_ref().and_then(|s| s.sensed_closest_m)),
        ),
        (
            "reports_received",
            counts(rows, |r| r.sensed.as_ref().map(|s| s.reports_received)),
        ),
        (
            "reports_lost",
            counts(rows, |r| r.sensed.as_ref().map(|s| s.reports_lost)),
        ),
    ]
}

/// When level `k + 1` was first raised on the sensed states.
fn first_level(r: &RunRow, k: usize) -> Option<f64> {
    r.sensed.as_ref().and_then(|s| s.first_level_t_s[k])
}

/// Whether a column may hold nulls.
fn nullable(name: &str) -> bool {
    !matches!(
        name,
        "index"
            | "run_id"
            | "kind"
            | "mode"
            | "ticks"
            | "collisions"
            | "near_misses"
            | "nmac"
            | "approaches"
            | "lowc"
            | "lowc_duration_s"
            | "messages"
            | "bad_frames"
            | "rejected"
            | "tick_cost_us_median"
            | "tick_cost_us_p99"
            | "wall_s"
    )
}

/// The results as Parquet bytes, `settings` in the file's metadata.
pub fn to_parquet(
    rows: &[RunRow],
    settings: &Settings,
    out: impl std::io::Write + Send,
) -> parquet::errors::Result<()> {
    crate::runs::table::write(&record_batch(rows), settings, out)
}

/// Write the results to `path` atomically, `settings` in the file's metadata: a reader (or a
/// re-run looking for finished shards) sees the whole file or none.
pub fn write_atomic(rows: &[RunRow], settings: &Settings, path: &Path) -> Result<()> {
    crate::runs::table::write_atomic(&record_batch(rows), settings, path)
}
