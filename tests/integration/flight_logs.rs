//! Autopilot logs (ArduPilot DataFlash, PX4 ULog) against what independent readers found in
//! the real logs of ../shared/fixtures/realdata (pymavlink's DFReader, pyulog: their
//! `.ref.json`), and bad input against the readers.

use std::collections::BTreeMap;
use std::path::PathBuf;

use savsim::codec::decode::Report;
use savsim::logs::dataflash::DataflashReader;
use savsim::logs::flightlog::{read_dataflash, read_ulog, FlightLog};
use savsim::logs::ulog::UlogReader;
use serde_json::Value;

use crate::common::shared_fixtures;

/// The files of `kind` in ../shared/fixtures/realdata with their references.
pub(crate) fn realdata(kind: &str) -> Vec<(PathBuf, Value)> {
    let Some(root) = shared_fixtures() else {
        return Vec::new();
    };
    let index: Value = serde_json::from_slice(
        &std::fs::read(root.join("realdata/index.json")).expect("index.json"),
    )
    .expect("index.json is JSON");
    index["files"]
        .as_array()
        .expect("files")
        .iter()
        .filter(|f| f["kind"] == kind)
        .map(|f| {
            let dir = root.join("realdata");
            let path = dir.join(f["file"].as_str().expect("file"));
            let reference = std::fs::read(dir.join(f["ref"].as_str().expect("ref"))).expect("ref");
            (
                path,
                serde_json::from_slice(&reference).expect("ref is JSON"),
            )
        })
        .collect()
}

#[test]
fn dataflash_messages_are_the_ones_pymavlink_reads() {
    let files = realdata("dataflash");
    for (path, reference) in &files {
        let data = std::fs::read(path).expect("log");
        let mut reader = DataflashReader::new(&data);
        let mut counts: BTreeMap<String, u64> = BTreeMap::new();
        let (mut first_us, mut last_us) = (None, None);
        while let Some(m) = reader.next_message() {
            *counts.entry(m.name().to_string()).or_default() += 1;
            let described = ["FMT", "FMTU", "UNIT", "MULT", "PARM", "MSG"].contains(&m.name());
            if let Some(t) = m.get("TimeUS").filter(|_| !described) {
                first_us.get_or_insert(t);
                last_us = Some(t);
            }
        }
        let expected: BTreeMap<String, u64> =
            serde_json::from_value(reference["message_counts"].clone()).expect("counts");
        assert_eq!(counts, expected, "{}", path.display());
        assert_eq!(
            reader.counts().messages,
            reference["total_messages"].as_u64().expect("total"),
            "{}",
            path.display()
        );
        assert_eq!(
            first_us,
            reference["first_time"].as_f64(),
            "{}",
            path.display()
        );
        assert_eq!(
            last_us,
            reference["last_time"].as_f64(),
            "{}",
            path.display()
        );
    }
    eprintln!("{} DataFlash logs compared with pymavlink", files.len());
}

#[test]
fn ulog_samples_are_the_ones_pyulog_reads() {
    let files = realdata("ulog");
    for (path, reference) in &files {
        let data = std::fs::read(path).expect("log");
        let mut reader = UlogReader::new(&data).expect("ULog");
        let mut seen: BTreeMap<(String, u8), (u64, u64, u64)> = BTreeMap::new();
        while let Some(s) = reader.next_sample().expect("readable formats") {
            let t = s.timestamp_us().expect("timestamp");
            let entry = seen
                .entry((s.topic.to_string(), s.instance))
                .or_insert((0, t, t));
            *entry = (entry.0 + 1, entry.1, t);
        }
        let expected: BTreeMap<(String, u8), (u64, u64, u64)> = reference["datasets"]
            .as_array()
            .expect("datasets")
            .iter()
            .map(|d| {
                let n = |k: &str| d[k].as_u64().expect(k);
                let name = d["name"].as_str().expect("name").to_string();
                (
                    (name, n("multi_id") as u8),
                    (n("count"), n("first_timestamp_us"), n("last_timestamp_us")),
                )
            })
            .collect();
        assert_eq!(seen, expected, "{}", path.display());
        let counts = reader.counts();
        let dropouts = &reference["dropouts"];
        assert_eq!(counts.dropouts, dropouts["count"].as_u64().expect("count"));
        assert_eq!(
            counts.dropout_ms,
            dropouts["total_ms"].as_u64().expect("ms")
        );
    }
    eprintln!("{} ULog files compared with pyulog", files.len());
}

/// The first and last position reports of a log: (lat, lon, alt) each.
fn ends(log: &FlightLog) -> Option<([f64; 3], [f64; 3])> {
    let mut positions = log.reports.iter().filter_map(|r| match r.report {
        Report::Position(p) => Some([p.position.lat_deg, p.position.lon_deg, p.position.alt_m]),
        _ => None,
    });
    let first = positions.next()?;
    Some((first, positions.next_back().unwrap_or(first)))
}

