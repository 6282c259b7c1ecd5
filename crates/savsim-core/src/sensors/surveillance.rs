//! What surveillance devices report of other aircraft: ADS-B in (each aircraft's own report of
//! its state, with its navigation errors, by range and late), radar and EO/IR (the aircraft as
//! measured from the vehicle: range and angles with their errors, then placed from the
//! vehicle's own position). Truth in, reports out; every draw keyed by (run, vehicle, device,
//! target, channel, instant).

use glam::{DQuat, DVec3};

use crate::sensors::device::{AdsbModel, EoIrModel, Model, RadarModel};
use crate::sensors::draws::{mix, Draws};
use crate::sensors::errors::{quantise, uniform_bias, MarkovState};

/// A target's true state at an instant.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Target {
    /// A stable key for the aircraft (its ICAO address, or the scene's track).
    pub key: u64,
    /// Where it is, scene ENU metres.
    pub position_enu_m: DVec3,
    /// Its velocity, ENU m/s.
    pub velocity_enu_mps: DVec3,
    /// Its height above the ellipsoid, metres (what its altitude report is made from).
    pub altitude_m: f64,
}

/// The vehicle carrying the device, true, at the instant.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Own {
    /// Where it is, scene ENU metres.
    pub position_enu_m: DVec3,
    /// Its velocity, ENU m/s.
    pub velocity_enu_mps: DVec3,
    /// Its attitude: ENU from its body's forward-right-down axes.
    pub enu_from_frd: DQuat,
}

/// A report of a target, as made at its instant.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TargetReport {
    /// The target.
    pub key: u64,
    /// Position as reported, scene ENU metres.
    pub position_enu_m: DVec3,
    /// Velocity as reported, ENU m/s (its vertical part: the vertical rate).
    pub velocity_enu_mps: DVec3,
    /// Altitude as reported, metres (rounded to the device's quantum).
    pub altitude_m: f64,
    /// The error's standard deviation per horizontal axis of position, metres (what a
    /// tracker would be told: DAIDALUS's `s_EW_std`, `s_NS_std`).
    pub position_sigma_m: f64,
    /// ... of the altitude, metres.
    pub altitude_sigma_m: f64,
    /// ... per horizontal axis of velocity, m/s.
    pub velocity_sigma_mps: f64,
    /// ... of the vertical rate, m/s.
    pub vertical_rate_sigma_mps: f64,
    /// Extra delay of this report beyond the device's latency, seconds.
    pub jitter_s: f64,
}

/// Per-target error states (each channel's correlated error, and its tracker).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct TargetState {
    channels: [MarkovState; 4],
    /// Radar and EO/IR: the alpha-beta tracker's position and velocity, and its instant.
    track: Option<(DVec3, DVec3, u64)>,
}

/// Channels of a target's draws.
#[derive(Debug, Clone, Copy)]
#[repr(u64)]
enum Channel {
    Receive = 1,
    North = 2,
    East = 3,
    VelNorth = 4,
    VelEast = 5,
    VerticalRate = 6,
    Altimetry = 7,
    AltimetryLayer = 8,
    Jitter = 9,
    Range = 10,
    RangeBias = 11,
    Azimuth = 12,
    AzimuthBias = 13,
    Elevation = 14,
    ElevationBias = 15,
}

fn stream(key: u64, target: u64, channel: Channel) -> u64 {
    mix(mix(key, target), channel as u64)
}

/// ICAO Annex 10 altimetry error scales by layer (DEGAS's table): the layer's upper bound
/// (feet), lambda1 and lambda2 (feet), and the chance an intruder's is lambda1.
const ANNEX10: [(f64, f64, f64, f64); 6] = [
    (2300.0, 35.0, 60.0, 0.391),
    (5000.0, 38.0, 60.0, 0.320),
    (10_000.0, 43.0, 69.0, 0.345),
    (20_000.0, 58.0, 87.0, 0.610),
    (41_000.0, 72.0, 101.0, 0.610),
    (f64::INFINITY, 94.0, 101.0, 0.610),
];

