//! Plots (PNG, via `plotters`), drawn to the path given (the commands give
//! a staging path of their [`crate::output::OutputSet`]).
//!
//! * [`fit_plot`]: pressure against contraction, data and model per load, as
//!   the paper's Fig. 5 (held-out samples dark, training samples light); for
//!   an isometric test pressure against force per held contraction, the
//!   test's own view. The model is drawn as the chip evaluates it, its
//!   static shape included.
//! * [`simulate_plot`]: measured and predicted contraction over time, and the
//!   error (model − measured).
//!
//! Every plot, here and in [`super::diagnose_plot`], follows the same rules:
//! pressure on the y axis of a loop (contraction, or an isometric test's
//! force, on x: the paper's Fig. 5, host-sim's characterisation plot and
//! `diagnose`'s `loops.png` alike), an error or residual is model −
//! measured and its axis says so, every axis names its quantity
//! with the unit in parentheses, and tick labels come from [`tick_format`]
//! (a zero prints as `0`, never `-0.000`).

use super::axes;
use std::collections::BTreeMap;
use std::path::Path;

use anyhow::{anyhow, Result};
use pam_core::effects::ConstraintShape;
use pam_core::{Branch, Coeffs};
use plotters::prelude::*;

use crate::evaluate::errors::ModelCache;
use crate::evaluate::simulate::SimSample;
use crate::identify::fit::TestKind;
use crate::record::split::Split;
use crate::record::Record;

const SIZE: (u32, u32) = (1400, 800);
/// Width of the legend column beside a chart, pixels: legends never cover data.
const LEGEND_W: u32 = 290;

type Area<'a> = DrawingArea<BitMapBackend<'a>, plotters::coord::Shift>;

/// A legend in its own area beside the chart.
fn legend(area: &Area, entries: &[(String, ShapeStyle)]) -> Result<()> {
    for (i, (label, style)) in entries.iter().enumerate() {
        let y = 40 + 24 * i as i32;
        area.draw(&PathElement::new(vec![(6, y), (34, y)], *style))
            .map_err(e)?;
        area.draw(&Text::new(label.clone(), (40, y - 8), ("sans-serif", 15)))
            .map_err(e)?;
    }
    Ok(())
}
/// Tick labels of an axis over `lo..hi`: each tick with the fewest decimals
/// that show it (to a millionth of the span), a zero (or the rounding noise
/// of one) as `0`, so no `-0.000` or `0.0`.
pub fn tick_format(lo: f64, hi: f64) -> impl Fn(&f64) -> String {
    let tol = ((hi - lo).abs() * 1e-6).max(f64::MIN_POSITIVE);
    move |v: &f64| {
        if v.abs() < tol {
            return "0".to_string();
        }
        (0..=9)
            .map(|d| format!("{v:.d$}"))
            .find(|s| s.parse::<f64>().is_ok_and(|r| (r - v).abs() < tol))
            .unwrap_or_else(|| format!("{v}"))
    }
}

/// Most points drawn per series (larger records are thinned evenly).
const MAX_POINTS: usize = 20_000;

fn e<E: std::fmt::Display>(err: E) -> anyhow::Error {
    anyhow!("plot: {err}")
}

fn color(k: usize) -> RGBColor {
    const C: [RGBColor; 8] = [
        RGBColor(31, 119, 180),
        RGBColor(214, 39, 40),
        RGBColor(44, 160, 44),
        RGBColor(148, 103, 189),
        RGBColor(255, 127, 14),
        RGBColor(140, 86, 75),
        RGBColor(227, 119, 194),
        RGBColor(23, 190, 207),
    ];
    C[k % C.len()]
}

