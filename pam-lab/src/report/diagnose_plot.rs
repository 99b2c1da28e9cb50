//! Plots of `pam-lab diagnose`: the residual against time with the regimes
//! marked, and the loops before and after the added effects.

use super::axes;
use std::path::Path;

use plotters::prelude::*;

use crate::identify::diagnose::DiagnoseReport;
use crate::record::Record;
use crate::report::plot::tick_format;

const BASE: RGBColor = RGBColor(200, 40, 40);
const AFTER: RGBColor = RGBColor(30, 80, 200);

/// Runs of `true` in `mask` as `(first, last)` index pairs.
fn runs(mask: &[bool]) -> Vec<(usize, usize)> {
    let mut out = Vec::new();
    let mut start = None;
    for (i, &m) in mask.iter().enumerate() {
        match (m, start) {
            (true, None) => start = Some(i),
            (false, Some(s)) => {
                out.push((s, i - 1));
                start = None;
            }
            _ => {}
        }
    }
    if let Some(s) = start {
        out.push((s, mask.len() - 1));
    }
    out
}

/// The measured value of what the diagnosis predicts: the contraction, or
/// on an isometric record the pressure; and its axis label.
fn measured(r: &DiagnoseReport, s: &crate::record::Sample) -> f64 {
    measured_in(isometric(r), s)
}

/// The quantity a diagnosis predicts: pressure on an isometric record (its
/// answer to the held length), contraction otherwise.
fn measured_in(isometric: bool, s: &crate::record::Sample) -> f64 {
    if isometric {
        s.pressure_mpa
    } else {
        s.contraction
    }
}

/// The residual every plot and table shows: model − measured, sample by
/// sample.
fn model_minus_measured(
    isometric: bool,
    predicted: &[f64],
    samples: &[crate::record::Sample],
) -> Vec<f64> {
    samples
        .iter()
        .zip(predicted)
        .map(|(s, x)| x - measured_in(isometric, s))
        .collect()
}

fn isometric(r: &DiagnoseReport) -> bool {
    r.test_kind == crate::identify::fit::TestKind::Isometric
}