/// An intruder's altimetry bias (metres): Laplace of a scale drawn by the altitude layer
/// (ICAO Annex 10; lambda1 with the layer's chance, else lambda2), once per run.
fn annex10_bias_m(draws: &Draws, key: u64, target: u64, altitude_m: f64) -> f64 {
    let feet = altitude_m / 0.3048;
    let (_, l1, l2, p1) = ANNEX10
        .iter()
        .copied()
        .find(|(top, ..)| feet < *top)
        .unwrap_or(ANNEX10[5]);
    let lambda_ft = if draws.uniform(stream(key, target, Channel::AltimetryLayer), 0) <= p1 {
        l1
    } else {
        l2
    };
    draws.laplace(stream(key, target, Channel::Altimetry), 0, lambda_ft) * 0.3048
}

/// How a surveillance device looks at its instant: the run's draws, the device's key (run,
/// vehicle, device), its instant `k` (instants `dt_s` apart from the vehicle's clock's start),
/// and the vehicle it is on.
#[derive(Clone, Copy)]
pub struct Look<'a> {
    /// The run's draws.
    pub draws: &'a Draws,
    /// The device's key.
    pub key: u64,
    /// The instant.
    pub k: u64,
    /// Seconds between instants.
    pub dt_s: f64,
    /// The vehicle.
    pub own: &'a Own,
}

impl Model {
    /// A surveillance device's report of `target` ([`AdsbModel::report`],
    /// [`RadarModel::report`], [`EoIrModel::report`]); a range device reports no aircraft.
    pub fn report(
        &self,
        state: &mut TargetState,
        look: &Look<'_>,
        target: &Target,
    ) -> Option<TargetReport> {
        match self {
            Model::Adsb(m) => m.report(state, look, target),
            Model::Radar(m) => m.report(state, look, target),
            Model::EoIr(m) => m.report(state, look, target),
            Model::Range(_) => None,
        }
    }
}

impl AdsbModel {
    /// The chance one report from `range_m` away gets through, at `rate_hz` reports a second.
    pub fn reception_at(&self, range_m: f64, rate_hz: f64) -> f64 {
        self.reception
            .iter()
            .find(|r| range_m <= r.within_m)
            .map_or(0.0, |r| r.per_report(rate_hz))
    }

    /// The report of `target` at the device's instant `k` (instants `dt_s` apart), or `None`
    /// when it does not get through. Position and velocity errors are Gauss-Markov per axis;
    /// the vertical rate's is Laplace, white; the altitude carries the target's altimetry bias
    /// and is rounded.
    pub fn report(
        &self,
        state: &mut TargetState,
        look: &Look<'_>,
        target: &Target,
    ) -> Option<TargetReport> {
        let (draws, key, k, dt_s, own) = (look.draws, look.key, look.k, look.dt_s, look.own);
        let t = target.key;
        let range_m = (target.position_enu_m - own.position_enu_m).length();
        let p = self.reception_at(range_m, 1.0 / dt_s);
        if draws.uniform(stream(key, t, Channel::Receive), k) >= p {
            return None;
        }
        let [n, e, vn, ve] = &mut state.channels;
        let north = self
            .position
            .at(n, draws, stream(key, t, Channel::North), k, dt_s);
        let east = self
            .position
            .at(e, draws, stream(key, t, Channel::East), k, dt_s);
        let v_north = self
            .velocity
            .at(vn, draws, stream(key, t, Channel::VelNorth), k, dt_s);
        let v_east = self
            .velocity
            .at(ve, draws, stream(key, t, Channel::VelEast), k, dt_s);
        let v_up = if self.vertical_rate_b_mps > 0.0 {
            draws.laplace(
                stream(key, t, Channel::VerticalRate),
                k,
                self.vertical_rate_b_mps,
            )
        } else {
            0.0
        };
        let bias = if self.annex10_altimetry {
            annex10_bias_m(draws, key, t, target.altitude_m)
        } else {
            0.0
        };
        let altitude_m = quantise(target.altitude_m + bias, self.altitude_quantum_m);
        let dz = altitude_m - target.altitude_m;
        Some(TargetReport {
            key: t,
            position_enu_m: target.position_enu_m + DVec3::new(east, north, dz),
            velocity_enu_mps: target.velocity_enu_mps + DVec3::new(v_east, v_north, v_up),
            altitude_m,
            position_sigma_m: self.position.sigma,
            altitude_sigma_m: self.altitude_quantum_m / 12f64.sqrt(),
            velocity_sigma_mps: self.velocity.sigma,
            vertical_rate_sigma_mps: std::f64::consts::SQRT_2 * self.vertical_rate_b_mps,
            jitter_s: self.latency_jitter_s * draws.uniform(stream(key, t, Channel::Jitter), k),
        })
    }
}

