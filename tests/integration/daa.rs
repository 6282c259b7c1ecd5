//! Detect and avoid: well clear and alerting. The formulas against values worked by hand from
//! DO-365's definitions (in this file's comments); `savsim daa`'s CSV against hand values;
//! losses of well clear in batch rows and events; the MIT LL encounter model's sampler against
//! its networks, and model encounters' miss distances; and, when `SAVSIM_DAIDALUS` names a script that runs
//! DAIDALUS's `DaidalusAlerting` (docs/daa.md says how to build one) and ../shared/fixtures/daa
//! holds DAIDALUS's configurations, parity cell by cell on DAIDALUS's H1 scenario and savsim's
//! own (tests/fixtures/daa).

use std::path::{Path, PathBuf};
use std::process::Command;

use glam::DVec3;
use savsim::daa::alerting::{Conflict, Filter};
use savsim::daa::conf::Config;
use savsim::daa::well_clear::{Relative, Volume};

use crate::common::{root, shared_fixtures};

fn rel(s: [f64; 3], v: [f64; 3]) -> Relative {
    Relative {
        s_m: DVec3::from(s),
        v_mps: DVec3::from(v),
    }
}

#[test]
fn the_taumod_entry_is_the_root_worked_by_hand() {
    // Head on, 5000 m apart, closing at 100 m/s; DTHR 600 m, TTHR 35 s. With x the range,
    // tau_mod = (x^2 - 600^2) / (100 x) = 35 gives x^2 - 3500 x - 360000 = 0, x = 3600 m:
    // 14 s from now. Leaving the 600 m circle: x = -600, t = 56 s.
    let v = Volume {
        dthr_m: 600.0,
        zthr_m: 100.0,
        tthr_s: 35.0,
        tcoa_s: 0.0,
    };
    let r = rel([5000.0, 0.0, 0.0], [-100.0, 0.0, 0.0]);
    let (t_in, t_out) = v.interval(&r, 0.0, 180.0).unwrap();
    assert!((t_in - 14.0).abs() < 1e-9, "{t_in}");
    assert!((t_out - 56.0).abs() < 1e-9, "{t_out}");
    // A miss distance of 601 m: never.
    let r = rel([5000.0, 601.0, 0.0], [-100.0, 0.0, 0.0]);
    assert_eq!(v.interval(&r, 0.0, 180.0), None);
    // Within the lookahead only: a 10 s lookahead ends before 14 s.
    let r = rel([5000.0, 0.0, 0.0], [-100.0, 0.0, 0.0]);
    assert_eq!(v.interval(&r, 0.0, 10.0), None);
}

#[test]
fn the_tcoa_entry_is_worked_by_hand() {
    // 300 m above, closing vertically at 10 m/s, level horizontally inside DTHR; ZTHR 100 m,
    // TCOA 20 s: co-altitude at 30 s, so violated from 30 - 20 = 10 s (before the 100 m band,
    // entered at 20 s) to 40 s (leaving the band below).
    let v = Volume {
        dthr_m: 600.0,
        zthr_m: 100.0,
        tthr_s: 0.0,
        tcoa_s: 20.0,
    };
    let r = rel([100.0, 0.0, 300.0], [0.0, 0.0, -10.0]);
    let (t_in, t_out) = v.interval(&r, 0.0, 180.0).unwrap();
    assert!(
        (t_in - 10.0).abs() < 1e-9 && (t_out - 40.0).abs() < 1e-9,
        "{t_in} {t_out}"
    );
    // Diverging vertically, 300 m apart: never.
    let r = rel([100.0, 0.0, 300.0], [0.0, 0.0, 10.0]);
    assert!(!v.violated(&r) && v.interval(&r, 0.0, 180.0).is_none());
}

