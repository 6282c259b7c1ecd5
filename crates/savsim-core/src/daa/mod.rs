//! Detect-and-avoid metrics: DO-365's well clear, alerting as a DAIDALUS configuration sets
//! it, and DAIDALUS's own files (`.conf`, `.daa`), so that savsim and DAIDALUS can be run side
//! by side on the same input.
//!
//! - [`approach`]: each vehicle's closest approach, NMAC and losses of well clear with each
//!   moving body over a run.
//! - [`well_clear`]: the well-clear predicate and its interval for linear relative motion.
//! - [`separation`]: a separation minimum (a sphere), judged as well clear is.
//! - [`slots`]: a show's slots, and each vehicle's departures from its own.
//! - [`alerting`]: alert levels, and their filtering (M of N, hysteresis, persistence).
//! - [`conf`], [`scenario`], [`units`]: DAIDALUS's configuration and state files.
//! - [`projection`]: geodetic states made Euclidean as DAIDALUS does.
//! - [`sum`]: sensor uncertainty mitigation: the violation interval under state errors.
//! - [`alerting_run`]: a state file's alerting, row by row, as `DaidalusAlerting` reports it.
//! - [`episodes`]: losses of well clear over a flight, for events, summaries and batch rows.
//! - [`encounter_model`]: MIT LL's encounter models read and sampled into tracks.
//! - [`pairing`], [`pairing_ini`]: importance-sampled pairing of model tracks (MIT LL's
//!   em-pairing-uncor-importancesampling) and its `.ini` settings.
//! - [`ratios`]: weighted NMAC and loss-of-well-clear rates and risk ratios over encounters.

pub mod alerting;
pub mod alerting_run;
pub mod approach;
pub mod conf;
pub mod encounter_model;
pub mod episodes;
pub mod pairing;
pub mod pairing_ini;
pub mod projection;
pub mod ratios;
pub mod scenario;
pub mod separation;
pub mod slots;
pub mod sum;
pub mod units;
pub mod well_clear;
