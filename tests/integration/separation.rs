//! The separation minimum (`--separation-m`): a pair nearer than it is lost at the instant an
//! independent calculation gives (a straight pass by a vehicle standing still: the chord of a
//! sphere), regained at the other end, and in the summary with its closest approach.

use std::sync::Arc;

use glam::DVec3;
use savsim::daa::approach::Approaches;
use savsim::daa::separation::Separation;
use savsim::geo::{Geodetic, LocalTangentPlane};
use savsim::pipeline::CollisionConfig;
use savsim::session::Session;

use crate::common::{feed, position_frames, scene_at};

/// Vehicle 1 flies east at 5 m/s along y = 0, 10 m up; vehicle 2 stands at (50, 2, 10):
/// nearer than 3 m for sqrt(3^2 - 2^2) = sqrt(5) m either side of x = 50.
#[test]
fn a_pass_nearer_than_the_minimum_is_lost_and_regained_where_the_sphere_says() {
    let origin = Geodetic::new(47.0, 8.0, 500.0);
    let plane = LocalTangentPlane::new(origin);
    let dir = tempfile::tempdir().unwrap();
    let events = dir.path().join("events.jsonl");
    let scene = Arc::new(scene_at(origin, ""));
    let mut session = Session::new(Some(scene), CollisionConfig::default(), Some(&events)).unwrap();
    session.set_approaches(
        Approaches::with_volume(None).with_separation(Some(Separation { minimum_m: 3.0 })),
    );
    let (mut seq1, mut seq2) = (0u8, 0u8);
    let t0 = 1_700_000_000.0;
    for k in 0..=200u32 {
        let t = f64::from(k) * 0.1;
        let ms = k * 100;
        let one = position_frames(
            &plane,
            1,
            &mut seq1,
            ms,
            DVec3::new(5.0 * t, 0.0, 10.0),
            DVec3::new(5.0, 0.0, 0.0),
        );
        feed(&mut session, t0 + t, &one);
        let two = position_frames(
            &plane,
            2,
            &mut seq2,
            ms,
            DVec3::new(50.0, 2.0, 10.0),
            DVec3::ZERO,
        );
        feed(&mut session, t0 + t, &two);
    }
    session.finish().unwrap();
    let lines: Vec<serde_json::Value> = std::fs::read_to_string(&events)
        .unwrap()
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    let of = |kind: &str, vehicle: u64| -> Vec<&serde_json::Value> {
        lines
            .iter()
            .filter(|e| e["kind"] == kind && e["vehicle"] == vehicle)
            .collect()
    };
    let half = 5f64.sqrt() / 5.0;
    // Each vehicle sees the other: one loss and one regain each.
    for vehicle in [1, 2] {
        let lost = of("separation_lost", vehicle);
        let regained = of("separation_regained", vehicle);
        assert_eq!((lost.len(), regained.len()), (1, 1), "{lines:#?}");
        let lost_t = lost[0]["lost_t"].as_f64().unwrap() - t0;
        let regained_t = regained[0]["regained_t"].as_f64().unwrap() - t0;
        // Positions are sent to 1e-7 degrees (about 1 cm): 5 ms at 5 m/s.
        assert!((lost_t - (10.0 - half)).abs() < 5e-3, "{lost_t}");
        assert!((regained_t - (10.0 + half)).abs() < 5e-3, "{regained_t}");
        assert_eq!(lost[0]["minimum_m"], 3.0);
        let duration_s = regained[0]["duration_s"].as_f64().unwrap();
        assert!((duration_s - 2.0 * half).abs() < 1e-2, "{duration_s}");
    }
    let summary = session.summary("test", "pass");
    let separation = &summary["separation"];
    assert_eq!(separation["minimum_m"], 3.0);
    assert_eq!(separation["losses"], 2);
    assert_eq!(separation["pairs_under"], 2);
    for pair in separation["pairs"].as_array().unwrap() {
        let closest_m = pair["closest_m"].as_f64().unwrap();
        assert!((closest_m - 2.0).abs() < 0.02, "{pair}");
        assert_eq!(pair["episodes"], 1);
    }
}

