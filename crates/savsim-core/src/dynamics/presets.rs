//! Frames with the numbers of the models the autopilots are tuned on (docs/lockstep.md gives
//! each number's source):
//!
//! - `arducopter-quad` (ArduPilot SITL's default multicopter, `SIM_Frame`'s default model, in
//!   the plus layout `copter.parm`'s FRAME_TYPE 0 mixes for) and `arducopter-quad-x` (the same
//!   in X, for FRAME_TYPE 1): 3 kg, arms 0.35 m, hover at 0.39 of full thrust, expo 0.65, PWM
//!   1150..1950 turning the rotors, slew 150/s, body drag area 0.184 m^2 from its reference
//!   flight (15.08 m/s at 45 degrees at 593 m), momentum drag, inertia 0.023/0.023/0.046.
//! - `iris` (PX4's `none_iris` airframe is tuned on Gazebo's Iris, `iris.sdf`): 1.545 kg,
//!   inertia 0.029125/0.029125/0.055225, rotor speed `1000 u + 100` rad/s up to 1100, thrust
//!   5.84e-6 w^2, moment 0.06 T, spin-up 0.0125 s, spin-down 0.025 s, rotor drag 1.75e-4 w v.

use super::air::density_kgpm3;
use super::frame::{Frame, Rotor, RotorModel, Spin};
use super::GRAVITY_MPS2;

/// ArduPilot's quad motor angles (degrees from the nose toward the right, motors 1..4) in plus.
const PLUS_DEG: [f64; 4] = [90.0, -90.0, 0.0, 180.0];
/// The same in X.
const X_DEG: [f64; 4] = [45.0, -135.0, -45.0, 135.0];

/// The names [`preset`] knows.
pub const PRESETS: [&str; 3] = ["arducopter-quad", "arducopter-quad-x", "iris"];

/// The preset frame `name` ([`PRESETS`]).
///
/// ```
/// use savsim_core::dynamics::presets::preset;
/// let quad = preset("arducopter-quad").unwrap();
/// assert!((quad.thrust_to_weight() - 1.0 / 0.39).abs() < 1e-9);
/// assert!(preset("iris").unwrap().check().is_ok());
/// assert!(preset("jetpack").is_none());
/// ```
pub fn preset(name: &str) -> Option<Frame> {
    match name {
        "arducopter-quad" => Some(arducopter(name, PLUS_DEG)),
        "arducopter-quad-x" => Some(arducopter(name, X_DEG)),
        "iris" => Some(iris()),
        _ => None,
    }
}

/// The frame an autopilot's own tuning flies when nothing names one: ArduPilot SITL's quad
/// (plus, as `copter.parm` mixes) for ArduCopter, the Iris for PX4 (`px4`); its preset name
/// and the frame.
///
/// ```
/// use savsim_core::dynamics::presets::{default_for, preset};
/// let (name, frame) = default_for(true);
/// assert_eq!((name, Some(frame)), ("iris", preset("iris")));
/// ```
pub fn default_for(px4: bool) -> (&'static str, Frame) {
    if px4 {
        ("iris", iris())
    } else {
        let name = "arducopter-quad";
        (name, arducopter(name, PLUS_DEG))
    }
}

