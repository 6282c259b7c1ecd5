//! savsim's integration tests: one binary, one module per area.
//!
//! - `architecture`: ARCHITECTURE.md's import rules, checked on the `crate::` paths of the
//!   source.
//! - `daa_sum`: DAIDALUS's sensor uncertainty mitigation in `savsim daa` (H1_SUM's levels;
//!   parity with DaidalusAlerting with `SAVSIM_DAIDALUS`).
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
//! - `forward`: `--forward`: a pymavlink ground station through savsim to a vehicle played by
//!   a tokio task.
//! - `signing`: MAVLink 2 signing against pymavlink's: bad frames dropped and counted, savsim's
//!   own frames accepted.
//! - `sitl_forward`: ground stations and routers (pymavlink, MAVProxy) against ArduCopter SITL
//!   (needs `SAVSIM_ARDUCOPTER`).
//! - `supervisor`: per-vehicle routing, requests, fallback, stale streams and reboots, on
//!   frames and times the test chooses.
//! - `faults`: live faults (garbage, truncation, repeats, reordering, reboots) and a 10 s burst
//!   of 100k messages/s, every frame accounted for.
//! - `feed`: the closed-loop feed: sector, bin and rangefinder distances against a slab ray
//!   cast, `replay --feed-out` read by pymavlink against the wire rules, two vehicles fed live.
//! - `extremes`: numerics at the poles, the antimeridian, -400 m to 20 km, 0 to 300 m/s, rays
//!   along faces and edges, millimetre to 10 km meshes, coplanar contact, gimbal lock.
//! - `sensed_daa`: batch rows alerting on sensed states, against `savsim daa` (and DAIDALUS).
//! - `sensor_feed`: the feed from modelled devices; `ideal` as before, bit for bit.
//! - `companion`: the companion link against a planner using the Python client: arrays whole,
//!   commands back as MAVLink at their latency, every failure an error naming the planner.
//! - `images`: depth images, segmentation and lidar channels against a scalar cast over
//!   every triangle; a field of view's edges to 0.01 degree; bad definitions.
//! - `sensor_models`: the sensor models against their specifications (distributions,
//!   correlation, reception, fields of regard, determinism, bad definitions).
//! - `scenes`: the scene file format and its errors.
//! - `collision`: golden scenarios, one per step of the algorithm.
//! - `terrain`: SRTM and ArduPilot elevation files, real flights over them.
//! - `properties`: property tests of rays, octree and sweeps against brute force.
//! - `cities`: CityJSON city models.
//! - `cli`: the commands README.md gives.
//! - `solids`: closed meshes (OSM and CityJSON buildings) as solids in every mode; open meshes
//!   as surfaces.
//! - `results`: figures drawn from every event of a run, never from the capped report list.
//! - `identities`: moving bodies and vehicles keep their identity across ticks (come, go,
//!   reorder, expire, reboot mid-contact, collide with each other, a swarm).
//! - `sweeps`: turning, rolling and climbing sweeps past a corner and over hills, and a fast
//!   low pass into the ground, against the reference.
//! - `mesh_residency`: a mesh budget smaller than the flight, the mesh worker, clones of one
//!   pipeline sharing its meshes.
//! - `clocks`: the vehicle's clock (two samples in one read, a quick reboot, speedups and
//!   drift, a far-future tlog stamp).
//! - `rays`: exact rays and the rangefinder against terrain held as height fields, checked by
//!   an analytic cast.
//! - `feed_geometry`: the feed far from the scene's origin (rangefinder over the ellipsoid,
//!   level sectors, ADS-B heading, climb and radius, COLLISION inside its volume).
//! - `bounded_inputs`: absurd numbers in batch rows and flags are errors, never hangs or
//!   panics.
//! - `daa`: well clear and alerting against values worked by hand, `savsim daa`'s CSV, the
//!   encounter model's sampler, and parity with DAIDALUS's DaidalusAlerting (needs
//!   `SAVSIM_DAIDALUS`).
//! - `pairing`: importance-sampled pairing of model tracks against its distributions and the
//!   model's own, weights included.
//! - `flight_logs`: PX4 ULog and ArduPilot DataFlash logs of ../shared/fixtures/realdata
//!   against pyulog's and pymavlink's readings of them; bad logs.
//! - `study`: `savsim study`: the generator's boxes across their paths, bad rows, the results
//!   table's risk ratios; obstacle-approach pairs on ArduCopter SITL, the same rows at two
//!   speedups, and examples/ray_study.py's shards against `savsim study`'s (needs
//!   `SAVSIM_ARDUCOPTER`; Ray); PX4 rows (needs `SAVSIM_PX4`).
//! - `osm`: OpenStreetMap buildings in scenes against pyosmium's counts of every realdata OSM
//!   file; holes, heights, bad files.
//! - `bench`: the bench's flight set against the reference; `savsim bench`'s report, JSON, chart.
//! - `bounded_reads`: `/dev/zero`, endless FIFOs and oversized files refused wherever a file is
//!   read whole.
//! - `batch`: `savsim batch` (encounters against their construction, jobs and shards, bad
//!   rows, schedulers) and the Python package and its Ray example against the CLI.
//! - `swarm`: a dense block judged within the approach reach gives the answers of the whole
//!   watch range.
//! - `viz`: the rerun logger (rerun-sdk's CLI verifies the recording; the memory sink); the
//!   default layout; SIGTERM during a recorded replay.
//! - `viz_render`: the demo's recording rendered headless by rerun's own viewer, the vehicle
//!   found in the picture.

#![allow(clippy::disallowed_methods)]

mod architecture;
mod batch;
mod bench;
mod bounded_inputs;
mod bounded_reads;
mod cities;
mod cli;
mod clocks;
mod collision;
mod common;
mod companion;
mod daa;
mod daa_sum;
mod extremes;
mod faults;
mod feed;
mod feed_geometry;
mod flight_logs;
mod forward;
mod geo;
mod identities;
mod images;
mod ingest;
mod live;
mod lockstep;
mod mesh_residency;
mod osm;
mod pairing;
mod properties;
mod rays;
mod report;
mod results;
mod scenes;
mod sensed_daa;
mod sensor_feed;
mod sensor_models;
mod separation;
mod shared_fixtures;
mod signing;
mod sitl;
mod sitl_feed;
mod sitl_forward;
mod sitl_px4;
mod sitl_px4_feed;
mod solids;
mod study;
mod supervisor;
mod swarm;
mod sweeps;
mod terrain;
#[cfg(feature = "viz")]
mod viz;
#[cfg(feature = "viz")]
mod viz_render;
