//! The companion round trip: a frame with a 160 x 120 depth image (and its segmentation) out
//! to a planner in Python that answers one velocity, the commands back, parsed; through the
//! package's client (python/savsim/companion.py, loaded from the source tree by
//! tests/python/companion_planner.py in its `noop` behaviour). Prints the round trips'
//! percentiles over 2,000 frames; `cargo bench --bench companion`. Figures in
//! docs/performance.md.

// criterion is not used: a percentile of single round trips is the goal, not a mean.
#![allow(missing_docs)]

use std::sync::atomic::AtomicBool;
use std::sync::Arc;
use std::time::{Duration, Instant};

use glam::{DQuat, DVec3};
use savsim::companion::link::Link;
use savsim::companion::protocol::{self, FrameOut, State};
use savsim::feed::capture::{Capture, CaptureData};
use savsim_core::sensors::image::DepthImage;

fn main() {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
    let dir = tempfile::tempdir().expect("a folder");
    let command = format!(
        "python3 {} noop",
        root.join("tests/python/companion_planner.py").display()
    );
    let never = AtomicBool::new(false);
    let timeout = Duration::from_secs(20);
    let mut link = Link::start(&command, dir.path(), timeout, &never).expect("it starts");
    let mut hello = Vec::new();
    protocol::message(
        &protocol::hello(&protocol::Hello {
            system_id: 1,
            px4: false,
            devices: &["cam".into()],
            hz: 30.0,
            latency_s: 0.0,
            clock: protocol::Clock::Lockstep,
        }),
        &[],
        &mut hello,
    );
    link.tell(&hello).expect("hello");
    let (w, h) = (160u32, 120u32);
    let n = (w * h) as usize;
    let image = DepthImage {
        width_px: w,
        height_px: h,
        depth_m: (0..n).map(|i| i as f32 * 1e-3).collect(),
        segment_id: vec![7; n],
        class: vec![1; n],
    };
    let capture = Arc::new(Capture {
        device: "cam".into(),
        system_id: 1,
        instant_s: 0.0,
        origin_enu_m: DVec3::ZERO,
        enu_from_device: DQuat::IDENTITY,
        data: CaptureData::Depth {
            image,
            fov_deg: [87.0, 58.0],
        },
    });
    let truth = State {
        position_enu_m: DVec3::ZERO,
        velocity_enu_mps: DVec3::ZERO,
        attitude_deg: [0.0; 3],
    };
    let (mut payload, mut message) = (Vec::new(), Vec::new());
    let mut trips = Vec::new();
    for seq in 0..2_200u64 {
        let began = Instant::now();
        let frame = FrameOut {
            seq,
            t_s: seq as f64 / 30.0,
            truth,
            estimate: Some((DVec3::ZERO, 0.0)),
            intent_enu_mps: Some(DVec3::X),
            captures: std::slice::from_ref(&capture),
            traffic: &[],
        };
        protocol::frame(&frame, &mut payload, &mut message);
        let commands = link.ask(seq, &message).expect("an answer");
        assert_eq!(commands.len(), 1);
        // The first 200 warm up.
        if seq >= 200 {
            trips.push(began.elapsed().as_secs_f64() * 1e3);
        }
    }
    trips.sort_by(f64::total_cmp);
    let at = |q: f64| trips[((trips.len() as f64 * q).ceil() as usize).min(trips.len()) - 1];
    println!(
        "companion round trip, 160 x 120 depth + segmentation ({} bytes a frame), {} frames: \
         median {:.3} ms, p99 {:.3} ms, max {:.3} ms",
        message.len(),
        trips.len(),
        at(0.5),
        at(0.99),
        at(1.0)
    );
}
