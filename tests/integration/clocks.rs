//! Time comes from the vehicle's clock: samples that arrive in one read are still two
//! instants; a quick reboot is a new track whose first interval is swept; event times are on
//! the arrival clock whatever the vehicle clock's speedup and drift; one far-future tlog stamp
//! does not freeze the clock.

use std::sync::Arc;
use std::time::Duration;

use glam::DVec3;
use mavlink::dialects::ardupilotmega::{MavAutopilot, MavType};
use savsim::geo::{Geodetic, LocalTangentPlane};
use savsim::links::address::ConnectAddress;
use savsim::links::sockets::Link;
use savsim::pipeline::CollisionConfig;
use savsim::session::Session;

use crate::common::{
    collisions_on, feed, frame_v2, heartbeat, pose_messages, position_frames, scene_at,
};

const ORIGIN: Geodetic = Geodetic::new(-35.363261, 149.165230, 584.0);

/// Samples that arrive in one TCP read share a receive time; their interval comes from the
/// vehicle's clock, so a 200 m/s pass through a 1 m wall between them is swept and found.
#[test]
fn two_samples_in_one_tcp_read_are_swept_apart() {
    let s = scene_at(
        ORIGIN,
        "[[obstacle]]\nid = \"wall\"\nkind = \"building\"\nshape = { box = [1.0, 40.0, 40.0] }\nposition_enu_m = [0.0, 0.0, 0.0]\n",
    );
    let plane = LocalTangentPlane::new(s.origin);
    let runtime = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
        .unwrap();
    let listener = runtime
        .block_on(tokio::net::TcpListener::bind("127.0.0.1:0"))
        .unwrap();
    let addr = listener.local_addr().unwrap();
    runtime.spawn(async move {
        use tokio::io::AsyncWriteExt;
        let (mut stream, _) = listener.accept().await.unwrap();
        let mut seq = 0u8;
        // Pairs 100 ms apart on the vehicle's clock, 20 m apart, each pair in one write; the
        // wall is crossed inside the second pair.
        for pair in 0..5u32 {
            let mut bytes = Vec::new();
            for k in 0..2u32 {
                let n = pair * 2 + k;
                let x = -50.0 + 20.0 * f64::from(n) + 5.0;
                bytes.extend(position_frames(
                    &plane,
                    1,
                    &mut seq,
                    10_000 + 100 * n,
                    DVec3::new(x, 0.0, 10.0),
                    DVec3::X * 200.0,
                ));
            }
            stream.write_all(&bytes).await.unwrap();
            tokio::time::sleep(Duration::from_millis(200)).await;
        }
    });
    let address = ConnectAddress::TcpOut(addr.into());
    let link = runtime.block_on(Link::open(&address)).unwrap();
    let session = Session::new(Some(Arc::new(s)), CollisionConfig::default(), None).unwrap();
    // The server sends for about 2 s, then closes; savsim would reconnect, and stops at 4 s.
    let run = crate::common::run_live(&runtime, vec![link], Duration::from_secs(4), session, None);
    let session = run.session;
    assert_eq!(session.stats().count_of(33), 10);
    let hits = collisions_on(session.notable(), 1);
    assert_eq!(hits.len(), 1, "{hits:?}");
    assert_eq!(hits[0].0, "wall");
}

/// A wall 1 m thick across the east axis at E 50 m: a vehicle flying east at `speed` crosses it
/// between two samples (no sample inside it at 10 Hz above 10 m/s).
const WALL: &str = "[[obstacle]]\nid = \"wall\"\nkind = \"building\"\nshape = { box = [1.0, 200.0, 60.0] }\nposition_enu_m = [50.0, 0.0, 0.0]\n";

/// A session over the wall with one vehicle's heartbeat taken.
fn wall_session() -> Session {
    let scene = Arc::new(scene_at(ORIGIN, WALL));
    let mut session = Session::new(Some(scene), CollisionConfig::default(), None).unwrap();
    let hb = heartbeat(
        MavType::MAV_TYPE_QUADROTOR,
        MavAutopilot::MAV_AUTOPILOT_ARDUPILOTMEGA,
    );
    feed(&mut session, 0.0, &frame_v2(1, 1, 0, &hb));
    session
}

/// The collisions with the wall the session reported: (`t`, `time_of_impact`, swept).
fn wall_collisions(session: &Session) -> Vec<(f64, f64, bool)> {
    session
        .notable()
        .iter()
        .filter_map(|e| match &e.kind {
            savsim::collision::events::EventKind::Collision {
                time_of_impact,
                swept,
                ..
            } => Some((e.t, *time_of_impact, *swept)),
            _ => None,
        })
        .collect()
}

