//! Live links on 127.0.0.1 (ports bound to 0) against vehicles played by tokio tasks with the
//! mavlink crate, behaving as the autopilots do: an ArduPilot streams positions only after a
//! SET_MESSAGE_INTERVAL addressed to its own (sysid, compid) and loses its streams at a
//! reboot; a PX4 streams at 50 Hz by default and falls back to it at a reboot. Several vehicles
//! on one UDP link, a forwarded companion computer, tcpin and tcpout lifecycles, SIGINT, and
//! `record`'s tlog read back by pymavlink. Every run stops once what the test waits for has
//! happened (the vehicles finished and savsim took all they sent, a silence was logged, a
//! link opened), within a deadline; no test sleeps for a guessed time.

use std::collections::BTreeMap;
use std::net::SocketAddr;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use mavlink::dialects::ardupilotmega::{
    MavAutopilot, MavCmd, MavMessage, MavResult, MavType, ATTITUDE_DATA, COMMAND_ACK_DATA,
    GLOBAL_POSITION_INT_DATA,
};
use savsim::geo::Geodetic;
use savsim::links::address::ConnectAddress;
use savsim::links::sockets::Link;
use savsim::live::LiveRun;
use savsim::pipeline::CollisionConfig;
use savsim::session::Session;
use savsim::world::SenderId;
use tokio::net::UdpSocket;

use crate::common::{
    frame_v2, have_pymavlink, heartbeat, python, root, run_live_until, runtime, signal_and_wait,
    udp_link, until_processed, wait_until,
};

/// How the played autopilot behaves.
#[derive(Debug, Clone, Copy)]
struct Behaviour {
    sysid: u8,
    autopilot: MavAutopilot,
    /// Streams at 50 Hz before any request (PX4), or nothing until asked (ArduPilot).
    streams_by_default: bool,
    /// Reboot at this time after start: silent for `reboot_silence`, then sequence and clock
    /// start again from 0 and the requested rates are forgotten.
    reboot_at: Option<Duration>,
    reboot_silence: Duration,
    /// Also forward a companion computer's heartbeat as sysid/191.
    forward_companion: bool,
    run_for: Duration,
}

impl Behaviour {
    fn ardupilot(sysid: u8) -> Self {
        Self {
            sysid,
            autopilot: MavAutopilot::MAV_AUTOPILOT_ARDUPILOTMEGA,
            streams_by_default: false,
            reboot_at: None,
            reboot_silence: Duration::from_millis(800),
            forward_companion: false,
            run_for: Duration::from_millis(2500),
        }
    }
}

/// What the vehicle heard from savsim.
#[derive(Debug, Default)]
struct Heard {
    gcs_heartbeats: usize,
    /// SET_MESSAGE_INTERVAL addressed to this vehicle: message id -> interval, us.
    interval_requests: BTreeMap<u32, f32>,
    /// Commands or requests addressed to anyone else (the forwarded companion).
    misaddressed: usize,
    data_stream_requests: usize,
    sent_positions: usize,
    positions_after_reboot: usize,
    last_position: Option<(i32, i32, i32)>,
    /// Its run is over: it sends nothing more.
    done: bool,
}

struct Encoder {
    sysid: u8,
    seq: u8,
}

impl Encoder {
    fn encode(&mut self, compid: u8, message: &MavMessage) -> Vec<u8> {
        let bytes = frame_v2(self.sysid, compid, self.seq, message);
        self.seq = self.seq.wrapping_add(1);
        bytes
    }
}

/// Where the vehicle sends, and how it reaches savsim.
enum Wire {
    Udp(UdpSocket, SocketAddr),
    Tcp(tokio::net::TcpStream),
}

