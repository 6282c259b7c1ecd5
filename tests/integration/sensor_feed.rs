//! The feed from modelled devices (`--sensors`): `ideal` is the feed savsim sent before sensors
//! were modelled, bit for bit; a device reads from its place along its own rays with its
//! errors, leaves what it does not see unknown, and draws the same errors at the same instants
//! of the vehicle's clock however the samples fall.

use std::sync::Arc;

use glam::DVec3;
use mavlink::dialects::ardupilotmega::{MavAutopilot, MavMessage, MavType};
use savsim::feed::{sensors_for, FeedConfig, FeedKinds};
use savsim::geo::{Geodetic, LocalTangentPlane};
use savsim::pipeline::CollisionConfig;
use savsim::session::Session;
use sha2::{Digest, Sha256};

use crate::cli::savsim;
use crate::common::{feed, frame_v2, heartbeat, position_frames, scene_at};

/// SHA-256 of `savsim demo --feed KINDS --feed-out` as savsim wrote it before sensors were
/// modelled (commit b2432dd), for each KINDS; `obstacle-distance`'s as savsim writes it since
/// boxes are cast in f64 (2026-12-07): 3 of its 145,800 distances moved by 1 cm (pymavlink
/// read both), where parry's f32 cast had rounded across a centimetre (b2432dd's was
/// 0be43f2ac6c1291ea5a5c728ea5d593966eaf2d6a786111ec8dbb4e7a2cbef18).
const BEFORE_SENSORS: [(&str, &str); 2] = [
    (
        "proximity,rangefinder,adsb,collision",
        "b440b041eea18b2860aa9e6d9461fd945d6e05582b829921499f9ed737dc3580",
    ),
    (
        "obstacle-distance",
        "511d1fcb1ee1d5f9e28bb048bec55e75bccbdbde28ca1c6cdcf8af1773a4ea7f",
    ),
];

#[test]
fn ideal_is_the_feed_savsim_sent_before_sensors_bit_for_bit() {
    let dir = tempfile::tempdir().unwrap();
    for (kinds, sha) in BEFORE_SENSORS {
        for sensors in [None, Some("ideal")] {
            let out = dir.path().join("feed.tlog");
            let mut cmd = savsim();
            cmd.args(["demo", "--feed", kinds, "--feed-out"]).arg(&out);
            if let Some(s) = sensors {
                cmd.args(["--sensors", s]);
            }
            crate::common::assert_ran(&cmd.output().unwrap());
            let digest = Sha256::digest(std::fs::read(&out).unwrap());
            let hex: String = digest.iter().map(|b| format!("{b:02x}")).collect();
            assert_eq!(hex, sha, "{kinds} with {sensors:?}");
        }
    }
}

const ORIGIN: Geodetic = Geodetic::new(47.0, 8.0, 400.0);

/// A wall 5 m east of the origin (its west face at E = 5), 40 m wide and 30 m tall.
fn wall() -> savsim::scene::Scene {
    scene_at(
        ORIGIN,
        "[[obstacle]]\nid = \"wall\"\nkind = \"building\"\nshape = { box = [2.0, 40.0, 30.0] }\nposition_enu_m = [6.0, 0.0, 0.0]\n",
    )
}

/// OBSTACLE_DISTANCE frames (the 72 distances, cm) of a vehicle hovering at 10 m over the
/// origin, nose east, sampled every `step_ms` for `ms`, with `sensors` seeded `seed`.
fn hover(sensors: &str, seed: u64, step_ms: u32, ms: u32) -> Vec<(u32, [u16; 72])> {
    fly(
        sensors,
        seed,
        (step_ms, ms),
        (DVec3::new(0.0, 0.0, 10.0), DVec3::ZERO),
    )
}

