//! One fixed step of a multicopter: rotors, drag and gravity, integrated semi-implicitly
//! (rates, then attitude; velocity, then position), then the ground and the obstacles it meets.

use glam::{DMat3, DQuat, DVec3};

use super::air::density_kgpm3;
use super::body::{Air, Body, Imu, Surroundings};
use super::frame::Frame;
use super::rotors::{force_and_torque, lagged, targets};
use super::GRAVITY_MPS2;

/// The shortest and longest step, seconds.
pub const STEP_RANGE_S: (f64, f64) = (0.0005, 0.02);
/// An IMU's accelerometer range, m/s^2 (16 g).
pub const IMU_RANGE_MPS2: f64 = 16.0 * GRAVITY_MPS2;
/// Body rates are held within this, rad/s (2000 degrees a second, an IMU's range).
pub const MAX_RATE_RADPS: f64 = 2000.0 * std::f64::consts::PI / 180.0;

/// Why a step was not taken (the body is left as it was).
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
pub enum StepError {
    /// The step is out of [`STEP_RANGE_S`].
    #[error("a step of {0} s (from {min} to {max} s)", min = STEP_RANGE_S.0, max = STEP_RANGE_S.1)]
    Step(f64),
    /// An output is not a number.
    #[error("output {0} is not a number")]
    Output(usize),
    /// The wind or home altitude is not finite.
    #[error("the air (wind, home altitude) is not finite")]
    Air,
    /// The state the step would make is not finite (the body, or what surrounds it, gave
    /// numbers out of range).
    #[error("the step would leave the body's state not finite")]
    NotFinite,
}

/// Move `body` of `frame` on by `dt_s`, its rotors driven by `outputs` (0..1 by output number;
/// `armed`: an armed rotor turns at least at its idle), in `air`, among `surroundings`. What
/// its IMU reads over the step: the ground's reaction not in it, as ArduPilot's SITL reads it
/// (a vehicle that lands hard reads the impact at the next step); an obstacle's blow in it,
/// within the IMU's range ([`IMU_RANGE_MPS2`]).
///
/// ```
/// use savsim_core::dynamics::{presets::preset, step, Air, Body, FlatGround};
/// let frame = preset("arducopter-quad").unwrap();
/// let mut body = Body::landed(&frame, 0.0, 0.0);
/// let air = Air { wind_ned_mps: glam::DVec3::ZERO, home_alt_m: 593.0 };
/// // Full throttle for a second: it climbs.
/// for _ in 0..400 {
///     step(&frame, &mut body, &[1.0; 4], true, &air, &FlatGround, 0.0025).unwrap();
/// }
/// assert!(body.position_ned_m.z < -5.0 && !body.on_ground);
/// ```
pub fn step(
    frame: &Frame,
    body: &mut Body,
    outputs: &[f64],
    armed: bool,
    air: &Air,
    surroundings: &dyn Surroundings,
    dt_s: f64,
) -> Result<Imu, StepError> {
    if !(STEP_RANGE_S.0..=STEP_RANGE_S.1).contains(&dt_s) {
        return Err(StepError::Step(dt_s));
    }
    if let Some(k) = outputs.iter().position(|u| !u.is_finite()) {
        return Err(StepError::Output(k));
    }
    if !(air.wind_ned_mps.is_finite() && air.home_alt_m.is_finite()) {
        return Err(StepError::Air);
    }
    let mut next = *body;
    let goal = targets(frame, outputs, armed);
    for (c, target) in next.commands.iter_mut().zip(goal).take(frame.rotors.len()) {
        *c = lagged(&frame.rotor_model, *c, target, dt_s);
    }
    let density = density_kgpm3(air.home_alt_m - body.position_ned_m.z);
    let frd_from_ned = body.ned_from_frd.inverse();
    let air_frd = frd_from_ned * (body.velocity_ned_mps - air.wind_ned_mps);
    let (mut force_frd, torque_frd) = force_and_torque(
        frame,
        &next.commands,
        density,
        air_frd,
        body.rates_frd_radps,
    );
    force_frd -= frame.drag_area_m2 * 0.5 * density * air_frd * air_frd.abs();
    // Rates first (Euler's equations, diagonal inertia), then the attitude with the new rates.
    let inertia = DVec3::from_array(frame.inertia_kgm2);
    let w = body.rates_frd_radps;
    let angular_accel =
        (torque_frd - w.cross(inertia * w)) / inertia - frame.rotational_damping_per_s * w;
    next.rates_frd_radps = (w + angular_accel * dt_s)
        .clamp(DVec3::splat(-MAX_RATE_RADPS), DVec3::splat(MAX_RATE_RADPS));
    let turn = DQuat::from_scaled_axis(next.rates_frd_radps * dt_s);
    next.ned_from_frd = (body.ned_from_frd * turn).normalize();
    // Velocity, then position with the new velocity.
    let gravity = DVec3::new(0.0, 0.0, GRAVITY_MPS2);
    let mut accel_ned = DMat3::from_quat(body.ned_from_frd) * (force_frd / frame.mass_kg) + gravity;
    if body.on_ground && accel_ned.z > 0.0 {
        accel_ned.z = 0.0;
    }
    let mut imu = Imu {
        accel_frd_mps2: frd_from_ned * (accel_ned - gravity),
        gyro_frd_radps: next.rates_frd_radps,
    };
    next.velocity_ned_mps = body.velocity_ned_mps + accel_ned * dt_s;
    next.position_ned_m = body.position_ned_m + next.velocity_ned_mps * dt_s;
    let flying_mps = next.velocity_ned_mps;
    stop_at_obstacles(frame, body, &mut next, surroundings);
    // The obstacle's blow is felt: the velocity it took, over the step, within the IMU's range.
    let blow_ned = (next.velocity_ned_mps - flying_mps) / dt_s;
    imu.accel_frd_mps2 = (imu.accel_frd_mps2 + frd_from_ned * blow_ned)
        .clamp(DVec3::splat(-IMU_RANGE_MPS2), DVec3::splat(IMU_RANGE_MPS2));
    rest_on_ground(frame, &mut next, surroundings);
    if !(next.is_finite() && imu.accel_frd_mps2.is_finite()) {
        return Err(StepError::NotFinite);
    }
    *body = next;
    Ok(imu)
}