/// The vehicle: heartbeats at 1 Hz, positions and attitude at the requested rate (checked
/// every 10 ms), answers SET_MESSAGE_INTERVAL addressed to it.
// REQUEST_DATA_STREAM is deprecated; the played ArduPilot still counts what it gets.
#[allow(deprecated)]
async fn vehicle(wire: Wire, b: Behaviour, heard: Arc<Mutex<Heard>>) {
    let mut enc = Encoder {
        sysid: b.sysid,
        seq: 0,
    };
    // The companion numbers its own frames; only every third reaches this link.
    let mut companion = Encoder {
        sysid: b.sysid,
        seq: 0,
    };
    // The vehicle was up for a minute before savsim; after a reboot its clock starts at 0.
    let mut clock_offset_ms = 60_000u32;
    let (udp, mut tcp) = match wire {
        Wire::Udp(socket, to) => (Some((socket, to)), None),
        Wire::Tcp(stream) => (None, Some(stream)),
    };
    let start = tokio::time::Instant::now();
    let mut boot = start;
    let mut rebooted = false;
    let default_interval = b.streams_by_default.then_some(Duration::from_millis(20));
    let mut interval: BTreeMap<u32, Duration> = BTreeMap::new();
    let mut next_stream = start;
    let mut next_heartbeat = start;
    let mut tick = tokio::time::interval(Duration::from_millis(10));
    let mut buf = vec![0u8; 4096];
    let mut n = 0i32;
    while start.elapsed() < b.run_for {
        let mut out = Vec::new();
        let mut forwarded: Vec<Vec<u8>> = Vec::new();
        tokio::select! {
            _ = tick.tick() => {
                let now = tokio::time::Instant::now();
                if let Some(at) = b.reboot_at {
                    if !rebooted && now - start >= at {
                        rebooted = true;
                        tokio::time::sleep(b.reboot_silence).await;
                        boot = tokio::time::Instant::now();
                        clock_offset_ms = 0;
                        enc.seq = 0;
                        interval.clear();
                        continue;
                    }
                }
                if now >= next_heartbeat {
                    next_heartbeat = now + Duration::from_secs(1);
                    out.push((1, heartbeat(MavType::MAV_TYPE_QUADROTOR, b.autopilot)));
                    if b.forward_companion {
                        let hb = heartbeat(MavType::MAV_TYPE_ONBOARD_CONTROLLER, MavAutopilot::MAV_AUTOPILOT_INVALID);
                        forwarded.push(companion.encode(191, &hb));
                        companion.seq = companion.seq.wrapping_add(2);
                    }
                }
                let period = interval.get(&33).copied().or(default_interval);
                if let Some(period) = period {
                    if now >= next_stream {
                        next_stream = now + period;
                        n += 1;
                        let ms = (now - boot).as_millis() as u32 + clock_offset_ms;
                        let (lat, lon, alt) = (-353_632_610 + n * 10, 1_491_652_300 + n * 5, 600_000 + n);
                        out.push((1, MavMessage::GLOBAL_POSITION_INT(GLOBAL_POSITION_INT_DATA {
                            time_boot_ms: ms, lat, lon, alt, relative_alt: 16_000,
                            vx: 50, vy: 25, vz: 0, hdg: 4500,
                        })));
                        out.push((1, MavMessage::ATTITUDE(ATTITUDE_DATA {
                            time_boot_ms: ms, roll: 0.0, pitch: 0.0, yaw: 0.785,
                            rollspeed: 0.0, pitchspeed: 0.0, yawspeed: 0.0,
                        })));
                        let mut h = heard.lock().unwrap();
                        h.sent_positions += 1;
                        h.positions_after_reboot += usize::from(rebooted);
                        h.last_position = Some((lat, lon, alt));
                    }
                }
            }
            received = async {
                match (&udp, &mut tcp) {
                    (Some((socket, _)), _) => socket.recv(&mut buf).await,
                    (None, Some(stream)) => {
                        use tokio::io::AsyncReadExt;
                        stream.read(&mut buf).await
                    }
                    _ => unreachable!(),
                }
            } => {
                let Ok(len) = received else { break };
                if len == 0 { break }
                let mut reader = mavlink::MavlinkReader::new(&buf[..len]);
                while let Ok((_, message)) = reader.read_any_message::<MavMessage>() {
                    let mut h = heard.lock().unwrap();
                    match message {
                        MavMessage::HEARTBEAT(hb) if hb.mavtype == MavType::MAV_TYPE_GCS => h.gcs_heartbeats += 1,
                        MavMessage::COMMAND_LONG(c) if (c.target_system, c.target_component) != (b.sysid, 1) => h.misaddressed += 1,
                        MavMessage::REQUEST_DATA_STREAM(r) => {
                            h.data_stream_requests += 1;
                            if (r.target_system, r.target_component) != (b.sysid, 1) { h.misaddressed += 1 }
                        }
                        MavMessage::COMMAND_LONG(c) if c.command == MavCmd::MAV_CMD_SET_MESSAGE_INTERVAL => {
                            h.interval_requests.insert(c.param1 as u32, c.param2);
                            interval.insert(c.param1 as u32, Duration::from_micros(c.param2 as u64));
                            out.push((1, MavMessage::COMMAND_ACK(COMMAND_ACK_DATA {
                                command: c.command,
                                result: MavResult::MAV_RESULT_ACCEPTED,
                                ..Default::default()
                            })));
                        }
                        _ => {}
                    }
                }
            }
        }
        let own = out
            .iter()
            .map(|(compid, m)| enc.encode(*compid, m))
            .collect::<Vec<_>>();
        for bytes in own.into_iter().chain(forwarded) {
            match (&udp, &mut tcp) {
                (Some((socket, to)), _) => {
                    socket.send_to(&bytes, to).await.unwrap();
                }
                (None, Some(stream)) => {
                    use tokio::io::AsyncWriteExt;
                    if stream.write_all(&bytes).await.is_err() {
                        return;
                    }
                }
                _ => unreachable!(),
            }
        }
    }
}

