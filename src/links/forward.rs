//! `--forward`: savsim as a router between its vehicles and ground stations (pure).
//!
//! Links are either vehicles' (`--connect`) or stations' (`--forward`). The rules are
//! mavlink-router's, with the vehicles on one side and the stations on the other:
//!
//! - A frame from a vehicle link goes, unchanged (its sequence and signature too), to every
//!   station endpoint: each fixed one (udpout, a TCP connection) and each udpin address heard
//!   in the last [`HEARD_FOR_S`]. Never back to a vehicle link, and not savsim's own traffic
//!   echoed by a router, nor what a vehicle addressed to savsim itself.
//! - A frame from a station goes to the vehicle it targets (MAVLink's `target_system`, and
//!   `target_component` where a vehicle of that system has it): the endpoint where that
//!   autopilot was last heard. An untargeted frame (a station's heartbeat) or a broadcast
//!   (target 0) goes to every vehicle endpoint and to the other stations. A target no vehicle
//!   was heard as is dropped and counted (`unroutable`).
//! - Frames whose checksum failed are not forwarded. Frames of messages the dialect does not
//!   know are forwarded as untargeted ones (their checksum cannot be checked: another
//!   dialect's; their target cannot be read), as mavlink-router does: from a vehicle to every
//!   station, from a station to every vehicle endpoint and the other stations.
//! - At most [`MAX_HEARD_STATIONS`] udpin station addresses are remembered; addresses not
//!   heard for [`HEARD_FOR_S`] are forgotten as new ones arrive, and a new address past the
//!   bound gets nothing until one is forgotten (counted, `stations_refused`).

use std::collections::BTreeMap;

use mavlink::dialects::ardupilotmega::MavMessage;
use mavlink::Message;
use serde::Serialize;

use crate::codec::frame::{FrameStatus, RawFrame};
use crate::links::supervisor::{Endpoint, LinkId};
use crate::world::SenderId;

/// A udpin station address heard within this long gets the vehicles' traffic, s.
pub const HEARD_FOR_S: f64 = 10.0;
/// The most udpin station addresses remembered at once.
pub const MAX_HEARD_STATIONS: usize = 1024;

/// What the forwarder did, for the summary's `link.forward`.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize)]
pub struct ForwardCounts {
    /// Frames from vehicles handed to a station (one per station).
    pub to_stations: u64,
    /// Frames from stations handed to a vehicle or another station (one per endpoint).
    pub from_stations: u64,
    /// Station frames aimed at a system no vehicle was heard as: dropped.
    pub unroutable: u64,
    /// Frames not forwarded because their checksum failed.
    pub corrupt: u64,
    /// savsim's own frames shown to the stations (`--forward-own`).
    pub own: u64,
    /// Frames from a new udpin station address while [`MAX_HEARD_STATIONS`] were remembered:
    /// routed, but the address gets no traffic.
    pub stations_refused: u64,
}

/// Routes frames between vehicle and station links.
#[derive(Debug, Clone)]
pub struct Forwarder {
    /// Links from this index on are stations'.
    first_station: LinkId,
    /// Station endpoints known without hearing them (udpout, TCP).
    fixed: Vec<Endpoint>,
    /// Station addresses heard, with the last time (receive clock, s).
    heard: BTreeMap<Endpoint, f64>,
    /// savsim's own identities (its GCS and its feed): never forwarded from a vehicle link.
    own: Vec<SenderId>,
    /// Counters.
    pub counts: ForwardCounts,
}

/// The target a frame names: system and component (0 = any), or none for an untargeted
/// message. Unknown or unparsable messages count as untargeted.
pub fn target_of(frame: &RawFrame<'_>) -> Option<(u8, u8)> {
    let message = MavMessage::parse(frame.version, frame.message_id, frame.payload).ok()?;
    let system = message.target_system_id()?;
    Some((system, message.target_component_id().unwrap_or(0)))
}

impl Forwarder {
    /// A forwarder whose station links are those from `first_station` on, with the fixed
    /// endpoints among them; `own` are savsim's identities.
    pub fn new(first_station: LinkId, fixed: Vec<Endpoint>, own: Vec<SenderId>) -> Self {
        Self {
            first_station,
            fixed,
            heard: BTreeMap::new(),
            own,
            counts: ForwardCounts::default(),
        }
    }

