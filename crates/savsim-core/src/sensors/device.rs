//! A device as savsim simulates it, validated: where it sits on the vehicle, how often it
//! reads and how late its readings arrive, and its model: a range sensor (rays) or a
//! surveillance sensor (tracks of other aircraft). Built from a [`DeviceSpec`]
//! (`crate::sensors::spec`) or a preset (`crate::sensors::presets`).
//!
//! [`DeviceSpec`]: crate::sensors::spec::DeviceSpec

use crate::sensors::errors::GaussMarkov;

/// Where a device sits on the vehicle: its offset from the vehicle's reference point in the
/// body frame (forward, right, down; metres), and where it looks: yaw clockwise from the nose
/// and pitch up from the body's horizontal plane, degrees.
#[derive(Debug, Clone, Copy, Default, PartialEq, serde::Serialize)]
pub struct Mount {
    /// Offset, body FRD, metres.
    pub position_frd_m: [f64; 3],
    /// Yaw, degrees clockwise from the nose.
    pub yaw_deg: f64,
    /// Pitch, degrees up.
    pub pitch_deg: f64,
}

/// One simulated device.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct Device {
    /// Its name (unique on a vehicle).
    pub name: String,
    /// Where it sits and looks.
    pub mount: Mount,
    /// Readings (or reports) per second of the vehicle's clock.
    pub rate_hz: f64,
    /// How long after its instant a reading reaches the autopilot, seconds of the vehicle's
    /// clock.
    pub latency_s: f64,
    /// What it measures and how.
    pub model: Model,
}

/// What a device measures.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
#[serde(tag = "kind", rename_all = "kebab-case")]
pub enum Model {
    /// Distances along rays: a depth camera, a scanning lidar, a rangefinder.
    Range(RangeModel),
    /// ADS-B in: other aircraft's own reports of their position and velocity.
    Adsb(AdsbModel),
    /// An airborne radar: range, range rate and angles of other aircraft.
    Radar(RadarModel),
    /// An electro-optical or infrared camera: angles, and a range estimate.
    EoIr(EoIrModel),
}

/// A range sensor: a grid of rays (or one beam), the distances they read, and their errors.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct RangeModel {
    /// Field of view across (horizontal in the device's frame) and up-down, degrees; 0 for one
    /// line of rays.
    pub fov_deg: [f64; 2],
    /// Angle between rays across and up-down, degrees (0 along a field of 0).
    pub step_deg: [f64; 2],
    /// Width of a single beam (a rangefinder's), degrees: its edge is cast too (5 rays), the
    /// nearest return counts. 0 for a ray.
    pub beam_deg: f64,
    /// A depth image: pixels across and down of a pinhole camera whose field of view is
    /// `fov_deg` (edge to edge), one ray through each pixel's centre; `step_deg` unused.
    pub image_px: Option<[u32; 2]>,
    /// A multi-channel lidar's rows, spread evenly over `fov_deg`'s second (its first and last
    /// at the field's edges); `step_deg`'s second unused.
    pub channels: Option<u32>,
    /// Nearest and farthest distance it reads, metres; a return nearer than the first is
    /// invalid (no reading), none within the second is "nothing in range".
    pub range_m: [f64; 2],
    /// Noise per reading, white: this standard deviation, metres...
    pub sigma_m: f64,
    /// ... plus this fraction of the distance...
    pub proportional: f64,
    /// ... plus a stereo camera's depth error, growing with the square of the distance.
    pub stereo: Option<Stereo>,
    /// A bias drawn once per run, uniform in +- this, metres.
    pub bias_m: f64,
    /// An error shared by every ray of a reading, correlated in time.
    pub markov: GaussMarkov,
    /// Readings rounded to this, metres (0: not rounded).
    pub quantum_m: f64,
    /// The chance that a whole reading is lost.
    pub dropout: f64,
    /// Lost readings in bursts, when given.
    pub burst: Option<Burst>,
    /// The chance that one ray of a reading is invalid (no return: a depth camera's holes).
    pub invalid_ray: f64,
    /// The chance that a ray returns a false echo, at a distance uniform within its range.
    pub false_return: f64,
}

/// A stereo camera's depth error: `sigma_z = z^2 subpixel / (focal baseline)` (Intel's D400
/// depth RMS formula).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct Stereo {
    /// The matcher's RMS error, pixels (0.08 for a D435 at its best).
    pub subpixel_px: f64,
    /// Focal length, pixels (424 at 848 pixels across and 90 degrees).
    pub focal_px: f64,
    /// Baseline between the imagers, metres (0.05 for a D435).
    pub baseline_m: f64,
}

impl Stereo {
    /// The depth error's standard deviation at distance `z_m`, metres.
    ///
    /// ```
    /// use savsim_core::sensors::device::Stereo;
    /// let d435 = Stereo { subpixel_px: 0.08, focal_px: 424.0, baseline_m: 0.05 };
    /// assert!((d435.sigma_m(2.0) - 0.0151).abs() < 1e-4);
    /// ```
    pub fn sigma_m(&self, z_m: f64) -> f64 {
        z_m * z_m * self.subpixel_px / (self.focal_px * self.baseline_m)
    }
}

/// Readings lost in bursts (a Gilbert-Elliott channel): from a good reading the next is the
/// first of a burst with chance `enter`; a burst lasts `mean_readings` on average (each of its
/// readings ends it with chance 1 / mean_readings).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct Burst {
    /// The chance a burst starts at a reading.
    pub enter: f64,
    /// Its mean length, readings (at least 1).
    pub mean_readings: f64,
}