/// Azimuth (right of the nose) and elevation (up), radians, and range of `rel_enu` seen from a
/// body with attitude `enu_from_frd`.
fn body_angles(enu_from_frd: DQuat, rel_enu: DVec3) -> (f64, f64, f64) {
    let b = enu_from_frd.inverse() * rel_enu;
    let range = b.length();
    let az = b.y.atan2(b.x);
    let el = (-b.z).atan2((b.x * b.x + b.y * b.y).sqrt());
    (az, el, range)
}

/// The ENU offset at azimuth `az`, elevation `el` (radians) and `range` from a body with
/// attitude `enu_from_frd`.
fn from_body_angles(enu_from_frd: DQuat, az: f64, el: f64, range: f64) -> DVec3 {
    let b = DVec3::new(el.cos() * az.cos(), el.cos() * az.sin(), -el.sin()) * range;
    enu_from_frd * b
}

/// The alpha-beta tracker's gains: position and velocity.
const ALPHA: f64 = 0.5;
const BETA: f64 = 0.2;

/// Smooth a measured position into the target's track (alpha-beta filter at instants `dt_s`
/// apart; a track more than 5 instants old starts again): its position and velocity.
fn track(state: &mut TargetState, k: u64, dt_s: f64, measured: DVec3) -> (DVec3, DVec3) {
    let (p, v) = match state.track {
        Some((p, v, last)) if k > last && k - last <= 5 => {
            let dt = (k - last) as f64 * dt_s;
            let predicted = p + v * dt;
            let residual = measured - predicted;
            (predicted + ALPHA * residual, v + BETA / dt * residual)
        }
        _ => (measured, DVec3::ZERO),
    };
    state.track = Some((p, v, k));
    (p, v)
}

/// The body angles (azimuth, elevation, rad) and range (m) of `target` from `own` when it is
/// within a field of regard of `field_of_regard_deg` (either side of the nose, across and
/// up-down) and `range_m`; otherwise `None`, and the track is dropped.
fn in_view(
    state: &mut TargetState,
    own: &Own,
    target: &Target,
    [for_az, for_el]: [f64; 2],
    [near_m, far_m]: [f64; 2],
) -> Option<(f64, f64, f64)> {
    let rel = target.position_enu_m - own.position_enu_m;
    let (az, el, range) = body_angles(own.enu_from_frd, rel);
    let outside = az.abs() > for_az.to_radians()
        || el.abs() > for_el.to_radians()
        || range < near_m
        || range > far_m;
    if outside {
        state.track = None;
        return None;
    }
    Some((az, el, range))
}

/// A tracked report's sigmas: position (horizontal, an axis), altitude, velocity (and vertical
/// rate).
struct Sigmas {
    position_m: f64,
    altitude_m: f64,
    velocity_mps: f64,
}

/// The report of a sensor that measures where `target` is (`measured`, at instant `k`):
/// smoothed by the alpha-beta tracker, its altitude moved as the track moved it.
fn tracked(
    state: &mut TargetState,
    (k, dt_s): (u64, f64),
    measured: DVec3,
    target: &Target,
    sigmas: Sigmas,
) -> TargetReport {
    let (p, v) = track(state, k, dt_s, measured);
    TargetReport {
        key: target.key,
        position_enu_m: p,
        velocity_enu_mps: v,
        altitude_m: target.altitude_m + (p.z - target.position_enu_m.z),
        position_sigma_m: sigmas.position_m,
        altitude_sigma_m: sigmas.altitude_m,
        velocity_sigma_mps: sigmas.velocity_mps,
        vertical_rate_sigma_mps: sigmas.velocity_mps,
        jitter_s: 0.0,
    }
}

