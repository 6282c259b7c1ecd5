//! Scene TOML text through the parser and loaders, with the files it names read from memory
//! (every name is missing but `m.obj`, a small mesh). Skipped: generated terrain (up to 20,000
//! cells a side is allowed, and generating that much takes minutes by design).
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    if text.contains("generated") {
        return;
    }
    let mut files = savsim::scene::MemoryFiles::default();
    files.insert("m.obj", b"v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 2 3\nf 1 2 4\n".to_vec());
    if let Ok(scene) = savsim::scene::format::parse(text, "fuzz.toml".as_ref(), "fuzz", &files) {
        // What a run does first with a scene: bounds, octree, one mesh per geometry.
        let _ = scene.bounds_enu_m();
        let pipeline = savsim::pipeline::Pipeline::new(&scene, Default::default());
        let _ = pipeline.octree().node_count();
        for g in scene.geometries.iter().take(4) {
            let _ = g.triangle_count();
        }
    }
});
