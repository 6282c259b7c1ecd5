//! Vehicle dynamics: a multicopter savsim flies itself, so that an autopilot in lockstep flies
//! savsim's world (docs/lockstep.md). Pure, deterministic, f64, one fixed step at a time: the
//! same frame, state, outputs and surroundings give the same next state, bit for bit.
//!
//! - [`frame`]: a frame as data (mass, inertia, rotors, thrust curve, drag), checked;
//!   [`presets`]: ArduPilot SITL's quad and Gazebo's Iris.
//! - [`body`]: the state, the IMU's reading, the air and the [`Surroundings`] (ground and
//!   obstacles) a step asks.
//! - [`step`](mod@step): one step; `rotors`: the rotors' part of it; [`air`]: the air's
//!   density.

pub mod air;
pub mod body;
pub mod frame;
pub mod presets;
mod rotors;
pub mod step;

pub use body::{Air, Body, FlatGround, Imu, Surroundings};
pub use frame::{Frame, FrameError};
pub use step::{step, StepError};

/// Standard gravity, m/s^2.
pub const GRAVITY_MPS2: f64 = 9.80665;

#[cfg(test)]
mod tests;
