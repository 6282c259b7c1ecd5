//! PX4 ULog files (`.ulg`): topics described by the log's own format messages, read
//! generically.
//!
//! A file is a 16-byte header (`ULog` magic, version, start time) then messages, each
//! `size: u16, type: u8, payload`. Formats (`F`) describe topics field by field (nested types
//! and arrays included); subscriptions (`A`) bind a message id to a topic and instance; data
//! (`D`) carries one sample. Dropouts (`O`) and data appended after a crash (the flag bits'
//! appended offsets) are honoured as pyulog does; a message of an unknown type or cut by the
//! end of the file is counted, and the read resumes at the next sync marker.

use std::collections::HashMap;
use std::sync::Arc;

/// The first bytes of every ULog file.
pub const MAGIC: [u8; 7] = *b"ULog\x01\x12\x35";
const HEADER_LEN: usize = 16;
const MSG_HEADER_LEN: usize = 3;
const SYNC: [u8; 8] = [0x2F, 0x73, 0x13, 0x20, 0x25, 0x0C, 0xBB, 0x12];

/// Why a file cannot be read as ULog at all.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum UlogError {
    /// The file does not start with ULog's magic bytes.
    #[error("not a ULog file (no ULog magic at the start)")]
    WrongMagic,
    /// The file ends inside the 16-byte header.
    #[error("ULog file cut inside its 16-byte header")]
    CutHeader,
    /// A topic's format that no data message could fill: more than [`MAX_LAYOUT_BYTES`]
    /// bytes, an array count beyond that, nesting deeper than [`MAX_NESTING`], a type that
    /// contains itself, or a field that is not `type name`.
    #[error("ULog format of topic {topic:?}: {why}")]
    BadFormat {
        /// The topic whose samples were to be read.
        topic: String,
        /// What is wrong with its format (or a nested type's).
        why: FormatProblem,
    },
}

/// What is wrong with a ULog format.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum FormatProblem {
    /// The flattened layout is larger than any message's payload.
    #[error("larger than a message's {MAX_LAYOUT_BYTES}-byte payload")]
    TooLarge,
    /// Nested more deeply than [`MAX_NESTING`] (or a type that contains itself).
    #[error("types nested more than {MAX_NESTING} deep")]
    TooDeep,
    /// A field that is not `type name` or `type[count] name`.
    #[error("field {0:?} is not `type name` or `type[count] name`")]
    BadField(String),
}

/// The largest payload a ULog message can carry (its size is a `u16`), less the data
/// message's 2-byte id: no layout may be larger, so none has more fields.
pub const MAX_LAYOUT_BYTES: usize = u16::MAX as usize - 2;
/// The deepest nesting of types a format may use (PX4's messages nest two or three deep).
pub const MAX_NESTING: usize = 8;

/// A field's primitive type.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Primitive {
    I8,
    U8,
    I16,
    U16,
    I32,
    U32,
    I64,
    U64,
    F32,
    F64,
    Bool,
    Char,
}

impl Primitive {
    fn parse(name: &str) -> Option<Self> {
        Some(match name {
            "int8_t" => Primitive::I8,
            "uint8_t" => Primitive::U8,
            "int16_t" => Primitive::I16,
            "uint16_t" => Primitive::U16,
            "int32_t" => Primitive::I32,
            "uint32_t" => Primitive::U32,
            "int64_t" => Primitive::I64,
            "uint64_t" => Primitive::U64,
            "float" => Primitive::F32,
            "double" => Primitive::F64,
            "bool" => Primitive::Bool,
            "char" => Primitive::Char,
            _ => return None,
        })
    }

    fn size(self) -> usize {
        match self {
            Primitive::I8 | Primitive::U8 | Primitive::Bool | Primitive::Char => 1,
            Primitive::I16 | Primitive::U16 => 2,
            Primitive::I32 | Primitive::U32 | Primitive::F32 => 4,
            Primitive::I64 | Primitive::U64 | Primitive::F64 => 8,
        }
    }

