//! Devices as written: a `[[sensor]]` table of a scene or a run's sensor file, or a preset's
//! name with settings (`adsb-1090es:nacp=7`). Every field is optional over the preset it
//! names; [`DeviceSpec::build`] (`sensors::build`) checks each and says which field is wrong.
//!
//! ```
//! use savsim_core::sensors::spec::DeviceSpec;
//! let spec: DeviceSpec = toml::from_str(r#"
//!     name = "nose"
//!     preset = "tfmini"
//!     mount = { pitch_deg = -90.0 }
//!     range_m = [0.3, 8.0]
//! "#).unwrap();
//! let device = spec.build().unwrap();
//! assert_eq!(device.mount.pitch_deg, -90.0);
//! let bad: DeviceSpec = toml::from_str("preset = \"tfmini\"\nrate_hz = 0.0").unwrap();
//! assert!(bad.build().unwrap_err().to_string().contains("rate_hz"));
//! ```

use serde::Deserialize;

/// A device as written. Fields that do not apply to its kind are errors.
#[derive(Debug, Clone, Default, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DeviceSpec {
    /// Its name (default: the preset's).
    pub name: Option<String>,
    /// The preset it starts from (`realsense-d435`, `rplidar-a2`, `tfmini`, `adsb-1090es`,
    /// `adsb-uat`, `radar-appq`, `eoir-appq`...).
    pub preset: Option<String>,
    /// `range`, `adsb`, `radar` or `eoir`, for a device without a preset.
    pub kind: Option<String>,
    /// Where it sits and looks.
    pub mount: Option<MountSpec>,
    /// Readings a second, vehicle's clock.
    pub rate_hz: Option<f64>,
    /// Latency, seconds.
    pub latency_s: Option<f64>,

    /// Range: field of view across and up-down, degrees.
    pub fov_deg: Option<[f64; 2]>,
    /// Range: angle between rays, degrees.
    pub step_deg: Option<[f64; 2]>,
    /// Range: a single beam's width, degrees.
    pub beam_deg: Option<f64>,
    /// Range: a depth image of this many pixels across and down (a pinhole camera over
    /// `fov_deg`, one ray through each pixel's centre) in place of a grid of rays.
    pub image_px: Option<[u32; 2]>,
    /// Range: a multi-channel lidar's rows (lasers), spread evenly over `fov_deg`'s second
    /// in place of `step_deg`'s second.
    pub channels: Option<u32>,
    /// Range (and radar): nearest and farthest distance, metres.
    pub range_m: Option<[f64; 2]>,
    /// Range: white noise sigma, metres.
    pub sigma_m: Option<f64>,
    /// Range: noise as a fraction of the distance.
    pub proportional: Option<f64>,
    /// Range: stereo matcher RMS error, pixels.
    pub stereo_subpixel_px: Option<f64>,
    /// Range: stereo focal length, pixels.
    pub stereo_focal_px: Option<f64>,
    /// Range: stereo baseline, metres.
    pub stereo_baseline_m: Option<f64>,
    /// Range: bias half-width per run, metres.
    pub bias_m: Option<f64>,
    /// Range: correlated error sigma, metres.
    pub markov_sigma_m: Option<f64>,
    /// Range: correlated error time constant, seconds.
    pub markov_tau_s: Option<f64>,
    /// Range: rounding, metres.
    pub quantum_m: Option<f64>,
    /// Range: chance a reading is lost.
    pub dropout: Option<f64>,
    /// Range: chance a burst of lost readings starts.
    pub burst_enter: Option<f64>,
    /// Range: mean burst length, readings.
    pub burst_mean_readings: Option<f64>,
    /// Range: chance one ray is invalid.
    pub invalid_ray: Option<f64>,
    /// Range: chance of a false echo per ray.
    pub false_return: Option<f64>,

    /// ADS-B: navigation accuracy category for position (1 to 11).
    pub nacp: Option<u8>,
    /// ADS-B: navigation accuracy category for velocity (1 to 4).
    pub nacv: Option<u8>,
    /// ADS-B: correlation time of the position and velocity errors, seconds.
    pub tau_s: Option<f64>,
    /// ADS-B: position error sigma per axis, metres, in place of NACp's.
    pub position_sigma_m: Option<f64>,
    /// ADS-B: velocity error sigma per axis, m/s, in place of NACv's.
    pub velocity_sigma_mps: Option<f64>,
    /// ADS-B: vertical rate error scale (Laplace), m/s.
    pub vertical_rate_b_mps: Option<f64>,
    /// ADS-B: altimetry bias by ICAO Annex 10.
    pub annex10_altimetry: Option<bool>,
    /// ADS-B: altitude rounding, feet.
    pub altitude_quantum_ft: Option<f64>,
    /// ADS-B: reception, `[[within_m, window_s], ...]`, nearest first.
    pub reception: Option<Vec<[f64; 2]>>,
    /// ADS-B: latency jitter, seconds.
    pub latency_jitter_s: Option<f64>,

    /// Radar and EO/IR: field of regard half-angles, degrees.
    pub field_of_regard_deg: Option<[f64; 2]>,
    /// Radar: range sigma, metres.
    pub range_sigma_m: Option<f64>,
    /// Radar: range bias half-width, metres.
    pub range_bias_m: Option<f64>,
    /// Radar: range-rate sigma, m/s.
    pub range_rate_sigma_mps: Option<f64>,
    /// Radar: range-rate bias half-width, m/s.
    pub range_rate_bias_mps: Option<f64>,
    /// Radar: angle sigma, degrees.
    pub angle_sigma_deg: Option<f64>,
    /// Radar: angle bias half-width, degrees.
    pub angle_bias_deg: Option<f64>,

    /// EO/IR: farthest range, metres.
    pub max_range_m: Option<f64>,
    /// EO/IR: angle sigma, milliradians.
    pub angle_sigma_mrad: Option<f64>,
    /// EO/IR: range error's correlation time, seconds.
    pub range_tau_s: Option<f64>,
    /// EO/IR: range error as a fraction of the range.
    pub range_proportional: Option<f64>,
}

/// A mount as written (every field optional: 0).
#[derive(Debug, Clone, Default, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MountSpec {
    /// Offset, body FRD, metres.
    pub position_frd_m: Option<[f64; 3]>,
    /// Yaw, degrees clockwise from the nose.
    pub yaw_deg: Option<f64>,
    /// Pitch, degrees up.
    pub pitch_deg: Option<f64>,
}

/// Why a device definition cannot be used: the device, the field and what is wrong.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("sensor {device:?}: {field}: {why}")]
pub struct SpecError {
    /// The device (its name, or its preset).
    pub device: String,
    /// The field.
    pub field: &'static str,
    /// What is wrong.
    pub why: String,
}