/// Residual (model − measured contraction, the sign of `simulate`'s error
/// and of the error tables; on an isometric record model − measured
/// pressure) against time, base and final model; held-out blocks shaded;
/// regime bands along the bottom.
pub fn residual_plot(r: &DiagnoseReport, record: &Record, path: &Path) -> anyhow::Result<()> {
    let s = &record.samples;
    let res_b = model_minus_measured(isometric(r), &r.predicted_base, s);
    let res_a = model_minus_measured(isometric(r), &r.predicted_after, s);
    let lim = res_b
        .iter()
        .chain(&res_a)
        .filter(|v| v.is_finite())
        .fold(0.0f64, |m, v| m.max(v.abs()))
        .max(1e-3)
        * 1.1;
    let t0 = s.first().map_or(0.0, |x| x.t_s);
    let t1 = s.last().map_or(1.0, |x| x.t_s).max(t0 + 1e-3);
    crate::report::plot::ensure_font();
    let root = BitMapBackend::new(path, (1600, 700)).into_drawing_area();
    root.fill(&WHITE)?;
    let title = format!(
        "{}: residual, held-out RMS {:.5} (paper) -> {:.5} (+ {})",
        r.source,
        r.rms_before,
        r.rms_after,
        if r.effects_added.is_empty() {
            "nothing".to_string()
        } else {
            r.effects_added.join(" + ")
        }
    );
    let mut chart = ChartBuilder::on(&root)
        .caption(title, ("sans-serif", 22))
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(70)
        // Below the data: one strip per regime; above it: room for the legend.
        .build_cartesian_2d(t0..t1, (-1.32 * lim)..(1.6 * lim))?;
    let (tt, rt) = (tick_format(t0, t1), tick_format(-lim, lim));
    chart
        .configure_mesh()
        .x_desc(axes::TIME_S)
        .y_desc(if isometric(r) {
            axes::PRESSURE_ERROR_MPA
        } else {
            axes::CONTRACTION_ERROR
        })
        .light_line_style(WHITE)
        .x_label_formatter(&tt)
        // Ticks only where the residual is drawn, not on the strips or legend room.
        .y_label_formatter(&|v| {
            if v.abs() <= lim * 1.001 {
                rt(v)
            } else {
                String::new()
            }
        })
        .draw()?;
    let t = |i: usize| s[i].t_s;
    // Held-out blocks, labelled on the plot and in the legend.
    let grey = RGBColor(228, 228, 228);
    chart
        .draw_series(runs(&r.heldout).into_iter().map(|(a, b)| {
            Rectangle::new([(t(a), -1.32 * lim), (t(b), 1.02 * lim)], grey.filled())
        }))?
        .label("held-out block (grey band)")
        .legend(move |(x, y)| Rectangle::new([(x, y - 5), (x + 15, y + 5)], grey.filled()));
    // The words on each band only where they fit (wide blocks); the legend
    // names the grey band either way.
    chart.draw_series(
        runs(&r.heldout)
            .into_iter()
            .filter(|&(a, b)| t(b) - t(a) > 0.06 * (t1 - t0))
            .map(|(a, _)| {
                Text::new(
                    "held out",
                    (t(a), 1.0 * lim),
                    ("sans-serif", 14).into_font().color(&RGBColor(90, 90, 90)),
                )
            }),
    )?;
    chart.draw_series(std::iter::once(PathElement::new(
        vec![(t0, -1.02 * lim), (t1, -1.02 * lim)],
        BLACK.mix(0.4),
    )))?;
    // Regime bands, each on its own strip at the bottom.
    let bands: [(&str, &Vec<bool>, RGBColor); 4] = [
        (
            "after inner reversal",
            &r.regimes.after_inner_reversal,
            RGBColor(255, 150, 0),
        ),
        ("fast ramp", &r.regimes.fast_ramp, RGBColor(220, 0, 160)),
        ("slow ramp", &r.regimes.slow_ramp, RGBColor(0, 170, 170)),
        (
            "hold after step",
            &r.regimes.hold_after_step,
            RGBColor(60, 170, 60),
        ),
    ];
    for (k, (name, mask, color)) in bands.iter().enumerate() {
        let y1 = -1.04 * lim - lim * 0.07 * k as f64;
        let y0 = y1 - lim * 0.05;
        let color = *color;
        chart
            .draw_series(
                runs(mask)
                    .into_iter()
                    .map(move |(a, b)| Rectangle::new([(t(a), y0), (t(b), y1)], color.filled())),
            )?
            .label(format!("strip {}: {name}", k + 1))
            .legend(move |(x, y)| Rectangle::new([(x, y - 5), (x + 15, y + 5)], color.filled()));
    }
    // Broken where the residual is not defined (an isometric test's slack
    // samples, judged on nothing).
    let pieces = |res: &[f64]| -> Vec<Vec<(f64, f64)>> {
        let mut out: Vec<Vec<(f64, f64)>> = vec![Vec::new()];
        for (i, v) in res.iter().enumerate() {
            if v.is_finite() {
                if let Some(p) = out.last_mut() {
                    p.push((t(i), *v));
                }
            } else if out.last().is_some_and(|p| !p.is_empty()) {
                out.push(Vec::new());
            }
        }
        out
    };
    chart
        .draw_series(
            pieces(&res_b)
                .into_iter()
                .map(|p| PathElement::new(p, BASE.stroke_width(1))),
        )?
        .label("paper's model")
        .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 15, y)], BASE.stroke_width(2)));
    chart
        .draw_series(
            pieces(&res_a)
                .into_iter()
                .map(|p| PathElement::new(p, AFTER.stroke_width(1))),
        )?
        .label("with added effects")
        .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 15, y)], AFTER.stroke_width(2)));
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .position(SeriesLabelPosition::UpperRight)
        .draw()?;
    root.present()?;
    Ok(())
}

/// The held-out block the loops plot shows, and why: the one where the
/// added effects cut the squared error most (so that the loops show what
/// the effect does: the minor loops of a memory, the fast ramps of a rate
/// law), or the longest one when they cut nothing (no effect added). A
/// noisy load column can cut the blocks into short pieces; the first may
/// be a single sample.
fn shown_block(
    heldout: &[bool],
    measured: &[f64],
    base: &[f64],
    after: &[f64],
) -> Option<((usize, usize), &'static str)> {
    let blocks = runs(heldout);
    let cut = |&(a, b): &(usize, usize)| -> f64 {
        (a..=b)
            .filter_map(|i| {
                let (x, pb, pa) = (*measured.get(i)?, *base.get(i)?, *after.get(i)?);
                let d = (x - pb).powi(2) - (x - pa).powi(2);
                d.is_finite().then_some(d)
            })
            .sum()
    };
    let best = blocks
        .iter()
        .map(|blk| (*blk, cut(blk)))
        .max_by(|x, y| x.1.total_cmp(&y.1));
    match best {
        Some((blk, c)) if c > 0.0 => Some((blk, "where the added effects cut the error most")),
        _ => blocks
            .into_iter()
            .max_by_key(|&(a, b)| b - a)
            .map(|blk| (blk, "the longest")),
    }
}

/// The smallest box holding the finite points added.
#[derive(Clone, Copy, Debug)]
struct Extent {
    x: (f64, f64),
    y: (f64, f64),
}

