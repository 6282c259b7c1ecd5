//! Helpers shared by the integration tests.

use std::path::{Path, PathBuf};
use std::process::Command;

use glam::{DQuat, DVec3};
use mavlink::dialects::ardupilotmega::{
    MavAutopilot, MavMessage, MavModeFlag, MavState, MavType, ATTITUDE_DATA,
    GLOBAL_POSITION_INT_DATA, HEARTBEAT_DATA,
};
use mavlink::{MavHeader, MavlinkVersion};
use savsim::codec::frame::{scan, Scan};
use savsim::geo::{Geodetic, LocalTangentPlane};
use savsim::scene::{parse, Scene};
use savsim::session::Session;
use savsim::world::{Attitude, TrackSample};

/// The crate's root.
pub fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// A command finished with success; its stderr is the failure message.
pub fn assert_ran(out: &std::process::Output) {
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
}

/// ../shared/fixtures, if present.
pub fn shared_fixtures() -> Option<PathBuf> {
    let p = root().join("../shared/fixtures");
    if p.is_dir() {
        Some(p)
    } else {
        eprintln!("SKIP: ../shared/fixtures is absent");
        None
    }
}

/// True when `python3 -c "import pymavlink"` works; says so when it does not.
pub fn have_pymavlink() -> bool {
    have_python_module(
        "pymavlink",
        "SAVSIM_REQUIRE_PYTHON",
        "pip install pymavlink; .ci/run does",
    )
}

/// True when `python3 -c "import {module}"` works; when it does not, says so, or fails if
/// `require_var` is set (CI sets it, so that a test cannot pass by skipping there).
pub fn have_python_module(module: &str, require_var: &str, how: &str) -> bool {
    let ok = Command::new("python3")
        .args(["-c", &format!("import {module}")])
        .output()
        .map(|o| o.status.success())
        .unwrap_or(false);
    if !ok {
        assert!(
            std::env::var_os(require_var).is_none(),
            "{module} is required here ({require_var} is set) but not importable"
        );
        eprintln!("SKIP: {module} is not installed ({how})");
    }
    ok
}

