//! A bench run's results: what it measured (its rows, `bench::rows`), the goals it checks,
//! and all of it as Markdown.

use std::fmt::Write as _;

use serde::{Deserialize, Serialize};

use crate::bench::machine::Machine;
use crate::bench::residency::ResidencyRow;
use crate::bench::rows::{FlightResult, SceneReport};
use crate::bench::scale;

/// A goal the bench checks (docs/performance.md, docs/accuracy-vs-speed.md) and whether this
/// run met it.
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
    /// The residency run (the first scene as meshes, under a budget), if it ran.
    #[serde(default)]
    pub residency: Option<ResidencyRow>,
    /// The goals, checked.
    pub goals: Vec<Goal>,
    /// Peak resident memory of the whole run, bytes (Linux; None elsewhere).
    pub peak_rss_bytes: Option<u64>,
    /// Wall time of the run, seconds.
    pub wall_s: f64,
}

pub(crate) fn goals(report: &BenchReport) -> Vec<Goal> {
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
    if let Some(f) = report.fleets.iter().max_by_key(|f| f.vehicles) {
        goals.push(Goal {
            goal: format!(
                "{} vehicles, obstacles to each other, at 50 Hz in real time on one core",
                f.vehicles
            ),
            measured: format!(
                "{:.0} ticks/s = {:.2}x real time",
                f.ticks_per_s, f.real_time_factor
            ),
            met: f.real_time_factor >= 1.0,
        });
    }
    if let Some(r) = &report.residency {
        goals.push(Goal {
            goal: format!(
                "{} as meshes: resident meshes within --mesh-budget-mib, 0 missed",
                r.scene
            ),
            measured: format!(
                "peak {:.1} of {:.1} MiB, {} missed, {} false",
                r.peak_bytes as f64 / 1048576.0,
                r.budget_bytes as f64 / 1048576.0,
                r.missed,
                r.false_collisions
            ),
            met: r.peak_bytes <= r.budget_bytes && r.missed == 0 && r.false_collisions == 0,
        });
    }
    goals
}

fn opt_ms(v: Option<f64>) -> String {
    v.map_or("-".into(), |s| format!("{:.3}", s * 1e3))
}

/// The report as markdown tables: the machine, then per scene its modes, their layers apart
/// and its flights, then scale, fleets, residency and goals (each when the run has it).
pub fn markdown(report: &BenchReport) -> String {
    let mut out = String::new();
    machine_line(&mut out, report);
    for s in &report.scenes {
        scene_modes_table(&mut out, s);
        scene_layers_table(&mut out, s);
        scene_flights_table(&mut out, s);
    }
    if !report.scale.is_empty() {
        scale_table(&mut out, &report.scale);
    }
    if !report.fleets.is_empty() {
        fleets_table(&mut out, &report.fleets);
    }
    if let Some(r) = &report.residency {
        residency_table(&mut out, r);
    }
    if !report.goals.is_empty() {
        goals_table(&mut out, &report.goals);
    }
    out
}

/// The machine, the wall time and the peak memory.
fn machine_line(out: &mut String, report: &BenchReport) {
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
}

/// A scene's heading and one row per mode: cost, colliders, memory, accuracy.
fn scene_modes_table(out: &mut String, s: &SceneReport) {
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
}

/// A scene's modes with the contact layer (per tick) and the sensing layer (per frame) apart.
fn scene_layers_table(out: &mut String, s: &SceneReport) {
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
}

/// A scene's flights: the reference's collisions and each mode's errors per flight, then what
/// each flight was built to do.
fn scene_flights_table(out: &mut String, s: &SceneReport) {
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
        let cells: Vec<String> = f.modes.iter().map(flight_cell).collect();
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

/// One mode's cell of the flights table: the reference's collisions, `ok`, or `-missed
/// +false`; near misses in brackets.
fn flight_cell(r: &FlightResult) -> String {
    let head = if r.mode == "reference" {
        r.collisions.to_string()
    } else if r.missed + r.false_collisions == 0 {
        "ok".into()
    } else {
        format!("-{} +{}", r.missed, r.false_collisions)
    };
    format!("{head} ({})", r.near_misses)
}

/// Cost by scene size.
fn scale_table(out: &mut String, rows: &[scale::SizeRow]) {
    let _ = writeln!(
        out,
        "### Scale: one flight over grids of box buildings\n\n\
         | obstacles | mode | start-up ms | octree MiB | median µs | p99 µs | × smallest | collisions |\n\
         |--:|---|--:|--:|--:|--:|--:|--:|"
    );
    for r in rows {
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

/// Throughput by fleet size.
fn fleets_table(out: &mut String, rows: &[scale::FleetRow]) {
    let _ = writeln!(
        out,
        "### Fleets: vehicles at 50 Hz in the first scene, exact, every vehicle an obstacle to the others, one core\n\n\
         | vehicles | ticks | ticks/s | × real time | median µs | p99 µs |\n|--:|--:|--:|--:|--:|--:|"
    );
    for f in rows {
        let _ = writeln!(
            out,
            "| {} | {} | {:.0} | {:.2} | {:.2} | {:.2} |",
            f.vehicles, f.ticks, f.ticks_per_s, f.real_time_factor, f.cost_median_us, f.cost_p99_us
        );
    }
    let _ = writeln!(out);
}

/// The residency run: meshes within the budget.
fn residency_table(out: &mut String, r: &ResidencyRow) {
    let mib = |b: usize| b as f64 / 1048576.0;
    let _ = writeln!(
        out,
        "### Residency: `{}` with every building a loaded triangle mesh, the flight set in one run, exact\n\n\
         {} meshes, {} triangles, {:.1} MiB were every mesh built at once; budget {:.1} MiB.\n\n\
         | peak resident MiB | built | built on contact | evicted | refused | ticks | median µs | p99 µs | collisions | missed | false |\n\
         |--:|--:|--:|--:|--:|--:|--:|--:|--:|--:|--:|\n\
         | {:.1} | {} | {} | {} | {} | {} | {:.2} | {:.2} | {} | {} | {} |\n",
        r.scene,
        r.mesh_obstacles,
        r.mesh_triangles,
        mib(r.all_meshes_bytes),
        mib(r.budget_bytes),
        mib(r.peak_bytes),
        r.built,
        r.built_on_contact,
        r.evicted,
        r.prefetch_refused,
        r.ticks,
        r.cost_median_us,
        r.cost_p99_us,
        r.collisions,
        r.missed,
        r.false_collisions
    );
}

/// The goals, checked.
fn goals_table(out: &mut String, goals: &[Goal]) {
    let _ = writeln!(out, "### Goals\n\n| goal | measured | met |\n|---|---|---|");
    for g in goals {
        let _ = writeln!(
            out,
            "| {} | {} | {} |",
            g.goal,
            g.measured,
            if g.met { "yes" } else { "**no**" }
        );
    }
}