impl Default for Extent {
    fn default() -> Self {
        Extent {
            x: (f64::INFINITY, f64::NEG_INFINITY),
            y: (f64::INFINITY, f64::NEG_INFINITY),
        }
    }
}

impl Extent {
    fn add(&mut self, (x, y): (f64, f64)) {
        if x.is_finite() && y.is_finite() {
            self.x = (self.x.0.min(x), self.x.1.max(x));
            self.y = (self.y.0.min(y), self.y.1.max(y));
        }
    }

    /// Each axis widened to at least its `min_span` about its middle, then
    /// padded by a twentieth of its span on both sides, not below 0 where
    /// no point is; `(0, min_span)` without a point.
    fn padded(self, min_span: (f64, f64)) -> ((f64, f64), (f64, f64)) {
        let axis = |(lo, hi): (f64, f64), span: f64| {
            if lo > hi {
                return (0.0, span);
            }
            let mid = 0.5 * (lo + hi);
            let half = (0.5 * (hi - lo)).max(0.5 * span);
            let pad = 0.1 * half;
            let low = mid - half - pad;
            (if lo >= 0.0 { low.max(0.0) } else { low }, mid + half + pad)
        };
        (axis(self.x, min_span.0), axis(self.y, min_span.1))
    }
}

/// Pressure–contraction loops of one held-out block (`shown_block`):
/// measured (grey) against the paper's model (left) and the model with the
/// added effects (right). Contraction on x and pressure on y, as `fit.png`.
///
/// On an isometric record (the length held, the pressure its answer) the
/// loops are pressure against force: measured, and the pressure the model
/// needs at the held length and the measured force.
pub fn loops_plot(r: &DiagnoseReport, record: &Record, path: &Path) -> anyhow::Result<()> {
    let s = &record.samples;
    let iso = isometric(r);
    let measured: Vec<f64> = s.iter().map(|x| measured(r, x)).collect();
    let ((a, b), why) = shown_block(&r.heldout, &measured, &r.predicted_base, &r.predicted_after)
        .unwrap_or(((0, s.len().saturating_sub(1)), "the whole record"));
    let idx: Vec<usize> = (a..=b)
        .filter(|&i| r.heldout.get(i) != Some(&false) || !iso)
        .collect();
    // The measured point of sample `i`, and the model's from its prediction.
    let point = |i: usize| -> (f64, f64) {
        if iso {
            (s[i].load_n, s[i].pressure_mpa)
        } else {
            (s[i].contraction, s[i].pressure_mpa)
        }
    };
    let model_point = |i: usize, pred: f64| -> (f64, f64) {
        if iso {
            (s[i].load_n, pred)
        } else {
            (pred, s[i].pressure_mpa)
        }
    };
    // Both panels on the block's own extent (measured and both models),
    // padded: an isometric block at one length spans a few newtons and
    // kilopascals, which axes from 0 crush into a corner.
    let mut extent = Extent::default();
    for &i in &idx {
        for p in [
            point(i),
            model_point(i, r.predicted_base[i]),
            model_point(i, r.predicted_after[i]),
        ] {
            extent.add(p);
        }
    }
    let min_span = if iso { (1.0, 0.01) } else { (0.005, 0.01) };
    let ((x_lo, x_hi), (y_lo, y_hi)) = extent.padded(min_span);
    crate::report::plot::ensure_font();
    let root = BitMapBackend::new(path, (1600, 730)).into_drawing_area();
    root.fill(&WHITE)?;
    let first = idx.first().copied().unwrap_or(0);
    let (t_a, t_b) = (
        idx.first().map_or(0.0, |&i| s[i].t_s),
        idx.last().map_or(0.0, |&i| s[i].t_s),
    );
    let at = match s.get(first) {
        Some(x) if iso => format!("held at contraction {:.4}", x.contraction),
        Some(x) => format!("at {:.0} N", x.load_n),
        None => String::new(),
    };
    let root = root.titled(
        &format!(
            "{}: held-out block {t_a:.0}–{t_b:.0} s {at} ({why})",
            r.source
        ),
        ("sans-serif", 20),
    )?;
    let (x_desc, rms_unit, model_label) = if iso {
        (
            axes::FORCE_N,
            " MPa",
            "pressure the model needs at the held length",
        )
    } else {
        (axes::CONTRACTION, "", "simulated from measured pressure")
    };
    let panels = root.split_evenly((1, 2));
    for (k, panel) in panels.iter().enumerate() {
        let (pred, color, name, rms) = if k == 0 {
            (
                &r.predicted_base,
                BASE,
                "paper's model".to_string(),
                r.rms_before,
            )
        } else {
            (
                &r.predicted_after,
                AFTER,
                if r.effects_added.is_empty() {
                    "no effect added".to_string()
                } else {
                    format!("+ {}", r.effects_added.join(" + "))
                },
                r.rms_after,
            )
        };
        let mut chart = ChartBuilder::on(panel)
            .caption(
                format!("{name} (held-out RMS of the record {rms:.5}{rms_unit})"),
                ("sans-serif", 20),
            )
            .margin(12)
            .x_label_area_size(40)
            .y_label_area_size(60)
            .build_cartesian_2d(x_lo..x_hi, y_lo..y_hi)?;
        let (xt, yt) = (tick_format(x_lo, x_hi), tick_format(y_lo, y_hi));
        chart
            .configure_mesh()
            .x_desc(x_desc)
            .y_desc(axes::PRESSURE_MPA)
            .x_label_formatter(&xt)
            .y_label_formatter(&yt)
            .draw()?;
        chart
            .draw_series(
                idx.iter()
                    .map(|&i| Circle::new(point(i), 2, RGBColor(150, 150, 150).filled())),
            )?
            .label("measured")
            .legend(|(x, y)| Circle::new((x + 7, y), 3, RGBColor(150, 150, 150).filled()));
        chart
            .draw_series(LineSeries::new(
                idx.iter()
                    .map(|&i| model_point(i, pred[i]))
                    .filter(|(x, y)| x.is_finite() && y.is_finite()),
                color.stroke_width(1),
            ))?
            .label(model_label)
            .legend(move |(x, y)| {
                PathElement::new(vec![(x, y), (x + 15, y)], color.stroke_width(2))
            });
        chart
            .configure_series_labels()
            .background_style(WHITE.mix(0.85))
            .border_style(BLACK)
            .position(SeriesLabelPosition::UpperLeft)
            .draw()?;
    }
    root.present()?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::{model_minus_measured, runs, shown_block, Extent};
    use crate::record::Sample;

    #[test]
    fn the_residual_is_model_minus_measured_in_the_quantity_predicted() {
        let s = [Sample {
            t_s: 0.0,
            load_n: 100.0,
            pressure_mpa: 0.3,
            contraction: 0.1,
        }];
        // A model above the measurement has a positive residual.
        let r = model_minus_measured(false, &[0.12], &s);
        assert!((r[0] - 0.02).abs() < 1e-12, "{r:?}");
        let r = model_minus_measured(true, &[0.25], &s);
        assert!((r[0] + 0.05).abs() < 1e-12, "{r:?}");
    }

    #[test]
    fn the_loops_show_where_the_effects_act() {
        // Two held-out blocks: a long one the effect leaves as it was, a
        // short one where it removes the error.
        let heldout = [true, true, true, true, false, true, true];
        let measured = [0.0; 7];
        let base = [0.1, 0.1, 0.1, 0.1, 0.0, 0.2, 0.2];
        let after = [0.1, 0.1, 0.1, 0.1, 0.0, 0.0, 0.0];
        let (blk, why) = shown_block(&heldout, &measured, &base, &after).unwrap();
        assert_eq!(blk, (5, 6));
        assert!(why.contains("cut"), "{why}");
        // Nothing added: the longest.
        let (blk, why) = shown_block(&heldout, &measured, &base, &base).unwrap();
        assert_eq!(blk, (0, 3));
        assert_eq!(why, "the longest");
        assert!(shown_block(&[false; 3], &[0.0; 3], &[0.0; 3], &[0.0; 3]).is_none());
    }

    #[test]
    fn the_loops_axes_hold_the_block_and_no_more() {
        let mut e = Extent::default();
        for p in [(170.0, 0.59), (187.0, 0.63), (f64::NAN, 9.0), (180.0, 0.60)] {
            e.add(p);
        }
        let ((x_lo, x_hi), (y_lo, y_hi)) = e.padded((1.0, 0.01));
        assert!(x_lo < 170.0 && x_lo > 168.0 && x_hi > 187.0 && x_hi < 189.0);
        assert!(y_lo < 0.59 && y_lo > 0.58 && y_hi > 0.63 && y_hi < 0.64);
        // A flat axis gets its least span; data from 0 keeps the axis at 0.
        let mut flat = Extent::default();
        flat.add((0.0, 0.3));
        flat.add((0.1, 0.3));
        let ((x_lo, _), (y_lo, y_hi)) = flat.padded((0.005, 0.01));
        assert_eq!(x_lo, 0.0);
        assert!(y_hi - y_lo >= 0.01 && y_lo < 0.3 && y_hi > 0.3);
        assert_eq!(
            Extent::default().padded((1.0, 0.1)),
            ((0.0, 1.0), (0.0, 0.1))
        );
    }

    #[test]
    fn runs_of_a_mask() {
        assert_eq!(
            runs(&[false, true, true, false, true]),
            vec![(1, 2), (4, 4)]
        );
        assert!(runs(&[]).is_empty());
    }
}
