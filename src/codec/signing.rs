//! MAVLink 2 signing (`--signing-key`, `--signing`): every frame savsim sends is signed, and
//! every frame a vehicle link brings is judged before anything else sees it. The signature
//! and the timestamp rules are the mavlink crate's (`mav2-message-signing`, as the spec at
//! mavlink.io/en/guide/message_signing.html says): SHA-256 of key, frame and timestamp; a
//! stream (link id, system, component) must move its timestamp forward; a new stream may be
//! at most a minute older than savsim's signing clock (its own clock, or the newest timestamp
//! accepted when that is later). savsim's own timestamps follow the
//! newest it accepted, so a SITL whose signing clock runs ahead at a speedup still takes them.

use std::path::Path;

use mavlink::dialects::ardupilotmega::MavMessage;
use mavlink::{MAVLinkV2MessageRaw, MavHeader, SigningConfig, SigningData};
use serde::Serialize;
use sha2::{Digest, Sha256};

use crate::codec::frame::{RawFrame, IFLAG_SIGNED, MAX_FRAME_LEN};
use crate::error::{Error, Result};

/// Why a key file gives no key.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum KeyFileError {
    /// Not 32 bytes, and not text either.
    #[error("{0} bytes: neither a 32-byte key nor a UTF-8 passphrase")]
    NotText(usize),
    /// Nothing in it (but a newline).
    #[error("empty: give a 32-byte key or a passphrase")]
    Empty,
    /// Longer than any key or passphrase (a log given by mistake).
    #[error("over {MAX_KEY_FILE} bytes: not a key or a passphrase")]
    TooLarge,
    /// A device (`/dev/zero`), not a file.
    #[error("a device, not a file: not a key or a passphrase")]
    Device,
}

/// The longest key file read, bytes; a longer one is refused, never read to its end.
pub const MAX_KEY_FILE: usize = 64 * 1024;

/// A 32-byte secret key.
#[derive(Clone, PartialEq, Eq)]
pub struct SigningKey(pub [u8; 32]);

impl std::fmt::Debug for SigningKey {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("SigningKey(..)")
    }
}

impl SigningKey {
    /// The key a passphrase gives, as MAVProxy's `signing setup PASSPHRASE` and pymavlink
    /// derive it: SHA-256 of its UTF-8 bytes.
    ///
    /// ```
    /// use savsim::codec::signing::SigningKey;
    /// let key = SigningKey::from_passphrase("abc");
    /// assert_eq!(key.0[..4], [0xba, 0x78, 0x16, 0xbf]);
    /// ```
    pub fn from_passphrase(passphrase: &str) -> Self {
        Self(Sha256::digest(passphrase.as_bytes()).into())
    }

    /// A key file's bytes: exactly 32 bytes are the key itself; anything else is a passphrase
    /// (UTF-8, one trailing newline ignored).
    pub fn from_file_bytes(bytes: &[u8]) -> std::result::Result<Self, KeyFileError> {
        if let Ok(key) = <[u8; 32]>::try_from(bytes) {
            return Ok(Self(key));
        }
        let text = std::str::from_utf8(bytes).map_err(|_| KeyFileError::NotText(bytes.len()))?;
        let text = text.strip_suffix('\n').unwrap_or(text);
        let text = text.strip_suffix('\r').unwrap_or(text);
        if text.is_empty() {
            return Err(KeyFileError::Empty);
        }
        Ok(Self::from_passphrase(text))
    }

    /// Read a key file ([`SigningKey::from_file_bytes`]), at most [`MAX_KEY_FILE`] bytes of it.
    pub fn read(path: &Path) -> Result<Self> {
        let key = match crate::files::read(path, MAX_KEY_FILE as u64) {
            Ok(bytes) => Self::from_file_bytes(&bytes),
            Err(e) if e.kind() == std::io::ErrorKind::InvalidData => Err(KeyFileError::TooLarge),
            Err(e) if e.kind() == std::io::ErrorKind::InvalidInput => Err(KeyFileError::Device),
            Err(e) => return Err(Error::file(path, e)),
        };
        key.map_err(|why| Error::Usage(format!("--signing-key {}: {why}", path.display())))
    }
}

