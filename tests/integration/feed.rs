//! The closed-loop feed (docs/closed-loop.md): sector and bin distances against a ray cast
//! written here (a slab test on axis-aligned boxes, sharing no code with savsim's), the wire
//! rules checked by pymavlink (tests/python/check_feed.py), and two vehicles fed live over
//! loopback UDP, each at its own address, one of them echoing the feed back.

use std::collections::BTreeMap;
use std::net::SocketAddr;
use std::sync::{Arc, Mutex};
use std::time::Duration;

use glam::DVec3;
use mavlink::dialects::ardupilotmega::{MavAutopilot, MavMessage, MavType};
use savsim::feed::{FeedConfig, FeedKinds, FeedMessage};
use savsim::geo::{Geodetic, LocalTangentPlane};
use savsim::logs::tlog::TlogWriter;
use savsim::pipeline::CollisionConfig;
use savsim::session::Session;
use savsim::world::SenderId;
use tokio::net::UdpSocket;

use crate::common::{
    feed, frame_v2, have_pymavlink, heartbeat, python, root, run_live, runtime, scene_at, udp_link,
};

const ORIGIN: Geodetic = Geodetic::new(-35.363261, 149.165230, 584.0);

/// Boxes as (min, max) ENU corners, and the scene that places them (position = base centre).
const BOXES: [([f64; 3], [f64; 3]); 3] = [
    ([-10.0, 20.0, 0.0], [10.0, 40.0, 60.0]),
    ([-40.0, -15.0, 0.0], [-30.0, 15.0, 25.0]),
    ([15.0, -30.0, 0.0], [45.0, -22.0, 35.0]),
];

fn boxes_scene() -> String {
    crate::common::boxes_scene(&BOXES)
}

/// The nearest entry of the ray into any box within `max_m` (slab test).
fn slab_distance(origin: DVec3, dir: DVec3, max_m: f64) -> Option<f64> {
    let mut best: Option<f64> = None;
    for (lo, hi) in BOXES {
        let (mut t0, mut t1) = (0.0f64, max_m);
        let mut hit = true;
        for a in 0..3 {
            let (o, d) = (origin[a], dir[a]);
            if d.abs() < 1e-12 {
                if o < lo[a] || o > hi[a] {
                    hit = false;
                }
                continue;
            }
            let (mut ta, mut tb) = ((lo[a] - o) / d, (hi[a] - o) / d);
            if ta > tb {
                std::mem::swap(&mut ta, &mut tb);
            }
            t0 = t0.max(ta);
            t1 = t1.min(tb);
        }
        if hit && t0 <= t1 {
            best = Some(best.map_or(t0, |b: f64| b.min(t0)));
        }
    }
    best
}

/// Heading `psi` (rad, clockwise from north) plus `clockwise_deg`, levelled, as ENU.
fn levelled(psi: f64, clockwise_deg: f64) -> DVec3 {
    let a = psi + clockwise_deg.to_radians();
    DVec3::new(a.sin(), a.cos(), 0.0)
}

/// The body's down axis in ENU for roll, pitch, yaw (NED Euler, radians).
fn body_down_enu(roll: f64, pitch: f64, yaw: f64) -> DVec3 {
    let (sr, cr) = roll.sin_cos();
    let (sp, cp) = pitch.sin_cos();
    let (sy, cy) = yaw.sin_cos();
    let ned = DVec3::new(cr * sp * cy + sr * sy, cr * sp * sy - sr * cy, cr * cp);
    DVec3::new(ned.y, ned.x, -ned.z)
}

/// A pose: ENU position, roll, pitch, yaw (radians).
type Pose = (DVec3, f64, f64, f64);

/// ATTITUDE and GLOBAL_POSITION_INT for `pose`, holding still.
fn pose_messages(plane: &LocalTangentPlane, time_boot_ms: u32, pose: Pose) -> [MavMessage; 2] {
    let (p, roll, pitch, yaw) = pose;
    crate::common::pose_messages(plane, time_boot_ms, p, DVec3::ZERO, [roll, pitch, yaw])
}

