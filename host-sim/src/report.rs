//! Output of the main job: CSV traces, SVG plots, the summary table.

use crate::bench::{Run, TraceRow};
use crate::rig::Sample;
use pam_lab::report::axes;
use pam_lab::report::plot::tick_format;
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

/// Axis range of `values` with `pad` (a fraction of the span) either side.
/// A constant (or nearly constant) signal gets a span of 10 % of its
/// magnitude, so its ticks read different values (a constant 200 N load
/// spans 190–210 N, not nine ticks reading 200.0).
fn range(values: impl Iterator<Item = f64>, pad: f64) -> std::ops::Range<f64> {
    let (lo, hi) = values
        .filter(|v| v.is_finite())
        .fold((f64::MAX, f64::MIN), |(a, b), v| (a.min(v), b.max(v)));
    if lo > hi {
        return 0.0..1.0;
    }
    let mid = 0.5 * (lo + hi);
    let min_span = (0.1 * mid.abs()).max(1e-6);
    if hi - lo < min_span {
        return (mid - 0.5 * min_span)..(mid + 0.5 * min_span);
    }
    let span = hi - lo;
    (lo - pad * span)..(hi + pad * span)
}

type Area<'a> = DrawingArea<SVGBackend<'a>, plotters::coord::Shift>;

/// A legend in its own area beside the chart, so it never covers data.
fn legend(area: &Area, entries: &[(String, ShapeStyle)]) -> Result<(), ReportError> {
    for (i, (label, style)) in entries.iter().enumerate() {
        let y = 30 + 22 * i as i32;
        area.draw(&PathElement::new(vec![(6, y), (34, y)], *style))?;
        area.draw(&Text::new(label.clone(), (40, y - 8), ("sans-serif", 14)))?;
    }
    Ok(())
}

/// One closed-loop run as plotted: its label and colour.
pub struct Series<'a> {
    /// Legend text (the RMS is added).
    pub label: &'a str,
    /// The run.
    pub run: &'a Run,
    /// Line colour.
    pub colour: RGBColor,
}

/// The colours of the three controllers, as in the summary table's order.
pub const RUN_COLOURS: [RGBColor; 3] = [ORANGE, BLUE, GREEN];

