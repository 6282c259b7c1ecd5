//! savsim's core: everything that decides what a vehicle perceives and what it hit, as pure,
//! synchronous code that a program can embed without savsim's I/O.
//!
//! - [`bounds`]: the ranges every number from outside is checked against.
//! - [`geo`]: WGS84 geodetic <-> ECEF <-> local ENU tangent plane, f64.
//! - [`scene`]: scene data, its loaders (bytes handed in through [`scene::Files`]) and the
//!   generators.
//! - [`reference`](mod@reference): the independent ground truth (dense sub-stepping), sharing
//!   no code with the contact layer.
//! - [`daa`]: detect-and-avoid metrics: well clear, alerting, DAIDALUS's files.
//! - [`world`]: vehicles and traffic keyed by identity, on their own clocks.
//! - [`dynamics`]: a multicopter savsim flies itself (lockstep), one fixed step at a time.
//! - [`collision`]: the contact layer (the truth), the sensing layer (Li et al. 2019), the
//!   exact ray fans a range sensor measures.
//! - [`pipeline`]: the per-tick orchestrator: the collision layers in every mode but
//!   `reference`, which it hands to [`reference`](mod@reference) (so neither imports the other
//!   beyond the data types the reference reads).
//!
//! The crate depends on geometry and parsing crates only (parry3d, glam, serde, the file
//! format readers); the build keeps tokio, mavlink, clap, arrow, parquet, plotters and rerun
//! out. The `savsim` crate wires it to sockets, logs, the viewer and batches.

pub mod bounds;
pub mod collision;
pub mod daa;
pub mod dynamics;
pub mod geo;
pub mod pipeline;
pub mod reference;
pub mod scene;
pub mod sensors;
pub mod world;
