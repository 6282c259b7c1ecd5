//! ArduPilot DataFlash logs (`.bin`): messages described by the log's own FMT records, read
//! generically.
//!
//! A message is `0xA3 0x95 TYPE` then the fields its FMT record declares. Bytes that do not
//! start a message of a known type are skipped one at a time and counted, as pymavlink's
//! `DFReader_binary` does; a message cut by the end of the file ends the read. Values are read
//! on demand, scaled as pymavlink scales them (`c`/`C`/`e`/`E` hundredths, `L` 1e-7 degrees).

/// The two bytes that start every message.
pub const HEAD: [u8; 2] = [0xA3, 0x95];
/// The message type of FMT, the record that describes the others.
const FMT_TYPE: u8 = 0x80;
/// FMT's whole length: header, Type, Length, Name[4], Format[16], Columns[64].
const FMT_LEN: usize = 89;
const HEADER_LEN: usize = 3;

/// One column of a message format.
#[derive(Debug, Clone)]
struct Column {
    name: Box<str>,
    /// Offset in the payload (after the 3-byte header), bytes.
    offset: usize,
    /// Its format character.
    kind: u8,
}

/// A message type as its FMT record describes it.
#[derive(Debug, Clone)]
pub struct Format {
    /// The type's name (ATT, POS, GPS...).
    pub name: Box<str>,
    /// The whole message's length, header included, bytes.
    len: usize,
    /// `None` when the FMT record contradicts itself.
    columns: Option<Vec<Column>>,
}

impl Format {
    /// The type a FMT payload describes and its format; the format has no columns when it is
    /// inconsistent (its declared length differs from what its format characters add up to,
    /// or a character is unknown): its messages are then stepped over, as pymavlink does.
    fn parse(payload: &[u8]) -> (u8, Format) {
        let (msg_type, len) = (payload[0], usize::from(payload[1]));
        let name = text(&payload[2..6]);
        let kinds = text(&payload[6..22]);
        let names = text(&payload[22..86]);
        let columns = columns(kinds, names).filter(|(_, size)| size + HEADER_LEN == len);
        let format = Format {
            name: name.into(),
            len: len.max(HEADER_LEN),
            columns: columns.map(|(c, _)| c),
        };
        (msg_type, format)
    }

    fn column(&self, name: &str) -> Option<&Column> {
        self.columns.as_ref()?.iter().find(|c| &*c.name == name)
    }
}

/// The columns that format characters `kinds` and comma-separated `names` describe, and the
/// bytes they take; `None` for a character DataFlash does not define.
fn columns(kinds: &str, names: &str) -> Option<(Vec<Column>, usize)> {
    let mut columns = Vec::with_capacity(kinds.len());
    let mut offset = 0;
    let mut names = names.split(',');
    for kind in kinds.bytes() {
        columns.push(Column {
            name: names.next().unwrap_or("").into(),
            offset,
            kind,
        });
        offset += size_of_kind(kind)?;
    }
    Some((columns, offset))
}

/// Bytes of a value of format character `kind`; `None` for a character DataFlash does not
/// define.
fn size_of_kind(kind: u8) -> Option<usize> {
    Some(match kind {
        b'b' | b'B' | b'M' => 1,
        b'h' | b'H' | b'c' | b'C' => 2,
        b'i' | b'I' | b'f' | b'e' | b'E' | b'L' | b'n' => 4,
        b'd' | b'q' | b'Q' => 8,
        b'N' => 16,
        b'Z' | b'a' => 64,
        _ => return None,
    })
}

/// The first `N` bytes of `at`.
fn bytes<const N: usize>(at: &[u8]) -> Option<[u8; N]> {
    at.get(..N)?.try_into().ok()
}

/// ASCII up to the first NUL (a name, a format, a column list).
fn text(bytes: &[u8]) -> &str {
    let end = bytes.iter().position(|&b| b == 0).unwrap_or(bytes.len());
    std::str::from_utf8(&bytes[..end]).unwrap_or("")
}

/// One message of a log.
#[derive(Debug, Clone, Copy)]
pub struct Message<'a> {
    /// Its format.
    pub format: &'a Format,
    /// Its fields, after the header.
    payload: &'a [u8],
}

impl Message<'_> {
    /// The type's name.
    pub fn name(&self) -> &str {
        &self.format.name
    }

    /// A numeric column's value, scaled as pymavlink scales it; `None` when the type has no
    /// such column or it is text.
    pub fn get(&self, column: &str) -> Option<f64> {
        let c = self.format.column(column)?;
        let at = &self.payload[c.offset..];
        Some(match c.kind {
            b'b' => f64::from(at[0] as i8),
            b'B' | b'M' => f64::from(at[0]),
            b'h' => f64::from(i16::from_le_bytes(bytes(at)?)),
            b'H' => f64::from(u16::from_le_bytes(bytes(at)?)),
            b'c' => f64::from(i16::from_le_bytes(bytes(at)?)) * 0.01,
            b'C' => f64::from(u16::from_le_bytes(bytes(at)?)) * 0.01,
            b'i' => f64::from(i32::from_le_bytes(bytes(at)?)),
            b'I' => f64::from(u32::from_le_bytes(bytes(at)?)),
            b'e' => f64::from(i32::from_le_bytes(bytes(at)?)) * 0.01,
            b'E' => f64::from(u32::from_le_bytes(bytes(at)?)) * 0.01,
            b'L' => f64::from(i32::from_le_bytes(bytes(at)?)) * 1e-7,
            b'f' => f64::from(f32::from_le_bytes(bytes(at)?)),
            b'd' => f64::from_le_bytes(bytes(at)?),
            b'q' => i64::from_le_bytes(bytes(at)?) as f64,
            b'Q' => u64::from_le_bytes(bytes(at)?) as f64,
            _ => return None,
        })
    }

    /// A text column (`n`, `N`, `Z`), up to its first NUL.
    pub fn text(&self, column: &str) -> Option<&str> {
        let c = self.format.column(column)?;
        let size = size_of_kind(c.kind)?;
        matches!(c.kind, b'n' | b'N' | b'Z').then(|| text(&self.payload[c.offset..][..size]))
    }
}

