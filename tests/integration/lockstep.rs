//! Lockstep (`physics = savsim`): the physics loop against an autopilot played here over UDP
//! (its replies, a re-sent packet, a bad packet, silence), and, with `SAVSIM_ARDUCOPTER`, rows
//! of ArduCopter SITL flown in lockstep twice giving the same results bit for bit, two vehicles
//! on one clock among them.

use std::net::UdpSocket;
use std::sync::Arc;
use std::time::{Duration, Instant};

use glam::DVec3;
use savsim::lockstep::backend::ArduPilotJson;
use savsim::lockstep::driver::{run, Ended, Lockstepped, LoopConfig, LoopError};
use savsim::lockstep::port::{JsonPort, MavPort, PortError};
use savsim::lockstep::vehicle::SimVehicle;
use savsim::pipeline::CollisionConfig;
use savsim::session::Session;
use savsim::world::SenderId;
use savsim_core::dynamics::presets::preset;

use crate::cli::savsim;
use crate::common::assert_ran;
use crate::sitl::{sitl_test, Autopilot, Netns};

const ID: SenderId = SenderId {
    system_id: 1,
    component_id: 1,
};

/// A servo packet: `magic`, frame `count`, every output at `pwm_us`, `len` bytes.
fn packet(magic: u16, count: u32, pwm_us: u16, len: usize) -> Vec<u8> {
    let mut b = vec![0u8; len];
    b[0..2].copy_from_slice(&magic.to_le_bytes());
    b[2..4].copy_from_slice(&400u16.to_le_bytes());
    b[4..8].copy_from_slice(&count.to_le_bytes());
    for k in 0..16.min((len.saturating_sub(8)) / 2) {
        b[8 + 2 * k..10 + 2 * k].copy_from_slice(&pwm_us.to_le_bytes());
    }
    b
}

/// One vehicle of the flat scene on a physics port of its own (port 0: any).
fn one_vehicle(scene: &savsim::scene::Scene) -> Lockstepped {
    let json = JsonPort::bind(0).unwrap();
    let serial0 = MavPort::bind().unwrap();
    let vehicle = SimVehicle::landed(
        ID,
        preset("arducopter-quad").unwrap(),
        (scene.origin, DVec3::ZERO),
        0.0,
        DVec3::ZERO,
    );
    Lockstepped::new(vehicle, Box::new(ArduPilotJson::new(json)), serial0)
}

fn flat_scene() -> savsim::scene::Scene {
    crate::common::scene_at(savsim::scene::gen::DEFAULT_ORIGIN, "")
}

fn config(end_s: f64) -> LoopConfig {
    LoopConfig {
        step_us: 2_500,
        truth_every_us: 20_000,
        real_time: None,
        silence: Duration::from_millis(500),
        end_us: Some((end_s * 1e6) as u64),
        stop_on_collision: false,
        end_with_first_pilot: false,
    }
}

/// Play an autopilot: `n` packets at `pwm_us` to `port`, each after the reply to the last
/// (one re-sent in the middle); the replies, parsed.
fn autopilot(port: u16, n: u32, pwm_us: u16) -> Vec<serde_json::Value> {
    let socket = UdpSocket::bind("127.0.0.1:0").unwrap();
    socket
        .set_read_timeout(Some(Duration::from_secs(5)))
        .unwrap();
    let mut replies = Vec::new();
    let mut buf = [0u8; 4096];
    for count in 0..n {
        socket
            .send_to(&packet(18458, count, pwm_us, 40), ("127.0.0.1", port))
            .unwrap();
        let k = socket.recv(&mut buf).unwrap();
        let text = String::from_utf8(buf[..k].to_vec()).unwrap();
        assert!(text.starts_with('\n') && text.ends_with('\n'), "{text:?}");
        if count == n / 2 {
            // Re-sent (as SITL does after a second without a reply): the same reply again.
            socket
                .send_to(&packet(18458, count, pwm_us, 40), ("127.0.0.1", port))
                .unwrap();
            let again = socket.recv(&mut buf).unwrap();
            assert_eq!(&buf[..again], text.as_bytes());
        }
        replies.push(serde_json::from_str(text.trim()).unwrap());
    }
    replies
}

