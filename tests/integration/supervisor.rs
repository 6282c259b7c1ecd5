//! The link supervisor on its own, driven by frames the mavlink crate wrote and by times the
//! test chooses (no sockets, no clock): routing per (sysid, compid), autopilots only, one
//! request per message, the ArduPilot-only fallback, refusals, stale streams and reboots.

use std::net::SocketAddr;

use mavlink::dialects::ardupilotmega::{
    MavAutopilot, MavCmd, MavMessage, MavResult, MavType, ATTITUDE_DATA, COMMAND_ACK_DATA,
    GLOBAL_POSITION_INT_DATA,
};
use savsim::codec::frame::{scan, Scan};
use savsim::links::supervisor::{Endpoint, RequestState, Supervisor, SupervisorConfig};
use savsim::world::SenderId;

use crate::common::{frame_v2, heartbeat};

fn position(time_boot_ms: u32) -> MavMessage {
    MavMessage::GLOBAL_POSITION_INT(GLOBAL_POSITION_INT_DATA {
        time_boot_ms,
        lat: -353_632_610,
        lon: 1_491_652_300,
        alt: 600_000,
        relative_alt: 0,
        vx: 0,
        vy: 0,
        vz: 0,
        hdg: 0,
    })
}

fn attitude(time_boot_ms: u32) -> MavMessage {
    MavMessage::ATTITUDE(ATTITUDE_DATA {
        time_boot_ms,
        roll: 0.0,
        pitch: 0.0,
        yaw: 0.0,
        rollspeed: 0.0,
        pitchspeed: 0.0,
        yawspeed: 0.0,
    })
}

fn ack(result: MavResult) -> MavMessage {
    MavMessage::COMMAND_ACK(COMMAND_ACK_DATA {
        command: MavCmd::MAV_CMD_SET_MESSAGE_INTERVAL,
        result,
        ..Default::default()
    })
}

fn endpoint(port: u16) -> Endpoint {
    Endpoint {
        link: 0,
        peer: Some(SocketAddr::from(([127, 0, 0, 1], port))),
    }
}

/// Feed one message from `sysid/compid` at `from`, `t_s`; true if it was a reboot.
fn observe(
    s: &mut Supervisor,
    from: Endpoint,
    t_s: f64,
    sysid: u8,
    compid: u8,
    message: &MavMessage,
) -> bool {
    let bytes = frame_v2(sysid, compid, 0, message);
    let Scan::Frame(frame) = scan(&bytes) else {
        panic!("the mavlink crate's frame scans")
    };
    s.observe(from, t_s, &frame).rebooted
}

/// The interval requests in `due`'s output: (endpoint, target, message id).
fn requests(due: &[(Endpoint, MavMessage)]) -> Vec<(Endpoint, (u8, u8), u32)> {
    due.iter()
        .filter_map(|(to, m)| match m {
            MavMessage::COMMAND_LONG(c) if c.command == MavCmd::MAV_CMD_SET_MESSAGE_INTERVAL => {
                Some((*to, (c.target_system, c.target_component), c.param1 as u32))
            }
            _ => None,
        })
        .collect()
}

#[allow(deprecated)]
fn data_stream_requests(due: &[(Endpoint, MavMessage)]) -> usize {
    due.iter()
        .filter(|(_, m)| matches!(m, MavMessage::REQUEST_DATA_STREAM(_)))
        .count()
}

fn state_of(s: &Supervisor, vehicle: &str, message: &str) -> RequestState {
    let v = s
        .vehicles()
        .into_iter()
        .find(|v| v.vehicle == vehicle)
        .unwrap();
    v.streams[message]
}

const COPTER: (MavType, MavAutopilot) = (
    MavType::MAV_TYPE_QUADROTOR,
    MavAutopilot::MAV_AUTOPILOT_ARDUPILOTMEGA,
);
const PX4: (MavType, MavAutopilot) = (MavType::MAV_TYPE_QUADROTOR, MavAutopilot::MAV_AUTOPILOT_PX4);

