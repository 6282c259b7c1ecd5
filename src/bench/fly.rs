//! Flying the flight set through every mode's pipeline, and what it cost.

use std::time::Instant;

use crate::bench::compare::{collisions, compare};
use crate::bench::flights::{Flight, Traffic};
use crate::bench::rows::{FlightResult, FlightRow, ModeRow, SceneReport};
use crate::bench::BenchOptions;
use crate::collision::events::{Event, EventKind};
use crate::costs::percentiles_us;
use crate::pipeline::{CollisionConfig, Mode, MovingBodies, Pipeline, VehicleKey};
use crate::scene::Scene;
use crate::world::TrackSample;

/// What a flight cost, nanoseconds: each tick whole, its contact layer, and each sensing
/// frame.
#[derive(Debug, Clone, Default)]
pub struct Costs {
    /// Each tick, whole.
    pub tick_ns: Vec<u64>,
    /// Each tick's contact layer (and episodes).
    pub contact_ns: Vec<u64>,
    /// Each sensing frame.
    pub sensing_ns: Vec<u64>,
}

impl Costs {
    fn extend(&mut self, other: Costs) {
        self.tick_ns.extend(other.tick_ns);
        self.contact_ns.extend(other.contact_ns);
        self.sensing_ns.extend(other.sensing_ns);
    }
}

/// Fly `samples` (with `traffic`) through `pipeline` as vehicle `vehicle`; return the costs
/// and the events, near misses closed at the end.
pub fn run_samples(
    pipeline: &mut Pipeline,
    scene: &Scene,
    vehicle: u16,
    samples: &[TrackSample],
    traffic: &[Traffic],
) -> (Costs, Vec<Event>) {
    let mut costs = Costs::default();
    let mut events = Vec::new();
    let mut dynamic = MovingBodies::default();
    for (i, current) in samples.iter().enumerate() {
        let previous = i.checked_sub(1).map(|p| &samples[p]);
        let t_before = previous.map_or(current.t_s, |p| p.t_s);
        dynamic.clear();
        dynamic.extend(
            traffic
                .iter()
                .enumerate()
                .map(|(k, a)| a.body(scene, k as u32, t_before, current.t_s)),
        );
        let started = Instant::now();
        let report = pipeline.step(
            scene,
            VehicleKey::new(vehicle),
            previous,
            current,
            &dynamic,
            &mut events,
        );
        costs.tick_ns.push(started.elapsed().as_nanos() as u64);
        costs.contact_ns.push(report.contact_ns);
        if report.sensed {
            costs.sensing_ns.push(report.sensing_ns);
        }
    }
    pipeline.finish(&mut events);
    (costs, events)
}

/// One mode's pipeline over a scene's flights: what it cost to start, what each tick cost,
/// and its contact time errors against the reference.
struct ModeRun {
    mode: Mode,
    pipeline: Pipeline,
    startup_s: f64,
    costs: Costs,
    /// First-contact time errors against the reference, seconds.
    errors: Vec<f64>,
}

impl ModeRun {
    /// `mode`'s pipeline for `scene`, timed.
    fn start(scene: &Scene, mode: Mode, options: &BenchOptions) -> Self {
        let t = Instant::now();
        let pipeline = Pipeline::new(
            scene,
            CollisionConfig {
                mode,
                ..options.config
            },
        );
        ModeRun {
            mode,
            pipeline,
            startup_s: t.elapsed().as_secs_f64(),
            costs: Costs::default(),
            errors: Vec::new(),
        }
    }
}

/// Fly every flight through every mode (mode after mode, flight by flight; vehicle `k + 1`
/// flies flight `k`) and judge each mode against the `reference`, which `modes` must hold.
pub(crate) fn bench_scene(
    scene: &Scene,
    load_s: f64,
    flights: &[Flight],
    modes: &[Mode],
    options: &BenchOptions,
    progress: &mut impl FnMut(&str),
) -> SceneReport {
    let mut runs: Vec<ModeRun> = modes
        .iter()
        .map(|&mode| ModeRun::start(scene, mode, options))
        .collect();
    let truth_index = modes
        .iter()
        .position(|&m| m == Mode::Reference)
        .expect("the reference runs");
    let mut flight_rows = Vec::new();
    for (k, flight) in flights.iter().enumerate() {
        progress(&format!(
            "{}: {} ({} ticks)",
            scene.name,
            flight.name,
            flight.samples.len()
        ));
        let vehicle = k as u16 + 1;
        flight_rows.push(fly(scene, vehicle, flight, &mut runs, truth_index));
    }
    let box_median = percentiles_us(&runs[0].costs.tick_ns).0;
    let mode_rows = runs
        .iter()
        .enumerate()
        .map(|(m, run)| mode_row(run, m, &flight_rows, box_median))
        .collect();
    SceneReport {
        scene: scene.name.clone(),
        obstacles: scene.obstacles.len(),
        triangles: scene
            .obstacles
            .iter()
            .map(|o| o.geometry.triangle_count())
            .sum(),
        load_s,
        modes: mode_rows,
        flights: flight_rows,
    }
}

