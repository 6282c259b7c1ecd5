//! A multicopter frame as data: its mass and inertia, its rotors (where, which way they turn,
//! which output drives them), how a command becomes thrust, and its drag. Presets in
//! [`super::presets`]; a user frame is TOML ([`Frame::from_toml`]), checked whole before it flies.

use glam::DVec3;
use serde::{Deserialize, Serialize};

/// Rotors a frame may have, at most.
pub const MAX_ROTORS: usize = 12;

/// One rotor.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Rotor {
    /// Where its hub is, body FRD metres from the centre of mass.
    pub position_frd_m: [f64; 3],
    /// Which way it turns, seen from above: `ccw` or `cw`. A counter-clockwise rotor's drag
    /// turns the body clockwise seen from above: a yaw torque nose-right (+z FRD).
    pub spin: Spin,
    /// The autopilot's output that drives it, from 0 (ArduPilot's SERVO1, PX4's first
    /// actuator control).
    pub output: usize,
}

/// A rotor's direction of turning, seen from above.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Spin {
    /// Counter-clockwise: its reaction yaws the body nose-right.
    Ccw,
    /// Clockwise: its reaction yaws the body nose-left.
    Cw,
}

impl Spin {
    /// +1 for counter-clockwise (yaw torque +z FRD), -1 for clockwise.
    pub fn sign(self) -> f64 {
        match self {
            Spin::Ccw => 1.0,
            Spin::Cw => -1.0,
        }
    }
}

/// How an output becomes a rotor's thrust and torque.
///
/// The output `u` (0..1, [`Frame::command_from_pwm_us`] for a PWM) is first raised to the
/// idle: `c = idle + (1 - idle) u` (0 when disarmed), then lagged ([`Self::slew_per_s`], then
/// [`Self::time_constant_up_s`] / `_down_s`), and the rotor's thrust is `max_thrust_n x
/// ((1 - expo) c + expo c^2)`: ArduPilot's SITL thrust curve, which `MOT_THST_EXPO` inverts, and
/// with `expo = 1` a rotor whose speed goes as `c` and thrust as its square (Gazebo's).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RotorModel {
    /// Static thrust of one rotor at full command, newtons, at
    /// [`Self::reference_air_density_kgpm3`].
    pub max_thrust_n: f64,
    /// The thrust curve's expo (0 linear in the command, 1 quadratic).
    pub thrust_expo: f64,
    /// The command an armed rotor turns at with zero output (0..1).
    #[serde(default)]
    pub idle: f64,
    /// The most the command changes in a second (a rate limit; ArduPilot's SITL: 150), or none.
    #[serde(default)]
    pub slew_per_s: Option<f64>,
    /// First-order lag of a rising command, seconds (0: none).
    #[serde(default)]
    pub time_constant_up_s: f64,
    /// First-order lag of a falling command, seconds (0: none).
    #[serde(default)]
    pub time_constant_down_s: f64,
    /// Yaw reaction torque per newton of thrust, metres.
    pub yaw_torque_per_thrust_m: f64,
    /// The yaw reaction also scales with the command (ArduPilot's SITL: `k c T`), else `k T`.
    #[serde(default)]
    pub yaw_torque_scales_with_command: bool,
    /// Air density the thrust was measured at, kg/m^3: thrust scales with the density at the
    /// vehicle's altitude. None: thrust does not depend on the air.
    #[serde(default)]
    pub reference_air_density_kgpm3: Option<f64>,
    /// Effective disc area of one rotor, m^2: air entering the disc from above (a climb) takes
    /// `0.5 rho A v_in^2` of its thrust (ArduPilot's SITL). None: no such loss.
    #[serde(default)]
    pub inflow_area_m2: Option<f64>,
    /// Thrust falls linearly to zero at this speed of the air along the rotor's axis into it,
    /// m/s (Gazebo's: 25). None: no such loss.
    #[serde(default)]
    pub axial_speed_limit_mps: Option<f64>,
    /// Rotor (momentum) drag: each rotor resists the air's motion across it with
    /// `k sqrt(T) v`, N per (m/s sqrt(N)).
    #[serde(default)]
    pub momentum_drag: f64,
    /// The momentum drag also resists motion along the rotor's axis (ArduPilot's SITL: yes).
    #[serde(default)]
    pub momentum_drag_axial: bool,
}

