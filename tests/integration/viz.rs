//! The rerun logger: a recording that rerun-sdk's own `rerun rrd verify` accepts and that holds
//! the documented entity paths; a run logged into rerun's in-memory sink.

use std::path::Path;
use std::process::Command;

use savsim::pipeline::CollisionConfig;
use savsim::session::Session;

use crate::common::{root, signal_and_wait, wait_until};

/// Paths every replay over the bundled city must log (docs/rerun.md).
const PATHS: [&str; 21] = [
    "world/obstacles/building",
    "world/vehicles/1/body",
    "world/vehicles/1/body/model",
    "world/vehicles/1/body/axes",
    "world/vehicles/1/chase",
    "world/vehicles/1/track/0",
    "world/vehicles/1/track/19",
    "world/vehicles/1/rays",
    "world/vehicles/1/rays/hits",
    "world/vehicles/1/node",
    "world/vehicles/1/node/neighbours",
    "world/vehicles/1/colliders/boxes",
    "world/vehicles/1/colliders/seen",
    "world/vehicles/1/colliders/meshes/b2150",
    "world/traffic/crossing-airliner",
    "world/traffic/crossing-airliner/box",
    "world/events/collisions",
    "world/events/collision_normals",
    "world/events/near_misses",
    "metrics/cost_us/1",
    "messages/1",
];

/// rerun-sdk's own verifier accepts the recording.
pub(crate) fn assert_rrd_verifies(rrd: &Path) {
    let verify = Command::new("rerun")
        .args(["rrd", "verify"])
        .arg(rrd)
        .output()
        .unwrap();
    assert!(
        verify.status.success(),
        "rerun rrd verify: {}{}",
        String::from_utf8_lossy(&verify.stdout),
        String::from_utf8_lossy(&verify.stderr)
    );
}

pub(crate) fn have_rerun_cli() -> bool {
    let ok = Command::new("rerun")
        .arg("--version")
        .output()
        .is_ok_and(|o| o.status.success());
    if !ok {
        assert!(
            std::env::var_os("SAVSIM_REQUIRE_PYTHON").is_none(),
            "the rerun CLI (pip install rerun-sdk==0.36.3) is required here but missing"
        );
        eprintln!(
            "SKIP: the rerun CLI is not installed (pip install rerun-sdk==0.36.3; .ci/run does)"
        );
    }
    ok
}

#[test]
fn a_replay_saves_a_recording_rerun_verifies() {
    if !have_rerun_cli() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let rrd = dir.path().join("demo.rrd");
    let summary = dir.path().join("s.json");
    let out = Command::new(env!("CARGO_BIN_EXE_savsim"))
        .current_dir(root())
        .args(["demo", "--rerun"])
        .arg(format!("save={}", rrd.display()))
        .arg("--summary-json")
        .arg(&summary)
        .output()
        .unwrap();
    crate::common::assert_ran(&out);
    let s: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&summary).unwrap()).unwrap();
    // 2025 ticks, 41 notes (the tlog's 38 STATUSTEXTs and 3 mode changes, as pymavlink counts
    // them) and the closest approaches at the end.
    assert_eq!(s["rerun"]["sent"], 2025 + 41 + 1);
    assert_rrd_verifies(&rrd);
    let printed = Command::new("rerun")
        .args(["rrd", "print", "-vv"])
        .arg(&rrd)
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&printed.stdout);
    for path in PATHS {
        assert!(text.contains(path), "{path} is not in the recording");
    }
    for timeline in ["tick", "vehicle_time", "tlog_time"] {
        assert!(text.contains(timeline), "timeline {timeline}");
    }
}

/// A session over the bundled city logging into rerun's in-memory sink.
fn city_session_in_memory(
    options: savsim::viz::VizOptions,
) -> (Session, rerun::sink::MemorySinkStorage) {
    let scene = savsim::scene::load(&root().join("scenes/city.toml")).unwrap();
    session_in_memory(scene, options)
}

/// A session over `scene` logging into rerun's in-memory sink.
fn session_in_memory(
    scene: savsim::scene::Scene,
    options: savsim::viz::VizOptions,
) -> (Session, rerun::sink::MemorySinkStorage) {
    let mut session = Session::new(
        Some(std::sync::Arc::new(scene)),
        CollisionConfig::default(),
        None,
    )
    .unwrap();
    let (rec, storage) = rerun::RecordingStreamBuilder::new("savsim-test")
        .memory()
        .unwrap();
    let start = session.run_start().unwrap();
    let logger = savsim::viz::Logger::with_stream(rec, start, options).unwrap();
    session.observe(Box::new(logger));
    (session, storage)
}

