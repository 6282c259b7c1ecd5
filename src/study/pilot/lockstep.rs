//! The pilot in savsim's lockstep loop: no socket and no reader thread; the loop hands it
//! what the autopilot said (through [`PilotInbox`], the loop's [`Actor`]) and sends what it
//! queued, and the two take turns through a [`Gate`].

use std::sync::mpsc::{sync_channel, SyncSender};
use std::sync::{Arc, Mutex};
use std::time::Duration;

use mavlink::dialects::ardupilotmega::MavMessage;

use super::heard::{Heard, News};
use super::{pass_on, Passed, Pilot, Shared, Wire};
use crate::geo::LocalTangentPlane;
use crate::lockstep::driver::Actor;
use crate::lockstep::gate::{Gate, Stuck};
use crate::world::SenderId;

impl Pilot {
    /// A pilot in lockstep for the autopilot `target`, positions mapped into `plane`: no
    /// socket and no reader thread of its own; savsim's physics loop hands it what the
    /// autopilot said through the returned [`PilotInbox`] and sends what it queues.
    pub fn lockstep(target: SenderId, plane: LocalTangentPlane) -> (Pilot, PilotInbox) {
        let heard = Arc::new(Mutex::new(Heard::default()));
        let (tx, news) = sync_channel(crate::session::HELD_ESTIMATES * 8);
        let gate = Arc::new(Gate::default());
        let outgoing = Arc::new(Mutex::new(Vec::new()));
        let wire = Wire::Queue(outgoing.clone());
        let pilot = Pilot::new(wire, target, news, heard.clone(), Some(gate.clone()));
        let inbox = PilotInbox {
            target,
            plane,
            heard,
            tx,
            gate,
            outgoing,
        };
        (pilot, inbox)
    }
}

/// The physics loop's side of a pilot in lockstep: what the autopilot said goes in here, and
/// what the pilot sends comes out.
pub struct PilotInbox {
    target: SenderId,
    plane: LocalTangentPlane,
    heard: Shared,
    tx: SyncSender<News>,
    /// The turn-taking with the pilot.
    gate: Arc<Gate>,
    outgoing: Arc<Mutex<Vec<Vec<u8>>>>,
}

impl Actor for PilotInbox {
    fn take(&mut self, bytes: &[u8]) {
        let mut reader = mavlink::MavlinkReader::new(bytes);
        let mut sent = 0;
        while let Ok((h, m)) = reader.read_any_message::<MavMessage>() {
            if pass_on(h, m, self.target, &self.plane, &self.heard, &self.tx) == Passed::Sent {
                sent += 1;
            }
        }
        self.gate.delivered(sent);
    }

    fn tick(&mut self, time_ms: u32) {
        if self.tx.send(News::Tick(time_ms)).is_ok() {
            self.gate.delivered(1);
        }
    }

    fn settle(&mut self, limit: Duration) -> Result<(), Stuck> {
        self.gate.wait_idle(limit)
    }

    fn outgoing(&mut self) -> Vec<Vec<u8>> {
        self.outgoing
            .lock()
            .map(|mut q| std::mem::take(&mut *q))
            .unwrap_or_default()
    }

    fn finished(&self) -> bool {
        self.gate.is_closed()
    }
}

impl Drop for PilotInbox {
    fn drop(&mut self) {
        self.gate.close();
    }
}
