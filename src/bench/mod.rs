//! `savsim bench`: the speed/accuracy trade of the collision modes, measured side by side in one
//! run, against the independent ground truth of the `reference` mode (savsim's Table 4).
//!
//! For each scene, every flight of [`flights::flight_set`] is flown once per mode, the modes
//! interleaved flight by flight so that a noisy machine slows them alike. Each mode has its own
//! [`Pipeline`](crate::pipeline::Pipeline); each flight its own vehicle number in
//! it. Per-tick cost is the wall time of
//! [`Pipeline::step`](crate::pipeline::Pipeline::step) alone (building the moving
//! obstacles of a tick is outside it).
//!
//! Accuracy: a flight's collisions (obstacle, time of impact) are matched to the reference's by
//! obstacle, the k-th contact with an obstacle to the k-th; what the reference has and the mode
//! does not is *missed*, the rest of the mode's are *false*. The time error is the difference
//! in time of impact of matched contacts.
//!
//! - [`flights`]: the flight set; [`fly`]: flying it through each mode, the costs.
//! - [`compare`]: a mode's collisions against the reference's.
//! - [`scale`]: scene sizes and fleets; [`machine`]: where it ran.
//! - [`rows`]: what a run measured, row by row; [`results`]: all of it, its goals, Markdown;
//!   [`chart`]: the chart.
//! - [`residency`]: the mesh budget run.

pub mod chart;
pub mod compare;
pub mod flights;
pub mod fly;
pub mod machine;
pub mod residency;
pub mod results;
pub mod rows;
pub mod scale;

pub use compare::collisions;
pub use fly::{run_samples, Costs};
pub use machine::{peak_rss_bytes, Machine};
pub use results::{markdown, BenchReport, Goal};
pub use rows::{FlightResult, FlightRow, ModeRow, SceneReport};

use std::path::PathBuf;
use std::time::Instant;

use crate::error::Result;
use crate::pipeline::{CollisionConfig, Mode};
use crate::scene::Scene;

use flights::Flight;

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
    /// The residency run's mesh budget, MiB (0: no residency run).
    pub residency_budget_mib: f64,
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
    let mut first_scene: Option<(Scene, Vec<Flight>)> = None;
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
        scenes.push(fly::bench_scene(
            &scene,
            load_s,
            &flights,
            &modes,
            options,
            &mut progress,
        ));
        if first_scene.is_none() {
            first_scene = Some((scene, flights));
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
        (Some((scene, _)), false) => {
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
    let residency = match &first_scene {
        Some((scene, flights)) if options.residency_budget_mib > 0.0 => {
            progress("residency: the first scene's buildings as meshes, under a budget");
            Some(residency::run(
                scene,
                flights,
                options.config,
                options.residency_budget_mib,
            ))
        }
        _ => None,
    };
    let mut report = BenchReport {
        machine: machine::machine(),
        scenes,
        scale,
        fleets,
        residency,
        goals: Vec::new(),
        peak_rss_bytes: peak_rss_bytes(),
        wall_s: started.elapsed().as_secs_f64(),
    };
    report.goals = results::goals(&report);
    Ok(report)
}
