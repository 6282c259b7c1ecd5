//! Frames from datagrams and byte streams (UDP, TCP), through the same framer as tlogs.
//!
//! A datagram is decoded on its own: a frame cut by the end of a datagram is garbage, never
//! joined with the next datagram. A stream keeps its tail for the next read. After a bad frame
//! the search resumes one byte later (a frame hidden behind a false start is found), unlike
//! tlogs, where a bad frame is skipped by its length as pymavlink does.

use crate::codec::frame::{scan, FrameStatus, RawFrame, Scan, MAX_FRAME_LEN};
use crate::codec::stats::IngestStats;

/// Bytes that were no frame.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Skipped {
    /// Bytes skipped.
    pub bytes: u64,
    /// Runs of skipped bytes.
    pub runs: u64,
}

impl Skipped {
    /// Add these to an input's counters.
    pub fn count_into(self, stats: &mut IngestStats) {
        stats.garbage_bytes += self.bytes;
        stats.resyncs += self.runs;
    }
}

/// Every complete frame in one datagram, valid or not (count them with
/// [`crate::codec::Ingestor::frame`]); returns the bytes that were no frame.
///
/// ```
/// use savsim::links::stream::frames_in_datagram;
/// let heartbeat = [0xfe, 9, 0, 1, 1, 0, 4, 0, 0, 0, 2, 3, 81, 3, 3, 0xe4, 0xe1];
/// let mut datagram = vec![0x55, 0x55];
/// datagram.extend_from_slice(&heartbeat);
/// datagram.extend_from_slice(&heartbeat[..4]);
/// let mut n = 0;
/// let skipped = frames_in_datagram(&datagram, |_| n += 1);
/// assert_eq!(n, 1);
/// assert_eq!(skipped.bytes, 6);
/// ```
pub fn frames_in_datagram(datagram: &[u8], mut on_frame: impl FnMut(&RawFrame<'_>)) -> Skipped {
    let (consumed, mut skipped) = frames_in(datagram, &mut on_frame);
    if consumed < datagram.len() {
        skipped.bytes += (datagram.len() - consumed) as u64;
        skipped.runs += 1;
    }
    skipped
}

/// Frames from the start of `bytes`; returns how many bytes were consumed (an incomplete frame
/// at the end is not) and what was skipped.
fn frames_in(bytes: &[u8], on_frame: &mut impl FnMut(&RawFrame<'_>)) -> (usize, Skipped) {
    let mut at = 0;
    let mut skipped = Skipped::default();
    while at < bytes.len() {
        match scan(&bytes[at..]) {
            Scan::Frame(frame) if frame.status == FrameStatus::Valid => {
                on_frame(&frame);
                at += frame.len;
            }
            Scan::Frame(frame) => {
                // Report the failed frame, then look for a frame starting inside it.
                on_frame(&frame);
                at += 1;
            }
            Scan::Garbage(n) => {
                skipped.bytes += n as u64;
                skipped.runs += 1;
                at += n;
            }
            Scan::Incomplete => break,
        }
    }
    (at, skipped)
}

/// Reassembles frames from a byte stream (TCP) across reads. Allocates its buffer once.
#[derive(Debug)]
pub struct StreamFramer {
    buf: Vec<u8>,
    len: usize,
}

impl Default for StreamFramer {
    fn default() -> Self {
        Self {
            buf: vec![0; 64 * 1024],
            len: 0,
        }
    }
}

impl StreamFramer {
    /// Take the bytes of one read, in order, and hand every frame they complete to `on_frame`.
    ///
    /// ```
    /// use savsim::links::stream::StreamFramer;
    /// let heartbeat = [0xfe, 9, 0, 1, 1, 0, 4, 0, 0, 0, 2, 3, 81, 3, 3, 0xe4, 0xe1];
    /// let mut framer = StreamFramer::default();
    /// let mut n = 0;
    /// framer.push(&heartbeat[..5], |_| n += 1);
    /// assert_eq!(n, 0);
    /// framer.push(&heartbeat[5..], |_| n += 1);
    /// assert_eq!(n, 1);
    /// ```
    pub fn push(&mut self, mut bytes: &[u8], mut on_frame: impl FnMut(&RawFrame<'_>)) -> Skipped {
        let mut skipped = Skipped::default();
        while !bytes.is_empty() {
            let n = (self.buf.len() - self.len).min(bytes.len());
            self.buf[self.len..self.len + n].copy_from_slice(&bytes[..n]);
            self.len += n;
            bytes = &bytes[n..];
            let (consumed, s) = frames_in(&self.buf[..self.len], &mut on_frame);
            self.buf.copy_within(consumed..self.len, 0);
            self.len -= consumed;
            // What is left is one incomplete frame (< MAX_FRAME_LEN), so there is always room.
            debug_assert!(self.buf.len() - self.len >= MAX_FRAME_LEN);
            skipped.bytes += s.bytes;
            skipped.runs += s.runs;
        }
        skipped
    }
}
