//! MAVLink v1/v2 framing over a byte slice: find a frame, check its length, flags and CRC.
//!
//! Pure and allocation-free; the one framer behind tlog replay, UDP datagrams and TCP streams.
//! It decides what a frame is and nothing else: decoding the payload is `decode`'s job. The
//! dialect (ardupilotmega, a superset of common) supplies each message's CRC_EXTRA and name
//! through [`message_info`].

use std::sync::OnceLock;

use mavlink::dialects::ardupilotmega::MavMessage;
use mavlink::{MavlinkVersion, Message};

/// MAVLink v1 start byte.
pub const MAGIC_V1: u8 = 0xFE;
/// MAVLink v2 start byte.
pub const MAGIC_V2: u8 = 0xFD;
/// Bytes before the payload of a v1 frame (magic, len, seq, sysid, compid, msgid).
pub const HEADER_LEN_V1: usize = 6;
/// Bytes before the payload of a v2 frame (magic, len, incompat, compat, seq, sysid, compid, msgid x3).
pub const HEADER_LEN_V2: usize = 10;
/// Length of a v2 signature block, present when incompat flag 0x01 is set.
pub const SIGNATURE_LEN: usize = 13;
/// The only incompatibility flag MAVLink v2 defines (signed frame).
pub const IFLAG_SIGNED: u8 = 0x01;
/// The longest frame there can be (v2, 255-byte payload, signed).
pub const MAX_FRAME_LEN: usize = HEADER_LEN_V2 + 255 + 2 + SIGNATURE_LEN;

/// A message id's name and CRC_EXTRA in the dialect.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct MessageInfo {
    /// MAVLink message name, e.g. `GLOBAL_POSITION_INT`.
    pub name: &'static str,
    /// The CRC_EXTRA byte folded into the frame checksum.
    pub extra_crc: u8,
}

const TABLE_LEN: usize = 1 << 16;

fn lookup(id: u32) -> Option<MessageInfo> {
    MavMessage::default_message_from_id(id).map(|message| MessageInfo {
        name: message.message_name(),
        extra_crc: MavMessage::extra_crc(id),
    })
}

/// The dialect's knowledge of message `id`, or `None` for an id it does not define.
///
/// ```
/// use savsim::codec::frame::message_info;
/// assert_eq!(message_info(33).unwrap().name, "GLOBAL_POSITION_INT");
/// assert_eq!(message_info(33).unwrap().extra_crc, 104);
/// assert!(message_info(9_999_999).is_none());
/// ```
pub fn message_info(id: u32) -> Option<MessageInfo> {
    static TABLE: OnceLock<Vec<Option<MessageInfo>>> = OnceLock::new();
    match usize::try_from(id) {
        Ok(index) if index < TABLE_LEN => {
            TABLE.get_or_init(|| (0..TABLE_LEN as u32).map(lookup).collect())[index]
        }
        _ => lookup(id),
    }
}

/// Whether a complete frame's checksum held.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FrameStatus {
    /// Known message, CRC matches.
    Valid,
    /// Known message, CRC does not match (corruption, or another definition of the message).
    BadCrc,
    /// The dialect does not define this message id, so its CRC cannot be checked.
    UnknownMessage,
    /// A v2 frame with incompatibility flags savsim does not understand.
    BadIncompatFlags,
}

/// A complete frame found at the start of a slice.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct RawFrame<'a> {
    /// Protocol version of the frame.
    pub version: MavlinkVersion,
    /// Sender system id.
    pub system_id: u8,
    /// Sender component id.
    pub component_id: u8,
    /// Packet sequence number.
    pub sequence: u8,
    /// Message id (24 bits in v2).
    pub message_id: u32,
    /// Payload bytes (v2 payloads may be truncated of trailing zeros).
    pub payload: &'a [u8],
    /// The whole frame, magic byte to checksum (and signature).
    pub bytes: &'a [u8],
    /// Total bytes the frame occupies, checksum and signature included.
    pub len: usize,
    /// Checksum verdict.
    pub status: FrameStatus,
}

/// What lies at the start of a byte slice.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Scan<'a> {
    /// A complete frame (valid or not: see its status).
    Frame(RawFrame<'a>),
    /// The slice holds the start of a frame but not all of it (or nothing at all).
    Incomplete,
    /// The first `n` bytes cannot start a frame: skip them.
    Garbage(usize),
}