    fn read(self, at: &[u8]) -> Option<f64> {
        fn b<const N: usize>(at: &[u8]) -> Option<[u8; N]> {
            at.get(..N)?.try_into().ok()
        }
        Some(match self {
            Primitive::I8 => f64::from(*at.first()? as i8),
            Primitive::U8 | Primitive::Bool | Primitive::Char => f64::from(*at.first()?),
            Primitive::I16 => f64::from(i16::from_le_bytes(b(at)?)),
            Primitive::U16 => f64::from(u16::from_le_bytes(b(at)?)),
            Primitive::I32 => f64::from(i32::from_le_bytes(b(at)?)),
            Primitive::U32 => f64::from(u32::from_le_bytes(b(at)?)),
            Primitive::I64 => i64::from_le_bytes(b(at)?) as f64,
            Primitive::U64 => u64::from_le_bytes(b(at)?) as f64,
            Primitive::F32 => f64::from(f32::from_le_bytes(b(at)?)),
            Primitive::F64 => f64::from_le_bytes(b(at)?),
        })
    }
}

/// A topic's fields flattened: `q[2]`, `gyro.x`... each at its byte offset.
#[derive(Debug, Clone, Default)]
pub struct Layout {
    fields: Vec<(Box<str>, usize, Primitive)>,
    size: usize,
    /// Where the `timestamp` field (a `uint64_t`) is, found once.
    timestamp: Option<usize>,
}

/// A layout with no fields.
static NO_FIELDS: Layout = Layout {
    fields: Vec::new(),
    size: 0,
    timestamp: None,
};

impl Layout {
    fn field(&self, name: &str) -> Option<(usize, Primitive)> {
        self.fields
            .iter()
            .find(|(n, _, _)| &**n == name)
            .map(|&(_, offset, kind)| (offset, kind))
    }
}

/// One sample of a topic.
#[derive(Debug, Clone, Copy)]
pub struct Sample<'a> {
    /// The topic's name.
    pub topic: &'a str,
    /// Its instance (`multi_id`).
    pub instance: u8,
    layout: &'a Layout,
    data: &'a [u8],
}

impl Sample<'_> {
    /// A field's value (`timestamp`, `lat`, `q[0]`...), `None` when the topic has no such
    /// field or the sample is too short for it.
    pub fn get(&self, field: &str) -> Option<f64> {
        let (offset, kind) = self.layout.field(field)?;
        kind.read(self.data.get(offset..)?)
    }

    /// The sample's time, microseconds on the log's clock.
    pub fn timestamp_us(&self) -> Option<u64> {
        let offset = self.layout.timestamp?;
        Some(u64::from_le_bytes(
            self.data.get(offset..offset + 8)?.try_into().ok()?,
        ))
    }

    /// A `char[N]` field as text, up to its first NUL.
    pub fn text(&self, field: &str, len: usize) -> Option<&str> {
        let (offset, _) = self.layout.field(&format!("{field}[0]"))?;
        let bytes = self.data.get(offset..offset + len)?;
        let end = bytes.iter().position(|&b| b == 0).unwrap_or(len);
        std::str::from_utf8(&bytes[..end]).ok()
    }
}

/// What a read met besides samples.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, serde::Serialize)]
pub struct UlogCounts {
    /// Data samples read.
    pub samples: u64,
    /// Dropouts the logger recorded (`O` messages).
    pub dropouts: u64,
    /// Their total length, milliseconds.
    pub dropout_ms: u64,
    /// Messages of an unknown type, or cut, or for an unknown subscription: each a skip to
    /// the next sync marker or message.
    pub corrupt: u64,
    /// Bytes skipped looking for a sync marker.
    pub skipped_bytes: u64,
}

/// A subscription: a message id bound to a topic's instance.
#[derive(Debug, Clone)]
struct Subscription {
    topic: Box<str>,
    instance: u8,
    /// Whether the reader hands its samples out (see [`UlogReader::only`]).
    wanted: bool,
    /// Its topic's layout, once resolved (until a format message changes the formats).
    layout: Option<Arc<Layout>>,
}