/// Full throttle from the ground: each reply a step of the clock later, the vehicle climbing,
/// its IMU reading the thrust; a re-sent packet answered with the same reply.
#[test]
fn the_loop_answers_each_servo_packet_with_the_next_step_of_its_clock() {
    let scene = flat_scene();
    let mut vehicles = [one_vehicle(&scene)];
    let port = vehicles[0].backend.port();
    let player = std::thread::spawn(move || autopilot(port, 400, 1950));
    let mut session = Session::new(
        Some(Arc::new(scene.clone())),
        CollisionConfig::default(),
        None,
    )
    .unwrap();
    let (time_us, ended) = run(&mut vehicles, &scene, &mut session, &config(1.0), &|_| {
        false
    })
    .unwrap();
    assert_eq!((time_us, ended), (1_000_000, Ended::Time));
    let replies = player.join().unwrap();
    for (k, r) in replies.iter().enumerate() {
        let t = r["timestamp"].as_f64().unwrap();
        assert!((t - (k + 1) as f64 * 0.0025).abs() < 1e-12, "{k}: {t}");
    }
    let last = &replies[399];
    let down_m = last["position"][2].as_f64().unwrap();
    assert!(down_m < -3.0, "climbed: {last}");
    let az = last["imu"]["accel_body"][2].as_f64().unwrap();
    assert!(az < -15.0, "full thrust read: {last}");
    // The world had the truth: the vehicle's track reached the height flown.
    let world = session.world();
    let track = world.vehicle(&ID).expect("the vehicle in the world");
    let up_m = track.history.latest().unwrap().position_enu_m.z;
    assert!((up_m + down_m).abs() < 0.5, "{up_m} vs {down_m}");
}

/// A packet of the wrong size or magic is an error that names it; an autopilot that never
/// sends is an error after the silence allowed, not a hang.
#[test]
fn bad_packets_and_a_silent_autopilot_end_the_loop_with_an_error() {
    let scene = flat_scene();
    let mut session = Session::new(None, CollisionConfig::default(), None).unwrap();
    for (bytes, says) in [
        (packet(18458, 0, 1500, 39), "39 bytes"),
        (packet(18459, 0, 1500, 40), "magic is 18459"),
        (packet(18458, 0, 1500, 72), "magic is 18458 for 72 bytes"),
    ] {
        let mut vehicles = [one_vehicle(&scene)];
        let port = vehicles[0].backend.port();
        let socket = UdpSocket::bind("127.0.0.1:0").unwrap();
        socket.send_to(&bytes, ("127.0.0.1", port)).unwrap();
        let e = run(&mut vehicles, &scene, &mut session, &config(1.0), &|_| {
            false
        })
        .unwrap_err();
        assert!(
            matches!(
                e,
                LoopError::Port {
                    source: PortError::Packet { .. },
                    ..
                }
            ),
            "{e}"
        );
        assert!(e.to_string().contains(says), "{e}");
    }
    let mut vehicles = [one_vehicle(&scene)];
    let started = Instant::now();
    let e = run(&mut vehicles, &scene, &mut session, &config(1.0), &|_| {
        false
    })
    .unwrap_err();
    assert!(e.to_string().contains("no servo packet"), "{e}");
    assert!(started.elapsed() < Duration::from_secs(5));
}

/// The results of a study's rows as (row id, column, value) text, every column but the
/// wall-clock ones (`wall_*`, `achieved_speedup`).
pub(crate) fn results(dir: &std::path::Path) -> Vec<String> {
    let mut shards: Vec<_> = std::fs::read_dir(dir)
        .unwrap()
        .flatten()
        .map(|e| e.path())
        .filter(|p| p.extension().is_some_and(|e| e == "parquet"))
        .collect();
    shards.sort();
    let mut out = Vec::new();
    for shard in shards {
        let batch = crate::batch::read(&shard);
        for (field, column) in batch.schema().fields().iter().zip(batch.columns()) {
            if field.name().starts_with("wall_") || field.name() == "achieved_speedup" {
                continue;
            }
            for i in 0..column.len() {
                let value = format!("{:?}", column.slice(i, 1));
                out.push(format!("{i} {} {}", field.name(), value.replace('\n', " ")));
            }
        }
    }
    out
}

