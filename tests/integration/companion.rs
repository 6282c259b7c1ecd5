//! The companion link against a planner in Python using the package's client (loaded from
//! python/savsim/companion.py): a 160 x 120 image and its segmentation arrive whole as numpy
//! views and the commands come back as MAVLink; a planner that crashes, hangs, answers
//! garbage, floods or sends NaN is an error naming it, within its deadline, and its process
//! is gone afterwards.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use glam::{DQuat, DVec3};
use mavlink::dialects::ardupilotmega::MavMessage;
use savsim::companion::link::{CompanionError, Link};
use savsim::companion::outgoing;
use savsim::companion::protocol::{self, Command, FrameOut, State};
use savsim::companion::slot::{CompanionConfig, Slot};
use savsim::feed::capture::{Capture, CaptureData};
use savsim::world::SenderId;
use savsim_core::sensors::image::DepthImage;

use crate::common::root;

fn planner(behaviour: &str) -> String {
    format!(
        "python3 {} {behaviour}",
        root().join("tests/python/companion_planner.py").display()
    )
}

/// A 160 x 120 image whose depth at (row r, column c) is `r + c / 1000` m and whose class is
/// `(r + c) % 6`.
fn image() -> Arc<Capture> {
    let (w, h) = (160u32, 120u32);
    let mut img = DepthImage {
        width_px: w,
        height_px: h,
        ..DepthImage::default()
    };
    for r in 0..h {
        for c in 0..w {
            img.depth_m.push(r as f32 + c as f32 / 1000.0);
            img.segment_id.push(r * w + c);
            img.class.push(((r + c) % 6) as u8);
        }
    }
    Arc::new(Capture {
        device: "cam".into(),
        system_id: 1,
        instant_s: 0.5,
        origin_enu_m: DVec3::new(1.0, 2.0, 3.0),
        enu_from_device: DQuat::IDENTITY,
        data: CaptureData::Depth {
            image: img,
            fov_deg: [87.0, 58.0],
        },
    })
}

fn truth() -> State {
    State {
        position_enu_m: DVec3::new(1.0, 2.0, 3.0),
        velocity_enu_mps: DVec3::ZERO,
        attitude_deg: [0.0; 3],
    }
}

fn frame_bytes(seq: u64, captures: &[Arc<Capture>]) -> Vec<u8> {
    let (mut payload, mut out) = (Vec::new(), Vec::new());
    protocol::frame(
        &FrameOut {
            seq,
            t_s: seq as f64 / 10.0,
            truth: truth(),
            estimate: None,
            intent_enu_mps: Some(DVec3::X),
            captures,
            traffic: &[],
        },
        &mut payload,
        &mut out,
    );
    out
}

fn started(behaviour: &str, timeout: Duration) -> (Link, tempfile::TempDir) {
    let dir = tempfile::tempdir().unwrap();
    let mut link = Link::start(&planner(behaviour), dir.path(), timeout, &GO).unwrap();
    let mut hello = Vec::new();
    protocol::message(
        &protocol::hello(&protocol::Hello {
            system_id: 1,
            px4: false,
            devices: &["cam".into()],
            hz: 10.0,
            latency_s: 0.0,
            clock: protocol::Clock::Lockstep,
        }),
        &[],
        &mut hello,
    );
    link.tell(&hello).unwrap();
    (link, dir)
}

#[test]
fn an_image_arrives_whole_and_the_commands_come_back() {
    let (mut link, _dir) = started("echo", Duration::from_secs(20));
    let capture = image();
    for seq in 0..5 {
        let commands = link
            .ask(seq, &frame_bytes(seq, std::slice::from_ref(&capture)))
            .unwrap();
        // The mean of r + c/1000 over the image, the pixel at (7, 9), the class at (3, 4).
        let mean = 59.5 + 0.0795;
        match &commands[0] {
            Command::Velocity { enu_mps, yaw_deg } => {
                assert!((enu_mps.x - mean).abs() < 1e-3, "{enu_mps}");
                assert!((enu_mps.y - 7.009).abs() < 1e-5, "{enu_mps}");
                assert_eq!(enu_mps.z, 1.0);
                assert_eq!(*yaw_deg, Some(seq as f64));
            }
            other => panic!("{other:?}"),
        }
        assert_eq!(commands[1], Command::Mode("GUIDED".into()));
    }
}

