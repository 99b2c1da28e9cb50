//! A starting point from the data.

use super::*;

/// A starting point from the data (not necessarily feasible: it is
/// projected). Stroke ends: where the record has samples near zero and full
/// pressure at the minimum load (isotonic tests), their median contraction;
/// otherwise (isometric tests, partial sweeps) where a surface
/// `p = k0 + k1·x + k2·s + k3·x·s` fitted to all training samples reaches 0
/// and `Pmax`. Load factors from the same ends per load bin or the surface;
/// the cubic's interior values from the mean of both branches; the ellipse
/// height from the gap between the branches at mid-stroke.
pub(super) fn initial_guess(
    samples: &[Sample],
    split: &Split,
    is_train: &dyn Fn(usize) -> bool,
    fixed: &Fixed,
    bin: f64,
) -> [f64; NP] {
    let pmax = fixed.pmax;
    let steps = |load_n: f64| (load_n - fixed.min_load_n) / fixed.load_step_n;
    let max_steps = steps(fixed.max_load_n);
    // Per load bin: the contractions near zero pressure and near Pmax.
    type Ends = (Vec<f64>, Vec<f64>);
    let mut ends: std::collections::BTreeMap<i64, Ends> = Default::default();
    for (i, s) in samples.iter().enumerate() {
        if !is_train(i) {
            continue;
        }
        let e = ends.entry((s.load_n / bin).round() as i64).or_default();
        if s.pressure_mpa < 0.03 * pmax {
            e.0.push(s.contraction);
        } else if s.pressure_mpa > 0.97 * pmax {
            e.1.push(s.contraction);
        }
    }
    let min_key = (fixed.min_load_n / bin).round() as i64;
    let surface = bilinear_surface(samples, is_train, &steps);
    let from_surface = |p: f64, s: f64| {
        surface.and_then(|k| {
            let slope = k[1] + k[3] * s;
            let x = (p - k[0] - k[2] * s) / slope;
            (slope > 0.0 && x.is_finite()).then_some(x)
        })
    };
    let measured = ends
        .get(&min_key)
        .filter(|(lo, hi)| lo.len() >= 5 && hi.len() >= 5)
        .and_then(|(lo, hi)| Some((quantile(lo.clone(), 0.5)?, quantile(hi.clone(), 0.5)?)));
    let all_x: Vec<f64> = samples.iter().map(|s| s.contraction).collect();
    let x_lo = quantile(all_x.clone(), 0.01).unwrap_or(0.0);
    let x_hi = quantile(all_x, 0.99).unwrap_or(0.2);
    let (r1, rx1) = match (measured, from_surface(0.0, 0.0), from_surface(pmax, 0.0)) {
        (Some(m), _, _) => m,
        (None, Some(a), Some(b)) => (a, b),
        _ => (x_lo, x_hi),
    };
    // Keep the stroke open and inside (-1, 1) so the anchor is a model.
    let r1 = r1.clamp(-0.5, 0.8);
    let rx1 = if rx1 > r1 + 1e-3 {
        rx1.min(0.95)
    } else {
        (r1 + 0.1).min(0.95)
    };
    // Regression of the ends on the load step count.
    let slope_of = |pick: &dyn Fn(&Ends) -> &Vec<f64>, p: f64| {
        let pts: Vec<(f64, f64)> = ends
            .iter()
            .filter(|(_, e)| pick(e).len() >= 5)
            .filter_map(|(k, e)| {
                quantile(pick(e).clone(), 0.5).map(|x| (steps(*k as f64 * bin), x))
            })
            .collect();
        if pts.len() < 2 {
            // The surface's ends at the two ends of the load range.
            return match (from_surface(p, 0.0), from_surface(p, max_steps)) {
                (Some(a), Some(b)) if max_steps > 0.0 => -(b - a) / max_steps,
                _ => 0.0,
            };
        }
        let n = pts.len() as f64;
        let (ms, mx) = (
            pts.iter().map(|p| p.0).sum::<f64>() / n,
            pts.iter().map(|p| p.1).sum::<f64>() / n,
        );
        let sxx: f64 = pts.iter().map(|p| (p.0 - ms).powi(2)).sum();
        let sxy: f64 = pts.iter().map(|p| (p.0 - ms) * (p.1 - mx)).sum();
        if sxx > 0.0 {
            -sxy / sxx
        } else {
            0.0
        }
    };
    let rg_l = slope_of(&|e| &e.0, 0.0);
    let rg_u = slope_of(&|e| &e.1, pmax);

    // Interior pressures and branch gap at the minimum load.
    let stroke = rx1 - r1;
    let mean_near = |x0: f64, br: Branch| {
        let (mut s, mut n) = (0.0, 0usize);
        for (i, smp) in samples.iter().enumerate() {
            if is_train(i)
                && split.branch[i] == Some(br)
                && (smp.load_n / bin).round() as i64 == min_key
                && (smp.contraction - x0).abs() < 0.04 * stroke
            {
                s += smp.pressure_mpa;
                n += 1;
            }
        }
        (n >= 5).then(|| s / n as f64)
    };
    let cm_at = |u: f64| {
        let x0 = r1 + u * stroke;
        match (
            mean_near(x0, Branch::Contraction),
            mean_near(x0, Branch::Expansion),
        ) {
            (Some(a), Some(b)) => 0.5 * (a + b),
            (Some(a), None) | (None, Some(a)) => a,
            (None, None) => pmax * anchor_shape(u),
        }
    };
    let (y1, y2) = (cm_at(U1), cm_at(U2));
    let be = match (
        mean_near(r1 + 0.5 * stroke, Branch::Contraction),
        mean_near(r1 + 0.5 * stroke, Branch::Expansion),
    ) {
        (Some(a), Some(b)) => (0.5 * (a - b)).clamp(0.0, 0.25 * pmax),
        _ => branch_gap(samples, split, is_train).clamp(0.0, 0.25 * pmax),
    };
    [r1, rx1, y1, y2.max(y1 + 1e-3 * pmax), rg_l, rg_u, 0.0, be]
}

