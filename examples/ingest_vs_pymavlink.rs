//! Tlog decode throughput of savsim next to pymavlink's, on the same file in one run.
//!
//! usage: cargo run --release --example ingest_vs_pymavlink [FILE.tlog]
//! (default: the bundled demo flight). Needs python3 with pymavlink.

use std::process::Command;
use std::time::Instant;

use savsim::codec::Ingestor;
use savsim::logs::tlog::TlogReader;

fn main() {
    let path = std::env::args().nth(1).unwrap_or_else(|| {
        savsim::bundled::bundled(savsim::bundled::DEMO_FLIGHT)
            .display()
            .to_string()
    });
    let bytes = std::fs::read(&path).expect("read the tlog");
    let repeats = 20;
    let started = Instant::now();
    let mut messages = 0u64;
    let mut decoded = 0u64;
    for _ in 0..repeats {
        let mut ingestor = Ingestor::default();
        let mut reader = TlogReader::new(&bytes[..]);
        while let Some(record) = reader.next_record(&mut ingestor.stats).expect("in memory") {
            decoded += u64::from(ingestor.frame(&record.frame).is_some());
        }
        messages += ingestor.stats.messages_total();
    }
    let ours_s = started.elapsed().as_secs_f64();
    let mb = (bytes.len() * repeats) as f64 / 1e6;
    println!("file: {path} ({} bytes)", bytes.len());
    println!(
        "savsim:    {:>10.1} MB/s {:>12.0} messages/s ({messages} messages, {decoded} reports, {ours_s:.3} s)",
        mb / ours_s,
        messages as f64 / ours_s
    );
    let script = concat!(env!("CARGO_MANIFEST_DIR"), "/benches/pymavlink_decode.py");
    let out = Command::new("python3")
        .args([script, &path, "1"])
        .output()
        .expect("python3");
    if !out.status.success() {
        eprintln!("pymavlink failed: {}", String::from_utf8_lossy(&out.stderr));
        std::process::exit(1);
    }
    let theirs: serde_json::Value = serde_json::from_slice(&out.stdout).expect("json");
    let their_s = theirs["seconds"].as_f64().unwrap();
    let their_msgs = theirs["messages"].as_f64().unwrap();
    let their_mb = theirs["bytes"].as_f64().unwrap() / 1e6;
    println!(
        "pymavlink: {:>10.1} MB/s {:>12.0} messages/s ({their_msgs} messages, {their_s:.3} s)",
        their_mb / their_s,
        their_msgs / their_s
    );
    println!(
        "ratio (savsim / pymavlink, messages/s): {:.1}x",
        (messages as f64 / ours_s) / (their_msgs / their_s)
    );
}