#[test]
fn each_vehicle_is_asked_at_its_own_address_one_message_at_a_time() {
    let mut s = Supervisor::new(SupervisorConfig::default());
    let (a, b) = (endpoint(5001), endpoint(5002));
    observe(&mut s, a, 0.0, 1, 1, &heartbeat(COPTER.0, COPTER.1));
    observe(&mut s, b, 0.0, 2, 1, &heartbeat(PX4.0, PX4.1));
    let due = s.due(0.0);
    // The heartbeat goes to both addresses; each vehicle gets its first request at its own.
    let heartbeats: Vec<Endpoint> = due
        .iter()
        .filter(|(_, m)| matches!(m, MavMessage::HEARTBEAT(_)))
        .map(|(e, _)| *e)
        .collect();
    assert_eq!(heartbeats, vec![a, b]);
    assert_eq!(requests(&due), vec![(a, (1, 1), 33), (b, (2, 1), 33)]);
    // Nothing more until an answer or the timeout: one request outstanding per vehicle.
    assert!(requests(&s.due(0.5)).is_empty());
    observe(&mut s, a, 0.6, 1, 1, &ack(MavResult::MAV_RESULT_ACCEPTED));
    assert_eq!(requests(&s.due(0.7)), vec![(a, (1, 1), 30)]);
    assert_eq!(
        state_of(&s, "1/1", "GLOBAL_POSITION_INT"),
        RequestState::Accepted
    );
    // Vehicle 1 moves to another address (a new source port): replies follow it.
    let a2 = endpoint(5003);
    observe(&mut s, a2, 0.8, 1, 1, &position(1_000));
    observe(&mut s, a2, 0.9, 1, 1, &ack(MavResult::MAV_RESULT_DENIED));
    assert_eq!(state_of(&s, "1/1", "ATTITUDE"), RequestState::Refused);
    assert_eq!(s.counts.refused, 1);
    // Vehicle 2 never answers: after the timeout it is asked again, to its own address.
    assert_eq!(requests(&s.due(1.05)), vec![(b, (2, 1), 33)]);
}

#[test]
fn a_companion_or_gcs_is_never_asked_and_its_position_makes_no_vehicle() {
    let mut s = Supervisor::new(SupervisorConfig::default());
    let from = endpoint(14550);
    observe(
        &mut s,
        from,
        0.0,
        1,
        191,
        &heartbeat(
            MavType::MAV_TYPE_ONBOARD_CONTROLLER,
            MavAutopilot::MAV_AUTOPILOT_INVALID,
        ),
    );
    observe(
        &mut s,
        from,
        0.0,
        200,
        0,
        &heartbeat(MavType::MAV_TYPE_GCS, MavAutopilot::MAV_AUTOPILOT_INVALID),
    );
    observe(&mut s, from, 0.1, 1, 191, &position(10));
    for t in [0.0, 1.5, 3.0, 4.5] {
        assert!(requests(&s.due(t)).is_empty());
    }
    assert!(s.vehicles().is_empty());
    assert_eq!(s.routes().count(), 0);
}

#[test]
fn request_data_stream_only_for_ardupilot_after_every_attempt_went_unanswered() {
    for (kind, fallback) in [(COPTER, 2), (PX4, 0)] {
        let mut s = Supervisor::new(SupervisorConfig::default());
        let from = endpoint(5760);
        let mut sent = Vec::new();
        let mut fallbacks = 0;
        let mut t = 0.0;
        // The fallback goes at 6 s; its streams would be stale (and asked again) at 8 s.
        while t < 7.9 {
            // Heartbeats go on; no COMMAND_ACK ever comes.
            observe(&mut s, from, t, 1, 1, &heartbeat(kind.0, kind.1));
            let due = s.due(t);
            sent.extend(requests(&due).into_iter().map(|(_, _, id)| id));
            fallbacks += data_stream_requests(&due);
            t += 0.25;
        }
        // Three attempts per message, each in its turn (PX4's first message, unanswered at
        // 3 s, is stale and asked again at 6 s).
        assert_eq!(sent[..6], [33, 33, 33, 30, 30, 30], "{kind:?}");
        assert_eq!(fallbacks, fallback, "{kind:?}");
        assert_eq!(s.counts.unanswered, 2);
    }
}

