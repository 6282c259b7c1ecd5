//! Sensors as they are: the devices savsim simulates for a vehicle (depth cameras, lidars,
//! rangefinders, ADS-B in, radar, EO/IR) with their fields of view, rates, latencies, noise,
//! biases, correlated errors, quantisation, dropouts and false returns, from DO-365 Appendix Q
//! (as MIT Lincoln Laboratory's DEGAS implements it) and the devices' datasheets
//! (docs/sensors.md).
//!
//! Pure and deterministic: every error is a function of the run's seed, the device, the
//! channel and the device's instant on the vehicle's clock ([`draws`]), so the same seed gives
//! the same readings bit for bit, at any speedup and on any machine. The truth stays exact:
//! contacts, NMAC and well clear are judged on the real states; these models make what the
//! vehicle is told.
//!
//! - [`draws`]: random numbers keyed by instant.
//! - [`errors`]: Gauss-Markov errors, biases, quantisation.
//! - [`device`]: a device, validated: its mount, rate, latency and model.
//! - [`spec`]: devices as written (TOML `[[sensor]]`, preset names with settings).
//! - [`build`]: a spec built into a device, its preset resolved and every field checked.
//! - [`presets`]: the named devices.
//! - [`suite`]: a vehicle's devices, and the names (`ideal`, lists, files) that give them.
//! - [`range`]: what a range device reads along its rays (a grid, a lidar's channels, a
//!   pinhole image's pixels).
//! - [`image`]: a reading as a depth image and segmentation, or a point cloud.
//! - [`surveillance`]: what ADS-B, radar and EO/IR report of other aircraft.

pub mod build;
pub mod device;
pub mod draws;
pub mod errors;
pub mod image;
pub mod presets;
pub mod range;
pub mod spec;
pub mod suite;
pub mod surveillance;