/// Look at the start of `bytes` for one MAVLink frame.
///
/// ```
/// use savsim::codec::frame::{scan, Scan, FrameStatus};
/// // A v1 HEARTBEAT from sysid 1, compid 1 (the bytes pymavlink writes).
/// let bytes = [0xfe, 9, 0, 1, 1, 0, 4, 0, 0, 0, 2, 3, 81, 3, 3, 0xe4, 0xe1];
/// match scan(&bytes) {
///     Scan::Frame(f) => {
///         assert_eq!((f.system_id, f.message_id, f.len), (1, 0, 17));
///         assert_eq!(f.status, FrameStatus::Valid);
///     }
///     other => panic!("{other:?}"),
/// }
/// assert_eq!(scan(&bytes[..5]), Scan::Incomplete);
/// assert_eq!(scan(&[0x00, 0x11, 0xfe]), Scan::Garbage(2));
/// ```
pub fn scan(bytes: &[u8]) -> Scan<'_> {
    let Some(&magic) = bytes.first() else {
        return Scan::Incomplete;
    };
    let (version, header_len) = match magic {
        MAGIC_V1 => (MavlinkVersion::V1, HEADER_LEN_V1),
        MAGIC_V2 => (MavlinkVersion::V2, HEADER_LEN_V2),
        _ => {
            let skip = bytes
                .iter()
                .position(|&b| b == MAGIC_V1 || b == MAGIC_V2)
                .unwrap_or(bytes.len());
            return Scan::Garbage(skip);
        }
    };
    if bytes.len() < header_len {
        return Scan::Incomplete;
    }
    let payload_len = usize::from(bytes[1]);
    let (incompat, signature_len) = match version {
        MavlinkVersion::V1 => (0, 0),
        MavlinkVersion::V2 => {
            let flags = bytes[2];
            (
                flags,
                if flags & IFLAG_SIGNED != 0 {
                    SIGNATURE_LEN
                } else {
                    0
                },
            )
        }
    };
    let len = header_len + payload_len + 2 + signature_len;
    if bytes.len() < len {
        return Scan::Incomplete;
    }
    let frame = frame_with_status(bytes, version, header_len, len, FrameStatus::Valid);
    let status = if incompat & !IFLAG_SIGNED != 0 {
        FrameStatus::BadIncompatFlags
    } else {
        match message_info(frame.message_id) {
            None => FrameStatus::UnknownMessage,
            Some(info) => {
                let crc_end = header_len + payload_len;
                let crc = u16::from_le_bytes([bytes[crc_end], bytes[crc_end + 1]]);
                if mavlink::calculate_crc(&bytes[1..crc_end], info.extra_crc) == crc {
                    FrameStatus::Valid
                } else {
                    FrameStatus::BadCrc
                }
            }
        }
    };
    Scan::Frame(RawFrame { status, ..frame })
}

/// The frame at the start of `bytes`, whose extent and status a previous [`scan`] established.
/// Reads the header only: no checksum work.
pub(crate) fn frame_known(bytes: &[u8], status: FrameStatus) -> RawFrame<'_> {
    let (version, header_len) = if bytes[0] == MAGIC_V2 {
        (MavlinkVersion::V2, HEADER_LEN_V2)
    } else {
        (MavlinkVersion::V1, HEADER_LEN_V1)
    };
    frame_with_status(bytes, version, header_len, bytes.len(), status)
}

fn frame_with_status(
    bytes: &[u8],
    version: MavlinkVersion,
    header_len: usize,
    len: usize,
    status: FrameStatus,
) -> RawFrame<'_> {
    let payload_len = usize::from(bytes[1]);
    let (sequence, system_id, component_id, message_id) = match version {
        MavlinkVersion::V1 => (bytes[2], bytes[3], bytes[4], u32::from(bytes[5])),
        MavlinkVersion::V2 => (
            bytes[4],
            bytes[5],
            bytes[6],
            u32::from_le_bytes([bytes[7], bytes[8], bytes[9], 0]),
        ),
    };
    RawFrame {
        version,
        system_id,
        component_id,
        sequence,
        message_id,
        payload: &bytes[header_len..header_len + payload_len],
        bytes: &bytes[..len],
        len,
        status,
    }
}
