//! Encoding what savsim sends: MAVLink 2 frames from one identity (system, component) with its
//! own sequence. The GCS (requests, heartbeat) and the closed-loop feed are two outboxes.

use mavlink::dialects::ardupilotmega::MavMessage;
use mavlink::{MavHeader, MavlinkVersion};

use crate::ingest::frame::MAX_FRAME_LEN;
use crate::ingest::stats::SenderId;

/// Encodes one identity's messages.
#[derive(Debug, Clone)]
pub struct Outbox {
    header: MavHeader,
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
        }
    }

    /// `message` as a MAVLink 2 frame; the sequence advances.
    pub fn encode(&mut self, message: &MavMessage) -> Vec<u8> {
        let mut bytes = Vec::with_capacity(MAX_FRAME_LEN);
        // Writing into a Vec cannot fail.
        let _ = mavlink::write_versioned_msg(&mut bytes, MavlinkVersion::V2, self.header, message);
        self.header.sequence = self.header.sequence.wrapping_add(1);
        bytes
    }
}
