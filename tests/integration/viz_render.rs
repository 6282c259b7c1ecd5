//! The demo's recording as a person sees it: rendered by rerun-sdk's own native viewer, headless
//! (Xvfb, software Vulkan), with savsim's default layout. The check cannot pass on a blank or
//! mis-framed picture: the vehicle's own colour must be where the chase view's eye looks.
//!
//! Needs `Xvfb` (apt: xvfb), a Vulkan driver (apt: mesa-vulkan-drivers) and the `rerun` CLI
//! (pip: rerun-sdk==0.36.3); skipped with a message without them, unless
//! `SAVSIM_REQUIRE_RENDERER` is set (`.ci/run` sets it and installs them).

use std::io::{BufRead, BufReader};
use std::path::Path;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use crate::common::root;

/// The first vehicle's colour (`savsim::viz::VEHICLE_COLORS[0]`), as shaded by the viewer:
/// strongly red, much less green, blue in between.
fn is_vehicle_pink([r, g, b]: [u8; 3]) -> bool {
    let (r, g, b) = (i32::from(r), i32::from(g), i32::from(b));
    r >= 180 && g <= 150 && b >= 120 && r - g >= 80 && (r - b).abs() <= 110
}

fn have(program: &str, arg: &str) -> bool {
    Command::new(program)
        .arg(arg)
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .status()
        .is_ok()
}

/// An X server on a display it picks itself (`-displayfd`); killed on drop.
struct Xvfb {
    child: Child,
    display: String,
}

impl Xvfb {
    fn start() -> Self {
        // A screen much larger than the window, so the pointer (at the screen's centre) is not
        // over the viewer and no tooltip covers the picture.
        let mut child = Command::new("Xvfb")
            .args([
                "-displayfd",
                "1",
                "-screen",
                "0",
                "5200x3400x24",
                "-nolisten",
                "tcp",
            ])
            .stdout(Stdio::piped())
            .stderr(Stdio::null())
            .spawn()
            .expect("Xvfb starts");
        let mut line = String::new();
        BufReader::new(child.stdout.take().unwrap())
            .read_line(&mut line)
            .unwrap();
        let display = format!(":{}", line.trim());
        assert!(display.len() > 1, "Xvfb gave no display number");
        Self { child, display }
    }
}

