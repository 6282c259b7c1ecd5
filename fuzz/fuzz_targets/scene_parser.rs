//! Scene TOML text through the parser and loaders. Skipped: inputs naming a file (reading
//! /dev/zero or a huge file is not a parser bug) and generated terrain (up to 20,000 cells a
//! side is allowed, and generating that much takes minutes by design).
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    if text.contains("file") || text.contains("path") || text.contains("generated") {
        return;
    }
    if let Ok(scene) = savsim::scene::format::parse(text, "fuzz.toml".as_ref(), "fuzz") {
        // What a run does first with a scene: bounds, octree, one mesh per geometry.
        let _ = scene.bounds_enu_m();
        let pipeline = savsim::collision::pipeline::Pipeline::new(&scene, Default::default());
        let _ = pipeline.octree.node_count();
        for g in scene.geometries.iter().take(4) {
            let _ = g.triangle_count();
        }
    }
});