/// [`pose_messages`] as MAVLink 2 frames from `sysid`/1, one after the other.
fn pose_frames(
    plane: &LocalTangentPlane,
    sysid: u8,
    seq: &mut u8,
    time_boot_ms: u32,
    pose: Pose,
) -> Vec<u8> {
    let mut bytes = Vec::new();
    for message in pose_messages(plane, time_boot_ms, pose) {
        bytes.extend(frame_v2(sysid, 1, *seq, &message));
        *seq = seq.wrapping_add(1);
    }
    bytes
}

fn config(list: &str) -> FeedConfig {
    FeedConfig {
        kinds: FeedKinds::parse(list).unwrap(),
        ..FeedConfig::default()
    }
}

/// Expected reading in cm: the wire's rounding, max + 1 for nothing within 40 m.
fn want_cm(distance: Option<f64>) -> i64 {
    match distance {
        Some(d) if d <= 40.0 => ((d * 100.0).round() as i64).max(20),
        _ => 4001,
    }
}

#[test]
fn sector_bin_and_rangefinder_distances_match_an_exact_ray_cast_within_a_centimetre() {
    let scene = Arc::new(scene_at(ORIGIN, &boxes_scene()));
    let plane = LocalTangentPlane::new(ORIGIN);
    // Level, yawed, pitched 25 deg nose down (levelled rays must not see the ground), rolled,
    // over a roof, and between the boxes.
    let poses: Vec<Pose> = vec![
        (DVec3::new(0.0, 5.0, 30.0), 0.0, 0.0, 0.0),
        (DVec3::new(0.0, 5.0, 30.0), 0.0, 0.0, 0.6),
        (DVec3::new(-5.0, 0.0, 20.0), 0.1, -0.44, 2.3),
        (DVec3::new(12.0, -5.0, 10.0), 0.35, 0.2, -1.9),
        (DVec3::new(0.0, 30.0, 70.0), 0.05, 0.1, 1.0),
        (DVec3::new(-20.0, 10.0, 12.0), 0.0, 0.0, 4.0),
    ];
    for kinds in ["proximity,rangefinder", "obstacle-distance"] {
        let mut session =
            Session::new(Some(scene.clone()), CollisionConfig::default(), None).unwrap();
        session.start_feed(config(kinds)).unwrap();
        let mut seq = 0;
        feed(
            &mut session,
            1000.0,
            &frame_v2(
                1,
                1,
                0,
                &heartbeat(
                    MavType::MAV_TYPE_QUADROTOR,
                    MavAutopilot::MAV_AUTOPILOT_ARDUPILOTMEGA,
                ),
            ),
        );
        let mut checked = 0;
        for (i, &pose) in poses.iter().enumerate() {
            let t_ms = 10_000 + 100 * i as u32;
            feed(
                &mut session,
                1000.0 + 0.1 * i as f64,
                &pose_frames(&plane, 1, &mut seq, t_ms, pose),
            );
            let origin = session
                .world()
                .vehicles()
                .map(|(_, v)| v)
                .next()
                .unwrap()
                .history
                .latest()
                .unwrap()
                .position_enu_m;
            let (_, roll, pitch, yaw) = pose;
            let out: Vec<FeedMessage> = session.drain_feed().collect();
            assert!(
                !out.is_empty(),
                "a frame for every sample 100 ms apart at 20 Hz"
            );
            for m in &out {
                assert_eq!(
                    m.to,
                    SenderId {
                        system_id: 1,
                        component_id: 1
                    }
                );
                match &m.message {
                    MavMessage::DISTANCE_SENSOR(d) => {
                        assert_eq!(d.time_boot_ms, t_ms);
                        let o = d.orientation as u8;
                        let want = match o {
                            0..=7 => (-4..=4)
                                .filter_map(|b| {
                                    slab_distance(
                                        origin,
                                        levelled(yaw, f64::from(o) * 45.0 + 5.0 * f64::from(b)),
                                        40.0,
                                    )
                                })
                                .min_by(f64::total_cmp),
                            24 => slab_distance(origin, DVec3::Z, 40.0),
                            25 => {
                                let down = body_down_enu(roll, pitch, yaw);
                                // No terrain: the ground is the plane U = 0.
                                let ground = (origin.z / -down.z).min(41.0);
                                slab_distance(origin, down, 40.0)
                                    .map_or(Some(ground), |d| Some(d.min(ground)))
                            }
                            other => panic!("orientation {other}"),
                        };
                        let got = i64::from(d.current_distance);
                        assert!(
                            (got - want_cm(want)).abs() <= 1,
                            "pose {i} orientation {o}: {got} cm, want {want:?}"
                        );
                        checked += 1;
                    }
                    MavMessage::OBSTACLE_DISTANCE(od) => {
                        for (j, &got) in od.distances.iter().enumerate() {
                            // Bin 0 is centred 20 degrees left of the nose.
                            let want =
                                slab_distance(origin, levelled(yaw, 5.0 * j as f64 - 20.0), 40.0);
                            assert!(
                                (i64::from(got) - want_cm(want)).abs() <= 1,
                                "pose {i} bin {j}: {got} cm, want {want:?}"
                            );
                            checked += 1;
                        }
                    }
                    other => panic!("unexpected {other:?}"),
                }
            }
        }
        // Something was in range in most directions, and out of range in others.
        assert!(checked >= poses.len() * 9, "{kinds}: {checked}");
    }
}