/// What [`fit_plot`] draws: the record and how the fit labelled it, and the
/// model.
pub struct FitPlot<'a> {
    /// The record.
    pub record: &'a Record,
    /// Its branch split.
    pub split: &'a Split,
    /// Held-out samples.
    pub heldout: &'a [bool],
    /// Slack samples (an isometric test's force at the load cell's floor).
    pub slack: &'a [bool],
    /// The model and its static shape.
    pub coeffs: &'a Coeffs,
    /// The static shape, when fitted.
    pub shape: Option<&'a ConstraintShape>,
    /// The kind of test.
    pub test: TestKind,
    /// Load bins, N.
    pub load_bin_n: f64,
}

/// Data against model: per load bin (up to 8, spread over the range),
/// pressure against contraction; for an isometric test per held
/// contraction (up to 8), pressure against force.
pub fn fit_plot(path: &Path, plot: &FitPlot<'_>) -> Result<()> {
    if plot.test == TestKind::Isometric {
        return isometric_plot(path, plot);
    }
    let FitPlot {
        record,
        split,
        heldout,
        slack,
        coeffs,
        shape,
        load_bin_n,
        ..
    } = *plot;
    let mut model = ModelCache::new(coeffs, shape);
    let samples = &record.samples;
    // A slack muscle's samples (an isometric test's force at the load
    // cell's floor, `fit::slack_mask`) are no samples of the model: not drawn.
    let drawn = |i: usize| split.branch[i].is_some() && !slack.get(i).copied().unwrap_or(false);
    let mut counts: BTreeMap<i64, usize> = BTreeMap::new();
    for (i, s) in samples.iter().enumerate() {
        if drawn(i) {
            *counts
                .entry((s.load_n / load_bin_n).round() as i64)
                .or_default() += 1;
        }
    }
    // Only loads with data enough to see (a load step passes through bins
    // with a few samples each): at least 20 samples and 1 % of the record.
    let classified: usize = counts.values().sum();
    let min_count = (classified / 100).max(20);
    let mut bins: Vec<(i64, usize)> = counts.into_iter().filter(|b| b.1 >= min_count).collect();
    // At most 8, spread over the range (an isometric record's forces fill
    // many bins; the most sampled would all be at the low end).
    bins.sort();
    if bins.len() > 8 {
        let n = bins.len();
        bins = (0..8).map(|k| bins[k * (n - 1) / 7]).collect();
    }
    let keys: Vec<i64> = bins.iter().map(|b| b.0).collect();
    let thin = (samples.len() / MAX_POINTS).max(1);
    let pmax = f64::from(coeffs.params().points.max_pressure_mpa);
    let (xmin, xmax) = samples.iter().fold((f64::MAX, f64::MIN), |(a, b), s| {
        (a.min(s.contraction), b.max(s.contraction))
    });
    let title = format!("{}: data and fitted model per load", record.source);
    ensure_font();
    (|| -> Result<()> {
        let tmp = path;
        let root = BitMapBackend::new(tmp, SIZE).into_drawing_area();
        root.fill(&WHITE).map_err(e)?;
        let root = root.titled(&title, ("sans-serif", 18)).map_err(e)?;
        let (plot_area, legend_area) = root.split_horizontally(SIZE.0 - LEGEND_W);
        let mut entries: Vec<(String, ShapeStyle)> = Vec::new();
        let (xr, yr) = (
            (xmin - 0.005)..(xmax + 0.005),
            (-0.02 * pmax)..(1.05 * pmax),
        );
        let (xt, yt) = (tick_format(xr.start, xr.end), tick_format(yr.start, yr.end));
        let mut chart = ChartBuilder::on(&plot_area)
            .margin(15)
            .x_label_area_size(50)
            .y_label_area_size(70)
            .build_cartesian_2d(xr, yr)
            .map_err(e)?;
        chart
            .configure_mesh()
            .x_desc(axes::CONTRACTION)
            .y_desc(axes::PRESSURE_MPA)
            .x_label_formatter(&xt)
            .y_label_formatter(&yt)
            .draw()
            .map_err(e)?;
        for (k, key) in keys.iter().enumerate() {
            let col = color(k);
            let load = *key as f64 * load_bin_n;
            let pts = |held: bool| {
                samples
                    .iter()
                    .enumerate()
                    .step_by(thin)
                    .filter(move |(i, s)| {
                        drawn(*i)
                            && heldout[*i] == held
                            && (s.load_n / load_bin_n).round() as i64 == *key
                    })
                    .map(move |(_, s)| {
                        Circle::new(
                            (s.contraction, s.pressure_mpa),
                            1,
                            col.mix(if held { 0.8 } else { 0.15 }).filled(),
                        )
                    })
            };
            chart.draw_series(pts(false)).map_err(e)?;
            chart.draw_series(pts(true)).map_err(e)?;
            entries.push((
                format!("{load:.0} N ({} samples)", bins[k].1),
                col.stroke_width(3),
            ));
            let (m, inverse) = model.get(load as f32);
            for (br, width) in [(Branch::Contraction, 3), (Branch::Expansion, 1)] {
                let (r, rx) = (m.root_contraction(), m.max_contraction());
                // The model's stroke, each point moved by the shape to the
                // muscle's contraction.
                let curve = (0..=300).map(|j| {
                    let x = r + (rx - r) * j as f32 / 300.0;
                    let muscle = inverse.as_ref().map_or(x, |s| s.apply(m, x));
                    (f64::from(muscle), f64::from(m.pressure_mpa(x, br)))
                });
                chart
                    .draw_series(LineSeries::new(curve, col.stroke_width(width)))
                    .map_err(e)?;
            }
        }
        entries.push(("thick: contraction branch".into(), BLACK.stroke_width(3)));
        entries.push(("thin: expansion branch".into(), BLACK.stroke_width(1)));
        entries.push((
            "dots: data, dark held out".into(),
            BLACK.mix(0.5).stroke_width(1),
        ));
        legend(&legend_area, &entries)?;
        root.present().map_err(e)?;
        Ok(())
    })()
}

