//! `savsim batch`: generated encounters against their construction, the same rows whatever
//! the jobs and the sharding, finished shards skipped, bad rows kept as rows with their error,
//! the scheduler's shard index; and the Python package (and its Ray example) against the CLI.
//! Parquet files are read back with the parquet crate's own reader.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use arrow_array::{Array, BooleanArray, Float64Array, RecordBatch, StringArray, UInt64Array};
use parquet::arrow::arrow_reader::ParquetRecordBatchReaderBuilder;

use crate::common::{assert_ran, have_python_module, root};

pub(crate) fn savsim(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_savsim"))
        .args(args)
        .env_remove("SLURM_ARRAY_TASK_ID")
        .env_remove("SLURM_ARRAY_TASK_COUNT")
        .env_remove("JOB_COMPLETION_INDEX")
        .output()
        .expect("savsim runs")
}

pub(crate) fn read(path: &Path) -> RecordBatch {
    let file = std::fs::File::open(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let reader = ParquetRecordBatchReaderBuilder::try_new(file)
        .expect("a parquet file")
        .with_batch_size(1 << 20)
        .build()
        .expect("readable");
    let mut batches: Vec<RecordBatch> = reader.map(|b| b.expect("a batch")).collect();
    assert_eq!(batches.len(), 1, "one batch");
    batches.remove(0)
}

/// The batch without the three measured columns.
fn outcome(batch: &RecordBatch) -> RecordBatch {
    let keep: Vec<usize> = (0..batch.num_columns())
        .filter(|&i| {
            !matches!(
                batch.schema().field(i).name().as_str(),
                "tick_cost_us_median" | "tick_cost_us_p99" | "wall_s"
            )
        })
        .collect();
    batch.project(&keep).expect("columns")
}

pub(crate) fn column<'a, T: 'static>(batch: &'a RecordBatch, name: &str) -> &'a T {
    batch
        .column_by_name(name)
        .unwrap_or_else(|| panic!("column {name}"))
        .as_any()
        .downcast_ref::<T>()
        .unwrap_or_else(|| panic!("column {name}'s type"))
}

fn city() -> String {
    root().join("scenes/city.toml").display().to_string()
}

fn demo_tlog() -> String {
    root()
        .join("scenes/flights/copter_square_10ms.tlog")
        .display()
        .to_string()
}

/// A manifest of `n` generated encounters, `duration_s` long, over the city or open air.
fn encounters(dir: &Path, n: usize, duration_s: &str, over_city: bool) -> PathBuf {
    let path = dir.join("encounters.csv");
    let n = n.to_string();
    let city = city();
    let mut args = vec!["batch", "gen-encounters", "--n", &n, "--seed", "11"];
    args.extend(["--duration-s", duration_s, "--out", path.to_str().unwrap()]);
    if over_city {
        args.extend(["--scene", city.as_str()]);
    }
    assert_ran(&savsim(&args));
    path
}

#[test]
fn generated_encounters_are_found_as_they_were_built() {
    let dir = tempfile::tempdir().unwrap();
    // Open air: over the city, the city's own airliner may pass closer than the intruder.
    let manifest = encounters(dir.path(), 300, "40", false);
    let out = dir.path().join("out");
    assert_ran(&savsim(&[
        "batch",
        manifest.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]));
    let rows = read(&out.join("part-00000-of-00001.parquet"));
    assert_eq!(rows.num_rows(), 300);
    let f = |name: &str| column::<Float64Array>(&rows, name);
    let b = |name: &str| column::<BooleanArray>(&rows, name);
    let mut nmacs = 0;
    for i in 0..rows.num_rows() {
        assert!(column::<StringArray>(&rows, "error").is_null(i));
        for (got, want) in [
            ("cpa_m", "expect_cpa_m"),
            ("cpa_horizontal_m", "expect_cpa_horizontal_m"),
            ("cpa_vertical_m", "expect_cpa_vertical_m"),
            ("cpa_t_s", "expect_cpa_t_s"),
        ] {
            let (g, w) = (f(got).value(i), f(want).value(i));
            assert!((g - w).abs() < 1e-6, "row {i}: {got} {g} against {w}");
        }
        assert_eq!(b("nmac").value(i), b("expect_nmac").value(i), "row {i}");
        nmacs += usize::from(b("nmac").value(i));
        assert_eq!(column::<UInt64Array>(&rows, "ticks").value(i), 401);
    }
    // About 9% by construction: the set holds both kinds.
    assert!((10..=50).contains(&nmacs), "{nmacs} NMACs in 300");
}

#[test]
fn rows_are_the_same_whatever_the_jobs_and_the_shards() {
    let dir = tempfile::tempdir().unwrap();
    let manifest = encounters(dir.path(), 20, "30", true);
    // A tlog and a failing row among them.
    let mut text = std::fs::read_to_string(&manifest).unwrap();
    // Rows as long as the header (the columns gen-encounters writes).
    let columns = text.lines().next().unwrap().split(',').count();
    let pad = |row: String| format!("{row}{}\n", ",".repeat(columns - row.split(',').count()));
    text += &pad(format!("demo,{},{}", demo_tlog(), city()));
    text += &pad("broken,,,,0 0 0 100; 10 100 0 100".to_string());
    std::fs::write(&manifest, text).unwrap();
    let m = manifest.to_str().unwrap();
    let run = |name: &str, extra: &[&str]| {
        let out = dir.path().join(name);
        let mut args = vec!["batch", m, "--out", out.to_str().unwrap()];
        args.extend_from_slice(extra);
        assert_ran(&savsim(&args));
        out
    };
    let one = outcome(&read(
        &run("one", &["--jobs", "1"]).join("part-00000-of-00001.parquet"),
    ));
    let two = outcome(&read(
        &run("two", &["--jobs", "2"]).join("part-00000-of-00001.parquet"),
    ));
    assert_eq!(one.num_rows(), 22);
    assert_eq!(one, two, "--jobs 1 and --jobs 2 differ");
    let mut offset = 0;
    for k in 0..3 {
        let shard = format!("{k}/3");
        let part =
            run("sharded", &["--shard", &shard]).join(format!("part-{k:05}-of-00003.parquet"));
        let rows = outcome(&read(&part));
        assert_eq!(rows, one.slice(offset, rows.num_rows()), "shard {shard}");
        offset += rows.num_rows();
    }
    assert_eq!(offset, 22);
    let errors = column::<StringArray>(&one, "error");
    assert!(
        errors.value(21).contains("intruder"),
        "{}",
        errors.value(21)
    );
    assert_eq!(errors.null_count(), 21);
    let obstacle = column::<StringArray>(&one, "first_collision_obstacle");
    assert_eq!(obstacle.value(20), "b2150");
}

#[test]
fn a_finished_shard_is_skipped_and_force_runs_it_again() {
    let dir = tempfile::tempdir().unwrap();
    let manifest = dir.path().join("m.toml");
    std::fs::write(
        &manifest,
        "[[run]]\nid = \"pass\"\nown = \"0 0 0 100; 20 200 0 100\"\nintruder = \"0 200 50 100; 20 0 50 100\"\n",
    )
    .unwrap();
    let out = dir.path().join("out");
    let args = [
        "batch",
        manifest.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ];
    assert_ran(&savsim(&args));
    let part = out.join("part-00000-of-00001.parquet");
    let first = std::fs::read(&part).unwrap();
    let again = savsim(&args);
    assert_ran(&again);
    assert!(String::from_utf8_lossy(&again.stderr).contains("skipped"));
    assert_eq!(
        std::fs::read(&part).unwrap(),
        first,
        "a done shard was rewritten"
    );
    let forced = [&args[..], &["--force"]].concat();
    assert_ran(&savsim(&forced));
    let rows = read(&part);
    // Head-on at 10 m/s each from 200 m apart, 50 m abeam at the same height: closest at 10 s.
    assert!((column::<Float64Array>(&rows, "cpa_m").value(0) - 50.0).abs() < 1e-9);
    assert!((column::<Float64Array>(&rows, "cpa_t_s").value(0) - 10.0).abs() < 1e-9);
    assert!(column::<BooleanArray>(&rows, "nmac").value(0));
    assert!(!dir
        .path()
        .join("out/part-00000-of-00001.parquet.tmp")
        .exists());
}

#[test]
fn bad_rows_are_rows_with_their_error_and_the_rest_still_run() {
    let dir = tempfile::tempdir().unwrap();
    let bad_scene = dir.path().join("bad.toml");
    std::fs::write(
        &bad_scene,
        "[origin]\nlat_deg = 95\nlon_deg = 0\nalt_m = 0\n",
    )
    .unwrap();
    let garbage = dir.path().join("garbage.tlog");
    std::fs::write(&garbage, vec![0x55u8; 4000]).unwrap();
    let manifest = dir.path().join("m.csv");
    let own = "0 0 0 100; 20 200 0 100";
    std::fs::write(
        &manifest,
        format!(
            "id,tlog,scene,mode,own,intruder,intruder_kind\n\
             missing,nowhere.tlog,,,,,\n\
             scene,{demo},bad.toml,,,,\n\
             mode,{demo},,fastest,,,\n\
             both,{demo},,,{own},{own},\n\
             waypoints,,,,0 0 0,{own},\n\
             kind,,,,{own},{own},zeppelin\n\
             garbage,garbage.tlog,,,,,\n\
             good,,,,{own},{own},\n",
            demo = demo_tlog()
        ),
    )
    .unwrap();
    let out = dir.path().join("out");
    let run = savsim(&[
        "batch",
        manifest.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]);
    assert_ran(&run);
    let rows = read(&out.join("part-00000-of-00001.parquet"));
    let errors = column::<StringArray>(&rows, "error");
    let want = [
        "nowhere.tlog",
        "lat_deg",
        "fastest",
        "either `tlog`",
        "four numbers",
        "zeppelin",
    ];
    for (i, w) in want.iter().enumerate() {
        assert!(
            errors.value(i).contains(w),
            "row {i}: {:?} lacks {w:?}",
            errors.value(i)
        );
    }
    // A file of garbage is a run with no positions (counted as bad bytes), not a failure.
    assert!(errors.is_null(6), "{}", errors.value(6));
    assert_eq!(column::<UInt64Array>(&rows, "ticks").value(6), 0);
    assert!(errors.is_null(7));
    assert_eq!(
        column::<UInt64Array>(&rows, "collisions").value(7),
        1,
        "the same track collides"
    );
    assert!(String::from_utf8_lossy(&run.stdout).contains("6 failed"));

    // A file that is not a manifest is a usage error, and says where.
    std::fs::write(&manifest, "id,colour\nx,blue\n").unwrap();
    let bad = savsim(&[
        "batch",
        manifest.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]);
    assert_eq!(bad.status.code(), Some(2));
    let said = String::from_utf8_lossy(&bad.stderr);
    assert!(said.contains("m.csv") && said.contains("colour"), "{said}");
}

#[test]
fn a_slurm_array_task_or_an_indexed_job_runs_its_own_shard() {
    let dir = tempfile::tempdir().unwrap();
    let manifest = encounters(dir.path(), 5, "10", false);
    let out = dir.path().join("out");
    let run = |env: &[(&str, &str)], extra: &[&str]| {
        let mut c = Command::new(env!("CARGO_BIN_EXE_savsim"));
        c.args([
            "batch",
            manifest.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
        ])
        .args(extra)
        .env_remove("SLURM_ARRAY_TASK_ID")
        .env_remove("SLURM_ARRAY_TASK_COUNT")
        .env_remove("JOB_COMPLETION_INDEX");
        for (k, v) in env {
            c.env(k, v);
        }
        c.output().unwrap()
    };
    // Slurm `--array=1-2`: task 2 is shard 1 of 2.
    assert_ran(&run(
        &[
            ("SLURM_ARRAY_TASK_ID", "2"),
            ("SLURM_ARRAY_TASK_MIN", "1"),
            ("SLURM_ARRAY_TASK_COUNT", "2"),
        ],
        &[],
    ));
    let slurm = read(&out.join("part-00001-of-00002.parquet"));
    assert_eq!(column::<UInt64Array>(&slurm, "index").values(), &[2, 3, 4]);
    // Kubernetes: the index from the job, the count from --shard.
    assert_ran(&run(&[("JOB_COMPLETION_INDEX", "0")], &["--shard", "5"]));
    let k8s = read(&out.join("part-00000-of-00005.parquet"));
    assert_eq!(column::<UInt64Array>(&k8s, "index").values(), &[0]);
    // `--shard N` with no scheduler says what it needs.
    let alone = run(&[], &["--shard", "5"]);
    assert_eq!(alone.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&alone.stderr).contains("JOB_COMPLETION_INDEX"));
}

#[test]
fn the_python_package_and_its_ray_example_give_the_clis_rows() {
    if !have_python_module(
        "savsim",
        "SAVSIM_REQUIRE_PYTHON_PACKAGE",
        "pip install ./python; .ci/run does",
    ) {
        return;
    }
    let ray = have_python_module(
        "ray, duckdb",
        "SAVSIM_REQUIRE_RAY",
        "pip install ray duckdb",
    );
    let dir = tempfile::tempdir().unwrap();
    let mut args = vec![
        env!("CARGO_BIN_EXE_savsim").to_string(),
        dir.path().display().to_string(),
    ];
    if ray {
        args.push("--ray".into());
    }
    let args: Vec<&str> = args.iter().map(String::as_str).collect();
    let said = crate::common::python(&root().join("tests/python/check_package.py"), &args);
    eprintln!("{said}");
    assert!(said.contains("GIL released"), "{said}");
    assert_eq!(said.contains("Ray on 2 workers"), ray, "{said}");
}

/// `--rerun-rows failed`: the rows that did not pass (NMAC encounters, the tlog that hits a
/// building) are recorded, flown again after they ran, and only they; each recording holds
/// what made its row fail; `batch report` links each.
#[test]
fn failed_rows_are_recorded_and_linked() {
    let dir = tempfile::tempdir().unwrap();
    let manifest = encounters(dir.path(), 30, "40", false);
    let mut text = std::fs::read_to_string(&manifest).unwrap();
    let header: Vec<&str> = text.lines().next().unwrap().split(',').collect();
    let row: Vec<String> = header
        .iter()
        .map(|c| match *c {
            "id" => "city-tlog".to_string(),
            "tlog" => demo_tlog(),
            "scene" => city(),
            _ => String::new(),
        })
        .collect();
    text += &(row.join(",") + "\n");
    std::fs::write(&manifest, text).unwrap();
    let out = dir.path().join("out");
    let ran = savsim(&[
        "batch",
        manifest.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--rerun-rows",
        "failed",
    ]);
    assert_ran(&ran);
    let rows = read(&out.join("part-00000-of-00001.parquet"));
    let ids = column::<StringArray>(&rows, "run_id");
    let (nmac, collisions) = (
        column::<BooleanArray>(&rows, "nmac"),
        column::<UInt64Array>(&rows, "collisions"),
    );
    let failed: Vec<(usize, &str)> = (0..rows.num_rows())
        .filter(|&i| nmac.value(i) || collisions.value(i) > 0)
        .map(|i| (i, ids.value(i)))
        .collect();
    assert!(failed.len() >= 2, "{failed:?}");
    assert!(failed.iter().any(|(_, id)| *id == "city-tlog"));
    let mut kept: Vec<PathBuf> = std::fs::read_dir(out.join("rows"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .collect();
    kept.sort();
    let want: Vec<PathBuf> = failed
        .iter()
        .map(|(i, id)| savsim::runs::recordings::recording_path(&out, *i as u64, id))
        .collect();
    assert_eq!(kept, want);
    if crate::viz::have_rerun_cli() {
        for (path, (i, id)) in kept.iter().zip(&failed) {
            crate::viz::assert_rrd_verifies(path);
            let printed = Command::new("rerun")
                .args(["rrd", "print", "-vv"])
                .arg(path)
                .output()
                .unwrap();
            let text = String::from_utf8_lossy(&printed.stdout);
            let what = if collisions.value(*i) > 0 {
                "world/events/collisions"
            } else {
                // An encounter's NMAC: its intruder, well clear lost, the closest approach
                // marked with the NMAC volume.
                assert!(text.contains("world/traffic/intruder"), "{id}");
                assert!(text.contains("world/events/well_clear"), "{id}");
                "world/events/closest_approaches/1/intruder/nmac"
            };
            assert!(text.contains(what), "{id}: no {what} in its recording");
        }
    }
    let report = savsim(&["batch", "report", out.to_str().unwrap()]);
    assert_ran(&report);
    let page = std::fs::read_to_string(out.join("report.html")).unwrap();
    assert_eq!(page.matches("<a href=\"rows/").count(), failed.len());
}