#[test]
fn replay_feed_out_writes_a_tlog_pymavlink_reads_by_the_rules() {
    if !have_pymavlink() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let flight = dir.path().join("flight.tlog");
    let scene_path = dir.path().join("boxes.toml");
    std::fs::write(
        &scene_path,
        format!(
            "[origin]\nlat_deg = {}\nlon_deg = {}\nalt_m = {}\n{}",
            ORIGIN.lat_deg,
            ORIGIN.lon_deg,
            ORIGIN.alt_m,
            boxes_scene()
        ),
    )
    .unwrap();
    // 10 s at 10 Hz flying north at 2 m/s towards b0's face at N 20 m.
    let plane = LocalTangentPlane::new(ORIGIN);
    let mut w = TlogWriter::new(std::io::BufWriter::new(
        std::fs::File::create(&flight).unwrap(),
    ));
    let mut seq = 0;
    let hb = heartbeat(
        MavType::MAV_TYPE_QUADROTOR,
        MavAutopilot::MAV_AUTOPILOT_ARDUPILOTMEGA,
    );
    for i in 0..100u32 {
        let t_us = 1_700_000_000_000_000 + u64::from(i) * 100_000;
        if i % 10 == 0 {
            w.write_record(t_us, &frame_v2(1, 1, 0, &hb)).unwrap();
        }
        let pose = (
            DVec3::new(0.0, -10.0 + 0.2 * f64::from(i), 30.0),
            0.0,
            0.0,
            0.0,
        );
        // One frame per tlog record.
        for message in pose_messages(&plane, 5_000 + i * 100, pose) {
            w.write_record(t_us, &frame_v2(1, 1, seq, &message))
                .unwrap();
            seq = seq.wrapping_add(1);
        }
    }
    w.flush().unwrap();
    drop(w);
    let out = dir.path().join("feed.tlog");
    let summary = dir.path().join("summary.json");
    let run = std::process::Command::new(env!("CARGO_BIN_EXE_savsim"))
        .args([
            "replay",
            flight.to_str().unwrap(),
            "--scene",
            scene_path.to_str().unwrap(),
        ])
        .args(["--feed", "proximity,rangefinder,adsb", "--feed-hz", "10"])
        .args([
            "--feed-out",
            out.to_str().unwrap(),
            "--summary-json",
            summary.to_str().unwrap(),
        ])
        .output()
        .unwrap();
    crate::common::assert_ran(&run);
    let checked: serde_json::Value = serde_json::from_str(&python(
        &root().join("tests/python/check_feed.py"),
        &[out.to_str().unwrap(), "--rangefinder"],
    ))
    .unwrap();
    // One frame per sample (10 Hz samples, 10 Hz feed), on the vehicle's clock.
    assert_eq!(checked["frames"], 100, "{checked}");
    assert!(
        (checked["rate_hz"].as_f64().unwrap() - 10.0).abs() < 0.1,
        "{checked}"
    );
    // The last sample is at N 9.8 m: b0's face at N 20 m is 10.2 m ahead; the ground 30 m down.
    assert_eq!(checked["last"]["0"], 1020, "{checked}");
    assert_eq!(checked["last"]["25"], 3000, "{checked}");
    assert_eq!(checked["last"]["4"], 4001, "{checked}");
    let s: serde_json::Value = serde_json::from_slice(&std::fs::read(&summary).unwrap()).unwrap();
    let v = &s["feed"]["vehicles"][0]["counts"];
    assert_eq!(v["frames"], 100, "{s}");
    assert_eq!(v["gaps"], 0, "{s}");
}