/// Reads the samples of a ULog file held in memory.
pub struct UlogReader<'a> {
    data: &'a [u8],
    offset: usize,
    /// Raw format texts by topic name (resolved into layouts on first use).
    formats: HashMap<Box<str>, Box<str>>,
    /// Layouts resolved so far, by type name (`None`: no format for it); cleared when a
    /// format message arrives.
    resolved: HashMap<Box<str>, Option<Arc<Layout>>>,
    subscriptions: HashMap<u16, Subscription>,
    /// The topics whose samples are handed out (all when `None`).
    only: Option<&'a [&'a str]>,
    parameters: HashMap<Box<str>, f64>,
    /// Where appended data starts (from the flag bits), ascending; passed ones removed.
    appended: Vec<usize>,
    /// The header's start time, microseconds.
    start_us: u64,
    counts: UlogCounts,
}

impl<'a> UlogReader<'a> {
    /// A reader over `data`, or why it is not ULog.
    pub fn new(data: &'a [u8]) -> Result<Self, UlogError> {
        if !data.starts_with(&MAGIC) {
            return Err(UlogError::WrongMagic);
        }
        let start = data.get(8..HEADER_LEN).ok_or(UlogError::CutHeader)?;
        let start_us = u64::from_le_bytes(start.try_into().map_err(|_| UlogError::CutHeader)?);
        Ok(Self {
            data,
            offset: HEADER_LEN,
            formats: HashMap::new(),
            resolved: HashMap::new(),
            subscriptions: HashMap::new(),
            only: None,
            parameters: HashMap::new(),
            appended: Vec::new(),
            start_us,
            counts: UlogCounts::default(),
        })
    }