#[test]
fn a_slot_sends_the_commands_as_the_companion_its_latency_later() {
    let dir = tempfile::tempdir().unwrap();
    let config = CompanionConfig {
        command: planner("echo"),
        hz: 10.0,
        latency_s: 0.25,
        timeout: Duration::from_secs(20),
    };
    let vehicle = SenderId {
        system_id: 1,
        component_id: 1,
    };
    let at = (dir.path(), &GO);
    let mut slot = Slot::start(&config, (vehicle, false), at, &["cam".into()]).unwrap();
    slot.collect(&[image()], &[]);
    let mut sent = Vec::new();
    // 1 s of a 2.5 ms clock: frames at 0, 100, ... 900 ms.
    for step in 0..400u64 {
        let t_us = step * 2500;
        slot.at(t_us, truth(), None).unwrap();
        for bytes in slot.due(t_us) {
            sent.push((t_us, bytes));
        }
    }
    assert_eq!(slot.counts.calls, 10);
    assert_eq!(slot.counts.commands, 20);
    // Each frame's two commands go 250 ms after it, from the companion's identity.
    let times: Vec<u64> = sent.iter().map(|(t, _)| *t).step_by(2).collect();
    assert_eq!(
        times,
        (0..8).map(|k| 250_000 + k * 100_000).collect::<Vec<_>>()
    );
    for (_, bytes) in &sent {
        let mut reader = mavlink::MavlinkReader::new(&bytes[..]);
        let (header, message) = reader
            .read_any_message::<MavMessage>()
            .expect("a MAVLink frame");
        assert_eq!(
            (header.system_id as u8, header.component_id),
            (1, outgoing::COMPANION_COMPONENT)
        );
        match message {
            MavMessage::SET_POSITION_TARGET_LOCAL_NED(m) => {
                assert_eq!((m.target_system, m.target_component), (1, 1));
                // East (the mean depth) goes to NED's y.
                assert!((m.vy - 59.5795).abs() < 1e-3);
            }
            MavMessage::COMMAND_LONG(m) => assert_eq!(m.param2, 4.0, "GUIDED is mode 4"),
            other => panic!("{other:?}"),
        }
    }
}

/// The error `behaviour` ends with, asked within `timeout`, and how long it took.
fn failure(behaviour: &str, timeout: Duration) -> (CompanionError, Duration) {
    let (mut link, _dir) = started(behaviour, timeout);
    let began = Instant::now();
    let mut seq = 0;
    loop {
        match link.ask(seq, &frame_bytes(seq, &[image()])) {
            Ok(_) => seq += 1,
            Err(e) => return (e, began.elapsed()),
        }
        assert!(seq < 3, "{behaviour}: no error");
    }
}

#[test]
fn a_planner_that_fails_is_an_error_naming_it_and_nothing_hangs() {
    let (e, _) = failure("crash", Duration::from_secs(20));
    let text = e.to_string();
    assert!(
        text.contains("companion_planner.py crash") && text.contains("giving up on frame 0"),
        "{text}"
    );
    let (e, took) = failure("hang", Duration::from_millis(1500));
    assert!(matches!(e, CompanionError::Timeout { seq: 0, .. }), "{e}");
    assert!(took < Duration::from_secs(5), "{took:?}");
    for (behaviour, says) in [
        ("garbage", "not the protocol's JSON"),
        ("flood", "a header of 100000000 bytes"),
        ("many", "1000 commands"),
        ("nan", "not the protocol's JSON"),
    ] {
        let (e, _) = failure(behaviour, Duration::from_secs(20));
        let text = e.to_string();
        assert!(
            text.contains(says) && text.contains(behaviour),
            "{behaviour}: {text}"
        );
    }
    // A planner that exits before it connects.
    let dir = tempfile::tempdir().unwrap();
    let e = Link::start(
        "echo leaving; exit 7",
        dir.path(),
        Duration::from_secs(1),
        &GO,
    )
    .unwrap_err();
    assert!(
        e.to_string().contains("exit status: 7") && e.to_string().contains("leaving"),
        "{e}"
    );
}