/// Start one UDP vehicle per behaviour, each on its own socket (its own source port), all
/// sending to one savsim udpin link; run savsim until every vehicle has finished and savsim has
/// taken all they sent (`common::until_processed`), within [`LIMIT`].
fn vehicles_on_one_udp_link(
    behaviours: &[Behaviour],
    record: Option<&std::path::Path>,
) -> (LiveRun, Vec<Heard>) {
    let runtime = runtime();
    let (link, savsim) = udp_link(&runtime);
    let heard: Vec<_> = behaviours
        .iter()
        .map(|b| {
            let h = Arc::new(Mutex::new(Heard::default()));
            let socket = runtime.block_on(UdpSocket::bind("127.0.0.1:0")).unwrap();
            runtime.spawn(vehicle_then_done(Wire::Udp(socket, savsim), *b, h.clone()));
            h
        })
        .collect();
    let stop = Arc::new(AtomicBool::new(false));
    let watcher = std::thread::spawn({
        let (heard, stop) = (heard.clone(), stop.clone());
        move || {
            let deadline = Instant::now() + LIMIT;
            let done = wait_until(deadline, || heard.iter().all(|h| h.lock().unwrap().done))
                && until_processed(savsim, deadline);
            stop.store(true, Ordering::Relaxed);
            done
        }
    });
    let session = Session::new(None, CollisionConfig::default(), None).unwrap();
    let run = run_live_until(&runtime, vec![link], LIMIT, session, record, stop);
    assert!(
        watcher.join().unwrap(),
        "the vehicles did not finish, or savsim did not take what they sent, within {LIMIT:?}"
    );
    let heard = heard
        .iter()
        .map(|h| std::mem::take(&mut *h.lock().unwrap()))
        .collect();
    (run, heard)
}

/// [`vehicle`], then `done` raised in what it heard.
async fn vehicle_then_done(wire: Wire, b: Behaviour, heard: Arc<Mutex<Heard>>) {
    vehicle(wire, b, heard.clone()).await;
    heard.lock().unwrap().done = true;
}

/// The longest any run of these tests may take, whatever the machine's load.
const LIMIT: Duration = Duration::from_secs(60);

/// The system of the autopilot heartbeat [`until_taken_over_tcp`] sends.
const TCP_MARKER: u8 = 250;

/// Wait until savsim has taken everything sent before on this TCP connection: an autopilot
/// heartbeat of system [`TCP_MARKER`], resent every 200 ms, until savsim asks that autopilot
/// for a stream (its SET_MESSAGE_INTERVAL comes only once its session thread has taken the
/// heartbeat, and a connection's bytes are taken in order). Whether it happened by `deadline`.
async fn until_taken_over_tcp(stream: &mut tokio::net::TcpStream, deadline: Instant) -> bool {
    use tokio::io::{AsyncReadExt, AsyncWriteExt};
    let mut enc = Encoder {
        sysid: TCP_MARKER,
        seq: 0,
    };
    let marker = heartbeat(
        MavType::MAV_TYPE_QUADROTOR,
        MavAutopilot::MAV_AUTOPILOT_ARDUPILOTMEGA,
    );
    let mut buf = vec![0u8; 4096];
    while Instant::now() < deadline {
        if stream.write_all(&enc.encode(1, &marker)).await.is_err() {
            return false;
        }
        let read = tokio::time::timeout(Duration::from_millis(200), stream.read(&mut buf)).await;
        let Ok(Ok(len)) = read else { continue };
        if len == 0 {
            return false;
        }
        let mut reader = mavlink::MavlinkReader::new(&buf[..len]);
        while let Ok((_, message)) = reader.read_any_message::<MavMessage>() {
            if matches!(message, MavMessage::COMMAND_LONG(c) if c.target_system == TCP_MARKER) {
                return true;
            }
        }
    }
    false
}