/// A multicopter frame.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Frame {
    /// Its name (a preset's, or the user's).
    pub name: String,
    /// Mass, kilograms.
    pub mass_kg: f64,
    /// Principal moments of inertia about body x, y, z (FRD), kg m^2.
    pub inertia_kgm2: [f64; 3],
    /// The rotors.
    pub rotors: Vec<Rotor>,
    /// How outputs become thrust.
    pub rotor_model: RotorModel,
    /// PWM of zero output and of full output, microseconds (ArduPilot's outputs are PWM: the
    /// command is `(pwm - lo) / (hi - lo)` with `lo = min + spin_min (max - min)`, `hi = min +
    /// spin_max (max - min)`). PX4's outputs arrive as 0..1 and skip this.
    #[serde(default = "default_pwm")]
    pub pwm_us: [f64; 2],
    /// MOT_SPIN_MIN and MOT_SPIN_MAX: where the PWM range starts and ends turning the rotors.
    #[serde(default = "default_spin")]
    pub spin: [f64; 2],
    /// Quadratic body drag, `drag_area_m2 x 0.5 rho v |v|` on each body axis: the drag area
    /// times its coefficient, m^2.
    #[serde(default)]
    pub drag_area_m2: f64,
    /// Rotational damping, rad/s^2 per rad/s.
    #[serde(default)]
    pub rotational_damping_per_s: f64,
    /// Radius of the body and its rotors, metres: what touches an obstacle.
    pub radius_m: f64,
    /// Height of the centre of mass above the ground when landed, metres.
    pub rest_height_m: f64,
}

fn default_pwm() -> [f64; 2] {
    [1000.0, 2000.0]
}

fn default_spin() -> [f64; 2] {
    [0.15, 0.95]
}

/// Why a frame cannot fly.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum FrameError {
    /// The TOML does not parse as a frame.
    #[error("frame: {0}")]
    Toml(String),
    /// A number is out of its range.
    #[error("frame {frame}: {field} = {value} ({why})")]
    Value {
        /// The frame's name.
        frame: String,
        /// The field.
        field: &'static str,
        /// Its value.
        value: f64,
        /// Its range.
        why: &'static str,
    },
    /// Rotors: none, too many, or an output number used twice or out of range.
    #[error("frame {frame}: rotors: {why}")]
    Rotors {
        /// The frame's name.
        frame: String,
        /// What is wrong.
        why: String,
    },
}

impl Frame {
    /// A frame from TOML (the fields of [`Frame`]), checked ([`Frame::check`]).
    pub fn from_toml(text: &str) -> Result<Frame, FrameError> {
        let frame: Frame = toml::from_str(text).map_err(|e| FrameError::Toml(e.to_string()))?;
        frame.check()?;
        Ok(frame)
    }

