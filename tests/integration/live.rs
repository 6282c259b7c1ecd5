//! A live UDP link on 127.0.0.1 (ports bound to 0) against a vehicle played by a tokio task with
//! the mavlink crate; and `record`'s tlog read back by pymavlink. Bounded in time: the link runs
//! for 2 s.

use std::collections::BTreeMap;
use std::net::SocketAddr;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Duration;

use mavlink::dialects::ardupilotmega::{
    MavAutopilot, MavCmd, MavMessage, MavModeFlag, MavResult, MavState, MavType, ATTITUDE_DATA,
    COMMAND_ACK_DATA, GLOBAL_POSITION_INT_DATA, HEARTBEAT_DATA,
};
use mavlink::{MavHeader, MavlinkVersion};
use savsim::collision::pipeline::CollisionConfig;
use savsim::geo::Geodetic;
use savsim::ingest::live::{run_link, ConnectAddress, Link, LiveOptions};
use savsim::ingest::stats::SenderId;
use savsim::session::Session;
use tokio::net::UdpSocket;

use crate::common::{have_pymavlink, python, root};

/// What the vehicle heard from savsim.
#[derive(Debug, Default)]
struct Heard {
    gcs_heartbeats: usize,
    interval_requests: BTreeMap<u32, f32>,
    sent_positions: usize,
    last_position: Option<(i32, i32, i32)>,
}

fn encode(seq: &mut u8, message: &MavMessage) -> Vec<u8> {
    let mut buf = Vec::new();
    let header = MavHeader {
        system_id: 7,
        component_id: 1,
        sequence: *seq,
    };
    *seq = seq.wrapping_add(1);
    mavlink::write_versioned_msg(&mut buf, MavlinkVersion::V2, header, message).unwrap();
    buf
}

/// The vehicle: streams a flight at 50 Hz for `duration`, answers interval requests.
async fn vehicle(
    socket: UdpSocket,
    savsim: SocketAddr,
    duration: Duration,
    heard: Arc<Mutex<Heard>>,
) {
    let mut seq = 0u8;
    let mut buf = [0u8; 2048];
    let start = tokio::time::Instant::now();
    let mut tick = tokio::time::interval(Duration::from_millis(20));
    let mut n = 0i32;
    while start.elapsed() < duration {
        tokio::select! {
            _ = tick.tick() => {
                n += 1;
                let lat = -353_632_610 + n * 10;
                let lon = 1_491_652_300 + n * 5;
                let alt = 600_000 + n;
                let mut out = Vec::new();
                if n % 50 == 1 {
                    out.push(MavMessage::HEARTBEAT(HEARTBEAT_DATA {
                        custom_mode: 0,
                        mavtype: MavType::MAV_TYPE_QUADROTOR,
                        autopilot: MavAutopilot::MAV_AUTOPILOT_ARDUPILOTMEGA,
                        base_mode: MavModeFlag::empty(),
                        system_status: MavState::MAV_STATE_ACTIVE,
                        mavlink_version: 3,
                    }));
                }
                out.push(MavMessage::GLOBAL_POSITION_INT(GLOBAL_POSITION_INT_DATA {
                    time_boot_ms: 10_000 + 20 * n as u32, lat, lon, alt, relative_alt: 16_000,
                    vx: 50, vy: 25, vz: 0, hdg: 4500,
                }));
                out.push(MavMessage::ATTITUDE(ATTITUDE_DATA {
                    time_boot_ms: 10_000 + 20 * n as u32, roll: 0.0, pitch: 0.0, yaw: 0.785,
                    rollspeed: 0.0, pitchspeed: 0.0, yawspeed: 0.0,
                }));
                for m in &out {
                    socket.send_to(&encode(&mut seq, m), savsim).await.unwrap();
                }
                let mut h = heard.lock().unwrap();
                h.sent_positions += 1;
                h.last_position = Some((lat, lon, alt));
            }
            received = socket.recv_from(&mut buf) => {
                let Ok((len, from)) = received else { continue };
                let mut reader = mavlink::MavlinkReader::new(&buf[..len]);
                while let Ok((_, message)) = reader.read_any_message::<MavMessage>() {
                    match message {
                        MavMessage::HEARTBEAT(h) if h.mavtype == MavType::MAV_TYPE_GCS => {
                            heard.lock().unwrap().gcs_heartbeats += 1;
                        }
                        MavMessage::COMMAND_LONG(c) if c.command == MavCmd::MAV_CMD_SET_MESSAGE_INTERVAL => {
                            assert_eq!((c.target_system, c.target_component), (7, 1));
                            heard.lock().unwrap().interval_requests.insert(c.param1 as u32, c.param2);
                            let ack = MavMessage::COMMAND_ACK(COMMAND_ACK_DATA {
                                command: c.command,
                                result: MavResult::MAV_RESULT_ACCEPTED,
                            });
                            socket.send_to(&encode(&mut seq, &ack), from).await.unwrap();
                        }
                        _ => {}
                    }
                }
            }
        }
    }
}