#[test]
fn miss_distances_and_times_are_worked_by_hand() {
    // s = (3000, 400), v = (-100, 0): tcpa = 30 s, dcpa = 400 m; HMD within 20 s: |(1000, 400)|.
    let r = rel([3000.0, 400.0, 50.0], [-100.0, 0.0, -1.0]);
    assert!((r.tcpa_s() - 30.0).abs() < 1e-12 && (r.dcpa_m() - 400.0).abs() < 1e-9);
    assert!((r.hmd_m(20.0) - 1000f64.hypot(400.0)).abs() < 1e-9);
    // Vertically: co-altitude at 50 s; VMD within 20 s is 30 m, within 60 s is 0.
    assert!((r.vmd_m(20.0) - 30.0).abs() < 1e-12 && r.vmd_m(60.0) == 0.0);
    assert_eq!(r.tcoa_s(), Some(50.0));
    // tau_mod for DTHR 1000 m: (1000^2 - 3000^2 - 400^2) / (-300000).
    let expect = (1e6 - 9e6 - 160000.0) / -300000.0;
    assert!((r.tau_mod_s(1000.0).unwrap() - expect).abs() < 1e-12);
}

#[test]
fn alert_levels_follow_the_alerting_times() {
    // One level, a 600 m cylinder, alerting time 20 s, early 30 s: at 100 m/s closing from
    // 4000 m the violation starts 34 s ahead: no alert; from 2500 m, 19 s: alert.
    let conf = "alerters = A\nA_alert_1_detector = d\nA_alert_1_alerting_time = 20 [s]\n\
        A_alert_1_early_alerting_time = 30 [s]\nA_alert_1_region = NEAR\n\
        A_d_WCV_DTHR = 600 [m]\nA_d_WCV_ZTHR = 100 [m]\nA_d_WCV_TTHR = 0 [s]\n\
        A_d_WCV_TCOA = 0 [s]\nA_load_core_detection_d = gov.nasa.larcfm.ACCoRD.WCV_TAUMOD\n";
    let c = Config::parse(conf).unwrap();
    let alerter = &c.alerters[0];
    let at = |x: f64| rel([x, 0.0, 0.0], [-100.0, 0.0, 0.0]);
    assert_eq!(alerter.raw_level(&at(4000.0), 180.0, None), 0);
    assert_eq!(alerter.raw_level(&at(2500.0), 180.0, None), 1);
    // Already alerting: held while the violation is within the early alerting time (29 s).
    assert_eq!(alerter.raw_level(&at(3500.0), 180.0, Some(1)), 1);
    assert_eq!(alerter.raw_level(&at(3500.0), 180.0, None), 0);
    let c0 = Conflict::of(&alerter.levels[0].volume, &at(2500.0), 180.0);
    assert!((c0.time_in_s - 19.0).abs() < 1e-9);
}

#[test]
fn the_filter_resets_after_the_hysteresis_time() {
    // M of N off; hysteresis 5 s, persistence 4 s: level 2 raised at t = 0 is held to 3 s, and
    // after a 6 s silence the filter starts afresh.
    let mut f = Filter::new(5.0, 4.0, 0, 0);
    assert_eq!(f.step(2, 0.0), 2);
    assert_eq!(f.step(0, 3.0), 2);
    assert_eq!(f.step(0, 4.0), 0);
    assert_eq!(f.step(1, 10.0), 1);
    assert_eq!(f.previous(10.0), None);
    assert_eq!(f.previous(11.0), Some(1));
}

#[test]
fn bad_configurations_and_state_files_are_clear_errors() {
    use savsim::daa::scenario::parse;
    let bad = [
        ("no alerters", "lookahead_time = 180 [s]\n"),
        ("a line without =", "alerters = A\nnonsense\n"),
        (
            "a detector savsim lacks",
            "alerters = A\nA_alert_1_detector = d\nA_load_core_detection_d = gov.nasa.larcfm.ACCoRD.TCAS3D\n",
        ),
        (
            "a negative threshold",
            "alerters = A\nA_alert_1_detector = d\nA_alert_1_alerting_time = 20 [s]\nA_d_WCV_DTHR = -1 [m]\nA_d_WCV_ZTHR = 1 [m]\nA_d_WCV_TTHR = 0 [s]\nA_d_WCV_TCOA = 0 [s]\nA_load_core_detection_d = WCV_TAUMOD\n",
        ),
    ];
    for (what, text) in bad {
        assert!(Config::parse(text).is_err(), "{what}");
    }
    for (what, text) in [
        ("empty", ""),
        ("no velocity", "name sx sy sz time\na 0 0 0 0\n"),
        (
            "unknown unit",
            "name sx sy sz vx vy vz time\n[none] [parsec] [m] [m] [m/s] [m/s] [m/s] [s]\n",
        ),
        (
            "not a number",
            "name sx sy sz vx vy vz time\na x 0 0 0 0 0 0\n",
        ),
        ("short row", "name sx sy sz vx vy vz time\na 0 0\n"),
        (
            "latitude 100",
            "name lat lon alt vx vy vz time\na 100 0 0 0 0 0 0\n",
        ),
        (
            "a huge number",
            "name sx sy sz vx vy vz time\na 1e300 0 0 0 0 0 0\n",
        ),
    ] {
        let e = parse(text).unwrap_err();
        assert!(!e.to_string().is_empty(), "{what}");
    }
}