/// Least-squares `p ≈ k0 + k1·x + k2·s + k3·x·s` over the training samples
/// (`s` the load step count), or `None` when singular.
pub(super) fn bilinear_surface(
    samples: &[Sample],
    is_train: &dyn Fn(usize) -> bool,
    steps: &dyn Fn(f64) -> f64,
) -> Option<[f64; 4]> {
    let mut ata = nalgebra::Matrix4::<f64>::zeros();
    let mut atb = nalgebra::Vector4::<f64>::zeros();
    for (i, s) in samples.iter().enumerate() {
        if !is_train(i) {
            continue;
        }
        let st = steps(s.load_n);
        let row = nalgebra::Vector4::new(1.0, s.contraction, st, s.contraction * st);
        ata += row * row.transpose();
        atb += row * s.pressure_mpa;
    }
    let k = ata.lu().solve(&atb)?;
    k.iter()
        .all(|v| v.is_finite())
        .then(|| [k[0], k[1], k[2], k[3]])
}

/// Half the typical pressure gap between the branches at equal contraction
/// and load: the mean rising-branch minus falling-branch pressure over
/// cells of (load bin of 5 % of the loads, 1/20 of the contraction range).
pub(super) fn branch_gap(
    samples: &[Sample],
    split: &Split,
    is_train: &dyn Fn(usize) -> bool,
) -> f64 {
    let xs: Vec<f64> = samples.iter().map(|s| s.contraction).collect();
    let ls: Vec<f64> = samples.iter().map(|s| s.load_n).collect();
    let (x0, x1) = (
        quantile(xs.clone(), 0.0).unwrap_or(0.0),
        quantile(xs, 1.0).unwrap_or(1.0),
    );
    let (l0, l1) = (
        quantile(ls.clone(), 0.0).unwrap_or(0.0),
        quantile(ls, 1.0).unwrap_or(1.0),
    );
    let cell = |s: &Sample| {
        (
            ((s.contraction - x0) / (x1 - x0).max(1e-9) * 20.0) as i64,
            ((s.load_n - l0) / (l1 - l0).max(1e-9) * 20.0) as i64,
        )
    };
    let mut acc: std::collections::HashMap<(i64, i64), [(f64, usize); 2]> = Default::default();
    for (i, s) in samples.iter().enumerate() {
        let Some(br) = split.branch[i].filter(|_| is_train(i)) else {
            continue;
        };
        let a = &mut acc.entry(cell(s)).or_default()[usize::from(br == Branch::Expansion)];
        a.0 += s.pressure_mpa;
        a.1 += 1;
    }
    let gaps: Vec<f64> = acc
        .values()
        .filter(|c| c[0].1 >= 3 && c[1].1 >= 3)
        .map(|c| 0.5 * (c[0].0 / c[0].1 as f64 - c[1].0 / c[1].1 as f64))
        .collect();
    quantile(gaps, 0.5).unwrap_or(0.0)
}
