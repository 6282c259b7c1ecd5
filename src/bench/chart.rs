//! The bench's PNG chart: per-tick cost (log scale) against collisions missed, one point per
//! mode per scene, drawn with plotters and a bundled font (DejaVu Sans Mono, see
//! assets/fonts/DejaVu-LICENSE.txt), so it needs no system fonts.

use std::path::Path;

use plotters::prelude::*;

use super::BenchReport;
use crate::chart_font::font;
use crate::error::{Error, Result};

/// Colour of a mode's points.
fn colour(mode: &str) -> RGBColor {
    match mode {
        "none" => RGBColor(150, 150, 150),
        "box" => RGBColor(31, 119, 180),
        "mesh" => RGBColor(255, 127, 14),
        "paper" => RGBColor(214, 39, 40),
        "exact" => RGBColor(44, 160, 44),
        _ => RGBColor(148, 103, 189),
    }
}

/// Draw the chart to `path` (PNG): one panel per scene, a point per mode.
pub fn draw(report: &BenchReport, path: &Path) -> Result<()> {
    font()?;
    let fail = |e: &dyn std::fmt::Display| Error::file(path, std::io::Error::other(e.to_string()));
    let costs = report
        .scenes
        .iter()
        .flat_map(|s| s.modes.iter().map(|r| r.cost_median_us.max(0.01)));
    let x_max = costs.clone().fold(1.0, f64::max) * 4.0;
    let x_min = costs.fold(f64::INFINITY, f64::min).min(1.0) / 3.0;
    let panels = report.scenes.len().max(1);
    let root = BitMapBackend::new(path, (560 * panels as u32, 560)).into_drawing_area();
    root.fill(&WHITE).map_err(|e| fail(&e))?;
    let root = root
        .titled(
            "savsim bench: median per-tick cost against collisions missed (truth: reference)",
            ("sans-serif", 18),
        )
        .map_err(|e| fail(&e))?;
    for (scene, area) in report.scenes.iter().zip(root.split_evenly((1, panels))) {
        let y_max = scene.modes.iter().map(|r| r.missed).max().unwrap_or(0) as f64 * 1.15 + 1.0;
        let mut chart = ChartBuilder::on(&area)
            .caption(&scene.scene, ("sans-serif", 16))
            .margin(12)
            .x_label_area_size(40)
            .y_label_area_size(48)
            .build_cartesian_2d((x_min..x_max).log_scale(), -0.5..y_max)
            .map_err(|e| fail(&e))?;
        chart
            .configure_mesh()
            .x_desc("microseconds per tick (log)")
            .y_desc("collisions missed")
            .label_style(("sans-serif", 13))
            .draw()
            .map_err(|e| fail(&e))?;
        for (k, r) in scene.modes.iter().enumerate() {
            let c = colour(&r.mode);
            let label = format!("{} (+{} false)", r.mode, r.false_collisions);
            // Alternate label heights so that modes at the same point stay readable.
            let dy = -16 + 14 * (k as i32 % 4);
            chart
                .draw_series(std::iter::once(
                    EmptyElement::at((r.cost_median_us.max(0.01), r.missed as f64))
                        + Circle::new((0, 0), 6, c.filled())
                        + Text::new(label, (9, dy), ("sans-serif", 13).into_font().color(&c)),
                ))
                .map_err(|e| fail(&e))?;
        }
    }
    root.present().map_err(|e| fail(&e))?;
    Ok(())
}