/// `savsim daa`'s output as its cells: (header, units, rows of cells).
fn cells(csv: &str) -> (Vec<String>, Vec<String>, Vec<Vec<String>>) {
    let split = |l: &str| {
        l.split(',')
            .map(|c| c.trim().to_string())
            .collect::<Vec<_>>()
    };
    let mut lines = csv.lines();
    let header = split(lines.next().unwrap());
    let units = split(lines.next().unwrap());
    (header, units, lines.map(split).collect())
}

fn savsim_daa(scenario: &Path, conf: &Path) -> String {
    let out = Command::new(env!("CARGO_BIN_EXE_savsim"))
        .arg("daa")
        .arg(scenario)
        .arg("--conf")
        .arg(conf)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8(out.stdout).unwrap()
}

#[test]
fn savsim_daa_writes_daidalus_columns_and_units_with_hand_values() {
    let dir = tempfile::tempdir().unwrap();
    let conf = dir.path().join("one.conf");
    std::fs::write(
        &conf,
        "lookahead_time = 180 [s]\nmin_horizontal_recovery = 0.66 [nmi]\n\
         min_vertical_recovery = 450 [ft]\nstep_hs = 5 [knot]\nstep_vs = 100 [fpm]\n\
         alerters = A\nA_alert_1_detector = d\nA_alert_1_alerting_time = 30 [s]\n\
         A_alert_1_region = MID\nA_d_WCV_DTHR = 1 [nmi]\nA_d_WCV_ZTHR = 500 [ft]\n\
         A_d_WCV_TTHR = 0 [s]\nA_d_WCV_TCOA = 0 [s]\n\
         A_load_core_detection_d = gov.nasa.larcfm.ACCoRD.WCV_TAUMOD\n",
    )
    .unwrap();
    // Euclidean, DAIDALUS's default units (nmi, ft, knot, fpm): 3 nmi apart head on at 360
    // knots closing (0.1 nmi/s): inside 1 nmi 20 s from now, alert (within 30 s); 1000 ft
    // apart vertically and closing at 3000 fpm (50 ft/s): inside 500 ft in 10 s.
    let daa = dir.path().join("one.daa");
    std::fs::write(
        &daa,
        "NAME sx sy sz vx vy vz time\nown 0 0 1000 180 0 -1500 0\nintr 3 0 0 -180 0 1500 0\n",
    )
    .unwrap();
    let (header, units, rows) = cells(&savsim_daa(&daa, &conf));
    assert_eq!(header[0], "Time");
    assert_eq!(header.len(), 16);
    assert_eq!(header[5], "Time to Volume of Alert(1)");
    assert_eq!(header[15], "Projected TAUMOD (WCV*)");
    assert_eq!(units[6], "[nmi]");
    assert_eq!(units[9], "[fpm]");
    let r = &rows[0];
    assert_eq!(
        (r[0].as_str(), r[1].as_str(), r[2].as_str()),
        ("0.0", "own", "intr")
    );
    assert_eq!((r[3].as_str(), r[4].as_str()), ("1", "1"));
    assert_eq!(r[5], "20.0"); // time to volume
    assert_eq!(r[6], "3.0"); // horizontal separation, nmi
    assert_eq!(r[7], "1000.0"); // vertical separation, ft
    assert_eq!(r[8], "360.0"); // horizontal closure, knot
    assert_eq!(r[9], "3000.0"); // vertical closure, fpm
    assert_eq!(r[10], "0.0"); // HMD: head on
    assert_eq!(r[11], "0.0"); // VMD: co-altitude at 20 s
    assert_eq!(r[12], "30.0"); // TCPA
    assert_eq!(r[13], "0.0"); // DCPA
    assert_eq!(r[14], "20.0"); // TCOA
                               // tau_mod for DTHR 1 nmi: (1 - 9) nmi^2 / (3 nmi * -0.1 nmi/s) = 26.666667 s.
    assert_eq!(r[15], "26.666667");
}

