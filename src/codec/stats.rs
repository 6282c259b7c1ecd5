//! Ingest accounting: every byte and every frame that reaches savsim is counted somewhere.
//!
//! [`IngestStats`] is what `--summary-json` reports about the input: messages per name (the
//! same counts pymavlink gives), frames with bad CRCs, unknown ids, garbage bytes, values
//! rejected by reason, senders, and the time span. Pure bookkeeping, no I/O.

use std::collections::BTreeMap;

use mavlink::MavlinkVersion;
use serde::Serialize;

use crate::codec::decode::Rejection;
use crate::codec::frame::{message_info, FrameStatus, RawFrame};
use crate::world::SenderId;

/// Ids below this are counted in an array (every common.xml message and ArduPilot's 150-230);
/// the rest (ArduPilot's 11000s, 42000s) in a map. 4 KiB per input instead of 512 KiB keeps a
/// session cheap to make (the fuzz targets and `savsim batch` make one per input).
const COUNTED_IDS: usize = 512;

/// A receive/tlog time more than this far ahead of the last one (seconds) waits for the next
/// time to confirm it before the clock follows ([`IngestStats::observe_time`]).
pub const HOLD_AHEAD_S: f64 = 2.0;

/// Counters for one input (a tlog, a connection).
#[derive(Debug, Clone)]
pub struct IngestStats {
    /// Valid frames per message id, for ids below 512 (indexed by id).
    by_id: Vec<u64>,
    /// Valid frames with larger ids.
    by_large_id: BTreeMap<u32, u64>,
    /// Valid frames per sender.
    pub by_sender: BTreeMap<SenderId, u64>,
    /// Sequence-number bookkeeping per sender: frames the link lost, repeated or delivered late.
    pub sequence: BTreeMap<SenderId, SequenceCounts>,
    /// Senders whose HEARTBEAT names an autopilot: the link totals count only these; what
    /// they forward (a GCS, a companion computer) is counted apart.
    pub autopilots: std::collections::BTreeSet<SenderId>,
    /// Valid frames per protocol version (v1, v2).
    pub by_version: [u64; 2],
    /// Frames whose checksum failed.
    pub bad_crc: u64,
    /// Frames with an id the dialect does not define, per id.
    pub unknown_ids: BTreeMap<u32, u64>,
    /// v2 frames with unknown incompatibility flags.
    pub bad_incompat_flags: u64,
    /// Bytes skipped because no frame could start there.
    pub garbage_bytes: u64,
    /// Times savsim had to search for the next frame after garbage.
    pub resyncs: u64,
    /// Decoded messages whose values were rejected, per reason.
    pub rejected: BTreeMap<Rejection, u64>,
    /// tlog records read (timestamp + frame).
    pub tlog_records: u64,
    /// Byte offset where an input ended inside a record, with the bytes left there.
    pub truncated_at: Option<(u64, u64)>,
    /// Times the receive or tlog clock stepped backwards.
    pub clock_backwards: u64,
    /// Times the clock stepped more than 2 s ahead for one record alone (a timestamp outside
    /// the CRC gone bad): held at the time before it, not followed.
    pub clock_outliers: u64,
    /// Times the clock jumped more than an hour ahead and stayed there (two recordings
    /// joined): followed.
    pub clock_jumps: u64,
    /// A jump ahead not yet confirmed by the next time (seconds).
    pending_jump_s: Option<f64>,
    /// The last raw time seen, seconds.
    last_raw_t_s: f64,
    /// First and last receive/tlog time seen, seconds (UNIX time for tlogs and live).
    pub time_span_s: Option<(f64, f64)>,
    /// Live: datagrams or reads dropped because the session thread was behind.
    pub dropped_chunks: u64,
    /// Live: bytes in those.
    pub dropped_bytes: u64,
}

