//! Results as an Arrow table and a Parquet file (snappy), one row per run, in manifest order.
//! `approaches` is a list of structs (one per pair of tracks); every other column is flat,
//! so `SELECT ... FROM 'out/*.parquet'` in DuckDB or `pyarrow.parquet.read_table` reads it
//! as it is.

use std::path::Path;
use std::sync::Arc;

use arrow_array::{
    ArrayRef, BooleanArray, Float64Array, ListArray, RecordBatch, StringArray, StructArray,
    UInt64Array, UInt8Array,
};
use arrow_buffer::OffsetBuffer;
use arrow_schema::{DataType, Field, Fields, Schema};
use parquet::arrow::ArrowWriter;
use parquet::basic::Compression;
use parquet::file::properties::WriterProperties;

use crate::batch::row::{ApproachRow, RunRow};
use crate::error::{Error, Result};

fn strings<'a>(rows: &'a [RunRow], f: impl Fn(&'a RunRow) -> Option<&'a str>) -> ArrayRef {
    Arc::new(rows.iter().map(f).collect::<StringArray>())
}

fn floats(rows: &[RunRow], f: impl Fn(&RunRow) -> Option<f64>) -> ArrayRef {
    Arc::new(rows.iter().map(f).collect::<Float64Array>())
}

fn counts(rows: &[RunRow], f: impl Fn(&RunRow) -> u64) -> ArrayRef {
    Arc::new(rows.iter().map(f).collect::<UInt64Array>())
}

fn approach_fields() -> Fields {
    Fields::from(vec![
        Field::new("vehicle", DataType::UInt8, false),
        Field::new("track", DataType::Utf8, false),
        Field::new("distance_m", DataType::Float64, false),
        Field::new("horizontal_m", DataType::Float64, false),
        Field::new("vertical_m", DataType::Float64, false),
        Field::new("t_s", DataType::Float64, false),
        Field::new("nmac", DataType::Boolean, false),
    ])
}

fn approaches(rows: &[RunRow]) -> ArrayRef {
    let all: Vec<&ApproachRow> = rows.iter().flat_map(|r| &r.approaches).collect();
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
    ];
    let values = StructArray::new(approach_fields(), children, None);
    let item = Arc::new(Field::new(
        "item",
        DataType::Struct(approach_fields()),
        false,
    ));
    let offsets = OffsetBuffer::from_lengths(rows.iter().map(|r| r.approaches.len()));
    Arc::new(ListArray::new(item, offsets, Arc::new(values), None))
}

/// The results as one Arrow record batch (an empty batch with the full schema when there are
/// no rows). Every batch has the same schema, whatever its rows hold.
pub fn record_batch(rows: &[RunRow]) -> RecordBatch {
    let columns: Vec<(&str, ArrayRef)> = vec![
        ("index", counts(rows, |r| r.index)),
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
        (
            "expect_nmac",
            Arc::new(
                rows.iter()
                    .map(|r| r.inputs.expect_nmac)
                    .collect::<BooleanArray>(),
            ),
        ),
        ("error", strings(rows, |r| r.error.as_deref())),
        ("ticks", counts(rows, |r| r.ticks)),
        ("collisions", counts(rows, |r| r.collisions)),
        (
            "first_collision_t_s",
            floats(rows, |r| r.first_collision_t_s),
        ),
        (
            "first_collision_obstacle",
            strings(rows, |r| r.first_collision_obstacle.as_deref()),
        ),
        ("near_misses", counts(rows, |r| r.near_misses)),
        (
            "closest_near_miss_m",
            floats(rows, |r| r.closest_near_miss_m),
        ),
        (
            "nmac",
            Arc::new(rows.iter().map(|r| Some(r.nmac)).collect::<BooleanArray>()),
        ),
        ("cpa_m", floats(rows, |r| r.cpa_m)),
        ("cpa_horizontal_m", floats(rows, |r| r.cpa_horizontal_m)),
        ("cpa_vertical_m", floats(rows, |r| r.cpa_vertical_m)),
        ("cpa_t_s", floats(rows, |r| r.cpa_t_s)),
        ("cpa_track", strings(rows, |r| r.cpa_track.as_deref())),
        ("approaches", approaches(rows)),
        (
            "lowc",
            Arc::new(rows.iter().map(|r| Some(r.lowc)).collect::<BooleanArray>()),
        ),
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
        ("messages", counts(rows, |r| r.messages)),
        ("bad_frames", counts(rows, |r| r.bad_frames)),
        ("rejected", counts(rows, |r| r.rejected)),
        (
            "tick_cost_us_median",
            floats(rows, |r| Some(r.tick_cost_us_median)),
        ),
        (
            "tick_cost_us_p99",
            floats(rows, |r| Some(r.tick_cost_us_p99)),
        ),
        ("wall_s", floats(rows, |r| Some(r.wall_s))),
    ];
    let fields: Vec<Field> = columns
        .iter()
        .map(|(name, array)| Field::new(*name, array.data_type().clone(), nullable(name)))
        .collect();
    RecordBatch::try_new(
        Arc::new(Schema::new(fields)),
        columns.into_iter().map(|(_, a)| a).collect(),
    )
    .expect("the columns match the schema")
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

/// The results as Parquet bytes.
pub fn to_parquet(rows: &[RunRow], out: impl std::io::Write + Send) -> parquet::errors::Result<()> {
    let batch = record_batch(rows);
    let properties = WriterProperties::builder()
        .set_compression(Compression::SNAPPY)
        .build();
    let mut writer = ArrowWriter::try_new(out, batch.schema(), Some(properties))?;
    writer.write(&batch)?;
    writer.close()?;
    Ok(())
}

/// Write the results to `path` atomically: a reader (or a re-run looking for finished shards)
/// sees the whole file or none.
pub fn write_atomic(rows: &[RunRow], path: &Path) -> Result<()> {
    let tmp = path.with_extension("parquet.tmp");
    let file = std::fs::File::create(&tmp).map_err(|e| Error::file(&tmp, e))?;
    let mut out = std::io::BufWriter::new(file);
    to_parquet(rows, &mut out).map_err(|e| Error::file(&tmp, std::io::Error::other(e)))?;
    let file = out
        .into_inner()
        .map_err(|e| Error::file(&tmp, e.into_error()))?;
    file.sync_all().map_err(|e| Error::file(&tmp, e))?;
    std::fs::rename(&tmp, path).map_err(|e| Error::file(path, e))
}
