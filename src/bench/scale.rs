//! Scale runs: tick cost as the static scene grows from 10^2 to 10^6 obstacles, and ticks per
//! second for fleets of 1 to 1000 vehicles.

use std::sync::Arc;
use std::time::Instant;

use glam::{DVec3, Vec3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};

use crate::costs::percentiles_us;
use crate::geo::LocalTangentPlane;
use crate::pipeline::{
    BodyPose, CollisionConfig, DynamicBody, Mode, MovingBodies, Pipeline, VehicleKey,
};
use crate::scene::geometry::Geometry;
use crate::scene::{Kind, Placement, Scene, StaticObstacle};
use crate::world::TrackSample;

/// Distance between neighbouring obstacles of a scale scene, metres.
const PITCH_M: f64 = 50.0;
/// Telemetry rate of the scale flights, Hz.
const RATE_HZ: f64 = 50.0;

/// One scene size.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct SizeRow {
    /// Static obstacles.
    pub obstacles: usize,
    /// Mode.
    pub mode: String,
    /// Building the pipeline (octree), seconds.
    pub startup_s: f64,
    /// Octree memory, bytes.
    pub octree_bytes: usize,
    /// Per-tick cost, microseconds.
    pub cost_median_us: f64,
    /// Per-tick cost, 99th percentile, microseconds.
    pub cost_p99_us: f64,
    /// Median cost relative to the smallest scene's, same mode.
    pub cost_vs_smallest: f64,
    /// Collisions found (the same flight crosses the same neighbourhood at every size).
    pub collisions: u64,
}

/// One fleet size.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct FleetRow {
    /// Vehicles.
    pub vehicles: usize,
    /// Ticks run (every vehicle at 50 Hz for the flight's length).
    pub ticks: u64,
    /// Ticks per second of collision work on one core.
    pub ticks_per_s: f64,
    /// `ticks_per_s` over the fleet's telemetry rate (vehicles x 50 Hz): above 1 is faster
    /// than real time.
    pub real_time_factor: f64,
    /// Per-tick cost, microseconds.
    pub cost_median_us: f64,
    /// Per-tick cost, 99th percentile, microseconds.
    pub cost_p99_us: f64,
}

/// A scene of `n` box buildings on a square grid around the origin, `PITCH_M` apart, 10 to
/// 80 m tall (seeded by position),
/// with the default vehicle and traffic models of a parsed empty scene.
pub fn grid_scene(n: usize, seed: u64) -> Scene {
    let mut scene = crate::scene::parse(
        "[origin]\nlat_deg = -35.363261\nlon_deg = 149.16523\nalt_m = 584.0\n",
        std::path::Path::new("<scale>"),
        &format!("grid-{n}"),
    )
    .expect("the empty scale scene parses");
    let heights: Vec<usize> = (0..8)
        .map(|k| {
            let h = 10.0 + 10.0 * k as f32;
            scene.geometries.push(Arc::new(
                Geometry::cuboid(Vec3::new(-12.0, -12.0, 0.0), Vec3::new(12.0, 12.0, h))
                    .expect("a positive box"),
            ));
            scene.geometries.len() - 1
        })
        .collect();
    // Lattice points at multiples of PITCH_M, centred on the origin, and each building's height
    // a function of its lattice point: every size has the same buildings around the origin.
    let side = (n as f64).sqrt().ceil() as i64;
    let first = -side / 2;
    scene.obstacles.reserve(n);
    for k in 0..n as i64 {
        let (i, j) = (first + k % side, first + k / side);
        let mut rng = ChaCha8Rng::seed_from_u64(
            seed ^ (i as u64).wrapping_mul(0x9E37_79B9) ^ (j as u64) << 32,
        );
        let geometry_index = heights[rng.random_range(0..heights.len())];
        let geometry = scene.geometries[geometry_index].clone();
        let placement =
            Placement::from_yaw(DVec3::new(i as f64 * PITCH_M, j as f64 * PITCH_M, 0.0), 0.0);
        scene.obstacles.push(StaticObstacle {
            id: format!("g{k}"),
            kind: Kind::Building,
            threat: Kind::Building.paper_threat(),
            aabb_enu_m: placement.enu_aabb(&geometry.local_aabb),
            placement,
            geometry,
            geometry_index,
        });
    }
    scene
}

