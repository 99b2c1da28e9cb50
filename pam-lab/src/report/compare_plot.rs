//! `pam-lab compare`'s picture: each model of the comparison as a point on
//! the accuracy × instructions plane, the one pam would flash marked.

use std::path::Path;

use anyhow::{anyhow, Result};
use plotters::prelude::*;

use super::plot::{ensure_font, tick_format};
use crate::evaluate::families::Comparison;

/// Draw `c` into `path` (PNG): instructions per sample (bench-m4's mean)
/// across, held-out RMS contraction error (% of rest length) up; a filled
/// point is a model pam can flash, a ring one it cannot yet, the chosen one
/// labelled so.
pub fn compare_plot(path: &Path, source: &str, c: &Comparison) -> Result<()> {
    ensure_font();
    if c.entries.is_empty() {
        return Err(anyhow!("plot: no model to draw"));
    }
    let x_max = c
        .entries
        .iter()
        .map(|e| e.instructions_mean)
        .fold(0.0, f64::max)
        * 2.0;
    let y_max = c
        .entries
        .iter()
        .map(|e| 100.0 * e.heldout_rms)
        .filter(|v| v.is_finite())
        .fold(0.0, f64::max)
        * 1.4;
    let (x_max, y_max) = (x_max.max(1.0), y_max.max(1e-3));
    let root = BitMapBackend::new(path, (900, 600)).into_drawing_area();
    root.fill(&WHITE)?;
    let mut chart = ChartBuilder::on(&root)
        .caption(
            format!("{source}: held-out error against cost on the chip"),
            ("sans-serif", 20),
        )
        .margin(15)
        .x_label_area_size(50)
        .y_label_area_size(70)
        .build_cartesian_2d(0.0..x_max, 0.0..y_max)?;
    chart
        .configure_mesh()
        .x_desc("instructions per sample on the Cortex-M4F (bench-m4, mean)")
        .y_desc("held-out RMS contraction error (% of rest length)")
        .x_label_formatter(&tick_format(0.0, x_max))
        .y_label_formatter(&tick_format(0.0, y_max))
        .draw()?;
    for (i, e) in c.entries.iter().enumerate() {
        let at = (e.instructions_mean, 100.0 * e.heldout_rms);
        if !at.1.is_finite() {
            continue;
        }
        let colour = if e.flashable { BLUE } else { RED };
        let style = if e.flashable {
            colour.filled()
        } else {
            colour.stroke_width(2)
        };
        chart.draw_series(std::iter::once(Circle::new(at, 8, style)))?;
        let status = if i == c.chosen {
            "pam flashes this"
        } else if e.flashable {
            "flashable"
        } else {
            "not flashable yet"
        };
        let font = ("sans-serif", 15).into_font().color(&colour);
        for (k, line) in [e.model.as_str(), status].into_iter().enumerate() {
            chart.draw_series(std::iter::once(Text::new(
                line.to_string(),
                (
                    at.0 + 0.02 * x_max,
                    at.1 + (0.03 - 0.035 * k as f64) * y_max,
                ),
                font.clone(),
            )))?;
        }
    }
    root.present()?;
    Ok(())
}
