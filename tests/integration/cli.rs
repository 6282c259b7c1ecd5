//! The commands README.md gives, run as a user runs them.

use std::process::Command;

use crate::common::root;

/// The savsim binary, run from the repository root.
pub(crate) fn savsim() -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_savsim"));
    c.current_dir(root());
    c
}

#[test]
fn demo_replays_the_bundled_flight_over_the_bundled_city() {
    let dir = tempfile::tempdir().unwrap();
    let summary = dir.path().join("summary.json");
    let events = dir.path().join("events.jsonl");
    let out = savsim()
        .args(["demo", "--summary-json"])
        .arg(&summary)
        .arg("--events")
        .arg(&events)
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{stdout}{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(stdout.contains("COLLISION"), "{stdout}");
    let s: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&summary).unwrap()).unwrap();
    assert_eq!(s["ingest"]["messages"]["GLOBAL_POSITION_INT"], 2100);
    assert_eq!(s["ingest"]["rejected"]["no_fix"], 75);
    assert_eq!(s["collision"]["ticks"], 2025);
    assert_eq!(s["collision"]["collisions"], 1);
    // Every event line is a JSON object with the documented fields.
    let text = std::fs::read_to_string(&events).unwrap();
    let mut kinds = std::collections::BTreeSet::new();
    for line in text.lines() {
        let e: serde_json::Value = serde_json::from_str(line).unwrap();
        assert!(
            e["t"].is_f64() && e["time_boot_ms"].is_u64() && e["vehicle"] == 1,
            "{line}"
        );
        kinds.insert(e["kind"].as_str().unwrap().to_owned());
    }
    for k in ["collision", "collider_swap", "near_miss"] {
        assert!(kinds.contains(k), "{kinds:?}");
    }
}

#[test]
fn colliders_never_flap_faster_than_the_hold_time() {
    let dir = tempfile::tempdir().unwrap();
    let events = dir.path().join("events.jsonl");
    let out = savsim()
        .args(["demo", "--events"])
        .arg(&events)
        .output()
        .unwrap();
    assert!(out.status.success());
    let mut last_upgrade: std::collections::HashMap<String, f64> = Default::default();
    for line in std::fs::read_to_string(&events).unwrap().lines() {
        let e: serde_json::Value = serde_json::from_str(line).unwrap();
        if e["kind"] != "collider_swap" {
            continue;
        }
        let id = e["obstacle"].as_str().unwrap().to_owned();
        let t = e["t"].as_f64().unwrap();
        if e["from"] == "mesh" {
            let up = last_upgrade.get(&id).copied().unwrap_or(f64::NEG_INFINITY);
            assert!(
                t - up >= 2.0,
                "{id} lost its mesh {} s after getting it",
                t - up
            );
        }
        if e["to"] == "mesh" {
            last_upgrade.insert(id, t);
        }
    }
}

/// `--until-s` ends a replay that many seconds after the first message: before the demo's
/// collision (+91.69 s) there is none; a negative or non-number time is a usage error.
#[test]
fn until_s_cuts_the_replay_on_the_reports_clock() {
    let dir = tempfile::tempdir().unwrap();
    let summary = dir.path().join("s.json");
    let cut = |until: &str| {
        savsim()
            .args(["demo", "--until-s", until, "--summary-json"])
            .arg(&summary)
            .output()
            .unwrap()
    };
    let out = cut("91.5");
    crate::common::assert_ran(&out);
    let s: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&summary).unwrap()).unwrap();
    let ticks = s["collision"]["ticks"].as_u64().unwrap();
    assert!(ticks > 100 && ticks < 2025, "{ticks} ticks");
    assert_eq!(s["collision"]["collisions"], 0);
    let out = cut("92");
    crate::common::assert_ran(&out);
    assert!(String::from_utf8_lossy(&out.stdout).contains("COLLISION  vehicle 1 with b2150"));
    for bad in ["-1", "NaN"] {
        let out = cut(bad);
        assert_eq!(out.status.code(), Some(2), "--until-s {bad}");
        assert!(String::from_utf8_lossy(&out.stderr).contains("--until-s"));
    }
}

#[test]
fn bad_input_gets_a_clear_message_and_exit_code_2() {
    let dir = tempfile::tempdir().unwrap();
    let scene = dir.path().join("broken.toml");
    std::fs::write(&scene, "[origin]\nlat_deg = 1.0\nlon_deg = 2.0\n").unwrap();
    let out = savsim()
        .args([
            "replay",
            "scenes/flights/copter_square_10ms.tlog",
            "--scene",
        ])
        .arg(&scene)
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("broken.toml") && err.contains("alt_m"),
        "{err}"
    );
    let out = savsim()
        .args(["live", "--connect", "serial:/dev/null"])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
    let out = savsim()
        .args(["replay", "/nonexistent.tlog"])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&out.stderr).contains("/nonexistent.tlog"));
}

#[test]
fn scene_info_describes_the_city() {
    let out = savsim()
        .args(["scene", "info", "scenes/city.toml"])
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success());
    assert!(
        stdout.contains("building") && stdout.contains("triangles") && stdout.contains("lat"),
        "{stdout}"
    );
}

#[test]
fn thresholds_and_the_ahp_matrix_come_from_the_command_line() {
    let dir = tempfile::tempdir().unwrap();
    let summary = dir.path().join("s.json");
    let out = savsim()
        .args([
            "demo",
            "--ahp-matrix",
            "1,2,4,1/2,1,2,1/4,1/2,1",
            "--mesh-beta",
            "1000",
            "--summary-json",
        ])
        .arg(&summary)
        .output()
        .unwrap();
    crate::common::assert_ran(&out);
    let s: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&summary).unwrap()).unwrap();
    let w = &s["collision"]["ahp"]["w"];
    assert!((w[0].as_f64().unwrap() - 4.0 / 7.0).abs() < 1e-9, "{w}");
    assert!(s["collision"]["ahp"]["cr"].as_f64().unwrap().abs() < 1e-9);
    let out = savsim()
        .args(["demo", "--ahp-matrix", "1,2,3"])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("nine numbers"));
}