/// Never raised: the tests' runs are not stopped by a signal.
static GO: AtomicBool = AtomicBool::new(false);

/// A planner that never connects holds the run no longer than the signal that stops it (not
/// the 30 s it is given to connect), and it is ended with the wait.
#[test]
fn a_signal_ends_the_wait_for_a_planner_that_never_connects() {
    let dir = tempfile::tempdir().unwrap();
    let pid_file = dir.path().join("pid");
    let command = format!("echo $$ > {}; exec sleep 60", pid_file.display());
    let stop = Arc::new(AtomicBool::new(false));
    let raise = {
        let stop = stop.clone();
        std::thread::spawn(move || {
            std::thread::sleep(Duration::from_millis(300));
            stop.store(true, Ordering::Relaxed);
        })
    };
    let began = Instant::now();
    let e = Link::start(&command, dir.path(), Duration::from_secs(1), &stop).unwrap_err();
    raise.join().unwrap();
    assert!(matches!(e, CompanionError::Stopped { .. }), "{e}");
    assert!(
        began.elapsed() < Duration::from_secs(3),
        "{:?}",
        began.elapsed()
    );
    let pid = std::fs::read_to_string(&pid_file).unwrap();
    let alive = std::path::Path::new(&format!("/proc/{}", pid.trim())).exists();
    assert!(!alive, "the planner {} still runs", pid.trim());
}

#[test]
fn a_hanging_planner_is_ended_with_its_link() {
    let dir = tempfile::tempdir().unwrap();
    let pid_file = dir.path().join("pid");
    let command = format!("echo $$ > {}; exec {}", pid_file.display(), planner("hang"));
    let mut link = Link::start(&command, dir.path(), Duration::from_millis(300), &GO).unwrap();
    let mut hello = Vec::new();
    protocol::message(
        &protocol::hello(&protocol::Hello {
            system_id: 1,
            px4: false,
            devices: &[],
            hz: 10.0,
            latency_s: 0.0,
            clock: protocol::Clock::Lockstep,
        }),
        &[],
        &mut hello,
    );
    link.tell(&hello).unwrap();
    assert!(link.ask(0, &frame_bytes(0, &[])).is_err());
    let pid = std::fs::read_to_string(&pid_file)
        .unwrap()
        .trim()
        .to_string();
    drop(link);
    let alive = std::path::Path::new("/proc").join(&pid).exists()
        && !std::fs::read_to_string(format!("/proc/{pid}/stat"))
            .unwrap_or_default()
            .contains(") Z ");
    assert!(!alive, "the planner {pid} outlived its link");
}

/// A wall 41 m north of home, 16 m wide and 40 m high, at ArduPilot SITL's home.
const WALL: &str = "[origin]\nlat_deg = -35.363261\nlon_deg = 149.16523\nalt_m = 584\n\n\
    [[obstacle]]\nid = \"wall\"\nkind = \"building\"\n\
    shape = { box = [16.0, 2.0, 40.0] }\nposition_enu_m = [0.0, 41.0, 0.0]\n";

/// `manifest` (a study's CSV, its rows over `wall.toml`: [`WALL`]) flown by `savsim study
/// --jobs JOBS`: its results (`crate::lockstep::results`) and how long the study took.
fn fly_study(manifest: &str, jobs: &str) -> (Vec<String>, Duration) {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("wall.toml"), WALL).unwrap();
    let path = dir.path().join("m.csv");
    std::fs::write(&path, manifest).unwrap();
    let out = dir.path().join("out");
    let began = Instant::now();
    let run = crate::cli::savsim()
        .args(["study", "--jobs", jobs, "--out"])
        .arg(&out)
        .arg(&path)
        .output()
        .unwrap();
    let took = began.elapsed();
    crate::common::assert_ran(&run);
    (crate::lockstep::results(&out), took)
}