    /// Whether `link` is a station's.
    pub fn is_station(&self, link: LinkId) -> bool {
        link >= self.first_station
    }

    /// Every station endpoint that gets traffic at `t_s`, but `except`.
    fn stations(&self, t_s: f64, except: Option<Endpoint>) -> impl Iterator<Item = Endpoint> + '_ {
        let heard = self
            .heard
            .iter()
            .filter(move |(e, last)| t_s - **last <= HEARD_FOR_S && !self.fixed.contains(e))
            .map(|(e, _)| *e);
        self.fixed
            .iter()
            .copied()
            .chain(heard)
            .filter(move |e| Some(*e) != except)
    }

    /// Where a frame from a vehicle link goes: every station (`send` once each).
    pub fn from_vehicle(&mut self, t_s: f64, frame: &RawFrame<'_>, mut send: impl FnMut(Endpoint)) {
        if frame.status == FrameStatus::BadCrc || frame.status == FrameStatus::BadIncompatFlags {
            self.counts.corrupt += 1;
            return;
        }
        let sender = SenderId {
            system_id: frame.system_id,
            component_id: frame.component_id,
        };
        if self.own.contains(&sender) {
            return;
        }
        if let Some((system, component)) = target_of(frame) {
            let to_own = self
                .own
                .iter()
                .any(|o| o.system_id == system && (component == 0 || o.component_id == component));
            if to_own {
                return;
            }
        }
        self.counts.to_stations += self.every_station(t_s, &mut send);
    }

    /// `send` to every station at `t_s`; how many.
    fn every_station(&self, t_s: f64, send: &mut impl FnMut(Endpoint)) -> u64 {
        self.stations(t_s, None).map(send).count() as u64
    }

    /// Where a frame from a station at `from` goes, given the vehicles' `routes` (each
    /// autopilot and where it was last heard) and the vehicle links' fixed endpoints.
    pub fn from_station(
        &mut self,
        from: Endpoint,
        t_s: f64,
        frame: &RawFrame<'_>,
        routes: impl Iterator<Item = (SenderId, Endpoint)>,
        vehicle_fixed: &[Endpoint],
        mut send: impl FnMut(Endpoint),
    ) {
        if from.peer.is_some() {
            self.hear(from, t_s);
        }
        if frame.status == FrameStatus::BadCrc || frame.status == FrameStatus::BadIncompatFlags {
            self.counts.corrupt += 1;
            return;
        }
        let mut to: Vec<Endpoint> = Vec::new();
        let add = |e: Endpoint, to: &mut Vec<Endpoint>| {
            if !to.contains(&e) {
                to.push(e);
            }
        };
        match target_of(frame) {
            Some((system, component)) if system != 0 => {
                let routes: Vec<(SenderId, Endpoint)> =
                    routes.filter(|(id, _)| id.system_id == system).collect();
                let exact = routes.iter().any(|(id, _)| id.component_id == component);
                for (id, e) in &routes {
                    if component == 0 || !exact || id.component_id == component {
                        add(*e, &mut to);
                    }
                }
                if to.is_empty() {
                    self.counts.unroutable += 1;
                    return;
                }
            }
            _ => {
                for (_, e) in routes {
                    add(e, &mut to);
                }
                for e in vehicle_fixed {
                    if !to.iter().any(|t| t.link == e.link) {
                        add(*e, &mut to);
                    }
                }
                let others: Vec<Endpoint> = self.stations(t_s, Some(from)).collect();
                for e in others {
                    add(e, &mut to);
                }
            }
        }
        self.counts.from_stations += to.len() as u64;
        to.into_iter().for_each(&mut send);
    }

    /// Remember station address `from` as heard at `t_s`: addresses not heard for
    /// [`HEARD_FOR_S`] are forgotten first when it is new; past [`MAX_HEARD_STATIONS`] it is
    /// refused.
    fn hear(&mut self, from: Endpoint, t_s: f64) {
        if let Some(last) = self.heard.get_mut(&from) {
            *last = t_s;
            return;
        }
        self.heard.retain(|_, last| t_s - *last <= HEARD_FOR_S);
        if self.heard.len() < MAX_HEARD_STATIONS {
            self.heard.insert(from, t_s);
        } else {
            self.counts.stations_refused += 1;
        }
    }

    /// Station addresses remembered now.
    pub fn heard_stations(&self) -> usize {
        self.heard.len()
    }

    /// Where savsim's own frame goes when the stations are to see it (`--forward-own`).
    pub fn own_frame(&mut self, t_s: f64, mut send: impl FnMut(Endpoint)) {
        self.counts.own += self.every_station(t_s, &mut send);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::codec::frame::{scan, Scan};
    use mavlink::dialects::ardupilotmega::{
        MavCmd, MavMessage, COMMAND_LONG_DATA, GLOBAL_POSITION_INT_DATA, HEARTBEAT_DATA,
    };
    use mavlink::{MavHeader, MavlinkVersion};

    fn bytes(from: (u8, u8), m: &MavMessage) -> Vec<u8> {
        let mut out = Vec::new();
        let header = MavHeader {
            system_id: u32::from(from.0),
            component_id: from.1,
            sequence: 0,
        };
        mavlink::write_versioned_msg(&mut out, MavlinkVersion::V2, header, m).unwrap();
        out
    }

    fn with_frame(b: &[u8], f: impl FnOnce(&RawFrame<'_>)) {
        match scan(b) {
            Scan::Frame(frame) => f(&frame),
            other => panic!("{other:?}"),
        }
    }

    fn command(target: (u8, u8)) -> MavMessage {
        MavMessage::COMMAND_LONG(COMMAND_LONG_DATA {
            command: MavCmd::MAV_CMD_COMPONENT_ARM_DISARM,
            target_system: target.0,
            target_component: target.1,
            ..Default::default()
        })
    }

    const GCS: SenderId = SenderId {
        system_id: 245,
        component_id: 190,
    };

    fn at(link: LinkId, port: Option<u16>) -> Endpoint {
        Endpoint {
            link,
            peer: port.map(|p| SocketAddr::from(([127, 0, 0, 1], p))),
        }
    }

    use std::net::SocketAddr;

    /// Links 0 and 1 are vehicles'; 2 a udpout station, 3 a udpin one.
    fn router() -> Forwarder {
        Forwarder::new(2, vec![at(2, Some(14550))], vec![GCS])
    }

    fn routes() -> Vec<(SenderId, Endpoint)> {
        vec![
            (
                SenderId {
                    system_id: 1,
                    component_id: 1,
                },
                at(0, Some(5000)),
            ),
            (
                SenderId {
                    system_id: 2,
                    component_id: 1,
                },
                at(1, None),
            ),
        ]
    }

    fn from_station(r: &mut Forwarder, from: Endpoint, t_s: f64, m: &MavMessage) -> Vec<Endpoint> {
        let b = bytes((255, 190), m);
        let mut to = Vec::new();
        with_frame(&b, |f| {
            r.from_station(from, t_s, f, routes().into_iter(), &[at(1, None)], |e| {
                to.push(e)
            })
        });
        to
    }

    #[test]
    fn a_targeted_command_goes_to_its_vehicle_only_and_an_unknown_target_nowhere() {
        let mut r = router();
        let station = at(3, Some(6000));
        assert_eq!(
            from_station(&mut r, station, 0.0, &command((2, 1))),
            [at(1, None)]
        );
        assert_eq!(
            from_station(&mut r, station, 0.0, &command((1, 0))),
            [at(0, Some(5000))]
        );
        assert!(from_station(&mut r, station, 0.0, &command((9, 1))).is_empty());
        assert_eq!(r.counts.unroutable, 1);
    }

    #[test]
    fn a_heartbeat_or_a_broadcast_goes_to_every_vehicle_and_the_other_stations_not_back() {
        let mut r = router();
        let hb = MavMessage::HEARTBEAT(HEARTBEAT_DATA::default());
        let from = at(3, Some(6000));
        let to = from_station(&mut r, from, 0.0, &hb);
        assert_eq!(to, [at(0, Some(5000)), at(1, None), at(2, Some(14550))]);
        let to = from_station(&mut r, at(2, Some(14550)), 1.0, &command((0, 0)));
        // The udpin station was heard: it gets it; the sender does not.
        assert_eq!(to, [at(0, Some(5000)), at(1, None), from]);
    }

    #[test]
    fn vehicle_frames_go_to_every_station_heard_lately_but_not_savsims_own() {
        let mut r = router();
        let hb = MavMessage::HEARTBEAT(HEARTBEAT_DATA::default());
        from_station(&mut r, at(3, Some(6000)), 0.0, &hb);
        let position = bytes(
            (1, 1),
            &MavMessage::GLOBAL_POSITION_INT(GLOBAL_POSITION_INT_DATA::default()),
        );
        let mut to = Vec::new();
        with_frame(&position, |f| r.from_vehicle(5.0, f, |e| to.push(e)));
        assert_eq!(to, [at(2, Some(14550)), at(3, Some(6000))]);
        // 10 s after the udpin station was last heard, only the fixed one.
        to.clear();
        with_frame(&position, |f| r.from_vehicle(10.5, f, |e| to.push(e)));
        assert_eq!(to, [at(2, Some(14550))]);
        // savsim's own echo, and what the vehicle addressed to savsim: nowhere.
        to.clear();
        let echo = bytes(
            (245, 190),
            &MavMessage::HEARTBEAT(HEARTBEAT_DATA::default()),
        );
        with_frame(&echo, |f| r.from_vehicle(10.5, f, |e| to.push(e)));
        let ack = bytes((1, 1), &command((245, 190)));
        with_frame(&ack, |f| r.from_vehicle(10.5, f, |e| to.push(e)));
        assert!(to.is_empty(), "{to:?}");
        // A corrupt frame: counted, not forwarded.
        let mut bad = position.clone();
        let n = bad.len();
        bad[n - 1] ^= 0xff;
        with_frame(&bad, |f| r.from_vehicle(10.5, f, |e| to.push(e)));
        assert!(to.is_empty());
        assert_eq!(r.counts.corrupt, 1);
        assert_eq!(r.counts.to_stations, 3);
    }

    /// A v2 frame of message id 60000, which the dialect does not define.
    fn unknown_message(from: (u8, u8)) -> Vec<u8> {
        let mut b = vec![0xFD, 4, 0, 0, 0, from.0, from.1, 0x60, 0xEA, 0x00];
        b.extend_from_slice(&[1, 2, 3, 4, 0x12, 0x34]);
        b
    }

    #[test]
    fn a_message_the_dialect_does_not_know_is_forwarded_as_untargeted() {
        let mut r = router();
        let station = at(3, Some(6000));
        let mut to = Vec::new();
        with_frame(&unknown_message((255, 190)), |f| {
            assert_eq!(f.status, FrameStatus::UnknownMessage);
            r.from_station(station, 0.0, f, routes().into_iter(), &[at(1, None)], |e| {
                to.push(e)
            })
        });
        assert_eq!(to, [at(0, Some(5000)), at(1, None), at(2, Some(14550))]);
        to.clear();
        with_frame(&unknown_message((1, 1)), |f| {
            r.from_vehicle(1.0, f, |e| to.push(e))
        });
        assert_eq!(to, [at(2, Some(14550)), station]);
    }

    #[test]
    fn station_addresses_are_forgotten_when_silent_and_bounded_in_number() {
        let mut r = router();
        let hb = MavMessage::HEARTBEAT(HEARTBEAT_DATA::default());
        for port in 0..MAX_HEARD_STATIONS as u16 {
            from_station(&mut r, at(3, Some(10_000 + port)), 0.0, &hb);
        }
        assert_eq!(r.heard_stations(), MAX_HEARD_STATIONS);
        // One more while all are fresh: refused (and routed, but never sent to).
        from_station(&mut r, at(3, Some(9000)), 1.0, &hb);
        assert_eq!(r.heard_stations(), MAX_HEARD_STATIONS);
        assert_eq!(r.counts.stations_refused, 1);
        // After they fall silent, a new one makes the old ones forgotten.
        from_station(&mut r, at(3, Some(9000)), 11.0, &hb);
        assert_eq!(r.heard_stations(), 1);
    }
}