/// What a played vehicle received: (UNIX us, datagram).
type Received = Arc<Mutex<Vec<(u64, Vec<u8>)>>>;

/// A vehicle holding a pose: heartbeat at 1 Hz, ATTITUDE + GLOBAL_POSITION_INT at 20 Hz (as
/// PX4 streams unasked), recording every datagram it receives to `record`; with `echo`, it
/// also sends every datagram back (as a router that forwards to all would).
async fn holding(
    socket: UdpSocket,
    to: SocketAddr,
    sysid: u8,
    pose: Pose,
    echo: bool,
    run_for: Duration,
    record: Received,
) {
    let plane = LocalTangentPlane::new(ORIGIN);
    let start = tokio::time::Instant::now();
    let mut seq = 0u8;
    let mut tick = tokio::time::interval(Duration::from_millis(50));
    let mut n = 0u32;
    let mut buf = vec![0u8; 65_536];
    let hb = heartbeat(MavType::MAV_TYPE_QUADROTOR, MavAutopilot::MAV_AUTOPILOT_PX4);
    while start.elapsed() < run_for {
        tokio::select! {
            _ = tick.tick() => {
                let mut bytes = Vec::new();
                if n.is_multiple_of(20) {
                    bytes.extend(frame_v2(sysid, 1, seq, &hb));
                    seq = seq.wrapping_add(1);
                }
                bytes.extend(pose_frames(&plane, sysid, &mut seq, 30_000 + 50 * n, pose));
                n += 1;
                socket.send_to(&bytes, to).await.unwrap();
            }
            received = socket.recv(&mut buf) => {
                let Ok(len) = received else { break };
                let now_us = std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH).unwrap().as_micros() as u64;
                record.lock().unwrap().push((now_us, buf[..len].to_vec()));
                if echo {
                    socket.send_to(&buf[..len], to).await.unwrap();
                }
            }
        }
    }
}