    /// Hand out only the samples of these topics (the others are counted, not decoded).
    pub fn only(mut self, topics: &'a [&'a str]) -> Self {
        self.only = Some(topics);
        self
    }

    /// What the read has met so far.
    pub fn counts(&self) -> UlogCounts {
        self.counts
    }

    /// The header's start time, microseconds on the log's clock.
    pub fn start_us(&self) -> u64 {
        self.start_us
    }

    /// A numeric parameter's value as last read (initial or changed).
    pub fn parameter(&self, name: &str) -> Option<f64> {
        self.parameters.get(name).copied()
    }

    /// The next data sample, `None` at the end of the file, or an error when a topic to be
    /// handed out has a format no message could fill ([`UlogError::BadFormat`]).
    pub fn next_sample(&mut self) -> Result<Option<Sample<'_>>, UlogError> {
        loop {
            let Some((kind, start, end)) = self.next_message() else {
                return Ok(None);
            };
            if kind != b'D' {
                self.take(kind, start, end);
                continue;
            }
            let data: &'a [u8] = self.data;
            let payload = &data[start..end];
            let Some(id) = payload.get(..2).map(|b| u16::from_le_bytes([b[0], b[1]])) else {
                self.counts.corrupt += 1;
                continue;
            };
            let Some(sub) = self.subscriptions.get(&id) else {
                self.counts.corrupt += 1;
                continue;
            };
            self.counts.samples += 1;
            if !sub.wanted {
                continue;
            }
            if sub.layout.is_none() {
                let topic = sub.topic.clone();
                let layout = self.layout(&topic)?.unwrap_or_default();
                // The same topic's other instances share it.
                for s in self.subscriptions.values_mut().filter(|s| s.topic == topic) {
                    s.layout = Some(layout.clone());
                }
            }
            let sub = &self.subscriptions[&id];
            // Set just above; an empty layout would do if it were not.
            let layout = sub.layout.as_deref().unwrap_or(&NO_FIELDS);
            return Ok(Some(Sample {
                topic: &sub.topic,
                instance: sub.instance,
                layout,
                data: &payload[2..],
            }));
        }
    }

    /// The next whole message: its type and payload range. Skips to the next appended section
    /// when a message would cross into it, and to the next sync marker after a corrupt one.
    fn next_message(&mut self) -> Option<(u8, usize, usize)> {
        loop {
            let header = self.data.get(self.offset..self.offset + MSG_HEADER_LEN)?;
            let size = usize::from(u16::from_le_bytes([header[0], header[1]]));
            let kind = header[2];
            let (start, end) = (
                self.offset + MSG_HEADER_LEN,
                self.offset + MSG_HEADER_LEN + size,
            );
            if let Some(&next) = self.appended.first() {
                if end > next && self.offset < next {
                    self.offset = next;
                    self.appended.remove(0);
                    continue;
                }
            }
            if end > self.data.len() || !b"BFIMPQADLCSOR".contains(&kind) {
                self.counts.corrupt += 1;
                self.resync();
                continue;
            }
            self.offset = end;
            return Some((kind, start, end));
        }
    }

    /// After a corrupt message: on to just past the next sync marker (or the end).
    fn resync(&mut self) {
        let from = self.offset + 1;
        let found = self
            .data
            .get(from..)
            .and_then(|rest| rest.windows(SYNC.len()).position(|w| w == SYNC));
        let next = found.map_or(self.data.len(), |at| from + at + SYNC.len());
        self.counts.skipped_bytes += (next - self.offset) as u64;
        self.offset = next;
    }

    /// Take in a message that is not data.
    fn take(&mut self, kind: u8, start: usize, end: usize) {
        let payload = &self.data[start..end];
        match kind {
            b'B' => self.take_flags(payload),
            b'F' => {
                if let Some((name, fields)) = std::str::from_utf8(payload)
                    .ok()
                    .and_then(|s| s.split_once(':'))
                {
                    self.formats.insert(name.into(), fields.into());
                    self.resolved.clear();
                    for s in self.subscriptions.values_mut() {
                        s.layout = None;
                    }
                }
            }
            b'A' if payload.len() > 3 => {
                let id = u16::from_le_bytes([payload[1], payload[2]]);
                let topic = String::from_utf8_lossy(&payload[3..]);
                let topic = topic.trim_end_matches('\0');
                let wanted = self.only.is_none_or(|only| only.contains(&topic));
                self.subscriptions.insert(
                    id,
                    Subscription {
                        topic: topic.into(),
                        instance: payload[0],
                        wanted,
                        layout: None,
                    },
                );
            }
            b'P' => self.take_parameter(payload),
            b'O' if payload.len() >= 2 => {
                self.counts.dropouts += 1;
                self.counts.dropout_ms += u64::from(u16::from_le_bytes([payload[0], payload[1]]));
            }
            _ => {}
        }
    }

    fn take_flags(&mut self, payload: &[u8]) {
        if payload.len() < 40 || payload[8] & 1 == 0 {
            return;
        }
        self.appended = payload[16..40]
            .chunks_exact(8)
            .filter_map(|b| b.try_into().ok().map(u64::from_le_bytes))
            .filter(|&at| at > 0)
            .filter_map(|at| usize::try_from(at).ok())
            .filter(|&at| at > self.offset)
            .collect();
        self.appended.sort_unstable();
    }

    fn take_parameter(&mut self, payload: &[u8]) {
        let Some((&key_len, rest)) = payload.split_first() else {
            return;
        };
        let Some((key, value)) = rest.split_at_checked(usize::from(key_len)) else {
            return;
        };
        let Some((kind, name)) = std::str::from_utf8(key)
            .ok()
            .and_then(|k| k.split_once(' '))
        else {
            return;
        };
        let value = match kind {
            "int32_t" => Primitive::I32.read(value),
            "float" => Primitive::F32.read(value),
            _ => None,
        };
        if let Some(value) = value {
            self.parameters.insert(name.into(), value);
        }
    }

    /// The flattened layout of `topic` from its format, nested types resolved once each (and
    /// kept in `resolved` until a format message changes the formats). `Ok(None)` for a type
    /// with no format; an error for a format no message could fill.
    fn layout(&mut self, topic: &str) -> Result<Option<Arc<Layout>>, UlogError> {
        resolve(&self.formats, &mut self.resolved, topic, 0).map_err(|why| UlogError::BadFormat {
            topic: topic.to_owned(),
            why,
        })
    }
}

