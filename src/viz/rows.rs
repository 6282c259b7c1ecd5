//! Per-tick rows gathered into chunks before they reach the recording stream.
//!
//! `RecordingStream::log` hands every row to rerun's batcher thread through a channel, one
//! send per row (what that cost is in docs/performance.md, "The rerun logger"). Rows logged
//! here are kept per entity and sent as one chunk every [`ROWS_PER_CHUNK`] rows, when
//! [`MAX_HOLD`] has passed if a viewer watches live (it sees them that late at most), and at
//! the end. Scalars, poses, arrows and line strips, the most frequent rows, are kept as plain
//! columns and become arrow arrays once per chunk, not once per row.

use std::collections::BTreeMap;
use std::time::{Duration, Instant};

use rerun::log::{Chunk, RowId, TimeColumn};
use rerun::{
    Arrows3D, AsComponents, Color, LineStrips3D, RecordingStream, RecordingStreamResult, Scalars,
    SerializedComponentBatch, TimeCell, TimePoint, Transform3D,
};

/// Rows per entity gathered into one chunk.
pub const ROWS_PER_CHUNK: usize = 1024;
/// The longest a row waits before it is sent.
pub const MAX_HOLD: Duration = Duration::from_millis(200);

type Row = (RowId, TimePoint, Vec<SerializedComponentBatch>);

/// The three timelines of a column's rows: tick, vehicle time (ns), tlog time (ns).
#[derive(Default)]
struct Times(Vec<[i64; 3]>);

impl Times {
    fn take(&mut self) -> [TimeColumn; 3] {
        let rows = std::mem::take(&mut self.0);
        [
            TimeColumn::new_sequence("tick", rows.iter().map(|r| r[0])),
            TimeColumn::new_duration_nanos("vehicle_time", rows.iter().map(|r| r[1])),
            TimeColumn::new_timestamp_nanos_since_epoch("tlog_time", rows.iter().map(|r| r[2])),
        ]
    }
}

/// A column of one entity: its values, one row each.
enum Values {
    Scalar(Vec<f64>),
    Pose(Vec<[f32; 3]>, Vec<rerun::Quaternion>),
    /// Arrows: vectors and origins, and how many of them each row has.
    Arrows(Vec<[f32; 3]>, Vec<[f32; 3]>, Vec<usize>),
    /// One line strip per row, all in one colour.
    Strip(Vec<Vec<[f32; 3]>>, Color),
}

/// The gathered rows, and the time they are logged at.
pub struct Rows {
    pending: BTreeMap<String, Vec<Row>>,
    columns: BTreeMap<String, (Times, Values)>,
    time: TimePoint,
    now: [i64; 3],
    since: Instant,
    /// Send by time too ([`MAX_HOLD`]), for a viewer watching live.
    live: bool,
}

impl Rows {
    /// Gathered rows for a recording a viewer watches live (`live`) or not.
    pub fn new(live: bool) -> Self {
        Self {
            pending: BTreeMap::new(),
            columns: BTreeMap::new(),
            time: TimePoint::default(),
            now: [0; 3],
            since: Instant::now(),
            live,
        }
    }
}

impl Rows {
    /// The time of the rows logged next: the three timelines of docs/rerun.md.
    pub fn set_time(&mut self, tick: u64, vehicle_time_s: f64, tlog_time_s: f64) {
        self.now = [
            tick as i64,
            (vehicle_time_s * 1e9) as i64,
            (tlog_time_s * 1e9) as i64,
        ];
        let mut time = TimePoint::default();
        time.insert_cell("tick", TimeCell::from_sequence(self.now[0]));
        time.insert_cell("vehicle_time", TimeCell::from_duration_nanos(self.now[1]));
        time.insert_cell(
            "tlog_time",
            TimeCell::from_timestamp_nanos_since_epoch(self.now[2]),
        );
        self.time = time;
    }

    /// The time rows are logged at now (`set_time`).
    pub fn time(&self) -> &TimePoint {
        &self.time
    }

    /// A scalar at `path`, now.
    pub fn scalar(
        &mut self,
        rec: &RecordingStream,
        path: String,
        value: f64,
    ) -> RecordingStreamResult<()> {
        self.push(
            rec,
            path,
            || Values::Scalar(Vec::new()),
            |values| {
                if let Values::Scalar(v) = values {
                    v.push(value);
                }
            },
        )
    }

    /// A pose (translation, rotation) at `path`, now.
    pub fn pose(
        &mut self,
        rec: &RecordingStream,
        path: String,
        translation: [f32; 3],
        rotation: rerun::Quaternion,
    ) -> RecordingStreamResult<()> {
        self.push(
            rec,
            path,
            || Values::Pose(Vec::new(), Vec::new()),
            |values| {
                if let Values::Pose(t, r) = values {
                    t.push(translation);
                    r.push(rotation);
                }
            },
        )
    }