/// Without `--separation-m` nothing is judged, and the summary says so (null).
#[test]
fn without_a_minimum_nothing_is_judged() {
    let session = Session::new(None, CollisionConfig::default(), None).unwrap();
    assert!(session.summary("test", "none")["separation"].is_null());
}

/// A minimum that is not a positive distance of at most 1000 m is a usage error naming it.
#[test]
fn a_bad_minimum_is_a_usage_error_naming_it() {
    replay_refuses_naming("--separation-m", &["0", "-3", "nan", "inf", "1e9", "three"]);
}

/// `savsim replay FLAG VALUE` is a usage error naming `flag` for each of `values`.
fn replay_refuses_naming(flag: &str, values: &[&str]) {
    for value in values {
        let out = crate::cli::savsim()
            .args(["replay", flag, value, "nothing.tlog"])
            .output()
            .unwrap();
        assert_eq!(out.status.code(), Some(2), "{value}");
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(stderr.contains(flag), "{value}: {stderr}");
    }
}

/// A drone show as `scripts/fleet.py --show` flies it (25 vehicles 3 m apart taking off
/// together, spreading with a wave, gathering and landing, vehicles 1 and 2 made to touch),
/// replayed with the show's slots as planned: the touch is a collision between them, theirs is
/// the only pair under the 2 m minimum (closest 0.1 m), every other pair keeps at least the
/// grid's 3 m, and vehicle 2 alone left its slot (by about the grid's spacing).
#[test]
fn a_show_with_one_faulty_pair_has_that_pair_alone_under_the_minimum() {
    if !crate::common::have_pymavlink() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let (tlog, slots) = (dir.path().join("show.tlog"), dir.path().join("slots.csv"));
    crate::common::python(
        &crate::common::root().join("scripts/fleet.py"),
        &[
            "0",
            "--show",
            "--vehicles",
            "25",
            "--seconds",
            "40",
            "--altitude-m",
            "10",
            "--tlog",
            tlog.to_str().unwrap(),
            "--slots-out",
            slots.to_str().unwrap(),
        ],
    );
    let scene = dir.path().join("empty.toml");
    std::fs::write(
        &scene,
        "[origin]\nlat_deg = -35.363261\nlon_deg = 149.16523\nalt_m = 584\n",
    )
    .unwrap();
    let summary = dir.path().join("summary.json");
    let events = dir.path().join("events.jsonl");
    let out = crate::cli::savsim()
        .args([
            "replay",
            "--well-clear",
            "none",
            "--near-miss-m",
            "0.5",
            "--separation-m",
            "2",
        ])
        .args(["--slot-tolerance-m", "0.5", "--slots"])
        .arg(&slots)
        .arg("--scene")
        .arg(&scene)
        .arg("--events")
        .arg(&events)
        .arg("--summary-json")
        .arg(&summary)
        .arg(&tlog)
        .output()
        .unwrap();
    crate::common::assert_ran(&out);
    let summary: serde_json::Value =
        serde_json::from_slice(&std::fs::read(&summary).unwrap()).unwrap();
    let separation = &summary["separation"];
    assert_eq!(separation["pairs_under"], 2, "{separation:#}");
    let mut under: Vec<(u64, String)> = separation["pairs"]
        .as_array()
        .unwrap()
        .iter()
        .map(|p| {
            assert!(p["closest_m"].as_f64().unwrap() < 0.15, "{p}");
            (
                p["vehicle"].as_u64().unwrap(),
                p["track"].as_str().unwrap().to_string(),
            )
        })
        .collect();
    under.sort();
    assert_eq!(
        under,
        [(1, "vehicle:2".to_string()), (2, "vehicle:1".to_string())]
    );
    for pair in summary["approaches"].as_array().unwrap() {
        let faulty = matches!(
            (pair["vehicle"].as_u64(), pair["track"].as_str()),
            (Some(1), Some("vehicle:2")) | (Some(2), Some("vehicle:1"))
        );
        if !faulty {
            assert!(pair["distance_m"].as_f64().unwrap() > 2.95, "{pair}");
        }
    }
    let slots = &summary["slots"];
    assert_eq!(
        (slots["vehicles"].as_u64(), slots["vehicles_left"].as_u64()),
        (Some(25), Some(1)),
        "{slots:#}"
    );
    let left = &slots["left"][0];
    assert_eq!(left["vehicle"], 2, "{slots:#}");
    // It drifts onto vehicle 1 (to 0.1 m east of it: 2 x 3 m - 0.1 m west of its spread slot,
    // and to its height, the wave up to 2.35 m apart), and back.
    let max_m = left["max_deviation_m"].as_f64().unwrap();
    assert!((5.85..6.4).contains(&max_m), "{slots:#}");
    let lines: Vec<serde_json::Value> = std::fs::read_to_string(&events)
        .unwrap()
        .lines()
        .map(|l| serde_json::from_str::<serde_json::Value>(l).unwrap())
        .collect();
    let collisions: Vec<&serde_json::Value> =
        lines.iter().filter(|e| e["kind"] == "collision").collect();
    assert!(!collisions.is_empty());
    for c in &collisions {
        let pair = (c["vehicle"].as_u64(), c["obstacle"].as_str());
        assert!(
            matches!(
                pair,
                (Some(1), Some("vehicle:2")) | (Some(2), Some("vehicle:1"))
            ),
            "{c}"
        );
    }
    let departures: Vec<&serde_json::Value> =
        lines.iter().filter(|e| e["kind"] == "left_slot").collect();
    assert_eq!(departures.len(), 1, "{departures:#?}");
    assert_eq!(departures[0]["vehicle"], 2);
    assert_eq!(
        lines.iter().filter(|e| e["kind"] == "back_in_slot").count(),
        1
    );
}

