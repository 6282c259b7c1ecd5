//! tlog files: read records (8-byte big-endian UNIX microseconds + one MAVLink frame) with
//! resynchronisation after garbage, and write them the way MAVProxy and QGroundControl do.
//!
//! The reader allocates its buffer once and streams any `Read`; a cut at the end of a file is
//! reported with its byte offset after every whole record has been returned. It counts what it
//! skips into [`IngestStats`]; it does not decode payloads.

use std::io::{self, Read, Write};

use crate::codec::frame::{frame_known, scan, FrameStatus, RawFrame, Scan, MAX_FRAME_LEN};
use crate::codec::stats::IngestStats;

/// Bytes of a tlog timestamp.
pub const TIMESTAMP_LEN: usize = 8;
const WINDOW: usize = TIMESTAMP_LEN + MAX_FRAME_LEN;
const BUFFER_LEN: usize = 256 * 1024;

/// One valid record of a tlog.
#[derive(Debug, Clone, Copy)]
pub struct TlogRecord<'a> {
    /// Byte offset of the record (its timestamp) in the file.
    pub offset: u64,
    /// The record's timestamp, microseconds since the UNIX epoch.
    pub timestamp_us: u64,
    /// The frame (count and decode it with [`crate::codec::Ingestor::frame`]).
    pub frame: RawFrame<'a>,
}

/// Streams the records of a tlog.
///
/// ```
/// use savsim::{codec::stats::IngestStats, logs::tlog::TlogReader};
/// let heartbeat = [0xfe, 9, 0, 1, 1, 0, 4, 0, 0, 0, 2, 3, 81, 3, 3, 0xe4, 0xe1];
/// let mut bytes = 1_600_000_000_000_000u64.to_be_bytes().to_vec();
/// bytes.extend_from_slice(&heartbeat);
/// bytes.extend_from_slice(&[0, 0, 0]); // a cut record
/// let mut stats = IngestStats::default();
/// let mut reader = TlogReader::new(&bytes[..]);
/// let record = reader.next_record(&mut stats).unwrap().unwrap();
/// assert_eq!(record.timestamp_us, 1_600_000_000_000_000);
/// assert!(reader.next_record(&mut stats).unwrap().is_none());
/// assert_eq!(stats.truncated_at, Some((25, 3)));
/// ```
pub struct TlogReader<R> {
    source: R,
    buf: Vec<u8>,
    start: usize,
    end: usize,
    /// File offset of `buf[0]`.
    buf_offset: u64,
    eof: bool,
    /// After garbage, only a frame with a valid checksum ends the search.
    resyncing: bool,
}

impl<R: Read> TlogReader<R> {
    /// A reader over `source` (a file, a byte slice, anything `Read`).
    pub fn new(source: R) -> Self {
        Self {
            source,
            buf: vec![0; BUFFER_LEN],
            start: 0,
            end: 0,
            buf_offset: 0,
            eof: false,
            resyncing: false,
        }
    }

    /// Bytes consumed so far.
    pub fn position(&self) -> u64 {
        self.buf_offset + self.start as u64
    }

    fn fill(&mut self) -> io::Result<()> {
        while !self.eof && self.end - self.start < WINDOW {
            if self.end == self.buf.len() {
                self.buf.copy_within(self.start..self.end, 0);
                self.buf_offset += self.start as u64;
                self.end -= self.start;
                self.start = 0;
            }
            match self.source.read(&mut self.buf[self.end..]) {
                Ok(0) => self.eof = true,
                Ok(n) => self.end += n,
                Err(e) if e.kind() == io::ErrorKind::Interrupted => {}
                Err(e) => return Err(e),
            }
        }
        Ok(())
    }

    fn advance(&mut self, stats: &mut IngestStats) -> io::Result<Option<(usize, FrameStatus)>> {
        // Where the next record lies in `buf`, and its frame's status.
        loop {
            self.fill()?;
            let avail = &self.buf[self.start..self.end];
            if avail.is_empty() {
                return Ok(None);
            }
            let scanned = if avail.len() > TIMESTAMP_LEN {
                scan(&avail[TIMESTAMP_LEN..])
            } else {
                Scan::Incomplete
            };
            match scanned {
                Scan::Frame(frame) if !self.resyncing || frame.status == FrameStatus::Valid => {
                    self.resyncing = false;
                    stats.tlog_records += 1;
                    let here = self.start;
                    self.start += TIMESTAMP_LEN + frame.len;
                    return Ok(Some((here, frame.status)));
                }
                Scan::Incomplete if self.eof => {
                    stats.truncated_at = Some((self.position(), avail.len() as u64));
                    self.start = self.end;
                    return Ok(None);
                }
                Scan::Incomplete => unreachable!("fill() keeps a whole window unless at EOF"),
                _ => {
                    if !self.resyncing {
                        stats.resyncs += 1;
                        self.resyncing = true;
                    }
                    stats.garbage_bytes += 1;
                    self.start += 1;
                }
            }
        }
    }

    /// The next record, or `None` at the end of the input. Garbage and a cut tail are counted
    /// into `stats` and skipped; a frame with a bad checksum where a record should start is
    /// returned (skipped by its length, as pymavlink does), one met while resynchronising is not.
    pub fn next_record(&mut self, stats: &mut IngestStats) -> io::Result<Option<TlogRecord<'_>>> {
        let Some((at, status)) = self.advance(stats)? else {
            return Ok(None);
        };
        let bytes = &self.buf[at..self.start];
        let mut timestamp = [0u8; TIMESTAMP_LEN];
        timestamp.copy_from_slice(&bytes[..TIMESTAMP_LEN]);
        Ok(Some(TlogRecord {
            offset: self.buf_offset + at as u64,
            timestamp_us: u64::from_be_bytes(timestamp),
            frame: frame_known(&bytes[TIMESTAMP_LEN..], status),
        }))
    }
}

/// Writes a standard tlog: each frame preceded by its big-endian microsecond UNIX timestamp.
pub struct TlogWriter<W: Write> {
    sink: W,
}

impl<W: Write> TlogWriter<W> {
    /// A writer into `sink` (wrap files in a `BufWriter`).
    pub fn new(sink: W) -> Self {
        Self { sink }
    }

    /// Append one record.
    pub fn write_record(&mut self, timestamp_us: u64, frame_bytes: &[u8]) -> io::Result<()> {
        self.sink.write_all(&timestamp_us.to_be_bytes())?;
        self.sink.write_all(frame_bytes)
    }

    /// Flush to the sink.
    pub fn flush(&mut self) -> io::Result<()> {
        self.sink.flush()
    }
}
