//! `savsim bench`: the speed/accuracy trade of the collision modes, measured side by side in one
//! run, against the independent ground truth of the `reference` mode (savsim's Table 4).
//!
//! For each scene, every flight of [`flights::flight_set`] is flown once per mode, the modes
//! interleaved flight by flight so that a noisy machine slows them alike. Each mode has its own
//! [`Pipeline`]; each flight its own vehicle number in it. Per-tick cost is the wall time of
//! [`Pipeline::step`] alone (building the moving obstacles of a tick is outside it).
//!
//! Accuracy: a flight's collisions (obstacle, time of impact) are matched to the reference's by
//! obstacle, the k-th contact with an obstacle to the k-th; what the reference has and the mode
//! does not is *missed*, the rest of the mode's are *false*. The time error is the difference
//! in time of impact of matched contacts.

pub mod chart;
pub mod flights;
pub mod scale;

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::PathBuf;
use std::time::Instant;

use serde::{Deserialize, Serialize};

use crate::collision::events::{Event, EventKind};
use crate::collision::pipeline::{CollisionConfig, DynamicBody, Mode, Pipeline, VehicleKey};
use crate::error::Result;
use crate::scene::Scene;
use crate::session::percentiles_us;
use crate::world::TrackSample;

use flights::{Flight, Traffic};

/// A scene to bench.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum SceneChoice {
    /// The bundled city (scenes/city.toml).
    City,
    /// The bundled mountain (scenes/mountain.toml).
    Mountain,
    /// A scene file.
    Path(PathBuf),
}

impl std::str::FromStr for SceneChoice {
    type Err = std::convert::Infallible;

    fn from_str(s: &str) -> std::result::Result<Self, Self::Err> {
        Ok(match s {
            "city" => SceneChoice::City,
            "mountain" => SceneChoice::Mountain,
            other => SceneChoice::Path(other.into()),
        })
    }
}

impl SceneChoice {
    /// The scene file.
    pub fn path(&self) -> PathBuf {
        match self {
            SceneChoice::City => crate::bundled::bundled("scenes/city.toml"),
            SceneChoice::Mountain => crate::bundled::bundled("scenes/mountain.toml"),
            SceneChoice::Path(p) => p.clone(),
        }
    }
}

/// What to run.
#[derive(Debug, Clone)]
pub struct BenchOptions {
    /// Scenes, in order.
    pub scenes: Vec<SceneChoice>,
    /// Only flights whose name contains one of these (all when empty).
    pub flights: Vec<String>,
    /// Modes to report. `box` (the cost reference) and `reference` (the truth) always run.
    pub modes: Vec<Mode>,
    /// Settings other than the mode.
    pub config: CollisionConfig,
    /// Scene sizes for the scale run (empty: none).
    pub scale_sizes: Vec<usize>,
    /// Fleet sizes for the fleet run in the first scene (empty: none).
    pub fleet_sizes: Vec<usize>,
}

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

/// The machine the run was on.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Machine {
    /// CPU model.
    pub cpu: String,
    /// Logical CPUs.
    pub cpus: usize,
    /// OS and architecture.
    pub os: String,
    /// savsim version and build profile.
    pub build: String,
}

/// A goal of issue 5 and whether this run met it.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Goal {
    /// The goal.
    pub goal: String,
    /// What was measured.
    pub measured: String,
    /// Met?
    pub met: bool,
}

/// Everything a bench run measured.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct BenchReport {
    /// Where.
    pub machine: Machine,
    /// Per scene.
    pub scenes: Vec<SceneReport>,
    /// Tick cost by scene size.
    pub scale: Vec<scale::SizeRow>,
    /// Throughput by fleet size.
    pub fleets: Vec<scale::FleetRow>,
    /// The goals, checked.
    pub goals: Vec<Goal>,
    /// Peak resident memory of the whole run, bytes (Linux; None elsewhere).
    pub peak_rss_bytes: Option<u64>,
    /// Wall time of the run, seconds.
    pub wall_s: f64,
}

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
    let mut dynamic: Vec<DynamicBody> = Vec::with_capacity(traffic.len());
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

/// The collisions among `events`: (obstacle, time of impact), in order.
pub fn collisions(events: &[Event]) -> Vec<(&str, f64)> {
    events
        .iter()
        .filter_map(|e| match &e.kind {
            EventKind::Collision {
                obstacle,
                time_of_impact,
                ..
            } => Some((obstacle.as_str(), *time_of_impact)),
            _ => None,
        })
        .collect()
}

