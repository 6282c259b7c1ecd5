//! A tlog, as bytes, replayed with the closed-loop feed on: every frame a vehicle's sample
//! casts (sectors and bins against the scene's exact shapes and its terrain, the rangefinder,
//! ADS-B and COLLISION for the scene's track and the other vehicles), paced on each
//! vehicle's fuzzed clock. The first byte picks the feed's kinds and rate.
#![no_main]

use std::sync::{Arc, OnceLock};

use libfuzzer_sys::fuzz_target;
use savsim::pipeline::{CollisionConfig, Pipeline};
use savsim::feed::{FeedConfig, FeedKinds};
use savsim::logs::tlog::TlogReader;
use savsim::scene::Scene;
use savsim::session::Session;

/// The scene and its pipeline, built once (each input runs on a clone, which shares them).
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

const KINDS: [&str; 4] = [
    "proximity,rangefinder,adsb,collision",
    "obstacle-distance,rangefinder,adsb,collision",
    "proximity,adsb",
    "obstacle-distance,collision",
];

fuzz_target!(|data: &[u8]| {
    let Some((&choice, tlog)) = data.split_first() else {
        return;
    };
    let (scene, pipeline) = scene_and_pipeline();
    let mut session = Session::with_pipeline(scene.clone(), pipeline.clone(), None).unwrap();
    let config = FeedConfig {
        kinds: FeedKinds::parse(KINDS[usize::from(choice & 3)]).unwrap(),
        hz: [5.0, 20.0, 50.0, 400.0][usize::from(choice >> 2 & 3)],
        ..FeedConfig::default()
    };
    session.start_feed(config).unwrap();
    let mut reader = TlogReader::new(tlog);
    loop {
        let record = match reader.next_record(session.stats_mut()) {
            Ok(Some(r)) => r,
            Ok(None) | Err(_) => break,
        };
        let t_s = record.timestamp_us as f64 * 1e-6;
        let _ = session.on_frame(t_s, &record.frame);
        // What live mode sends: encoded by the feed's identity, then dropped.
        session.drain_feed().for_each(drop);
    }
    let _ = session.finish();
    let _ = session.summary("fuzz", "fuzz");
});
