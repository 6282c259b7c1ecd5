//! The report's charts as SVG text, drawn with plotters (the crate the bench's PNG is drawn
//! with; its SVG backend writes plain `<rect>`, `<circle>`, `<polyline>` and `<text>`, which a
//! browser shows without a script or a network). Each chart says what it counts in its
//! caption; the page puts the numbers beside it.

use std::collections::BTreeMap;

use plotters::coord::types::RangedCoordf64;
use plotters::coord::Shift;
use plotters::prelude::*;

use crate::chart_font::font;
use crate::daa::ratios::{Estimate, VariantRatios};
use crate::error::{Error, Result};
use crate::runs::summary::Ratio;

/// Outcomes in the order they are stacked, with their colours.
pub const OUTCOMES: [(&str, RGBColor); 5] = [
    ("collision", RGBColor(214, 39, 40)),
    ("nmac", RGBColor(255, 127, 14)),
    ("soft_fail", RGBColor(188, 189, 34)),
    ("pass", RGBColor(44, 160, 44)),
    ("error", RGBColor(127, 127, 127)),
];

/// The colour of a variant's bars in histograms (by its position).
const VARIANT_COLOURS: [RGBColor; 6] = [
    RGBColor(31, 119, 180),
    RGBColor(148, 103, 189),
    RGBColor(23, 190, 207),
    RGBColor(140, 86, 75),
    RGBColor(227, 119, 194),
    RGBColor(127, 127, 127),
];

const WIDTH: u32 = 1000;
pub(super) const FONT: (&str, u32) = ("sans-serif", 13);
const CAPTION: (&str, u32) = ("sans-serif", 15);

pub(super) fn failed(e: impl std::fmt::Display) -> Error {
    Error::Usage(format!("drawing a chart: {e}"))
}

/// Draw into an SVG string of the page's width and `height` pixels.
fn svg(
    height: u32,
    draw: impl FnOnce(&DrawingArea<SVGBackend, Shift>) -> Result<()>,
) -> Result<String> {
    svg_of((WIDTH, height), draw)
}

/// Draw into an SVG string of `size` pixels.
pub(super) fn svg_of(
    size: (u32, u32),
    draw: impl FnOnce(&DrawingArea<SVGBackend, Shift>) -> Result<()>,
) -> Result<String> {
    font()?;
    let mut text = String::new();
    {
        let root = SVGBackend::with_string(&mut text, size).into_drawing_area();
        root.fill(&WHITE).map_err(failed)?;
        draw(&root)?;
        root.present().map_err(failed)?;
    }
    Ok(text)
}

/// Pixels for category labels of `names` (the font's advance is about 8 px at 13 px; a label
/// longer than [`LABEL_CHARS`] is shortened).
fn label_width(names: &[String]) -> u32 {
    let longest = names.iter().map(|n| n.chars().count()).max().unwrap_or(0);
    (longest.min(LABEL_CHARS) as u32 * 8 + 16).max(80)
}

/// The longest category label, in characters; longer ones keep their end (where variants
/// differ), after an ellipsis.
const LABEL_CHARS: usize = 48;

fn shorten(name: &str) -> String {
    let n = name.chars().count();
    if n <= LABEL_CHARS {
        return name.to_string();
    }
    let tail: String = name.chars().skip(n - (LABEL_CHARS - 1)).collect();
    format!("…{tail}")
}

/// The label of category `y` (an integer position) among `names`, else nothing.
fn category(names: &[String], y: f64) -> String {
    let i = y.round();
    if (y - i).abs() > 1e-6 || i < 0.0 {
        return String::new();
    }
    names
        .get(i as usize)
        .map(|n| shorten(n))
        .unwrap_or_default()
}

/// A count axis's label: the count at a whole number, nothing between (an axis from 0 to 2 has
/// ticks at 0, 0.2, ...: each would read "0", "0", "1", ... once rounded).
fn whole(x: f64) -> String {
    if (x - x.round()).abs() < 1e-6 {
        format!("{:.0}", x.round())
    } else {
        String::new()
    }
}

