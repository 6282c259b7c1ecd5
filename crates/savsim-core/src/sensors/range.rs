//! What a range device reads: its beams (directions in the device's frame), and each reading
//! made from the true distances along them by the device's errors: invalid rays, false
//! returns, the noise (constant, proportional, stereo), the run's bias, the correlated error,
//! rounding, readings lost alone or in bursts, and the limits of its range.

use glam::DVec3;

use crate::sensors::device::RangeModel;
use crate::sensors::draws::{mix, Draws};
use crate::sensors::errors::{quantise, uniform_bias, MarkovState, MAX_STEPS};

/// What one beam of a reading says.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum BeamReading {
    /// A return at this distance, metres.
    Range(f64),
    /// Nothing within the device's range.
    Clear,
    /// No reading: an invalid ray, a return nearer than the device reads, a lost reading.
    NoData,
}

/// The channels a range device draws from (each its own stream).
#[derive(Debug, Clone, Copy)]
#[repr(u64)]
enum Channel {
    Invalid = 1,
    False = 2,
    FalseRange = 3,
    Noise = 4,
    Lost = 5,
    Burst = 6,
    Bias = 7,
    Markov = 8,
}

/// A range device's state on one vehicle: its correlated error, its bursts, its last instant.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct RangeState {
    markov: MarkovState,
    in_burst: bool,
    burst_instant: Option<u64>,
}

/// What is true along one beam: the nearest return's distance (`None`: nothing within range)
/// and the cosine of the beam's angle from the device's boresight (a stereo camera's error is
/// on the depth along its optical axis, not on the slant range).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BeamTruth {
    /// The nearest return along the beam, metres.
    pub distance_m: Option<f64>,
    /// The cosine of the beam's angle from the boresight (1 along it).
    pub axial_cos: f64,
}

impl BeamTruth {
    /// The truth along `beam` (its first ray is its centre, in the device's frame, x along the
    /// boresight) at `distance_m`.
    pub fn along(beam: &Beam, distance_m: Option<f64>) -> Self {
        BeamTruth {
            distance_m,
            axial_cos: beam.first().map_or(1.0, |d| d.x),
        }
    }
}

/// The least cosine a stereo error is carried back to the slant range with: a beam 89.9
/// degrees off a camera's axis (no stereo camera sees so wide).
const MIN_AXIAL_COS: f64 = 1e-3;

/// A beam: the rays cast for it (one, or a single beam's centre and edge) in the device's frame
/// (x along its boresight, y to its right, z down), unit vectors.
pub type Beam = smallvec::SmallVec<[DVec3; 5]>;

impl RangeModel {
    /// The device's beams in its frame, across then up-down (row by row from the top): a grid
    /// over its field of view at its steps, centred on the boresight; a field of 360 degrees
    /// wraps without its last ray.
    ///
    /// ```
    /// use savsim_core::sensors::spec::DeviceSpec;
    /// use savsim_core::sensors::device::Model;
    /// let spec = DeviceSpec { preset: Some("rplidar-a2".into()), ..DeviceSpec::default() };
    /// let Model::Range(lidar) = spec.build().unwrap().model else { panic!() };
    /// assert_eq!(lidar.beams().len(), 800); // 360 / 0.45
    /// let spec = DeviceSpec { preset: Some("tfmini".into()), ..DeviceSpec::default() };
    /// let Model::Range(beam) = spec.build().unwrap().model else { panic!() };
    /// assert_eq!((beam.beams().len(), beam.beams()[0].len()), (1, 5));
    /// ```
    pub fn beams(&self) -> Vec<Beam> {
        if let Some([w, h]) = self.image_px {
            return pinhole_rays(w, h, self.fov_deg)
                .map(|d| Beam::from_elem(d, 1))
                .collect();
        }
        let angles = |fov: f64, step: f64| -> Vec<f64> {
            if fov <= 0.0 || step <= 0.0 {
                return vec![0.0];
            }
            if fov >= 360.0 {
                let n = (360.0 / step).round().max(1.0) as usize;
                return (0..n)
                    .map(|i| -180.0 + i as f64 * 360.0 / n as f64)
                    .collect();
            }
            let n = (fov / step).floor() as usize;
            let first = -(n as f64) * step / 2.0;
            (0..=n).map(|i| first + i as f64 * step).collect()
        };
        let across = angles(self.fov_deg[0], self.step_deg[0]);
        let up_down = match self.channels {
            Some(n) => channel_angles(n, self.fov_deg[1]),
            None => angles(self.fov_deg[1], self.step_deg[1]),
        };
        let mut out = Vec::with_capacity(across.len() * up_down.len());
        for &el in up_down.iter().rev() {
            for &az in &across {
                out.push(self.beam(az, el));
            }
        }
        out
    }

