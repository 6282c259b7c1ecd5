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
