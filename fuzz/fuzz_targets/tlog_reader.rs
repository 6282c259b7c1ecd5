//! A tlog, as bytes, replayed through the whole path: reader (resync, truncation), decode,
//! world store and collision ticks over a small scene.
#![no_main]

use std::sync::{Arc, OnceLock};

use libfuzzer_sys::fuzz_target;
use savsim::collision::pipeline::CollisionConfig;
use savsim::ingest::tlog::TlogReader;
use savsim::scene::Scene;
use savsim::session::Session;

fn scene() -> Arc<Scene> {
    static SCENE: OnceLock<Arc<Scene>> = OnceLock::new();
    SCENE
        .get_or_init(|| {
            let text = include_str!("../scene.toml");
            Arc::new(savsim::scene::format::parse(text, "fuzz/scene.toml".as_ref(), "fuzz").unwrap())
        })
        .clone()
}

fuzz_target!(|data: &[u8]| {
    let mut session = Session::new(Some(scene()), CollisionConfig::default(), None).unwrap();
    let mut reader = TlogReader::new(data);
    loop {
        let record = match reader.next_record(&mut session.ingestor.stats) {
            Ok(Some(r)) => r,
            Ok(None) | Err(_) => break,
        };
        let t_s = record.timestamp_us as f64 * 1e-6;
        let _ = session.on_frame(t_s, &record.frame);
    }
    let _ = session.finish();
    let _ = session.summary("fuzz", "fuzz");
});