    /// A spinning device's turn: the columns (beams across) it sweeps, in [`Self::beams`]
    /// order within each row (from 180 degrees left of its boresight, turning right, as a
    /// Velodyne or an RPLIDAR turns seen from above). `None` for an image, or a field across of
    /// less than a whole turn: that device reads at once.
    ///
    /// ```
    /// use savsim_core::sensors::spec::DeviceSpec;
    /// use savsim_core::sensors::device::Model;
    /// let build = |p: &str| DeviceSpec { preset: Some(p.into()), ..DeviceSpec::default() }.build();
    /// let Model::Range(vlp16) = build("velodyne-vlp16").unwrap().model else { panic!() };
    /// assert_eq!(vlp16.turn_columns(), Some(1800));
    /// let Model::Range(d435) = build("realsense-d435").unwrap().model else { panic!() };
    /// assert_eq!(d435.turn_columns(), None);
    /// ```
    pub fn turn_columns(&self) -> Option<usize> {
        let spins = self.image_px.is_none() && self.fov_deg[0] >= 360.0 && self.step_deg[0] > 0.0;
        spins.then(|| (360.0 / self.step_deg[0]).round().max(1.0) as usize)
    }

    /// The beam at azimuth `az_deg` (right of the boresight) and elevation `el_deg` (up).
    fn beam(&self, az_deg: f64, el_deg: f64) -> Beam {
        let mut beam = Beam::new();
        beam.push(direction(az_deg, el_deg));
        if self.beam_deg > 0.0 {
            let h = self.beam_deg / 2.0;
            for (da, de) in [(h, 0.0), (-h, 0.0), (0.0, h), (0.0, -h)] {
                beam.push(direction(az_deg + da, el_deg + de));
            }
        }
        beam
    }

    /// The noise's standard deviation on the range, metres, at true distance `d_m` along a beam
    /// at `axial_cos` to the boresight: the constant and proportional terms on the range; a
    /// stereo camera's on the depth `z = d axial_cos`, carried back along the beam
    /// (`sigma_z(z) / axial_cos`), so that the depth a pixel reads has the stereo law's sigma.
    ///
    /// ```
    /// use savsim_core::sensors::spec::DeviceSpec;
    /// use savsim_core::sensors::device::Model;
    /// let spec = DeviceSpec { preset: Some("realsense-d435".into()), ..DeviceSpec::default() };
    /// let Model::Range(d435) = spec.build().unwrap().model else { panic!() };
    /// // A wall 5 m ahead: along the axis, and 40 degrees off it (6.53 m along the ray).
    /// let c = 40f64.to_radians().cos();
    /// let on_axis = d435.sigma_at(5.0, 1.0);
    /// assert!((d435.sigma_at(5.0 / c, c) * c - on_axis).abs() < 1e-12);
    /// ```
    pub fn sigma_at(&self, d_m: f64, axial_cos: f64) -> f64 {
        let stereo = self.stereo.map_or(0.0, |s| {
            let c = axial_cos.max(MIN_AXIAL_COS);
            s.sigma_m(d_m * c) / c
        });
        self.sigma_m + self.proportional * d_m + stereo
    }

    /// The reading at the device's instant `k` (instants `dt_s` apart from the start of the
    /// vehicle's clock) from what is true along each beam, written to `out`. Draws are keyed by `key` (the run, vehicle and device), the channel,
    /// the beam and `k`: the readings do not depend on when they were asked. False when the
    /// whole reading is lost (then `out` holds `NoData`).
    pub fn read(
        &self,
        state: &mut RangeState,
        draws: &Draws,
        key: u64,
        (k, dt_s): (u64, f64),
        truths: &[BeamTruth],
        out: &mut [BeamReading],
    ) -> bool {
        let stream = |channel: Channel, beam: u64| mix(mix(key, channel as u64), beam);
        let lost = self.lost(state, draws, key, k)
            || (self.dropout > 0.0 && draws.uniform(stream(Channel::Lost, 0), k) < self.dropout);
        if lost {
            out.iter_mut().for_each(|r| *r = BeamReading::NoData);
            return false;
        }
        let bias = uniform_bias(draws, stream(Channel::Bias, 0), self.bias_m);
        let common = bias
            + self.markov.at(
                &mut state.markov,
                draws,
                stream(Channel::Markov, 0),
                k,
                dt_s,
            );
        let [near_m, far_m] = self.range_m;
        for (j, (truth, reading)) in truths.iter().zip(out.iter_mut()).enumerate() {
            let j = j as u64;
            if self.invalid_ray > 0.0
                && draws.uniform(stream(Channel::Invalid, j), k) < self.invalid_ray
            {
                *reading = BeamReading::NoData;
                continue;
            }
            let distance_m = if self.false_return > 0.0
                && draws.uniform(stream(Channel::False, j), k) < self.false_return
            {
                Some(near_m + (far_m - near_m) * draws.uniform(stream(Channel::FalseRange, j), k))
            } else {
                truth.distance_m
            };
            *reading = match distance_m {
                None => BeamReading::Clear,
                Some(d) if d < near_m => BeamReading::NoData,
                Some(d) if d > far_m => BeamReading::Clear,
                Some(d) => {
                    let sigma_m = self.sigma_at(d, truth.axial_cos);
                    let noise = sigma_m * draws.normal(stream(Channel::Noise, j), k);
                    let measured = quantise(d + common + noise, self.quantum_m);
                    if measured < near_m {
                        BeamReading::NoData
                    } else if measured > far_m {
                        BeamReading::Clear
                    } else {
                        BeamReading::Range(measured)
                    }
                }
            };
        }
        true
    }