impl Default for IngestStats {
    fn default() -> Self {
        Self {
            by_id: vec![0; COUNTED_IDS],
            by_large_id: BTreeMap::new(),
            by_sender: BTreeMap::new(),
            sequence: BTreeMap::new(),
            autopilots: Default::default(),
            by_version: [0; 2],
            bad_crc: 0,
            unknown_ids: BTreeMap::new(),
            bad_incompat_flags: 0,
            garbage_bytes: 0,
            resyncs: 0,
            rejected: BTreeMap::new(),
            tlog_records: 0,
            truncated_at: None,
            clock_backwards: 0,
            clock_outliers: 0,
            clock_jumps: 0,
            pending_jump_s: None,
            last_raw_t_s: f64::NEG_INFINITY,
            time_span_s: None,
            dropped_chunks: 0,
            dropped_bytes: 0,
        }
    }
}

impl IngestStats {
    /// Count a complete frame by its status. Returns true when it is valid (to be decoded).
    /// Sequence numbers are judged at the last time [`IngestStats::observe_time`] was given.
    pub fn count_frame(&mut self, frame: &RawFrame<'_>) -> bool {
        let t_s = self.time_span_s.map_or(0.0, |(_, last)| last);
        match frame.status {
            FrameStatus::Valid => {
                match usize::try_from(frame.message_id) {
                    Ok(i) if i < COUNTED_IDS => self.by_id[i] += 1,
                    _ => *self.by_large_id.entry(frame.message_id).or_default() += 1,
                }
                let sender = SenderId {
                    system_id: frame.system_id,
                    component_id: frame.component_id,
                };
                *self.by_sender.entry(sender).or_default() += 1;
                self.sequence
                    .entry(sender)
                    .or_insert_with(|| SequenceCounts::starting_at(frame.sequence))
                    .observe_at(frame.sequence, t_s);
                if frame.message_id == crate::codec::decode::ID_HEARTBEAT
                    && crate::codec::decode::heartbeat_from(frame.payload).is_autopilot()
                {
                    self.autopilots.insert(sender);
                }
                self.by_version[usize::from(frame.version == MavlinkVersion::V2)] += 1;
                true
            }
            FrameStatus::BadCrc => {
                self.bad_crc += 1;
                false
            }
            FrameStatus::UnknownMessage => {
                *self.unknown_ids.entry(frame.message_id).or_default() += 1;
                false
            }
            FrameStatus::BadIncompatFlags => {
                self.bad_incompat_flags += 1;
                false
            }
        }
    }

    /// Restart a sender's sequence bookkeeping at `sequence` (its next frame): it rebooted
    /// (its clock went back). Once per reboot: the pause before it may have restarted it already.
    pub fn restart_sequence(&mut self, sender: SenderId, sequence: u8) {
        let t_s = self.time_span_s.map_or(0.0, |(_, last)| last);
        if let Some(counts) = self.sequence.get_mut(&sender) {
            counts.rebooted(sequence, t_s);
        }
    }

    /// Count a rejected value.
    pub fn count_rejection(&mut self, reason: Rejection) {
        *self.rejected.entry(reason).or_default() += 1;
    }