    /// Every number in its range: mass, inertia, thrust and sizes positive and finite, the
    /// curve's expo and the idle in 0..1, lags not negative, 1 to [`MAX_ROTORS`] rotors on
    /// distinct outputs below 32.
    pub fn check(&self) -> Result<(), FrameError> {
        let m = &self.rotor_model;
        let positive = [
            ("mass_kg", self.mass_kg),
            ("inertia_kgm2[0]", self.inertia_kgm2[0]),
            ("inertia_kgm2[1]", self.inertia_kgm2[1]),
            ("inertia_kgm2[2]", self.inertia_kgm2[2]),
            ("rotor_model.max_thrust_n", m.max_thrust_n),
            ("radius_m", self.radius_m),
        ];
        for (field, value) in positive {
            if !(value.is_finite() && value > 0.0 && value < 1e6) {
                return Err(self.bad(field, value, "positive and finite, below 1e6"));
            }
        }
        let unit = [
            ("rotor_model.thrust_expo", m.thrust_expo),
            ("rotor_model.idle", m.idle),
            ("spin[0]", self.spin[0]),
            ("spin[1]", self.spin[1]),
        ];
        for (field, value) in unit {
            if !(0.0..=1.0).contains(&value) {
                return Err(self.bad(field, value, "0 to 1"));
            }
        }
        let optional = [
            m.slew_per_s,
            m.reference_air_density_kgpm3,
            m.inflow_area_m2,
        ];
        let not_negative = [
            ("rotor_model.time_constant_up_s", m.time_constant_up_s),
            ("rotor_model.time_constant_down_s", m.time_constant_down_s),
            (
                "rotor_model.yaw_torque_per_thrust_m",
                m.yaw_torque_per_thrust_m,
            ),
            ("rotor_model.momentum_drag", m.momentum_drag),
            ("drag_area_m2", self.drag_area_m2),
            ("rotational_damping_per_s", self.rotational_damping_per_s),
            ("rest_height_m", self.rest_height_m),
            ("rotor_model.slew_per_s", optional[0].unwrap_or(1.0)),
            (
                "rotor_model.reference_air_density_kgpm3",
                optional[1].unwrap_or(1.0),
            ),
            ("rotor_model.inflow_area_m2", optional[2].unwrap_or(1.0)),
            (
                "rotor_model.axial_speed_limit_mps",
                m.axial_speed_limit_mps.unwrap_or(1.0),
            ),
        ];
        for (field, value) in not_negative {
            if !(value.is_finite() && (0.0..1e6).contains(&value)) {
                return Err(self.bad(field, value, "0 or more, finite, below 1e6"));
            }
        }
        if m.slew_per_s == Some(0.0) || m.axial_speed_limit_mps == Some(0.0) {
            return Err(self.bad("a rate or a limit", 0.0, "positive when given"));
        }
        if !(self.pwm_us[0].is_finite() && self.pwm_us[1].is_finite())
            || self.pwm_us[1] <= self.pwm_us[0]
            || self.spin[1] <= self.spin[0]
        {
            return Err(self.bad("pwm_us / spin", self.pwm_us[1], "the top above the bottom"));
        }
        self.check_rotors()
    }

    fn check_rotors(&self) -> Result<(), FrameError> {
        let rotors = |why: String| FrameError::Rotors {
            frame: self.name.clone(),
            why,
        };
        if self.rotors.is_empty() || self.rotors.len() > MAX_ROTORS {
            return Err(rotors(format!(
                "{} rotors (1 to {MAX_ROTORS})",
                self.rotors.len()
            )));
        }
        let mut used = 0u32;
        for (k, r) in self.rotors.iter().enumerate() {
            if r.output >= 32 || used & (1 << r.output) != 0 {
                return Err(rotors(format!(
                    "rotor {k}'s output {} is used twice or past 31",
                    r.output
                )));
            }
            used |= 1 << r.output;
            if !r
                .position_frd_m
                .iter()
                .all(|v| v.is_finite() && v.abs() < 100.0)
            {
                return Err(rotors(format!("rotor {k}'s position is not within 100 m")));
            }
        }
        Ok(())
    }

    fn bad(&self, field: &'static str, value: f64, why: &'static str) -> FrameError {
        FrameError::Value {
            frame: self.name.clone(),
            field,
            value,
            why,
        }
    }

    /// The command (0..1) a PWM output gives: 0 at or below MOT_SPIN_MIN's PWM, 1 at or above
    /// MOT_SPIN_MAX's; a PWM that is not finite gives 0.
    pub fn command_from_pwm_us(&self, pwm_us: f64) -> f64 {
        let span = self.pwm_us[1] - self.pwm_us[0];
        let lo = self.pwm_us[0] + self.spin[0] * span;
        let hi = self.pwm_us[0] + self.spin[1] * span;
        let c = (pwm_us - lo) / (hi - lo);
        if c.is_finite() {
            c.clamp(0.0, 1.0)
        } else {
            0.0
        }
    }

    /// Rotor `k`'s hub, body FRD metres.
    pub fn rotor_position_frd_m(&self, k: usize) -> DVec3 {
        DVec3::from_array(self.rotors[k].position_frd_m)
    }

    /// Total static thrust at full command over the weight (at the reference air density).
    pub fn thrust_to_weight(&self) -> f64 {
        self.rotors.len() as f64 * self.rotor_model.max_thrust_n
            / (self.mass_kg * super::GRAVITY_MPS2)
    }
}
