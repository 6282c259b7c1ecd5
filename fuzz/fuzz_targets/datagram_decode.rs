//! Bytes as UDP datagrams and as a TCP stream (split where the input says), through the live
//! path's framing, decode and world store.
#![no_main]

use libfuzzer_sys::fuzz_target;
use savsim::pipeline::CollisionConfig;
use savsim::links::stream::{frames_in_datagram, StreamFramer};
use savsim::session::Session;

fuzz_target!(|data: &[u8]| {
    let Some((&split, rest)) = data.split_first() else {
        return;
    };
    // As datagrams of at most `split + 1` bytes each.
    let mut session = Session::new(None, CollisionConfig::default(), None).unwrap();
    let mut t_s = 1.0e9;
    for datagram in rest.chunks(usize::from(split) + 1) {
        t_s += 0.01;
        let skipped = frames_in_datagram(datagram, |frame| {
            let _ = session.on_frame(t_s, frame);
        });
        skipped.count_into(session.stats_mut());
    }
    // As one TCP stream read in pieces of the same size.
    let mut framer = StreamFramer::default();
    for piece in rest.chunks(usize::from(split) + 1) {
        let skipped = framer.push(piece, |frame| {
            let _ = session.on_frame(t_s, frame);
        });
        skipped.count_into(session.stats_mut());
    }
    let _ = session.summary("fuzz", "fuzz");
});