/// Slots that cannot be used are usage errors naming the file and the line.
#[test]
fn bad_slots_are_usage_errors_naming_them() {
    let dir = tempfile::tempdir().unwrap();
    let slots = dir.path().join("slots.csv");
    std::fs::write(
        &slots,
        "vehicle,t_s,east_m,north_m,up_m\n1,0,0,0,0\n1,0,1,0,0\n",
    )
    .unwrap();
    let out = crate::cli::savsim()
        .args(["replay", "--slots"])
        .arg(&slots)
        .arg("nothing.tlog")
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        stderr.contains("slots.csv: line 3: t_s 0: not after"),
        "{stderr}"
    );
    let out = crate::cli::savsim()
        .args(["replay", "--slot-tolerance-m", "2", "nothing.tlog"])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("--slot-tolerance-m needs --slots"));
    // An absurd tolerance is named by its own flag, before the file is read.
    for tolerance in ["0", "-1", "nan", "1e300"] {
        let out = crate::cli::savsim()
            .args(["replay", "--slots"])
            .arg(&slots)
            .arg(format!("--slot-tolerance-m={tolerance}"))
            .arg("nothing.tlog")
            .output()
            .unwrap();
        assert_eq!(out.status.code(), Some(2), "{tolerance}");
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(
            stderr.contains("--slot-tolerance-m"),
            "{tolerance}: {stderr}"
        );
        assert!(!stderr.contains("slots.csv"), "{tolerance}: {stderr}");
    }
}

