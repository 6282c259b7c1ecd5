//! A dense block of vehicles: a tick without a sensing frame takes only the bodies within its
//! approach reach (session::traffic), and makes the whole state (the attitude, the box) only
//! of those the pipeline can use, the rest by their positions; it gives the answers a tick that
//! takes every body of the watch range, whole, gives (a recorded run takes them all: the
//! viewer draws them). In `exact` (the sensor's region) and in `paper` (the octree node's).

use glam::DVec3;
use savsim::geo::{Geodetic, LocalTangentPlane};
use savsim::logs::tlog::TlogWriter;

use crate::cli::savsim;
use crate::common::{assert_ran, frame_v2, pose_messages};

/// The bundled city's origin (scenes/city.toml).
const ORIGIN: Geodetic = Geodetic::new(-35.363261, 149.16523, 584.0);

/// The tlog's first instant, microseconds since the Unix epoch (2026-01-01).
const EPOCH_US: u64 = 1_767_225_600_000_000;

/// Vehicle `sysid`'s positions and attitudes at 10 Hz for 3 s from `phase_s`, each
/// `motion(t_s)` (ENU position and velocity), into `records` as (stamp, frame).
fn fly(
    records: &mut Vec<(u64, Vec<u8>)>,
    plane: &LocalTangentPlane,
    sysid: u8,
    phase_s: f64,
    motion: impl Fn(f64) -> (DVec3, DVec3),
) {
    let mut seq = 0u8;
    for k in 0..30 {
        let t_s = phase_s + f64::from(k) / 10.0;
        let (p, v) = motion(t_s);
        let ms = 1000 + (t_s * 1000.0).round() as u32;
        for m in pose_messages(plane, ms, p, v, [0.0, 0.0, v.x.atan2(v.y)]) {
            let stamp_us = EPOCH_US + (t_s * 1e6).round() as u64;
            records.push((stamp_us, frame_v2(sysid, 1, seq, &m)));
            seq = seq.wrapping_add(1);
        }
    }
}

/// A 6 x 6 block 20 m apart, 300 m over the city's origin, each vehicle circling 12 m at
/// 8 m/s (neighbours' circles overlap: they meet), each at its own phase; two flying head on
/// through its middle (they meet at 2.5 s); one hovering 400 m east of the block (within the
/// sensing reach, beyond the approach reach): a tlog.
fn block_tlog() -> Vec<u8> {
    let plane = LocalTangentPlane::new(ORIGIN);
    let (side, spacing_m, radius_m, speed_mps) = (6u8, 20.0, 12.0, 8.0);
    let mut records = Vec::new();
    for n in 0..side * side {
        let centre = DVec3::new(
            f64::from(n % side) * spacing_m,
            f64::from(n / side) * spacing_m,
            300.0,
        );
        let phase_s = f64::from(n) / f64::from(side * side) / 10.0;
        fly(&mut records, &plane, n + 1, phase_s, |t_s| {
            let a = speed_mps / radius_m * t_s + f64::from(n);
            let p = centre + radius_m * DVec3::new(a.cos(), a.sin(), 0.0);
            (p, speed_mps * DVec3::new(-a.sin(), a.cos(), 0.0))
        });
    }
    for (sysid, from_x, v_x) in [(37u8, 30.0, 8.0), (38, 70.0, -8.0), (39, 500.0, 0.0)] {
        fly(&mut records, &plane, sysid, 0.0, |t_s| {
            let p = DVec3::new(from_x + v_x * t_s, 50.0, 300.0);
            (p, DVec3::new(v_x, 0.0, 0.0))
        });
    }
    records.sort_by_key(|r| r.0);
    let mut out = Vec::new();
    let mut w = TlogWriter::new(&mut out);
    for (t, f) in &records {
        w.write_record(*t, f).unwrap();
    }
    out
}