/// The VFH example's command line.
fn vfh() -> String {
    format!(
        "python3 {}",
        root().join("examples/companion_vfh.py").display()
    )
}

/// ArduCopter in lockstep flies north at 4 m/s towards a wall 40 m ahead: without avoidance
/// it hits it; flown by examples/companion_vfh.py from the `depth-160x120` camera, with its
/// own avoidance off, it does not, and a planner that spends 60 ms of wall time on each frame
/// (more than its modelled 50 ms) gives the same row to the last bit (every result column but
/// the wall times, the round trips, the row's id and the command line; both rows draw their
/// camera's errors with one `sensor_seed`). Held 20 of 20 here (its manifest flown by the
/// release build beside a cold CI build: every run the same outcomes, fast and slow equal,
/// every run equal to the first).
#[test]
fn arducopter_flown_by_a_companion_misses_the_wall_whatever_the_planners_speed() {
    use crate::sitl::{sitl_test, Autopilot, Netns};
    let Some(_turn) = sitl_test(Autopilot::ArduCopter, Netns::Study, &[]) else {
        return;
    };
    let planner = |sleep: &str| format!("VFH_SLEEP_S={sleep} {}", vfh());
    let (rows, _) = fly_study(
        &format!(
            "id,scene,physics,plan,duration_s,params,feed,sensors,sensor_seed,companion,companion_hz,companion_latency_s\n\
             nominal,wall.toml,savsim,takeoff 15;velocity 0 4 0 20,80,AVOID_ENABLE=0,,,,,,\n\
             fast,wall.toml,savsim,takeoff 15;velocity 0 4 0 20,80,AVOID_ENABLE=0,proximity,depth-160x120,5,{},10,0.05\n\
             slow,wall.toml,savsim,takeoff 15;velocity 0 4 0 20,80,AVOID_ENABLE=0,proximity,depth-160x120,5,{},10,0.05\n",
            planner("0"),
            planner("0.06"),
        ),
        "2",
    );
    let value = |name: &str, row: usize| crate::lockstep::cell(&rows, name, row);
    assert!(
        value("outcome", 0).contains("\"collision\""),
        "{}",
        value("error", 0)
    );
    for row in [1, 2] {
        assert!(
            value("outcome", row).contains("\"pass\""),
            "{}",
            value("error", row)
        );
        // A frame every 100 ms of the row's 72 s.
        let calls = value("companion_calls", row);
        assert!(calls.contains("[   723, ]"), "{calls}");
    }
    let skip = ["index", "row_id", "companion", "companion_p99_ms"];
    let column = |l: &str| l.split(' ').nth(1).unwrap_or_default().to_string();
    let of = |row: usize| -> Vec<String> {
        rows.iter()
            .filter(|l| l.starts_with(&format!("{row} ")))
            .filter(|l| !skip.contains(&column(l).as_str()))
            .map(|l| l.split_once(' ').unwrap().1.to_string())
            .collect()
    };
    let (fast, slow) = (of(1), of(2));
    let differ: Vec<_> = fast.iter().zip(&slow).filter(|(a, b)| a != b).collect();
    assert!(differ.is_empty(), "{differ:#?}");
}

