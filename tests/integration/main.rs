//! savsim's integration tests: one binary, one module per area.
//!
//! - `common`: helpers (paths, pymavlink availability, synthetic flights).
//! - `geo`: geodesy against PROJ's values (tests/fixtures/geo_reference.json).
//! - `ingest`: framing, decoding, bad input, and tlogs written by pymavlink.
//! - `shared_fixtures`: the real tlogs of ../shared/fixtures against pymavlink's counts.
//! - `live`: a UDP link to a vehicle played by a tokio task using the mavlink crate; recording.
//! - `scenes`: the scene file format and its errors.
//! - `collision`: golden scenarios, one per step of the algorithm.
//! - `terrain`: SRTM and ArduPilot elevation files, real flights over them.
//! - `properties`: property tests of rays, octree and sweeps against brute force.
//! - `cities`: CityJSON city models.
//! - `cli`: the commands README.md gives.
//! - `viz`: the rerun logger (rerun-sdk's CLI verifies the recording; the memory sink).

mod cities;
mod cli;
mod collision;
mod common;
mod geo;
mod ingest;
mod live;
mod properties;
mod scenes;
mod shared_fixtures;
mod terrain;
mod viz;