impl RadarModel {
    /// The radar's track of `target` at instant `k`, or `None` outside its field of regard or
    /// range. Range, azimuth and elevation get a white error and a bias per run; the measured
    /// position, placed from the vehicle's own, is smoothed by an alpha-beta tracker.
    pub fn report(
        &self,
        state: &mut TargetState,
        look: &Look<'_>,
        target: &Target,
    ) -> Option<TargetReport> {
        let (draws, key, k, dt_s, own) = (look.draws, look.key, look.k, look.dt_s, look.own);
        let t = target.key;
        let (az, el, range) = in_view(state, own, target, self.field_of_regard_deg, self.range_m)?;
        let s = |c| stream(key, t, c);
        let range_m = range
            + uniform_bias(draws, s(Channel::RangeBias), self.range_bias_m)
            + self.range_sigma_m * draws.normal(s(Channel::Range), k);
        let angle = |draws: &Draws, value: f64, noise: Channel, bias: Channel| {
            value
                + uniform_bias(draws, s(bias), self.angle_bias_deg.to_radians())
                + self.angle_sigma_deg.to_radians() * draws.normal(s(noise), k)
        };
        let az = angle(draws, az, Channel::Azimuth, Channel::AzimuthBias);
        let el = angle(draws, el, Channel::Elevation, Channel::ElevationBias);
        let measured =
            own.position_enu_m + from_body_angles(own.enu_from_frd, az, el, range_m.max(0.0));
        let cross_m = range * self.angle_sigma_deg.to_radians();
        let sigmas = Sigmas {
            position_m: cross_m.max(self.range_sigma_m),
            altitude_m: cross_m,
            velocity_mps: self.range_rate_sigma_mps,
        };
        Some(tracked(state, (k, dt_s), measured, target, sigmas))
    }
}

impl EoIrModel {
    /// The camera's track of `target` at instant `k`, or `None` beyond its range or field of
    /// regard. Angles get a white error; the range a Gauss-Markov error whose sigma grows with
    /// the range; the measured position is smoothed by an alpha-beta tracker.
    pub fn report(
        &self,
        state: &mut TargetState,
        look: &Look<'_>,
        target: &Target,
    ) -> Option<TargetReport> {
        let (draws, key, k, dt_s, own) = (look.draws, look.key, look.k, look.dt_s, look.own);
        let t = target.key;
        let field = self.field_of_regard_deg;
        let (az, el, range) = in_view(state, own, target, field, [0.0, self.max_range_m])?;
        let s = |c| stream(key, t, c);
        // The correlated range error, unit sigma, scaled by this instant's sigma (DEGAS's
        // range-proportional colored noise).
        let unit = crate::sensors::errors::GaussMarkov {
            sigma: 1.0,
            tau_s: self.range_tau_s,
        };
        let sigma_m = self.range_sigma_m + self.range_proportional * range;
        let range_m =
            range + sigma_m * unit.at(&mut state.channels[0], draws, s(Channel::Range), k, dt_s);
        let mrad = self.angle_sigma_mrad * 1e-3;
        let az = az + mrad * draws.normal(s(Channel::Azimuth), k);
        let el = el + mrad * draws.normal(s(Channel::Elevation), k);
        let measured =
            own.position_enu_m + from_body_angles(own.enu_from_frd, az, el, range_m.max(0.0));
        let sigmas = Sigmas {
            position_m: sigma_m.max(range * mrad),
            altitude_m: range * mrad,
            velocity_mps: sigma_m / self.range_tau_s.max(dt_s),
        };
        Some(tracked(state, (k, dt_s), measured, target, sigmas))
    }
}