    /// Note a receive/tlog time; returns the time to use, never earlier than the last one.
    /// Each step back of the raw clock counts once in `clock_backwards`. A step more than
    /// [`HOLD_AHEAD_S`] ahead is held (the time before it is used) until the next time
    /// confirms it (at most [`HOLD_AHEAD_S`] before it, at most an hour after): alone, it is an
    /// outlier (`clock_outliers`) and never moves the clock, however far ahead it was;
    /// confirmed, the clock follows, and a step of more than an hour is counted as a jump
    /// (`clock_jumps`: two recordings joined).
    ///
    /// ```
    /// let mut stats = savsim::codec::stats::IngestStats::default();
    /// assert_eq!(stats.observe_time(100.0), 100.0);
    /// assert_eq!(stats.observe_time(9e9), 100.0); // one bad timestamp...
    /// assert_eq!(stats.observe_time(100.1), 100.1); // ...is not followed
    /// assert_eq!(stats.observe_time(1900.0), 100.1); // nor one half an hour ahead
    /// assert_eq!(stats.observe_time(100.2), 100.2);
    /// assert_eq!(stats.observe_time(110.0), 100.2); // a pause in the recording...
    /// assert_eq!(stats.observe_time(110.1), 110.1); // ...confirmed by the next time
    /// assert_eq!(stats.observe_time(200_000.0), 110.1);
    /// assert_eq!(stats.observe_time(200_000.1), 200_000.1); // two recordings joined
    /// assert_eq!((stats.clock_outliers, stats.clock_jumps), (2, 1));
    /// ```
    pub fn observe_time(&mut self, t_s: f64) -> f64 {
        const JUMP_S: f64 = 3600.0;
        if t_s < self.last_raw_t_s {
            self.clock_backwards += 1;
        }
        self.last_raw_t_s = t_s;
        let confirmed = match self.pending_jump_s.take() {
            Some(pending) if (pending - HOLD_AHEAD_S..=pending + JUMP_S).contains(&t_s) => {
                let last = self.time_span_s.map_or(pending, |(_, last)| last);
                if pending > last + JUMP_S {
                    self.clock_jumps += 1;
                }
                true
            }
            Some(_) => {
                self.clock_outliers += 1;
                false
            }
            None => false,
        };
        if let Some((_, last)) = self.time_span_s {
            if t_s > last + HOLD_AHEAD_S && !confirmed {
                self.pending_jump_s = Some(t_s);
                return last;
            }
        }
        match &mut self.time_span_s {
            None => {
                self.time_span_s = Some((t_s, t_s));
                t_s
            }
            Some((_, last)) if t_s < *last => *last,
            Some((_, last)) => {
                *last = t_s;
                t_s
            }
        }
    }

