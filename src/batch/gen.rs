//! `savsim batch gen-encounters`: a deterministic set of pairwise encounters whose closest
//! approach is known by construction.
//!
//! Each encounter is two level, straight, constant-speed tracks in the scene's ENU frame (open
//! air around ArduPilot SITL's home unless a scene is given), drawn from a ChaCha8 stream
//! seeded with `seed` (the same manifest on every machine):
//!
//! | quantity | distribution |
//! |---|---|
//! | time of closest approach | uniform, 1/3 to 2/3 of the duration |
//! | ownship position then | uniform in a 3 km square around the origin, 120 to 300 m up |
//! | ownship speed, course | uniform 5 to 30 m/s, uniform 0 to 360 deg |
//! | intruder speed, course | uniform 10 to 60 m/s, uniform 0 to 360 deg (redrawn while the relative speed is under 1 m/s) |
//! | horizontal miss distance | uniform 0 to 500 m, on a random side |
//! | vertical miss distance | uniform -100 to 100 m (intruder above positive) |
//!
//! The intruder is placed so that, relative to the ownship, it passes the point at the miss
//! distances at the time of closest approach, perpendicular to the (horizontal) relative
//! velocity: so that is the closest approach, at those distances, and the pair is an NMAC
//! exactly when the horizontal miss is under 500 ft and the vertical under 100 ft. About 9%
//! of encounters are NMACs.

use glam::DVec3;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use crate::batch::manifest::Run;
use crate::daa::approach::{NMAC_HORIZONTAL_M, NMAC_VERTICAL_M};
use crate::error::{Error, Result};
use crate::pipeline::Mode;
use crate::scene::Kind;

/// What to generate.
#[derive(Debug, Clone)]
pub struct GenOptions {
    /// How many encounters.
    pub n: usize,
    /// The random stream's seed.
    pub seed: u64,
    /// A scene for every run (none: open air).
    pub scene: Option<String>,
    /// Collision mode for every run.
    pub mode: String,
    /// Length of each encounter, seconds.
    pub duration_s: f64,
    /// Ownship samples per second.
    pub rate_hz: f64,
    /// The intruder's kind.
    pub intruder_kind: String,
}

/// The most encounters one `gen-encounters` writes (what that many weigh: docs/batch.md).
pub const MAX_GENERATED: usize = 10_000_000;

/// A two-point waypoint track: at `start` at 0 s, flying `velocity` for `duration_s`.
fn straight(start: DVec3, velocity: DVec3, duration_s: f64) -> String {
    let end = start + velocity * duration_s;
    format!(
        "0 {} {} {}; {} {} {} {}",
        start.x, start.y, start.z, duration_s, end.x, end.y, end.z
    )
}

/// Options that make no sense are a usage error.
pub fn check(options: &GenOptions) -> Result<()> {
    use savsim_core::bounds::{positive, MAX_DURATION_S, MAX_RATE_HZ};
    positive(
        "duration_s (--duration-s)",
        options.duration_s,
        MAX_DURATION_S,
    )?;
    positive("rate_hz (--rate-hz)", options.rate_hz, MAX_RATE_HZ)?;
    if options.n > MAX_GENERATED {
        return Err(Error::Usage(format!(
            "--n {}: at most {MAX_GENERATED} encounters a file (shard a larger study)",
            options.n
        )));
    }
    if Mode::from_name(&options.mode).is_none() {
        return Err(Error::Usage(format!("mode {:?}: not a mode", options.mode)));
    }
    if Kind::from_name(&options.intruder_kind).is_none() {
        return Err(Error::Usage(format!(
            "intruder kind {:?}: not a kind (a320, b737, dji, airship, balloon, ...)",
            options.intruder_kind
        )));
    }
    Ok(())
}

/// The encounters, as manifest rows; options that make no sense are a usage error.
///
/// ```
/// use savsim::batch::gen::{encounters, GenOptions};
/// let options = GenOptions { n: 3, seed: 7, scene: None, mode: "exact".into(),
///     duration_s: 180.0, rate_hz: 10.0, intruder_kind: "dji".into() };
/// let a = encounters(&options).unwrap();
/// assert_eq!(a, encounters(&options).unwrap()); // deterministic
/// assert_eq!(a[2].id.as_deref(), Some("enc-000002"));
/// ```
pub fn encounters(options: &GenOptions) -> Result<Vec<Run>> {
    check(options)?;
    let mut rng = ChaCha8Rng::seed_from_u64(options.seed);
    let d = options.duration_s;
    let heading = |rng: &mut ChaCha8Rng, speed: f64| {
        let course = rng.random_range(0.0..std::f64::consts::TAU);
        DVec3::new(course.sin(), course.cos(), 0.0) * speed
    };
    Ok((0..options.n)
        .map(|i| {
            let t_cpa = rng.random_range(d / 3.0..=2.0 * d / 3.0);
            let own_at_cpa = DVec3::new(
                rng.random_range(-1500.0..=1500.0),
                rng.random_range(-1500.0..=1500.0),
                rng.random_range(120.0..=300.0),
            );
            let own_speed = rng.random_range(5.0..=30.0);
            let own_velocity = heading(&mut rng, own_speed);
            let intruder_velocity = loop {
                let speed = rng.random_range(10.0..=60.0);
                let v = heading(&mut rng, speed);
                if (v - own_velocity).length() >= 1.0 {
                    break v;
                }
            };
            let horizontal_m: f64 = rng.random_range(0.0..=500.0);
            let side = if rng.random_bool(0.5) { 1.0 } else { -1.0 };
            let vertical_m: f64 = rng.random_range(-100.0..=100.0);
            // Perpendicular to the relative velocity, in the horizontal plane.
            let across = (intruder_velocity - own_velocity)
                .normalize_or_zero()
                .cross(DVec3::Z)
                * side;
            let intruder_at_cpa = own_at_cpa + across * horizontal_m + DVec3::Z * vertical_m;
            Run {
                id: Some(format!("enc-{i:06}")),
                scene: options.scene.clone(),
                mode: Some(options.mode.clone()),
                own: Some(straight(own_at_cpa - own_velocity * t_cpa, own_velocity, d)),
                intruder: Some(straight(
                    intruder_at_cpa - intruder_velocity * t_cpa,
                    intruder_velocity,
                    d,
                )),
                intruder_kind: Some(options.intruder_kind.clone()),
                rate_hz: Some(options.rate_hz),
                duration_s: Some(d),
                expect_cpa_m: Some(horizontal_m.hypot(vertical_m)),
                expect_cpa_horizontal_m: Some(horizontal_m),
                expect_cpa_vertical_m: Some(vertical_m),
                expect_cpa_t_s: Some(t_cpa),
                expect_nmac: Some(
                    horizontal_m < NMAC_HORIZONTAL_M && vertical_m.abs() < NMAC_VERTICAL_M,
                ),
                seed: Some(options.seed),
                ..Run::default()
            }
        })
        .collect())
}
