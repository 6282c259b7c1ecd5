//! `--forward`: a ground station through savsim. The station is pymavlink (tests/python/
//! station.py, independent of savsim); the vehicle is a tokio task that answers as an
//! autopilot does (PARAM_REQUEST_READ, DO_SET_MODE, arming, SET_MESSAGE_INTERVAL). On
//! 127.0.0.1, ports bound to 0; every run stops by itself within a few seconds.

use std::collections::BTreeMap;
use std::io::{BufRead, BufReader};
use std::net::SocketAddr;
use std::process::{Command, Stdio};
use std::sync::atomic::AtomicBool;
use std::sync::{Arc, Mutex};
use std::time::Duration;

use mavlink::dialects::ardupilotmega::{
    MavAutopilot, MavCmd, MavMessage, MavModeFlag, MavParamType, MavResult, MavState, MavType,
    COMMAND_ACK_DATA, GLOBAL_POSITION_INT_DATA, HEARTBEAT_DATA, PARAM_VALUE_DATA, SYS_STATUS_DATA,
};
use mavlink::Message;
use savsim::links::address::ConnectAddress;
use savsim::live::{run_links, LiveOptions, LiveRun};
use savsim::pipeline::CollisionConfig;
use savsim::session::Session;
use tokio::net::UdpSocket;

use crate::common::{frame_v2, have_pymavlink, root, runtime, udp_link};

/// What the played vehicle sent and heard.
#[derive(Debug, Default)]
struct Vehicle {
    /// Sent, per message name, except what was addressed to savsim itself.
    sent_for_stations: BTreeMap<String, u64>,
    /// COMMAND_ACKs sent to savsim (its SET_MESSAGE_INTERVAL).
    acks_to_savsim: u64,
    /// Heard, per (sysid, compid) then message name.
    heard: BTreeMap<(u8, u8), BTreeMap<String, u64>>,
}

fn hb(custom_mode: u32, armed: bool) -> MavMessage {
    MavMessage::HEARTBEAT(HEARTBEAT_DATA {
        custom_mode,
        mavtype: MavType::MAV_TYPE_QUADROTOR,
        autopilot: MavAutopilot::MAV_AUTOPILOT_ARDUPILOTMEGA,
        base_mode: if armed {
            MavModeFlag::MAV_MODE_FLAG_SAFETY_ARMED | MavModeFlag::MAV_MODE_FLAG_CUSTOM_MODE_ENABLED
        } else {
            MavModeFlag::MAV_MODE_FLAG_CUSTOM_MODE_ENABLED
        },
        system_status: MavState::MAV_STATE_ACTIVE,
        mavlink_version: 3,
    })
}

fn ack(command: MavCmd, to: (u8, u8)) -> MavMessage {
    MavMessage::COMMAND_ACK(COMMAND_ACK_DATA {
        command,
        result: MavResult::MAV_RESULT_ACCEPTED,
        target_system: to.0,
        target_component: to.1,
        ..Default::default()
    })
}