/// Matches `found` to `truth` by obstacle, k-th to k-th: (missed, false, |dt| of each match,
/// |dt| of the first contact when both have one).
fn compare(truth: &[(&str, f64)], found: &[(&str, f64)]) -> (usize, usize, Vec<f64>, Option<f64>) {
    let mut by_obstacle: BTreeMap<&str, (Vec<f64>, Vec<f64>)> = BTreeMap::new();
    for &(o, t) in truth {
        by_obstacle.entry(o).or_default().0.push(t);
    }
    for &(o, t) in found {
        by_obstacle.entry(o).or_default().1.push(t);
    }
    let (mut missed, mut false_, mut errors) = (0, 0, Vec::new());
    for (t, f) in by_obstacle.values() {
        missed += t.len().saturating_sub(f.len());
        false_ += f.len().saturating_sub(t.len());
        errors.extend(t.iter().zip(f).map(|(a, b)| (a - b).abs()));
    }
    let first = match (truth.first(), found.first()) {
        (Some(a), Some(b)) => Some((a.1 - b.1).abs()),
        _ => None,
    };
    (missed, false_, errors, first)
}

fn machine() -> Machine {
    let cpu = std::fs::read_to_string("/proc/cpuinfo")
        .ok()
        .and_then(|s| {
            s.lines()
                .find(|l| l.starts_with("model name"))
                .and_then(|l| l.split(':').nth(1))
                .map(|m| m.trim().to_owned())
        })
        .unwrap_or_else(|| "unknown".into());
    Machine {
        cpu,
        cpus: std::thread::available_parallelism().map_or(1, |n| n.get()),
        os: format!("{} {}", std::env::consts::OS, std::env::consts::ARCH),
        build: format!(
            "savsim {} ({})",
            env!("CARGO_PKG_VERSION"),
            if cfg!(debug_assertions) {
                "debug build: costs are not representative"
            } else {
                "release build"
            }
        ),
    }
}

/// Peak resident set of this process, bytes (VmHWM; Linux only).
pub fn peak_rss_bytes() -> Option<u64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kb: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb * 1024)
}

/// Run the bench; `progress` hears what is being done.
pub fn run(options: &BenchOptions, mut progress: impl FnMut(&str)) -> Result<BenchReport> {
    let started = Instant::now();
    // box is the cost reference and `reference` the truth: both always run.
    let mut modes: Vec<Mode> = Vec::new();
    for m in [Mode::Box]
        .into_iter()
        .chain(options.modes.iter().copied())
        .chain([Mode::Reference])
    {
        if !modes.contains(&m) {
            modes.push(m);
        }
    }
    let mut scenes = Vec::new();
    let mut first_scene: Option<Scene> = None;
    for choice in &options.scenes {
        let path = choice.path();
        progress(&format!("loading {}", path.display()));
        let t = Instant::now();
        let scene = crate::scene::load(&path)?;
        let load_s = t.elapsed().as_secs_f64();
        let flights: Vec<Flight> = flights::flight_set(&scene)
            .into_iter()
            .filter(|f| {
                options.flights.is_empty()
                    || options.flights.iter().any(|n| f.name.contains(n.as_str()))
            })
            .collect();
        scenes.push(bench_scene(
            &scene,
            load_s,
            &flights,
            &modes,
            options,
            &mut progress,
        ));
        if first_scene.is_none() {
            first_scene = Some(scene);
        }
    }
    let scale = if options.scale_sizes.is_empty() {
        Vec::new()
    } else {
        progress("scale: scenes of 10^2 .. 10^6 obstacles");
        scale::sizes(
            &options.scale_sizes,
            &[Mode::Box, Mode::Exact],
            options.config,
        )
    };
    let fleets = match (&first_scene, options.fleet_sizes.is_empty()) {
        (Some(scene), false) => {
            progress("fleets: 1 .. 1000 vehicles");
            scale::fleets(
                scene,
                &options.fleet_sizes,
                CollisionConfig {
                    mode: Mode::Exact,
                    ..options.config
                },
            )
        }
        _ => Vec::new(),
    };
    let mut report = BenchReport {
        machine: machine(),
        scenes,
        scale,
        fleets,
        goals: Vec::new(),
        peak_rss_bytes: peak_rss_bytes(),
        wall_s: started.elapsed().as_secs_f64(),
    };
    report.goals = goals(&report);
    Ok(report)
}

