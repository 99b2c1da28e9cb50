//! Output of the main job: CSV traces, SVG plots, the summary table.

use crate::bench::{Run, TraceRow};
use crate::rig::Sample;
use plotters::prelude::*;
use std::path::Path;

/// Error of a report write.
pub type ReportError = Box<dyn std::error::Error>;

/// Write a run's trace as CSV (one row per control period, decimated by `every`).
pub fn write_trace_csv(path: &Path, trace: &[TraceRow], every: usize) -> Result<(), ReportError> {
    let mut w = csv::Writer::from_path(path)?;
    for row in trace.iter().step_by(every.max(1)) {
        w.serialize(row)?;
    }
    w.flush()?;
    Ok(())
}

const BLUE: RGBColor = RGBColor(31, 119, 180);
const ORANGE: RGBColor = RGBColor(230, 110, 10);
const GREY: RGBColor = RGBColor(90, 90, 90);
const GREEN: RGBColor = RGBColor(44, 160, 44);

fn range(values: impl Iterator<Item = f64>, pad: f64) -> std::ops::Range<f64> {
    let (lo, hi) = values.fold((f64::MAX, f64::MIN), |(a, b), v| (a.min(v), b.max(v)));
    let span = (hi - lo).max(1e-9);
    (lo - pad * span)..(hi + pad * span)
}

/// Tracking, pressure and load over time for the feedforward and PI-only runs
/// of one scenario: three stacked panels.
pub fn plot_scenario(path: &Path, title: &str, ff: &Run, pi: &Run) -> Result<(), ReportError> {
    ensure_font();
    let root = SVGBackend::new(path, (1100, 900)).into_drawing_area();
    root.fill(&WHITE)?;
    let root = root.titled(title, ("sans-serif", 22))?;
    let panels = root.split_evenly((3, 1));
    let t_end = ff.trace.last().map(|r| r.t_s).unwrap_or(1.0);
    let step = (ff.trace.len() / 4000).max(1);

    // 1. Tracking.
    let yr = range(
        ff.trace
            .iter()
            .chain(pi.trace.iter())
            .flat_map(|r| [r.reference, r.contraction]),
        0.05,
    );
    let mut c = ChartBuilder::on(&panels[0])
        .margin(8)
        .x_label_area_size(30)
        .y_label_area_size(60)
        .build_cartesian_2d(0.0..t_end, yr)?;
    c.configure_mesh()
        .x_desc("time (s)")
        .y_desc("contraction")
        .draw()?;
    let line = |trace: &[TraceRow], f: fn(&TraceRow) -> f64| -> Vec<(f64, f64)> {
        trace.iter().step_by(step).map(|r| (r.t_s, f(r))).collect()
    };
    c.draw_series(LineSeries::new(
        line(&ff.trace, |r| r.reference),
        GREY.stroke_width(2),
    ))?
    .label("reference")
    .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], GREY));
    c.draw_series(LineSeries::new(line(&pi.trace, |r| r.contraction), ORANGE))?
        .label(format!("PI only (RMS {:.4})", pi.metrics.rms_error))
        .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], ORANGE));
    c.draw_series(LineSeries::new(line(&ff.trace, |r| r.contraction), BLUE))?
        .label(format!("model FF + PI (RMS {:.4})", ff.metrics.rms_error))
        .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], BLUE));
    c.configure_series_labels()
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .position(SeriesLabelPosition::UpperRight)
        .draw()?;

    // 2. Pressure.
    let yr = range(
        ff.trace
            .iter()
            .chain(pi.trace.iter())
            .flat_map(|r| [r.pressure_mpa, r.feedforward_mpa]),
        0.05,
    );
    let mut c = ChartBuilder::on(&panels[1])
        .margin(8)
        .x_label_area_size(30)
        .y_label_area_size(60)
        .build_cartesian_2d(0.0..t_end, yr)?;
    c.configure_mesh()
        .x_desc("time (s)")
        .y_desc("pressure (MPa)")
        .draw()?;
    c.draw_series(LineSeries::new(line(&pi.trace, |r| r.pressure_mpa), ORANGE))?
        .label("chamber, PI only")
        .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], ORANGE));
    c.draw_series(LineSeries::new(line(&ff.trace, |r| r.pressure_mpa), BLUE))?
        .label("chamber, FF + PI")
        .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], BLUE));
    c.draw_series(LineSeries::new(
        line(&ff.trace, |r| r.feedforward_mpa),
        GREEN,
    ))?
    .label("feedforward (model)")
    .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], GREEN));
    c.configure_series_labels()
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .position(SeriesLabelPosition::UpperRight)
        .draw()?;

    // 3. Load.
    let yr = range(
        ff.trace.iter().flat_map(|r| [r.load_n, r.model_load_n]),
        0.08,
    );
    let mut c = ChartBuilder::on(&panels[2])
        .margin(8)
        .x_label_area_size(30)
        .y_label_area_size(60)
        .build_cartesian_2d(0.0..t_end, yr)?;
    c.configure_mesh()
        .x_desc("time (s)")
        .y_desc("load (N)")
        .draw()?;
    c.draw_series(LineSeries::new(
        line(&ff.trace, |r| r.load_n),
        GREY.stroke_width(2),
    ))?
    .label("load on the rig")
    .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], GREY));
    c.draw_series(LineSeries::new(line(&ff.trace, |r| r.model_load_n), BLUE))?
        .label("controller's active model")
        .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], BLUE));
    c.configure_series_labels()
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .position(SeriesLabelPosition::UpperRight)
        .draw()?;
    root.present()?;
    Ok(())
}

