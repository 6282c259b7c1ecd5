//! DAIDALUS's sensor uncertainty mitigation (SUM) in `savsim daa`: the uncertainty columns of a
//! state file, `WCV_TAUMOD_SUM` detectors and their z-scores. On DAIDALUS's own H1_SUM the alert
//! levels are those DaidalusAlerting printed (v2.0.4, commit e0439250: docs/daa.md), and with
//! `SAVSIM_DAIDALUS` every cell of every SUM scenario is compared with DAIDALUS's.

use std::path::{Path, PathBuf};
use std::process::Command;

use crate::common::{root, shared_fixtures};

/// `savsim daa` on `scenario` with `conf`: its CSV rows (after the header and units lines).
fn savsim_daa(scenario: &Path, conf: &Path) -> Vec<Vec<String>> {
    let out = crate::cli::savsim()
        .arg("daa")
        .arg("--conf")
        .arg(conf)
        .arg(scenario)
        .output()
        .unwrap();
    crate::common::assert_ran(&out);
    rows(&String::from_utf8(out.stdout).unwrap())
}

fn rows(csv: &str) -> Vec<Vec<String>> {
    csv.lines()
        .skip(2)
        .map(|l| l.split(',').map(|c| c.trim().to_string()).collect())
        .collect()
}

/// H1_SUM's alert levels as DaidalusAlerting printed them, as (from, to, level) spans of
/// whole seconds: under DO_365B_SUM.conf and under DO_365B_no_SUM.conf.
const H1_SUM_LEVELS: [(u32, u32, &str); 4] = [
    (27, 115, "0"),
    (116, 141, "2"),
    (142, 206, "3"),
    (207, 229, "0"),
];
const H1_NO_SUM_LEVELS: [(u32, u32, &str); 4] = [
    (27, 111, "0"),
    (112, 141, "2"),
    (142, 205, "3"),
    (206, 229, "0"),
];

#[test]
fn h1_sum_raises_the_levels_daidalus_raises_with_and_without_sum() {
    let Some(shared) = shared_fixtures() else {
        return;
    };
    let daa = shared.join("daa");
    for (conf, spans) in [
        ("DO_365B_SUM.conf", H1_SUM_LEVELS),
        ("DO_365B_no_SUM.conf", H1_NO_SUM_LEVELS),
    ] {
        let rows = savsim_daa(&daa.join("H1_SUM.daa"), &daa.join(conf));
        assert_eq!(rows.len(), 203, "{conf}");
        for r in &rows {
            let t: f64 = r[0].parse().unwrap();
            let want = spans
                .iter()
                .find(|(from, to, _)| (f64::from(*from)..=f64::from(*to)).contains(&t))
                .map(|s| s.2)
                .unwrap();
            assert_eq!(r[4], want, "{conf} at {t} s");
        }
    }
}

/// The errors of sensor uncertainty mitigation, worked by hand from H1_SUM's first row: each
/// aircraft 37.5 m and 75.5 m of position error, 1.25 m/s of velocity error each.
#[test]
fn relative_errors_add_the_aircrafts_and_scale_by_the_z_scores() {
    use savsim::daa::sum::{Uncertainty, ZScores};
    let z = ZScores {
        h_pos: 1.5,
        h_vel_min: 0.5,
        h_vel_max: 1.0,
        h_vel_distance_m: 9260.0,
        v_pos: 0.75,
        v_vel: 1.5,
    };
    let own = Uncertainty {
        s_ew_m: 37.5,
        s_ns_m: 37.5,
        sz_m: 30.48,
        v_ew_mps: 1.25,
        v_ns_mps: 1.25,
        vz_mps: 0.03175,
        ..Uncertainty::default()
    };
    // A correlated intruder: covariance -30^2 with 75.6 and 60 m: the semi-major axis is the
    // square root of the larger eigenvalue of [[75.6^2, -900], [-900, 60^2]].
    let intruder = Uncertainty {
        s_ew_m: 75.6,
        s_ns_m: 60.0,
        s_en_m: -30.0,
        ..own
    };
    let (a, b, c) = (75.6f64.powi(2), 60f64.powi(2), -900.0f64);
    let lambda = (a + b) / 2.0 + (((a - b) / 2.0).powi(2) + c * c).sqrt();
    assert!((intruder.position_error_m() - lambda.sqrt()).abs() < 1e-9);
    let far = z.errors(&own, &intruder, 20_000.0);
    assert!((far.s_m - 1.5 * (37.5 + lambda.sqrt())).abs() < 1e-9);
    assert!(
        (far.v_mps - 0.5 * (1.25 + 1.25)).abs() < 1e-12,
        "far: the minimum z"
    );
    assert!((far.sz_m - 0.75 * 2.0 * 30.48).abs() < 1e-12);
    assert!((far.vz_mps - 1.5 * 2.0 * 0.03175).abs() < 1e-12);
    // At a range of s_err: r = 0, the maximum z.
    let near = z.errors(&own, &intruder, far.s_m);
    assert!((near.v_mps - 1.0 * 2.5).abs() < 1e-12);
}