#[test]
fn a_stale_stream_is_asked_again_while_heartbeats_go_on() {
    let mut s = Supervisor::new(SupervisorConfig::default());
    let from = endpoint(5760);
    let mut t = 0.0;
    observe(&mut s, from, t, 1, 1, &heartbeat(COPTER.0, COPTER.1));
    s.due(t);
    observe(&mut s, from, t, 1, 1, &ack(MavResult::MAV_RESULT_ACCEPTED));
    s.due(t);
    observe(&mut s, from, t, 1, 1, &ack(MavResult::MAV_RESULT_ACCEPTED));
    // Positions and attitude flow for 3 s, then stop; heartbeats go on.
    let mut asked_at = None;
    while t < 8.0 {
        if t < 3.0 {
            let ms = (t * 1000.0) as u32 + 5_000;
            observe(&mut s, from, t, 1, 1, &position(ms));
            observe(&mut s, from, t, 1, 1, &attitude(ms));
        }
        if (t * 10.0).round() as i64 % 10 == 0 {
            observe(&mut s, from, t, 1, 1, &heartbeat(COPTER.0, COPTER.1));
        }
        if requests(&s.due(t)).iter().any(|r| r.2 == 33) && asked_at.is_none() {
            asked_at = Some(t);
        }
        t += 0.05;
    }
    // Stale after max(5 periods at 20 Hz, 2 s) = 2 s without a position.
    let asked_at = asked_at.expect("the stale stream was asked again");
    assert!((5.0..5.2).contains(&asked_at), "{asked_at}");
    assert_eq!(s.counts.re_requests, 2, "both streams stopped");
    // A vehicle whose heartbeats stopped too is away, not stale: nothing is sent to it.
    let mut quiet = s.clone();
    assert!(requests(&quiet.due(30.0)).is_empty());
}

#[test]
fn a_reboot_is_reported_and_everything_is_asked_again() {
    let mut s = Supervisor::new(SupervisorConfig::default());
    let from = endpoint(5760);
    observe(&mut s, from, 0.0, 1, 1, &heartbeat(PX4.0, PX4.1));
    s.due(0.0);
    observe(
        &mut s,
        from,
        0.1,
        1,
        1,
        &ack(MavResult::MAV_RESULT_ACCEPTED),
    );
    s.due(0.2);
    observe(
        &mut s,
        from,
        0.3,
        1,
        1,
        &ack(MavResult::MAV_RESULT_ACCEPTED),
    );
    assert!(!observe(
        &mut s,
        from,
        0.4,
        1,
        1,
        &position(u32::MAX - 1_000)
    ));
    // A wrap of the 32-bit clock is not a reboot; a step back is.
    assert!(!observe(&mut s, from, 0.5, 1, 1, &position(u32::MAX - 10)));
    assert!(!observe(&mut s, from, 0.6, 1, 1, &position(20)));
    assert!(!observe(&mut s, from, 1.0, 1, 1, &position(20)));
    assert!(!observe(&mut s, from, 10.0, 1, 1, &heartbeat(PX4.0, PX4.1)));
    observe(&mut s, from, 10.0, 1, 1, &position(50_000));
    assert!(observe(&mut s, from, 10.1, 1, 1, &position(900)));
    assert_eq!(s.counts.reboots, 1);
    let v = &s.vehicles()[0];
    assert_eq!((v.reboots, v.returns), (1, 1));
    assert_eq!(requests(&s.due(10.2)).len(), 1);
}

