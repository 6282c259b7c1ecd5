//! Batch rows that alert on sensed states (`daa_conf`, `sensors`): the levels a row raises are
//! those `savsim daa` raises on the state file of what the row sensed (and DaidalusAlerting,
//! with `SAVSIM_DAIDALUS`), whose uncertainty columns are the sigmas of the sensor models.

use std::path::Path;

use arrow_array::{Array, Float64Array, StringArray, UInt64Array};

use crate::cli::savsim;

/// A SUM alerter with one small-UAS level (2000 ft, 250 ft): DO-365B's z-scores.
const CONF: &str = "lookahead_time = 120 [s]\nhysteresis_time = 5 [s]\npersistence_time = 4 [s]\n\
alerting_m = 2\nalerting_n = 4\nh_pos_z_score = 1.5\nh_vel_z_score_min = 0.5\n\
h_vel_z_score_max = 1.0\nh_vel_z_distance = 5 [nmi]\nv_pos_z_score = 0.75\nv_vel_z_score = 1.5\n\
alerters = S\nS_alert_1_region = NEAR\nS_alert_1_alerting_time = 40 [s]\n\
S_alert_1_early_alerting_time = 60 [s]\nS_alert_1_detector = d\nS_d_WCV_DTHR = 2000 [ft]\n\
S_d_WCV_ZTHR = 250 [ft]\nS_d_WCV_TTHR = 0 [s]\nS_d_WCV_TCOA = 0 [s]\n\
S_load_core_detection_d = gov.nasa.larcfm.ACCoRD.WCV_TAUMOD_SUM\n";

/// The alert level of each step of `savsim daa` on `daa` with `conf`: (time, level).
fn daa_levels(daa: &Path, conf: &Path) -> Vec<(f64, u64)> {
    let out = savsim()
        .arg("daa")
        .arg("--conf")
        .arg(conf)
        .arg(daa)
        .output()
        .unwrap();
    crate::common::assert_ran(&out);
    String::from_utf8(out.stdout)
        .unwrap()
        .lines()
        .skip(2)
        .map(|l| {
            let c: Vec<&str> = l.split(',').map(str::trim).collect();
            (c[0].parse().unwrap(), c[4].parse().unwrap())
        })
        .collect()
}

