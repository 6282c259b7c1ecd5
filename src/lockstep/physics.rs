//! A lockstep run's physics settings from text (a manifest's cells, flags): the frame, the
//! step and the wind, each checked.

use glam::DVec3;
use savsim_core::dynamics::presets::{preset, PRESETS};
use savsim_core::dynamics::step::STEP_RANGE_S;
use savsim_core::dynamics::Frame;

/// Why a physics setting is refused.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum PhysicsError {
    /// Not a preset, and not a frame file that reads.
    #[error("{0}")]
    Frame(String),
    /// A step out of range or not whole microseconds.
    #[error("{0}: give {lo} to {hi} ms in whole microseconds", lo = STEP_RANGE_S.0 * 1e3, hi = STEP_RANGE_S.1 * 1e3)]
    Step(f64),
    /// Not three numbers within 100 m/s.
    #[error("{0:?}: give `E N U` m/s, each within 100")]
    Wind(String),
}

/// A preset's frame, or one read from a TOML file.
///
/// ```
/// use savsim::lockstep::physics::frame_named;
/// assert!(frame_named("iris").is_ok());
/// // A file that cannot be read is named in the error.
/// let e = frame_named("/nonexistent/quad.toml").unwrap_err().to_string();
/// assert!(e.contains("/nonexistent/quad.toml"), "{e}");
/// ```
pub fn frame_named(name: &str) -> Result<Frame, PhysicsError> {
    if let Some(frame) = preset(name) {
        return Ok(frame);
    }
    if !name.ends_with(".toml") {
        return Err(PhysicsError::Frame(format!(
            "{name:?}: give a preset ({}) or a .toml file",
            PRESETS.join(", ")
        )));
    }
    let text = crate::files::read_text(std::path::Path::new(name), 1 << 20)
        .map_err(|e| PhysicsError::Frame(format!("{name}: {e}")))?;
    Frame::from_toml(&text).map_err(|e| PhysicsError::Frame(format!("{name}: {e}")))
}

/// A step of `step_ms` in microseconds.
///
/// ```
/// use savsim::lockstep::physics::step_us;
/// assert_eq!(step_us(2.5), Ok(2_500));
/// assert!(step_us(0.0).is_err() && step_us(1000.0).is_err() && step_us(2.5004).is_err());
/// ```
pub fn step_us(step_ms: f64) -> Result<u64, PhysicsError> {
    let us = (step_ms * 1000.0).round();
    let (lo, hi) = (STEP_RANGE_S.0 * 1e3, STEP_RANGE_S.1 * 1e3);
    if !(lo..=hi).contains(&step_ms) || (us - step_ms * 1000.0).abs() > 1e-6 {
        return Err(PhysicsError::Step(step_ms));
    }
    Ok(us as u64)
}

/// A wind of `E N U` m/s (the scene's frame, where the air goes), as NED.
///
/// ```
/// use savsim::lockstep::physics::wind_ned_mps;
/// assert_eq!(wind_ned_mps("3 4 0").unwrap(), glam::DVec3::new(4.0, 3.0, -0.0));
/// assert!(wind_ned_mps("3 4").is_err() && wind_ned_mps("1 1 NaN").is_err());
/// ```
pub fn wind_ned_mps(text: &str) -> Result<DVec3, PhysicsError> {
    let bad = || PhysicsError::Wind(text.to_string());
    let v: Vec<f64> = text
        .split_whitespace()
        .map(str::parse)
        .collect::<Result<_, _>>()
        .map_err(|_| bad())?;
    let [e, n, u] = <[f64; 3]>::try_from(v).map_err(|_| bad())?;
    if ![e, n, u].iter().all(|c| c.is_finite() && c.abs() <= 100.0) {
        return Err(bad());
    }
    Ok(DVec3::new(n, e, -u))
}