fn sender(sysid: u8) -> SenderId {
    SenderId {
        system_id: sysid,
        component_id: 1,
    }
}

#[test]
fn live_udp_mirrors_the_vehicle_and_requests_rates() {
    let (run, heard) = vehicles_on_one_udp_link(&[Behaviour::ardupilot(7)], None);
    let (session, heard) = (&run.session, &heard[0]);
    // Every position sent was received and decoded (loopback loses nothing at 20 Hz).
    let stats = &session.stats();
    assert!(heard.sent_positions > 20, "{heard:?}");
    assert_eq!(stats.count_of(33) as usize, heard.sent_positions);
    assert_eq!(stats.dropped_chunks, 0);
    let track = session.world().vehicle(&sender(7)).unwrap();
    let latest = track.history.latest().unwrap();
    let (lat, lon, alt) = heard.last_position.unwrap();
    let want = Geodetic::new(lat as f64 * 1e-7, lon as f64 * 1e-7, alt as f64 * 1e-3);
    assert!((latest.position.lat_deg - want.lat_deg).abs() < 1e-12);
    assert!((latest.position.lon_deg - want.lon_deg).abs() < 1e-12);
    assert!((latest.position.alt_m - want.alt_m).abs() < 1e-9);
    assert_eq!(
        track.heartbeat.map(|h| h.mav_type),
        Some(MavType::MAV_TYPE_QUADROTOR as u8)
    );
    // savsim spoke to the vehicle: heartbeats and both interval requests at 20 Hz.
    assert!(heard.gcs_heartbeats >= 2, "{heard:?}");
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
    // The vehicle accepted, so no REQUEST_DATA_STREAM fallback; the latency was measured.
    assert_eq!(run.report.counts.stream_requests, 0);
    assert_eq!(heard.data_stream_requests, 0);
    let latency = run.report.latency.unwrap();
    assert!(latency.chunks > 0 && latency.p50_us <= latency.p99_us);
}

#[test]
fn two_vehicles_on_one_udpin_link_are_each_asked_at_their_own_address() {
    let behaviours = [Behaviour::ardupilot(1), Behaviour::ardupilot(2)];
    let (run, heard) = vehicles_on_one_udp_link(&behaviours, None);
    for (b, h) in behaviours.iter().zip(&heard) {
        // An ArduPilot streams only once asked at its own (sysid, compid): both were.
        assert!(h.gcs_heartbeats >= 2, "{b:?} {h:?}");
        assert!(h.interval_requests.contains_key(&33), "{b:?} {h:?}");
        assert_eq!(h.misaddressed, 0, "{b:?} {h:?}");
        let seen = run.session.world().seen[&sender(b.sysid)];
        assert_eq!(seen.positions as usize, h.sent_positions, "{b:?}");
        assert!(h.sent_positions > 10, "{b:?} {h:?}");
    }
    assert_eq!(run.report.vehicles.len(), 2);
}

#[test]
fn a_rebooted_ardupilot_is_asked_again_and_its_sequence_restarts() {
    let b = Behaviour {
        reboot_at: Some(Duration::from_millis(1500)),
        reboot_silence: Duration::from_millis(800),
        run_for: Duration::from_millis(5000),
        ..Behaviour::ardupilot(3)
    };
    let (run, heard) = vehicles_on_one_udp_link(&[b], None);
    let h = &heard[0];
    // Streams came back after the reboot because savsim asked again.
    assert!(h.positions_after_reboot > 10, "{h:?}");
    let stats = &run.session.stats();
    assert_eq!(stats.count_of(33) as usize, h.sent_positions);
    let seq = stats.sequence[&sender(3)];
    assert_eq!((seq.lost, seq.late), (0, 0), "{seq:?}");
    assert!(seq.restarts >= 1, "{seq:?}");
    let v = &run.report.vehicles[0];
    assert!(v.reboots + v.returns + v.re_requests >= 1, "{v:?}");
    assert_eq!(run.session.world().seen[&sender(3)].boot_resets, 1);
}

