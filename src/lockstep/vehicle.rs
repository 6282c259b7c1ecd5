//! One vehicle savsim flies: its frame and state on savsim's clock, stepped with its
//! autopilot's outputs, and its truth as the world store takes it.

use glam::DVec3;
use savsim_core::dynamics::{step, Air, Body, Frame, Imu, StepError, Surroundings};

use crate::geo::{Geodetic, LocalTangentPlane};
use crate::world::inputs::{AttitudeReport, PositionReport, Report};
use crate::world::SenderId;

/// A vehicle flown by savsim's dynamics.
#[derive(Debug, Clone)]
pub struct SimVehicle {
    /// Its MAVLink identity (the autopilot's).
    pub id: SenderId,
    /// Its frame.
    pub frame: Frame,
    /// Its state, NED from its home.
    pub body: Body,
    /// What its IMU read at the last step.
    pub imu: Imu,
    /// Its home, scene ENU metres (on the ground).
    pub home_enu_m: DVec3,
    /// The air it flies in.
    pub air: Air,
}

impl SimVehicle {
    /// `frame` landed at `home` (`home_enu_m` in the scene's frame), facing `yaw_rad`, in
    /// a constant `wind_ned_mps`.
    pub fn landed(
        id: SenderId,
        frame: Frame,
        (home, home_enu_m): (Geodetic, DVec3),
        yaw_rad: f64,
        wind_ned_mps: DVec3,
    ) -> SimVehicle {
        let body = Body::landed(&frame, 0.0, yaw_rad);
        SimVehicle {
            id,
            imu: Imu {
                accel_frd_mps2: DVec3::new(0.0, 0.0, -savsim_core::dynamics::GRAVITY_MPS2),
                gyro_frd_radps: DVec3::ZERO,
            },
            frame,
            body,
            home_enu_m,
            air: Air {
                wind_ned_mps,
                home_alt_m: home.alt_m,
            },
        }
    }

    /// One step of `dt_s` with the autopilot's `outputs` (0..1 by output number).
    pub fn advance(
        &mut self,
        outputs: &[f64],
        armed: bool,
        surroundings: &dyn Surroundings,
        dt_s: f64,
    ) -> Result<(), StepError> {
        self.imu = step(
            &self.frame,
            &mut self.body,
            outputs,
            armed,
            &self.air,
            surroundings,
            dt_s,
        )?;
        Ok(())
    }

    /// Where it is, scene ENU metres.
    pub fn position_enu_m(&self) -> DVec3 {
        let p = self.body.position_ned_m;
        self.home_enu_m + DVec3::new(p.y, p.x, -p.z)
    }

    /// Its truth at `time_ms` of the row's clock, as the world store takes it: attitude,
    /// then position (the position moves it and ticks the collision layers).
    pub fn reports(&self, plane: &LocalTangentPlane, time_ms: u32) -> [Report; 2] {
        let at = plane.geodetic_from_enu_m(self.position_enu_m());
        let home_alt_m = plane.geodetic_from_enu_m(self.home_enu_m).alt_m;
        let [roll_rad, pitch_rad, yaw_rad] = self.body.euler_rad();
        let v = self.body.velocity_ned_mps;
        let heading_deg = yaw_rad.to_degrees().rem_euclid(360.0);
        [
            Report::Attitude(AttitudeReport {
                time_boot_ms: time_ms,
                roll_rad,
                pitch_rad,
                yaw_rad,
                body_rates_radps: self.body.rates_frd_radps,
            }),
            Report::Position(PositionReport {
                time_boot_ms: time_ms,
                position: at,
                relative_alt_m: at.alt_m - home_alt_m,
                velocity_ned_mps: v,
                heading_deg: Some(heading_deg),
            }),
        ]
    }
}