/// The script that runs DaidalusAlerting, from `SAVSIM_DAIDALUS`.
fn daidalus() -> Option<PathBuf> {
    match std::env::var_os("SAVSIM_DAIDALUS") {
        Some(p) => Some(PathBuf::from(p)),
        None => {
            eprintln!("SKIP: SAVSIM_DAIDALUS is not set (a script running DaidalusAlerting)");
            None
        }
    }
}

/// How two CSVs differ: rows, level mismatches, the largest difference of any numeric cell,
/// and the cells that differ by more than the printed precision.
struct Diff {
    rows: usize,
    level_mismatches: usize,
    max_abs: f64,
    beyond: Vec<String>,
}

fn compare(ours: &str, theirs: &str) -> Diff {
    let (h1, u1, r1) = cells(ours);
    let (h2, u2, r2) = cells(theirs);
    assert_eq!(h1, h2, "headers");
    assert_eq!(u1, u2, "units");
    assert_eq!(r1.len(), r2.len(), "rows");
    let mut diff = Diff {
        rows: r1.len(),
        level_mismatches: 0,
        max_abs: 0.0,
        beyond: Vec::new(),
    };
    for (k, (a, b)) in r1.iter().zip(&r2).enumerate() {
        assert_eq!(a[..4], b[..4], "row {k}: time, names, alerter");
        if a[4] != b[4] {
            diff.level_mismatches += 1;
            diff.beyond
                .push(format!("row {k} level {} vs {}", a[4], b[4]));
        }
        for (c, (x, y)) in a.iter().zip(b).enumerate().skip(5) {
            let (px, py) = (x.parse::<f64>(), y.parse::<f64>());
            match (px, py) {
                (Ok(x), Ok(y)) if x.is_finite() && y.is_finite() => {
                    let d = (x - y).abs();
                    diff.max_abs = diff.max_abs.max(d);
                    // Within the printed precision: one unit of the 6th decimal, relative to
                    // the magnitude for large values.
                    if d > 1.01e-6 * x.abs().max(1.0) {
                        diff.beyond.push(format!("row {k} {}: {x} vs {y}", h1[c]));
                    }
                }
                _ if x == y => {}
                _ => diff
                    .beyond
                    .push(format!("row {k} {}: {x:?} vs {y:?}", h1[c])),
            }
        }
    }
    diff
}

#[test]
fn savsim_daa_matches_daidalus_cell_by_cell() {
    let (Some(script), Some(shared)) = (daidalus(), shared_fixtures()) else {
        return;
    };
    let confs = shared.join("daa");
    if !confs.join("DO_365B_no_SUM.conf").exists() {
        eprintln!("SKIP: ../shared/fixtures/daa has no DAIDALUS configurations");
        return;
    }
    let mut scenarios: Vec<PathBuf> = std::fs::read_dir(root().join("tests/fixtures/daa"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "daa"))
        .collect();
    scenarios.sort();
    scenarios.push(confs.join("H1.daa"));
    let dir = tempfile::tempdir().unwrap();
    let mut failures = Vec::new();
    for scenario in &scenarios {
        for conf in [
            "DO_365B_no_SUM",
            "DO_365B_no_SUM_Phase_II",
            "DO_365B_no_SUM_Non_Coop",
            "sUAS_2000ft_250ft",
        ] {
            let conf_path = confs.join(format!("{conf}.conf"));
            let theirs_path = dir.path().join("theirs.csv");
            let status = Command::new(&script)
                .arg("--conf")
                .arg(&conf_path)
                .arg("--out")
                .arg(&theirs_path)
                .arg(scenario)
                .stderr(std::process::Stdio::null())
                .status()
                .unwrap();
            assert!(status.success(), "DAIDALUS on {}", scenario.display());
            let theirs = std::fs::read_to_string(&theirs_path).unwrap();
            let ours = savsim_daa(scenario, &conf_path);
            let d = compare(&ours, &theirs);
            let name = scenario.file_stem().unwrap().to_string_lossy();
            eprintln!(
                "| {name} | {conf} | {} | {} | {:.1e} | {} |",
                d.rows,
                d.level_mismatches,
                d.max_abs,
                d.beyond.len()
            );
            if !d.beyond.is_empty() {
                failures.push(format!(
                    "{name} {conf}: {:?}",
                    &d.beyond[..d.beyond.len().min(5)]
                ));
            }
        }
    }
    assert!(failures.is_empty(), "{failures:#?}");
}