/// A chart of one row per category (`names`, from the bottom) along a value axis from 0 to
/// `x_max`, its caption and its axis drawn: the axis's description and its labels' decimals.
fn category_chart<'a, 'b>(
    root: &'a DrawingArea<SVGBackend<'b>, Shift>,
    caption: &str,
    names: &[String],
    x_max: f64,
    (x_desc, decimals): (&str, usize),
) -> Result<ChartContext<'a, SVGBackend<'b>, Cartesian2d<RangedCoordf64, RangedCoordf64>>> {
    let n = names.len().max(1);
    let mut chart = ChartBuilder::on(root)
        .caption(caption, CAPTION)
        .margin(10)
        .x_label_area_size(32)
        .y_label_area_size(label_width(names))
        .build_cartesian_2d(0f64..x_max, -0.5f64..(n as f64 - 0.5))
        .map_err(failed)?;
    chart
        .configure_mesh()
        .disable_y_mesh()
        .y_labels(n)
        .y_label_formatter(&|y| category(names, *y))
        .x_label_formatter(&|x| match decimals {
            0 => whole(*x),
            _ => format!("{x:.decimals$}"),
        })
        .x_desc(x_desc)
        .label_style(FONT)
        .draw()
        .map_err(failed)?;
    Ok(chart)
}

/// Per variant one horizontal bar, stacked by outcome ([`OUTCOMES`]): rows counted.
pub fn outcomes(counts: &BTreeMap<String, BTreeMap<String, u64>>) -> Result<String> {
    let names: Vec<String> = counts.keys().cloned().collect();
    let most = counts
        .values()
        .map(|c| c.values().sum::<u64>())
        .max()
        .unwrap_or(0);
    let n = names.len().max(1);
    // At least the legend's five lines high.
    svg((90 + 34 * n as u32).max(200), |root| {
        // Room on the right for the legend.
        let x_max = most.max(1) as f64 * 1.3;
        let mut chart = category_chart(
            root,
            "rows per variant, by outcome",
            &names,
            x_max,
            ("rows", 0),
        )?;
        for (name, colour) in OUTCOMES {
            let bars = counts.values().enumerate().filter_map(|(i, c)| {
                let before: u64 = OUTCOMES
                    .iter()
                    .take_while(|(o, _)| *o != name)
                    .filter_map(|(o, _)| c.get(*o))
                    .sum();
                let here = *c.get(name)?;
                let y = i as f64;
                Some(Rectangle::new(
                    [
                        (before as f64, y - 0.35),
                        ((before + here) as f64, y + 0.35),
                    ],
                    colour.filled(),
                ))
            });
            chart
                .draw_series(bars)
                .map_err(failed)?
                .label(name)
                .legend(move |(x, y)| {
                    Rectangle::new([(x, y - 5), (x + 10, y + 5)], colour.filled())
                });
        }
        chart
            .configure_series_labels()
            .background_style(WHITE.mix(0.85))
            .border_style(BLACK)
            .label_font(FONT)
            .position(SeriesLabelPosition::UpperRight)
            .draw()
            .map_err(failed)
    })
}

/// Every defined ratio as a point with its 95% interval as a line (an unbounded end drawn to
/// the chart's edge with an arrowhead), one line per variant and measure; 1 (no effect)
/// a grey line. `None` when no ratio is defined.
pub fn ratios(ratios: &[VariantRatios]) -> Result<Option<String>> {
    let rows: Vec<(String, Estimate)> = ratios
        .iter()
        .flat_map(|r| {
            Ratio::ALL.map(|k| {
                let (m, e) = k.of(r);
                (format!("{} {m}", r.variant), *e)
            })
        })
        .filter(|(_, e)| e.value.is_some())
        .collect();
    if rows.is_empty() {
        return Ok(None);
    }
    let finite = rows
        .iter()
        .flat_map(|(_, e)| [e.value, e.low, e.high])
        .flatten()
        .fold(1.0f64, f64::max);
    let x_max = finite * 1.15;
    let names: Vec<String> = rows.iter().map(|(n, _)| n.clone()).collect();
    let n = rows.len();
    let chart = svg(90 + 30 * n as u32, |root| {
        let caption = "risk ratios against the nominal variant, 95% intervals";
        let x_desc = ("ratio (1: no change)", 2);
        let mut chart = category_chart(root, caption, &names, x_max, x_desc)?;
        chart
            .draw_series(std::iter::once(PathElement::new(
                vec![(1.0, -0.5), (1.0, n as f64 - 0.5)],
                BLACK.mix(0.4).stroke_width(1),
            )))
            .map_err(failed)?;
        let colour = VARIANT_COLOURS[0];
        for (i, (_, e)) in rows.iter().enumerate() {
            let y = i as f64;
            let low = e.low.unwrap_or(0.0);
            let high = e.high.unwrap_or(x_max);
            chart
                .draw_series(std::iter::once(PathElement::new(
                    vec![(low, y), (high, y)],
                    colour.stroke_width(2),
                )))
                .map_err(failed)?;
            if e.high.is_none() {
                chart
                    .draw_series(std::iter::once(TriangleMarker::new(
                        (x_max, y),
                        6,
                        colour.filled(),
                    )))
                    .map_err(failed)?;
            }
            let value = e.value.unwrap_or(0.0);
            chart
                .draw_series(std::iter::once(Circle::new((value, y), 5, colour.filled())))
                .map_err(failed)?;
        }
        Ok(())
    })?;
    Ok(Some(chart))
}