    /// Valid messages per name, as pymavlink names them.
    pub fn messages_by_name(&self) -> BTreeMap<&'static str, u64> {
        let small = self
            .by_id
            .iter()
            .enumerate()
            .filter(|(_, &n)| n > 0)
            .map(|(id, &n)| (id as u32, n));
        let large = self.by_large_id.iter().map(|(&id, &n)| (id, n));
        let mut names = BTreeMap::new();
        for (id, n) in small.chain(large) {
            let name = message_info(id).map_or("UNKNOWN", |info| info.name);
            *names.entry(name).or_default() += n;
        }
        names
    }

    /// Count of valid messages with this id.
    pub fn count_of(&self, message_id: u32) -> u64 {
        match usize::try_from(message_id) {
            Ok(i) if i < COUNTED_IDS => self.by_id[i],
            _ => self.by_large_id.get(&message_id).copied().unwrap_or(0),
        }
    }

    /// All valid messages.
    pub fn messages_total(&self) -> u64 {
        self.by_version.iter().sum()
    }

    /// Frames dropped as bad: CRC, unknown message id, unknown incompatibility flags.
    pub fn bad_frames(&self) -> u64 {
        self.bad_crc + self.unknown_ids.values().sum::<u64>() + self.bad_incompat_flags
    }

    /// Decoded values rejected as implausible.
    pub fn rejected_total(&self) -> u64 {
        self.rejected.values().sum()
    }

    /// Fold another input's counts into these.
    pub fn merge(&mut self, other: &IngestStats) {
        for (a, b) in self.by_id.iter_mut().zip(&other.by_id) {
            *a += b;
        }
        for (k, v) in &other.by_large_id {
            *self.by_large_id.entry(*k).or_default() += v;
        }
        for (k, v) in &other.by_sender {
            *self.by_sender.entry(*k).or_default() += v;
        }
        for (k, v) in &other.sequence {
            let mine = self.sequence.entry(*k).or_default();
            mine.lost += v.lost;
            mine.repeated += v.repeated;
            mine.late += v.late;
            mine.restarts += v.restarts;
            mine.last = v.last;
        }
        for i in 0..2 {
            self.by_version[i] += other.by_version[i];
        }
        self.bad_crc += other.bad_crc;
        for (k, v) in &other.unknown_ids {
            *self.unknown_ids.entry(*k).or_default() += v;
        }
        self.bad_incompat_flags += other.bad_incompat_flags;
        self.garbage_bytes += other.garbage_bytes;
        self.resyncs += other.resyncs;
        for (k, v) in &other.rejected {
            *self.rejected.entry(*k).or_default() += v;
        }
        self.tlog_records += other.tlog_records;
        self.truncated_at = self.truncated_at.or(other.truncated_at);
        self.clock_backwards += other.clock_backwards;
        self.clock_outliers += other.clock_outliers;
        self.clock_jumps += other.clock_jumps;
        self.dropped_chunks += other.dropped_chunks;
        self.dropped_bytes += other.dropped_bytes;
        self.autopilots.extend(other.autopilots.iter().copied());
        self.time_span_s = match (self.time_span_s, other.time_span_s) {
            (Some((a0, a1)), Some((b0, b1))) => Some((a0.min(b0), a1.max(b1))),
            (a, b) => a.or(b),
        };
    }

    /// Sequence counts summed over the senders `pick` chooses.
    fn sequence_summary(&self, pick: impl Fn(&SenderId) -> bool) -> SequenceSummary {
        let picked = || {
            self.sequence
                .iter()
                .filter(|(s, _)| pick(s))
                .map(|(_, c)| c)
        };
        SequenceSummary {
            senders: picked().count() as u64,
            lost: picked().map(|s| s.lost).sum(),
            repeated: picked().map(|s| s.repeated).sum(),
            late: picked().map(|s| s.late).sum(),
            restarts: picked().map(|s| s.restarts).sum(),
        }
    }

    /// The JSON object `--summary-json` writes under `"ingest"`.
    pub fn to_summary(&self) -> IngestSummary {
        IngestSummary {
            messages: self.messages_by_name(),
            messages_total: self.messages_total(),
            mavlink_version: VersionCounts {
                v1: self.by_version[0],
                v2: self.by_version[1],
            },
            tlog_records: self.tlog_records,
            bad_frames: BadFrames {
                bad_crc: self.bad_crc,
                unknown_message_id: self.unknown_ids.values().sum(),
                unknown_message_ids: self
                    .unknown_ids
                    .iter()
                    .map(|(id, n)| (id.to_string(), *n))
                    .collect(),
                bad_incompat_flags: self.bad_incompat_flags,
                garbage_bytes: self.garbage_bytes,
                resyncs: self.resyncs,
            },
            truncated: self.truncated_at.map(|(offset, bytes)| Truncated {
                at_byte: offset,
                bytes_left: bytes,
            }),
            rejected: self
                .rejected
                .iter()
                .map(|(k, v)| (k.as_str(), *v))
                .collect(),
            clock_backwards: self.clock_backwards,
            clock_outliers: self.clock_outliers,
            clock_jumps: self.clock_jumps,
            live: Live {
                dropped_chunks: self.dropped_chunks,
                dropped_bytes: self.dropped_bytes,
            },
            sequence: self.sequence_summary(|s| self.autopilots.contains(s)),
            forwarded_sequence: self.sequence_summary(|s| !self.autopilots.contains(s)),
            senders: self
                .by_sender
                .iter()
                .map(|(s, n)| (s.to_string(), *n))
                .collect(),
            time_span: self.time_span_s.map(|(first_s, last_s)| TimeSpan {
                first_s,
                last_s,
                span_s: last_s - first_s,
            }),
        }
    }
}

