//! OpenStreetMap files through savsim's reader: the input read as OSM XML (when it is UTF-8)
//! and as OSM PBF, and what reads assembled into building footprints (rings joined from member
//! ways, parts preferred) and their heights. No input may panic or hang.
//!
//! The `osmpbf` crate panics on some crafted blocks (an integer overflow in its dense-node
//! decoding, debug assertions on); `scene::osm::parse_pbf` contains that with `catch_unwind`
//! and returns an error. libFuzzer's panic hook aborts before an unwind can be caught, so this
//! target puts back a silent hook: a panic anywhere else still aborts (libfuzzer-sys catches
//! the unwind at the top and aborts).
#![no_main]

use libfuzzer_sys::fuzz_target;
use savsim::scene::osm;

static QUIET: std::sync::Once = std::sync::Once::new();

fuzz_target!(|data: &[u8]| {
    QUIET.call_once(|| std::panic::set_hook(Box::new(|_| {})));
    let mut read = Vec::new();
    if let Ok(text) = std::str::from_utf8(data) {
        read.extend(osm::parse_xml(text).ok());
    }
    read.extend(osm::parse_pbf(data).ok());
    for data in read {
        let (footprints, _) = osm::footprints(&data);
        for f in footprints {
            let _ = osm::heights(&f.tags, osm::HeightPolicy::default());
        }
    }
});