/// Pressure–contraction loops of a closed-loop run (true chamber pressure
/// against true contraction after the warm-up), like the paper's Figs. 6–8.
pub fn plot_loops(path: &Path, title: &str, run: &Run, warmup_s: f64) -> Result<(), ReportError> {
    ensure_font();
    let root = SVGBackend::new(path, (800, 650)).into_drawing_area();
    root.fill(&WHITE)?;
    let pts: Vec<(f64, f64)> = run
        .trace
        .iter()
        .filter(|r| r.t_s >= warmup_s)
        .step_by(5)
        .map(|r| (r.contraction, r.pressure_mpa))
        .collect();
    let xr = range(pts.iter().map(|p| p.0), 0.05);
    let yr = range(pts.iter().map(|p| p.1), 0.05);
    let mut c = ChartBuilder::on(&root)
        .caption(title, ("sans-serif", 20))
        .margin(10)
        .x_label_area_size(40)
        .y_label_area_size(60)
        .build_cartesian_2d(xr, yr)?;
    c.configure_mesh()
        .x_desc("contraction")
        .y_desc("pressure (MPa)")
        .draw()?;
    // Colour by load so each load's loop can be told apart.
    let loads: Vec<f64> = run
        .trace
        .iter()
        .filter(|r| r.t_s >= warmup_s)
        .step_by(5)
        .map(|r| r.load_n)
        .collect();
    let (lmin, lmax) = loads
        .iter()
        .fold((f64::MAX, f64::MIN), |(a, b), &v| (a.min(v), b.max(v)));
    c.draw_series(pts.iter().zip(loads.iter()).map(|(&p, &l)| {
        let u = if lmax > lmin {
            (l - lmin) / (lmax - lmin)
        } else {
            0.0
        };
        let col = RGBColor((40.0 + 200.0 * u) as u8, 80, (220.0 - 180.0 * u) as u8);
        Circle::new(p, 1, col.filled())
    }))?;
    root.present()?;
    Ok(())
}

/// The characterisation run's loops, one colour per load (like the paper's
/// Fig. 1 and Fig. 5).
pub fn plot_characterisation(path: &Path, samples: &[Sample]) -> Result<(), ReportError> {
    ensure_font();
    let root = SVGBackend::new(path, (900, 700)).into_drawing_area();
    root.fill(&WHITE)?;
    let mut c = ChartBuilder::on(&root)
        .caption(
            "Characterisation run: isotonic loops of the simulated muscle, 100-600 N",
            ("sans-serif", 20),
        )
        .margin(10)
        .x_label_area_size(40)
        .y_label_area_size(60)
        .build_cartesian_2d(-0.01..0.27, -0.01..0.52)?;
    c.configure_mesh()
        .x_desc("measured contraction")
        .y_desc("measured pressure (MPa)")
        .draw()?;
    let colours = [
        BLUE,
        ORANGE,
        GREEN,
        RGBColor(214, 39, 40),
        RGBColor(148, 103, 189),
        GREY,
    ];
    for (i, load) in crate::characterisation::LOADS_N.iter().enumerate() {
        let col = colours[i % colours.len()];
        let pts: Vec<(f64, f64)> = samples
            .iter()
            .filter(|s| (s.load_n - load).abs() < 15.0)
            .map(|s| (s.contraction, s.pressure_mpa))
            .collect();
        c.draw_series(LineSeries::new(pts, col))?
            .label(format!("{load:.0} N"))
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], col));
    }
    c.configure_series_labels()
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .position(SeriesLabelPosition::UpperLeft)
        .draw()?;
    root.present()?;
    Ok(())
}

/// Register pam-lab's bundled DejaVu Sans (`pam-lab/assets/DejaVuSans.ttf`)
/// as plotters' `sans-serif`, once. With plotters' `ab_glyph` text backend
/// (which pam-lab enables too, so a workspace build unifies it) nothing is
/// drawn without a registered font: without this, `cargo build --release`
/// of the workspace followed by the main job failed with `FontUnavailable`.
fn ensure_font() {
    static ONCE: std::sync::Once = std::sync::Once::new();
    ONCE.call_once(|| {
        let bytes: &'static [u8] = include_bytes!("../../pam-lab/assets/DejaVuSans.ttf");
        // A fixed, valid file: registration cannot fail at run time (the
        // plots' test below would fail first).
        let _ =
            plotters::style::register_font("sans-serif", plotters::style::FontStyle::Normal, bytes);
    });
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn characterisation_plot_draws_with_text() {
        let samples: Vec<Sample> = (0..50)
            .map(|k| Sample {
                t_s: 0.02 * k as f64,
                load_n: 100.0,
                pressure_mpa: 0.01 * k as f64,
                contraction: 0.02 + 0.004 * k as f64,
            })
            .collect();
        let path = std::env::temp_dir().join(format!("host-sim-plot-{}.svg", std::process::id()));
        plot_characterisation(&path, &samples).unwrap();
        let svg = std::fs::read_to_string(&path).unwrap();
        let _ = std::fs::remove_file(&path);
        assert!(svg.contains("<text"), "no text drawn");
    }
}