/// Serialized form of [`IngestStats`].
#[derive(Debug, Clone, Serialize)]
pub struct IngestSummary {
    /// Valid messages per MAVLink message name.
    pub messages: BTreeMap<&'static str, u64>,
    /// Sum of `messages`.
    pub messages_total: u64,
    /// Valid messages per protocol version.
    pub mavlink_version: VersionCounts,
    /// tlog records read.
    pub tlog_records: u64,
    /// Frames and bytes that were not valid messages.
    pub bad_frames: BadFrames,
    /// Where the input ended inside a record, if it did.
    pub truncated: Option<Truncated>,
    /// Values rejected after decoding, per reason.
    pub rejected: BTreeMap<&'static str, u64>,
    /// Receive/tlog timestamps that went backwards (clamped to the last one).
    pub clock_backwards: u64,
    /// Single timestamps more than an hour ahead, not followed.
    pub clock_outliers: u64,
    /// Jumps of more than an hour ahead that the next timestamp confirmed, followed.
    pub clock_jumps: u64,
    /// Live link counters (zero for replays).
    pub live: Live,
    /// Frames lost, repeated or late by the autopilots' sequence numbers (the link's own
    /// quality; per sender under `vehicles`).
    pub sequence: SequenceSummary,
    /// The same for every other sender (GCSs, companion computers a vehicle forwards; a tlog
    /// with no heartbeat has only these).
    pub forwarded_sequence: SequenceSummary,
    /// Valid messages per "sysid/compid".
    pub senders: BTreeMap<String, u64>,
    /// First and last receive/tlog time, seconds.
    pub time_span: Option<TimeSpan>,
}

/// Sequence counts summed over senders.
#[derive(Debug, Clone, Serialize)]
pub struct SequenceSummary {
    /// Senders summed.
    pub senders: u64,
    /// Times a sender's bookkeeping restarted (a reboot, or a silence).
    pub restarts: u64,
    /// Frames missing from the sequence (lost on the link or before the recording).
    pub lost: u64,
    /// Frames whose sequence number repeated the previous one (duplicated by the link).
    pub repeated: u64,
    /// Frames older than the previous one (reordered by the link).
    pub late: u64,
}

/// One sender's sequence-number bookkeeping. MAVLink's 8-bit sequence counts each sender's
/// frames; a jump of 2..=128 means frames were lost, 0 a repeat, more than 128 (a step back) a
/// late frame, which is then no longer lost. Runs of more than 127 lost frames in a row are
/// undercounted by 256 each. After a silence of [`SequenceCounts::SILENCE_S`], or a pause of
/// [`SequenceCounts::REBOOT_PAUSE_S`] ending in sequence 0 (a reboot), the bookkeeping
/// restarts: what a silence lost cannot be told.
///
/// ```
/// use savsim::codec::stats::SequenceCounts;
/// let mut s = SequenceCounts::starting_at(10);
/// for seq in [10, 11, 14, 14, 12, 15, 100] {
///     s.observe(seq);
/// }
/// assert_eq!((s.lost, s.repeated, s.late), (1 + 84, 1, 1));
/// // A reboot: 5 s of silence, then the sequence starts again at 0. Nothing is late or lost.
/// let mut r = SequenceCounts::starting_at(0);
/// for (seq, t_s) in [(0, 0.0), (1, 0.1), (2, 0.2), (0, 5.2), (1, 5.3)] {
///     r.observe_at(seq, t_s);
/// }
/// assert_eq!((r.lost, r.late, r.restarts), (0, 0, 1));
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize)]
pub struct SequenceCounts {
    /// The newest sequence number seen.
    pub last: u8,
    /// Frames missing.
    pub lost: u64,
    /// Repeats.
    pub repeated: u64,
    /// Late (reordered) frames.
    pub late: u64,
    /// Restarts (reboots, silences).
    pub restarts: u64,
    /// When the last frame came, s.
    #[serde(skip)]
    last_t_s: Option<f64>,
    /// When the bookkeeping last restarted, s.
    #[serde(skip)]
    restarted_t_s: Option<f64>,
}

impl SequenceCounts {
    /// Bookkeeping whose next expected frame is `first` (call [`SequenceCounts::observe`]
    /// with it).
    pub fn starting_at(first: u8) -> Self {
        Self {
            last: first.wrapping_sub(1),
            ..Self::default()
        }
    }