#[test]
fn a_detectors_own_z_score_is_refused_by_name() {
    let conf = "alerters = A\nA_alert_1_detector = d\nA_alert_1_alerting_time = 30 [s]\n\
        A_d_WCV_DTHR = 600 [m]\nA_d_WCV_ZTHR = 100 [m]\nA_d_WCV_TTHR = 0 [s]\nA_d_WCV_TCOA = 0 [s]\n\
        A_load_core_detection_d = gov.nasa.larcfm.ACCoRD.WCV_TAUMOD_SUM\nA_d_h_pos_z_score = 3.0\n";
    let err = savsim::daa::conf::Config::parse(conf)
        .unwrap_err()
        .to_string();
    assert!(err.contains("A_d_h_pos_z_score"), "{err}");
    let ok = conf.replace("A_d_h_pos_z_score", "h_pos_z_score");
    let c = savsim::daa::conf::Config::parse(&ok).unwrap();
    assert!(c.alerters[0].levels[0].sum);
    assert_eq!(c.z_scores.h_pos, 3.0);
}

/// The script that runs DaidalusAlerting, from `SAVSIM_DAIDALUS`.
fn daidalus() -> Option<PathBuf> {
    let p = std::env::var_os("SAVSIM_DAIDALUS").map(PathBuf::from);
    if p.is_none() {
        eprintln!("SKIP: SAVSIM_DAIDALUS is not set (a script running DaidalusAlerting)");
    }
    p
}

#[test]
fn savsim_daa_matches_daidalus_with_sum_cell_by_cell() {
    let (Some(script), Some(shared)) = (daidalus(), shared_fixtures()) else {
        return;
    };
    let confs = shared.join("daa");
    let mut scenarios: Vec<PathBuf> = std::fs::read_dir(root().join("tests/fixtures/daa/sum"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .collect();
    scenarios.sort();
    scenarios.push(confs.join("H1_SUM.daa"));
    let dir = tempfile::tempdir().unwrap();
    for scenario in &scenarios {
        for conf in ["DO_365B_SUM.conf", "DO_365B_no_SUM.conf"] {
            let theirs = dir.path().join("theirs.csv");
            let status = Command::new(&script)
                .arg("--conf")
                .arg(confs.join(conf))
                .arg("--out")
                .arg(&theirs)
                .arg(scenario)
                .status()
                .unwrap();
            assert!(status.success());
            let theirs = rows(&std::fs::read_to_string(&theirs).unwrap());
            let ours = savsim_daa(scenario, &confs.join(conf));
            assert_eq!(ours.len(), theirs.len(), "{}", scenario.display());
            for (a, b) in ours.iter().zip(&theirs) {
                assert_eq!(
                    a[..5],
                    b[..5],
                    "{} {conf}: time, names, alerter, level",
                    scenario.display()
                );
                for (x, y) in a.iter().zip(b).skip(5) {
                    let same = x == y
                        || x.parse::<f64>()
                            .ok()
                            .zip(y.parse::<f64>().ok())
                            .is_some_and(|(p, q)| (p - q).abs() <= 1.01e-6 * p.abs().max(1.0));
                    assert!(
                        same,
                        "{} {conf} at {}: {x} vs {y}",
                        scenario.display(),
                        a[0]
                    );
                }
            }
        }
    }
}