fn run_vehicle_and_savsim(record: Option<&std::path::Path>) -> (Session, Heard) {
    let runtime = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
        .unwrap();
    let (savsim_socket, vehicle_socket) = runtime.block_on(async {
        (
            UdpSocket::bind("127.0.0.1:0").await.unwrap(),
            UdpSocket::bind("127.0.0.1:0").await.unwrap(),
        )
    });
    let savsim_addr = savsim_socket.local_addr().unwrap();
    let heard = Arc::new(Mutex::new(Heard::default()));
    runtime.spawn(vehicle(
        vehicle_socket,
        savsim_addr,
        Duration::from_millis(1800),
        heard.clone(),
    ));
    let options = LiveOptions {
        address: ConnectAddress::UdpIn(savsim_addr),
        rate_hz: 20.0,
        duration: Some(Duration::from_millis(2500)),
        ..LiveOptions::default()
    };
    let session = Session::new(None, CollisionConfig::default(), None).unwrap();
    let link = Link::Udp {
        socket: savsim_socket,
        peer: None,
        fixed_peer: false,
    };
    let shutdown = Arc::new(AtomicBool::new(false));
    let session = run_link(&runtime, link, options, session, record, shutdown.clone()).unwrap();
    assert!(!shutdown.load(Ordering::Relaxed));
    let heard = std::mem::take(&mut *heard.lock().unwrap());
    (session, heard)
}

#[test]
fn live_udp_mirrors_the_vehicle_and_requests_rates() {
    let (session, heard) = run_vehicle_and_savsim(None);
    let sender = SenderId {
        system_id: 7,
        component_id: 1,
    };
    // Every position sent was received and decoded (loopback loses nothing at 50 Hz).
    let stats = &session.ingestor.stats;
    assert_eq!(stats.count_of(33) as usize, heard.sent_positions);
    assert_eq!(stats.dropped_chunks, 0);
    let track = &session.world.vehicles[&sender];
    let latest = track.history.latest().unwrap();
    let (lat, lon, alt) = heard.last_position.unwrap();
    let want = Geodetic::new(lat as f64 * 1e-7, lon as f64 * 1e-7, alt as f64 * 1e-3);
    assert!((latest.position.lat_deg - want.lat_deg).abs() < 1e-12);
    assert!((latest.position.lon_deg - want.lon_deg).abs() < 1e-12);
    assert!((latest.position.alt_m - want.alt_m).abs() < 1e-9);
    assert_eq!(track.vehicle_type, Some(MavType::MAV_TYPE_QUADROTOR));
    // savsim spoke to the vehicle: heartbeats and both interval requests at 20 Hz.
    assert!(heard.gcs_heartbeats >= 1, "{heard:?}");
    assert_eq!(
        heard.interval_requests.get(&33),
        Some(&50_000.0),
        "{heard:?}"
    );
    assert_eq!(
        heard.interval_requests.get(&30),
        Some(&50_000.0),
        "{heard:?}"
    );
    // The vehicle accepted, so no REQUEST_DATA_STREAM fallback.
    assert_eq!(stats.stream_requests, 0);
}

