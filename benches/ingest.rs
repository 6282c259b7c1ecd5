//! Criterion: tlog decode throughput (bytes/s) on the bundled flight, and the framer alone.
//! The comparison with pymavlink is `cargo run --release --example ingest_vs_pymavlink`.

// criterion_group! makes an undocumented function.
#![allow(missing_docs)]

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use savsim::codec::frame::{scan, Scan};
use savsim::codec::Ingestor;
use savsim::logs::tlog::TlogReader;

fn decode_tlog(c: &mut Criterion) {
    let bytes = std::fs::read(savsim::bundled::bundled(savsim::bundled::DEMO_FLIGHT)).unwrap();
    let mut group = c.benchmark_group("ingest");
    group.throughput(Throughput::Bytes(bytes.len() as u64));
    group.bench_function("tlog_decode_demo_flight", |b| {
        b.iter(|| {
            let mut ingestor = Ingestor::default();
            let mut reader = TlogReader::new(&bytes[..]);
            let mut n = 0;
            while let Some(r) = reader.next_record(&mut ingestor.stats).unwrap() {
                n += usize::from(ingestor.frame(&r.frame).is_some());
            }
            n
        })
    });
    group.bench_function("frame_scan_demo_flight", |b| {
        b.iter(|| {
            let mut at = 8;
            let mut n = 0;
            while at < bytes.len() {
                match scan(&bytes[at..]) {
                    Scan::Frame(f) => {
                        n += 1;
                        at += f.len + 8;
                    }
                    _ => break,
                }
            }
            n
        })
    });
    group.finish();
}

criterion_group!(benches, decode_tlog);
criterion_main!(benches);