/// Samples of vehicle `k` of a fleet: a straight 20 s line at 12 m/s, 50 Hz, its start spread
/// over the scene, between 30 and 90 m up.
fn fleet_flight(scene: &Scene, k: usize, seconds: f64) -> Vec<TrackSample> {
    let plane = LocalTangentPlane::new(scene.origin);
    let mut rng = ChaCha8Rng::seed_from_u64(1000 + k as u64);
    let b = scene.bounds_enu_m();
    let inner = |lo: f64, hi: f64| lo + 0.2 * (hi - lo)..hi - 0.2 * (hi - lo);
    let start = DVec3::new(
        rng.random_range(inner(b.min.x, b.max.x)),
        rng.random_range(inner(b.min.y, b.max.y)),
        rng.random_range(30.0..90.0),
    );
    let heading = rng.random_range(0.0..std::f64::consts::TAU);
    let v = DVec3::new(heading.cos(), heading.sin(), 0.0) * 12.0;
    super::flights::line_samples(&plane, start, start + v * seconds, 12.0, RATE_HZ)
}

/// Tick cost of one flight across the middle of grid scenes of each size, per mode.
pub fn sizes(sizes: &[usize], modes: &[Mode], config: CollisionConfig) -> Vec<SizeRow> {
    let mut rows: Vec<SizeRow> = Vec::new();
    for &n in sizes {
        let scene = grid_scene(n, 11);
        let plane = LocalTangentPlane::new(scene.origin);
        // 20 s at 15 m/s, 45 m up, along a row of buildings' edges: some hits, many near.
        let samples = super::flights::line_samples(
            &plane,
            DVec3::new(-150.0, 12.0, 45.0),
            DVec3::new(150.0, 12.0, 45.0),
            15.0,
            RATE_HZ,
        );
        for &mode in modes {
            let started = Instant::now();
            let mut pipeline = Pipeline::new(&scene, CollisionConfig { mode, ..config });
            let startup_s = started.elapsed().as_secs_f64();
            let (costs, events) = super::run_samples(&mut pipeline, &scene, 1, &samples, &[]);
            let (median, p99) = percentiles_us(&costs.tick_ns);
            let smallest = rows
                .iter()
                .find(|r| r.mode == mode.name())
                .map_or(median, |r| r.cost_median_us);
            rows.push(SizeRow {
                obstacles: n,
                mode: mode.name().to_owned(),
                startup_s,
                octree_bytes: pipeline.octree().memory_bytes(),
                cost_median_us: median,
                cost_p99_us: p99,
                cost_vs_smallest: median / smallest.max(1e-9),
                collisions: super::collisions(&events).len() as u64,
            });
        }
    }
    rows
}

/// Ticks per second for fleets of each size flying in `scene`, in `mode`: each vehicle against
/// the static scene and against every other vehicle of the fleet (a swarm: they are obstacles
/// to each other).
pub fn fleets(scene: &Scene, fleet_sizes: &[usize], config: CollisionConfig) -> Vec<FleetRow> {
    let seconds = 20.0;
    fleet_sizes
        .iter()
        .map(|&n| {
            let flights: Vec<Vec<TrackSample>> =
                (0..n).map(|k| fleet_flight(scene, k, seconds)).collect();
            let mut pipeline = Pipeline::new(scene, config);
            let mut events = Vec::new();
            let mut costs = Vec::with_capacity(n * flights[0].len());
            let mut busy_ns = 0u64;
            let model = scene.vehicle_model(1);
            let mut bodies = MovingBodies::default();
            let ids: Vec<Arc<str>> = (0..n).map(|k| format!("vehicle:{k}").into()).collect();
            // Time steps in order, every vehicle at each: as a live fleet arrives. The fleet's
            // poses are gathered once a step (what a world store holds), outside the timing.
            for i in 0..flights[0].len() {
                bodies.clear();
                bodies.extend(flights.iter().enumerate().map(|(k, f)| {
                    let pose = |s: &TrackSample| BodyPose::of(s);
                    DynamicBody {
                        key: VehicleKey::new(k as u16).as_body(),
                        id: ids[k].clone(),
                        kind: Kind::Dji,
                        threat: scene.threat_of(Kind::Dji),
                        geometry_index: model,
                        previous: pose(&f[i.saturating_sub(1)]),
                        current: pose(&f[i]),
                        speed_mps: f[i].velocity_enu_mps.length(),
                    }
                }));
                for (k, f) in flights.iter().enumerate() {
                    let previous = i.checked_sub(1).map(|p| &f[p]);
                    let started = Instant::now();
                    pipeline.step(
                        scene,
                        VehicleKey::new(k as u16),
                        previous,
                        &f[i],
                        &bodies,
                        &mut events,
                    );
                    let ns = started.elapsed().as_nanos() as u64;
                    busy_ns += ns;
                    costs.push(ns);
                }
                events.clear();
            }
            let ticks = costs.len() as u64;
            let ticks_per_s = ticks as f64 / (busy_ns.max(1) as f64 * 1e-9);
            let (median, p99) = percentiles_us(&costs);
            FleetRow {
                vehicles: n,
                ticks,
                ticks_per_s,
                real_time_factor: ticks_per_s / (n as f64 * RATE_HZ),
                cost_median_us: median,
                cost_p99_us: p99,
            }
        })
        .collect()
}