/// An obstacle on the way stops the body at its surface: it goes no further than where it
/// touches, and keeps only the part of its velocity along the surface.
fn stop_at_obstacles(frame: &Frame, from: &Body, next: &mut Body, surroundings: &dyn Surroundings) {
    next.against_obstacle = false;
    let (p0, p1) = (from.position_ned_m, next.position_ned_m);
    let Some((fraction, normal)) = surroundings.first_contact(p0, p1, frame.radius_m) else {
        return;
    };
    if !(fraction.is_finite() && normal.is_finite()) {
        return;
    }
    let normal = normal.normalize_or_zero();
    next.position_ned_m = p0 + (p1 - p0) * fraction.clamp(0.0, 1.0);
    let into = next.velocity_ned_mps.dot(normal);
    if into < 0.0 {
        next.velocity_ned_mps -= into * normal;
    }
    next.against_obstacle = true;
}

/// On or below the ground under it: on it, level (its heading kept), not moving but upward, not
/// turning (ArduPilot's SITL multicopter on the ground).
fn rest_on_ground(frame: &Frame, next: &mut Body, surroundings: &dyn Surroundings) {
    let p = next.position_ned_m;
    let rest_down_m = surroundings.ground_down_m(p.x, p.y) - frame.rest_height_m;
    next.on_ground = rest_down_m.is_finite() && p.z >= rest_down_m;
    if !next.on_ground {
        return;
    }
    next.position_ned_m.z = rest_down_m;
    let (yaw, _, _) = next.ned_from_frd.to_euler(glam::EulerRot::ZYX);
    next.ned_from_frd = DQuat::from_rotation_z(yaw);
    next.velocity_ned_mps = DVec3::new(0.0, 0.0, next.velocity_ned_mps.z.min(0.0));
    next.rates_frd_radps = DVec3::ZERO;
}
