//! Lockstep: savsim flies the vehicles and every autopilot waits for savsim's clock
//! (docs/lockstep.md).
//!
//! - [`backend`]: one autopilot's protocol in the loop (outputs in, state out);
//! - [`json`]: ArduPilot SITL's JSON physics backend as bytes (servo packets in, state out),
//!   and its clock mirrored;
//! - [`port`]: an autopilot's sockets (its physics port, its MAVLink ports);
//! - [`px4`]: PX4's simulator_mavlink (HIL_SENSOR and HIL_GPS out, HIL_ACTUATOR_CONTROLS in);
//! - [`hil_noise`]: the compass's and barometer's noise PX4 needs to take them as alive;
//! - [`vehicle`]: a vehicle flown by the core's dynamics, and its truth for the world;
//! - [`physics`]: the frame, step and wind from text;
//! - [`pin`]: a row of one autopilot kept to one core;
//! - [`surroundings`]: the scene's ground and obstacles as the dynamics ask for them;
//! - [`gate`]: the turn-taking with a pilot thread;
//! - [`estimates`]: an autopilot's estimate against the truth;
//! - [`driver`]: the loop.

pub mod backend;
pub mod driver;
pub mod estimates;
pub mod gate;
pub mod hil_noise;
pub mod json;
pub mod physics;
pub mod pin;
pub mod port;
pub mod px4;
pub mod surroundings;
pub mod vehicle;