#[test]
fn a_run_logs_into_the_memory_sink() {
    let (mut session, storage) = city_session_in_memory(savsim::viz::VizOptions::default());
    crate::common::replay_session(
        &root().join("scenes/flights/copter_square_10ms.tlog"),
        &mut session,
    );
    let messages = storage.take();
    assert!(messages.len() > 100, "{} messages", messages.len());
    let text = format!("{messages:?}");
    for path in PATHS {
        assert!(text.contains(path), "{path} is not in the memory sink");
    }
    // The whole octree is drawn only on request.
    assert!(!text.contains("world/octree"));
    // The layout: a chase view whose origin is the vehicle's chase frame and whose eye is set,
    // an overview, the time series, and the first collision selected on the time panel.
    for part in [
        "EyeControls3D",
        "space_origin",
        "time_selection",
        "TimeSeries",
        "overview",
        "vehicle 1 (chase)",
    ] {
        assert!(text.contains(part), "{part} is not in the layout");
    }
}

/// `--rerun-octree` draws every leaf.
#[test]
fn the_whole_octree_is_drawn_on_request() {
    let (mut session, storage) = city_session_in_memory(savsim::viz::VizOptions {
        whole_octree: true,
        ..Default::default()
    });
    session.finish().unwrap();
    let text = format!("{:?}", storage.take());
    assert!(text.contains("world/octree"));
}

/// `scene show`: nothing flies, so no time series is laid out, and the overview's eye is set
/// (framing the scene; `savsim::viz::blueprint::overview_eye`).
#[test]
fn a_scene_alone_is_framed_without_empty_plots() {
    let (mut session, storage) = city_session_in_memory(savsim::viz::VizOptions::default());
    session.finish().unwrap();
    let text = format!("{:?}", storage.take());
    assert!(!text.contains("TimeSeries"), "an empty plot is laid out");
    assert!(text.contains("overview") && text.contains("EyeControls3D"));
}

#[test]
fn a_far_scene_is_logged_near_zero() {
    let text = "[origin]\nlat_deg = 47.0\nlon_deg = 8.0\nalt_m = 400.0\n\
        [[obstacle]]\nid = \"far\"\nkind = \"building\"\nshape = { box = [10.0, 10.0, 10.0] }\n\
        position_enu_m = [1000400.0, -250300.0, 0.0]\n";
    let scene = savsim::scene::parse(text, Path::new("far.toml"), "far").unwrap();
    let offset = savsim::viz::viz_offset(&scene);
    assert_eq!(offset.to_array(), [1_000_000.0, -250_000.0, 0.0]);
    // What is logged is within a kilometre of zero, where f32 keeps better than 0.1 mm.
    let logged = scene.obstacles[0].aabb_enu_m.centre() - offset;
    assert!(logged.length() < 1000.0);
    let near = savsim::scene::parse(
        &text.replace("1000400.0, -250300.0", "400.0, -300.0"),
        Path::new("n.toml"),
        "n",
    )
    .unwrap();
    assert_eq!(savsim::viz::viz_offset(&near).length(), 0.0);
}

/// How far process `pid` has read the file at `path` (its offset over its length), from
/// Linux's /proc; None while it has no such file open.
fn read_fraction(pid: u32, path: &std::path::Path) -> Option<f64> {
    let length = std::fs::metadata(path).ok()?.len() as f64;
    let wanted = std::fs::canonicalize(path).ok()?;
    let fds = std::fs::read_dir(format!("/proc/{pid}/fd")).ok()?;
    fds.flatten().find_map(|fd| {
        if std::fs::read_link(fd.path()).ok()? != wanted {
            return None;
        }
        let info = std::fs::read_to_string(format!(
            "/proc/{pid}/fdinfo/{}",
            fd.file_name().to_string_lossy()
        ))
        .ok()?;
        let pos: f64 = info
            .lines()
            .find_map(|l| l.strip_prefix("pos:"))?
            .trim()
            .parse()
            .ok()?;
        Some(pos / length)
    })
}