#[test]
fn two_vehicles_are_fed_live_each_at_its_own_address_and_an_echo_is_ignored() {
    let rt = runtime();
    let (link, savsim_at) = udp_link(&rt);
    let run_for = Duration::from_millis(3000);
    // Vehicle 1 faces b0's south face (N 20 m) from N 10 m; vehicle 2 from N -5 m, 50 m up (20 m above vehicle 1, out of its levelled rays).
    let poses: BTreeMap<u8, Pose> = [
        (1, (DVec3::new(0.0, 10.0, 30.0), 0.0, 0.0, 0.0)),
        (2, (DVec3::new(5.0, -5.0, 50.0), 0.0, 0.0, 0.0)),
    ]
    .into();
    let records: Vec<_> = poses
        .iter()
        .map(|(&sysid, &pose)| {
            let record = Arc::new(Mutex::new(Vec::new()));
            let socket = rt.block_on(UdpSocket::bind("127.0.0.1:0")).unwrap();
            rt.spawn(holding(
                socket,
                savsim_at,
                sysid,
                pose,
                sysid == 1,
                run_for,
                record.clone(),
            ));
            (sysid, record)
        })
        .collect();
    let scene = Arc::new(scene_at(ORIGIN, &boxes_scene()));
    let mut session = Session::new(Some(scene), CollisionConfig::default(), None).unwrap();
    session.start_feed(config("proximity,adsb")).unwrap();
    let run = run_live(
        &rt,
        vec![link],
        run_for + Duration::from_millis(300),
        session,
        None,
    );
    // The echoed feed (ADS-B of vehicle 2 included) was counted, never applied to the world.
    let world = &run.session.world();
    assert_eq!(
        world
            .vehicles()
            .map(|(k, _)| k)
            .map(|k| k.system_id)
            .collect::<Vec<_>>(),
        vec![1, 2]
    );
    assert!(
        world.traffic().next().is_none(),
        "an echoed ADSB_VEHICLE became traffic"
    );
    let feed = run.report.feed.as_ref().unwrap();
    assert_eq!(feed.unrouted, 0);
    assert!(feed.heartbeats >= 2);
    let latency = feed.latency.unwrap();
    assert!(latency.p50_us <= latency.p99_us);
    if !have_pymavlink() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    for (sysid, record) in records {
        let path = dir.path().join(format!("v{sysid}.tlog"));
        let mut w = TlogWriter::new(std::fs::File::create(&path).unwrap());
        for (t_us, bytes) in record.lock().unwrap().iter() {
            w.write_record(*t_us, bytes).unwrap();
        }
        w.flush().unwrap();
        let checked: serde_json::Value = serde_json::from_str(&python(
            &root().join("tests/python/check_feed.py"),
            &[path.to_str().unwrap()],
        ))
        .unwrap();
        // 20 Hz on the vehicle's clock for ~3 s.
        assert!(checked["frames"].as_u64().unwrap() >= 40, "{checked}");
        let rate = checked["rate_hz"].as_f64().unwrap();
        assert!((rate - 20.0).abs() <= 1.0, "vehicle {sysid}: {rate} Hz");
        // Each vehicle was told its own distance to b0's face, not the other's.
        let want = if sysid == 1 { 1000 } else { 2500 };
        assert_eq!(checked["last"]["0"], want, "vehicle {sysid}: {checked}");
        // ... and about the other vehicle as ADS-B traffic (ICAO 0xF1 | sysid | compid).
        let other = if sysid == 1 { 2u32 } else { 1 };
        let icao = (0xF1_0000 | (other << 8) | 1).to_string();
        assert!(
            checked["adsb"].get(&icao).is_some(),
            "vehicle {sysid}: {checked}"
        );
        assert!(
            checked["adsb"].as_object().unwrap().len() == 1,
            "vehicle {sysid}: {checked}"
        );
    }
}

/// The feed's frames for samples of vehicle 1 at `times_ms` (its clock), a pose 10 m south
/// of b0: the stamps of the frames cast.
fn frame_stamps(hz: f64, times_ms: &[u32]) -> (Vec<u32>, serde_json::Value) {
    let scene = Arc::new(scene_at(ORIGIN, &boxes_scene()));
    let plane = LocalTangentPlane::new(ORIGIN);
    let mut session = Session::new(Some(scene), CollisionConfig::default(), None).unwrap();
    session
        .start_feed(FeedConfig {
            hz,
            ..config("proximity")
        })
        .unwrap();
    let mut seq = 0;
    let pose = (DVec3::new(0.0, 10.0, 30.0), 0.0, 0.0, 0.0);
    let mut stamps = Vec::new();
    for (i, &t_ms) in times_ms.iter().enumerate() {
        let t_s = 1000.0 + i as f64 * 0.02;
        feed(
            &mut session,
            t_s,
            &pose_frames(&plane, 1, &mut seq, t_ms, pose),
        );
        if let Some(MavMessage::DISTANCE_SENSOR(d)) =
            session.pending_feed().first().map(|m| &m.message)
        {
            stamps.push(d.time_boot_ms);
        }
        session.drain_feed().for_each(drop);
    }
    let summary = session.summary("replay", "test");
    (stamps, summary["feed"]["vehicles"][0].clone())
}

