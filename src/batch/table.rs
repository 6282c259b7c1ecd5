//! Results as an Arrow table and a Parquet file (snappy), one row per run, in manifest order.
//! `approaches` is a list of structs (one per pair of tracks); every other column is flat,
//! so `SELECT ... FROM 'out/*.parquet'` in DuckDB or `pyarrow.parquet.read_table` reads it
//! as it is.

use std::path::Path;
use std::sync::Arc;

use arrow_array::{ArrayRef, BooleanArray, Float64Array, RecordBatch, StringArray, UInt8Array};
use arrow_schema::{DataType, Field, Fields};

use crate::batch::row::{ApproachRow, RunRow};
use crate::error::Result;
use crate::runs::table::{bools, counts, floats, strings, struct_lists, Settings};

fn approach_fields() -> Fields {
    Fields::from(vec![
        Field::new("vehicle", DataType::UInt8, false),
        Field::new("track", DataType::Utf8, false),
        Field::new("distance_m", DataType::Float64, false),
        Field::new("horizontal_m", DataType::Float64, false),
        Field::new("vertical_m", DataType::Float64, false),
        Field::new("t_s", DataType::Float64, false),
        Field::new("nmac", DataType::Boolean, false),
        Field::new("lowc", DataType::Boolean, false),
    ])
}

fn approaches(rows: &[RunRow]) -> ArrayRef {
    approach_lists(rows.iter().map(|r| r.approaches.as_slice()))
}

/// Each row's approaches, as a list of structs (`approaches` in batch and study results).
pub(crate) fn approach_lists<'a>(
    rows: impl Iterator<Item = &'a [ApproachRow]> + Clone,
) -> ArrayRef {
    let all: Vec<&ApproachRow> = rows.clone().flatten().collect();
    let float = |f: fn(&ApproachRow) -> f64| -> ArrayRef {
        Arc::new(all.iter().map(|a| f(a)).collect::<Float64Array>())
    };
    let children: Vec<ArrayRef> = vec![
        Arc::new(all.iter().map(|a| a.vehicle).collect::<UInt8Array>()),
        Arc::new(
            all.iter()
                .map(|a| Some(a.track.as_str()))
                .collect::<StringArray>(),
        ),
        float(|a| a.distance_m),
        float(|a| a.horizontal_m),
        float(|a| a.vertical_m),
        float(|a| a.t_s),
        Arc::new(all.iter().map(|a| Some(a.nmac)).collect::<BooleanArray>()),
        Arc::new(all.iter().map(|a| Some(a.lowc)).collect::<BooleanArray>()),
    ];
    struct_lists(approach_fields(), children, rows.map(<[ApproachRow]>::len))
}

/// The results as one Arrow record batch (an empty batch with the full schema when there are
/// no rows). Every batch has the same schema, whatever its rows hold.
pub fn record_batch(rows: &[RunRow]) -> RecordBatch {
    let mut columns = input_columns(rows);
    columns.extend(result_columns(rows));
    columns.extend(sensed_columns(rows));
    crate::runs::table::record_batch(columns, nullable)
}

type Columns = Vec<(&'static str, ArrayRef)>;

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
    vec![
        ("error", strings(rows, |r| r.error.as_deref())),
        ("ticks", counts(rows, |r| Some(r.ticks))),
        ("collisions", counts(rows, |r| Some(r.collisions))),
        (
            "first_collision_t_s",
            floats(rows, |r| r.first_collision_t_s),
        ),
        (
            "first_collision_obstacle",
            strings(rows, |r| r.first_collision_obstacle.as_deref()),
        ),
        ("near_misses", counts(rows, |r| Some(r.near_misses))),
        (
            "closest_near_miss_m",
            floats(rows, |r| r.closest_near_miss_m),
        ),
        ("nmac", bools(rows, |r| Some(r.nmac))),
        ("cpa_m", floats(rows, |r| r.cpa_m)),
        ("cpa_horizontal_m", floats(rows, |r| r.cpa_horizontal_m)),
        ("cpa_vertical_m", floats(rows, |r| r.cpa_vertical_m)),
        ("cpa_t_s", floats(rows, |r| r.cpa_t_s)),
        ("cpa_track", strings(rows, |r| r.cpa_track.as_deref())),
        ("approaches", approaches(rows)),
        ("lowc", bools(rows, |r| Some(r.lowc))),
        ("lowc_first_t_s", floats(rows, |r| r.lowc_first_t_s)),
        ("lowc_duration_s", floats(rows, |r| Some(r.lowc_duration_s))),
        ("min_taumod_s", floats(rows, |r| r.min_taumod_s)),
        (
            "lowc_min_horizontal_m",
            floats(rows, |r| r.lowc_min_horizontal_m),
        ),
        (
            "lowc_min_vertical_m",
            floats(rows, |r| r.lowc_min_vertical_m),
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
    ]
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
