//! Your own avoidance in the loop (docs/companion.md): a planner of the user's, in a process
//! of its own, is handed at each of its instants the vehicle's state (the autopilot's estimate,
//! and the truth marked as such), its images and point clouds, and the traffic it was told;
//! its commands go to the autopilot as a companion computer's do. In a lockstep row savsim
//! waits for each answer, so the row is the same whatever the planner's speed; beside a vehicle
//! flying in wall time it is asked at the vehicle's instants and never waited for.
//!
//! - [`protocol`]: the messages, as bytes (pure).
//! - [`beside`]: a planner asked by a worker beside a vehicle in wall time.
//! - [`link`]: the planner's process and its socket, every wait bounded.
//! - [`outgoing`]: its commands as MAVLink, sent as the companion's own identity.
//! - [`slot`]: one vehicle's companion: its instants, its latency, its counts.

mod beside;
pub mod link;
pub mod outgoing;
pub mod protocol;
pub mod slot;