/// A session judging a show as `savsim replay --well-clear none --near-miss-m 0.5
/// --separation-m 2 --slots SLOTS` does, its events to `events`.
fn show_session(slots: &std::path::Path, events: &std::path::Path) -> Session {
    let origin = Geodetic::new(-35.363261, 149.16523, 584.0);
    let config = CollisionConfig {
        near_miss_m: 0.5,
        ..CollisionConfig::default()
    };
    let mut session =
        Session::new(Some(Arc::new(scene_at(origin, ""))), config, Some(events)).unwrap();
    session.set_approaches(
        Approaches::with_volume(None).with_separation(Some(Separation { minimum_m: 2.0 })),
    );
    let text = std::fs::read_to_string(slots).unwrap();
    session.set_slots(savsim::daa::slots::Slots::parse(&text, 0.5).unwrap());
    session
}

/// What an events file says happened, on the vehicles' own clocks: each event's vehicle,
/// kind, what it concerned and the vehicle's `time_boot_ms` (the receive clock's times differ
/// between a live run and a replay; the vehicles' own do not).
fn happenings(events: &std::path::Path) -> Vec<String> {
    let mut out: Vec<String> = std::fs::read_to_string(events)
        .unwrap()
        .lines()
        .map(|l| {
            let e: serde_json::Value = serde_json::from_str(l).unwrap();
            let about = e
                .get("track")
                .or(e.get("obstacle"))
                .cloned()
                .unwrap_or_default();
            format!(
                "{} {} {} {}",
                e["vehicle"], e["kind"], about, e["time_boot_ms"]
            )
        })
        .collect();
    out.sort();
    out
}

/// The show flown live (its datagrams sent on 127.0.0.1 on their schedule, 33 s) and the
/// same datagrams replayed from a tlog give the same events: every collision, separation and
/// slot event, for the same vehicles, at the same samples of their own clocks. Held 20 of 20
/// here (the debug test binary, 10 runs beside two busy processes and 10 quiet).
#[test]
fn a_show_flown_live_gives_the_replays_events() {
    if !crate::common::have_pymavlink() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let path = |name: &str| dir.path().join(name);
    let fleet = crate::common::root().join("scripts/fleet.py");
    let show = [
        "--show",
        "--vehicles",
        "9",
        "--seconds",
        "34",
        "--altitude-m",
        "5",
    ];
    let tlog = path("show.tlog");
    let mut replay_args = vec!["0"];
    replay_args.extend(show);
    replay_args.extend(["--tlog", tlog.to_str().unwrap(), "--slots-out"]);
    let slots = path("slots.csv");
    replay_args.push(slots.to_str().unwrap());
    crate::common::python(&fleet, &replay_args);
    let mut replayed = show_session(&slots, &path("replayed.jsonl"));
    crate::common::replay_session(&tlog, &mut replayed);

    let runtime = crate::common::runtime();
    let (link, address) = crate::common::udp_link(&runtime);
    let port = address.port().to_string();
    let sender = std::process::Command::new("python3")
        .arg(&fleet)
        .arg(&port)
        .args(show)
        .stdout(std::process::Stdio::null())
        .spawn()
        .unwrap();
    let mut sender = Killed(sender);
    let live = show_session(&slots, &path("live.jsonl"));
    let run = crate::common::run_live(
        &runtime,
        vec![link],
        std::time::Duration::from_secs(40),
        live,
        None,
    );
    assert!(sender.0.wait().unwrap().success());
    let mut live = run.session;
    live.finish().unwrap();
    let positions = |s: &Session| -> u64 { s.world().vehicles().map(|(_, v)| v.positions).sum() };
    assert_eq!(
        positions(&live),
        positions(&replayed),
        "every position taken live"
    );
    let (live_events, replayed_events) = (
        happenings(&path("live.jsonl")),
        happenings(&path("replayed.jsonl")),
    );
    assert!(replayed_events
        .iter()
        .any(|e| e.contains("\"separation_lost\"")));
    assert!(replayed_events.iter().any(|e| e.contains("\"left_slot\"")));
    assert!(replayed_events.iter().any(|e| e.contains("\"collision\"")));
    assert_eq!(live_events, replayed_events);
}