/// ArduCopter on its own physics, in wall time at 3x, flown by the VFH planner beside it (the
/// camera at 80 x 60 and 10 Hz, so that the debug build keeps up on a loaded machine: at
/// 160 x 120 the feed fell 0.3 s behind beside two busy processes, and the planner stopped
/// 0.35 m from the wall), misses the wall the nominal row hits: the planner asked at about
/// every instant of its rate, its setpoints flying the vehicle. Held 20 of 20 here (see
/// docs/companion.md).
#[test]
fn arducopter_on_its_own_physics_flown_by_a_companion_misses_the_wall() {
    use crate::sitl::{sitl_test, Autopilot, Netns};
    let Some(_turn) = sitl_test(Autopilot::ArduCopter, Netns::Study, &[]) else {
        return;
    };
    let (rows, _) = fly_study(
        &format!(
            "id,scene,speedup,plan,duration_s,params,feed,sensors,sensor_seed,companion,companion_hz\n\
             nominal,wall.toml,3,takeoff 15;velocity 0 4 0 20,80,AVOID_ENABLE=0,,,,,\n\
             vfh,wall.toml,3,takeoff 15;velocity 0 4 0 20,80,AVOID_ENABLE=0,proximity,\"depth-160x120:rate_hz=10:image_px=[80,60]\",5,{},10\n",
            vfh()
        ),
        "2",
    );
    let value = |name: &str, row: usize| crate::lockstep::cell(&rows, name, row);
    let number = |name: &str| -> u64 {
        let cell = value(name, 1);
        let digits: String = cell.chars().filter(char::is_ascii_digit).collect();
        digits.parse().unwrap_or_else(|_| panic!("{name}: {cell}"))
    };
    assert!(
        value("outcome", 0).contains("\"collision\""),
        "{}",
        value("error", 0)
    );
    let seen = [
        "outcome",
        "closest_obstacle_m",
        "feed_latency_p99_us",
        "error",
    ]
    .map(|c| value(c, 1));
    assert!(value("outcome", 1).contains("\"pass\""), "{seen:#?}");
    // About 630 instants from its first position to the row's end (72 s of its clock).
    let (calls, skipped) = (number("companion_calls"), number("companion_skipped"));
    assert!(
        calls + skipped >= 550 && skipped * 10 <= calls,
        "{calls} {skipped}"
    );
    assert!(number("companion_commands") >= 100);
}

/// A planner that crashes beside ArduCopter on its own physics makes the row an error row
/// naming it and what it said, and ends the row then, not at its 120 s of clock (40 s of wall
/// time at 3x). Held 20 of 20 here (10 runs beside two busy processes, 10 quiet).
#[test]
fn a_planner_that_crashes_beside_sitl_ends_its_row_as_an_error_naming_it() {
    use crate::sitl::{sitl_test, Autopilot, Netns};
    let Some(_turn) = sitl_test(Autopilot::ArduCopter, Netns::Study, &[]) else {
        return;
    };
    let (rows, took) = fly_study(
        &format!(
            "id,scene,speedup,plan,duration_s,companion\n\
             crash,wall.toml,3,takeoff 15;velocity 0 4 0 20,120,{}\n",
            planner("crash")
        ),
        "1",
    );
    let value = |name: &str| crate::lockstep::cell(&rows, name, 0);
    assert!(
        value("outcome").contains("\"error\""),
        "{}",
        value("outcome")
    );
    let error = value("error");
    assert!(error.contains("companion_planner.py crash"), "{error}");
    assert!(error.contains("giving up on frame 0"), "{error}");
    // 3.3 s here, SITL's boot included.
    assert!(took < Duration::from_secs(30), "the study took {took:?}");
}

/// PX4 in lockstep flown by the VFH planner, which asks for OFFBOARD (its `hello` names the
/// autopilot) while the pilot keeps the sticks centred: it misses the wall the nominal row
/// hits, and PX4 flew in OFFBOARD. Held 20 of 20 here (see docs/companion.md).
#[test]
fn px4_flown_by_a_companion_in_offboard_misses_the_wall() {
    use crate::sitl::{sitl_test, Autopilot, Netns};
    let Some(_turn) = sitl_test(Autopilot::Px4, Netns::Study, &[]) else {
        return;
    };
    let (rows, _) = fly_study(
        &format!(
            "id,autopilot,physics,scene,plan,duration_s,feed,sensors,sensor_seed,companion\n\
             nominal,px4,savsim,wall.toml,takeoff 15;velocity 0 4 0 20,80,,,,\n\
             vfh,px4,savsim,wall.toml,takeoff 15;velocity 0 4 0 20,80,proximity,depth-160x120,5,{}\n",
            vfh()
        ),
        "1",
    );
    let value = |name: &str, row: usize| crate::lockstep::cell(&rows, name, row);
    assert!(
        value("outcome", 0).contains("\"collision\""),
        "{}",
        value("error", 0)
    );
    let seen = ["outcome", "closest_obstacle_m", "modes", "error"].map(|c| value(c, 1));
    assert!(!value("outcome", 1).contains("collision"), "{seen:#?}");
    assert!(!value("outcome", 1).contains("error"), "{seen:#?}");
    let closest_m: f64 = value("closest_obstacle_m", 1)
        .split(['[', ','])
        .nth(1)
        .and_then(|v| v.trim().parse().ok())
        .unwrap_or_else(|| panic!("{seen:#?}"));
    // 1.3 m here; the wall-time row without lockstep came to 0.37 m.
    assert!(closest_m > 0.5, "{seen:#?}");
    assert!(value("modes", 1).contains("OFFBOARD"), "{seen:#?}");
}