/// Tracking, tracking error, pressure and load over time for every run of
/// one scenario: four stacked panels, the legends in a column to the
/// right. The tracking error has its own panel (on the tracking panel's
/// 0–0.16 axis an error of 0.005 is invisible); the warm-up, not counted in
/// the RMS, is shaded.
pub fn plot_scenario(
    path: &Path,
    title: &str,
    runs: &[Series],
    warmup_s: f64,
) -> Result<(), ReportError> {
    ensure_font();
    let Some(first) = runs.first() else {
        return Err("no run to plot".into());
    };
    let root = SVGBackend::new(path, (1300, 1250)).into_drawing_area();
    root.fill(&WHITE)?;
    let root = root.titled(title, ("sans-serif", 22))?;
    let rows = root.split_evenly((4, 1));
    let t_end = first
        .run
        .trace
        .last()
        .map(|r| r.t_s)
        .unwrap_or(1.0)
        .max(1e-3);
    let step = (first.run.trace.len() / 4000).max(1);
    let line = |trace: &[TraceRow], f: &dyn Fn(&TraceRow) -> f64| -> Vec<(f64, f64)> {
        trace.iter().step_by(step).map(|r| (r.t_s, f(r))).collect()
    };
    let all = || runs.iter().flat_map(|s| s.run.trace.iter());
    let warm = GREY.mix(0.12);

    // 1. Tracking.
    let (chart_area, legend_area) = rows[0].split_horizontally(1000);
    let yr = range(all().flat_map(|r| [r.reference, r.contraction]), 0.05);
    let mut c = ChartBuilder::on(&chart_area)
        .margin(8)
        .x_label_area_size(30)
        .y_label_area_size(70)
        .build_cartesian_2d(0.0..t_end, yr.clone())?;
    c.configure_mesh()
        .x_desc(axes::TIME_S)
        .y_desc(axes::CONTRACTION)
        .draw()?;
    c.draw_series(std::iter::once(Rectangle::new(
        [(0.0, yr.start), (warmup_s.min(t_end), yr.end)],
        warm.filled(),
    )))?;
    c.draw_series(LineSeries::new(
        line(&first.run.trace, &|r| r.reference),
        GREY.stroke_width(3),
    ))?;
    let mut entries = vec![("reference".to_string(), GREY.stroke_width(3))];
    for s in runs {
        c.draw_series(LineSeries::new(
            line(&s.run.trace, &|r| r.contraction),
            s.colour,
        ))?;
        entries.push((s.label.to_string(), s.colour.stroke_width(2)));
    }
    entries.push((
        format!("warm-up ({warmup_s:.0} s, shaded)"),
        warm.filled().stroke_width(10),
    ));
    legend(&legend_area, &entries)?;

    // 2. Tracking error, on its own scale (after the warm-up).
    let (chart_area, legend_area) = rows[1].split_horizontally(1000);
    let emax = all()
        .filter(|r| r.t_s >= warmup_s)
        .map(|r| (r.contraction - r.reference).abs())
        .fold(1e-4, f64::max)
        * 1.1;
    let mut c = ChartBuilder::on(&chart_area)
        .margin(8)
        .x_label_area_size(30)
        .y_label_area_size(70)
        .build_cartesian_2d(0.0..t_end, -emax..emax)?;
    c.configure_mesh()
        .x_desc(axes::TIME_S)
        .y_desc("tracking error (fraction of rest length)")
        .y_label_formatter(&tick_format(-emax, emax))
        .draw()?;
    c.draw_series(std::iter::once(Rectangle::new(
        [(0.0, -emax), (warmup_s.min(t_end), emax)],
        warm.filled(),
    )))?;
    let mut entries = Vec::new();
    for s in runs {
        let pts: Vec<(f64, f64)> = line(&s.run.trace, &|r| {
            (r.contraction - r.reference).clamp(-emax, emax)
        });
        c.draw_series(LineSeries::new(pts, s.colour))?;
        entries.push((
            format!("{}: RMS {:.4}", s.label, s.run.metrics.rms_error),
            s.colour.stroke_width(2),
        ));
    }
    entries.push(("contraction − reference".to_string(), WHITE.stroke_width(0)));
    legend(&legend_area, &entries)?;

    // 3. Pressure.
    let (chart_area, legend_area) = rows[2].split_horizontally(1000);
    let yr = range(
        all().flat_map(|r| [r.pressure_mpa, r.feedforward_mpa]),
        0.05,
    );
    let mut c = ChartBuilder::on(&chart_area)
        .margin(8)
        .x_label_area_size(30)
        .y_label_area_size(70)
        .build_cartesian_2d(0.0..t_end, yr)?;
    c.configure_mesh()
        .x_desc(axes::TIME_S)
        .y_desc(axes::PRESSURE_MPA)
        .draw()?;
    let mut entries = Vec::new();
    for s in runs {
        c.draw_series(LineSeries::new(
            line(&s.run.trace, &|r| r.pressure_mpa),
            s.colour,
        ))?;
        entries.push((format!("chamber, {}", s.label), s.colour.stroke_width(2)));
    }
    for s in runs
        .iter()
        .filter(|s| s.run.trace.iter().any(|r| r.feedforward_mpa != 0.0))
    {
        let dashed = s.colour.mix(0.5);
        c.draw_series(LineSeries::new(
            line(&s.run.trace, &|r| r.feedforward_mpa),
            dashed.stroke_width(1),
        ))?;
        entries.push((format!("feedforward, {}", s.label), dashed.stroke_width(1)));
    }
    legend(&legend_area, &entries)?;

    // 4. Load.
    let (chart_area, legend_area) = rows[3].split_horizontally(1000);
    let yr = range(all().flat_map(|r| [r.load_n, r.model_load_n]), 0.08);
    let mut c = ChartBuilder::on(&chart_area)
        .margin(8)
        .x_label_area_size(30)
        .y_label_area_size(70)
        .build_cartesian_2d(0.0..t_end, yr)?;
    c.configure_mesh()
        .x_desc(axes::TIME_S)
        .y_desc("load (N)")
        .draw()?;
    c.draw_series(LineSeries::new(
        line(&first.run.trace, &|r| r.load_n),
        GREY.stroke_width(3),
    ))?;
    let mut entries = vec![("load on the rig".to_string(), GREY.stroke_width(3))];
    for s in runs
        .iter()
        .filter(|s| s.run.trace.iter().any(|r| r.feedforward_mpa != 0.0))
    {
        c.draw_series(LineSeries::new(
            line(&s.run.trace, &|r| r.model_load_n),
            s.colour,
        ))?;
        entries.push((
            format!("active model, {}", s.label),
            s.colour.stroke_width(2),
        ));
    }
    legend(&legend_area, &entries)?;
    root.present()?;
    Ok(())
}