    /// Arrows (vectors from origins) at `path`, now; their colours and widths go through
    /// [`Rows::log`] when they change.
    pub fn arrows(
        &mut self,
        rec: &RecordingStream,
        path: String,
        vectors: &[[f32; 3]],
        origins: &[[f32; 3]],
    ) -> RecordingStreamResult<()> {
        self.push(
            rec,
            path,
            || Values::Arrows(Vec::new(), Vec::new(), Vec::new()),
            |values| {
                if let Values::Arrows(v, o, n) = values {
                    v.extend_from_slice(vectors);
                    o.extend_from_slice(origins);
                    n.push(vectors.len());
                }
            },
        )
    }

    /// A line strip in `color` at `path`, now.
    pub fn strip(
        &mut self,
        rec: &RecordingStream,
        path: String,
        points: &[[f32; 3]],
        color: Color,
    ) -> RecordingStreamResult<()> {
        self.push(
            rec,
            path,
            || Values::Strip(Vec::new(), color),
            |values| {
                if let Values::Strip(s, _) = values {
                    s.push(points.to_vec());
                }
            },
        )
    }

    /// One row of the column at `path` (made by `empty` on first use), filled by `add`.
    fn push(
        &mut self,
        rec: &RecordingStream,
        path: String,
        empty: impl FnOnce() -> Values,
        add: impl FnOnce(&mut Values),
    ) -> RecordingStreamResult<()> {
        let (times, values) = self
            .columns
            .entry(path)
            .or_insert_with(|| (Times::default(), empty()));
        times.0.push(self.now);
        add(values);
        let n = times.0.len();
        self.flush_if_due(rec, n)
    }

    fn flush_if_due(&mut self, rec: &RecordingStream, rows: usize) -> RecordingStreamResult<()> {
        if rows >= ROWS_PER_CHUNK || (self.live && self.since.elapsed() >= MAX_HOLD) {
            self.flush(rec)?;
        }
        Ok(())
    }

    /// Add a row at `path`, now (archetypes without a column of their own here).
    pub fn log(
        &mut self,
        rec: &RecordingStream,
        path: String,
        archetype: &dyn AsComponents,
    ) -> RecordingStreamResult<()> {
        let rows = self.pending.entry(path).or_default();
        rows.push((
            RowId::new(),
            self.time.clone(),
            archetype.as_serialized_batches(),
        ));
        let n = rows.len();
        self.flush_if_due(rec, n)
    }

    /// Send every gathered row.
    pub fn flush(&mut self, rec: &RecordingStream) -> RecordingStreamResult<()> {
        // Entities with nothing since the last flush (a closed track segment, a vehicle gone)
        // are forgotten, so a long live run does not keep one entry per segment ever logged.
        self.pending.retain(|_, rows| !rows.is_empty());
        self.columns.retain(|_, (times, _)| !times.0.is_empty());
        for (path, rows) in &mut self.pending {
            if rows.is_empty() {
                continue;
            }
            let chunk = rows
                .drain(..)
                .fold(Chunk::builder(path.as_str()), |b, (id, time, batches)| {
                    b.with_serialized_batches(id, time, batches)
                })
                .build()?;
            rec.send_chunk(chunk);
        }
        for (path, (times, values)) in &mut self.columns {
            if times.0.is_empty() {
                continue;
            }
            let times = times.take();
            match values {
                Values::Scalar(v) => rec.send_columns(
                    path.as_str(),
                    times,
                    Scalars::new(std::mem::take(v)).columns_of_unit_batches()?,
                )?,
                Values::Arrows(v, o, n) => rec.send_columns(
                    path.as_str(),
                    times,
                    Arrows3D::update_fields()
                        .with_vectors(std::mem::take(v))
                        .with_origins(std::mem::take(o))
                        .columns(std::mem::take(n))?,
                )?,
                Values::Strip(strips, color) => {
                    let colors = vec![*color; strips.len()];
                    rec.send_columns(
                        path.as_str(),
                        times,
                        LineStrips3D::new(std::mem::take(strips))
                            .with_colors(colors)
                            .columns_of_unit_batches()?,
                    )?
                }
                Values::Pose(t, r) => rec.send_columns(
                    path.as_str(),
                    times,
                    Transform3D::update_fields()
                        .with_many_translation(std::mem::take(t))
                        .with_many_quaternion(std::mem::take(r))
                        .columns_of_unit_batches()?,
                )?,
            }
        }
        self.since = Instant::now();
        Ok(())
    }
}