/// An isometric test: pressure against force at each held contraction (up
/// to 8, spread over the range), data and the model's two branches.
fn isometric_plot(path: &Path, plot: &FitPlot<'_>) -> Result<()> {
    let FitPlot {
        record,
        split,
        heldout,
        slack,
        coeffs,
        shape,
        ..
    } = *plot;
    let mut model = ModelCache::new(coeffs, shape);
    let samples = &record.samples;
    let drawn = |i: usize| split.branch[i].is_some() && !slack.get(i).copied().unwrap_or(false);
    // The held contractions: exact values with a share of the samples.
    let mut counts: BTreeMap<u64, usize> = BTreeMap::new();
    for (i, s) in samples.iter().enumerate() {
        if drawn(i) {
            *counts.entry(s.contraction.to_bits()).or_default() += 1;
        }
    }
    let classified: usize = counts.values().sum();
    let min_count = (classified / 100).max(20);
    let mut held: Vec<(f64, usize)> = counts
        .into_iter()
        .filter(|c| c.1 >= min_count)
        .map(|(bits, n)| (f64::from_bits(bits), n))
        .collect();
    held.sort_by(|a, b| a.0.total_cmp(&b.0));
    if held.len() > 8 {
        let n = held.len();
        held = (0..8).map(|k| held[k * (n - 1) / 7]).collect();
    }
    let thin = (samples.len() / MAX_POINTS).max(1);
    let pmax = f64::from(coeffs.params().points.max_pressure_mpa);
    let fmax = samples
        .iter()
        .enumerate()
        .filter(|(i, _)| drawn(*i))
        .fold(0.0f64, |a, (_, s)| a.max(s.load_n));
    let title = format!(
        "{}: data and fitted model per held contraction (isometric)",
        record.source
    );
    ensure_font();
    let root = BitMapBackend::new(path, SIZE).into_drawing_area();
    root.fill(&WHITE).map_err(e)?;
    let root = root.titled(&title, ("sans-serif", 18)).map_err(e)?;
    let (plot_area, legend_area) = root.split_horizontally(SIZE.0 - LEGEND_W);
    let mut entries: Vec<(String, ShapeStyle)> = Vec::new();
    let (xr, yr) = (0.0..(1.05 * fmax.max(1.0)), (-0.02 * pmax)..(1.05 * pmax));
    let (xt, yt) = (tick_format(xr.start, xr.end), tick_format(yr.start, yr.end));
    let mut chart = ChartBuilder::on(&plot_area)
        .margin(15)
        .x_label_area_size(50)
        .y_label_area_size(70)
        .build_cartesian_2d(xr, yr)
        .map_err(e)?;
    chart
        .configure_mesh()
        .x_desc(axes::FORCE_N)
        .y_desc(axes::PRESSURE_MPA)
        .x_label_formatter(&xt)
        .y_label_formatter(&yt)
        .draw()
        .map_err(e)?;
    for (k, &(x, n)) in held.iter().enumerate() {
        let col = color(k);
        let pts = |held_out: bool| {
            samples
                .iter()
                .enumerate()
                .step_by(thin)
                .filter(move |(i, s)| {
                    drawn(*i) && heldout[*i] == held_out && s.contraction.to_bits() == x.to_bits()
                })
                .map(move |(_, s)| {
                    Circle::new(
                        (s.load_n, s.pressure_mpa),
                        1,
                        col.mix(if held_out { 0.8 } else { 0.15 }).filled(),
                    )
                })
        };
        chart.draw_series(pts(false)).map_err(e)?;
        chart.draw_series(pts(true)).map_err(e)?;
        entries.push((format!("held at {x:.4} ({n} samples)"), col.stroke_width(3)));
        for (br, width) in [(Branch::Contraction, 3), (Branch::Expansion, 1)] {
            let curve: Vec<(f64, f64)> = (0..=200)
                .map(|j| {
                    let load = fmax * f64::from(j) / 200.0;
                    let p = model.pressure_mpa(x as f32, load as f32, br);
                    (load, f64::from(p))
                })
                .collect();
            chart
                .draw_series(LineSeries::new(curve, col.stroke_width(width)))
                .map_err(e)?;
        }
    }
    entries.push(("thick: contraction branch".into(), BLACK.stroke_width(3)));
    entries.push(("thin: expansion branch".into(), BLACK.stroke_width(1)));
    entries.push((
        "dots: data, dark held out".into(),
        BLACK.mix(0.5).stroke_width(1),
    ));
    legend(&legend_area, &entries)?;
    root.present().map_err(e)?;
    Ok(())
}