#[test]
fn a_rows_sensed_alerting_is_savsim_daas_on_what_it_sensed() {
    let dir = tempfile::tempdir().unwrap();
    let conf = dir.path().join("s.conf");
    std::fs::write(&conf, CONF).unwrap();
    // Head on at 100 m, 20 m/s each, 40 m abeam: alerted well before.
    let own = "0 0 -2400 100; 120 0 2400 100";
    let intruder = "0 40 2400 110; 120 40 -2400 110";
    let manifest = dir.path().join("m.csv");
    let mut csv = String::from("id,own,intruder,sensors,sensor_seed,daa_conf,sensed_daa\n");
    for (id, sensors) in [
        ("exact", "ideal"),
        ("adsb", "adsb-1090es:nacp=7,gps-ins"),
        ("late", "ideal-adsb:latency_s=2"),
    ] {
        csv += &format!(
            "{id},{own},{intruder},\"{sensors}\",7,{},{}\n",
            conf.display(),
            dir.path().join(format!("{id}.daa")).display()
        );
    }
    std::fs::write(&manifest, csv).unwrap();
    let out = dir.path().join("out");
    let ran = savsim()
        .args(["batch", "--jobs", "1", "--out"])
        .arg(&out)
        .arg(&manifest)
        .output()
        .unwrap();
    crate::common::assert_ran(&ran);
    let file = std::fs::File::open(out.join("part-00000-of-00001.parquet")).unwrap();
    let batch = parquet::arrow::arrow_reader::ParquetRecordBatchReaderBuilder::try_new(file)
        .unwrap()
        .build()
        .unwrap()
        .next()
        .unwrap()
        .unwrap();
    let col = |n: &str| batch.column_by_name(n).unwrap().clone();
    let ids = col("run_id");
    let ids = ids.as_any().downcast_ref::<StringArray>().unwrap();
    let errors = col("error");
    let errors = errors.as_any().downcast_ref::<StringArray>().unwrap();
    let max = col("alert_max_level");
    let max = max.as_any().downcast_ref::<UInt64Array>().unwrap();
    let first = col("first_alert_1_t_s");
    let first = first.as_any().downcast_ref::<Float64Array>().unwrap();
    let mut firsts = Vec::new();
    for i in 0..batch.num_rows() {
        assert!(errors.is_null(i), "{}", errors.value(i));
        let id = ids.value(i);
        let levels = daa_levels(&dir.path().join(format!("{id}.daa")), &conf);
        let daa_max = levels.iter().map(|l| l.1).max().unwrap();
        let daa_first = levels.iter().find(|l| l.1 >= 1).map(|l| l.0);
        assert_eq!(max.value(i), daa_max, "{id}");
        assert_eq!(Some(first.value(i)), daa_first, "{id}");
        firsts.push((id.to_string(), first.value(i)));
    }
    // 2 s of latency alerts no earlier than exact states.
    let t = |id: &str| firsts.iter().find(|f| f.0 == id).unwrap().1;
    assert!(t("late") >= t("exact"), "{firsts:?}");
    // The state file's uncertainty is the models': NACp 7's intruder, NACp 8's ownship.
    let text = std::fs::read_to_string(dir.path().join("adsb.daa")).unwrap();
    let own_row = text.lines().nth(2).unwrap();
    let intruder_row = text.lines().find(|l| l.starts_with("Intruder")).unwrap();
    let sigma = |row: &str| -> f64 { row.split(',').nth(8).unwrap().trim().parse().unwrap() };
    assert!((sigma(own_row) - 92.6 / 2.4477).abs() < 0.01, "{own_row}");
    assert!(
        (sigma(intruder_row) - 185.2 / 2.4477).abs() < 0.01,
        "{intruder_row}"
    );
    // DAIDALUS on the same files, when it is here.
    if let Some(script) = std::env::var_os("SAVSIM_DAIDALUS") {
        for (id, _) in &firsts {
            let theirs = dir.path().join("theirs.csv");
            let status = std::process::Command::new(&script)
                .arg("--conf")
                .arg(&conf)
                .arg("--out")
                .arg(&theirs)
                .arg(dir.path().join(format!("{id}.daa")))
                .status()
                .unwrap();
            assert!(status.success());
            let theirs: Vec<u64> = std::fs::read_to_string(&theirs)
                .unwrap()
                .lines()
                .skip(2)
                .map(|l| l.split(',').nth(4).unwrap().trim().parse().unwrap())
                .collect();
            let ours: Vec<u64> = daa_levels(&dir.path().join(format!("{id}.daa")), &conf)
                .iter()
                .map(|l| l.1)
                .collect();
            assert_eq!(ours, theirs, "{id}: savsim daa and DaidalusAlerting");
        }
    } else {
        eprintln!("SKIP: SAVSIM_DAIDALUS is not set: the sensed files are not given to DAIDALUS");
    }
}

/// ADS-B with NACp `nacp`, one report a second at whole seconds, every report received, no
/// latency: the report a state file holds at second t was made at t.
fn adsb_every_second(dir: &Path, nacp: u8) -> std::path::PathBuf {
    let path = dir.join(format!("nacp{nacp}.toml"));
    std::fs::write(
        &path,
        format!(
            "[[sensor]]\npreset = \"adsb-1090es\"\nnacp = {nacp}\nrate_hz = 1.0\n\
             reception = [[37040.0, 0.001]]\nlatency_s = 0.0\nlatency_jitter_s = 0.0\n"
        ),
    )
    .unwrap();
    path
}

/// The intruder's first sensed position (east, north) in a state file savsim wrote.
fn first_intruder_en(daa: &Path) -> [f64; 2] {
    let text = std::fs::read_to_string(daa).unwrap();
    let row = text
        .lines()
        .find(|l| l.starts_with("Intruder"))
        .unwrap_or_else(|| panic!("{}: no intruder row", daa.display()));
    let c: Vec<f64> = row
        .split(',')
        .skip(1)
        .map(|v| v.trim().parse().unwrap())
        .collect();
    [c[0], c[1]]
}

