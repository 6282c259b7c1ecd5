//! Tracks drawn from an MIT Lincoln Laboratory encounter model and placed for an encounter:
//! sampled until the model gives one, turned to a heading and moved to meet a point at the time
//! of closest approach (`batch gen-encounters --model` and `study gen --kind model` both draw
//! them so).

use glam::{DQuat, DVec3};
use rand_chacha::ChaCha8Rng;

use crate::daa::encounter_model::{track, Model, TrackPoint};
use crate::error::{Error, Result};

/// Tracks drawn for one encounter before the model is judged unable to give one.
const MAX_TRACK_TRIES: usize = 10_000;

/// A sampled track, turned by `heading_rad` about its start and moved so that it is at
/// `at_enu_m` at `tca_s`: its waypoints.
pub fn placed(
    track: &[TrackPoint],
    heading_rad: f64,
    tca_s: usize,
    at_enu_m: DVec3,
) -> Vec<(f64, DVec3)> {
    let turn = DQuat::from_rotation_z(-heading_rad);
    let shift = at_enu_m - turn * track[tca_s].position_enu_m;
    track
        .iter()
        .map(|p| (p.t_s, turn * p.position_enu_m + shift))
        .collect()
}

/// A track of `seconds` drawn from `model` (drawn again while the model gives none).
pub fn sample(model: &Model, seconds: usize, rng: &mut ChaCha8Rng) -> Result<Vec<TrackPoint>> {
    for _ in 0..MAX_TRACK_TRIES {
        if let Some(t) = track(model, seconds, rng) {
            return Ok(t);
        }
    }
    Err(Error::Usage(format!(
        "the model gave no acceptable {seconds} s track in {MAX_TRACK_TRIES} draws"
    )))
}

/// The velocity at `k` along placed waypoints (the second after it, or before it at the end).
pub fn velocity(points: &[(f64, DVec3)], k: usize) -> DVec3 {
    if k + 1 < points.len() {
        points[k + 1].1 - points[k].1
    } else {
        points[k].1 - points[k - 1].1
    }
}
