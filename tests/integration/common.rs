//! Helpers shared by the integration tests.

use std::path::{Path, PathBuf};
use std::process::Command;

use glam::{DQuat, DVec3};
use savsim::geo::{Geodetic, LocalTangentPlane};
use savsim::world::{Attitude, TrackSample};

/// The crate's root.
pub fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// ../shared/fixtures, if present.
pub fn shared_fixtures() -> Option<PathBuf> {
    let p = root().join("../shared/fixtures");
    if p.is_dir() {
        Some(p)
    } else {
        eprintln!("SKIP: ../shared/fixtures is absent");
        None
    }
}

/// True when `python3 -c "import pymavlink"` works; says so when it does not.
pub fn have_pymavlink() -> bool {
    let ok = Command::new("python3")
        .args(["-c", "import pymavlink"])
        .output()
        .map(|o| o.status.success())
        .unwrap_or(false);
    if !ok {
        assert!(
            std::env::var_os("SAVSIM_REQUIRE_PYTHON").is_none(),
            "pymavlink is required here (SAVSIM_REQUIRE_PYTHON is set) but not importable"
        );
        eprintln!("SKIP: pymavlink is not installed (pip install pymavlink; .ci/run does)");
    }
    ok
}

/// Run a Python script with arguments; return its stdout.
pub fn python(script: &Path, args: &[&str]) -> String {
    let out = Command::new("python3")
        .arg(script)
        .args(args)
        .output()
        .expect("python3 runs");
    assert!(
        out.status.success(),
        "{} failed: {}",
        script.display(),
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8(out.stdout).expect("utf-8")
}

/// A sample at `t_s` at ENU position `p` (relative to `origin`), flying along `velocity`,
/// with the nose along the velocity (or east when still).
pub fn sample(origin: Geodetic, t_s: f64, p: DVec3, velocity: DVec3) -> TrackSample {
    let plane = LocalTangentPlane::new(origin);
    let heading = if velocity.truncate().length() > 0.0 {
        velocity.y.atan2(velocity.x)
    } else {
        0.0
    };
    TrackSample {
        t_s,
        time_boot_ms: (t_s * 1000.0) as u32,
        position: plane.geodetic_from_enu_m(p),
        position_enu_m: p,
        velocity_enu_mps: velocity,
        attitude: Attitude {
            time_boot_ms: 0,
            enu_from_frd: DQuat::from_rotation_z(heading)
                * DQuat::from_rotation_x(std::f64::consts::PI),
            body_rates_radps: DVec3::ZERO,
        },
    }
}

/// Samples of a straight flight from `a` to `b` at `speed_mps`, `rate_hz` samples a second.
pub fn straight(
    origin: Geodetic,
    a: DVec3,
    b: DVec3,
    speed_mps: f64,
    rate_hz: f64,
) -> Vec<TrackSample> {
    let length = (b - a).length();
    let duration = length / speed_mps;
    let n = (duration * rate_hz).ceil() as usize;
    let velocity = (b - a) / duration;
    (0..=n)
        .map(|i| {
            let t = (i as f64 / rate_hz).min(duration);
            sample(origin, 1000.0 + t, a + velocity * t, velocity)
        })
        .collect()
}

/// Replay a tlog as fast as possible into `session` and finish it.
pub fn replay_session(path: &Path, session: &mut savsim::session::Session) {
    let shutdown = std::sync::atomic::AtomicBool::new(false);
    savsim::app::replay(path, savsim::app::Speed::Max, false, session, &shutdown).unwrap();
    session.finish().unwrap();
}

/// Replay a tlog as fast as possible into a new session (over `scene`, if given) and finish it.
pub fn replay_into_session(
    path: &Path,
    scene: Option<savsim::scene::Scene>,
) -> savsim::session::Session {
    let mut session = savsim::session::Session::new(
        scene.map(std::sync::Arc::new),
        savsim::collision::pipeline::CollisionConfig::default(),
        None,
    )
    .unwrap();
    replay_session(path, &mut session);
    session
}
