//! Rows as Arrow columns and a shard as one Parquet file (snappy), written whole or not at
//! all, its key-value metadata holding savsim's version and what the run was given
//! ([`Settings`]); and a directory of shards read back, batch by batch.

use std::fs::File;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use arrow_array::{
    Array, ArrayRef, BooleanArray, Float64Array, ListArray, RecordBatch, StringArray, StructArray,
    UInt64Array,
};
use arrow_buffer::OffsetBuffer;
use arrow_schema::{DataType, Field, Fields, Schema};
use parquet::arrow::arrow_reader::ParquetRecordBatchReaderBuilder;
use parquet::arrow::ArrowWriter;
use parquet::basic::Compression;
use parquet::file::metadata::KeyValue;
use parquet::file::properties::WriterProperties;

use crate::error::{Error, Result};
use crate::runs::shard::Shard;

/// A column of text, one value (or null) per row.
pub fn strings<'a, R, S: AsRef<str>>(rows: &'a [R], f: impl Fn(&'a R) -> Option<S>) -> ArrayRef {
    Arc::new(rows.iter().map(f).collect::<StringArray>())
}

/// A column of numbers.
pub fn floats<R>(rows: &[R], f: impl Fn(&R) -> Option<f64>) -> ArrayRef {
    Arc::new(rows.iter().map(f).collect::<Float64Array>())
}

/// A column of counts.
pub fn counts<R>(rows: &[R], f: impl Fn(&R) -> Option<u64>) -> ArrayRef {
    Arc::new(rows.iter().map(f).collect::<UInt64Array>())
}

/// A column of booleans.
pub fn bools<R>(rows: &[R], f: impl Fn(&R) -> Option<bool>) -> ArrayRef {
    Arc::new(rows.iter().map(f).collect::<BooleanArray>())
}

/// A column whose value per row is a list of structs (`fields`): the structs of every row in
/// order as `children` (one array per field), `lengths` how many each row has.
pub fn struct_lists(
    fields: Fields,
    children: Vec<ArrayRef>,
    lengths: impl Iterator<Item = usize>,
) -> ArrayRef {
    let values = StructArray::new(fields.clone(), children, None);
    let item = Arc::new(Field::new("item", DataType::Struct(fields), false));
    let offsets = OffsetBuffer::from_lengths(lengths);
    Arc::new(ListArray::new(item, offsets, Arc::new(values), None))
}

/// Named columns as one record batch; `nullable` says which may hold nulls.
pub fn record_batch(
    columns: Vec<(&str, ArrayRef)>,
    nullable: impl Fn(&str) -> bool,
) -> RecordBatch {
    let fields: Vec<Field> = columns
        .iter()
        .map(|(name, a)| Field::new(*name, a.data_type().clone(), nullable(name)))
        .collect();
    RecordBatch::try_new(
        Arc::new(Schema::new(fields)),
        columns.into_iter().map(|(_, a)| a).collect(),
    )
    .expect("the columns match the schema")
}

/// What a shard's file says of how it was made, as its Parquet key-value metadata:
/// `savsim_version`, `command`, `manifest`, `shard` (`K/N`), then the command's own settings.
#[derive(Debug, Clone, PartialEq)]
pub struct Settings {
    /// `batch` or `study`.
    pub command: &'static str,
    /// The manifest's path (empty when the rows came another way, as from Python).
    pub manifest: String,
    /// The shard.
    pub shard: Shard,
    /// The command's settings (`jobs`, `speedup`, the autopilots...), as (key, value).
    pub more: Vec<(&'static str, String)>,
}

impl Settings {
    fn key_values(&self) -> Vec<KeyValue> {
        let mut kv = vec![
            KeyValue::new(
                "savsim_version".into(),
                env!("CARGO_PKG_VERSION").to_string(),
            ),
            KeyValue::new("command".into(), self.command.to_string()),
            KeyValue::new("manifest".into(), self.manifest.clone()),
            KeyValue::new(
                "shard".into(),
                format!("{}/{}", self.shard.index, self.shard.count),
            ),
        ];
        kv.extend(
            self.more
                .iter()
                .map(|(k, v)| KeyValue::new((*k).to_string(), v.clone())),
        );
        kv
    }
}

/// `batch` as Parquet bytes, with `settings` as the file's metadata.
pub fn write(
    batch: &RecordBatch,
    settings: &Settings,
    out: impl std::io::Write + Send,
) -> parquet::errors::Result<()> {
    let properties = WriterProperties::builder()
        .set_compression(Compression::SNAPPY)
        .set_key_value_metadata(Some(settings.key_values()))
        .build();
    let mut writer = ArrowWriter::try_new(out, batch.schema(), Some(properties))?;
    writer.write(batch)?;
    writer.close()?;
    Ok(())
}

/// Write `batch` to `path` atomically (a temporary file, synced, then renamed): a reader, or a
/// re-run looking for finished shards, sees the whole file or none.
pub fn write_atomic(batch: &RecordBatch, settings: &Settings, path: &Path) -> Result<()> {
    crate::files::write_atomic(path, |out| {
        write(batch, settings, out).map_err(std::io::Error::other)
    })
    .map_err(|e| Error::file(path, e))
}

/// A shard file's key-value metadata.
pub fn read_settings(path: &Path) -> Result<Vec<(String, String)>> {
    let bad = |e: parquet::errors::ParquetError| Error::file(path, std::io::Error::other(e));
    let file = File::open(path).map_err(|e| Error::file(path, e))?;
    let builder = ParquetRecordBatchReaderBuilder::try_new(file).map_err(bad)?;
    Ok(builder
        .metadata()
        .file_metadata()
        .key_value_metadata()
        .map(|kv| {
            kv.iter()
                .map(|k| (k.key.clone(), k.value.clone().unwrap_or_default()))
                .collect()
        })
        .unwrap_or_default())
}

/// Call `f` on every record batch of every `*.parquet` file in `dir` (in name order); the
/// files read. No such file is an error.
pub fn for_each_batch(
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
/// of another type (a shard of another schema).
pub fn column<'a, T: 'static>(batch: &'a RecordBatch, name: &str, path: &Path) -> Result<&'a T> {
    batch
        .column_by_name(name)
        .and_then(|c| c.as_any().downcast_ref::<T>())
        .ok_or_else(|| Error::Usage(format!("{}: no column {name} of its type", path.display())))
}

/// Column `name` of `batch` when it is there with type `T` (columns a report shows where a
/// shard has them).
pub fn optional<'a, T: 'static>(batch: &'a RecordBatch, name: &str) -> Option<&'a T> {
    batch
        .column_by_name(name)
        .and_then(|c| c.as_any().downcast_ref::<T>())
}

/// Row `i` of an optional number column, `None` where it is absent or null.
pub fn float_at(column: Option<&Float64Array>, i: usize) -> Option<f64> {
    column.filter(|c| c.is_valid(i)).map(|c| c.value(i))
}

/// Row `i` of an optional text column, `None` where it is absent or null.
pub fn text_at(column: Option<&StringArray>, i: usize) -> Option<String> {
    column
        .filter(|c| c.is_valid(i))
        .map(|c| c.value(i).to_string())
}

/// Row `i` of a text column, or `default` where it is null.
pub fn text_or(column: &StringArray, i: usize, default: &str) -> String {
    if column.is_valid(i) {
        column.value(i).to_string()
    } else {
        default.to_string()
    }
}