/// System 1 on `socket`, sending to `to`: heartbeat 2 Hz, positions 20 Hz, SYS_STATUS 5 Hz,
/// for `run_for`; answers what a station and savsim ask.
async fn vehicle(socket: UdpSocket, to: SocketAddr, run_for: Duration, log: Arc<Mutex<Vehicle>>) {
    let start = tokio::time::Instant::now();
    let (mut mode, mut armed, mut seq, mut n) = (0u32, false, 0u8, 0u32);
    let mut tick = tokio::time::interval(Duration::from_millis(10));
    let mut buf = vec![0u8; 2048];
    while start.elapsed() < run_for {
        let mut out: Vec<(MavMessage, bool)> = Vec::new();
        tokio::select! {
            _ = tick.tick() => {
                n += 1;
                if n % 50 == 1 { out.push((hb(mode, armed), true)); }
                if n % 5 == 0 {
                    out.push((MavMessage::GLOBAL_POSITION_INT(GLOBAL_POSITION_INT_DATA {
                        time_boot_ms: n * 10, lat: -353_632_610, lon: 1_491_652_300, alt: 600_000,
                        relative_alt: 16_000, ..Default::default()
                    }), true));
                }
                if n % 20 == 0 {
                    out.push((MavMessage::SYS_STATUS(SYS_STATUS_DATA::default()), true));
                }
            }
            got = socket.recv(&mut buf) => {
                let Ok(len) = got else { break };
                let mut reader = mavlink::MavlinkReader::new(&buf[..len]);
                while let Ok((h, m)) = reader.read_any_message::<MavMessage>() {
                    let from = (h.system_id as u8, h.component_id);
                    *log.lock().unwrap().heard.entry(from).or_default()
                        .entry(m.message_name().to_string()).or_default() += 1;
                    match m {
                        MavMessage::PARAM_REQUEST_READ(p) if p.target_system == 1 => {
                            let mut id = [0u8; 16];
                            id[..13].copy_from_slice(b"SYSID_THISMAV");
                            out.push((MavMessage::PARAM_VALUE(PARAM_VALUE_DATA {
                                param_value: 1.0, param_count: 1, param_index: 0,
                                param_id: id.into(), param_type: MavParamType::MAV_PARAM_TYPE_INT8,
                            }), true));
                        }
                        MavMessage::COMMAND_LONG(c) if c.target_system == 1 => {
                            match c.command {
                                MavCmd::MAV_CMD_DO_SET_MODE => mode = c.param2 as u32,
                                MavCmd::MAV_CMD_COMPONENT_ARM_DISARM => armed = c.param1 == 1.0,
                                _ => {}
                            }
                            let to_savsim = from == (245, 190);
                            out.push((ack(c.command, from), !to_savsim));
                            if c.command == MavCmd::MAV_CMD_DO_SET_MODE
                                || c.command == MavCmd::MAV_CMD_COMPONENT_ARM_DISARM
                            {
                                out.push((hb(mode, armed), true));
                            }
                        }
                        _ => {}
                    }
                }
            }
        }
        for (m, for_stations) in out {
            let bytes = frame_v2(1, 1, seq, &m);
            seq = seq.wrapping_add(1);
            if socket.send_to(&bytes, to).await.is_err() {
                return;
            }
            let mut l = log.lock().unwrap();
            if for_stations {
                *l.sent_for_stations
                    .entry(m.message_name().to_string())
                    .or_default() += 1;
            } else {
                l.acks_to_savsim += 1;
            }
        }
    }
}

/// The station, started first: its process and the UDP port it listens on.
fn start_station(
    args: &[&str],
) -> (
    std::process::Child,
    BufReader<std::process::ChildStdout>,
    u16,
) {
    let mut child = Command::new("python3")
        .arg(root().join("tests/python/station.py"))
        .args(args)
        .stdout(Stdio::piped())
        .spawn()
        .expect("python3 runs");
    let mut out = BufReader::new(child.stdout.take().unwrap());
    let mut line = String::new();
    out.read_line(&mut line).unwrap();
    let port = line
        .trim()
        .strip_prefix("PORT ")
        .and_then(|p| p.parse().ok())
        .unwrap_or_else(|| panic!("station said {line:?}"));
    (child, out, port)
}

fn station_result(
    mut child: std::process::Child,
    mut out: BufReader<std::process::ChildStdout>,
) -> serde_json::Value {
    let mut text = String::new();
    std::io::Read::read_to_string(&mut out, &mut text).unwrap();
    assert!(child.wait().unwrap().success(), "station failed");
    serde_json::from_str(text.lines().last().unwrap_or(""))
        .unwrap_or_else(|e| panic!("{e}: {text}"))
}

/// savsim with one vehicle link and a station at udpout `station_port`, for `run_for`.
fn through_savsim(station_port: u16, run_for: Duration, forward_own: bool) -> (LiveRun, Vehicle) {
    let rt = runtime();
    let (vehicle_link, savsim_at) = udp_link(&rt);
    let station = ConnectAddress::UdpOut(
        format!("127.0.0.1:{station_port}")
            .parse::<SocketAddr>()
            .unwrap()
            .into(),
    );
    let station_link = rt
        .block_on(savsim::links::sockets::Link::open(&station))
        .unwrap();
    let log = Arc::new(Mutex::new(Vehicle::default()));
    let socket = rt.block_on(UdpSocket::bind("127.0.0.1:0")).unwrap();
    rt.spawn(vehicle(
        socket,
        savsim_at,
        run_for - Duration::from_millis(500),
        log.clone(),
    ));
    let options = LiveOptions {
        duration: Some(run_for),
        forward: vec![station],
        forward_own,
        ..Default::default()
    };
    let session = Session::new(None, CollisionConfig::default(), None).unwrap();
    let shutdown = Arc::new(AtomicBool::new(false));
    let run = run_links(
        rt.handle(),
        vec![vehicle_link, station_link],
        &options,
        session,
        None,
        shutdown,
    )
    .unwrap();
    if let Err(e) = &run.ended {
        panic!("the live run ended with {e}");
    }
    let vehicle = std::mem::take(&mut *log.lock().unwrap());
    (run, vehicle)
}