/// What a read met besides messages.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, serde::Serialize)]
pub struct DataflashCounts {
    /// Messages read, FMT records included.
    pub messages: u64,
    /// Bytes skipped because they did not start a message of a known type.
    pub skipped_bytes: u64,
    /// FMT records that contradict themselves (their messages are stepped over).
    pub bad_formats: u64,
    /// Messages of such a type, stepped over.
    pub unreadable: u64,
    /// Byte offset of a message cut by the end of the file, if one was.
    pub truncated_at: Option<u64>,
}

/// Reads the messages of a DataFlash log held in memory.
///
/// ```
/// use savsim::logs::dataflash::DataflashReader;
/// // A FMT describing type 0x81 "TST" with one uint16 column "V", then a TST message.
/// let mut log = vec![0xA3, 0x95, 0x80, 0x81, 5];
/// let field = |s: &str, n: usize| { let mut v = s.as_bytes().to_vec(); v.resize(n, 0); v };
/// log.extend(field("TST", 4));
/// log.extend(field("H", 16));
/// log.extend(field("V", 64));
/// log.extend([0xA3, 0x95, 0x81, 0x34, 0x12]);
/// let mut reader = DataflashReader::new(&log);
/// assert_eq!(reader.next_message().unwrap().name(), "FMT");
/// let m = reader.next_message().unwrap();
/// assert_eq!((m.name(), m.get("V")), ("TST", Some(4660.0)));
/// assert!(reader.next_message().is_none());
/// assert_eq!(reader.counts().messages, 2);
/// ```
pub struct DataflashReader<'a> {
    data: &'a [u8],
    offset: usize,
    formats: Vec<Option<Format>>,
    counts: DataflashCounts,
}

impl<'a> DataflashReader<'a> {
    /// A reader at the start of `data`.
    pub fn new(data: &'a [u8]) -> Self {
        let fmt = Format {
            name: "FMT".into(),
            len: FMT_LEN,
            columns: columns("BBnNZ", "Type,Length,Name,Format,Columns").map(|(c, _)| c),
        };
        let mut formats = vec![None; 256];
        formats[usize::from(FMT_TYPE)] = Some(fmt);
        Self {
            data,
            offset: 0,
            formats,
            counts: DataflashCounts::default(),
        }
    }

    /// What the read has met so far.
    pub fn counts(&self) -> DataflashCounts {
        self.counts
    }

    /// The next message, or `None` at the end of the data.
    pub fn next_message(&mut self) -> Option<Message<'_>> {
        loop {
            let (msg_type, len) = self.find_next()?;
            let start = self.offset;
            self.offset += len;
            let payload = &self.data[start + HEADER_LEN..start + len];
            if msg_type == FMT_TYPE {
                self.learn(payload);
            }
            if self.formats[usize::from(msg_type)]
                .as_ref()
                .is_some_and(|f| f.columns.is_none())
            {
                self.counts.unreadable += 1;
                continue;
            }
            self.counts.messages += 1;
            let format = self.formats[usize::from(msg_type)].as_ref()?;
            return Some(Message { format, payload });
        }
    }

    /// Take in a FMT record (FMT's own format stays as DataFlash defines it).
    fn learn(&mut self, payload: &[u8]) {
        let (described, format) = Format::parse(payload);
        if format.columns.is_none() {
            self.counts.bad_formats += 1;
        }
        if described != FMT_TYPE {
            self.formats[usize::from(described)] = Some(format);
        }
    }

    /// Skips to the next message of a known type that fits in the data: its type and length.
    fn find_next(&mut self) -> Option<(u8, usize)> {
        loop {
            let rest = self.data.get(self.offset..)?;
            if rest.len() < HEADER_LEN {
                self.counts.skipped_bytes += rest.len() as u64;
                self.offset = self.data.len();
                return None;
            }
            let known = self.formats[usize::from(rest[2])].as_ref().map(|f| f.len);
            match known {
                Some(len) if rest[..2] == HEAD => {
                    if rest.len() < len {
                        self.counts.truncated_at = Some(self.offset as u64);
                        self.offset = self.data.len();
                        return None;
                    }
                    return Some((rest[2], len));
                }
                _ => {
                    self.counts.skipped_bytes += 1;
                    self.offset += 1;
                }
            }
        }
    }
}
