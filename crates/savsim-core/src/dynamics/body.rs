//! A multicopter's state, what its IMU reads, and what surrounds it.

use glam::{DQuat, DVec3};

use super::frame::{Frame, MAX_ROTORS};

/// A vehicle's state: where it is relative to its home, how it moves, how its rotors turn.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Body {
    /// Position from home, NED metres.
    pub position_ned_m: DVec3,
    /// Velocity, NED m/s.
    pub velocity_ned_mps: DVec3,
    /// Attitude: rotation from body FRD to NED.
    pub ned_from_frd: DQuat,
    /// Body rates, FRD rad/s.
    pub rates_frd_radps: DVec3,
    /// Each rotor's lagged command (0..1), in the frame's order.
    pub commands: [f64; MAX_ROTORS],
    /// Resting on the ground (set by the last step).
    pub on_ground: bool,
    /// Stopped against an obstacle by the last step.
    pub against_obstacle: bool,
}

impl Body {
    /// Landed at home, on the ground below it (`ground_down_m`, NED down of the ground under
    /// home; 0 on flat ground), facing `yaw_rad` (clockwise from north), rotors still.
    pub fn landed(frame: &Frame, ground_down_m: f64, yaw_rad: f64) -> Body {
        Body {
            position_ned_m: DVec3::new(0.0, 0.0, ground_down_m - frame.rest_height_m),
            velocity_ned_mps: DVec3::ZERO,
            ned_from_frd: DQuat::from_rotation_z(yaw_rad),
            rates_frd_radps: DVec3::ZERO,
            commands: [0.0; MAX_ROTORS],
            on_ground: true,
            against_obstacle: false,
        }
    }

    /// Whether every number is finite.
    pub fn is_finite(&self) -> bool {
        self.position_ned_m.is_finite()
            && self.velocity_ned_mps.is_finite()
            && self.ned_from_frd.is_finite()
            && self.rates_frd_radps.is_finite()
            && self.commands.iter().all(|c| c.is_finite())
    }

    /// Roll, pitch and yaw, radians (ZYX Euler angles of [`Body::ned_from_frd`]).
    pub fn euler_rad(&self) -> [f64; 3] {
        let (yaw, pitch, roll) = self.ned_from_frd.to_euler(glam::EulerRot::ZYX);
        [roll, pitch, yaw]
    }
}

/// What a perfect IMU on the body reads after a step.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Imu {
    /// Specific force, body FRD m/s^2 (at rest, level: (0, 0, -g)).
    pub accel_frd_mps2: DVec3,
    /// Body rates, FRD rad/s.
    pub gyro_frd_radps: DVec3,
}

/// The air around the vehicle.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Air {
    /// Wind (where the air goes), NED m/s.
    pub wind_ned_mps: DVec3,
    /// Home's altitude above mean sea level, metres (the air's density goes with altitude).
    pub home_alt_m: f64,
}

/// What the vehicle can run into: the ground under it and the obstacles around it, in its
/// home's NED frame.
pub trait Surroundings {
    /// NED down coordinate of the ground at (`north_m`, `east_m`) from home.
    fn ground_down_m(&self, north_m: f64, east_m: f64) -> f64;
    /// The first obstacle a sphere of `radius_m` meets moving straight from `from_ned_m` to
    /// `to_ned_m`: the fraction of the way (0..1) and the obstacle's outward normal there (NED,
    /// unit). None when the way is clear.
    fn first_contact(
        &self,
        from_ned_m: DVec3,
        to_ned_m: DVec3,
        radius_m: f64,
    ) -> Option<(f64, DVec3)>;
}

/// Flat ground through home and nothing else.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct FlatGround;

impl Surroundings for FlatGround {
    fn ground_down_m(&self, _north_m: f64, _east_m: f64) -> f64 {
        0.0
    }

    fn first_contact(&self, _: DVec3, _: DVec3, _: f64) -> Option<(f64, DVec3)> {
        None
    }
}
