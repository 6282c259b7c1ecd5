//! What an autopilot says for a person to read, from the frames it sends: its STATUSTEXTs,
//! its flight-mode changes (HEARTBEAT's custom_mode, named for ArduCopter and PX4) and the
//! changes of its COLLISION messages (threat, action, level), each as a line of text with a MAVLink severity (0 emergency .. 7
//! debug). The viewer puts them on the timeline.

use std::collections::HashMap;

use mavlink::dialects::ardupilotmega::{
    MavCollisionSrc, COLLISION_DATA, HEARTBEAT_DATA, STATUSTEXT_DATA,
};
use mavlink::{MavlinkVersion, MessageData};

use crate::codec::frame::RawFrame;
use crate::world::inputs::HeartbeatReport;
use crate::world::SenderId;

/// MAV_SEVERITY_WARNING: a COLLISION message.
pub const WARNING: u8 = 4;
/// MAV_SEVERITY_INFO: a mode change.
pub const INFO: u8 = 6;

/// One line an autopilot said.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Note {
    /// Who said it.
    pub sender: SenderId,
    /// MAV_SEVERITY: 0 emergency .. 7 debug.
    pub severity: u8,
    /// The line.
    pub text: String,
}

/// Notes from frames, remembering each sender's flight mode and last COLLISION to tell their
/// changes.
#[derive(Debug, Default)]
pub struct Notes {
    modes: HashMap<SenderId, u32>,
    /// Each sender's last COLLISION: threat id, source, action, level.
    collisions: HashMap<SenderId, (u32, u8, u8, u8)>,
}

/// The senders whose modes [`Notes`] remembers at most (a stream of forged system ids cannot
/// grow it without bound).
const MAX_SENDERS: usize = 1024;

impl Notes {
    /// The note `frame` makes, if it is a STATUSTEXT, a COLLISION unlike the sender's last, or
    /// a HEARTBEAT of an autopilot whose mode changed (its first heartbeat names its mode too).
    ///
    /// ```
    /// use mavlink::dialects::ardupilotmega::{MavMessage, STATUSTEXT_DATA, MavSeverity};
    /// use savsim::codec::{frame::{scan, Scan}, notes::Notes};
    /// let mut text = [0u8; 50];
    /// text[..13].copy_from_slice(b"ADSB: avoid 1");
    /// let m = MavMessage::STATUSTEXT(STATUSTEXT_DATA {
    ///     severity: MavSeverity::MAV_SEVERITY_WARNING, text: text.into(), ..Default::default() });
    /// let mut bytes = Vec::new();
    /// let header = mavlink::MavHeader { system_id: 1, component_id: 1, sequence: 0 };
    /// mavlink::write_versioned_msg(&mut bytes, mavlink::MavlinkVersion::V2, header, &m).unwrap();
    /// let Scan::Frame(frame) = scan(&bytes) else { panic!() };
    /// let note = Notes::default().take(&frame).unwrap();
    /// assert_eq!((note.severity, note.text.as_str()), (4, "ADSB: avoid 1"));
    /// ```
    pub fn take(&mut self, frame: &RawFrame<'_>) -> Option<Note> {
        let sender = SenderId {
            system_id: frame.system_id,
            component_id: frame.component_id,
        };
        let version = frame.version;
        let (severity, text) = match frame.message_id {
            STATUSTEXT_DATA::ID => {
                let m = STATUSTEXT_DATA::deser(version, frame.payload).ok()?;
                let bytes: &[u8] = &m.text[..];
                let end = bytes.iter().position(|b| *b == 0).unwrap_or(bytes.len());
                let text = String::from_utf8_lossy(&bytes[..end]).trim().to_string();
                (m.severity as u8, text)
            }
            COLLISION_DATA::ID => {
                let m = COLLISION_DATA::deser(version, frame.payload).ok()?;
                (WARNING, self.collision_change(sender, &m)?)
            }
            HEARTBEAT_DATA::ID => (INFO, self.mode_change(sender, version, frame.payload)?),
            _ => return None,
        };
        Some(Note {
            sender,
            severity,
            text,
        })
    }

