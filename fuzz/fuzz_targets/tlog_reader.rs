//! A tlog, as bytes, replayed through the whole path: reader (resync, truncation), decode,
//! world store and collision ticks over a small scene.
#![no_main]

use std::sync::{Arc, OnceLock};

use libfuzzer_sys::fuzz_target;
use savsim::pipeline::{CollisionConfig, Pipeline};
use savsim::logs::tlog::TlogReader;
use savsim::scene::Scene;
use savsim::session::Session;

/// What no input can change, built once: the scene, and its pipeline with every mesh and
/// exact shape built (each input runs on a clone, which shares them).
fn scene_and_pipeline() -> &'static (Arc<Scene>, Pipeline) {
    static BUILT: OnceLock<(Arc<Scene>, Pipeline)> = OnceLock::new();
    BUILT.get_or_init(|| {
        let text = include_str!("../scene.toml");
        let scene = savsim::scene::parse(text, "fuzz/scene.toml".as_ref(), "fuzz").unwrap();
        let mut pipeline = Pipeline::new(&scene, CollisionConfig::default());
        pipeline.build_every_mesh(&scene);
        (Arc::new(scene), pipeline)
    })
}

fuzz_target!(|data: &[u8]| {
    let (scene, pipeline) = scene_and_pipeline();
    let mut session = Session::with_pipeline(scene.clone(), pipeline.clone(), None).unwrap();
    let mut reader = TlogReader::new(data);
    loop {
        let record = match reader.next_record(session.stats_mut()) {
            Ok(Some(r)) => r,
            Ok(None) | Err(_) => break,
        };
        let t_s = record.timestamp_us as f64 * 1e-6;
        let _ = session.on_frame(t_s, &record.frame);
    }
    let _ = session.finish();
    let _ = session.summary("fuzz", "fuzz");
});