/// Run a Python script with arguments; return its stdout.
pub fn python(script: &Path, args: &[&str]) -> String {
    let out = Command::new("python3")
        .arg(script)
        .args(args)
        .output()
        .expect("python3 runs");
    assert!(
        out.status.success(),
        "{} failed: {}",
        script.display(),
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8(out.stdout).expect("utf-8")
}

/// `python3 -c code`'s standard output; its standard error is the failure message.
pub fn python_code(code: &str) -> String {
    let out = Command::new("python3")
        .args(["-c", code])
        .output()
        .expect("python3 runs");
    assert_ran(&out);
    String::from_utf8(out.stdout).expect("utf-8")
}

/// A sample at `t_s` at ENU position `p` (relative to `origin`), flying along `velocity`,
/// with the nose along the velocity (or east when still).
pub fn sample(origin: Geodetic, t_s: f64, p: DVec3, velocity: DVec3) -> TrackSample {
    let plane = LocalTangentPlane::new(origin);
    let heading = if velocity.truncate().length() > 0.0 {
        velocity.y.atan2(velocity.x)
    } else {
        0.0
    };
    TrackSample {
        t_s,
        time_boot_ms: (t_s * 1000.0) as u32,
        position: plane.geodetic_from_enu_m(p),
        position_enu_m: p,
        velocity_enu_mps: velocity,
        attitude: Attitude {
            time_boot_ms: 0,
            enu_from_frd: DQuat::from_rotation_z(heading)
                * DQuat::from_rotation_x(std::f64::consts::PI),
            body_rates_radps: DVec3::ZERO,
        },
    }
}

/// Samples of a straight flight from `a` to `b` at `speed_mps`, `rate_hz` samples a second.
pub fn straight(
    origin: Geodetic,
    a: DVec3,
    b: DVec3,
    speed_mps: f64,
    rate_hz: f64,
) -> Vec<TrackSample> {
    let length = (b - a).length();
    let duration = length / speed_mps;
    let n = (duration * rate_hz).ceil() as usize;
    let velocity = (b - a) / duration;
    (0..=n)
        .map(|i| {
            let t = (i as f64 / rate_hz).min(duration);
            sample(origin, 1000.0 + t, a + velocity * t, velocity)
        })
        .collect()
}

/// Replay a tlog as fast as possible into `session` and finish it.
pub fn replay_session(path: &Path, session: &mut savsim::session::Session) {
    let shutdown = std::sync::atomic::AtomicBool::new(false);
    savsim::replay::replay(
        path,
        savsim::replay::Speed::Max,
        false,
        None,
        session,
        &shutdown,
    )
    .unwrap();
    session.finish().unwrap();
}

/// Replay a tlog as fast as possible into a new session (over `scene`, if given) and finish it.
pub fn replay_into_session(
    path: &Path,
    scene: Option<savsim::scene::Scene>,
) -> savsim::session::Session {
    let mut session = savsim::session::Session::new(
        scene.map(std::sync::Arc::new),
        savsim::pipeline::CollisionConfig::default(),
        None,
    )
    .unwrap();
    replay_session(path, &mut session);
    session
}

/// A scene from the body of a scene file (obstacles, terrain, ...) at `origin`.
pub fn scene_at(origin: Geodetic, body: &str) -> Scene {
    let text = format!(
        "[origin]\nlat_deg = {}\nlon_deg = {}\nalt_m = {}\n{body}",
        origin.lat_deg, origin.lon_deg, origin.alt_m
    );
    parse(&text, Path::new("test.toml"), "test").unwrap()
}

/// A scene body of building boxes, each given by its (min, max) ENU corners (placed by its
/// base centre), named `b0`, `b1`, ...
pub fn boxes_scene(boxes: &[([f64; 3], [f64; 3])]) -> String {
    boxes
        .iter()
        .enumerate()
        .map(|(i, (lo, hi))| {
            let size = [hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]];
            let at = [(lo[0] + hi[0]) / 2.0, (lo[1] + hi[1]) / 2.0, lo[2]];
            format!(
                "[[obstacle]]\nid = \"b{i}\"\nkind = \"building\"\nshape = {{ box = {size:?} }}\nposition_enu_m = {at:?}\n"
            )
        })
        .collect()
}

/// ATTITUDE (roll, pitch, yaw: NED Euler, radians) and GLOBAL_POSITION_INT (heading from the
/// yaw) at ENU `p`, flying along ENU `v`, stamped `time_boot_ms`.
pub fn pose_messages(
    plane: &LocalTangentPlane,
    time_boot_ms: u32,
    p: DVec3,
    v: DVec3,
    [roll, pitch, yaw]: [f64; 3],
) -> [MavMessage; 2] {
    let g = plane.geodetic_from_enu_m(p);
    [
        MavMessage::ATTITUDE(ATTITUDE_DATA {
            time_boot_ms,
            roll: roll as f32,
            pitch: pitch as f32,
            yaw: yaw as f32,
            rollspeed: 0.0,
            pitchspeed: 0.0,
            yawspeed: 0.0,
        }),
        MavMessage::GLOBAL_POSITION_INT(GLOBAL_POSITION_INT_DATA {
            time_boot_ms,
            lat: (g.lat_deg * 1e7).round() as i32,
            lon: (g.lon_deg * 1e7).round() as i32,
            alt: (g.alt_m * 1e3).round() as i32,
            relative_alt: 0,
            vx: (v.y * 100.0).round() as i16,
            vy: (v.x * 100.0).round() as i16,
            vz: (-v.z * 100.0).round() as i16,
            hdg: (yaw.to_degrees().rem_euclid(360.0) * 100.0).round() as u16 % 36_000,
        }),
    ]
}

/// A MAVLink GLOBAL_POSITION_INT (+ ATTITUDE, nose east) frame pair for `sysid` at ENU `p`.
pub fn position_frames(
    plane: &LocalTangentPlane,
    sysid: u8,
    seq: &mut u8,
    time_boot_ms: u32,
    p: DVec3,
    v: DVec3,
) -> Vec<u8> {
    let mut bytes = Vec::new();
    let nose_east = [0.0, 0.0, std::f64::consts::FRAC_PI_2];
    for message in pose_messages(plane, time_boot_ms, p, v, nose_east) {
        bytes.extend(frame_v2(sysid, 1, *seq, &message));
        *seq = seq.wrapping_add(1);
    }
    bytes
}