    /// Whether instant `k` falls in a burst of lost readings, stepping the burst channel
    /// through every instant since the last asked (from instant 0 the first time).
    fn lost(&self, state: &mut RangeState, draws: &Draws, key: u64, k: u64) -> bool {
        let Some(burst) = self.burst else {
            return false;
        };
        let stream = mix(key, Channel::Burst as u64);
        let (mut i, mut in_burst) = match state.burst_instant {
            Some(last) if last <= k && k - last <= MAX_STEPS => (last, state.in_burst),
            _ => {
                let start = k.saturating_sub(MAX_STEPS);
                (start, draws.uniform(stream, start) < burst.enter)
            }
        };
        while i < k {
            i += 1;
            let u = draws.uniform(stream, i);
            in_burst = if in_burst {
                u >= 1.0 / burst.mean_readings
            } else {
                u < burst.enter
            };
        }
        state.in_burst = in_burst;
        state.burst_instant = Some(k);
        in_burst
    }
}

/// The elevations of `n` channels spread evenly over `fov_deg` (up-down, centred on the
/// boresight), lowest first; one channel looks along the boresight.
///
/// ```
/// use savsim_core::sensors::range::channel_angles;
/// assert_eq!(channel_angles(16, 30.0)[..3], [-15.0, -13.0, -11.0]);
/// assert_eq!(channel_angles(16, 30.0)[15], 15.0);
/// assert_eq!(channel_angles(1, 30.0), [0.0]);
/// ```
pub fn channel_angles(n: u32, fov_deg: f64) -> Vec<f64> {
    if n <= 1 {
        return vec![0.0];
    }
    let step = fov_deg / f64::from(n - 1);
    (0..n)
        .map(|i| -fov_deg / 2.0 + f64::from(i) * step)
        .collect()
}

/// A pinhole image's focal length across, pixels: half its width over the tangent of half
/// its field of view (446.8 for 848 pixels over 87 degrees).
///
/// ```
/// assert!((savsim_core::sensors::range::focal_px(848, 87.0) - 446.8).abs() < 0.05);
/// ```
pub fn focal_px(width_px: u32, fov_across_deg: f64) -> f64 {
    f64::from(width_px) / 2.0 / (fov_across_deg / 2.0).to_radians().tan()
}

/// The rays of a pinhole image `w` x `h` pixels whose field of view is `fov_deg` (across and
/// down, edge to edge): through each pixel's centre, row by row from the top left, in the
/// device's frame (x along the optical axis, y right, z down), unit vectors. Pixel `(u, v)`'s
/// ray is `(1, (u + 0.5 - w/2) / fx, (v + 0.5 - h/2) / fy)` normalised, with `fx = w / 2 /
/// tan(fov across / 2)` and `fy` alike.
///
/// ```
/// use savsim_core::sensors::range::pinhole_rays;
/// let rays: Vec<_> = pinhole_rays(2, 2, [90.0, 90.0]).collect();
/// // The four pixels' centres sit half way to the edges: tan(a) = 0.5.
/// let a = 0.5f64.atan();
/// assert!((rays[0].y / rays[0].x + 0.5).abs() < 1e-12 && rays[0].z < 0.0);
/// assert!((rays[3].z / rays[3].x - a.tan()).abs() < 1e-12);
/// ```
pub fn pinhole_rays(w: u32, h: u32, fov_deg: [f64; 2]) -> impl Iterator<Item = DVec3> {
    let tan = |fov: f64| (fov / 2.0).to_radians().tan();
    let (tx, ty) = (tan(fov_deg[0]), tan(fov_deg[1]));
    let (wf, hf) = (f64::from(w), f64::from(h));
    (0..h).flat_map(move |v| {
        (0..w).map(move |u| {
            let y = (f64::from(u) + 0.5 - wf / 2.0) / (wf / 2.0) * tx;
            let z = (f64::from(v) + 0.5 - hf / 2.0) / (hf / 2.0) * ty;
            DVec3::new(1.0, y, z).normalize_or_zero()
        })
    })
}

/// The unit vector at azimuth `az_deg` (right) and elevation `el_deg` (up) in a forward-right-
/// down frame.
pub fn direction(az_deg: f64, el_deg: f64) -> DVec3 {
    let (az, el) = (az_deg.to_radians(), el_deg.to_radians());
    DVec3::new(el.cos() * az.cos(), el.cos() * az.sin(), -el.sin())
}