/// The time axis of [`simulate_plot`]: from the first sample drawn to the
/// last (`runs`, not empty), so that an isometric record's slack samples
/// before or after its holds, which are not drawn, do not stretch it.
fn drawn_time_range(sim: &[SimSample], runs: &[Vec<usize>]) -> (f64, f64) {
    let at = |i: Option<&usize>| i.and_then(|&i| sim.get(i)).map(|s| s.t_s);
    let t0 = at(runs.first().and_then(|r| r.first())).unwrap_or(0.0);
    let t1 = at(runs.last().and_then(|r| r.last())).unwrap_or(t0);
    (t0, t1.max(t0 + 1e-9))
}

/// `simulate`'s plot: measured and predicted over time, and the error
/// (model − measured) below. On an isotonic record the contraction the
/// model reaches from the measured pressure and load; on an isometric one
/// (`isometric_slack`: its slack samples, left out as fit leaves them out)
/// the pressure the model needs at the held contraction and the measured
/// force, the quantity an isometric test measures.
pub fn simulate_plot(
    path: &Path,
    source: &str,
    sim: &[SimSample],
    isometric_slack: Option<&[bool]>,
) -> Result<()> {
    if sim.is_empty() {
        return Err(anyhow!("plot: nothing to plot"));
    }
    type Pick = fn(&SimSample) -> f64;
    let (measured, predicted, error, value_axis, error_axis, what): (Pick, Pick, Pick, _, _, _) =
        match isometric_slack {
            None => (
                |s| s.measured_contraction,
                |s| s.predicted_contraction,
                |s| s.error(),
                axes::CONTRACTION,
                axes::CONTRACTION_ERROR,
                "the contraction from measured pressure and load",
            ),
            Some(_) => (
                |s| s.pressure_mpa,
                |s| s.predicted_pressure_mpa,
                |s| s.pressure_error_mpa(),
                axes::PRESSURE_MPA,
                axes::PRESSURE_ERROR_MPA,
                "the pressure at the held contraction and measured force (slack samples left out)",
            ),
        };
    let shown =
        |i: usize| isometric_slack.is_none_or(|slack| !slack.get(i).copied().unwrap_or(false));
    // Runs of consecutive shown samples, each drawn as its own line (no
    // line across the slack samples between them).
    let mut runs: Vec<Vec<usize>> = Vec::new();
    let thin = (sim.len() / MAX_POINTS).max(1);
    for i in (0..sim.len()).step_by(thin) {
        if shown(i) {
            match runs.last_mut() {
                Some(r) if r.last().is_some_and(|&j| j + thin == i) => r.push(i),
                _ => runs.push(vec![i]),
            }
        }
    }
    if runs.is_empty() {
        return Err(anyhow!("plot: no sample under load to plot"));
    }
    let (t0, t1) = drawn_time_range(sim, &runs);
    let finite = |v: f64| v.is_finite();
    let (ymin, ymax) = runs
        .iter()
        .flatten()
        .fold((f64::MAX, f64::MIN), |(a, b), &i| {
            let (m, p) = (measured(&sim[i]), predicted(&sim[i]));
            (
                [m, p].into_iter().filter(|v| finite(*v)).fold(a, f64::min),
                [m, p].into_iter().filter(|v| finite(*v)).fold(b, f64::max),
            )
        });
    let (ymin, ymax) = if ymin <= ymax {
        (ymin, ymax)
    } else {
        (0.0, 1.0)
    };
    let pad = 0.03 * (ymax - ymin).max(1e-6);
    let emax = runs
        .iter()
        .flatten()
        .map(|&i| error(&sim[i]).abs())
        .filter(|v| v.is_finite())
        .fold(1e-6, f64::max);
    ensure_font();
    (|| -> Result<()> {
        let root = BitMapBackend::new(path, SIZE).into_drawing_area();
        root.fill(&WHITE).map_err(e)?;
        let root = root
            .titled(&format!("{source}: simulated, {what}"), ("sans-serif", 22))
            .map_err(e)?;
        let (root, legend_area) = root.split_horizontally(SIZE.0 - LEGEND_W);
        legend(
            &legend_area,
            &[
                ("measured".into(), BLACK.mix(0.6).stroke_width(2)),
                ("model".into(), color(1).stroke_width(2)),
                ("model − measured (lower)".into(), color(0).stroke_width(2)),
            ],
        )?;
        let (top, bottom) = root.split_vertically(480);
        let tt = tick_format(t0, t1);
        let yr = (ymin - pad)..(ymax + pad);
        let yt = tick_format(yr.start, yr.end);
        let mut c1 = ChartBuilder::on(&top)
            .margin(15)
            .x_label_area_size(45)
            .y_label_area_size(70)
            .build_cartesian_2d(t0..t1, yr)
            .map_err(e)?;
        c1.configure_mesh()
            .x_desc(axes::TIME_S)
            .y_desc(value_axis)
            .x_label_formatter(&tt)
            .y_label_formatter(&yt)
            .draw()
            .map_err(e)?;
        let et = tick_format(-1.05 * emax, 1.05 * emax);
        let mut c2 = ChartBuilder::on(&bottom)
            .margin(15)
            .x_label_area_size(45)
            .y_label_area_size(70)
            .build_cartesian_2d(t0..t1, (-1.05 * emax)..(1.05 * emax))
            .map_err(e)?;
        c2.configure_mesh()
            .x_desc(axes::TIME_S)
            .y_desc(error_axis)
            .x_label_formatter(&tt)
            .y_label_formatter(&et)
            .draw()
            .map_err(e)?;
        for run in &runs {
            let line = |f: Pick| run.iter().map(move |&i| (sim[i].t_s, f(&sim[i])));
            c1.draw_series(LineSeries::new(line(measured), BLACK.mix(0.6)))
                .map_err(e)?;
            c1.draw_series(LineSeries::new(line(predicted), color(1)))
                .map_err(e)?;
            c2.draw_series(LineSeries::new(line(error), color(0)))
                .map_err(e)?;
        }
        root.present().map_err(e)?;
        Ok(())
    })()
}