/// SIGTERM during a paced replay with a recording: the run stops cleanly, and the events,
/// summary and .rrd it leaves are complete and readable (rerun's own verifier).
#[test]
fn sigterm_during_replay_leaves_complete_files() {
    let dir = tempfile::tempdir().unwrap();
    let (summary, events, rrd) = (
        dir.path().join("s.json"),
        dir.path().join("e.jsonl"),
        dir.path().join("r.rrd"),
    );
    let mut child = Command::new(env!("CARGO_BIN_EXE_savsim"))
        .current_dir(root())
        .args([
            "replay",
            "scenes/flights/copter_square_10ms.tlog",
            "--speed",
            "10",
            "--scene",
            "scenes/city.toml",
        ])
        .arg("--summary-json")
        .arg(&summary)
        .arg("--events")
        .arg(&events)
        .arg("--rerun")
        .arg(format!("save={}", rrd.display()))
        .stdout(std::process::Stdio::null())
        .spawn()
        .unwrap();
    // Once savsim has read half of the flight (its ticks began after the first fixes, within
    // its first tenth; the flight lasts 21 s at this speed, paced), stop it.
    let flight = root().join("scenes/flights/copter_square_10ms.tlog");
    let deadline = std::time::Instant::now() + std::time::Duration::from_secs(120);
    let pid = child.id();
    let mut running = || child.try_wait().unwrap().is_none();
    let halfway = wait_until(deadline, || {
        read_fraction(pid, &flight).is_some_and(|f| f >= 0.5) || !running()
    });
    assert!(halfway && running(), "savsim ended before the signal");
    let status = signal_and_wait(&mut child, "TERM");
    assert!(status.success(), "{status:?}");
    let s: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&summary).unwrap()).unwrap();
    assert_eq!(
        s["interrupted"], true,
        "the run ended before the signal: {s}"
    );
    assert!(s["collision"]["ticks"].as_u64().unwrap() > 0);
    for line in std::fs::read_to_string(&events).unwrap().lines() {
        serde_json::from_str::<serde_json::Value>(line).expect("every event line is whole JSON");
    }
    if !have_rerun_cli() {
        return;
    }
    assert_rrd_verifies(&rrd);
}

/// Six vehicles: the first four get a chase view each, the others are in the overview only,
/// and the final layout leaves every vehicle's rays and colliders out of the overview.
#[test]
fn a_fleet_gets_four_chase_views_and_one_overview() {
    let scene = crate::common::scene_at(
        savsim::geo::Geodetic {
            lat_deg: 47.0,
            lon_deg: 8.0,
            alt_m: 400.0,
        },
        "[[obstacle]]\nid = \"b\"\nkind = \"building\"\nshape = { box = [20.0, 20.0, 30.0] }\n\
         position_enu_m = [0.0, 200.0, 0.0]\n",
    );
    let plane = savsim::geo::LocalTangentPlane::new(scene.origin);
    let (mut session, storage) = session_in_memory(scene, savsim::viz::VizOptions::default());
    let mut seq = 0;
    for step in 0..20u32 {
        for sysid in 1..=6u8 {
            let p = glam::DVec3::new(f64::from(sysid) * 30.0, f64::from(step), 40.0);
            let bytes = crate::common::position_frames(
                &plane,
                sysid,
                &mut seq,
                1000 + step * 100,
                p,
                glam::DVec3::Y * 10.0,
            );
            crate::common::feed(&mut session, 1.7e9 + f64::from(step) * 0.1, &bytes);
        }
    }
    session.finish().unwrap();
    let text = format!("{:?}", storage.take());
    for id in 1..=6 {
        assert!(
            text.contains(&format!("world/vehicles/{id}/body")),
            "vehicle {id}"
        );
        assert!(
            text.contains(&format!("- /world/vehicles/{id}/colliders/**")),
            "the overview leaves out vehicle {id}'s colliders"
        );
    }
    for id in 1..=4 {
        assert!(
            text.contains(&format!("vehicle {id} (chase)")),
            "chase view {id}"
        );
    }
    for id in 5..=6 {
        assert!(
            !text.contains(&format!("vehicle {id} (chase)")),
            "no chase view {id}"
        );
    }
}