/// Rows whose companion cannot fly are error rows naming the column, and the study goes on
/// (no autopilot is needed to find out).
#[test]
fn rows_with_a_companion_they_cannot_fly_are_error_rows_naming_it() {
    let dir = tempfile::tempdir().unwrap();
    let manifest = dir.path().join("m.csv");
    std::fs::write(
        &manifest,
        "id,autopilot,physics,plan,duration_s,companion,companion_hz,companion_latency_s\n\
         inf-hz,arducopter,,takeoff 10,30,python3 planner.py,inf,\n\
         early,px4,savsim,takeoff 10,30,python3 planner.py,,-0.1\n\
         zero-hz,arducopter,savsim,takeoff 10,30,python3 planner.py,0,\n\
         late,arducopter,savsim,takeoff 10,30,python3 planner.py,,11\n\
         nan,arducopter,savsim,takeoff 10,30,python3 planner.py,,nan\n\
         alone,arducopter,savsim,takeoff 10,30,,5,\n",
    )
    .unwrap();
    let out = dir.path().join("out");
    let run = crate::cli::savsim()
        .env_remove("SAVSIM_ARDUCOPTER")
        .env_remove("SAVSIM_PX4")
        .args(["study", "--out"])
        .arg(&out)
        .arg(&manifest)
        .output()
        .unwrap();
    crate::common::assert_ran(&run);
    let rows = crate::lockstep::results(&out);
    let error = |row: usize| crate::lockstep::cell(&rows, "error", row);
    for (row, says) in [
        (0, "companion_hz: inf"),
        (1, "companion_latency_s: -0.1"),
        (2, "companion_hz: 0"),
        (3, "companion_latency_s: 11"),
        (4, "companion_latency_s: NaN"),
        (5, "companion_hz: give a companion"),
    ] {
        assert!(error(row).contains(says), "row {row}: {}", error(row));
    }
}

