//! Encoding what savsim sends: MAVLink 2 frames from one identity (system, component) with its
//! own sequence, signed when a key is given (`--signing-key`). The GCS (requests, heartbeat)
//! and the closed-loop feed are two outboxes.

use std::sync::Arc;

use mavlink::dialects::ardupilotmega::{
    MavAutopilot, MavMessage, MavModeFlag, MavState, MavType, HEARTBEAT_DATA,
};
use mavlink::{MavHeader, MavlinkVersion};

use crate::codec::frame::MAX_FRAME_LEN;
use crate::codec::signing::Signing;
use crate::world::SenderId;

/// Encodes one identity's messages.
#[derive(Debug)]
pub struct Outbox {
    header: MavHeader,
    signing: Option<Arc<Signing>>,
    /// Frames signed so far.
    pub signed: u64,
}

impl Outbox {
    /// An outbox sending as `from`, sequence from 0.
    pub fn new(from: SenderId) -> Self {
        Self {
            header: MavHeader {
                system_id: u32::from(from.system_id),
                component_id: from.component_id,
                sequence: 0,
            },
            signing: None,
            signed: 0,
        }
    }

    /// The same outbox, signing every frame with `signing`.
    pub fn signed_with(mut self, signing: Option<Arc<Signing>>) -> Self {
        self.signing = signing;
        self
    }

    /// `message` as a MAVLink 2 frame; the sequence advances.
    pub fn encode(&mut self, message: &MavMessage) -> Vec<u8> {
        if let Some(signing) = &self.signing {
            let bytes = signing.encode(self.header, message);
            self.header.sequence = self.header.sequence.wrapping_add(1);
            self.signed += 1;
            return bytes;
        }
        let mut bytes = Vec::with_capacity(MAX_FRAME_LEN);
        // Writing into a Vec cannot fail.
        let _ = mavlink::write_versioned_msg(&mut bytes, MavlinkVersion::V2, self.header, message);
        self.header.sequence = self.header.sequence.wrapping_add(1);
        bytes
    }
}

/// A ground station's HEARTBEAT (savsim's GCS identity on a link, the study's pilot): what
/// makes an autopilot stream to it and keep its GCS failsafe quiet.
pub fn gcs_heartbeat() -> MavMessage {
    MavMessage::HEARTBEAT(HEARTBEAT_DATA {
        custom_mode: 0,
        mavtype: MavType::MAV_TYPE_GCS,
        autopilot: MavAutopilot::MAV_AUTOPILOT_INVALID,
        base_mode: MavModeFlag::empty(),
        system_status: MavState::MAV_STATE_ACTIVE,
        mavlink_version: 3,
    })
}
