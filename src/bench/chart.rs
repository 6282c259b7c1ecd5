//! The bench's PNG chart: per-tick cost (log scale) against collisions missed, one point per
//! mode per scene, drawn with plotters and a bundled font (DejaVu Sans Mono, see
//! assets/fonts/DejaVu-LICENSE.txt), so it needs no system fonts.

use std::path::Path;
use std::sync::Once;

use plotters::prelude::*;
use plotters::style::{register_font, FontStyle};

use super::BenchReport;
use crate::error::{Error, Result};

static FONT: &[u8] = include_bytes!("../../assets/fonts/DejaVuSansMono.ttf");

fn font() -> Result<()> {
    static REGISTER: Once = Once::new();
    let mut failed = false;
    REGISTER.call_once(|| failed = register_font("sans-serif", FontStyle::Normal, FONT).is_err());
    if failed {
        return Err(Error::Usage("the bundled chart font does not load".into()));
    }
    Ok(())
}

/// Colour of a mode's points.
fn colour(mode: &str) -> RGBColor {
    match mode {
        "none" => RGBColor(150, 150, 150),
        "box" => RGBColor(31, 119, 180),
        "mesh" => RGBColor(255, 127, 14),
        "paper" => RGBColor(214, 39, 40),
        "adaptive" => RGBColor(44, 160, 44),
        _ => RGBColor(148, 103, 189),
    }
}

/// Draw the chart to `path` (PNG, 1000 x 640).
pub fn draw(report: &BenchReport, path: &Path) -> Result<()> {
    font()?;
    let fail = |e: &dyn std::fmt::Display| Error::file(path, std::io::Error::other(e.to_string()));
    let points: Vec<(&str, &str, f64, usize, usize)> = report
        .scenes
        .iter()
        .flat_map(|s| {
            s.modes.iter().map(move |r| {
                (
                    s.scene.as_str(),
                    r.mode,
                    r.cost_median_us.max(0.01),
                    r.missed,
                    r.false_collisions,
                )
            })
        })
        .collect();
    let x_max = points.iter().map(|p| p.2).fold(1.0, f64::max) * 3.0;
    let x_min = points
        .iter()
        .map(|p| p.2)
        .fold(f64::INFINITY, f64::min)
        .min(1.0)
        / 3.0;
    let y_max = points.iter().map(|p| p.3).max().unwrap_or(0) as f64 * 1.15 + 1.0;
    let root = BitMapBackend::new(path, (1000, 640)).into_drawing_area();
    root.fill(&WHITE).map_err(|e| fail(&e))?;
    let mut chart = ChartBuilder::on(&root)
        .caption(
            "savsim bench: per-tick cost against collisions missed (truth: oracle)",
            ("sans-serif", 20),
        )
        .margin(16)
        .x_label_area_size(44)
        .y_label_area_size(56)
        .build_cartesian_2d((x_min..x_max).log_scale(), -0.5..y_max)
        .map_err(|e| fail(&e))?;
    chart
        .configure_mesh()
        .x_desc("median per-tick cost, microseconds (log)")
        .y_desc("collisions missed")
        .label_style(("sans-serif", 14))
        .draw()
        .map_err(|e| fail(&e))?;
    for &(scene, mode, cost, missed, false_collisions) in &points {
        let c = colour(mode);
        let label = format!("{scene}/{mode} (+{false_collisions} false)");
        chart
            .draw_series(std::iter::once(
                EmptyElement::at((cost, missed as f64))
                    + Circle::new((0, 0), 6, c.filled())
                    + Text::new(label, (8, -14), ("sans-serif", 13).into_font().color(&c)),
            ))
            .map_err(|e| fail(&e))?;
    }
    root.present().map_err(|e| fail(&e))?;
    Ok(())
}
