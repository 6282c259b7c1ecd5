//! savsim: sense-and-avoid simulation for UAVs.
//!
//! A MAVLink flight (live SITL or a recorded tlog) is mirrored into a scene of buildings,
//! terrain and traffic; the collision core tells what the vehicle is about to hit and what it
//! did hit, choosing per obstacle between a cheap box and an exact mesh collider (Li et al.
//! 2019, see docs/ARCHITECTURE.md).

pub use savsim_core::{collision, daa, geo, pipeline, sensors, world};

pub mod app;
pub mod batch;
pub mod bench;
pub mod bundled;
pub mod chart_font;
pub mod cli;
pub mod codec;
pub mod companion;
pub mod costs;
pub mod daa_csv;
pub mod error;
pub mod feed;
pub mod files;
pub mod links;
pub mod live;
pub mod lockstep;
pub mod logs;
pub mod observe;
pub mod replay;
pub mod runs;
pub mod scene;
pub mod session;
pub mod signals;
pub mod sim;
pub mod study;
#[cfg(feature = "viz")]
pub mod viz;