/// One ratio's estimates as pairs accumulate: (pairs flown, estimate).
pub type Trace = (String, Vec<(usize, Estimate)>);

/// One panel per ratio, two a row: its value (points joined) and its 95% interval (a band; an
/// unbounded end clipped at the panel's top) against the number of pairs flown. `None`
/// without traces.
pub fn convergence(traces: &[Trace]) -> Result<Option<String>> {
    if traces.is_empty() {
        return Ok(None);
    }
    let pairs_max = traces
        .iter()
        .flat_map(|(_, t)| t.iter().map(|(n, _)| *n))
        .max()
        .unwrap_or(1)
        .max(1) as f64;
    // Two panels a row.
    let rows = traces.len().div_ceil(2);
    let chart = svg(170 * rows as u32, |root| {
        let areas = root.split_evenly((rows, 2));
        for ((name, trace), area) in traces.iter().zip(&areas) {
            let top = trace
                .iter()
                .flat_map(|(_, e)| [e.value, e.high])
                .flatten()
                .fold(1.0f64, f64::max)
                * 1.1;
            let mut chart = ChartBuilder::on(area)
                .caption(name, FONT)
                .margin(6)
                .x_label_area_size(28)
                .y_label_area_size(50)
                .build_cartesian_2d(0f64..pairs_max * 1.02, 0f64..top)
                .map_err(failed)?;
            chart
                .configure_mesh()
                .x_desc("pairs flown")
                .y_desc("ratio")
                .x_label_formatter(&|x| whole(*x))
                .y_labels(4)
                .label_style(FONT)
                .draw()
                .map_err(failed)?;
            let colour = VARIANT_COLOURS[0];
            let band: Vec<(f64, f64)> = trace
                .iter()
                .filter(|(_, e)| e.value.is_some())
                .map(|(n, e)| (*n as f64, e.high.unwrap_or(top).min(top)))
                .chain(
                    trace
                        .iter()
                        .rev()
                        .filter(|(_, e)| e.value.is_some())
                        .map(|(n, e)| (*n as f64, e.low.unwrap_or(0.0))),
                )
                .collect();
            chart
                .draw_series(std::iter::once(Polygon::new(
                    band,
                    colour.mix(0.2).filled(),
                )))
                .map_err(failed)?;
            let points: Vec<(f64, f64)> = trace
                .iter()
                .filter_map(|(n, e)| Some((*n as f64, e.value?)))
                .collect();
            chart
                .draw_series(std::iter::once(PathElement::new(
                    points.clone(),
                    colour.stroke_width(2),
                )))
                .map_err(failed)?;
            chart
                .draw_series(
                    points
                        .into_iter()
                        .map(|p| Circle::new(p, 3, colour.filled())),
                )
                .map_err(failed)?;
        }
        Ok(())
    })?;
    Ok(Some(chart))
}

/// Bins of equal width from 0 to the largest value (at least 1), and each series' counts.
fn bin(series: &[(String, Vec<f64>)], bins: usize) -> (f64, Vec<Vec<u64>>) {
    let top = series
        .iter()
        .flat_map(|(_, v)| v.iter().copied())
        .filter(|v| v.is_finite())
        .fold(1.0f64, f64::max);
    let width = top / bins as f64 * (1.0 + 1e-9);
    let counts = series
        .iter()
        .map(|(_, values)| {
            let mut c = vec![0u64; bins];
            for v in values.iter().filter(|v| v.is_finite()) {
                c[((v.max(0.0) / width) as usize).min(bins - 1)] += 1;
            }
            c
        })
        .collect();
    (width, counts)
}