#[test]
fn a_station_through_forward_sees_everything_the_vehicle_sends_and_its_commands_act() {
    if !have_pymavlink() {
        return;
    }
    let (station, out, port) = start_station(&["--mode", "4", "--arm", "--run-s", "6"]);
    let (run, vehicle) = through_savsim(port, Duration::from_millis(4000), false);
    let seen = station_result(station, out);

    // Every message the vehicle sent for the stations arrived, as many times as it was sent.
    let from_vehicle = &seen["counts"]["1/1"];
    for (name, n) in &vehicle.sent_for_stations {
        assert_eq!(from_vehicle[name].as_u64(), Some(*n), "{name}: {seen}");
    }
    assert!(
        vehicle.sent_for_stations["GLOBAL_POSITION_INT"] > 50,
        "{vehicle:?}"
    );
    // Nothing but the vehicle's: not savsim's own heartbeat or requests, not the ACKs
    // the vehicle sent savsim, not the station's own frames back.
    let senders: Vec<&String> = seen["counts"].as_object().unwrap().keys().collect();
    assert_eq!(senders, ["1/1"], "{seen}");
    assert!(
        vehicle.acks_to_savsim > 0,
        "savsim asked its streams: {vehicle:?}"
    );
    assert_eq!(
        from_vehicle["COMMAND_ACK"].as_u64(),
        vehicle.sent_for_stations.get("COMMAND_ACK").copied(),
        "{seen}"
    );

    // The station's commands reached the vehicle and took effect, each once per ask.
    assert_eq!(seen["param"].as_f64(), Some(1.0), "{seen}");
    assert_eq!(seen["mode_set"], true, "{seen}");
    assert_eq!(seen["armed"], true, "{seen}");
    let from_station = &vehicle.heard[&(255, 190)];
    assert!(from_station["HEARTBEAT"] >= 3, "{from_station:?}");
    assert!(from_station["PARAM_REQUEST_READ"] >= 1, "{from_station:?}");

    let forward = run.report.forward.as_ref().expect("forward report");
    assert_eq!(
        forward.counts.to_stations,
        vehicle.sent_for_stations.values().sum::<u64>(),
        "{forward:?}"
    );
    assert_eq!(forward.counts.unroutable, 0);
    assert_eq!(forward.counts.own, 0);
    assert!(forward.latency.is_some(), "{forward:?}");
    // The station's frames went to the vehicle only, never into savsim's world.
    assert_eq!(
        run.session.stats().count_of(0),
        vehicle.sent_for_stations["HEARTBEAT"],
        "only the vehicle's heartbeats reach the session"
    );
}

#[test]
fn forward_own_shows_savsims_heartbeat_and_requests_to_the_station() {
    if !have_pymavlink() {
        return;
    }
    let (station, out, port) = start_station(&["--run-s", "4"]);
    let (run, _) = through_savsim(port, Duration::from_millis(2500), true);
    let seen = station_result(station, out);
    let own = &seen["counts"]["245/190"];
    assert!(own["HEARTBEAT"].as_u64() >= Some(2), "{seen}");
    assert!(own["COMMAND_LONG"].as_u64() >= Some(1), "{seen}");
    assert!(run.report.forward.as_ref().unwrap().counts.own >= 3);
}

#[test]
fn forward_addresses_are_checked_like_connect() {
    let out = crate::cli::savsim()
        .args([
            "live",
            "--connect",
            "udpin:127.0.0.1:0",
            "--forward",
            "serial:/dev/ttyS0",
            "--duration-s",
            "1",
        ])
        .output()
        .unwrap();
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("serial:/dev/ttyS0"), "{err}");
}