/// What a vehicle says (STATUSTEXT, its mode changes, COLLISION) is a text log on its
/// timelines, and the ADS-B reports the feed sent it are drawn where they put the aircraft,
/// labelled; the layout has a text view of them.
#[test]
fn what_a_vehicle_says_and_the_adsb_it_was_told_are_in_its_recording() {
    use mavlink::dialects::ardupilotmega::{
        MavAutopilot, MavCollisionAction, MavCollisionSrc, MavCollisionThreatLevel, MavMessage,
        MavSeverity, MavType, COLLISION_DATA, HEARTBEAT_DATA, STATUSTEXT_DATA,
    };
    let origin = savsim::geo::Geodetic {
        lat_deg: 47.0,
        lon_deg: 8.0,
        alt_m: 400.0,
    };
    let scene = crate::common::scene_at(
        origin,
        "[[dynamic]]\nid = \"airliner\"\nkind = \"a320\"\nwaypoints = [\
         { t_s = 0.0, position_enu_m = [700.0, 0.0, 30.0] }, \
         { t_s = 100.0, position_enu_m = [-3300.0, 0.0, 30.0] }]\n",
    );
    let plane = savsim::geo::LocalTangentPlane::new(scene.origin);
    let (mut session, storage) = session_in_memory(scene, savsim::viz::VizOptions::default());
    session
        .start_feed(savsim::feed::FeedConfig {
            kinds: savsim::feed::FeedKinds::parse("adsb").unwrap(),
            ..savsim::feed::FeedConfig::default()
        })
        .unwrap();
    let heartbeat = |custom_mode: u32| {
        let MavMessage::HEARTBEAT(hb) = crate::common::heartbeat(
            MavType::MAV_TYPE_QUADROTOR,
            MavAutopilot::MAV_AUTOPILOT_ARDUPILOTMEGA,
        ) else {
            unreachable!()
        };
        MavMessage::HEARTBEAT(HEARTBEAT_DATA { custom_mode, ..hb })
    };
    let said = MavMessage::STATUSTEXT(STATUSTEXT_DATA {
        severity: MavSeverity::MAV_SEVERITY_WARNING,
        text: "ADSB: avoiding 4840D6".into(),
        ..STATUSTEXT_DATA::default()
    });
    let collision = |first: bool| {
        MavMessage::COLLISION(COLLISION_DATA {
            src: MavCollisionSrc::MAV_COLLISION_SRC_ADSB,
            id: 0x48_40D6,
            action: if first {
                MavCollisionAction::MAV_COLLISION_ACTION_REPORT
            } else {
                MavCollisionAction::MAV_COLLISION_ACTION_MOVE_HORIZONTALLY
            },
            threat_level: MavCollisionThreatLevel::MAV_COLLISION_THREAT_LEVEL_HIGH,
            time_to_minimum_delta: 12.0,
            altitude_minimum_delta: 3.0,
            horizontal_minimum_delta: 40.0,
        })
    };
    let mut seq = 0;
    for step in 0..40u32 {
        let mut bytes = Vec::new();
        // GUIDED (4), then AVOID_ADSB (19) from step 20, with a STATUSTEXT then.
        let mode = if step < 20 { 4 } else { 19 };
        bytes.extend(crate::common::frame_v2(1, 1, seq, &heartbeat(mode)));
        if step == 20 {
            bytes.extend(crate::common::frame_v2(1, 1, seq, &said));
        }
        // The same COLLISION repeated, then its action changed.
        if (21..26).contains(&step) {
            bytes.extend(crate::common::frame_v2(1, 1, seq, &collision(step < 24)));
        }
        let p = glam::DVec3::new(0.0, f64::from(step), 30.0);
        bytes.extend(crate::common::position_frames(
            &plane,
            1,
            &mut seq,
            50_000 + step * 100,
            p,
            glam::DVec3::Y * 10.0,
        ));
        crate::common::feed(&mut session, 1.7e9 + f64::from(step) * 0.1, &bytes);
        session.drain_feed().for_each(drop);
    }
    session.finish().unwrap();
    let text = format!("{:?}", storage.take());
    for part in [
        "messages/1",
        "mode GUIDED",
        "mode AVOID_ADSB",
        "ADSB: avoiding 4840D6",
        "world/vehicles/1/feed/adsb/",
        "what the vehicles said",
        // The airliner passes within well clear: the loss marked, its volume drawn.
        "world/events/well_clear",
        "world/events/well_clear/volumes",
        "Cylinders3D",
        // Its closest approach to the airliner, marked when the run ended.
        "world/events/closest_approaches/1/airliner",
        "CPA v1 airliner",
    ] {
        assert!(text.contains(part), "{part} is not in the recording");
    }
    // A mode is said once, when it changes, not at every heartbeat; a COLLISION when it
    // changes.
    assert_eq!(text.matches("mode AVOID_ADSB").count(), 1);
    assert_eq!(
        text.matches("COLLISION: threat ADS-B 4840D6").count(),
        2,
        "{text}"
    );
    assert_eq!(
        text.matches("MAV_COLLISION_ACTION_MOVE_HORIZONTALLY")
            .count(),
        1
    );
}
