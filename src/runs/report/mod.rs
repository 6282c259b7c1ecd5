//! `savsim study report DIR` and `savsim batch report DIR`: a results directory as one
//! self-contained HTML page (no network, no script but the table's sorting): the outcome
//! counts per variant, every risk ratio with its 95% interval, the ratios as pairs accumulate,
//! histograms of the closest approaches (to traffic, to obstacles), of when the autopilot first
//! acted and of the achieved speedups, the rows worth a look in plan (their tracks and the
//! scene's footprints), the rows (each linked to its recording when `--rerun-rows` kept one)
//! and the study's metadata from its shard files. Written whole or not at all.

pub mod charts;
pub mod html;
pub mod plan;

use std::path::{Path, PathBuf};

use crate::daa::ratios::{rates, ratios, Estimate, VariantRatios};
use crate::error::{Error, Result};
use crate::runs::recordings::{recording_path, RECORDINGS};
use crate::runs::summary::{Ratio, RowView, Summary};
use crate::runs::table::read_settings;

/// What the report is of.
#[derive(Debug, Clone, Copy)]
pub struct Options<'a> {
    /// `study` or `batch`.
    pub command: &'static str,
    /// The variant the others are compared with.
    pub nominal: &'a str,
    /// Only the rows that did not pass in the table (a batch of 10^5 rows), else every row.
    pub failing_rows_only: bool,
}

/// `study report` / `batch report`: the page of `summary` (read from `dir`) written to `out`
/// (default `dir/report.html`), its path printed.
pub fn command(dir: &Path, out: Option<&Path>, summary: &Summary, options: Options) -> Result<()> {
    let path = write(dir, summary, out, options)?;
    println!("{}", path.display());
    Ok(())
}

/// Write the report of `summary` (read from `dir`) to `out` (default `dir/report.html`);
/// the path written.
pub fn write(
    dir: &Path,
    summary: &Summary,
    out: Option<&Path>,
    options: Options,
) -> Result<PathBuf> {
    let out = out.map_or_else(|| dir.join("report.html"), Path::to_path_buf);
    let page = page(dir, summary, &out, options)?;
    crate::files::write_atomic(&out, |w| std::io::Write::write_all(w, page.as_bytes()))
        .map_err(|e| Error::file(&out, e))?;
    Ok(out)
}

/// The page's text.
fn page(dir: &Path, summary: &Summary, out: &Path, options: Options) -> Result<String> {
    let Options {
        command, nominal, ..
    } = options;
    let title = format!("savsim {command} report: {}", dir.display());
    // The bootstrap is the report's cost: each estimate computed once.
    let all = ratios(&summary.outcomes, nominal);
    let text = summary.text_of(&rates(&summary.outcomes), &all, nominal, 3);
    let mut sections = vec![html::section(
        "summary",
        "Summary",
        &format!("<pre>{}</pre>\n", html::escape(&text)),
    )];
    sections.push(html::section(
        "outcomes",
        "Outcomes",
        &html::figure(Some(charts::outcomes(&summary.counts)?), ""),
    ));
    sections.push(html::section(
        "ratios",
        &format!("Risk ratios against {nominal}"),
        &html::figure(
            charts::ratios(&all)?,
            "No ratio is defined: no variant was flown over the same pairs as the nominal one, \
             or the nominal one had no event.",
        ),
    ));
    sections.push(html::section(
        "convergence",
        "Risk ratios as pairs accumulate",
        &html::figure(
            charts::convergence(&convergence(summary, &all, nominal))?,
            "No ratio is defined.",
        ),
    ));
    sections.extend(distributions(summary)?);
    sections.extend(plans_section(dir, summary, out, options)?);
    sections.push(rows_section(dir, summary, out, options));
    sections.push(metadata(summary)?);
    Ok(html::page(&title, &sections))
}

/// Points on the convergence chart: the ratios over the first k/[`STEPS`] of the pairs (a
/// prefix costs its share of a bootstrap over all of them: 6 points cost 2.5 more).
const STEPS: usize = 6;