fn close(a: [f64; 3], b: [f64; 3]) -> bool {
    (a[0] - b[0]).abs() < 1e-9 && (a[1] - b[1]).abs() < 1e-9 && (a[2] - b[2]).abs() < 1e-4
}

/// The log's first and last positions are the reference's `first` and `last`, read with the
/// reference's names for latitude, longitude and altitude.
fn assert_ends(log: &FlightLog, position: &Value, keys: [&str; 3], path: &std::path::Path) {
    let at = |k: &str| keys.map(|key| position[k][key].as_f64().expect(key));
    let (first, last) = ends(log).expect("positions");
    assert!(
        close(first, at("first")) && close(last, at("last")),
        "{}: {first:?} {last:?}",
        path.display()
    );
}

#[test]
fn flights_in_logs_are_where_the_independent_readers_put_them() {
    for (path, reference) in realdata("ulog") {
        let log = read_ulog(&std::fs::read(&path).expect("log")).expect("ULog");
        let s = &log.summary;
        let attitude = &reference["attitude"];
        assert_eq!(
            Some(s.attitudes),
            attitude["count"].as_u64(),
            "{}",
            path.display()
        );
        let position = &reference["position"];
        if position.is_null() {
            assert_eq!(
                (s.positions, s.position_source),
                (0, None),
                "{}",
                path.display()
            );
            continue;
        }
        assert_eq!(
            s.position_source,
            position["topic"].as_str(),
            "{}",
            path.display()
        );
        let all = s.positions + s.positions_without_fix;
        assert_eq!(Some(all), position["count"].as_u64(), "{}", path.display());
        assert_ends(&log, position, ["lat_deg", "lon_deg", "alt_m"], &path);
    }
    for (path, reference) in realdata("dataflash") {
        let log = read_dataflash(&std::fs::read(&path).expect("log"));
        let s = &log.summary;
        let source = s.position_source.expect("a position source");
        let position = &reference[source];
        let all = s.positions + s.positions_without_fix;
        assert_eq!(Some(all), position["count"].as_u64(), "{}", path.display());
        assert_eq!(
            Some(s.attitudes),
            reference["ATT"]["count"].as_u64(),
            "{}",
            path.display()
        );
        assert_ends(&log, position, ["Lat", "Lng", "Alt"], &path);
    }
}

#[test]
fn bad_logs_get_an_error_or_a_counted_skip() {
    assert!(UlogReader::new(b"ULo").is_err());
    assert_eq!(
        UlogReader::new(b"ULog\x01\x12\x35\x01").err(),
        Some(savsim::logs::ulog::UlogError::CutHeader)
    );
    assert!(read_ulog(b"not a ulog file at all").is_err());
    // Garbage after a valid header, and every cut of a small DataFlash log: no panic.
    let mut ulog = b"ULog\x01\x12\x35\x01".to_vec();
    ulog.extend([0u8; 8]);
    ulog.extend((0..4096u32).map(|i| (i.wrapping_mul(2_654_435_761) >> 13) as u8));
    let log = read_ulog(&ulog).expect("header is valid");
    assert!(log.summary.ulog.expect("counts").corrupt > 0);
    let df: Vec<u8> = (0..4096u32)
        .map(|i| (i.wrapping_mul(40_503) >> 7) as u8)
        .collect();
    let log = read_dataflash(&df);
    assert_eq!(log.summary.dataflash.expect("counts").skipped_bytes, 4096);
}

#[test]
fn real_logs_cut_and_corrupted_anywhere_read_without_a_panic() {
    let mut files = realdata("ulog");
    files.extend(realdata("dataflash"));
    for (path, _) in files {
        let data = std::fs::read(&path).expect("log");
        let mut state = 0x2545_f491_4f6c_dd1d_u64;
        let mut next = |n: usize| {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state % n as u64) as usize
        };
        for _ in 0..12 {
            let mut bad = data[..next(data.len())].to_vec();
            for _ in 0..64 {
                if !bad.is_empty() {
                    let at = next(bad.len());
                    bad[at] ^= 1 << next(8);
                }
            }
            match read_ulog(&bad) {
                Ok(log) => assert!(log.reports.windows(2).all(|w| w[0].t_us <= w[1].t_us)),
                Err(_) => {
                    let _ = read_dataflash(&bad);
                }
            }
        }
    }
}