#[test]
fn a_px4_reboot_restores_the_asked_rate() {
    let b = Behaviour {
        autopilot: MavAutopilot::MAV_AUTOPILOT_PX4,
        streams_by_default: true,
        reboot_at: Some(Duration::from_millis(1500)),
        reboot_silence: Duration::from_millis(300),
        run_for: Duration::from_millis(4000),
        ..Behaviour::ardupilot(4)
    };
    let (run, heard) = vehicles_on_one_udp_link(&[b], None);
    let v = &run.report.vehicles[0];
    assert_eq!(v.reboots, 1, "{v:?}");
    // Asked twice per message: at the start and after the reboot; never REQUEST_DATA_STREAM.
    assert_eq!(
        run.report.counts.interval_requests, 4,
        "{:?}",
        run.report.counts
    );
    assert_eq!(heard[0].data_stream_requests, 0);
    let seq = run.session.stats().sequence[&sender(4)];
    assert_eq!((seq.lost, seq.late), (0, 0), "{seq:?}");
}

#[test]
fn a_forwarded_companion_is_never_asked_and_counted_apart() {
    let b = Behaviour {
        forward_companion: true,
        ..Behaviour::ardupilot(5)
    };
    let (run, heard) = vehicles_on_one_udp_link(&[b], None);
    let h = &heard[0];
    assert_eq!(h.misaddressed, 0, "{h:?}");
    assert_eq!(run.report.vehicles.len(), 1);
    // The companion's frames share the vehicle's sequence (one router), so as a sender of its
    // own it shows gaps: those are counted apart from the vehicle's link quality (with the
    // test's own marker, `common::MARKER`, another sender that is no autopilot).
    let summary = run.session.stats().to_summary();
    assert_eq!(summary.sequence.senders, 1);
    assert_eq!(summary.sequence.lost, 0);
    assert_eq!(summary.forwarded_sequence.senders, 2);
    assert!(
        summary.forwarded_sequence.lost > 0,
        "{:?}",
        summary.forwarded_sequence
    );
}