/// `topic`'s layout from `formats`, memoised in `resolved`: each type is flattened once, so a
/// type used as an array of nested types costs its fields, not the fields of every element
/// resolved again. Sizes are checked before anything is allocated for them.
fn resolve(
    formats: &HashMap<Box<str>, Box<str>>,
    resolved: &mut HashMap<Box<str>, Option<Arc<Layout>>>,
    topic: &str,
    depth: usize,
) -> Result<Option<Arc<Layout>>, FormatProblem> {
    if let Some(known) = resolved.get(topic) {
        return Ok(known.clone());
    }
    if depth > MAX_NESTING {
        return Err(FormatProblem::TooDeep);
    }
    let Some(format) = formats.get(topic) else {
        return Ok(None);
    };
    let mut layout = Layout::default();
    for field in format.split(';').filter(|f| !f.is_empty()) {
        let bad = || FormatProblem::BadField(field.chars().take(80).collect());
        let (kind, name) = field.split_once(' ').ok_or_else(bad)?;
        let (kind, count, array) = match kind.split_once('[') {
            Some((k, n)) => {
                let n = n.strip_suffix(']').ok_or_else(bad)?;
                let count = n.parse::<usize>().map_err(|_| bad())?;
                if count > MAX_LAYOUT_BYTES {
                    return Err(FormatProblem::TooLarge);
                }
                (k, count, true)
            }
            None => (kind, 1, false),
        };
        let element = match Primitive::parse(kind) {
            Some(p) => Element::Primitive(p),
            None => match resolve(formats, resolved, kind, depth + 1)? {
                Some(nested) => Element::Nested(nested),
                // A nested type with no format: the topic cannot be read (as before).
                None => return Ok(None),
            },
        };
        let element_size = element.size();
        if layout.size + count.saturating_mul(element_size) > MAX_LAYOUT_BYTES {
            return Err(FormatProblem::TooLarge);
        }
        for i in 0..count {
            let name = if array {
                format!("{name}[{i}]")
            } else {
                name.to_string()
            };
            match &element {
                Element::Primitive(p) => layout.fields.push((name.into(), layout.size, *p)),
                Element::Nested(nested) => {
                    for (n, offset, p) in &nested.fields {
                        let full = format!("{name}.{n}");
                        layout.fields.push((full.into(), layout.size + offset, *p));
                    }
                }
            }
            layout.size += element_size;
        }
    }
    layout.timestamp = layout
        .fields
        .iter()
        .find(|(n, _, p)| &**n == "timestamp" && *p == Primitive::U64)
        .map(|&(_, offset, _)| offset);
    let layout = Some(Arc::new(layout));
    resolved.insert(topic.into(), layout.clone());
    Ok(layout)
}

/// One element of a format's field: a primitive, or a nested type's layout.
enum Element {
    Primitive(Primitive),
    Nested(Arc<Layout>),
}