/// ArduPilot SITL's default multicopter with its four motors at `angles_deg` (from the nose
/// toward the right; motors 1 and 2 counter-clockwise, 3 and 4 clockwise, motor k on SERVOk).
fn arducopter(name: &str, angles_deg: [f64; 4]) -> Frame {
    let (mass_kg, arm_m, hover_out) = (3.0, 0.35, 0.39);
    // Its reference flight: level at 15.08 m/s leaning 45 degrees, at 593 m, hovering on
    // 29.3 A at 12.09 V; rotor discs 0.385 m^2 in all, momentum drag coefficient 0.2.
    let (speed_mps, lean_rad) = (15.08, 45f64.to_radians());
    let rho = density_kgpm3(593.0);
    let weight_n = mass_kg * GRAVITY_MPS2;
    let outflow_hover_mps = 2.0 * 29.3 * 12.09 / weight_n;
    let inflow_area_m2 = weight_n / (0.5 * rho * outflow_hover_mps.powi(2)) / 4.0;
    let momentum_drag = 0.2 * (rho * 0.385 / 4.0).sqrt();
    let lean_thrust_n = weight_n / lean_rad.cos();
    let momentum_drag_n =
        lean_rad.cos() * 0.2 * speed_mps * lean_rad.cos() * (lean_thrust_n * rho * 0.385).sqrt();
    let drag_area_m2 =
        (weight_n * lean_rad.tan() - momentum_drag_n) / (0.5 * rho * speed_mps.powi(2));
    let spins = [Spin::Ccw, Spin::Ccw, Spin::Cw, Spin::Cw];
    let rotors = angles_deg
        .iter()
        .zip(spins)
        .enumerate()
        .map(|(output, (deg, spin))| {
            let a = deg.to_radians();
            Rotor {
                position_frd_m: [arm_m * a.cos(), arm_m * a.sin(), 0.0],
                spin,
                output,
            }
        })
        .collect();
    let ring = mass_kg * (arm_m / 2.0).powi(2);
    Frame {
        name: name.into(),
        mass_kg,
        inertia_kgm2: [0.25 * ring, 0.25 * ring, 0.5 * ring],
        rotors,
        rotor_model: RotorModel {
            max_thrust_n: weight_n / (4.0 * hover_out),
            thrust_expo: 0.65,
            idle: 0.0,
            slew_per_s: Some(150.0),
            time_constant_up_s: 0.0,
            time_constant_down_s: 0.0,
            yaw_torque_per_thrust_m: 0.05 * arm_m,
            yaw_torque_scales_with_command: true,
            reference_air_density_kgpm3: Some(rho),
            inflow_area_m2: Some(inflow_area_m2),
            axial_speed_limit_mps: None,
            momentum_drag,
            momentum_drag_axial: true,
        },
        pwm_us: [1000.0, 2000.0],
        spin: [0.15, 0.95],
        drag_area_m2,
        rotational_damping_per_s: 400f64.to_radians() / 120.0,
        // The arm and a rotor's radius (a 0.35 m disc).
        radius_m: arm_m + 0.175,
        rest_height_m: 0.1,
    }
}

/// Gazebo's Iris, the model PX4's `none_iris` airframe is tuned on.
fn iris() -> Frame {
    let max_rad_s: f64 = 1100.0;
    let max_thrust_n = 5.84e-6 * max_rad_s.powi(2);
    let rotor = |x: f64, y: f64, spin, output| Rotor {
        position_frd_m: [x, y, 0.0],
        spin,
        output,
    };
    Frame {
        name: "iris".into(),
        // The base link and its IMU, four rotors and GPS links.
        mass_kg: 1.545,
        inertia_kgm2: [0.029125, 0.029125, 0.055225],
        rotors: vec![
            rotor(0.13, 0.22, Spin::Ccw, 0),
            rotor(-0.13, -0.20, Spin::Ccw, 1),
            rotor(0.13, -0.22, Spin::Cw, 2),
            rotor(-0.13, 0.20, Spin::Cw, 3),
        ],
        rotor_model: RotorModel {
            max_thrust_n,
            thrust_expo: 1.0,
            idle: 100.0 / max_rad_s,
            slew_per_s: None,
            time_constant_up_s: 0.0125,
            time_constant_down_s: 0.025,
            yaw_torque_per_thrust_m: 0.06,
            yaw_torque_scales_with_command: false,
            reference_air_density_kgpm3: None,
            inflow_area_m2: None,
            axial_speed_limit_mps: Some(25.0),
            // 1.75e-4 |w| v across the rotor, |w| = 1100 sqrt(T / T_max).
            momentum_drag: 1.75e-4 * max_rad_s / max_thrust_n.sqrt(),
            momentum_drag_axial: false,
        },
        pwm_us: [1000.0, 2000.0],
        spin: [0.0, 1.0],
        drag_area_m2: 0.0,
        rotational_damping_per_s: 0.0,
        radius_m: 0.2555 + 0.128,
        rest_height_m: 0.1,
    }
}