/// How likely a report gets through within a range: the chance that at least one report in
/// `window_s` seconds arrives is 0.95 (DO-365 Appendix Q: 3 s out to 10 NM, 7 s to 20 NM).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct Reception {
    /// Out to this range, metres.
    pub within_m: f64,
    /// The window in which at least one report arrives with chance 0.95, seconds.
    pub window_s: f64,
}

impl Reception {
    /// The chance that one report gets through, for reports `rate_hz` a second:
    /// `1 - 0.05^(1 / (window rate))` (0.632 for 3 s at 1 Hz, 0.348 for 7 s).
    ///
    /// ```
    /// use savsim_core::sensors::device::Reception;
    /// let near = Reception { within_m: 18_520.0, window_s: 3.0 };
    /// assert!((near.per_report(1.0) - 0.6316).abs() < 1e-4);
    /// assert!((near.per_report(2.0) - 0.3930).abs() < 1e-4);
    /// ```
    pub fn per_report(&self, rate_hz: f64) -> f64 {
        1.0 - libm::pow(0.05, 1.0 / (self.window_s * rate_hz))
    }
}

/// ADS-B in (DO-365 Appendix Q): each report of another aircraft's position and velocity, with
/// the errors of its navigation source, gets through by range and arrives late.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct AdsbModel {
    /// Navigation accuracy category for position: the horizontal 95% bound it stands for
    /// gives the position error's sigma per axis.
    pub nacp: u8,
    /// Navigation accuracy category for velocity.
    pub nacv: u8,
    /// Horizontal position error per axis (sigma from NACp), metres.
    pub position: GaussMarkov,
    /// Horizontal velocity error per axis (sigma from NACv), m/s.
    pub velocity: GaussMarkov,
    /// Vertical rate error: Laplace, white, of this scale, m/s (2.02 ft/s: 336 fpm at 95%).
    pub vertical_rate_b_mps: f64,
    /// Altimetry bias: Laplace per run, scale by altitude layer (ICAO Annex 10).
    pub annex10_altimetry: bool,
    /// Altitude rounded to this, metres (25 ft for 1090ES and UAT, 100 ft for Gillham).
    pub altitude_quantum_m: f64,
    /// Reception by range, nearest first; none beyond the last.
    pub reception: Vec<Reception>,
    /// Extra latency per report, uniform in [0, this], seconds (DEGAS: 0 to 0.4 s).
    pub latency_jitter_s: f64,
}

/// An airborne radar (DO-365 Appendix Q): range, range rate, azimuth and elevation of every
/// aircraft within its field of regard, each with a white error and a bias per run.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct RadarModel {
    /// Nearest and farthest range, metres.
    pub range_m: [f64; 2],
    /// Field of regard: half-angles in azimuth and elevation, degrees.
    pub field_of_regard_deg: [f64; 2],
    /// Range error: sigma, metres...
    pub range_sigma_m: f64,
    /// ... and bias half-width, metres.
    pub range_bias_m: f64,
    /// Range rate error: sigma, m/s...
    pub range_rate_sigma_mps: f64,
    /// ... and bias half-width, m/s.
    pub range_rate_bias_mps: f64,
    /// Azimuth and elevation error: sigma, degrees...
    pub angle_sigma_deg: f64,
    /// ... and bias half-width, degrees.
    pub angle_bias_deg: f64,
}

/// An electro-optical or infrared camera (DO-365 Appendix Q): angles of every aircraft within
/// range, and a range estimate whose error grows with the range.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct EoIrModel {
    /// Farthest range, metres.
    pub max_range_m: f64,
    /// Field of regard: half-angles in azimuth and elevation, degrees (180, 90: all around).
    pub field_of_regard_deg: [f64; 2],
    /// Azimuth and elevation error, white, milliradians.
    pub angle_sigma_mrad: f64,
    /// Range error: Gauss-Markov of this correlation time, seconds...
    pub range_tau_s: f64,
    /// ... whose sigma is this, metres...
    pub range_sigma_m: f64,
    /// ... plus this fraction of the range.
    pub range_proportional: f64,
}

/// The horizontal 95% position bound of NACp `nacp`, metres (DO-260B; 0 and out of range:
/// none, `None`).
///
/// ```
/// use savsim_core::sensors::device::nacp_bound95_m;
/// assert_eq!(nacp_bound95_m(8), Some(92.6));
/// assert_eq!(nacp_bound95_m(7), Some(185.2));
/// assert_eq!(nacp_bound95_m(0), None);
/// ```
pub fn nacp_bound95_m(nacp: u8) -> Option<f64> {
    const NM: f64 = 1852.0;
    Some(match nacp {
        1 => 10.0 * NM,
        2 => 4.0 * NM,
        3 => 2.0 * NM,
        4 => NM,
        5 => 0.5 * NM,
        6 => 0.3 * NM,
        7 => 185.2,
        8 => 92.6,
        9 => 30.0,
        10 => 10.0,
        11 => 3.0,
        _ => return None,
    })
}

/// The horizontal 95% velocity bound of NACv `nacv`, m/s (DO-260B; 0 and out of range:
/// `None`).
///
/// ```
/// use savsim_core::sensors::device::nacv_bound95_mps;
/// assert_eq!(nacv_bound95_mps(2), Some(3.0));
/// ```
pub fn nacv_bound95_mps(nacv: u8) -> Option<f64> {
    Some(match nacv {
        1 => 10.0,
        2 => 3.0,
        3 => 1.0,
        4 => 0.3,
        _ => return None,
    })
}