#[test]
fn recording_is_a_tlog_pymavlink_reads_with_the_same_counts() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("rec.tlog");
    let (run, _) = vehicles_on_one_udp_link(&[Behaviour::ardupilot(7)], Some(&path));
    let ours = run.session.stats().messages_by_name();
    // savsim reads its own recording back identically.
    let again = crate::common::replay_into_session(&path, None);
    assert_eq!(again.stats().messages_by_name(), ours);
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
    let runtime = runtime();
    let listener = runtime
        .block_on(tokio::net::TcpListener::bind("127.0.0.1:0"))
        .unwrap();
    let addr = listener.local_addr().unwrap();
    let sent = 300usize;
    let stop = Arc::new(AtomicBool::new(false));
    let server = runtime.spawn({
        let stop = stop.clone();
        async move {
            use tokio::io::AsyncWriteExt;
            let (mut stream, _) = listener.accept().await.unwrap();
            let mut enc = Encoder { sysid: 7, seq: 0 };
            let mut bytes = Vec::new();
            for n in 0..sent as i32 {
                bytes.extend(enc.encode(
                    1,
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
            let taken = until_taken_over_tcp(&mut stream, Instant::now() + LIMIT).await;
            stop.store(true, Ordering::Relaxed);
            taken
        }
    });
    let link = runtime
        .block_on(Link::open(&ConnectAddress::TcpOut(addr.into())))
        .unwrap();
    let session = Session::new(None, CollisionConfig::default(), None).unwrap();
    let run = run_live_until(&runtime, vec![link], LIMIT, session, None, stop);
    assert!(
        runtime.block_on(server).unwrap(),
        "savsim did not take what was sent within {LIMIT:?}"
    );
    let stats = &run.session.stats();
    assert_eq!(stats.count_of(33) as usize, sent);
    assert_eq!(stats.garbage_bytes as usize, 2 * sent);
    assert_eq!(stats.bad_crc, 0);
}

/// tcpout started before its server: savsim retries until the server is up, and reconnects
/// after the server closes and comes back; a vehicle on a UDP link is mirrored beside it.
#[test]
fn tcpout_waits_for_its_server_and_reconnects_beside_a_udp_link() {
    let runtime = runtime();
    // A port nothing listens on yet.
    let port = std::net::TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port();
    let tcp = runtime
        .block_on(Link::open(&ConnectAddress::TcpOut(
            SocketAddr::from(([127, 0, 0, 1], port)).into(),
        )))
        .unwrap();
    let (udp, savsim_udp) = udp_link(&runtime);
    let tcp_heard = Arc::new(Mutex::new(Heard::default()));
    let server_heard = tcp_heard.clone();
    let deadline = Instant::now() + LIMIT;
    // Two rounds of a vehicle, then a third connection on which savsim shows it has taken both.
    let tcp_taken: Arc<Mutex<Option<bool>>> = Arc::default();
    runtime.spawn({
        let tcp_taken = tcp_taken.clone();
        async move {
            tokio::time::sleep(Duration::from_millis(300)).await;
            let listener = tokio::net::TcpListener::bind(("127.0.0.1", port))
                .await
                .unwrap();
            for round in 0..2 {
                let (stream, _) = listener.accept().await.unwrap();
                let b = Behaviour {
                    run_for: Duration::from_millis(800),
                    ..Behaviour::ardupilot(10 + round)
                };
                // The vehicle closes the connection when its time is up.
                vehicle(Wire::Tcp(stream), b, server_heard.clone()).await;
                tokio::time::sleep(Duration::from_millis(300)).await;
            }
            let (mut stream, _) = listener.accept().await.unwrap();
            let taken = until_taken_over_tcp(&mut stream, deadline).await;
            *tcp_taken.lock().unwrap() = Some(taken);
        }
    });
    let udp_heard = Arc::new(Mutex::new(Heard::default()));
    let socket = runtime.block_on(UdpSocket::bind("127.0.0.1:0")).unwrap();
    runtime.spawn(vehicle_then_done(
        Wire::Udp(socket, savsim_udp),
        Behaviour {
            run_for: Duration::from_millis(3500),
            ..Behaviour::ardupilot(20)
        },
        udp_heard.clone(),
    ));
    let stop = Arc::new(AtomicBool::new(false));
    let watcher = std::thread::spawn({
        let (tcp_taken, udp_heard, stop) = (tcp_taken.clone(), udp_heard.clone(), stop.clone());
        move || {
            let both = wait_until(deadline, || {
                tcp_taken.lock().unwrap().is_some() && udp_heard.lock().unwrap().done
            });
            let taken = both
                && *tcp_taken.lock().unwrap() == Some(true)
                && until_processed(savsim_udp, deadline);
            stop.store(true, Ordering::Relaxed);
            taken
        }
    });
    let session = Session::new(None, CollisionConfig::default(), None).unwrap();
    let run = run_live_until(&runtime, vec![tcp, udp], LIMIT, session, None, stop);
    assert!(
        watcher.join().unwrap(),
        "the vehicles did not finish, or savsim did not take what they sent, within {LIMIT:?}"
    );
    // Two rounds served and the third connection; savsim may have connected once more.
    assert!(run.report.connects >= 3, "{:?}", run.report);
    assert!(run.report.closes >= 2, "{:?}", run.report);
    let seen = &run.session.world().seen;
    for sysid in [10, 11, 20] {
        assert!(
            seen.get(&sender(sysid)).is_some_and(|s| s.positions > 5),
            "{sysid}: {seen:?}"
        );
    }
    let stats = &run.session.stats();
    let sent = tcp_heard.lock().unwrap().sent_positions + udp_heard.lock().unwrap().sent_positions;
    assert_eq!(stats.count_of(33) as usize, sent);
}

/// A log writer that raises `seen` when what it is given contains `text`.
#[derive(Clone)]
struct LogWatch {
    text: &'static str,
    seen: Arc<AtomicBool>,
}

impl std::io::Write for LogWatch {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        if String::from_utf8_lossy(buf).contains(self.text) {
            self.seen.store(true, Ordering::Relaxed);
        }
        Ok(buf.len())
    }

    fn flush(&mut self) -> std::io::Result<()> {
        Ok(())
    }
}

/// tcpin waits for a connection; its silence is logged and counted once; a shutdown during the
/// wait (raised once the silence was logged: the run's chores log on the caller's thread) ends
/// the run promptly with its report.
#[test]
fn tcpin_interrupted_while_waiting_ends_cleanly() {
    let runtime = runtime();
    let address = ConnectAddress::TcpIn("127.0.0.1:0".parse::<SocketAddr>().unwrap().into());
    let link = runtime.block_on(Link::open(&address)).unwrap();
    let shutdown = Arc::new(AtomicBool::new(false));
    let watch = LogWatch {
        text: "nothing received for",
        seen: Arc::new(AtomicBool::new(false)),
    };
    let raised = std::thread::spawn({
        let (flag, seen) = (shutdown.clone(), watch.seen.clone());
        move || {
            let logged = wait_until(Instant::now() + LIMIT, || seen.load(Ordering::Relaxed));
            flag.store(true, Ordering::Relaxed);
            logged.then(Instant::now)
        }
    });
    let options = savsim::live::LiveOptions {
        duration: Some(LIMIT),
        ..Default::default()
    };
    let session = Session::new(None, CollisionConfig::default(), None).unwrap();
    let log = tracing_subscriber::fmt()
        .with_writer(move || watch.clone())
        .with_max_level(tracing::Level::WARN)
        .finish();
    let run = tracing::subscriber::with_default(log, || {
        savsim::live::run_links(
            runtime.handle(),
            vec![link],
            &options,
            session,
            None,
            shutdown,
        )
    })
    .unwrap();
    let ended = Instant::now();
    let raised = raised.join().unwrap().expect("the silence was logged");
    assert!(run.ended.is_ok());
    assert!(run.session.interrupted());
    assert_eq!(run.report.silences, 1);
    // Promptly: the run polls its flag every 20 ms and drains for at most STOP_DRAIN (0.5 s).
    assert!(
        ended.duration_since(raised) < Duration::from_secs(3),
        "{:?} after the shutdown",
        ended.duration_since(raised)
    );
}

/// Whether process `pid` catches SIGINT (savsim's handler is installed) and holds a socket
/// (its link is open): `savsim live` is waiting on its link. Reads Linux's /proc.
fn waits_on_its_link(pid: u32) -> bool {
    let status = std::fs::read_to_string(format!("/proc/{pid}/status")).unwrap_or_default();
    let catches_int = status
        .lines()
        .find_map(|l| l.strip_prefix("SigCgt:"))
        .and_then(|mask| u64::from_str_radix(mask.trim(), 16).ok())
        .is_some_and(|mask| mask & (1 << (2 - 1)) != 0);
    let holds_a_socket = std::fs::read_dir(format!("/proc/{pid}/fd")).is_ok_and(|fds| {
        fds.flatten().any(|fd| {
            std::fs::read_link(fd.path())
                .is_ok_and(|target| target.to_string_lossy().starts_with("socket:"))
        })
    });
    catches_int && holds_a_socket
}

/// SIGINT during `savsim live` leaves a complete summary and events file, whether it waits on
/// a UDP socket or for a TCP connection.
#[test]
fn sigint_during_live_writes_the_summary() {
    for connect in ["udpin:127.0.0.1:0", "tcpin:localhost:0"] {
        let dir = tempfile::tempdir().unwrap();
        let summary = dir.path().join("s.json");
        let events = dir.path().join("e.jsonl");
        let mut child = std::process::Command::new(env!("CARGO_BIN_EXE_savsim"))
            .current_dir(root())
            .args([
                "live",
                "--connect",
                connect,
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
        let waiting = wait_until(Instant::now() + LIMIT, || waits_on_its_link(child.id()));
        assert!(waiting, "{connect}: savsim never opened its link");
        let status = signal_and_wait(&mut child, "INT");
        assert!(status.success(), "{connect}: {status:?}");
        let s: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(&summary).unwrap()).unwrap();
        assert_eq!(s["interrupted"], true, "{connect}");
        assert_eq!(s["command"], "live");
        assert_eq!(s["link"]["endpoints"][0], connect);
        assert!(events.exists());
    }
}