/// A vehicle played on 127.0.0.1 for `play`: a heartbeat a second and its pose at 50 Hz at
/// `at` (scene ENU), its clock the wall's; what reached it from the companion (component 191):
/// its velocity setpoints (NED m/s) and its mode changes (custom modes).
fn played_vehicle(
    savsim: std::net::SocketAddr,
    origin: savsim::geo::Geodetic,
    at: DVec3,
    (play, reboot_at): (Duration, Option<Duration>),
) -> (Vec<[f32; 3]>, Vec<f32>, usize) {
    use crate::common::{frame_v2, heartbeat, pose_messages};
    use mavlink::dialects::ardupilotmega::{MavAutopilot, MavType};
    let socket = std::net::UdpSocket::bind("127.0.0.1:0").unwrap();
    socket
        .set_read_timeout(Some(Duration::from_millis(2)))
        .unwrap();
    let plane = savsim::geo::LocalTangentPlane::new(origin);
    let began = Instant::now();
    let (mut seq, mut sent, mut next_heartbeat) = (0u8, 0usize, Duration::ZERO);
    let (mut velocities, mut modes) = (Vec::new(), Vec::new());
    let mut buffer = [0u8; 2048];
    while began.elapsed() < play {
        let mut out = Vec::new();
        if began.elapsed() >= next_heartbeat {
            next_heartbeat += Duration::from_secs(1);
            let hb = heartbeat(
                MavType::MAV_TYPE_QUADROTOR,
                MavAutopilot::MAV_AUTOPILOT_ARDUPILOTMEGA,
            );
            out.extend(frame_v2(1, 1, seq, &hb));
            seq = seq.wrapping_add(1);
        }
        // After a reboot its clock starts again from 0.
        let since = reboot_at
            .filter(|r| began.elapsed() >= *r)
            .unwrap_or_default();
        let ms = (began.elapsed() - since).as_millis() as u32;
        for m in pose_messages(&plane, ms, at, DVec3::ZERO, [0.0; 3]) {
            out.extend(frame_v2(1, 1, seq, &m));
            seq = seq.wrapping_add(1);
        }
        sent += 1;
        socket.send_to(&out, savsim).unwrap();
        let until = Instant::now() + Duration::from_millis(20);
        while Instant::now() < until {
            let Ok(n) = socket.recv(&mut buffer) else {
                continue;
            };
            let mut reader = mavlink::MavlinkReader::new(&buffer[..n]);
            while let Ok((header, message)) = reader.read_any_message::<MavMessage>() {
                if header.component_id != outgoing::COMPANION_COMPONENT {
                    continue;
                }
                match message {
                    MavMessage::SET_POSITION_TARGET_LOCAL_NED(m) => {
                        velocities.push([m.vx, m.vy, m.vz]);
                    }
                    MavMessage::COMMAND_LONG(m) => modes.push(m.param2),
                    _ => {}
                }
            }
        }
    }
    (velocities, modes, sent)
}

/// `planner` beside a vehicle played in wall time (`savsim live --companion`): what the
/// vehicle heard from it, what savsim counted, and the positions it sent and savsim took.
type Beside = (
    Vec<[f32; 3]>,
    Vec<f32>,
    savsim::companion::slot::CompanionCounts,
    (usize, u64),
);

/// [`beside_a_played_vehicle`], or how the run ended when it failed.
fn beside_a_played_vehicle(behaviour: &str, reboot_at: Option<Duration>) -> Result<Beside, String> {
    use savsim::live::{CompanionOptions, LiveOptions};
    let origin = savsim::geo::Geodetic::new(-35.363261, 149.16523, 584.0);
    let scene = crate::common::scene_at(origin, "");
    let session = savsim::session::Session::new(
        Some(Arc::new(scene)),
        savsim::pipeline::CollisionConfig::default(),
        None,
    )
    .unwrap();
    let dir = tempfile::tempdir().unwrap();
    let runtime = crate::common::runtime();
    let (link, address) = crate::common::udp_link(&runtime);
    let options = LiveOptions {
        duration: Some(Duration::from_millis(3500)),
        companion: Some(CompanionOptions {
            config: CompanionConfig::checked(&planner(behaviour), 10.0, 0.0).unwrap(),
            target_system_id: 1,
            px4: false,
            dir: dir.path().to_path_buf(),
            intent: Default::default(),
        }),
        ..LiveOptions::default()
    };
    let at = DVec3::new(3.0, 4.0, 10.0);
    let play = (Duration::from_millis(2500), reboot_at);
    let vehicle = std::thread::spawn(move || played_vehicle(address, origin, at, play));
    let stop = Arc::new(std::sync::atomic::AtomicBool::new(false));
    let run = savsim::live::run_links(runtime.handle(), vec![link], &options, session, None, stop)
        .unwrap();
    let (velocities, modes, sent) = vehicle.join().unwrap();
    run.ended.map_err(|e| e.to_string())?;
    let taken = run
        .session
        .world()
        .vehicle_of_system(1)
        .map_or(0, |v| v.positions);
    Ok((velocities, modes, run.companion.unwrap(), (sent, taken)))
}