/// `savsim batch MANIFEST --out OUT` on one job, checked to have run.
pub(crate) fn batch_on_one_job(manifest: &Path, out: &Path) -> std::process::Output {
    let run = crate::batch::savsim(&[
        "batch",
        manifest.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--jobs",
        "1",
        "--no-progress",
    ]);
    crate::common::assert_ran(&run);
    run
}

/// The rows of the one shard a one-shard run wrote to `out`.
pub(crate) fn only_shard(out: &Path) -> arrow_array::RecordBatch {
    crate::batch::read(&out.join("part-00000-of-00001.parquet"))
}

#[test]
fn batch_rows_carry_the_loss_of_well_clear_and_summarize_gives_the_ratios() {
    use arrow_array::{Array, BooleanArray, Float64Array};
    let dir = tempfile::tempdir().unwrap();
    // Own east at 20 m/s along y = 0, 100 m up; the intruder west at 20 m/s, `offset_m` north,
    // level. Closing at 40 m/s from 2000 m: with the small-UAS volume (DTHR 609.6 m) and a
    // 100 m offset, lost when dx = sqrt(609.6^2 - 100^2) = 601.34 m, at (2000 - 601.34) / 40
    // = 34.966 s, for 2 * 601.34 / 40 = 30.067 s (within the 100 s flown). With 50 m offset:
    // also an NMAC.
    let own = "0 -1000 0 100; 100 1000 0 100";
    let intruder = |offset_m: f64| format!("0 1000 {offset_m} 100; 100 -1000 {offset_m} 100");
    let mut csv = String::from("id,own,intruder,duration_s,variant,pair,w,well_clear\n");
    // Four pairs: nominal always an NMAC (50 m); mitigated an NMAC once, a LoWC without
    // NMAC once (300 m), clear twice (1000 m). Weights 1, 2, 1, 1.
    for (k, (mitigated_m, w)) in [(50.0, 1.0), (300.0, 2.0), (1000.0, 1.0), (1000.0, 1.0)]
        .into_iter()
        .enumerate()
    {
        csv += &format!("n{k},{own},{},100,nominal,p{k},{w},\n", intruder(50.0));
        csv += &format!(
            "m{k},{own},{},100,mitigated,p{k},{w},\n",
            intruder(mitigated_m)
        );
    }
    csv += &format!("hand,{own},{},100,,,,\n", intruder(100.0));
    // Well clear not judged: no loss reported, the NMAC still is.
    csv += &format!("off,{own},{},100,,,,none\n", intruder(100.0));
    let manifest = dir.path().join("m.csv");
    std::fs::write(&manifest, csv).unwrap();
    let out = dir.path().join("out");
    batch_on_one_job(&manifest, &out);
    let batch = only_shard(&out);
    let lowc = crate::batch::column::<BooleanArray>(&batch, "lowc");
    let first = crate::batch::column::<Float64Array>(&batch, "lowc_first_t_s");
    let duration = crate::batch::column::<Float64Array>(&batch, "lowc_duration_s");
    let hand = batch.num_rows() - 2;
    let off = batch.num_rows() - 1;
    assert!(!lowc.value(off) && first.is_null(off));
    assert!(crate::batch::column::<BooleanArray>(&batch, "nmac").value(off));
    let dx = (609.6f64.powi(2) - 100.0f64.powi(2)).sqrt();
    assert!(lowc.value(hand));
    assert!(
        (first.value(hand) - (2000.0 - dx) / 40.0).abs() < 1e-6,
        "{}",
        first.value(hand)
    );
    assert!(
        (duration.value(hand) - 2.0 * dx / 40.0).abs() < 1e-6,
        "{}",
        duration.value(hand)
    );
    let least = crate::batch::column::<Float64Array>(&batch, "lowc_min_horizontal_m");
    assert!(
        (least.value(hand) - 100.0).abs() < 1e-6,
        "{}",
        least.value(hand)
    );
    // The mitigated pass 1000 m off never loses well clear.
    assert!(!lowc.value(5));
    let summary = Command::new(env!("CARGO_BIN_EXE_savsim"))
        .args(["batch", "summarize", out.to_str().unwrap(), "--json"])
        .output()
        .unwrap();
    assert!(
        summary.status.success(),
        "{}",
        String::from_utf8_lossy(&summary.stderr)
    );
    let json: serde_json::Value = serde_json::from_slice(&summary.stdout).unwrap();
    let ratio = &json["ratios"][0];
    assert_eq!(ratio["variant"], "mitigated");
    assert_eq!(ratio["pairs"], 4);
    // NMAC: mitigated 1 (w 1) of nominal 4 (w 5): 0.2; LoWC: 1 + 2 of 5: 0.6.
    assert!((ratio["nmac_ratio"]["value"].as_f64().unwrap() - 0.2).abs() < 1e-12);
    assert!((ratio["lowc_ratio"]["value"].as_f64().unwrap() - 0.6).abs() < 1e-12);
    let low = ratio["nmac_ratio"]["low"].as_f64();
    let high = ratio["nmac_ratio"]["high"].as_f64();
    assert!(
        low.zip(high).is_some_and(|(l, h)| l <= 0.2 && 0.2 <= h),
        "{ratio}"
    );
    // The report's table holds the rows that did not pass: the four nominal NMACs, m0's, and
    // the two unpaired rows' (100 m off: an NMAC).
    let report = Command::new(env!("CARGO_BIN_EXE_savsim"))
        .args(["batch", "report", out.to_str().unwrap()])
        .output()
        .unwrap();
    crate::common::assert_ran(&report);
    let page = std::fs::read_to_string(out.join("report.html")).unwrap();
    assert!(
        page.contains("The 7 of 10 rows that did not pass"),
        "{page}"
    );
    assert_eq!(page.matches("<tr class=\"nmac\">").count(), 7);
    assert_eq!(page.matches("<tr class=").count(), 7);
}

