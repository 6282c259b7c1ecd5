//! `savsim bench`: the flight set is deterministic and does what its descriptions say (checked
//! by the reference, and `exact` equals it), and the command writes a report, JSON and a PNG.

use std::process::Command;

use savsim::bench::flights::flight_set;
use savsim::bench::{collisions, run_samples};
use savsim::collision::events::EventKind;
use savsim::pipeline::{CollisionConfig, Mode, Pipeline};

use crate::common::root;

#[test]
fn the_city_flight_set_is_deterministic_and_its_near_misses_are_near_misses() {
    let scene = savsim::scene::load(&root().join("scenes/city.toml")).unwrap();
    let flights = flight_set(&scene);
    assert!(flights.len() >= 20, "{} flights", flights.len());
    assert_eq!(flights, flight_set(&scene));
    for family in [
        "cross-",
        "low-street",
        "near-miss-",
        "graze-concave-",
        "fast-",
        "traffic-",
    ] {
        assert!(
            flights.iter().any(|f| f.name.starts_with(family)),
            "no {family} flight"
        );
    }
    for rate in [5.0, 10.0, 50.0] {
        assert!(
            flights.iter().any(|f| f.rate_hz == rate),
            "no flight at {rate} Hz"
        );
    }
    // What the descriptions promise: collisions against the reference, near misses as the
    // contact layer reports them (the reference reports collisions only).
    let mut reference = Pipeline::new(
        &scene,
        CollisionConfig {
            mode: Mode::Reference,
            ..CollisionConfig::default()
        },
    );
    let mut exact = Pipeline::new(&scene, CollisionConfig::default());
    for (k, f) in flights.iter().enumerate() {
        let promise_clear = f.name.starts_with("near-miss-")
            || f.name.starts_with("graze-concave-")
            || f.name.ends_with("-above-5m")
            || f.name.ends_with("-2m")
            || f.name == "cross-above-all";
        let promise_hit = f.name == "traffic-a320-collision" || f.name.starts_with("fast-100-thin");
        if !(promise_clear || promise_hit) {
            continue;
        }
        let (_, truth) = run_samples(&mut reference, &scene, k as u16 + 1, &f.samples, &f.traffic);
        let hits = collisions(&truth);
        let (_, events) = run_samples(&mut exact, &scene, k as u16 + 1, &f.samples, &f.traffic);
        let found = collisions(&events);
        assert_eq!(found.len(), hits.len(), "{}: {found:?} vs {hits:?}", f.name);
        for (a, b) in found.iter().zip(&hits) {
            assert!(
                a.0 == b.0 && (a.1 - b.1).abs() <= 1e-3,
                "{}: exact {a:?} against the reference {b:?}",
                f.name
            );
        }
        let near = events
            .iter()
            .filter(|e| matches!(e.kind, EventKind::NearMiss { .. }))
            .count();
        if promise_clear {
            assert!(hits.is_empty(), "{}: {hits:?}", f.name);
            if f.name != "cross-above-all" {
                assert!(near >= 1, "{}: no near miss", f.name);
            }
        } else {
            assert!(!hits.is_empty(), "{}: no collision", f.name);
        }
    }
}

#[test]
fn bench_writes_a_report_json_and_a_chart() {
    let dir = tempfile::tempdir().unwrap();
    let scene = dir.path().join("small.toml");
    // A tower, a gate (concave) and a little terrain: every flight family has something.
    std::fs::write(
        &scene,
        "[origin]\nlat_deg = -35.363261\nlon_deg = 149.16523\nalt_m = 584.0\n\
         [[obstacle]]\nid = \"tower\"\nkind = \"building\"\nshape = { box = [20.0, 20.0, 60.0] }\nposition_enu_m = [40.0, 40.0, 0.0]\n\
         [[obstacle]]\nid = \"gate\"\nkind = \"building\"\nshape = { blocks = [[-15.0, -5.0, 0.0, -9.0, 5.0, 30.0], [9.0, -5.0, 0.0, 15.0, 5.0, 30.0], [-15.0, -5.0, 24.0, 15.0, 5.0, 30.0]] }\nposition_enu_m = [-40.0, -30.0, 0.0]\n\
         [[terrain]]\nid = \"hill\"\nkind = \"mountain\"\ngenerated = { seed = 3, size_m = [600, 600], cell_m = 20, relief_m = 30 }\nposition_enu_m = [-300.0, -300.0, -40.0]\n",
    )
    .unwrap();
    let (json, chart) = (dir.path().join("b.json"), dir.path().join("b.png"));
    let out = Command::new(env!("CARGO_BIN_EXE_savsim"))
        .args(["bench", "--scene"])
        .arg(&scene)
        .args([
            "--modes",
            "box,adaptive,paper",
            "--scale-max",
            "1000",
            "--fleet-max",
            "10",
        ])
        .arg("--json")
        .arg(&json)
        .arg("--chart")
        .arg(&chart)
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout);
    crate::common::assert_ran(&out);
    assert!(
        stdout.contains("| exact |") && stdout.contains("### Goals"),
        "{stdout}"
    );
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    let modes = report["scenes"][0]["modes"].as_array().unwrap();
    let names: Vec<&str> = modes.iter().map(|m| m["mode"].as_str().unwrap()).collect();
    // `adaptive` is the old name of `exact`.
    assert_eq!(names, ["box", "exact", "paper", "reference"]);
    let exact = &modes[1];
    assert_eq!(exact["missed"], 0, "{exact}");
    assert_eq!(exact["false_collisions"], 0, "{exact}");
    assert!(exact["sensing_frames"].as_u64().unwrap() > 0, "{exact}");
    assert!(report["scenes"][0]["flights"].as_array().unwrap().len() >= 15);
    assert_eq!(report["scale"].as_array().unwrap().len(), 4);
    assert_eq!(report["fleets"].as_array().unwrap().len(), 2);
    // The residency run: the tower and the gate as loaded meshes, under the default budget.
    let residency = &report["residency"];
    assert_eq!(residency["mesh_obstacles"], 2, "{residency}");
    assert_eq!(residency["missed"], 0, "{residency}");
    assert_eq!(residency["false_collisions"], 0, "{residency}");
    assert!(residency["collisions"].as_u64().unwrap() > 0, "{residency}");
    assert!(residency["peak_bytes"].as_u64() <= residency["budget_bytes"].as_u64());
    let png = std::fs::read(&chart).unwrap();
    assert_eq!(&png[..8], b"\x89PNG\r\n\x1a\n");
}