/// Register the bundled DejaVu Sans (`assets/DejaVuSans.ttf`, licence beside
/// it) as plotters' `sans-serif`, once. Bundling the font keeps the plots free
/// of system font libraries (fontconfig, freetype), so a fresh machine builds
/// and draws them with nothing installed.
pub fn ensure_font() {
    static ONCE: std::sync::Once = std::sync::Once::new();
    ONCE.call_once(|| {
        let bytes: &'static [u8] = include_bytes!("../../assets/DejaVuSans.ttf");
        // The font is a fixed, valid file: registration cannot fail at run time
        // (checked by the test below).
        let _ =
            plotters::style::register_font("sans-serif", plotters::style::FontStyle::Normal, bytes);
    });
}

#[cfg(test)]
mod font_tests {
    #[test]
    fn bundled_font_registers() {
        let bytes: &'static [u8] = include_bytes!("../../assets/DejaVuSans.ttf");
        assert!(plotters::style::register_font(
            "sans-serif",
            plotters::style::FontStyle::Normal,
            bytes
        )
        .is_ok());
    }
}

#[cfg(test)]
mod tick_tests {
    use super::tick_format;

    #[test]
    fn a_zero_tick_prints_as_0_and_others_with_the_decimals_they_need() {
        let t = tick_format(-0.04, 0.04);
        // The rounding noise of a zero tick, either sign.
        assert_eq!(t(&-1.3e-17), "0");
        assert_eq!(t(&0.0), "0");
        assert_eq!(t(&-0.01), "-0.01");
        assert_eq!(t(&0.015), "0.015");
        assert_eq!(t(&(0.1 + 0.2 - 0.3 + 0.02)), "0.02");
        let t = tick_format(0.0, 900.0);
        assert_eq!(t(&300.0), "300");
        assert_eq!(t(&0.0), "0");
    }
}

#[cfg(test)]
mod time_axis_tests {
    use super::drawn_time_range;
    use crate::evaluate::simulate::SimSample;
    use pam_core::Branch;

    #[test]
    fn the_time_axis_spans_the_samples_drawn_not_the_slack_ones_around_them() {
        let sim: Vec<SimSample> = (0..10)
            .map(|i| SimSample {
                t_s: f64::from(i),
                load_n: 0.0,
                pressure_mpa: 0.0,
                measured_contraction: 0.0,
                predicted_contraction: 0.0,
                predicted_pressure_mpa: 0.0,
                branch: Branch::Contraction,
                active_load_n: 0.0,
            })
            .collect();
        // Samples 0–1 and 8–9 slack (not drawn), two holds between.
        assert_eq!(
            drawn_time_range(&sim, &[vec![2, 3, 4], vec![6, 7]]),
            (2.0, 7.0)
        );
        // One sample drawn: a range of its own, not empty.
        let (t0, t1) = drawn_time_range(&sim, &[vec![5]]);
        assert!(t0 == 5.0 && t1 > t0, "{t0} {t1}");
    }
}