/// A child process killed if the test fails before it ends.
struct Killed(std::process::Child);

impl Drop for Killed {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

/// A summary lists at most `LISTED_PAIRS_MAX` pairs in each list, the closest, and counts
/// them all: 40 vehicles standing at scattered places (every pair at its own distance, all
/// within each other's reach, a separation minimum of 1000 m, small-UAS well clear) make
/// 1,560 pairs (each vehicle's with each other); the 1000 listed in each list are those this
/// test finds nearest from the positions it sent.
#[test]
fn a_summary_lists_the_closest_pairs_and_counts_them_all() {
    use savsim::session::summary::LISTED_PAIRS_MAX;
    let origin = Geodetic::new(47.0, 8.0, 500.0);
    let plane = LocalTangentPlane::new(origin);
    let mut session = Session::new(
        Some(Arc::new(scene_at(origin, ""))),
        CollisionConfig::default(),
        None,
    )
    .unwrap();
    session.set_approaches(
        Approaches::with_volume(Some(savsim::daa::well_clear::Volume::SMALL_UAS))
            .with_separation(Some(Separation { minimum_m: 1000.0 })),
    );
    let mut state = 0x2545_f491_4f6c_dd1d_u64;
    let mut uniform = |span: f64| {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        (state >> 11) as f64 / (1u64 << 53) as f64 * span
    };
    let places: Vec<DVec3> = (0..40)
        .map(|_| DVec3::new(uniform(200.0), uniform(200.0), 20.0 + uniform(20.0)))
        .collect();
    let mut seq = 0u8;
    for t_ms in [1000u32, 1100] {
        for (i, p) in places.iter().enumerate() {
            let frames = position_frames(&plane, i as u8 + 1, &mut seq, t_ms, *p, DVec3::ZERO);
            feed(&mut session, f64::from(t_ms) / 1000.0, &frames);
        }
    }
    let summary = session.summary("test", "scattered");
    // The nearest pairs by the positions sent: each pair listed from both of its vehicles.
    let mut apart: Vec<(f64, usize, usize)> = Vec::new();
    for i in 0..places.len() {
        for j in i + 1..places.len() {
            apart.push(((places[i] - places[j]).length(), i + 1, j + 1));
        }
    }
    apart.sort_by(|a, b| a.0.total_cmp(&b.0));
    let mut nearest: Vec<String> = apart[..LISTED_PAIRS_MAX / 2]
        .iter()
        .flat_map(|&(_, a, b)| [format!("{a} vehicle:{b}"), format!("{b} vehicle:{a}")])
        .collect();
    nearest.sort();
    let names = |list: &serde_json::Value| {
        let mut out: Vec<String> = list
            .as_array()
            .unwrap()
            .iter()
            .map(|p| format!("{} {}", p["vehicle"], p["track"].as_str().unwrap()))
            .collect();
        out.sort();
        out
    };
    assert_eq!(summary["approach_pairs"], 1560);
    assert_eq!(summary["well_clear"]["pairs_lost"], 1560);
    assert_eq!(summary["separation"]["pairs_under"], 1560);
    for list in [
        &summary["approaches"],
        &summary["well_clear"]["pairs"],
        &summary["separation"]["pairs"],
    ] {
        assert_eq!(names(list), nearest);
    }
    // Asked for every pair (`--summary-pairs 0`), it lists them all.
    session.set_summary_pairs(None);
    let summary = session.summary("test", "scattered");
    assert_eq!(summary["approaches"].as_array().unwrap().len(), 1560);
    assert_eq!(
        summary["separation"]["pairs"].as_array().unwrap().len(),
        1560
    );
}

/// An absurd `--summary-pairs` is a usage error naming the flag.
#[test]
fn absurd_summary_pairs_are_usage_errors_naming_the_flag() {
    replay_refuses_naming(
        "--summary-pairs",
        &["-1", "nan", "1.5", "99999999999999999999999", ""],
    );
}
