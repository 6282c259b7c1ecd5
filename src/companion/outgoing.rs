//! A planner's commands as the MAVLink a companion computer sends: a velocity as
//! SET_POSITION_TARGET_LOCAL_NED (velocities, and the heading when given), a mode as
//! MAV_CMD_DO_SET_MODE with the autopilot's own number for it, MAVLink frames as they came
//! (each checked to be whole frames). Sent as the companion's identity: the vehicle's system
//! id, component MAV_COMP_ID_ONBOARD_COMPUTER (191).

use glam::DVec3;
use mavlink::dialects::ardupilotmega::{
    MavCmd, MavFrame, MavMessage, PositionTargetTypemask, COMMAND_LONG_DATA,
    SET_POSITION_TARGET_LOCAL_NED_DATA,
};

use super::protocol::Command;
use crate::codec::frame::{scan, Scan};
use crate::codec::notes::{arducopter_mode_name, px4_mode_name};
use crate::codec::outbox::Outbox;
use crate::world::SenderId;

/// MAV_COMP_ID_ONBOARD_COMPUTER.
pub const COMPANION_COMPONENT: u8 = 191;

/// The companion's identity on vehicle `system_id`.
pub fn identity(system_id: u8) -> SenderId {
    SenderId {
        system_id,
        component_id: COMPANION_COMPONENT,
    }
}

/// Why a command cannot be sent.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum OutgoingError {
    /// A mode the autopilot does not have.
    #[error("mode {0:?}: not a mode of this autopilot")]
    Mode(String),
    /// Bytes that are not whole MAVLink frames.
    #[error("mavlink: {0}")]
    Frames(String),
}

/// The autopilot's custom mode of `name` (ArduCopter's numbers, or PX4's main and sub mode in
/// its third and fourth bytes).
///
/// ```
/// use savsim::companion::outgoing::custom_mode;
/// assert_eq!(custom_mode("GUIDED", false), Some(4));
/// assert_eq!(custom_mode("guided", false), Some(4));
/// assert!(custom_mode("OFFBOARD", true).is_some());
/// assert_eq!(custom_mode("WARP", false), None);
/// ```
pub fn custom_mode(name: &str, px4: bool) -> Option<u32> {
    let name = name.to_ascii_uppercase();
    if px4 {
        (1..=8u32)
            .flat_map(|main| (0..=10u32).map(move |sub| main << 16 | sub << 24))
            .find(|&m| px4_mode_name(m).eq_ignore_ascii_case(&name))
    } else {
        (0..32u32).find(|&m| arducopter_mode_name(m) == name)
    }
}

/// `command` as frames from `outbox` to `target`, appended to `out`.
pub fn encode(
    command: &Command,
    target: SenderId,
    px4: bool,
    outbox: &mut Outbox,
    out: &mut Vec<Vec<u8>>,
) -> Result<(), OutgoingError> {
    match command {
        Command::Velocity { enu_mps, yaw_deg } => {
            out.push(outbox.encode(&velocity(*enu_mps, *yaw_deg, target)));
        }
        Command::Mode(name) => {
            let mode = custom_mode(name, px4).ok_or_else(|| OutgoingError::Mode(name.clone()))?;
            let params = if px4 {
                [1.0, ((mode >> 16) & 0xff) as f32, (mode >> 24) as f32]
            } else {
                [1.0, mode as f32, 0.0]
            };
            out.push(outbox.encode(&MavMessage::COMMAND_LONG(COMMAND_LONG_DATA {
                command: MavCmd::MAV_CMD_DO_SET_MODE,
                param1: params[0],
                param2: params[1],
                param3: params[2],
                target_system: target.system_id,
                target_component: target.component_id,
                ..COMMAND_LONG_DATA::default()
            })));
        }
        Command::Mavlink(bytes) => {
            let mut rest = &bytes[..];
            while !rest.is_empty() {
                match scan(rest) {
                    Scan::Frame(frame) => {
                        out.push(rest[..frame.len].to_vec());
                        rest = &rest[frame.len..];
                    }
                    Scan::Garbage(n) => {
                        return Err(OutgoingError::Frames(format!(
                            "{n} bytes that are not a MAVLink frame"
                        )))
                    }
                    Scan::Incomplete => {
                        return Err(OutgoingError::Frames(format!(
                            "{} bytes of an unfinished frame",
                            rest.len()
                        )))
                    }
                }
            }
        }
    }
    Ok(())
}

/// SET_POSITION_TARGET_LOCAL_NED: velocities (and the heading when given).
fn velocity(enu_mps: DVec3, yaw_deg: Option<f64>, target: SenderId) -> MavMessage {
    // Bits set are ignored: position, acceleration, yaw and yaw rate; yaw (bit 10) used when
    // given.
    let velocity_only: u16 = 0b0000_1101_1100_0111;
    let mask = match yaw_deg {
        Some(_) => velocity_only & !(1 << 10),
        None => velocity_only,
    };
    MavMessage::SET_POSITION_TARGET_LOCAL_NED(SET_POSITION_TARGET_LOCAL_NED_DATA {
        vx: enu_mps.y as f32,
        vy: enu_mps.x as f32,
        vz: -enu_mps.z as f32,
        yaw: yaw_deg.map_or(0.0, |y| y.to_radians() as f32),
        type_mask: PositionTargetTypemask::from_bits_truncate(mask),
        target_system: target.system_id,
        target_component: target.component_id,
        coordinate_frame: MavFrame::MAV_FRAME_LOCAL_NED,
        ..SET_POSITION_TARGET_LOCAL_NED_DATA::default()
    })
}