/// Beside a vehicle flying in wall time, the planner is asked at its instants on the vehicle's
/// clock, told the state savsim mirrors and that the clock is the wall's; its commands reach
/// the vehicle as the companion's.
#[test]
fn beside_a_vehicle_in_wall_time_the_planner_is_asked_and_its_commands_reach_it() {
    let (velocities, modes, counts, (sent, taken)) =
        beside_a_played_vehicle("where", None).unwrap();
    // About 25 instants in the vehicle's 2.5 s; a fast planner misses only those that came in
    // the backlog of positions queued while it started (taken in a burst, its answer to the
    // first not back yet).
    let instants = counts.calls + counts.skipped;
    assert!((22..=26).contains(&instants), "{counts:?}");
    assert!(counts.skipped <= 4, "{counts:?}");
    assert_eq!(velocities.len() as u64, counts.calls, "{counts:?}");
    // ENU (3, 4, 10) as NED: north 4, east 3, down -10.
    for v in &velocities {
        assert!(
            (v[0] - 4.0).abs() < 0.05 && (v[1] - 3.0).abs() < 0.05,
            "{v:?}"
        );
        assert!((v[2] + 10.0).abs() < 0.05, "{v:?}");
    }
    assert_eq!(
        modes,
        [4.0],
        "GUIDED once, the hello having said the clock is the wall's"
    );
    assert_eq!(taken as usize, sent);
}

/// A planner slower than the vehicle's instants never holds the vehicle up: the instants
/// that find it busy are skipped and counted, and every position is taken.
#[test]
fn beside_a_vehicle_in_wall_time_a_slow_planner_skips_instants_and_holds_nothing_up() {
    let (velocities, _, counts, (sent, taken)) =
        beside_a_played_vehicle("slow-where", None).unwrap();
    // 300 ms a frame: at most one instant in three is asked.
    assert!((4..=10).contains(&counts.calls), "{counts:?}");
    assert!(counts.skipped >= 2 * counts.calls - 2, "{counts:?}");
    assert!(velocities.len() as u64 >= counts.calls - 1, "{counts:?}");
    assert_eq!(taken as usize, sent);
}

/// A planner that fails beside a vehicle in wall time ends the run with an error naming it
/// and what it said; nothing hangs.
#[test]
fn beside_a_vehicle_in_wall_time_a_failing_planner_ends_the_run_naming_it() {
    let began = Instant::now();
    let error = beside_a_played_vehicle("crash", None)
        .err()
        .unwrap_or_default();
    assert!(error.contains("companion_planner.py crash"), "{error}");
    assert!(error.contains("giving up on frame 0"), "{error}");
    assert!(began.elapsed() < Duration::from_secs(10));
}

/// A vehicle that reboots (its clock starts again from 0) is asked again on its new clock:
/// about as many instants in all as without the reboot, and its commands keep coming.
#[test]
fn beside_a_vehicle_that_reboots_the_planner_is_asked_on_its_new_clock() {
    let (velocities, _, counts, (sent, taken)) =
        beside_a_played_vehicle("where", Some(Duration::from_millis(1500))).unwrap();
    // 1.5 s and then 1 s of its clocks: about 25 instants, as many as without the reboot.
    let instants = counts.calls + counts.skipped;
    assert!((21..=27).contains(&instants), "{counts:?}");
    assert!(velocities.len() >= 18, "{} of {counts:?}", velocities.len());
    assert_eq!(taken as usize, sent);
}

/// `savsim live`'s companion settings out of range are usage errors naming the flag, before
/// any planner starts or link opens.
#[test]
fn live_companion_settings_out_of_range_are_usage_errors_naming_them() {
    for (flag, value) in [
        ("--companion-hz", "-1"),
        ("--companion-hz", "nan"),
        ("--companion-hz", "1e9"),
        ("--companion-latency-s", "-0.5"),
        ("--companion-latency-s", "inf"),
    ] {
        let out = crate::cli::savsim()
            .args([
                "live",
                "--connect",
                "udpin:127.0.0.1:0",
                "--duration-s",
                "1",
            ])
            .args(["--companion", "true", flag, value])
            .output()
            .unwrap();
        assert_eq!(out.status.code(), Some(2), "{flag} {value}");
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(
            stderr.contains(&format!("{flag}: ")),
            "{flag} {value}: {stderr}"
        );
    }
}