    /// A COLLISION message as text when its threat, source, action or level differ from
    /// `sender`'s last one (an autopilot repeats it while the threat lasts).
    fn collision_change(&mut self, sender: SenderId, m: &COLLISION_DATA) -> Option<String> {
        let key = (m.id, m.src as u8, m.action as u8, m.threat_level as u8);
        if self.collisions.get(&sender) == Some(&key)
            || (!self.collisions.contains_key(&sender) && self.collisions.len() >= MAX_SENDERS)
        {
            return None;
        }
        self.collisions.insert(sender, key);
        let threat = match m.src {
            MavCollisionSrc::MAV_COLLISION_SRC_ADSB => format!("ADS-B {:06X}", m.id),
            _ => format!("system {}", m.id),
        };
        Some(format!(
            "COLLISION: threat {threat} {:?}, action {:?}, closest {:.0} m horizontal and {:.0} m \
             vertical in {:.1} s (repeats not shown until it changes)",
            m.threat_level,
            m.action,
            m.horizontal_minimum_delta,
            m.altitude_minimum_delta,
            m.time_to_minimum_delta
        ))
    }

    /// `mode NAME` when `sender`'s HEARTBEAT names a mode other than its last one.
    fn mode_change(
        &mut self,
        sender: SenderId,
        version: MavlinkVersion,
        payload: &[u8],
    ) -> Option<String> {
        let hb = HEARTBEAT_DATA::deser(version, payload).ok()?;
        let autopilot = hb.autopilot as u8;
        if autopilot == HeartbeatReport::AUTOPILOT_INVALID {
            return None;
        }
        let before = self.modes.get(&sender).copied();
        if before == Some(hb.custom_mode) || (before.is_none() && self.modes.len() >= MAX_SENDERS) {
            return None;
        }
        self.modes.insert(sender, hb.custom_mode);
        let name = match autopilot {
            HeartbeatReport::AUTOPILOT_PX4 => px4_mode_name(hb.custom_mode),
            HeartbeatReport::AUTOPILOT_ARDUPILOT if is_copter(hb.mavtype as u8) => {
                arducopter_mode_name(hb.custom_mode)
            }
            _ => format!("MODE{}", hb.custom_mode),
        };
        Some(format!("mode {name}"))
    }
}

/// Whether MAV_TYPE `t` is one ArduCopter flies: quad, coaxial, helicopter, hexa, octo, tri,
/// dodeca, deca.
fn is_copter(t: u8) -> bool {
    matches!(t, 2 | 3 | 4 | 13 | 14 | 15 | 29 | 35)
}

/// ArduCopter's name of flight mode `custom_mode`.
pub fn arducopter_mode_name(custom_mode: u32) -> String {
    const NAMES: [&str; 28] = [
        "STABILIZE",
        "ACRO",
        "ALT_HOLD",
        "AUTO",
        "GUIDED",
        "LOITER",
        "RTL",
        "CIRCLE",
        "",
        "LAND",
        "",
        "DRIFT",
        "",
        "SPORT",
        "FLIP",
        "AUTOTUNE",
        "POSHOLD",
        "BRAKE",
        "THROW",
        "AVOID_ADSB",
        "GUIDED_NOGPS",
        "SMART_RTL",
        "FLOWHOLD",
        "FOLLOW",
        "ZIGZAG",
        "SYSTEMID",
        "AUTOROTATE",
        "AUTO_RTL",
    ];
    match NAMES.get(custom_mode as usize) {
        Some(name) if !name.is_empty() => (*name).to_string(),
        _ => format!("MODE{custom_mode}"),
    }
}

/// PX4's name of flight mode `custom_mode` (main mode in its third byte, AUTO's sub mode in
/// its fourth).
pub fn px4_mode_name(custom_mode: u32) -> String {
    let (main, sub) = ((custom_mode >> 16) & 0xff, custom_mode >> 24);
    const MAIN: [&str; 9] = [
        "",
        "MANUAL",
        "ALTCTL",
        "POSCTL",
        "AUTO",
        "ACRO",
        "OFFBOARD",
        "STABILIZED",
        "RATTITUDE",
    ];
    const AUTO: [&str; 10] = [
        "", "READY", "TAKEOFF", "LOITER", "MISSION", "RTL", "LAND", "", "FOLLOW", "PRECLAND",
    ];
    match (MAIN.get(main as usize), AUTO.get(sub as usize)) {
        (Some(&"AUTO"), Some(sub)) if !sub.is_empty() => format!("AUTO.{sub}"),
        (Some(main), _) if !main.is_empty() => (*main).to_string(),
        _ => format!("MODE{custom_mode:#x}"),
    }
}
