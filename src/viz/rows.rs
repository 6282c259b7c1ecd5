//! Per-tick rows gathered into chunks before they reach the recording stream.
//!
//! `RecordingStream::log` hands every row to rerun's batcher thread through a channel; at a
//! dozen rows per tick that cost the logger several times the collision core's own time. Rows
//! logged here are kept per entity and sent as one chunk every [`ROWS_PER_CHUNK`] rows, when
//! [`MAX_HOLD`] has passed (a viewer watching a live run sees them that late at most), and at
//! the end.

use std::collections::BTreeMap;
use std::time::{Duration, Instant};

use rerun::log::{Chunk, RowId};
use rerun::{
    AsComponents, RecordingStream, RecordingStreamResult, SerializedComponentBatch, TimeCell,
    TimePoint,
};

/// Rows per entity gathered into one chunk.
pub const ROWS_PER_CHUNK: usize = 256;
/// The longest a row waits before it is sent.
pub const MAX_HOLD: Duration = Duration::from_millis(200);

type Row = (RowId, TimePoint, Vec<SerializedComponentBatch>);

/// The gathered rows, and the time they are logged at.
pub struct Rows {
    pending: BTreeMap<String, Vec<Row>>,
    time: TimePoint,
    since: Instant,
}

impl Default for Rows {
    fn default() -> Self {
        Self {
            pending: BTreeMap::new(),
            time: TimePoint::default(),
            since: Instant::now(),
        }
    }
}

impl Rows {
    /// The time of the rows logged next: the three timelines of docs/rerun.md.
    pub fn set_time(&mut self, tick: u64, vehicle_time_s: f64, tlog_time_s: f64) {
        let mut time = TimePoint::default();
        time.insert_cell("tick", TimeCell::from_sequence(tick as i64));
        time.insert_cell(
            "vehicle_time",
            TimeCell::from_duration_nanos((vehicle_time_s * 1e9) as i64),
        );
        time.insert_cell(
            "tlog_time",
            TimeCell::from_timestamp_secs_since_epoch(tlog_time_s),
        );
        self.time = time;
    }

    /// The time rows are logged at now.
    pub fn time(&self) -> &TimePoint {
        &self.time
    }

    /// Add a row at `path`; a full chunk goes out at once.
    pub fn log(
        &mut self,
        rec: &RecordingStream,
        path: String,
        archetype: &dyn AsComponents,
    ) -> RecordingStreamResult<()> {
        let time = self.time.clone();
        self.log_at(rec, path, time, archetype)
    }

    /// Add a row at `path` at another time than now.
    pub fn log_at(
        &mut self,
        rec: &RecordingStream,
        path: String,
        time: TimePoint,
        archetype: &dyn AsComponents,
    ) -> RecordingStreamResult<()> {
        let rows = self.pending.entry(path).or_default();
        rows.push((RowId::new(), time, archetype.as_serialized_batches()));
        if rows.len() >= ROWS_PER_CHUNK || self.since.elapsed() >= MAX_HOLD {
            self.flush(rec)?;
        }
        Ok(())
    }

    /// Send every gathered row.
    pub fn flush(&mut self, rec: &RecordingStream) -> RecordingStreamResult<()> {
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
        self.since = Instant::now();
        Ok(())
    }
}