#[test]
fn a_daa_file_is_a_batch_row_with_every_intruder() {
    use arrow_array::{Array, BooleanArray, ListArray, StringArray, StructArray};
    let dir = tempfile::tempdir().unwrap();
    let daa = root().join("tests/fixtures/daa/three_aircraft.daa");
    let manifest = dir.path().join("m.csv");
    std::fs::write(
        &manifest,
        format!("id,daa,well_clear\nthree,{},small-uas\n", daa.display()),
    )
    .unwrap();
    let out = dir.path().join("out");
    batch_on_one_job(&manifest, &out);
    let batch = only_shard(&out);
    let error = crate::batch::column::<StringArray>(&batch, "error");
    assert!(error.is_null(0), "{}", error.value(0));
    let approaches = crate::batch::column::<ListArray>(&batch, "approaches").value(0);
    let approaches = approaches.as_any().downcast_ref::<StructArray>().unwrap();
    let tracks = approaches
        .column_by_name("track")
        .unwrap()
        .as_any()
        .downcast_ref::<StringArray>()
        .unwrap();
    let mut names: Vec<&str> = (0..tracks.len()).map(|i| tracks.value(i)).collect();
    names.sort_unstable();
    assert_eq!(names, ["Left", "Right"]);
    // DAIDALUS raises alerts on both with a small-UAS volume (its CSV, docs/daa.md): lost.
    assert!(crate::batch::column::<BooleanArray>(&batch, "lowc").value(0));
}