/// Column `name` of row `row` in [`results`]' lines (empty when it has none).
pub(crate) fn cell(rows: &[String], name: &str, row: usize) -> String {
    rows.iter()
        .find(|l| l.starts_with(&format!("{row} {name} ")))
        .cloned()
        .unwrap_or_default()
}

/// A row of one ArduCopter and a row of two (the second flying 300 m from the first) flown in
/// lockstep, two at once, twice: every result column the same to the last bit (the truth
/// track, the collisions and approaches, the outcome, the autopilot's modes and estimate).
#[test]
fn lockstep_rows_flown_twice_give_the_same_results_bit_for_bit() {
    let Some(_turn) = sitl_test(Autopilot::ArduCopter, Netns::Study, &[]) else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let manifest = dir.path().join("m.csv");
    std::fs::write(
        &manifest,
        "id,physics,plan,duration_s,intruder_autopilot,intruder_plan,intruder_home\n\
         one,savsim,takeoff 15;velocity 4 0 0 5;hold 2,80,,,\n\
         two,savsim,takeoff 15;hold 10,80,arducopter,takeoff 15;velocity 0 5 0 10,300 -30\n",
    )
    .unwrap();
    let mut flown = Vec::new();
    for k in 0..2 {
        let out = dir.path().join(format!("out{k}"));
        let run = savsim()
            .args(["study", "--jobs", "2", "--out"])
            .arg(&out)
            .arg(&manifest)
            .output()
            .unwrap();
        assert_ran(&run);
        flown.push(results(&out));
    }
    let value = |name: &str, row: usize| cell(&flown[0], name, row);
    for row in 0..2 {
        assert!(
            value("outcome", row).contains("\"pass\""),
            "{}",
            value("error", row)
        );
        assert!(value("plan_completed", row).contains("true"), "{row}");
    }
    assert!(
        value("clock_skew_s", 1).contains(" 0.0"),
        "{}",
        value("clock_skew_s", 1)
    );
    let differ: Vec<_> = flown[0]
        .iter()
        .zip(&flown[1])
        .filter(|(a, b)| a != b)
        .collect();
    assert!(differ.is_empty(), "{differ:#?}");
}

/// PX4 in lockstep (simulator_mavlink, savsim's Iris): it boots on savsim's sensors, arms,
/// takes off to 10 m and holds, its estimate within a metre of the truth. Held 20 of 20 here
/// in the release build, 20 of 20 in the debug build CI runs, and 10 of 10 beside two CPU
/// hogs (docs/lockstep.md); before the compass and barometer had noise, 3 boots of 16 never
/// armed.
#[test]
fn a_px4_in_lockstep_takes_off_and_holds() {
    let Some(_turn) = sitl_test(Autopilot::Px4, Netns::Study, &[]) else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let manifest = dir.path().join("m.csv");
    std::fs::write(
        &manifest,
        "id,autopilot,physics,plan,duration_s,params\n\
         hover,px4,savsim,takeoff 10;hold 5,90,MPC_POS_MODE=3\n",
    )
    .unwrap();
    let out = dir.path().join("out");
    let run = savsim()
        .args(["study", "--out"])
        .arg(&out)
        .arg(&manifest)
        .output()
        .unwrap();
    assert_ran(&run);
    let flown = results(&out);
    let value = |name: &str| cell(&flown, name, 0);
    assert!(value("outcome").contains("\"pass\""), "{}", value("error"));
    assert!(value("plan_completed").contains("true"), "{flown:#?}");
    assert!(value("frame").contains("\"iris\""), "{}", value("frame"));
    // The last point of its track, `t e n u`: at about 10 m.
    let track = value("vehicle_track");
    let last = track.rsplit(';').next().unwrap_or_default();
    let up_m: f64 = last
        .split_whitespace()
        .nth(3)
        .and_then(|u| {
            u.trim_matches(|c: char| !c.is_ascii_digit() && c != '.')
                .parse()
                .ok()
        })
        .unwrap_or(0.0);
    assert!((8.5..=11.5).contains(&up_m), "{track}");
    let error = value("estimate_error_h_max_m");
    let metres: f64 = error
        .split(|c: char| !(c.is_ascii_digit() || c == '.'))
        .filter_map(|p| p.parse().ok())
        .next_back()
        .unwrap_or(f64::INFINITY);
    assert!(metres < 1.0, "{error}");
}