#[test]
fn recording_is_a_tlog_pymavlink_reads_with_the_same_counts() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("rec.tlog");
    let (session, _) = run_vehicle_and_savsim(Some(&path));
    let ours = session.ingestor.stats.messages_by_name();
    // savsim reads its own recording back identically.
    let again = crate::common::replay_into_session(&path, None);
    assert_eq!(again.ingestor.stats.messages_by_name(), ours);
    if !have_pymavlink() {
        return;
    }
    let counts = python(
        &root().join("tests/fixtures/count_tlog.py"),
        &[path.to_str().unwrap()],
    );
    let theirs: BTreeMap<String, u64> = serde_json::from_str(counts.trim()).unwrap();
    let ours: BTreeMap<String, u64> = ours.into_iter().map(|(k, v)| (k.to_owned(), v)).collect();
    assert_eq!(ours, theirs);
}

/// A SITL-like TCP server on 127.0.0.1:0: accepts savsim, streams frames cut into odd pieces.
#[test]
fn live_tcp_reassembles_frames_across_reads() {
    let runtime = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
        .unwrap();
    let listener = runtime
        .block_on(tokio::net::TcpListener::bind("127.0.0.1:0"))
        .unwrap();
    let addr = listener.local_addr().unwrap();
    let sent = 300usize;
    runtime.spawn(async move {
        use tokio::io::AsyncWriteExt;
        let (mut stream, _) = listener.accept().await.unwrap();
        let mut seq = 0u8;
        let mut bytes = Vec::new();
        for n in 0..sent as i32 {
            bytes.extend(encode(
                &mut seq,
                &MavMessage::GLOBAL_POSITION_INT(GLOBAL_POSITION_INT_DATA {
                    time_boot_ms: 1000 + n as u32,
                    lat: -353_632_610 + n,
                    lon: 1_491_652_300,
                    alt: 600_000,
                    relative_alt: 0,
                    vx: 0,
                    vy: 0,
                    vz: 0,
                    hdg: 0,
                }),
            ));
            bytes.extend_from_slice(&[0x00, 0x42]); // line noise between frames
        }
        for piece in bytes.chunks(37) {
            stream.write_all(piece).await.unwrap();
            tokio::time::sleep(Duration::from_micros(200)).await;
        }
        // Closing the connection ends savsim's run.
    });
    let link = runtime
        .block_on(Link::open(&ConnectAddress::TcpOut(addr.to_string())))
        .unwrap();
    let options = LiveOptions {
        address: ConnectAddress::TcpOut(addr.to_string()),
        duration: Some(Duration::from_secs(20)),
        ..LiveOptions::default()
    };
    let session = Session::new(None, CollisionConfig::default(), None).unwrap();
    let session = run_link(
        &runtime,
        link,
        options,
        session,
        None,
        Arc::new(AtomicBool::new(false)),
    )
    .unwrap();
    let stats = &session.ingestor.stats;
    assert_eq!(stats.count_of(33) as usize, sent);
    assert_eq!(stats.garbage_bytes as usize, 2 * sent);
    assert_eq!(stats.bad_crc, 0);
}

/// SIGINT during `savsim live` leaves a complete summary and events file.
#[test]
fn sigint_during_live_writes_the_summary() {
    let dir = tempfile::tempdir().unwrap();
    let summary = dir.path().join("s.json");
    let events = dir.path().join("e.jsonl");
    let mut child = std::process::Command::new(env!("CARGO_BIN_EXE_savsim"))
        .current_dir(root())
        .args([
            "live",
            "--connect",
            "udpin:127.0.0.1:0",
            "--scene",
            "scenes/city.toml",
            "--duration-s",
            "30",
            "--summary-json",
        ])
        .arg(&summary)
        .arg("--events")
        .arg(&events)
        .stdout(std::process::Stdio::null())
        .spawn()
        .unwrap();
    std::thread::sleep(Duration::from_millis(1500));
    let killed = std::process::Command::new("kill")
        .args(["-INT", &child.id().to_string()])
        .status()
        .unwrap();
    assert!(killed.success());
    let status = child.wait().unwrap();
    assert!(status.success(), "{status:?}");
    let s: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&summary).unwrap()).unwrap();
    assert_eq!(s["interrupted"], true);
    assert_eq!(s["command"], "live");
    assert!(events.exists());
}