#[test]
fn acks_for_another_gcs_and_our_own_echo_are_ignored() {
    let gcs = SenderId {
        system_id: 255,
        component_id: 190,
    };
    let mut s = Supervisor::new(SupervisorConfig {
        gcs,
        ..SupervisorConfig::default()
    });
    let from = endpoint(5760);
    observe(&mut s, from, 0.0, 1, 1, &heartbeat(COPTER.0, COPTER.1));
    s.due(0.0);
    // COMMAND_ACK's target_system (an extension field) names GCS 42: not our answer.
    let command = (MavCmd::MAV_CMD_SET_MESSAGE_INTERVAL as u16).to_le_bytes();
    let mut payload = vec![
        command[0],
        command[1],
        MavResult::MAV_RESULT_ACCEPTED as u8,
        0,
        0,
        0,
        0,
        0,
    ];
    payload.extend([42, 0]);
    let bytes = raw_v2(1, 1, 77, &payload);
    let Scan::Frame(frame) = scan(&bytes) else {
        panic!()
    };
    s.observe(from, 0.1, &frame);
    assert_eq!(
        state_of(&s, "1/1", "GLOBAL_POSITION_INT"),
        RequestState::Pending
    );
    // Our own heartbeat echoed back by a router makes no route.
    observe(
        &mut s,
        endpoint(9999),
        0.2,
        255,
        190,
        &heartbeat(MavType::MAV_TYPE_GCS, MavAutopilot::MAV_AUTOPILOT_INVALID),
    );
    let due = s.due(1.5);
    assert!(due.iter().all(|(e, _)| *e == from), "{due:?}");
}

/// COMMAND_ACK for SET_MESSAGE_INTERVAL from vehicle 1/1, accepted, targeted at
/// `target_system`/`target_component` (MAVLink 2's extension fields).
fn interval_ack(target_system: u8, target_component: u8) -> Vec<u8> {
    let command = (MavCmd::MAV_CMD_SET_MESSAGE_INTERVAL as u16).to_le_bytes();
    let mut payload = vec![command[0], command[1], MavResult::MAV_RESULT_ACCEPTED as u8];
    payload.extend([0, 0, 0, 0, 0, target_system, target_component]);
    raw_v2(1, 1, 77, &payload)
}

#[test]
fn a_ground_station_beside_savsim_is_neither_its_echo_nor_its_acknowledgement() {
    // savsim's default identity, and QGroundControl's (255/190) on the same link.
    let ours = SupervisorConfig::default().gcs;
    assert_eq!((ours.system_id, ours.component_id), (245, 190));
    let mut s = Supervisor::new(SupervisorConfig::default());
    let from = endpoint(5760);
    observe(&mut s, from, 0.0, 1, 1, &heartbeat(COPTER.0, COPTER.1));
    assert_eq!(requests(&s.due(0.0)).len(), 1);
    let ack = |s: &mut Supervisor, t_s: f64, bytes: &[u8]| {
        let Scan::Frame(frame) = scan(bytes) else {
            panic!()
        };
        s.observe(from, t_s, &frame);
    };
    // QGroundControl's acknowledgement (255/190), then one for another component of savsim's
    // system (245/191): neither answers savsim's request.
    ack(&mut s, 0.1, &interval_ack(255, 190));
    ack(&mut s, 0.2, &interval_ack(245, 191));
    assert_eq!(
        state_of(&s, "1/1", "GLOBAL_POSITION_INT"),
        RequestState::Pending
    );
    // QGroundControl's heartbeat is a peer heard at its address, not an echo to drop: savsim
    // sends its heartbeat there too.
    let station = endpoint(14550);
    observe(
        &mut s,
        station,
        0.3,
        255,
        190,
        &heartbeat(MavType::MAV_TYPE_GCS, MavAutopilot::MAV_AUTOPILOT_INVALID),
    );
    let due = s.due(1.5);
    assert!(due.iter().any(|(e, _)| *e == station), "{due:?}");
    // The acknowledgement for savsim itself (245/190) answers it.
    ack(&mut s, 1.6, &interval_ack(245, 190));
    assert_eq!(
        state_of(&s, "1/1", "GLOBAL_POSITION_INT"),
        RequestState::Accepted
    );
}

/// A MAVLink 2 frame with `payload` for message `id`, its CRC computed as the crate does.
fn raw_v2(sysid: u8, compid: u8, id: u32, payload: &[u8]) -> Vec<u8> {
    use mavlink::Message;
    let extra = MavMessage::extra_crc(id);
    let mut frame = vec![
        0xFD,
        payload.len() as u8,
        0,
        0,
        0,
        sysid,
        compid,
        id as u8,
        (id >> 8) as u8,
        (id >> 16) as u8,
    ];
    frame.extend_from_slice(payload);
    let crc = mavlink::calculate_crc(&frame[1..], extra);
    frame.extend_from_slice(&crc.to_le_bytes());
    frame
}