fn bench_scene(
    scene: &Scene,
    load_s: f64,
    flights: &[Flight],
    modes: &[Mode],
    options: &BenchOptions,
    progress: &mut impl FnMut(&str),
) -> SceneReport {
    let mut pipelines: Vec<(Pipeline, f64)> = modes
        .iter()
        .map(|&mode| {
            let t = Instant::now();
            let p = Pipeline::new(
                scene,
                CollisionConfig {
                    mode,
                    ..options.config
                },
            );
            (p, t.elapsed().as_secs_f64())
        })
        .collect();
    let mut costs: Vec<Costs> = vec![Costs::default(); modes.len()];
    let mut per_mode_errors: Vec<Vec<f64>> = vec![Vec::new(); modes.len()];
    let mut flight_rows = Vec::new();
    let truth_index = modes
        .iter()
        .position(|&m| m == Mode::Reference)
        .expect("the reference runs");
    for (k, flight) in flights.iter().enumerate() {
        progress(&format!(
            "{}: {} ({} ticks)",
            scene.name,
            flight.name,
            flight.samples.len()
        ));
        let vehicle = k as u16 + 1;
        let events: Vec<Vec<Event>> = pipelines
            .iter_mut()
            .enumerate()
            .map(|(m, (pipeline, _))| {
                let (c, e) =
                    run_samples(pipeline, scene, vehicle, &flight.samples, &flight.traffic);
                costs[m].extend(c);
                e
            })
            .collect();
        let truth = collisions(&events[truth_index]);
        let results = modes
            .iter()
            .enumerate()
            .map(|(m, mode)| {
                let found = collisions(&events[m]);
                let (missed, false_collisions, errors, first) = compare(&truth, &found);
                per_mode_errors[m].extend(errors);
                FlightResult {
                    mode: mode.name().to_owned(),
                    collisions: found.len(),
                    missed,
                    false_collisions,
                    near_misses: events[m]
                        .iter()
                        .filter(|e| matches!(e.kind, EventKind::NearMiss { .. }))
                        .count(),
                    first_contact_error_s: first,
                }
            })
            .collect();
        flight_rows.push(FlightRow {
            name: flight.name.clone(),
            what: flight.what.clone(),
            rate_hz: flight.rate_hz,
            speed_mps: flight.speed_mps,
            ticks: flight.samples.len(),
            modes: results,
        });
    }
    let box_median = percentiles_us(&costs[0].tick_ns).0;
    let mode_rows = modes
        .iter()
        .enumerate()
        .map(|(m, mode)| {
            let (pipeline, startup_s) = &pipelines[m];
            let totals = &pipeline.totals;
            let ticks = totals.ticks.max(1) as f64;
            let (median, p99) = percentiles_us(&costs[m].tick_ns);
            let (contact_median, contact_p99) = percentiles_us(&costs[m].contact_ns);
            let (sensing_median, _) = percentiles_us(&costs[m].sensing_ns);
            let errors = &per_mode_errors[m];
            let sum = |f: fn(&FlightResult) -> usize| {
                flight_rows.iter().map(|r| f(&r.modes[m])).sum::<usize>()
            };
            ModeRow {
                mode: mode.name().to_owned(),
                ticks: totals.ticks,
                cost_median_us: median,
                cost_p99_us: p99,
                cost_vs_box: median / box_median.max(1e-9),
                contact_median_us: contact_median,
                contact_p99_us: contact_p99,
                sensing_frames: totals.sensing_frames,
                sensing_median_us: sensing_median,
                meshes_built_on_contact: pipeline.meshes.built_on_contact,
                active_box_mean: totals.active_box_sum as f64 / ticks,
                active_mesh_mean: totals.active_mesh_sum as f64 / ticks,
                triangles_mean: totals.active_triangles_sum as f64 / ticks,
                triangles_max: totals.active_triangles_max,
                memory_bytes: pipeline.octree.memory_bytes() + pipeline.meshes.bytes,
                startup_s: *startup_s,
                mesh_build_s: pipeline.meshes.build_time.as_secs_f64(),
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
        })
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

fn goals(report: &BenchReport) -> Vec<Goal> {
    let mut goals = Vec::new();
    for s in &report.scenes {
        let row = |m: &str| s.modes.iter().find(|r| r.mode == m);
        let (Some(e), Some(b)) = (row("exact"), row("box")) else {
            continue;
        };
        let error_ms = e.contact_time_error_max_s.unwrap_or(0.0) * 1e3;
        goals.push(Goal {
            goal: format!(
                "{}: exact 0 missed, 0 false, contact time error <= 1 ms",
                s.scene
            ),
            measured: format!(
                "{} missed, {} false, {error_ms:.3} ms",
                e.missed, e.false_collisions
            ),
            met: e.missed == 0 && e.false_collisions == 0 && error_ms <= 1.0,
        });
        let median = e.contact_median_us / b.contact_median_us.max(1e-9);
        let p99 = e.contact_p99_us / b.contact_p99_us.max(1e-9);
        goals.push(Goal {
            goal: format!(
                "{}: exact contact layer median <= 1.5x box, p99 <= 5x box",
                s.scene
            ),
            measured: format!("{median:.2}x median, {p99:.2}x p99"),
            met: median <= 1.5 && p99 <= 5.0,
        });
        if s.scene == "city" {
            goals.push(Goal {
                goal: "city: sensing frame (six rays, beta, residency) <= 3 us median".into(),
                measured: format!("{:.2} us", e.sensing_median_us),
                met: e.sensing_median_us <= 3.0,
            });
        }
    }
    let exact_scale: Vec<_> = report.scale.iter().filter(|r| r.mode == "exact").collect();
    if let (Some(first), Some(last)) = (exact_scale.first(), exact_scale.last()) {
        goals.push(Goal {
            goal: format!(
                "exact: {} -> {} obstacles costs <= 3x per tick",
                first.obstacles, last.obstacles
            ),
            measured: format!("{:.2}x", last.cost_vs_smallest),
            met: last.cost_vs_smallest <= 3.0,
        });
    }
    if let Some(f) = report.fleets.iter().find(|f| f.vehicles == 100) {
        goals.push(Goal {
            goal: "100 vehicles at 50 Hz in real time on one core".into(),
            measured: format!(
                "{:.0} ticks/s = {:.2}x real time",
                f.ticks_per_s, f.real_time_factor
            ),
            met: f.real_time_factor >= 1.0,
        });
    }
    goals
}

fn opt_ms(v: Option<f64>) -> String {
    v.map_or("-".into(), |s| format!("{:.3}", s * 1e3))
}

/// The report as markdown tables.
pub fn markdown(report: &BenchReport) -> String {
    let mut out = String::new();
    let m = &report.machine;
    let _ = writeln!(
        out,
        "Machine: {} ({} logical CPUs), {}, {}. Wall time {:.0} s, peak RSS {}.\n",
        m.cpu,
        m.cpus,
        m.os,
        m.build,
        report.wall_s,
        report.peak_rss_bytes.map_or("unknown".into(), |b| format!(
            "{:.0} MiB",
            b as f64 / 1048576.0
        ))
    );
    for s in &report.scenes {
        let _ = writeln!(
            out,
            "### Scene `{}`: {} obstacles, {} triangles, loaded in {:.2} s\n",
            s.scene, s.obstacles, s.triangles, s.load_s
        );
        let _ = writeln!(
            out,
            "| mode | median µs | p99 µs | × box | boxes | meshes | triangles (mean / max) | memory MiB | start-up ms | mesh build ms | collisions | missed | false | contact time error ms (mean / max) |\n\
             |---|--:|--:|--:|--:|--:|--:|--:|--:|--:|--:|--:|--:|--:|"
        );
        for r in &s.modes {
            let _ = writeln!(
                out,
                "| {} | {:.2} | {:.2} | {:.2} | {:.1} | {:.1} | {:.0} / {} | {:.1} | {:.1} | {:.0} | {} | {} | {} | {} / {} |",
                r.mode,
                r.cost_median_us,
                r.cost_p99_us,
                r.cost_vs_box,
                r.active_box_mean,
                r.active_mesh_mean,
                r.triangles_mean,
                r.triangles_max,
                r.memory_bytes as f64 / 1048576.0,
                r.startup_s * 1e3,
                r.mesh_build_s * 1e3,
                r.collisions,
                r.missed,
                r.false_collisions,
                opt_ms(r.contact_time_error_mean_s),
                opt_ms(r.contact_time_error_max_s),
            );
        }
        let _ = writeln!(
            out,
            "\nThe layers apart: the contact layer per tick, the sensing layer per frame.\n\n\
             | mode | contact median µs | contact p99 µs | contact × box (median / p99) | sensing frames | sensing µs per frame (median) | meshes built on contact |\n\
             |---|--:|--:|--:|--:|--:|--:|"
        );
        let box_row = s.modes.iter().find(|r| r.mode == "box");
        for r in &s.modes {
            let vs = box_row.map_or("-".into(), |b| {
                format!(
                    "{:.2} / {:.2}",
                    r.contact_median_us / b.contact_median_us.max(1e-9),
                    r.contact_p99_us / b.contact_p99_us.max(1e-9)
                )
            });
            let _ = writeln!(
                out,
                "| {} | {:.2} | {:.2} | {} | {} | {:.2} | {} |",
                r.mode,
                r.contact_median_us,
                r.contact_p99_us,
                vs,
                r.sensing_frames,
                r.sensing_median_us,
                r.meshes_built_on_contact
            );
        }
        let _ = writeln!(
            out,
            "\nPer flight: the reference's collisions, and per mode `ok` or `-missed +false` \
             (near misses in brackets).\n"
        );
        let names: Vec<&str> = s.modes.iter().map(|r| r.mode.as_str()).collect();
        let _ = writeln!(
            out,
            "| flight | Hz | m/s | ticks | {} |\n|---|--:|--:|--:|{}",
            names.join(" | "),
            "--:|".repeat(names.len())
        );
        for f in &s.flights {
            let cells: Vec<String> = f
                .modes
                .iter()
                .map(|r| {
                    let head = if r.mode == "reference" {
                        r.collisions.to_string()
                    } else if r.missed + r.false_collisions == 0 {
                        "ok".into()
                    } else {
                        format!("-{} +{}", r.missed, r.false_collisions)
                    };
                    format!("{head} ({})", r.near_misses)
                })
                .collect();
            let _ = writeln!(
                out,
                "| {} | {} | {} | {} | {} |",
                f.name,
                f.rate_hz,
                f.speed_mps,
                f.ticks,
                cells.join(" | ")
            );
        }
        let _ = writeln!(out, "\nFlights:\n");
        for f in &s.flights {
            let _ = writeln!(out, "- `{}`: {}", f.name, f.what);
        }
        let _ = writeln!(out);
    }
    if !report.scale.is_empty() {
        let _ = writeln!(
            out,
            "### Scale: one flight over grids of box buildings\n\n\
             | obstacles | mode | start-up ms | octree MiB | median µs | p99 µs | × smallest | collisions |\n\
             |--:|---|--:|--:|--:|--:|--:|--:|"
        );
        for r in &report.scale {
            let _ = writeln!(
                out,
                "| {} | {} | {:.1} | {:.2} | {:.2} | {:.2} | {:.2} | {} |",
                r.obstacles,
                r.mode,
                r.startup_s * 1e3,
                r.octree_bytes as f64 / 1048576.0,
                r.cost_median_us,
                r.cost_p99_us,
                r.cost_vs_smallest,
                r.collisions
            );
        }
        let _ = writeln!(out);
    }
    if !report.fleets.is_empty() {
        let _ = writeln!(
            out,
            "### Fleets: vehicles at 50 Hz in the first scene, exact, every vehicle an obstacle to the others, one core\n\n\
             | vehicles | ticks | ticks/s | × real time | median µs | p99 µs |\n|--:|--:|--:|--:|--:|--:|"
        );
        for f in &report.fleets {
            let _ = writeln!(
                out,
                "| {} | {} | {:.0} | {:.2} | {:.2} | {:.2} |",
                f.vehicles,
                f.ticks,
                f.ticks_per_s,
                f.real_time_factor,
                f.cost_median_us,
                f.cost_p99_us
            );
        }
        let _ = writeln!(out);
    }
    if !report.goals.is_empty() {
        let _ = writeln!(out, "### Goals\n\n| goal | measured | met |\n|---|---|---|");
        for g in &report.goals {
            let _ = writeln!(
                out,
                "| {} | {} | {} |",
                g.goal,
                g.measured,
                if g.met { "yes" } else { "**no**" }
            );
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::compare;

    #[test]
    fn compare_matches_by_obstacle_in_order() {
        let truth = [("a", 1.0), ("b", 2.0), ("a", 5.0)];
        let found = [("a", 1.2), ("c", 3.0)];
        let (missed, false_, errors, first) = compare(&truth, &found);
        assert_eq!((missed, false_), (2, 1));
        assert_eq!(errors.len(), 1);
        assert!((errors[0] - 0.2).abs() < 1e-12);
        assert!((first.unwrap() - 0.2).abs() < 1e-12);
    }
}