    /// A silence this long restarts the bookkeeping, s: longer than a lost heartbeat or two
    /// (1 Hz), shorter than a reboot of ArduPilot or PX4 SITL.
    pub const SILENCE_S: f64 = 2.5;

    /// Start again at `sequence` (the next frame's), counting a restart.
    pub fn restart(&mut self, sequence: u8) {
        self.last = sequence.wrapping_sub(1);
        self.restarts += 1;
    }

    /// A sequence starting again at 0 after a pause this long is a reboot, s: shorter than any
    /// autopilot's silence across a restart (PX4 SITL's, the shortest seen, is in
    /// docs/live.md), longer than a gap in a stream of positions; a stream this slow is only
    /// heartbeats, whose 0 after 255 continues the count anyway.
    pub const REBOOT_PAUSE_S: f64 = 0.2;

    /// The sender rebooted (told by its clock, at `t_s`): restart at `sequence`, unless a pause
    /// restarted the bookkeeping in the last 60 s (the same reboot, seen first by its silence).
    pub fn rebooted(&mut self, sequence: u8, t_s: f64) {
        if self.restarted_t_s.is_some_and(|r| t_s - r < 60.0) {
            return;
        }
        self.restart(sequence);
        self.restarted_t_s = Some(t_s);
    }

    /// Note the next frame's sequence number, received at `t_s`.
    pub fn observe_at(&mut self, sequence: u8, t_s: f64) {
        let pause_s = self.last_t_s.map_or(0.0, |last| t_s - last);
        let restarted_at_zero = sequence == 0 && sequence != self.last.wrapping_add(1);
        if pause_s > Self::SILENCE_S || (pause_s > Self::REBOOT_PAUSE_S && restarted_at_zero) {
            self.restart(sequence);
            self.restarted_t_s = Some(t_s);
        }
        self.last_t_s = Some(t_s);
        self.observe(sequence);
    }

    /// Note the next frame's sequence number.
    pub fn observe(&mut self, sequence: u8) {
        match sequence.wrapping_sub(self.last) {
            0 => self.repeated += 1,
            step @ 1..=128 => {
                self.lost += u64::from(step - 1);
                self.last = sequence;
            }
            // A late frame was counted lost when its successor came.
            _ => {
                self.late += 1;
                self.lost = self.lost.saturating_sub(1);
            }
        }
    }
}

/// Valid messages per protocol version.
#[derive(Debug, Clone, Serialize)]
pub struct VersionCounts {
    /// MAVLink 1 frames.
    pub v1: u64,
    /// MAVLink 2 frames.
    pub v2: u64,
}

/// Frames and bytes that were not valid messages.
#[derive(Debug, Clone, Serialize)]
pub struct BadFrames {
    /// Frames whose checksum failed.
    pub bad_crc: u64,
    /// Frames with ids the dialect does not define.
    pub unknown_message_id: u64,
    /// The same, per id.
    pub unknown_message_ids: BTreeMap<String, u64>,
    /// v2 frames with unknown incompatibility flags.
    pub bad_incompat_flags: u64,
    /// Bytes skipped because no frame could start there.
    pub garbage_bytes: u64,
    /// Searches for the next frame after garbage.
    pub resyncs: u64,
}

/// Where an input ended inside a record.
#[derive(Debug, Clone, Serialize)]
pub struct Truncated {
    /// Byte offset of the incomplete record.
    pub at_byte: u64,
    /// Bytes from there to the end of the input.
    pub bytes_left: u64,
}

/// First and last receive/tlog time.
#[derive(Debug, Clone, Serialize)]
pub struct TimeSpan {
    /// First time, seconds.
    pub first_s: f64,
    /// Last time, seconds.
    pub last_s: f64,
    /// last - first, seconds.
    pub span_s: f64,
}

/// Live link counters.
#[derive(Debug, Clone, Serialize)]
pub struct Live {
    /// Datagrams or reads dropped because the session thread was behind.
    pub dropped_chunks: u64,
    /// Bytes in those.
    pub dropped_bytes: u64,
}