/// As [`hover`], the vehicle at `start` (ENU, m) at 10 s and flying at `velocity` (m/s); each
/// frame with the sample time it was sent at, ms.
fn fly(
    sensors: &str,
    seed: u64,
    (step_ms, ms): (u32, u32),
    (start, velocity): (DVec3, DVec3),
) -> Vec<(u32, [u16; 72])> {
    let scene = wall();
    let plane = LocalTangentPlane::new(ORIGIN);
    let suite = sensors_for(Some(sensors), Some(&scene)).unwrap();
    let mut session =
        Session::new(Some(Arc::new(scene)), CollisionConfig::default(), None).unwrap();
    session
        .start_feed(FeedConfig {
            kinds: FeedKinds::parse("obstacle-distance").unwrap(),
            sensors: suite,
            sensor_seed: seed,
            ..FeedConfig::default()
        })
        .unwrap();
    let hb = heartbeat(
        MavType::MAV_TYPE_QUADROTOR,
        MavAutopilot::MAV_AUTOPILOT_ARDUPILOTMEGA,
    );
    feed(&mut session, 1000.0, &frame_v2(1, 1, 0, &hb));
    let mut seq = 1u8;
    let mut out = Vec::new();
    for t_ms in (10_000..10_000 + ms).step_by(step_ms as usize) {
        let frames = position_frames(
            &plane,
            1,
            &mut seq,
            t_ms,
            start + velocity * f64::from(t_ms - 10_000) / 1000.0,
            velocity,
        );
        feed(&mut session, f64::from(t_ms) / 1000.0, &frames);
        for m in session.drain_feed() {
            if let MavMessage::OBSTACLE_DISTANCE(d) = m.message {
                out.push((t_ms, d.distances));
            }
        }
    }
    out
}

/// Bin 4 is centred on the nose (bin 0 is 20 degrees left of it); bin 40 on the tail.
const NOSE: usize = 4;
const TAIL: usize = 40;

#[test]
fn a_lidar_reads_the_wall_with_its_noise_and_a_front_camera_leaves_the_rest_unknown() {
    // RPLIDAR A2: all around, 1% of the distance; the wall 5 m ahead (the quad's reference
    // point at the origin, the lidar on it).
    let frames = hover("rplidar-a2", 1, 50, 3000);
    assert!(frames.len() > 40);
    for (_, d) in frames.iter().skip(3) {
        let nose = f64::from(d[NOSE]);
        assert!(
            (nose - 500.0).abs() <= 3.0 * 5.0 + 1.0,
            "nose bin {nose} cm"
        );
        // Nothing within 12 m behind: clear (max + 1).
        assert_eq!(d[TAIL], 1201);
    }
    // A bin is the nearest of its 11 or 12 rays (0.45 degrees apart in 5), each with its own
    // noise (5 cm at 5 m): short of the wall by the expected least of that many normal draws,
    // 1.59 to 1.63 sigma (docs/sensors.md).
    let noses: Vec<f64> = frames
        .iter()
        .skip(3)
        .map(|(_, d)| f64::from(d[NOSE]))
        .collect();
    let short_sigmas = (500.0 - noses.iter().sum::<f64>() / noses.len() as f64) / 5.0;
    assert!(
        (1.3..=1.9).contains(&short_sigmas),
        "{short_sigmas} sigma short"
    );
    // A D435 sees 87 degrees ahead: behind it, unknown (UINT16_MAX). A bin is the nearest of
    // its rays (five across, seven rows), each with the z^2 error (9.4 cm at 5 m): below 5 m
    // by up to four sigma, above by at most one.
    let frames = hover("realsense-d435", 1, 50, 3000);
    let sigma_cm = 25.0 * 0.08 / (424.0 * 0.05) * 100.0;
    for (_, d) in frames.iter().skip(3) {
        let nose = f64::from(d[NOSE]);
        assert!(
            (500.0 - 4.0 * sigma_cm..=500.0 + sigma_cm).contains(&nose),
            "{nose}"
        );
        assert_eq!(d[TAIL], u16::MAX);
        let unknown = d.iter().filter(|&&c| c == u16::MAX).count();
        // 87 of 360 degrees: about 18 of the 72 bins known.
        assert!((52..=56).contains(&unknown), "{unknown} bins unknown");
    }
}

