//! Every number from outside is bounded before it sizes anything: absurd numbers in a batch
//! row are that row's error (the rest run), absurd flags are usage errors, and neither hangs
//! nor panics.

/// `savsim` with `args`, killed if it runs longer than `limit` (a hang is a failure).
fn savsim_within(args: &[&str], limit: std::time::Duration) -> std::process::Output {
    let mut child = std::process::Command::new(env!("CARGO_BIN_EXE_savsim"))
        .args(args)
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    let started = std::time::Instant::now();
    while child.try_wait().unwrap().is_none() {
        if started.elapsed() > limit {
            let _ = child.kill();
            panic!("savsim {args:?} still running after {limit:?}");
        }
        std::thread::sleep(std::time::Duration::from_millis(20));
    }
    child.wait_with_output().unwrap()
}

#[test]
fn absurd_numbers_in_a_row_are_that_rows_error_and_the_rest_run() {
    use arrow_array::{cast::AsArray, types::UInt64Type, Array};
    let dir = tempfile::tempdir().unwrap();
    let manifest = dir.path().join("m.csv");
    let own = "0 0 0 100; 20 200 0 100";
    std::fs::write(
        &manifest,
        format!(
            "id,own,intruder,duration_s,rate_hz\n\
             long,{own},{own},1e14,\n\
             fast,{own},{own},,1e300\n\
             many,{own},{own},1e6,1000\n\
             far,0 0 0 1e300; 1 0 0 0,{own},,\n\
             nan,{own},{own},NaN,\n\
             good,{own},{own},,\n"
        ),
    )
    .unwrap();
    let out = dir.path().join("out");
    let run = savsim_within(
        &[
            "batch",
            manifest.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
        ],
        std::time::Duration::from_secs(60),
    );
    crate::common::assert_ran(&run);
    let file = std::fs::File::open(out.join("part-00000-of-00001.parquet")).unwrap();
    let batch = parquet::arrow::arrow_reader::ParquetRecordBatchReaderBuilder::try_new(file)
        .unwrap()
        .build()
        .unwrap()
        .next()
        .unwrap()
        .unwrap();
    let errors = batch.column_by_name("error").unwrap().as_string::<i32>();
    for (i, want) in [
        "duration_s 1e14",
        "rate_hz 1e300",
        "samples a row",
        "waypoint 1",
        "duration_s NaN",
    ]
    .iter()
    .enumerate()
    {
        assert!(
            errors.value(i).contains(want),
            "row {i}: {:?}",
            errors.value(i)
        );
    }
    assert!(errors.is_null(5), "{}", errors.value(5));
    let collisions = batch
        .column_by_name("collisions")
        .unwrap()
        .as_primitive::<UInt64Type>();
    assert_eq!(collisions.value(5), 1);
}

#[test]
fn absurd_flags_are_usage_errors_not_panics() {
    for args in [
        &[
            "live",
            "--connect",
            "udpin:127.0.0.1:0",
            "--duration-s",
            "1e20",
        ][..],
        &[
            "live",
            "--connect",
            "udpin:127.0.0.1:0",
            "--rate-hz",
            "1e300",
        ],
        &["replay", "x.tlog", "--ray-length-m", "1e300"],
        &["replay", "x.tlog", "--sensor-hz", "1e300"],
        &["batch", "gen-encounters", "--n", "1000000000000"],
        &[
            "batch",
            "gen-encounters",
            "--n",
            "1",
            "--duration-s",
            "1e300",
        ],
        &["bench", "--scale-max", "1000000000000"],
    ] {
        let run = savsim_within(args, std::time::Duration::from_secs(20));
        let said = String::from_utf8_lossy(&run.stderr);
        assert_eq!(run.status.code(), Some(2), "{args:?}: {said}");
        assert!(!said.contains("panicked"), "{args:?}: {said}");
    }
}