#[test]
fn frames_are_paced_on_the_vehicle_clock_never_burst_and_restart_after_a_reboot() {
    // 50 Hz telemetry with +-4 ms of jitter, 10 s: a 20 Hz feed, within 5%, no interval under
    // 35 ms or over 65 ms.
    let times: Vec<u32> = (0..500u32).map(|i| 60_000 + i * 20 + (i * 7 % 9)).collect();
    let (stamps, v) = frame_stamps(20.0, &times);
    let rate = (stamps.len() - 1) as f64 * 1000.0 / f64::from(stamps[stamps.len() - 1] - stamps[0]);
    assert!((rate - 20.0).abs() <= 1.0, "{rate} Hz");
    assert!(
        stamps
            .windows(2)
            .all(|w| (35..=65).contains(&(w[1] - w[0]))),
        "{stamps:?}"
    );
    assert_eq!(v["counts"]["gaps"], 0, "{v}");
    // Telemetry slower than the feed: one frame per sample, none invented.
    let slow: Vec<u32> = (0..50u32).map(|i| 60_000 + i * 200).collect();
    let (stamps, _) = frame_stamps(20.0, &slow);
    assert_eq!(stamps, slow);
    // A 2 s telemetry gap: one frame after it (counted as a gap), not 40 to catch up.
    let mut gap: Vec<u32> = (0..20u32).map(|i| 60_000 + i * 50).collect();
    gap.extend((0..20u32).map(|i| 63_000 + i * 50));
    let (stamps, v) = frame_stamps(20.0, &gap);
    assert_eq!(stamps.len(), 40, "{stamps:?}");
    assert_eq!(v["counts"]["gaps"], 1, "{v}");
    // A reboot: the clock goes back to 1 s; pacing starts again and stamps follow the new clock.
    let mut reboot: Vec<u32> = (0..20u32).map(|i| 60_000 + i * 50).collect();
    reboot.extend((0..20u32).map(|i| 1_000 + i * 50));
    let (stamps, v) = frame_stamps(20.0, &reboot);
    assert_eq!(stamps.len(), 40, "{stamps:?}");
    assert_eq!(stamps[20], 1_000);
    assert_eq!(v["counts"]["restarts"], 1, "{v}");
    // The vehicle's clock at the end of its 49.7 days: no overflow, a frame per period.
    let end: Vec<u32> = (0..10u32).map(|i| u32::MAX - 450 + i * 50).collect();
    let (stamps, _) = frame_stamps(20.0, &end);
    assert_eq!(stamps, end);
}

