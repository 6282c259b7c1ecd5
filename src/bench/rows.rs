//! What a bench run measured, row by row: each mode in each scene, each flight, each scene.

use serde::{Deserialize, Serialize};

/// One mode in one scene.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct ModeRow {
    /// Mode name.
    pub mode: String,
    /// Ticks over all flights.
    pub ticks: u64,
    /// Median per-tick cost, microseconds.
    pub cost_median_us: f64,
    /// 99th percentile per-tick cost, microseconds.
    pub cost_p99_us: f64,
    /// Median cost over `box`'s median in the same run.
    pub cost_vs_box: f64,
    /// Median per-tick cost of the contact layer alone, microseconds.
    #[serde(default)]
    pub contact_median_us: f64,
    /// 99th percentile per-tick cost of the contact layer alone, microseconds.
    #[serde(default)]
    pub contact_p99_us: f64,
    /// Sensing frames run.
    #[serde(default)]
    pub sensing_frames: u64,
    /// Median cost of one sensing frame (rays, beta, residency), microseconds.
    #[serde(default)]
    pub sensing_median_us: f64,
    /// Meshes built because a contact needed one that was not resident.
    #[serde(default)]
    pub meshes_built_on_contact: usize,
    /// Mean active box colliders per tick.
    pub active_box_mean: f64,
    /// Mean active mesh colliders per tick.
    pub active_mesh_mean: f64,
    /// Mean triangles in active meshes per tick.
    pub triangles_mean: f64,
    /// Most triangles in active meshes at one tick.
    pub triangles_max: usize,
    /// Memory the mode's pipeline holds at the end (octree and built meshes), bytes.
    pub memory_bytes: usize,
    /// Building the pipeline, seconds.
    pub startup_s: f64,
    /// Building meshes during the flights, seconds.
    pub mesh_build_s: f64,
    /// Collisions reported.
    pub collisions: usize,
    /// The reference's collisions this mode did not report.
    pub missed: usize,
    /// Collisions this mode reported that the reference did not.
    pub false_collisions: usize,
    /// Mean |time of impact - reference's| over matched collisions, seconds.
    pub contact_time_error_mean_s: Option<f64>,
    /// Largest |time of impact - reference's| over matched collisions, seconds.
    pub contact_time_error_max_s: Option<f64>,
    /// Flights with a missed or false collision.
    pub wrong_flights: Vec<String>,
}

/// One flight's result in one mode.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct FlightResult {
    /// Mode name.
    pub mode: String,
    /// Collisions reported.
    pub collisions: usize,
    /// Missed against the reference.
    pub missed: usize,
    /// False against the reference.
    pub false_collisions: usize,
    /// Near misses reported.
    pub near_misses: usize,
    /// |time of impact - reference's| of the flight's first collision, seconds.
    pub first_contact_error_s: Option<f64>,
}

/// One flight.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct FlightRow {
    /// Name.
    pub name: String,
    /// What it was built to do.
    pub what: String,
    /// Telemetry rate, Hz.
    pub rate_hz: f64,
    /// Speed, m/s.
    pub speed_mps: f64,
    /// Samples.
    pub ticks: usize,
    /// Results per mode.
    pub modes: Vec<FlightResult>,
}

/// One scene.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct SceneReport {
    /// Scene name.
    pub scene: String,
    /// Static obstacles.
    pub obstacles: usize,
    /// Triangles of all static obstacles.
    pub triangles: usize,
    /// Loading the scene file, seconds.
    pub load_s: f64,
    /// Per mode.
    pub modes: Vec<ModeRow>,
    /// Per flight.
    pub flights: Vec<FlightRow>,
}