#[test]
fn a_quick_reboot_is_a_new_track_whose_first_interval_is_swept() {
    let plane = LocalTangentPlane::new(ORIGIN);
    let mut session = wall_session();
    let mut seq = 0u8;
    // Up to 6.5 s of its clock, hovering west of the wall.
    for i in 0..=65u32 {
        let bytes = crate::common::position_frames(
            &plane,
            1,
            &mut seq,
            i * 100,
            DVec3::new(0.0, 0.0, 30.0),
            DVec3::ZERO,
        );
        feed(&mut session, 100.0 + f64::from(i) * 0.1, &bytes);
    }
    // Silent 2 s, then streaming again from 1.5 s of a new clock (PX4 SITL restarts in
    // 0.49 s), flying east at 20 m/s through the wall between its first two samples.
    for (k, east_m) in [40.0, 60.0, 80.0].into_iter().enumerate() {
        let bytes = crate::common::position_frames(
            &plane,
            1,
            &mut seq,
            1_500 + 100 * k as u32,
            DVec3::new(east_m, 0.0, 30.0),
            DVec3::new(20.0, 0.0, 0.0),
        );
        feed(&mut session, 108.5 + 0.1 * k as f64, &bytes);
    }
    let seen = session.world().seen.values().next().unwrap();
    assert_eq!(seen.boot_resets, 1, "{seen:?}");
    let hits = wall_collisions(&session);
    assert_eq!(hits.len(), 1, "{hits:?}");
    let (t, toi, swept) = hits[0];
    assert!(swept, "{hits:?}");
    // Half way between the samples that arrived at 108.5 and 108.6 s.
    assert!(
        (toi - 108.55).abs() < 0.03 && (t - 108.6).abs() < 0.03,
        "{hits:?}"
    );
}

/// Flies east at 10 m/s of the vehicle's clock, sampled every 100 ms of it, through the wall
/// at E 50 m, with the vehicle's clock running `speedup` times the arrival clock; returns the
/// collision and the arrival time of the first sample east of the wall's face.
fn fly_through_wall(speedup: f64, latency: impl Fn(u32) -> f64) -> ((f64, f64, bool), f64) {
    let plane = LocalTangentPlane::new(ORIGIN);
    let mut session = wall_session();
    let mut seq = 0u8;
    let mut crossed_at = None;
    for i in 0..120u32 {
        let east_m = f64::from(i) - 0.25;
        let arrival_s = 1000.0 + f64::from(i) * 0.1 / speedup + latency(i);
        let bytes = crate::common::position_frames(
            &plane,
            1,
            &mut seq,
            30_000 + i * 100,
            DVec3::new(east_m, 0.0, 30.0),
            DVec3::new(10.0, 0.0, 0.0),
        );
        feed(&mut session, arrival_s, &bytes);
        if east_m >= 49.5 && crossed_at.is_none() {
            crossed_at = Some(arrival_s);
        }
    }
    let hits = wall_collisions(&session);
    assert_eq!(hits.len(), 1, "{hits:?}");
    (hits[0], crossed_at.unwrap())
}

#[test]
fn event_times_are_the_arrival_clock_at_any_speedup_and_drift() {
    // SITL at speedups 1, 5 and 30 with jittered latency; PX4 SIH running slow (0.9).
    for speedup in [1.0, 5.0, 30.0, 0.9] {
        let ((t, toi, _), crossed_at) =
            fly_through_wall(speedup, |i| 0.002 + f64::from(i * 37 % 11) * 0.001);
        assert!(
            (t - crossed_at).abs() < 0.3 && toi <= t && t - toi < 0.1 / speedup + 0.02,
            "speedup {speedup}: collision at t {t}, impact {toi}; the track crossed at {crossed_at}"
        );
    }
}

#[test]
fn one_far_future_tlog_timestamp_does_not_freeze_the_clock() {
    let dir = tempfile::tempdir().unwrap();
    let flight = dir.path().join("f.tlog");
    let plane = LocalTangentPlane::new(ORIGIN);
    let mut w = savsim::logs::tlog::TlogWriter::new(std::fs::File::create(&flight).unwrap());
    let mut seq = 0u8;
    for i in 0..100u32 {
        let t_us = 1_700_000_000_000_000 + u64::from(i) * 100_000;
        // One record's timestamp (outside the CRC) is 300 years on.
        let first_us = if i == 10 {
            10_000_000_000_000_000
        } else {
            t_us
        };
        let messages = pose_messages(
            &plane,
            1000 + 100 * i,
            DVec3::new(f64::from(i), 0.0, 30.0),
            DVec3::new(10.0, 0.0, 0.0),
            [0.0, 0.0, 0.0],
        );
        for (k, m) in messages.iter().enumerate() {
            let at = if k == 0 { first_us } else { t_us };
            w.write_record(at, &frame_v2(1, 1, seq, m)).unwrap();
            seq = seq.wrapping_add(1);
        }
    }
    w.flush().unwrap();
    drop(w);
    let session = crate::common::replay_into_session(&flight, None);
    let stats = &session.stats();
    eprintln!(
        "records {} outliers {} jumps {} back {} span {:?}",
        stats.tlog_records,
        stats.clock_outliers,
        stats.clock_jumps,
        stats.clock_backwards,
        stats.time_span_s
    );
    assert_eq!(stats.clock_outliers, 1);
    let (first, last) = stats.time_span_s.unwrap();
    assert!((last - first - 9.9).abs() < 1e-6, "{first} {last}");
    let latest = session
        .world()
        .vehicles()
        .map(|(_, v)| v)
        .next()
        .unwrap()
        .history
        .latest()
        .unwrap()
        .t_s;
    assert!(
        (latest - last).abs() < 0.05,
        "the last sample at {latest}, the clock at {last}"
    );
}