impl Element {
    fn size(&self) -> usize {
        match self {
            Element::Primitive(p) => p.size(),
            Element::Nested(l) => l.size,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A ULog file: the header, then `(type, payload)` messages.
    fn ulog(messages: &[(u8, Vec<u8>)]) -> Vec<u8> {
        let mut out = MAGIC.to_vec();
        out.push(1);
        out.extend_from_slice(&0u64.to_le_bytes());
        for (kind, payload) in messages {
            out.extend_from_slice(&(payload.len() as u16).to_le_bytes());
            out.push(*kind);
            out.extend_from_slice(payload);
        }
        out
    }

    /// Formats, a subscription of `topic` as id 0, and one data message of `data_len` bytes.
    fn log_of(formats: &[&str], topic: &str, data_len: usize) -> Vec<u8> {
        let mut messages: Vec<(u8, Vec<u8>)> = formats
            .iter()
            .map(|f| (b'F', f.as_bytes().to_vec()))
            .collect();
        let mut subscribe = vec![0u8, 0, 0];
        subscribe.extend_from_slice(topic.as_bytes());
        messages.push((b'A', subscribe));
        messages.push((b'D', vec![0u8; 2 + data_len]));
        ulog(&messages)
    }

    fn first(data: &[u8]) -> Result<Option<usize>, UlogError> {
        let mut reader = UlogReader::new(data).unwrap();
        Ok(reader.next_sample()?.map(|s| s.layout.fields.len()))
    }

    #[test]
    fn an_array_larger_than_any_message_is_an_error_not_an_allocation() {
        for count in ["100000000", "18446744073709551615", "65534"] {
            let format = format!("big:uint64_t timestamp;uint8_t[{count}] x;");
            let data = log_of(&[&format], "big", 16);
            assert!(data.len() < 1024);
            let err = first(&data).unwrap_err();
            assert!(
                matches!(&err, UlogError::BadFormat { topic, why: FormatProblem::TooLarge }
                    if topic == "big"),
                "{count}: {err}"
            );
        }
        // A count that does not parse is a bad field, not a panic.
        let data = log_of(&["t:uint8_t[99999999999999999999999] x;"], "t", 4);
        assert!(matches!(
            first(&data),
            Err(UlogError::BadFormat {
                why: FormatProblem::BadField(_),
                ..
            })
        ));
    }

    #[test]
    fn nested_arrays_that_multiply_past_a_message_are_an_error() {
        // 255 x 255 x 255 x 8 bytes: 132 MB of fields if flattened.
        let formats = [
            "a:uint64_t timestamp;b[255] x;",
            "b:c[255] y;",
            "c:uint64_t[255] z;",
        ];
        let data = log_of(&formats, "a", 16);
        assert!(data.len() < 1024);
        assert!(matches!(
            first(&data),
            Err(UlogError::BadFormat {
                why: FormatProblem::TooLarge,
                ..
            })
        ));
        // A type that contains itself.
        let data = log_of(&["loop:loop[1] x;"], "loop", 4);
        assert!(matches!(
            first(&data),
            Err(UlogError::BadFormat {
                why: FormatProblem::TooDeep,
                ..
            })
        ));
    }

    #[test]
    fn nested_types_are_flattened_once_and_read_at_their_offsets() {
        let formats = [
            "outer:uint64_t timestamp;inner[3] v;uint8_t flag;",
            "inner:float x;int16_t[2] y;",
        ];
        let mut data = log_of(&formats, "outer", 0);
        // Replace the empty data message with one that carries values.
        let cut = data.len() - 5;
        data.truncate(cut);
        let mut payload = vec![0u8, 0];
        payload.extend_from_slice(&7u64.to_le_bytes());
        for k in 0..3 {
            payload.extend_from_slice(&(k as f32 + 0.5).to_le_bytes());
            payload.extend_from_slice(&(-(k as i16)).to_le_bytes());
            payload.extend_from_slice(&(k as i16 * 10).to_le_bytes());
        }
        payload.push(1);
        data.extend_from_slice(&(payload.len() as u16).to_le_bytes());
        data.push(b'D');
        data.extend_from_slice(&payload);
        let mut reader = UlogReader::new(&data).unwrap();
        let s = reader.next_sample().unwrap().unwrap();
        assert_eq!(s.timestamp_us(), Some(7));
        assert_eq!(s.get("v[2].x"), Some(2.5));
        assert_eq!(s.get("v[1].y[0]"), Some(-1.0));
        assert_eq!(s.get("v[2].y[1]"), Some(20.0));
        assert_eq!(s.get("flag"), Some(1.0));
        assert_eq!(s.layout.fields.len(), 1 + 3 * 3 + 1);
        assert_eq!(reader.resolved.len(), 2, "inner resolved once, outer once");
    }
}