/// What signing makes of an incoming frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Verdict {
    /// Signed with the key, its timestamp in order.
    Signed,
    /// Not signed (MAVLink 1 frames never are).
    Unsigned,
    /// Signed, but not with the key (or altered).
    BadSignature,
    /// Rightly signed, but its timestamp does not move its stream forward (a replay), or a
    /// new stream's is more than a minute old (stale).
    Replayed,
}

/// Counts of what signing judged, for the summary's `link.signing`.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize)]
pub struct SigningCounts {
    /// Frames rightly signed.
    pub signed: u64,
    /// Unsigned frames taken (`--signing accept`).
    pub unsigned_accepted: u64,
    /// Unsigned frames dropped (`--signing require`).
    pub unsigned_dropped: u64,
    /// Frames signed with another key (or altered): dropped.
    pub bad_signature: u64,
    /// Replayed or stale frames: dropped.
    pub replayed: u64,
    /// Frames savsim signed and sent.
    pub sent_signed: u64,
}

/// A key, its timestamp state, and whether unsigned frames are dropped.
pub struct Signing {
    key: [u8; 32],
    data: SigningData,
    require: bool,
}

impl std::fmt::Debug for Signing {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Signing")
            .field("require", &self.require)
            .finish()
    }
}

/// The signature's link id savsim sends with.
pub const LINK_ID: u8 = 0;

fn raw_v2(bytes: &[u8]) -> MAVLinkV2MessageRaw {
    let mut raw = MAVLinkV2MessageRaw::new();
    let n = bytes.len().min(MAX_FRAME_LEN);
    raw.as_mut_slice()[..n].copy_from_slice(&bytes[..n]);
    raw
}

impl Signing {
    /// Signing with `key`; `require` drops unsigned frames.
    pub fn new(key: &SigningKey, require: bool) -> Self {
        Self {
            key: key.0,
            data: SigningData::from_config(SigningConfig::new(key.0, LINK_ID, true, !require)),
            require,
        }
    }

    /// Whether unsigned frames are dropped.
    pub fn requires(&self) -> bool {
        self.require
    }

    /// Judge a complete frame (and, when it is rightly signed, move its stream's timestamp).
    pub fn verdict(&self, frame: &RawFrame<'_>) -> Verdict {
        let signed = frame.version == mavlink::MavlinkVersion::V2
            && frame.bytes.get(2).is_some_and(|f| f & IFLAG_SIGNED != 0);
        if !signed {
            return Verdict::Unsigned;
        }
        let raw = raw_v2(frame.bytes);
        let mut signature = [0u8; 6];
        raw.calculate_signature(&self.key, &mut signature);
        if signature != raw.signature_value() {
            Verdict::BadSignature
        } else if self.data.verify_signature(&raw) {
            Verdict::Signed
        } else {
            Verdict::Replayed
        }
    }

    /// Whether a frame is kept, counting what was judged.
    pub fn keep(&self, frame: &RawFrame<'_>, counts: &mut SigningCounts) -> bool {
        match self.verdict(frame) {
            Verdict::Signed => counts.signed += 1,
            Verdict::Unsigned if self.require => {
                counts.unsigned_dropped += 1;
                return false;
            }
            Verdict::Unsigned => counts.unsigned_accepted += 1,
            Verdict::BadSignature => {
                counts.bad_signature += 1;
                return false;
            }
            Verdict::Replayed => {
                counts.replayed += 1;
                return false;
            }
        }
        true
    }

    /// `message` as a signed MAVLink 2 frame from `header`.
    pub fn encode(&self, header: MavHeader, message: &MavMessage) -> Vec<u8> {
        let mut raw = MAVLinkV2MessageRaw::new();
        raw.serialize_message_for_signing(header, message);
        self.data.sign_message(&mut raw);
        raw.raw_bytes().to_vec()
    }
}