/// One histogram panel per series (a variant), the same bins in each; `None` when no series
/// has a value.
pub fn histograms(x_desc: &str, series: &[(String, Vec<f64>)]) -> Result<Option<String>> {
    let series: Vec<(String, Vec<f64>)> = series
        .iter()
        .filter(|(_, v)| !v.is_empty())
        .cloned()
        .collect();
    if series.is_empty() {
        return Ok(None);
    }
    const BINS: usize = 30;
    let (width, counts) = bin(&series, BINS);
    let panels = series.len();
    let chart = svg(150 * panels as u32, |root| {
        let areas = root.split_evenly((panels, 1));
        for (k, ((name, values), area)) in series.iter().zip(&areas).enumerate() {
            let most = counts[k].iter().copied().max().unwrap_or(0).max(1);
            let mut chart = ChartBuilder::on(area)
                .caption(format!("{name}: {} rows", values.len()), FONT)
                .margin(6)
                .x_label_area_size(28)
                .y_label_area_size(50)
                .build_cartesian_2d(0f64..width * BINS as f64, 0f64..most as f64 * 1.1)
                .map_err(failed)?;
            chart
                .configure_mesh()
                .disable_x_mesh()
                .x_desc(x_desc)
                .y_desc("rows")
                .y_labels(4)
                .y_label_formatter(&|y| whole(*y))
                .label_style(FONT)
                .draw()
                .map_err(failed)?;
            let colour = VARIANT_COLOURS[k % VARIANT_COLOURS.len()];
            let bars = counts[k]
                .iter()
                .enumerate()
                .filter(|(_, c)| **c > 0)
                .map(|(b, c)| {
                    let x = b as f64 * width;
                    Rectangle::new([(x, 0.0), (x + width * 0.92, *c as f64)], colour.filled())
                });
            chart.draw_series(bars).map_err(failed)?;
        }
        Ok(())
    })?;
    Ok(Some(chart))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn values_fall_in_their_bins_and_the_largest_in_the_last() {
        let series = vec![("a".to_string(), vec![0.0, 0.5, 9.99, 10.0, f64::NAN])];
        let (width, counts) = bin(&series, 10);
        assert!((width - 1.0).abs() < 1e-6);
        assert_eq!(counts[0][0], 2);
        assert_eq!(counts[0][9], 2);
        assert_eq!(counts[0].iter().sum::<u64>(), 4);
    }

    /// The texts of an SVG's `<text>` elements.
    fn texts(svg: &str) -> Vec<String> {
        svg.split("<text")
            .skip(1)
            .filter_map(|t| t.split_once('>').and_then(|(_, r)| r.split_once("</text>")))
            .map(|(text, _)| text.trim().to_string())
            .collect()
    }

    /// A four-row study's outcomes: the count axis is labelled 0, 1, 2 once each (it read
    /// "0 0 1 1 2 2" before).
    #[test]
    fn a_count_axis_names_each_whole_number_once() {
        let mut counts = BTreeMap::new();
        for (variant, outcome, n) in [("nominal", "collision", 2), ("mitigated", "pass", 2)] {
            counts
                .entry(variant.to_string())
                .or_insert_with(BTreeMap::new)
                .insert(outcome.to_string(), n);
        }
        let numbers: Vec<String> = texts(&outcomes(&counts).unwrap())
            .into_iter()
            .filter(|t| t.parse::<f64>().is_ok())
            .collect();
        let mut unique = numbers.clone();
        unique.dedup();
        assert_eq!(numbers, unique, "{numbers:?}");
        assert!(numbers.contains(&"2".to_string()), "{numbers:?}");
        assert_eq!(whole(0.4), "");
        assert_eq!(whole(3.0000000001), "3");
    }

    #[test]
    fn categories_are_named_only_at_their_positions() {
        let names = vec!["nominal".to_string(), "mitigated".to_string()];
        assert_eq!(category(&names, 1.0), "mitigated");
        assert_eq!(category(&names, 0.5), "");
        assert_eq!(category(&names, 2.0), "");
        assert_eq!(category(&names, -1.0), "");
        let long = format!("mitigated/{}", "x".repeat(60));
        let short = shorten(&long);
        assert_eq!(short.chars().count(), LABEL_CHARS);
        assert!(short.starts_with('…') && short.ends_with("xxx"));
    }
}