#[test]
fn a_lidar_turn_is_read_as_it_is_swept_so_a_fast_vehicle_sees_the_wall_where_it_was() {
    // An RPLIDAR without errors or latency, its turn 0.1 s, flying east at 10 m/s towards the
    // wall (its face at E = 5), sampled every 20 ms for 0.8 s from E = -6 (the feed's frames
    // every 50 ms). Its nose column (azimuth 0,
    // column 400 of 800) is read half a turn before the reading's instant: 0.5 m farther back
    // than the vehicle is at the instant.
    let sensors = "rplidar-a2:latency_s=0.0:proportional=0.0:quantum_m=0.0";
    let v_mps = 10.0;
    let start = DVec3::new(-6.0, 0.0, 10.0);
    let frames = fly(sensors, 1, (20, 800), (start, DVec3::new(v_mps, 0.0, 0.0)));
    assert!(frames.len() >= 14, "{}", frames.len());
    let east_at = |t_s: f64| start.x + v_mps * (t_s - 10.0);
    for (t_ms, d) in &frames {
        // The reading taken at the newest instant k / 10 s at or before the frame's sample.
        let instant_s = (f64::from(*t_ms) / 100.0 + 1e-9).floor() / 10.0;
        let swept_s = instant_s - 0.1 + 400.5 / 800.0 * 0.1;
        let expected_cm = (5.0 - east_at(swept_s)) * 100.0;
        let at_instant_cm = (5.0 - east_at(instant_s)) * 100.0;
        let nose = f64::from(d[NOSE]);
        // The bin is the nearest of its rays, which are read within +-0.7 ms of the nose's
        // and cast from their fan's middle (+-1.6 ms): within 3 cm, truncated to the cm.
        assert!(
            (nose - expected_cm).abs() <= 3.0,
            "{t_ms} ms: nose {nose} cm, swept {expected_cm:.1}, at the instant {at_instant_cm:.1}"
        );
        assert!(nose - at_instant_cm >= 45.0, "{t_ms} ms: {nose} cm");
    }
    // Hovering, the same lidar reads the wall at its distance: spreading changes nothing.
    for (_, d) in hover(sensors, 1, 20, 600).iter().skip(1) {
        assert!((f64::from(d[NOSE]) - 500.0).abs() <= 1.0, "{}", d[NOSE]);
    }
}

#[test]
fn the_same_seed_gives_the_same_readings_at_the_same_instants_however_samples_fall() {
    // A 5 Hz device: its instants fall on samples 100 ms and 20 ms apart alike, so the truth
    // is the same and so are the readings.
    let sensors = "rplidar-a2:rate_hz=5.0:proportional=0.05:bias_m=0.3";
    let distinct = |frames: Vec<(u32, [u16; 72])>| {
        let mut pictures: Vec<[u16; 72]> = Vec::new();
        for (_, d) in frames {
            if pictures.last() != Some(&d) {
                pictures.push(d);
            }
        }
        pictures
    };
    let coarse = distinct(hover(sensors, 7, 100, 4000));
    let fine = distinct(hover(sensors, 7, 20, 4000));
    assert!(coarse.len() >= 15, "{}", coarse.len());
    assert_eq!(coarse, fine);
    assert_eq!(coarse, distinct(hover(sensors, 7, 100, 4000)), "run to run");
    assert_ne!(
        coarse,
        distinct(hover(sensors, 8, 100, 4000)),
        "another seed"
    );
}

#[test]
fn bad_sensor_lists_are_clear_errors() {
    let scene = wall();
    for (list, says) in [
        ("lidar", "not a preset"),
        ("ideal,tfmini", "ideal"),
        ("tfmini,tfmini", "two sensors"),
        ("adsb-1090es:nacp=99", "nacp"),
        ("tfmini:rate_hz", "key=value"),
        ("missing.toml", "missing.toml"),
        // An array setting is read whole (it was cut at its comma), and checked.
        ("rplidar-a2:fov_deg=[400,0]", "fov_deg"),
        // A number from outside is written as a person reads it, not in 301 digits.
        ("rplidar-a2:rate_hz=1e300", "rate_hz: 1e300: give"),
    ] {
        let err = sensors_for(Some(list), Some(&scene))
            .unwrap_err()
            .to_string();
        assert!(err.contains(says), "{list}: {err}");
        assert!(err.len() < 300, "{list}: {err}");
    }
    // An array setting within range is taken, beside another device.
    let suite = sensors_for(Some("rplidar-a2:fov_deg=[180,0],tfmini-down"), Some(&scene)).unwrap();
    let savsim::sensors::device::Model::Range(lidar) = &suite.devices()[0].model else {
        panic!("{suite:?}")
    };
    assert_eq!(lidar.fov_deg, [180.0, 0.0]);
    assert_eq!(suite.devices().len(), 2);
    let out = savsim()
        .args([
            "demo",
            "--feed",
            "proximity",
            "--sensors",
            "tfmini:sigma_m=-1",
        ])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("sigma_m"));
}

/// Every device file shipped in scenes/sensors/ is a valid `--sensors` list.
#[test]
fn the_shipped_sensor_files_load() {
    let dir = crate::common::root().join("scenes/sensors");
    let mut files: Vec<_> = std::fs::read_dir(&dir)
        .unwrap()
        .flatten()
        .map(|e| e.path())
        .filter(|p| p.extension().is_some_and(|x| x == "toml"))
        .collect();
    files.sort();
    assert!(files.len() >= 7, "{files:?}");
    for file in files {
        let path = file.to_str().unwrap();
        if let Err(e) = sensors_for(Some(path), None) {
            panic!("{path}: {e}");
        }
    }
}