/// The bundled MIT LL uncorrelated model.
fn uncor_model() -> savsim::daa::encounter_model::Model {
    let path = root().join("scenes/encounter-models/uncor_1200code_v2p1.txt");
    savsim::daa::encounter_model::Model::parse(&std::fs::read_to_string(path).unwrap()).unwrap()
}

/// The p-value of a chi-square test of `observed` counts against `probabilities` (bins
/// expected under 5 merged into one).
pub(crate) fn chi_square_p(observed: &[f64], probabilities: &[f64]) -> f64 {
    use statrs::distribution::{ChiSquared, ContinuousCDF};
    let n: f64 = observed.iter().sum();
    let (mut stat, mut cells) = (0.0, 0usize);
    let (mut small_o, mut small_e) = (0.0, 0.0);
    for (o, p) in observed.iter().zip(probabilities) {
        let e = n * p;
        if e < 5.0 {
            small_o += o;
            small_e += e;
        } else {
            stat += (o - e).powi(2) / e;
            cells += 1;
        }
    }
    if small_e > 0.0 {
        stat += (small_o - small_e).powi(2) / small_e.max(1e-12);
        cells += 1;
    }
    if cells < 2 {
        return 1.0;
    }
    1.0 - ChiSquared::new((cells - 1) as f64).unwrap().cdf(stat)
}

/// P(x[i] | its parents' bins in x), from the counts as the model format lays them out
/// (written here: each variable's counts a bins x configurations matrix stored column by
/// column, the configuration of ascending parents with the first varying fastest).
fn conditional(net: &savsim::daa::encounter_model::Network, i: usize, x: &[usize]) -> f64 {
    let r = net.bins[i];
    let (mut j, mut stride) = (0, 1);
    for (p, &bin) in x.iter().enumerate() {
        if net.parents[i].contains(&p) {
            j += bin * stride;
            stride *= net.bins[p];
        }
    }
    let column = &net.counts[i][j * r..(j + 1) * r];
    let total: f64 = column.iter().sum();
    if total > 0.0 {
        column[x[i]] / total
    } else {
        1.0 / r as f64
    }
}

#[test]
fn the_encounter_model_sampler_reproduces_its_networks() {
    use rand::SeedableRng;
    let model = uncor_model();
    let net = &model.initial;
    assert_eq!(
        net.labels,
        ["G", "A", "L", "v", "\\dot v", "\\dot h", "\\dot \\psi"]
    );
    // Each variable's exact marginal, by enumerating every joint state (4*4*4*8*5*7*7 of them)
    // with the product of its conditional probabilities: another way than ancestral sampling.
    let n = net.labels.len();
    // G has no parents: its counts are the file's first four numbers of N_initial.
    let text =
        std::fs::read_to_string(root().join("scenes/encounter-models/uncor_1200code_v2p1.txt"))
            .unwrap();
    let line = text
        .lines()
        .skip_while(|l| !l.starts_with("# N_initial"))
        .nth(1)
        .unwrap();
    let g: Vec<f64> = line
        .split_whitespace()
        .take(4)
        .map(|v| v.parse().unwrap())
        .collect();
    let g_total: f64 = g.iter().sum();
    let mut marginals: Vec<Vec<f64>> = net.bins.iter().map(|&r| vec![0.0; r]).collect();
    let total: usize = net.bins.iter().product();
    let mut x = vec![0usize; n];
    for mut code in 0..total {
        for (xi, &r) in x.iter_mut().zip(&net.bins) {
            *xi = code % r;
            code /= r;
        }
        let p: f64 = (0..n).map(|i| conditional(net, i, &x)).product();
        for i in 0..n {
            marginals[i][x[i]] += p;
        }
    }
    for (k, c) in g.iter().enumerate() {
        assert!((marginals[0][k] - c / g_total).abs() < 1e-9, "G marginal");
    }
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(2024);
    let mut counts: Vec<Vec<f64>> = net.bins.iter().map(|&r| vec![0.0; r]).collect();
    for _ in 0..100_000 {
        let s = model.sample_initial(&mut rng);
        for i in 0..n {
            counts[i][s[i]] += 1.0;
        }
    }
    for i in 0..n {
        let p = chi_square_p(&counts[i], &marginals[i]);
        assert!(
            p > 0.01,
            "{}: p = {p}, {:?} vs {:?}",
            net.labels[i],
            counts[i],
            marginals[i]
        );
    }
    // The transition network: from one state, the next second's bins of each dynamic
    // variable against its conditional probabilities.
    let start = model.sample_initial(&mut rng);
    for &(now, next) in &model.temporal {
        let mut state = start.clone();
        state.resize(model.transition.labels.len(), 0);
        let p = model.transition.probabilities(next, &state);
        let mut seen = vec![0.0; p.len()];
        for _ in 0..100_000 {
            let mut x = start.clone();
            model.step(&mut x, &mut rng);
            seen[x[now]] += 1.0;
        }
        let pv = chi_square_p(&seen, &p);
        assert!(pv > 0.01, "{}: p = {pv}", model.transition.labels[next]);
    }
}