/// Each ratio defined over all the pairs (`all`), computed again over the first pairs (in the
/// order the rows name them) at [`STEPS`] sizes: is the answer settled, or still moving?
fn convergence(summary: &Summary, all: &[VariantRatios], nominal: &str) -> Vec<charts::Trace> {
    let mut order: Vec<&str> = Vec::new();
    let mut seen = std::collections::HashSet::new();
    for o in &summary.outcomes {
        if seen.insert(o.pair.as_str()) {
            order.push(o.pair.as_str());
        }
    }
    let mut traces: std::collections::BTreeMap<String, Vec<(usize, Estimate)>> = Default::default();
    let mut sizes: Vec<usize> = (1..STEPS).map(|k| order.len() * k / STEPS).collect();
    sizes.dedup();
    let prefixes = sizes.into_iter().filter(|n| *n > 0).map(|n| {
        let first: std::collections::HashSet<&str> = order[..n].iter().copied().collect();
        let some: Vec<_> = summary
            .outcomes
            .iter()
            .filter(|o| first.contains(o.pair.as_str()))
            .cloned()
            .collect();
        ratios(&some, nominal)
    });
    for rs in prefixes.chain(std::iter::once(all.to_vec())) {
        for r in rs {
            for (measure, e) in Ratio::ALL.map(|k| k.of(&r)) {
                traces
                    .entry(format!("{} {measure} ratio", r.variant))
                    .or_default()
                    .push((r.pairs, *e));
            }
        }
    }
    // Only the ratios defined over all the pairs.
    traces
        .into_iter()
        .filter(|(_, t)| t.last().is_some_and(|(_, e)| e.value.is_some()))
        .collect()
}

/// One row measure per variant, over the rows that have it.
fn per_variant(summary: &Summary, f: impl Fn(&RowView) -> Option<f64>) -> Vec<(String, Vec<f64>)> {
    summary
        .counts
        .keys()
        .map(|variant| {
            let values = summary
                .rows
                .iter()
                .filter(|r| &r.variant == variant)
                .filter_map(&f)
                .collect();
            (variant.clone(), values)
        })
        .collect()
}

/// A histogram's section id, heading, unit, and the measure of a row it counts.
type Measure = (
    &'static str,
    &'static str,
    &'static str,
    fn(&RowView) -> Option<f64>,
);

/// The histograms: closest approaches, first action, achieved speedup.
fn distributions(summary: &Summary) -> Result<Vec<String>> {
    let specs: [Measure; 4] = [
        ("traffic", "Closest approach to traffic", "metres", |r| {
            r.cpa_m
        }),
        (
            "obstacles",
            "Closest approach to an obstacle",
            "metres",
            |r| r.closest_obstacle_m,
        ),
        (
            "acted",
            "When the autopilot first acted",
            "seconds on the row's timeline",
            |r| r.first_acted_t_s,
        ),
        (
            "speedups",
            "Achieved speedup",
            "simulated seconds per wall-clock second",
            |r| r.achieved_speedup,
        ),
    ];
    specs
        .iter()
        .map(|&(id, heading, unit, f)| {
            let chart = charts::histograms(unit, &per_variant(summary, f))?;
            Ok(html::section(
                id,
                heading,
                &html::figure(chart, "No row has this measure."),
            ))
        })
        .collect()
}

/// The link to row `row`'s recording in `dir`, from the page at `out`: relative when the page
/// is in `dir`, else absolute; `None` when there is no recording.
fn recording_link(dir: &Path, out: &Path, row: &RowView) -> Option<String> {
    let path = recording_path(dir, row.index, &row.id);
    if !path.is_file() {
        return None;
    }
    if out.parent().is_some_and(|p| same_dir(p, dir)) {
        let name = path.file_name().unwrap_or_default().to_string_lossy();
        Some(format!("{RECORDINGS}/{name}"))
    } else {
        Some(path.canonicalize().unwrap_or(path).display().to_string())
    }
}

/// Plans drawn at most: the first rows worth a look.
const MAX_PLANS: usize = 24;