/// `live --feed-out` records what the feed sent, as sent: the frames the vehicle received, in
/// order, each stamped with when it was handed to the link; pymavlink reads it as a feed.
#[test]
fn live_feed_out_records_exactly_what_the_vehicle_received() {
    let rt = runtime();
    let (link, savsim_at) = udp_link(&rt);
    let run_for = Duration::from_millis(2000);
    let record: Received = Arc::new(Mutex::new(Vec::new()));
    let socket = rt.block_on(UdpSocket::bind("127.0.0.1:0")).unwrap();
    let pose = (DVec3::new(0.0, 10.0, 30.0), 0.0, 0.0, 0.0);
    rt.spawn(holding(
        socket,
        savsim_at,
        1,
        pose,
        false,
        run_for,
        record.clone(),
    ));
    let scene = Arc::new(scene_at(ORIGIN, &boxes_scene()));
    let mut session = Session::new(Some(scene), CollisionConfig::default(), None).unwrap();
    session.start_feed(config("proximity")).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let feed_out = dir.path().join("feed.tlog");
    let options = savsim::live::LiveOptions {
        duration: Some(run_for + Duration::from_millis(300)),
        feed_out: Some(feed_out.clone()),
        ..Default::default()
    };
    let shutdown = Arc::new(std::sync::atomic::AtomicBool::new(false));
    let run = savsim::live::run_links(rt.handle(), vec![link], &options, session, None, shutdown)
        .unwrap();
    run.ended.unwrap();
    // The tlog: 8-byte big-endian UNIX microseconds, then a MAVLink 2 frame (the feed's).
    let bytes = std::fs::read(&feed_out).unwrap();
    let (mut at, mut recorded, mut last_us) = (0, Vec::new(), 0u64);
    while at < bytes.len() {
        let t_us = u64::from_be_bytes(bytes[at..at + 8].try_into().unwrap());
        assert!(t_us >= last_us, "stamps go forward");
        last_us = t_us;
        let frame = &bytes[at + 8..];
        assert_eq!(frame[0], 0xFD, "a MAVLink 2 frame");
        let len = 12 + usize::from(frame[1]) + if frame[2] & 1 == 1 { 13 } else { 0 };
        recorded.push(frame[..len].to_vec());
        at += 8 + len;
    }
    // What the vehicle received from the feed's identity (245/196), not from savsim's GCS.
    let received: Vec<Vec<u8>> = record
        .lock()
        .unwrap()
        .iter()
        .filter(|(_, b)| b.len() > 6 && b[5] == 245 && b[6] == 196)
        .map(|(_, b)| b.clone())
        .collect();
    let feed = run.report.feed.as_ref().unwrap();
    assert_eq!(recorded.len() as u64, feed.sent + feed.heartbeats);
    assert!(recorded.len() > 100, "{} frames", recorded.len());
    // What reached the vehicle is what was recorded (loopback loses nothing; the peer may stop
    // listening a little before savsim stops sending).
    assert!(received.len() <= recorded.len() && received.len() + 20 >= recorded.len());
    assert!(
        received[..] == recorded[..received.len()],
        "the vehicle received other frames than were recorded"
    );
    if have_pymavlink() {
        let checked: serde_json::Value = serde_json::from_str(&python(
            &root().join("tests/python/check_feed.py"),
            &[feed_out.to_str().unwrap()],
        ))
        .unwrap();
        assert_eq!(checked["last"]["0"], 1000, "{checked}");
    }
}

/// A vehicle re-streams the traffic it was told about under its own identity (ArduPilot with
/// ADSB_TYPE > 0, PX4's transponder relay): those ADSB_VEHICLE are the feed's own aircraft
/// coming back, counted and never made a second body; other traffic the vehicle reports is
/// applied as before.
#[test]
fn traffic_the_vehicle_re_streams_is_not_read_back_as_traffic() {
    let scene = scene_at(
        ORIGIN,
        "[[dynamic]]\nid = \"airliner\"\nkind = \"a320\"\nwaypoints = [\
         { t_s = 0.0, position_enu_m = [2000.0, 0.0, 30.0] }, \
         { t_s = 100.0, position_enu_m = [-2000.0, 0.0, 30.0] }]\n",
    );
    let plane = LocalTangentPlane::new(ORIGIN);
    let mut session =
        Session::new(Some(Arc::new(scene)), CollisionConfig::default(), None).unwrap();
    session.start_feed(config("adsb")).unwrap();
    let (mut seq, mut echoed) = (0, 0);
    let pose = (DVec3::new(0.0, 0.0, 30.0), 0.0, 0.0, 0.0);
    for i in 0..50u32 {
        let t_s = 1000.0 + f64::from(i) * 0.1;
        let mut bytes = pose_frames(&plane, 1, &mut seq, 60_000 + i * 100, pose);
        // Last sample's ADS-B, handed back by the vehicle (1/1) ...
        for m in session.drain_feed() {
            if let MavMessage::ADSB_VEHICLE(mut a) = m.message {
                bytes.extend(frame_v2(1, 1, seq, &MavMessage::ADSB_VEHICLE(a.clone())));
                echoed += 1;
                // ... beside an aircraft of its own receiver's, 300 m north.
                a.ICAO_address = 0x48_40D6;
                a.lat += 27_000;
                bytes.extend(frame_v2(
                    1,
                    1,
                    seq.wrapping_add(1),
                    &MavMessage::ADSB_VEHICLE(a),
                ));
                seq = seq.wrapping_add(2);
            }
        }
        feed(&mut session, t_s, &bytes);
    }
    assert!(echoed >= 5, "the feed sent ADS-B {echoed} times");
    let traffic: Vec<u32> = session.world().traffic().map(|(k, _)| *k).collect();
    assert_eq!(
        traffic,
        [0x48_40D6],
        "only the receiver's own aircraft is traffic"
    );
    let summary = session.summary("replay", "test");
    assert_eq!(
        summary["feed"]["adsb_echoes"], echoed,
        "{}",
        summary["feed"]
    );
}