/// Colour of a load on the loops plot's scale.
fn load_colour(u: f64) -> RGBColor {
    let u = u.clamp(0.0, 1.0);
    RGBColor((40.0 + 200.0 * u) as u8, 80, (220.0 - 180.0 * u) as u8)
}

/// Pressure–contraction loops of a closed-loop run (true chamber pressure
/// against true contraction after the warm-up), like the paper's Figs. 6–8,
/// coloured by load with a colour bar beside the chart.
pub fn plot_loops(path: &Path, title: &str, run: &Run, warmup_s: f64) -> Result<(), ReportError> {
    ensure_font();
    let root = SVGBackend::new(path, (900, 650)).into_drawing_area();
    root.fill(&WHITE)?;
    let root = root.titled(title, ("sans-serif", 20))?;
    let (chart_area, bar_area) = root.split_horizontally(770);
    let kept: Vec<&TraceRow> = run
        .trace
        .iter()
        .filter(|r| r.t_s >= warmup_s)
        .step_by(5)
        .collect();
    let xr = range(kept.iter().map(|r| r.contraction), 0.05);
    let yr = range(kept.iter().map(|r| r.pressure_mpa), 0.05);
    let mut c = ChartBuilder::on(&chart_area)
        .margin(10)
        .x_label_area_size(40)
        .y_label_area_size(60)
        .build_cartesian_2d(xr, yr)?;
    c.configure_mesh()
        .x_desc(axes::CONTRACTION)
        .y_desc(axes::PRESSURE_MPA)
        .draw()?;
    let (lmin, lmax) = kept.iter().fold((f64::MAX, f64::MIN), |(a, b), r| {
        (a.min(r.load_n), b.max(r.load_n))
    });
    let u = |l: f64| {
        if lmax > lmin {
            (l - lmin) / (lmax - lmin)
        } else {
            0.5
        }
    };
    c.draw_series(kept.iter().map(|r| {
        Circle::new(
            (r.contraction, r.pressure_mpa),
            1,
            load_colour(u(r.load_n)).filled(),
        )
    }))?;
    // Colour bar: the load scale.
    bar_area.draw(&Text::new("load (N)", (10, 20), ("sans-serif", 15)))?;
    let (top, bottom) = (50, 560);
    if lmax > lmin {
        let steps = 100;
        for k in 0..steps {
            let y0 = bottom - (bottom - top) * (k + 1) / steps;
            let y1 = bottom - (bottom - top) * k / steps;
            let col = load_colour(k as f64 / (steps - 1) as f64);
            bar_area.draw(&Rectangle::new([(14, y0), (40, y1)], col.filled()))?;
        }
        bar_area.draw(&Rectangle::new(
            [(14, top), (40, bottom)],
            BLACK.stroke_width(1),
        ))?;
        for k in 0..=4 {
            let v = lmin + (lmax - lmin) * k as f64 / 4.0;
            let y = bottom - (bottom - top) * k / 4;
            bar_area.draw(&PathElement::new(vec![(40, y), (46, y)], BLACK))?;
            bar_area.draw(&Text::new(
                format!("{v:.0}"),
                (50, y - 7),
                ("sans-serif", 14),
            ))?;
        }
    } else if lmax >= lmin {
        // One load: one colour, no scale to read.
        bar_area.draw(&Rectangle::new(
            [(14, top), (40, top + 26)],
            load_colour(0.5).filled(),
        ))?;
        bar_area.draw(&Text::new(
            format!("{lmin:.0} N"),
            (46, top + 5),
            ("sans-serif", 14),
        ))?;
        bar_area.draw(&Text::new("(constant)", (14, top + 36), ("sans-serif", 14)))?;
    }
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
        .x_desc("measured contraction (fraction of rest length)")
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

/// The end-to-end run as bars: one panel per scenario, one group per rig,
/// the RMS tracking error of PI alone, the paper's model and the diagnosed
/// model as feedforward. A run without a bar is named in its place: the
/// firmware refused the blob, or the controller went to its safe state
/// (then its RMS, in the table, is not a tracking error).
pub fn plot_end_to_end(
    path: &Path,
    outcomes: &[crate::end_to_end::RigOutcome],
) -> Result<(), ReportError> {
    ensure_font();
    let scenarios: Vec<&str> = outcomes
        .iter()
        .flat_map(|o| o.runs.iter().map(|r| r.scenario))
        .fold(Vec::new(), |mut v, s| {
            if !v.contains(&s) {
                v.push(s);
            }
            v
        });
    if scenarios.is_empty() {
        return Err("no end-to-end run to plot".into());
    }
    let root = SVGBackend::new(path, (1300, 330 * scenarios.len() as u32 + 60)).into_drawing_area();
    root.fill(&WHITE)?;
    let root = root.titled(
        "End to end: RMS tracking error per rig (characterise -> fit / diagnose -> blob -> firmware)",
        ("sans-serif", 22),
    )?;
    let rows = root.split_evenly((scenarios.len(), 1));
    let labels = ["PI only", "paper FF + PI", "diagnosed FF + PI"];
    for (row, scenario) in rows.iter().zip(&scenarios) {
        let (chart_area, legend_area) = row.split_horizontally(1000);
        // A run that ended in a safe state is not tracking: no bar, a note.
        let tracked = |r: &Run| r.first_fault.is_none().then_some(r.metrics.rms_error);
        let bars: Vec<(usize, [Result<f64, &str>; 3])> = outcomes
            .iter()
            .enumerate()
            .filter_map(|(i, o)| {
                let r = o.runs.iter().find(|r| r.scenario == *scenario)?;
                Some((
                    i,
                    [
                        tracked(&r.pi).ok_or("tripped"),
                        tracked(&r.paper).ok_or("tripped"),
                        match &r.diagnosed {
                            Ok(d) => tracked(d).ok_or("tripped"),
                            Err(_) => Err("refused"),
                        },
                    ],
                ))
            })
            .collect();
        let ymax = bars
            .iter()
            .flat_map(|(_, b)| b.iter().filter_map(|v| v.ok()))
            .fold(0.0f64, f64::max)
            * 1.15;
        let names: Vec<String> = outcomes
            .iter()
            .map(|o| format!("{} ({})", o.rig.name, o.rig.effect))
            .collect();
        let mut c = ChartBuilder::on(&chart_area)
            .margin(8)
            .caption(*scenario, ("sans-serif", 18))
            .x_label_area_size(30)
            .y_label_area_size(70)
            .build_cartesian_2d(0.0..outcomes.len() as f64, 0.0..ymax.max(1e-4))?;
        c.configure_mesh()
            .disable_x_mesh()
            .x_labels(outcomes.len() * 2 + 1)
            .x_label_formatter(&|x| {
                let k = x - x.floor();
                if (k - 0.5).abs() < 1e-6 {
                    names.get(x.floor() as usize).cloned().unwrap_or_default()
                } else {
                    String::new()
                }
            })
            .y_desc("RMS error (fraction of rest length)")
            .draw()?;
        for (i, b) in &bars {
            for (j, v) in b.iter().enumerate() {
                let x0 = *i as f64 + 0.12 + 0.25 * j as f64;
                match v {
                    Ok(v) => {
                        c.draw_series(std::iter::once(Rectangle::new(
                            [(x0, 0.0), (x0 + 0.24, *v)],
                            RUN_COLOURS[j].filled(),
                        )))?;
                    }
                    Err(why) => {
                        c.draw_series(std::iter::once(Text::new(
                            *why,
                            (x0, 0.05 * ymax),
                            ("sans-serif", 13).into_font().color(&RUN_COLOURS[j]),
                        )))?;
                    }
                }
            }
        }
        let entries: Vec<(String, ShapeStyle)> = labels
            .iter()
            .zip(RUN_COLOURS)
            .map(|(l, c)| (l.to_string(), c.filled().stroke_width(10)))
            .collect();
        legend(&legend_area, &entries)?;
    }
    root.present()?;
    Ok(())
}

/// The worn muscle over the hour: per repetition of the scenarios, the
/// tracking error of the flashed model and of the adapted one (a
/// repetition in which the flashed model went to its safe state is drawn
/// at the panel's top, clipped), the fresh identification's as a dashed
/// level; below, the adapted stroke scale. One line per seed.
pub fn plot_worn(
    path: &Path,
    comparisons: &[crate::wear::WornComparison],
) -> Result<(), ReportError> {
    ensure_font();
    let root = SVGBackend::new(path, (1000, 760)).into_drawing_area();
    root.fill(&WHITE)?;
    let (chart_area, legend_area) = root.split_horizontally(760);
    let panels = chart_area.split_evenly((2, 1));
    let t_max = comparisons
        .iter()
        .flat_map(|c| c.adapted.repetitions.iter().map(|r| r.t_s))
        .fold(1.0f64, f64::max);
    // The tracking errors while controlling; a safe-state repetition is
    // far above and would flatten the rest.
    let healthy = comparisons
        .iter()
        .flat_map(|c| {
            c.flashed
                .repetitions
                .iter()
                .chain(&c.adapted.repetitions)
                .map(|r| r.rms_error)
                .chain([c.fresh_rms])
        })
        .filter(|v| *v < 0.02);
    let e = range(healthy, 0.1);
    let mut top = ChartBuilder::on(&panels[0])
        .caption(
            "The worn muscle: stroke -15 %, friction +30 %, stiffness -10 % over an hour",
            ("sans-serif", 18),
        )
        .margin(10)
        .x_label_area_size(35)
        .y_label_area_size(70)
        .build_cartesian_2d(0.0..t_max, e.clone())?;
    top.configure_mesh()
        .x_desc("start of the repetition (s)")
        .x_label_formatter(&|v| format!("{v:.0}"))
        .y_desc("RMS tracking error (contraction)")
        .y_label_formatter(&tick_format(e.start, e.end))
        .draw()?;
    let mut entries = Vec::new();
    for (i, c) in comparisons.iter().enumerate() {
        let alpha = 1.0 - 0.25 * i as f64;
        let flashed = ORANGE.mix(alpha).stroke_width(2);
        let adapted = BLUE.mix(alpha).stroke_width(2);
        let fresh = GREEN.mix(alpha).stroke_width(1);
        let clip = |v: f64| v.min(e.end);
        top.draw_series(LineSeries::new(
            c.flashed
                .repetitions
                .iter()
                .map(|r| (r.t_s, clip(r.rms_error))),
            flashed,
        ))?;
        // Repetitions whose error is off the panel (the safe state).
        top.draw_series(
            c.flashed
                .repetitions
                .iter()
                .filter(|r| r.rms_error > e.end)
                .map(|r| TriangleMarker::new((r.t_s, e.end), 7, ORANGE.filled())),
        )?;
        top.draw_series(LineSeries::new(
            c.adapted
                .repetitions
                .iter()
                .map(|r| (r.t_s, clip(r.rms_error))),
            adapted,
        ))?;
        let last = c.adapted.repetitions.last().map_or(t_max, |r| r.t_s);
        top.draw_series(DashedLineSeries::new(
            [(last - 600.0, c.fresh_rms), (last, c.fresh_rms)],
            6,
            4,
            fresh,
        ))?;
        entries.push((format!("flashed, seed {}", c.seed), flashed));
        entries.push((format!("adapted, seed {}", c.seed), adapted));
        entries.push((format!("fresh fit (worn), seed {}", c.seed), fresh));
    }
    let s = range(
        comparisons
            .iter()
            .flat_map(|c| {
                c.adapted
                    .repetitions
                    .iter()
                    .map(|r| f64::from(r.stroke_scale))
            })
            .chain([1.0]),
        0.1,
    );
    let mut bottom = ChartBuilder::on(&panels[1])
        .margin(10)
        .x_label_area_size(35)
        .y_label_area_size(70)
        .build_cartesian_2d(0.0..t_max, s.clone())?;
    bottom
        .configure_mesh()
        .x_desc("time (s)")
        .x_label_formatter(&|v| format!("{v:.0}"))
        .y_desc("adapted stroke scale")
        .y_label_formatter(&tick_format(s.start, s.end))
        .draw()?;
    for (i, c) in comparisons.iter().enumerate() {
        let adapted = BLUE.mix(1.0 - 0.25 * i as f64).stroke_width(2);
        bottom.draw_series(LineSeries::new(
            c.adapted
                .repetitions
                .iter()
                .map(|r| (r.t_s, f64::from(r.stroke_scale))),
            adapted,
        ))?;
    }
    entries.push((
        "▲ flashed: off the panel (safe state)".to_string(),
        WHITE.stroke_width(0),
    ));
    legend(&legend_area, &entries)?;
    root.present()?;
    Ok(())
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