#[test]
fn model_encounters_hold_their_miss_distances_at_tca_and_fly() {
    let dir = tempfile::tempdir().unwrap();
    let model = root().join("scenes/encounter-models/uncor_1200code_v2p1.txt");
    let manifest = dir.path().join("enc.csv");
    let gen = |out: &Path| {
        Command::new(env!("CARGO_BIN_EXE_savsim"))
            .args([
                "batch",
                "gen-encounters",
                "--n",
                "12",
                "--seed",
                "5",
                "--duration-s",
                "120",
            ])
            .arg("--model")
            .arg(&model)
            .arg("--out")
            .arg(out)
            .output()
            .unwrap()
    };
    let out = gen(&manifest);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let again = dir.path().join("again.csv");
    assert!(gen(&again).status.success());
    assert_eq!(
        std::fs::read(&manifest).unwrap(),
        std::fs::read(&again).unwrap(),
        "deterministic"
    );
    let mut reader = csv::Reader::from_path(&manifest).unwrap();
    let headers = reader.headers().unwrap().clone();
    let col = |name: &str| headers.iter().position(|h| h == name).unwrap();
    let at = |track: &str, t: f64| -> DVec3 {
        let w = savsim::runs::waypoints::parse_waypoints(track).unwrap();
        let k = w.iter().position(|p| (p.t_s - t).abs() < 1e-9).unwrap();
        DVec3::from(w[k].position_enu_m)
    };
    let mut turning = 0;
    for row in reader.records() {
        let row = row.unwrap();
        let tca: f64 = row[col("tca_s")].parse().unwrap();
        let (own, intruder) = (&row[col("own")], &row[col("intruder")]);
        let d = at(intruder, tca) - at(own, tca);
        let hmd: f64 = row[col("hmd_at_tca_m")].parse().unwrap();
        let vmd: f64 = row[col("vmd_at_tca_m")].parse().unwrap();
        assert!((d.truncate().length() - hmd).abs() < 0.01, "{d} vs {hmd}");
        assert!((d.z - vmd).abs() < 0.01, "{d} vs {vmd}");
        // Not straight lines: some tracks turn (their heading changes along them).
        let w = savsim::runs::waypoints::parse_waypoints(own).unwrap();
        let heading = |k: usize| {
            let v = DVec3::from(w[k + 1].position_enu_m) - DVec3::from(w[k].position_enu_m);
            v.y.atan2(v.x)
        };
        if (heading(0) - heading(w.len() - 2)).abs() > 0.1 {
            turning += 1;
        }
    }
    assert!(turning > 0, "no model track turned");
    let results = dir.path().join("out");
    let run = batch_on_one_job(&manifest, &results);
    assert!(
        String::from_utf8_lossy(&run.stdout).contains("12 runs"),
        "{}",
        String::from_utf8_lossy(&run.stdout)
    );
    assert!(String::from_utf8_lossy(&run.stdout).contains("0 failed"));
}