/// Two vehicles behind one router address (one socket sends both, as MAVProxy's or
/// mavlink-router's output does): the feed names no target, so it is refused with an error
/// that says what to do, and nothing was sent to the shared address; without the feed both
/// are mirrored.
#[test]
fn the_feed_is_refused_for_vehicles_behind_one_router_address() {
    let run = |feeding: bool| {
        let rt = runtime();
        let (link, savsim_at) = udp_link(&rt);
        let router = rt.block_on(UdpSocket::bind("127.0.0.1:0")).unwrap();
        let run_for = Duration::from_millis(1500);
        rt.spawn(async move {
            let plane = LocalTangentPlane::new(ORIGIN);
            let hb = heartbeat(MavType::MAV_TYPE_QUADROTOR, MavAutopilot::MAV_AUTOPILOT_PX4);
            let (mut seq, start) = ([0u8; 2], tokio::time::Instant::now());
            let mut tick = tokio::time::interval(Duration::from_millis(50));
            let mut n = 0u32;
            while start.elapsed() < run_for {
                tick.tick().await;
                for (k, sysid) in [1u8, 2].into_iter().enumerate() {
                    let mut bytes = Vec::new();
                    if n.is_multiple_of(10) {
                        bytes.extend(frame_v2(sysid, 1, seq[k], &hb));
                        seq[k] = seq[k].wrapping_add(1);
                    }
                    let pose = (DVec3::new(f64::from(sysid) * 5.0, 0.0, 30.0), 0.0, 0.0, 0.0);
                    bytes.extend(pose_frames(
                        &plane,
                        sysid,
                        &mut seq[k],
                        30_000 + 50 * n,
                        pose,
                    ));
                    let _ = router.send_to(&bytes, savsim_at).await;
                }
                n += 1;
            }
        });
        let scene = Arc::new(scene_at(ORIGIN, &boxes_scene()));
        let mut session = Session::new(Some(scene), CollisionConfig::default(), None).unwrap();
        if feeding {
            session.start_feed(config("proximity")).unwrap();
        }
        let options = savsim::live::LiveOptions {
            duration: Some(run_for),
            ..Default::default()
        };
        let shutdown = Arc::new(std::sync::atomic::AtomicBool::new(false));
        savsim::live::run_links(rt.handle(), vec![link], &options, session, None, shutdown).unwrap()
    };
    let refused = run(true);
    let err = refused.ended.expect_err("the feed is refused").to_string();
    assert!(
        err.contains("vehicles 1/1 and 2/1") || err.contains("vehicles 2/1 and 1/1"),
        "{err}"
    );
    assert!(err.contains("its own link"), "{err}");
    // Before the second vehicle is heard the address is the first one's alone: at most its
    // first frame of sectors (9 messages) went there; nothing once both were heard.
    let sent = refused.report.feed.as_ref().unwrap().sent;
    assert!(sent <= 9, "{sent} feed messages went to the shared address");

    let mirrored = run(false);
    mirrored.ended.unwrap();
    assert_eq!(
        mirrored.report.vehicles.len(),
        2,
        "{:?}",
        mirrored.report.vehicles
    );
}