/// One flight through every mode's pipeline as `vehicle`; each mode's collisions compared with
/// the reference's (`runs[truth_index]`).
fn fly(
    scene: &Scene,
    vehicle: u16,
    flight: &Flight,
    runs: &mut [ModeRun],
    truth_index: usize,
) -> FlightRow {
    let events: Vec<Vec<Event>> = runs
        .iter_mut()
        .map(|run| {
            let (c, e) = run_samples(
                &mut run.pipeline,
                scene,
                vehicle,
                &flight.samples,
                &flight.traffic,
            );
            run.costs.extend(c);
            e
        })
        .collect();
    let truth = collisions(&events[truth_index]);
    let results = runs
        .iter_mut()
        .zip(&events)
        .map(|(run, events)| {
            let found = collisions(events);
            let (missed, false_collisions, errors, first) = compare(&truth, &found);
            run.errors.extend(errors);
            FlightResult {
                mode: run.mode.name().to_owned(),
                collisions: found.len(),
                missed,
                false_collisions,
                near_misses: events
                    .iter()
                    .filter(|e| matches!(e.kind, EventKind::NearMiss { .. }))
                    .count(),
                first_contact_error_s: first,
            }
        })
        .collect();
    FlightRow {
        name: flight.name.clone(),
        what: flight.what.clone(),
        rate_hz: flight.rate_hz,
        speed_mps: flight.speed_mps,
        ticks: flight.samples.len(),
        modes: results,
    }
}

/// Mode `m`'s row over every flight: costs, colliders, memory, accuracy; its median cost over
/// `box_median_us`.
fn mode_row(run: &ModeRun, m: usize, flight_rows: &[FlightRow], box_median_us: f64) -> ModeRow {
    let pipeline = &run.pipeline;
    let totals = &pipeline.totals();
    let ticks = totals.ticks.max(1) as f64;
    let (median, p99) = percentiles_us(&run.costs.tick_ns);
    let (contact_median, contact_p99) = percentiles_us(&run.costs.contact_ns);
    let (sensing_median, _) = percentiles_us(&run.costs.sensing_ns);
    let errors = &run.errors;
    let sum =
        |f: fn(&FlightResult) -> usize| flight_rows.iter().map(|r| f(&r.modes[m])).sum::<usize>();
    ModeRow {
        mode: run.mode.name().to_owned(),
        ticks: totals.ticks,
        cost_median_us: median,
        cost_p99_us: p99,
        cost_vs_box: median / box_median_us.max(1e-9),
        contact_median_us: contact_median,
        contact_p99_us: contact_p99,
        sensing_frames: totals.sensing_frames,
        sensing_median_us: sensing_median,
        meshes_built_on_contact: pipeline.meshes().counts().built_on_contact,
        active_box_mean: totals.active_box_sum as f64 / ticks,
        active_mesh_mean: totals.active_mesh_sum as f64 / ticks,
        triangles_mean: totals.active_triangles_sum as f64 / ticks,
        triangles_max: totals.active_triangles_max,
        memory_bytes: pipeline.octree().memory_bytes() + pipeline.meshes().counts().bytes,
        startup_s: run.startup_s,
        mesh_build_s: pipeline.meshes().counts().build_time.as_secs_f64(),
        collisions: sum(|r| r.collisions),
        missed: sum(|r| r.missed),
        false_collisions: sum(|r| r.false_collisions),
        contact_time_error_mean_s: (!errors.is_empty())
            .then(|| errors.iter().sum::<f64>() / errors.len() as f64),
        contact_time_error_max_s: errors.iter().copied().reduce(f64::max),
        wrong_flights: flight_rows
            .iter()
            .filter(|r| r.modes[m].missed + r.modes[m].false_collisions > 0)
            .map(|r| r.name.clone())
            .collect(),
    }
}