/// One MAVLink 2 frame of `message` from `sysid`/`compid`, numbered `seq`.
pub fn frame_v2(sysid: u8, compid: u8, seq: u8, message: &MavMessage) -> Vec<u8> {
    let header = MavHeader {
        system_id: u32::from(sysid),
        component_id: compid,
        sequence: seq,
    };
    let mut bytes = Vec::new();
    mavlink::write_versioned_msg(&mut bytes, MavlinkVersion::V2, header, message).unwrap();
    bytes
}

/// An active HEARTBEAT of `mavtype` and `autopilot`.
pub fn heartbeat(mavtype: MavType, autopilot: MavAutopilot) -> MavMessage {
    MavMessage::HEARTBEAT(HEARTBEAT_DATA {
        custom_mode: 0,
        mavtype,
        autopilot,
        base_mode: MavModeFlag::empty(),
        system_status: MavState::MAV_STATE_ACTIVE,
        mavlink_version: 3,
    })
}

/// Send `signal` (`INT`, `TERM`) to `child` with kill(1) and wait for it to exit.
pub fn signal_and_wait(child: &mut std::process::Child, signal: &str) -> std::process::ExitStatus {
    let killed = Command::new("kill")
        .args([format!("-{signal}"), child.id().to_string()])
        .status()
        .unwrap();
    assert!(killed.success());
    child.wait().unwrap()
}

/// Feed every frame in `bytes` to `session` as received at `t_s`.
pub fn feed(session: &mut Session, t_s: f64, bytes: &[u8]) {
    let mut rest = bytes;
    while let Scan::Frame(frame) = scan(rest) {
        let used = frame.len;
        session.on_frame(t_s, &frame).unwrap();
        rest = &rest[used..];
    }
    assert!(
        rest.is_empty(),
        "savsim reads every frame the mavlink crate wrote"
    );
}

/// Run savsim's live path on links already open on `runtime` for `duration`, with no scene.
pub fn run_live(
    runtime: &tokio::runtime::Runtime,
    links: Vec<savsim::links::sockets::Link>,
    duration: std::time::Duration,
    session: Session,
    record: Option<&Path>,
) -> savsim::live::LiveRun {
    let shutdown = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
    run_live_until(runtime, links, duration, session, record, shutdown)
}

/// [`run_live`] until `shutdown` is raised, or `limit` passes.
pub fn run_live_until(
    runtime: &tokio::runtime::Runtime,
    links: Vec<savsim::links::sockets::Link>,
    limit: std::time::Duration,
    session: Session,
    record: Option<&Path>,
    shutdown: std::sync::Arc<std::sync::atomic::AtomicBool>,
) -> savsim::live::LiveRun {
    let options = savsim::live::LiveOptions {
        duration: Some(limit),
        ..Default::default()
    };
    let run = savsim::live::run_links(runtime.handle(), links, &options, session, record, shutdown)
        .unwrap();
    if let Err(e) = &run.ended {
        panic!("the live run ended with {e}");
    }
    run
}

/// A tokio runtime with two workers for a test's peers and savsim's links.
pub fn runtime() -> tokio::runtime::Runtime {
    tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
        .unwrap()
}

/// A UDP link bound to 127.0.0.1:0 on `runtime`, with its address.
pub fn udp_link(
    runtime: &tokio::runtime::Runtime,
) -> (savsim::links::sockets::Link, std::net::SocketAddr) {
    let address = savsim::links::address::ConnectAddress::UdpIn(
        "127.0.0.1:0"
            .parse::<std::net::SocketAddr>()
            .unwrap()
            .into(),
    );
    let link = runtime
        .block_on(savsim::links::sockets::Link::open(&address))
        .unwrap();
    let local = link.local_addr().unwrap();
    (link, local)
}

