//! savsim's integration tests: one binary, one module per area.
//!
//! - `common`: helpers (paths, pymavlink availability, synthetic flights, `wait_until` and
//!   `until_processed`: waits on a condition with a deadline, never a guessed sleep).
//! - `geo`: geodesy against PROJ's values (tests/fixtures/geo_reference.json).
//! - `ingest`: framing, decoding, bad input, and tlogs written by pymavlink.
//! - `shared_fixtures`: the real tlogs of ../shared/fixtures against pymavlink's counts.
//! - `live`: a UDP link to a vehicle played by a tokio task using the mavlink crate; recording.
//! - `sitl`: `sitl_test`, the gate every SITL test goes through (the autopilot's binary from
//!   `SAVSIM_ARDUCOPTER` / `SAVSIM_PX4`, a network namespace; `SKIP: <test>: <why> [SITL]`, or
//!   a failure under `SAVSIM_REQUIRE_SITL`; `SITL-RAN: <test>` when it flies); two ArduCopter
//!   SITLs on one UDP link, one rebooted.
//! - `sitl_feed`: ArduCopter SITL fed by savsim's proximity feed stops before a wall of the
//!   bundled city, and flies into it without the feed; ArduPilot's own autotests for these
//!   inputs mirrored (proximity health and echo, OBSTACLE_DISTANCE, rangefinder); ADS-B
//!   avoidance of a scripted airliner (needs `SAVSIM_ARDUCOPTER`).
//! - `sitl_forward`: ground stations through `--forward` (pymavlink, MAVProxy), savsim behind
//!   MAVProxy refused the feed, MAVLink 2 signing, all against ArduCopter SITL (needs
//!   `SAVSIM_ARDUCOPTER`).
//! - `sitl_px4`: two PX4 SIH quadrotors on one UDP link, one restarted once it has flown (needs
//!   `SAVSIM_PX4`; PX4 started by savsim's own launcher, `savsim::study::sitl::Px4`).
//! - `sitl_px4_feed`: PX4's collision prevention keeps its distance from a wall with savsim's
//!   OBSTACLE_DISTANCE feed, and PX4's obstacle map is savsim's bins (needs `SAVSIM_PX4`).
//! - `supervisor`: per-vehicle routing, requests, fallback, stale streams and reboots, on
//!   frames and times the test chooses.
//! - `faults`: live faults (garbage, truncation, repeats, reordering, reboots) and a 10 s burst
//!   of 100k messages/s, every frame accounted for.
//! - `feed`: the closed-loop feed: sector, bin and rangefinder distances against a slab ray
//!   cast, `replay --feed-out` read by pymavlink against the wire rules, two vehicles fed live.
//! - `extremes`: numerics at the poles, the antimeridian, -400 m to 20 km, 0 to 300 m/s, rays
//!   along faces and edges, millimetre to 10 km meshes, coplanar contact, gimbal lock.
//! - `scenes`: the scene file format and its errors.
//! - `collision`: golden scenarios, one per step of the algorithm.
//! - `terrain`: SRTM and ArduPilot elevation files, real flights over them.
//! - `properties`: property tests of rays, octree and sweeps against brute force.
//! - `cities`: CityJSON city models.
//! - `cli`: the commands README.md gives.
//! - `issue_11_layers`: identities across ticks, the vehicle's clock, `--near-miss-m 0`,
//!   reboots mid-contact, vehicle-vehicle collisions, the mesh budget, rotating sweeps against
//!   the reference.
//! - `issue_23_trust`: what outside checks found (rays against height fields, the feed's
//!   rangefinder over terrain, clocks, reboots, bounded inputs, the feed's geometry, ingest),
//!   each failing before its fix.
//! - `issue_24_daa`: well clear and alerting against values worked by hand, `savsim daa`'s
//!   CSV, and parity with DAIDALUS's DaidalusAlerting (needs `SAVSIM_DAIDALUS`).
//! - `pairing`: importance-sampled pairing of model tracks against its distributions and the
//!   model's own, weights included.
//! - `issue_26_logs`: PX4 ULog and ArduPilot DataFlash logs of ../shared/fixtures/realdata
//!   against pyulog's and pymavlink's readings of them; bad logs.
//! - `study`: `savsim study`: the generator's boxes across their paths, bad rows, the results
//!   table's risk ratios; obstacle-approach pairs on ArduCopter SITL, the same rows at two
//!   speedups, and examples/ray_study.py's shards against `savsim study`'s (needs
//!   `SAVSIM_ARDUCOPTER`; Ray); PX4 rows (needs `SAVSIM_PX4`).
//! - `osm`: OpenStreetMap buildings in scenes against pyosmium's counts of every realdata OSM
//!   file; holes, heights, bad files.
//! - `bench`: the bench's flight set against the reference; `savsim bench`'s report, JSON, chart.
//! - `batch`: `savsim batch` (encounters against their construction, jobs and shards, bad
//!   rows, schedulers) and the Python package and its Ray example against the CLI.
//! - `viz`: the rerun logger (rerun-sdk's CLI verifies the recording; the memory sink); the
//!   default layout; SIGTERM during a recorded replay.
//! - `viz_render`: the demo's recording rendered headless by rerun's own viewer, the vehicle
//!   found in the picture.

#![allow(clippy::disallowed_methods)]

mod batch;
mod bench;
mod cities;
mod cli;
mod collision;
mod common;
mod extremes;
mod faults;
mod feed;
mod forward;
mod geo;
mod ingest;
mod issue_11_layers;
mod issue_23_trust;
mod issue_24_daa;
mod issue_26_logs;
mod live;
mod osm;
mod pairing;
mod properties;
mod scenes;
mod shared_fixtures;
mod signing;
mod sitl;
mod sitl_feed;
mod sitl_forward;
mod sitl_px4;
mod sitl_px4_feed;
mod study;
mod supervisor;
mod terrain;
#[cfg(feature = "viz")]
mod viz;
#[cfg(feature = "viz")]
mod viz_render;