/// The events and the summary's closest approaches (every pair listed) and collision figures
/// of a replay of `tlog` in `mode` at `--sensor-hz 2`, recorded or not.
fn replay(
    dir: &std::path::Path,
    tlog: &std::path::Path,
    mode: &str,
    recorded: bool,
) -> (String, String) {
    let name = format!("{mode}-{}", if recorded { "recorded" } else { "plain" });
    let (events, summary) = (
        dir.join(format!("{name}.jsonl")),
        dir.join(format!("{name}.json")),
    );
    let mut c = savsim();
    c.arg("replay")
        .arg(tlog)
        .args(["--scene", "scenes/city.toml", "--well-clear", "none"])
        .args(["--mode", mode])
        .args([
            "--sensor-hz",
            "2",
            "--summary-pairs",
            "0",
            "--no-progress",
            "--events",
        ])
        .arg(&events)
        .arg("--summary-json")
        .arg(&summary);
    if recorded {
        c.arg("--rerun").arg(format!(
            "save={}",
            dir.join(format!("{name}.rrd")).display()
        ));
    }
    assert_ran(&c.output().unwrap());
    let s: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&summary).unwrap()).unwrap();
    let mut collision = s["collision"].clone();
    // What the ticks cost is not an answer.
    for timed in ["cost_us_median", "cost_us_p99"] {
        collision["per_tick"][timed] = serde_json::Value::Null;
    }
    collision["mesh_build_s"] = serde_json::Value::Null;
    let figures = serde_json::json!({"approaches": s["approaches"], "collision": collision});
    (
        std::fs::read_to_string(&events).unwrap(),
        figures.to_string(),
    )
}

/// The first place `a` and `b` differ, with some context.
fn first_difference(a: &str, b: &str) -> String {
    let at = a.bytes().zip(b.bytes()).take_while(|(x, y)| x == y).count();
    let from = at.saturating_sub(200);
    let part = |s: &str| {
        s.get(from..(at + 200).min(s.len()))
            .unwrap_or("")
            .to_string()
    };
    format!("at byte {at}:\n{}\n{}", part(a), part(b))
}

#[test]
#[cfg(feature = "viz")]
fn a_dense_block_judged_within_the_approach_reach_gives_the_whole_ranges_answers() {
    let dir = tempfile::tempdir().unwrap();
    let tlog = dir.path().join("block.tlog");
    std::fs::write(&tlog, block_tlog()).unwrap();
    for mode in ["exact", "paper"] {
        judged_within_reach(dir.path(), &tlog, mode);
    }
}

/// The block's replay in `mode`, plain and recorded: the same answers.
#[cfg(feature = "viz")]
fn judged_within_reach(dir: &std::path::Path, tlog: &std::path::Path, mode: &str) {
    let (plain_events, plain) = replay(dir, tlog, mode, false);
    let (recorded_events, recorded) = replay(dir, tlog, mode, true);
    // The block meets: collisions, and vehicles within NMAC of each other.
    let collisions = plain_events.matches("\"kind\":\"collision\"").count();
    assert!(collisions > 0, "no collision in {plain_events:.2000}");
    assert!(plain.contains("\"nmac\":true"), "{plain:.2000}");
    // Pairs are judged only within the approach reach (about 180 m here): the hovering vehicle
    // has no closest approach to the block's (the scene's own tracks are judged at every
    // tick), though the block is within its sensing reach.
    let s: serde_json::Value = serde_json::from_str(&plain).unwrap();
    let of_far = s["approaches"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|a| a["vehicle"] == 39 || a["track"] == "vehicle:39");
    let tracks: Vec<_> = of_far.map(|a| a["track"].to_string()).collect();
    assert!(tracks.iter().all(|t| !t.contains("vehicle:")), "{tracks:?}");
    assert!(!tracks.is_empty());
    assert!(
        plain_events == recorded_events,
        "{mode}: events differ {}",
        first_difference(&plain_events, &recorded_events)
    );
    assert!(
        plain == recorded,
        "{mode}: figures differ {}",
        first_difference(&plain, &recorded)
    );
}
