//! The rotors' part of a step: each command lagged, and the thrust, torque and drag the rotors
//! put on the body.

use glam::DVec3;

use super::frame::{Frame, RotorModel, MAX_ROTORS};

/// Each rotor's command for `outputs` (the autopilot's outputs, 0..1, by output number; a
/// missing one is 0): the idle raised when `armed`, 0 when not.
pub(super) fn targets(frame: &Frame, outputs: &[f64], armed: bool) -> [f64; MAX_ROTORS] {
    let mut targets = [0.0; MAX_ROTORS];
    if !armed {
        return targets;
    }
    let idle = frame.rotor_model.idle;
    for (target, rotor) in targets.iter_mut().zip(&frame.rotors) {
        let u = outputs
            .get(rotor.output)
            .copied()
            .unwrap_or(0.0)
            .clamp(0.0, 1.0);
        *target = idle + (1.0 - idle) * u;
    }
    targets
}

/// `command` moved toward `target` over `dt_s`: rate limited, then lagged (first order, exact
/// for the step).
pub(super) fn lagged(model: &RotorModel, command: f64, target: f64, dt_s: f64) -> f64 {
    let mut next = target;
    if let Some(slew) = model.slew_per_s {
        let most = slew * dt_s;
        next = command + (next - command).clamp(-most, most);
    }
    let tau = if next > command {
        model.time_constant_up_s
    } else {
        model.time_constant_down_s
    };
    if tau > 0.0 {
        next = command + (next - command) * (1.0 - (-dt_s / tau).exp());
    }
    next.clamp(0.0, 1.0)
}

/// The rotors' force and torque on the body (FRD, N and N m), the rotors turning at
/// `commands`, the air at `density_kgpm3` moving past the body at `air_frd_mps` (the body's
/// velocity relative to the air) while it turns at `rates_frd_radps`.
pub(super) fn force_and_torque(
    frame: &Frame,
    commands: &[f64; MAX_ROTORS],
    density_kgpm3: f64,
    air_frd_mps: DVec3,
    rates_frd_radps: DVec3,
) -> (DVec3, DVec3) {
    let model = &frame.rotor_model;
    let density_ratio = model
        .reference_air_density_kgpm3
        .map_or(1.0, |reference| density_kgpm3 / reference);
    let (mut force, mut torque) = (DVec3::ZERO, DVec3::ZERO);
    for (k, rotor) in frame.rotors.iter().enumerate() {
        let c = commands[k];
        let r = frame.rotor_position_frd_m(k);
        // The air's motion at the hub, and its part along the axis into the disc from above.
        let at_hub = air_frd_mps + rates_frd_radps.cross(r);
        let climbing_mps = -at_hub.z;
        let mut thrust =
            model.max_thrust_n * ((1.0 - model.thrust_expo) * c + model.thrust_expo * c * c);
        thrust *= density_ratio;
        if let Some(area) = model.inflow_area_m2 {
            thrust -= 0.5 * density_kgpm3 * area * climbing_mps.max(0.0).powi(2);
        }
        if let Some(limit) = model.axial_speed_limit_mps {
            thrust *= (1.0 - climbing_mps / limit).clamp(0.0, 1.0);
        }
        let thrust = thrust.max(0.0);
        let f = DVec3::new(0.0, 0.0, -thrust);
        let reaction = model.yaw_torque_per_thrust_m
            * thrust
            * if model.yaw_torque_scales_with_command {
                c
            } else {
                1.0
            };
        torque += r.cross(f) + DVec3::new(0.0, 0.0, rotor.spin.sign() * reaction);
        let axial = if model.momentum_drag_axial {
            at_hub.z
        } else {
            0.0
        };
        let drag = model.momentum_drag * thrust.sqrt() * DVec3::new(at_hub.x, at_hub.y, axial);
        force += f - drag;
    }
    (force, torque)
}