/// The rows worth a look (`RowView::worth_a_look`) that hold their track, in plan: the first
/// [`MAX_PLANS`], each linked to its recording. `None` when no row holds a track (a batch).
fn plans_section(
    dir: &Path,
    summary: &Summary,
    out: &Path,
    options: Options,
) -> Result<Option<String>> {
    let tracked = || summary.rows.iter().filter(|r| r.vehicle_track.is_some());
    if tracked().next().is_none() {
        return Ok(None);
    }
    let chosen: Vec<&RowView> = tracked()
        .filter(|r| r.worth_a_look(options.nominal))
        .collect();
    let scenes = crate::runs::scenes::SceneCache::load(
        chosen
            .iter()
            .take(MAX_PLANS)
            .filter_map(|r| r.scene.as_deref()),
    );
    let mut body = format!(
        "<p>{}</p>\n",
        html::escape(&format!(
            "{} rows are worth a look (not passed in a variant other than {nominal}, passed \
             in {nominal}, or failed to run){}. Seen from above: the vehicle's track (blue), \
             the intruder's (orange, from {around} s before the marked moment to {around} s \
             after), each from its dot; the scene's footprints (grey); the red crosses mark \
             both where the first collision, else the closest approach to traffic, happened.",
            chosen.len(),
            if chosen.len() > MAX_PLANS {
                format!(": the first {MAX_PLANS} are drawn")
            } else {
                String::new()
            },
            nominal = options.nominal,
            around = plan::AROUND_S,
        ))
    );
    for row in chosen.iter().take(MAX_PLANS) {
        let scene = scenes.get(row.scene.as_deref());
        let Some(svg) = plan::chart(row, scene.as_deref().ok())? else {
            continue;
        };
        let mut caption = html::escape(&format!("{} ({}, {})", row.id, row.variant, row.ended));
        if let Err(e) = scene {
            caption += &html::escape(&format!("; footprints not drawn: {e}"));
        }
        if let Some(href) = recording_link(dir, out, row) {
            caption += &format!(" <a href=\"{}\">.rrd</a>", html::escape(&href));
        }
        body +=
            &format!("<figure class=\"plan\">{svg}<figcaption>{caption}</figcaption></figure>\n");
    }
    Ok(Some(html::section(
        "plans",
        "Rows worth a look, in plan",
        &body,
    )))
}

/// The rows' table, each linked to its recording when there is one.
fn rows_section(dir: &Path, summary: &Summary, out: &Path, options: Options) -> String {
    let shown: Vec<&RowView> = summary
        .rows
        .iter()
        .filter(|r| !options.failing_rows_only || r.ended != "pass")
        .collect();
    let table = html::rows_table(&shown, |row| recording_link(dir, out, row));
    let what = if options.failing_rows_only {
        format!(
            "The {} of {} rows that did not pass; click a heading to sort.",
            shown.len(),
            summary.rows.len(),
        )
    } else {
        format!("All {} rows; click a heading to sort.", shown.len())
    };
    html::section(
        "rows",
        "Rows",
        &format!("<p>{}</p>\n{table}", html::escape(&what)),
    )
}

/// Whether `a` and `b` name one directory (`""` is the current one).
fn same_dir(a: &Path, b: &Path) -> bool {
    let real = |p: &Path| {
        let p = if p.as_os_str().is_empty() {
            Path::new(".")
        } else {
            p
        };
        p.canonicalize().ok()
    };
    real(a).is_some() && real(a) == real(b)
}

/// The shard files and what the first says of how the results were made.
fn metadata(summary: &Summary) -> Result<String> {
    let mut pairs: Vec<(String, String)> = match summary.files.first() {
        Some(first) => read_settings(first)?,
        None => Vec::new(),
    };
    // Arrow's own copy of the schema (base64) is for readers, not people.
    pairs.retain(|(k, _)| !k.starts_with("ARROW:"));
    let mut versions: Vec<&str> = summary
        .rows
        .iter()
        .filter_map(|r| r.autopilot_version.as_deref())
        .collect();
    versions.sort_unstable();
    versions.dedup();
    if !versions.is_empty() {
        pairs.push(("autopilot versions (rows)".into(), versions.join(", ")));
    }
    let files: Vec<String> = summary
        .files
        .iter()
        .map(|f| f.display().to_string())
        .collect();
    pairs.push(("shard files".into(), files.join(", ")));
    Ok(html::section(
        "metadata",
        "How these results were made",
        &html::pairs_table(&pairs),
    ))
}