/// The collisions of vehicle `vehicle` among `events`: (obstacle, time of impact).
pub fn collisions_on(
    events: &[savsim::collision::events::Event],
    vehicle: u16,
) -> Vec<(String, f64)> {
    events
        .iter()
        .filter(|e| e.vehicle == vehicle)
        .filter_map(|e| match &e.kind {
            savsim::collision::events::EventKind::Collision {
                obstacle,
                time_of_impact,
                ..
            } => Some((obstacle.clone(), *time_of_impact)),
            _ => None,
        })
        .collect()
}

/// The down reading of a feed frame, metres (`None`: max + 1, nothing within range).
pub fn rangefinder_m(messages: &[MavMessage]) -> Option<f64> {
    messages.iter().find_map(|m| match m {
        MavMessage::DISTANCE_SENSOR(d) if d.orientation as u8 == 25 => {
            (d.current_distance <= d.max_distance).then(|| f64::from(d.current_distance) / 100.0)
        }
        _ => None,
    })
}

/// Wait until `condition` holds, checking every 20 ms, or until `deadline` passes: whether it
/// held. A test waits on what it needs, never for a guessed time.
pub fn wait_until(deadline: std::time::Instant, mut condition: impl FnMut() -> bool) -> bool {
    loop {
        if condition() {
            return true;
        }
        if std::time::Instant::now() >= deadline {
            return false;
        }
        std::thread::sleep(std::time::Duration::from_millis(20));
    }
}

/// The identity of [`until_processed`]'s marker: a companion computer (MAV_COMP_ID_ONBOARD...
/// 191) of system 250, never an autopilot, so savsim never asks it for streams.
pub const MARKER: savsim::world::SenderId = savsim::world::SenderId {
    system_id: 250,
    component_id: 191,
};

/// Wait until savsim's live run listening on UDP `savsim` has taken everything sent to it
/// before this call: a heartbeat of [`MARKER`] from a socket of its own, resent every 200 ms,
/// until savsim's ground-station heartbeat comes back to that socket. savsim sends to an
/// address only once its session thread has taken a frame from it, and the datagrams sent to
/// one socket are taken in the order they arrived. Whether it happened by `deadline`.
pub fn until_processed(savsim: std::net::SocketAddr, deadline: std::time::Instant) -> bool {
    let socket = std::net::UdpSocket::bind("127.0.0.1:0").unwrap();
    socket
        .set_read_timeout(Some(std::time::Duration::from_millis(200)))
        .unwrap();
    let marker = heartbeat(
        MavType::MAV_TYPE_ONBOARD_CONTROLLER,
        MavAutopilot::MAV_AUTOPILOT_INVALID,
    );
    let mut buffer = [0u8; 2048];
    let mut seq = 0u8;
    while std::time::Instant::now() < deadline {
        let frame = frame_v2(MARKER.system_id, MARKER.component_id, seq, &marker);
        seq = seq.wrapping_add(1);
        let _ = socket.send_to(&frame, savsim);
        let Ok(n) = socket.recv(&mut buffer) else {
            continue;
        };
        let mut reader = mavlink::MavlinkReader::new(&buffer[..n]);
        while let Ok((_, message)) = reader.read_any_message::<MavMessage>() {
            if matches!(message, MavMessage::HEARTBEAT(h) if h.mavtype == MavType::MAV_TYPE_GCS) {
                return true;
            }
        }
    }
    false
}

/// The Kolmogorov-Smirnov statistic of `samples` against `cdf`, and its p-value
/// (Kolmogorov's asymptotic series).
pub fn ks(mut samples: Vec<f64>, cdf: impl Fn(f64) -> f64) -> (f64, f64) {
    samples.sort_by(f64::total_cmp);
    let n = samples.len() as f64;
    let d = samples
        .iter()
        .enumerate()
        .map(|(i, &x)| {
            let f = cdf(x);
            (f - i as f64 / n).max((i + 1) as f64 / n - f)
        })
        .fold(0.0, f64::max);
    let lambda = (n.sqrt() + 0.12 + 0.11 / n.sqrt()) * d;
    let p: f64 = (1..=100)
        .map(|j| {
            let j = j as f64;
            2.0 * (-1f64).powf(j - 1.0) * (-2.0 * j * j * lambda * lambda).exp()
        })
        .sum();
    (d, p.clamp(0.0, 1.0))
}