/// `savsim batch` replays ULog and DataFlash logs given in the `tlog` column: one row each,
/// every position with a fix a collision tick (the same as `savsim replay`).
#[test]
fn batch_rows_replay_autopilot_logs() {
    let mut files = realdata("ulog");
    files.extend(realdata("dataflash"));
    if files.is_empty() {
        eprintln!("skipped: ../shared/fixtures/realdata is absent");
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let mut csv = String::from("id,tlog\n");
    let mut expected = Vec::new();
    for (k, (path, _)) in files.iter().enumerate() {
        let data = std::fs::read(path).unwrap();
        let positions = match read_ulog(&data) {
            Ok(log) => log.summary.positions,
            Err(_) => read_dataflash(&data).summary.positions,
        };
        csv += &format!("log{k},{}\n", path.display());
        expected.push(positions);
    }
    std::fs::write(dir.path().join("m.csv"), csv).unwrap();
    let out = crate::cli::savsim()
        .args(["batch", "--no-progress", "--out"])
        .arg(dir.path().join("out"))
        .arg(dir.path().join("m.csv"))
        .output()
        .unwrap();
    crate::common::assert_ran(&out);
    let batch = crate::batch::read(&dir.path().join("out/part-00000-of-00001.parquet"));
    use arrow_array::Array;
    let errors = batch.column_by_name("error").unwrap();
    assert_eq!(errors.null_count(), batch.num_rows(), "a row failed");
    let t = batch.column_by_name("ticks").unwrap();
    let t = t
        .as_any()
        .downcast_ref::<arrow_array::UInt64Array>()
        .unwrap();
    let ticks: Vec<u64> = t.values().to_vec();
    assert_eq!(ticks, expected);
}

/// A DataFlash log of ArduCopter SITL (Copter-4.5.6, `ADSB_LOG=2`, an ADS-B intruder fed by
/// savsim; trimmed to POS, ATT, ADSB and PARM by tests/fixtures/trim_dataflash.py): every
/// ADSB message is traffic, as pymavlink's DFReader reads it (raw columns: Lat/Lng 1e-7
/// degrees, Alt millimetres, Heading centidegrees, velocities cm/s).
#[test]
fn dataflash_adsb_messages_are_traffic_as_dfreader_reads_them() {
    if !crate::common::have_pymavlink() {
        return;
    }
    let path = crate::common::root().join("tests/fixtures/arducopter_adsb.bin");
    let code = format!(
        "import json\n\
         from pymavlink import DFReader\n\
         r = DFReader.DFReader_binary({:?}, zero_time_base=False)\n\
         out = []\n\
         while True:\n\
         \x20   m = r.recv_msg()\n\
         \x20   if m is None: break\n\
         \x20   if m.get_type() == 'ADSB' and (m.Lat, m.Lng) != (0, 0):\n\
         \x20       out.append([m.TimeUS, m.ICAO_address, m.Lat, m.Lng, m.Alt, m.Heading, m.Hor_vel, m.Ver_vel])\n\
         print(json.dumps(out))",
        path.display().to_string()
    );
    let expected: Vec<[f64; 8]> = serde_json::from_str(&crate::common::python_code(&code)).unwrap();
    assert!(expected.len() > 100, "{} ADSB messages", expected.len());

    let log = read_dataflash(&std::fs::read(&path).unwrap());
    let traffic: Vec<_> = log
        .reports
        .iter()
        .filter_map(|r| match &r.report {
            Report::Adsb(a) => Some((r.t_us, r.sender, *a)),
            _ => None,
        })
        .collect();
    assert_eq!(log.summary.traffic, expected.len() as u64);
    assert_eq!(traffic.len(), expected.len());
    for ((t_us, sender, a), e) in traffic.iter().zip(&expected) {
        assert_eq!(*t_us as f64, e[0]);
        assert_eq!(f64::from(a.icao_address), e[1]);
        assert!(
            (a.position.lat_deg - e[2] * 1e-7).abs() < 1e-12,
            "{a:?} {e:?}"
        );
        assert!(
            (a.position.lon_deg - e[3] * 1e-7).abs() < 1e-12,
            "{a:?} {e:?}"
        );
        assert!((a.position.alt_m - e[4] * 1e-3).abs() < 1e-9, "{a:?} {e:?}");
        assert!((a.heading_deg - e[5] * 0.01).abs() < 1e-9);
        assert!((a.horizontal_speed_mps - e[6] * 0.01).abs() < 1e-9);
        assert!((a.vertical_speed_mps - e[7] * 0.01).abs() < 1e-9);
        // Heard by the vehicle's receiver, never the vehicle itself.
        assert_eq!(sender.component_id, 156);
    }
    // The intruder was flown 37 m above home (584 m): the altitude is millimetres.
    let alt = traffic[0].2.position.alt_m;
    assert!((600.0..640.0).contains(&alt), "{alt} m");
    assert!(log.summary.positions > 1000 && log.summary.attitudes > 1000);
}