/// Every encounter draws its own sensor errors (by default a row's seed is made from its
/// `seed` and its pair): 1000 encounters of one geometry (200 pairs under each of the base
/// seeds 1 to 5), an intruder holding still 3.2 km off, each reported by ADS-B with NACp 6
/// (227 m an axis): the first reports' errors east and north are normal with NACp 6's sigma
/// (Kolmogorov-Smirnov, p > 0.01) and centred. Before, every row drew with seed 1, and all had
/// the same error. The `mitigated` variant of a pair, with NACp 7 (75.7 m an axis), draws the
/// same realisation: a third of its nominal's error. Two pairs given one `sensor_seed` draw the
/// same errors; another base seed, another error for the same pair; the same manifest flown
/// again (and over two jobs) gives the same state files.
#[test]
fn every_encounter_draws_its_own_adsb_errors_and_its_variants_share_them() {
    let dir = tempfile::tempdir().unwrap();
    let conf = dir.path().join("s.conf");
    std::fs::write(&conf, CONF).unwrap();
    let (nacp6, nacp7) = (
        adsb_every_second(dir.path(), 6),
        adsb_every_second(dir.path(), 7),
    );
    let truth = [2000.0, 2500.0];
    let (own, intruder) = (
        "0 0 0 100; 3 0 0 100",
        format!("0 {0} {1} 100; 3 {0} {1} 100", truth[0], truth[1]),
    );
    let daa = |id: &str| dir.path().join("daa").join(format!("{id}.daa"));
    std::fs::create_dir_all(dir.path().join("daa")).unwrap();
    let mut csv =
        String::from("id,pair,variant,own,intruder,sensors,sensor_seed,seed,daa_conf,sensed_daa\n");
    let mut row = |id: &str, pair: &str, variant: &str, sensors: &Path, seeds: &str| {
        csv += &format!(
            "{id},{pair},{variant},{own},{intruder},{},{seeds},{},{}\n",
            sensors.display(),
            conf.display(),
            daa(id).display()
        );
    };
    for seed in 1..=5 {
        for p in 0..200 {
            let id = format!("s{seed}p{p}-n");
            row(
                &id,
                &format!("p{p}"),
                "nominal",
                &nacp6,
                &format!(",{seed}"),
            );
        }
    }
    for p in 0..10 {
        row(
            &format!("s1p{p}-m"),
            &format!("p{p}"),
            "mitigated",
            &nacp7,
            ",1",
        );
    }
    row("own-a", "qa", "nominal", &nacp6, "5,");
    row("own-b", "qb", "nominal", &nacp6, "5,");
    let manifest = dir.path().join("m.csv");
    std::fs::write(&manifest, csv).unwrap();
    let fly = |jobs: &str, out: &str| {
        let ran = savsim()
            .args(["batch", "--jobs", jobs, "--out"])
            .arg(dir.path().join(out))
            .arg(&manifest)
            .output()
            .unwrap();
        crate::common::assert_ran(&ran);
    };
    fly("1", "out1");
    let error = |id: &str| {
        let [e, n] = first_intruder_en(&daa(id));
        [e - truth[0], n - truth[1]]
    };
    let errors: Vec<[f64; 2]> = (1..=5)
        .flat_map(|seed| (0..200).map(move |p| format!("s{seed}p{p}-n")))
        .map(|id| error(&id))
        .collect();
    let sigma = 0.3 * 1852.0 / 2.4477;
    let normal = statrs::distribution::Normal::new(0.0, sigma).unwrap();
    for (axis, name) in [(0, "east"), (1, "north")] {
        let x: Vec<f64> = errors.iter().map(|e| e[axis]).collect();
        let mean = x.iter().sum::<f64>() / x.len() as f64;
        let sd = (x.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (x.len() - 1) as f64).sqrt();
        let (d, p) = crate::common::ks(x, |v| statrs::distribution::ContinuousCDF::cdf(&normal, v));
        eprintln!("{name}: mean {mean:.1} m, sd {sd:.1} m, KS D {d:.4}, p {p:.3}");
        assert!(p > 0.01, "{name}: KS p {p} (D {d}), mean {mean}, sd {sd}");
        assert!(
            mean.abs() < 3.0 * sigma / 1000f64.sqrt(),
            "{name}: mean {mean}"
        );
    }
    // The variants of a pair: NACp 7's sigma is a third of NACp 6's, the draw the same
    // (within the state file's micrometres).
    for (p, &n) in errors.iter().enumerate().take(10) {
        let m = error(&format!("s1p{p}-m"));
        for axis in 0..2 {
            assert!(
                (n[axis] / 3.0 - m[axis]).abs() < 1e-3,
                "pair p{p}: {n:?} and {m:?}"
            );
        }
    }
    // One explicit seed, one draw; another base seed, another draw for the same pair.
    assert_eq!(error("own-a"), error("own-b"));
    assert_ne!(error("own-a"), errors[0]);
    assert_ne!(error("s2p0-n"), error("s1p0-n"));
    // Flown again, over two jobs: the same state files.
    let first: Vec<String> = ["s1p0-n", "s1p7-m", "own-a", "s2p0-n"]
        .iter()
        .map(|id| std::fs::read_to_string(daa(id)).unwrap())
        .collect();
    fly("2", "out2");
    for (id, before) in ["s1p0-n", "s1p7-m", "own-a", "s2p0-n"].iter().zip(&first) {
        assert_eq!(&std::fs::read_to_string(daa(id)).unwrap(), before, "{id}");
    }
}