impl Drop for Xvfb {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// Render `rrd` with the native viewer at 1280x800 points into `png`: a fresh viewer state (no
/// layout or window size persisted from earlier runs), its gRPC server on 127.0.0.1 only.
pub fn screenshot(rrd: &Path, png: &Path) {
    let x = Xvfb::start();
    let state = tempfile::tempdir().unwrap();
    let mut viewer = Command::new("rerun")
        .args([
            "--bind",
            "127.0.0.1",
            "--port",
            "0",
            "--window-size",
            "1280x800",
        ])
        .arg("--screenshot-to")
        .arg(png)
        .arg(rrd)
        .env("DISPLAY", &x.display)
        .env("XDG_DATA_HOME", state.path())
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    // It writes the PNG, then may exit non-zero; give it three minutes on two cores.
    let started = Instant::now();
    while viewer.try_wait().unwrap().is_none() {
        if started.elapsed() > Duration::from_secs(180) {
            let _ = viewer.kill();
            break;
        }
        std::thread::sleep(Duration::from_millis(200));
    }
    let _ = viewer.wait();
}

/// Whether recordings can be rendered here (Xvfb and the rerun CLI); without them a test
/// skips with a message, or fails when `SAVSIM_REQUIRE_RENDERER` is set.
pub fn can_render() -> bool {
    if have("Xvfb", "-help") && have("rerun", "--version") {
        return true;
    }
    assert!(
        std::env::var_os("SAVSIM_REQUIRE_RENDERER").is_none(),
        "Xvfb and the rerun CLI are required here but missing"
    );
    eprintln!(
        "SKIP: no headless renderer (apt-get install xvfb mesa-vulkan-drivers; \
         pip install rerun-sdk==0.36.3; .ci/run does)"
    );
    false
}

/// A row's recording as it opens: the pure red pixels (the collision marker and its label,
/// `COLLISION v1 ...`, and the body's forward axis) in its chase view (the top-left half of
/// the window); a second picture when the first shows fewer than `at_least` (the viewer may
/// take it before the file has loaded).
pub fn collision_pixels_in_chase_view(rrd: &Path, name: &str, at_least: usize) -> usize {
    let png = Path::new(env!("CARGO_TARGET_TMPDIR")).join(format!("{name}.png"));
    let mut found = 0;
    for _ in 0..2 {
        let _ = std::fs::remove_file(&png);
        screenshot(rrd, &png);
        assert!(
            png.exists(),
            "the viewer wrote no screenshot of {}",
            rrd.display()
        );
        found = count_in(
            &png,
            |(x, y), (w, h)| x < w / 2 && y > h / 10 && y < h * 72 / 100,
            |[r, g, b]| r >= 235 && g <= 30 && b <= 30,
        );
        if found >= at_least {
            break;
        }
    }
    found
}

/// Pixels of `png` in the region `inside` ((x, y), (width, height)) whose colour `is`.
fn count_in(
    png: &Path,
    inside: impl Fn((usize, usize), (usize, usize)) -> bool,
    is: impl Fn([u8; 3]) -> bool,
) -> usize {
    let decoder = png::Decoder::new(BufReader::new(std::fs::File::open(png).unwrap()));
    let mut reader = decoder.read_info().unwrap();
    let mut pixels = vec![0; reader.output_buffer_size().unwrap()];
    let info = reader.next_frame(&mut pixels).unwrap();
    let (w, h) = (info.width as usize, info.height as usize);
    let channels = info.line_size / w;
    assert!(channels >= 3, "{:?}", info.color_type);
    (0..h)
        .flat_map(|y| (0..w).map(move |x| (x, y)))
        .filter(|&(x, y)| inside((x, y), (w, h)))
        .filter(|&(x, y)| {
            let i = y * info.line_size + x * channels;
            is([pixels[i], pixels[i + 1], pixels[i + 2]])
        })
        .count()
}

#[test]
fn the_demo_recording_shows_the_vehicle_in_its_chase_view() {
    if !can_render() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let rrd = dir.path().join("demo.rrd");
    let out = Command::new(env!("CARGO_BIN_EXE_savsim"))
        .current_dir(root())
        .args(["demo", "--rerun"])
        .arg(format!("save={}", rrd.display()))
        .output()
        .unwrap();
    crate::common::assert_ran(&out);
    // Kept after the run (target/tmp/), to look at when this fails.
    let png = Path::new(env!("CARGO_TARGET_TMPDIR")).join("viz_render_demo.png");
    // The viewer takes its screenshot ten frames after it starts, whatever it has loaded by
    // then (software rendering is slow, so that can be part of the file): a second picture
    // is taken when the first shows no vehicle.
    let mut found = Vec::new();
    for _ in 0..2 {
        let _ = std::fs::remove_file(&png);
        screenshot(&rrd, &png);
        assert!(png.exists(), "the viewer wrote no screenshot");
        let n = vehicle_pixels_near_chase_centre(&png);
        found.push(n);
        if n >= 200 {
            return;
        }
    }
    panic!("vehicle-coloured pixels near the chase view's centre, per picture: {found:?}");
}

/// Pixels of the vehicle's colour around where the chase view's eye looks.
fn vehicle_pixels_near_chase_centre(png: &Path) -> usize {
    // The layout: the chase view is the top-left half of the window (below the menu bar,
    // above the time series), its eye looking at the vehicle from behind and above.
    count_in(
        png,
        |(x, y), (w, h)| {
            let (cx, cy) = (w / 4, h * 2 / 5);
            let (dx, dy) = (w * 8 / 100, h * 12 / 100);
            x + dx >= cx && x < cx + dx && y + dy >= cy && y < cy + dy
        },
        is_vehicle_pink,
    )
}
