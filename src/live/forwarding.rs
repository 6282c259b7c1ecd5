//! `--forward` on the session thread: the router, and the frames it routed from the chunk
//! at hand until they are handed to the links.

use super::new_histogram;
use crate::codec::frame::RawFrame;
use crate::links::forward::Forwarder;
use crate::links::sockets::{unix_now_s, Chunk, Outgoing, Sender};
use crate::links::supervisor::{Endpoint, Supervisor};

/// The router's state on the session thread.
pub(super) struct Forwarding {
    pub(super) router: Forwarder,
    pub(super) vehicle_fixed: Vec<Endpoint>,
    /// The links (none when driven without a network, as the fuzz target does).
    pub(super) sender: Option<Sender>,
    /// Frames routed from the chunk at hand, handed to the links once it is framed.
    pub(super) pending: Vec<Outgoing>,
    pub(super) latency_us: hdrhistogram::Histogram<u64>,
}

impl Forwarding {
    pub(super) fn new(
        router: Forwarder,
        vehicle_fixed: Vec<Endpoint>,
        sender: Option<Sender>,
    ) -> Self {
        Self {
            router,
            vehicle_fixed,
            sender,
            pending: Vec::new(),
            latency_us: new_histogram(),
        }
    }

    pub(super) fn route_from_vehicle(&mut self, t_s: f64, frame: &RawFrame<'_>) {
        let pending = &mut self.pending;
        self.router.from_vehicle(t_s, frame, |to| {
            pending.push(Outgoing {
                to,
                bytes: frame.bytes.to_vec(),
            })
        });
    }

    pub(super) fn route_from_station(
        &mut self,
        chunk: &Chunk,
        frame: &RawFrame<'_>,
        supervisor: &Supervisor,
    ) {
        let pending = &mut self.pending;
        self.router.from_station(
            chunk.endpoint(),
            chunk.t_s,
            frame,
            supervisor.routes(),
            &self.vehicle_fixed,
            |to| {
                pending.push(Outgoing {
                    to,
                    bytes: frame.bytes.to_vec(),
                })
            },
        );
    }

    /// Hand what was routed to the links, noting how long after `received_t_s`.
    pub(super) fn flush(&mut self, received_t_s: f64) {
        if self.pending.is_empty() {
            return;
        }
        match &self.sender {
            Some(sender) => self.pending.drain(..).for_each(|out| sender.send(out)),
            None => self.pending.clear(),
        }
        let waited_us = ((unix_now_s() - received_t_s) * 1e6).max(0.0) as u64;
        self.latency_us.saturating_record(waited_us);
    }
}
