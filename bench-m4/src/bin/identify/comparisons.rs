//! The comparisons beyond held-out cycles: held-out loads, another protocol,
//! another muscle; each a markdown table.

use super::*;

/// Grid loads left out of training for the held-out-load table (300 and
/// 500 N): every model is identified without them and tested there.
pub(crate) const HELDOUT_GRID: [usize; 2] = [2, 4];

/// One row of a comparison table: the model's key (`accuracy.tsv`,
/// report.py), its name, how it was identified, its errors.
pub(crate) type Row = (&'static str, &'static str, String, Errors);

/// One comparison: its key in `accuracy.tsv`, its markdown, its rows.
pub(crate) struct Comparison {
    pub(crate) key: &'static str,
    pub(crate) md: String,
    pub(crate) rows: Vec<Row>,
}

impl Comparison {
    /// The comparison `key` of `rows`, introduced by `intro`.
    pub(crate) fn new(key: &'static str, intro: &str, rows: Vec<Row>) -> Comparison {
        Comparison {
            key,
            md: table_md(intro, &rows),
            rows,
        }
    }
}

/// pam-core's two models of a record from pam-lab's fit: the paper's model
/// alone (`fit --no-static-shape`), and what `fit` writes by default (its
/// parameters with its static shape: the stroke table where the cubic
/// leaves a systematic misfit, as on this rig).
pub(crate) struct PamFit {
    pub(crate) paper: Params,
    pub(crate) fit: Params,
    pub(crate) shape: Option<ConstraintShape>,
}

/// Every model identified on `train`'s samples outside `heldout` and scored
/// on `test` (every sample held out) or on `train`'s held-out samples
/// ([`identify_models`], [`score`]): the table's rows.
pub(crate) fn compare(
    train: &[Sample],
    heldout: &[bool],
    pam: &PamFit,
    test: Option<&[Sample]>,
) -> Vec<Row> {
    let models = identify_models(train, heldout, pam);
    rows(&models, &score(&models, train, heldout, test))
}

/// The rows of `models` with their errors `e`.
pub(crate) fn rows(models: &Models, e: &Scores) -> Vec<Row> {
    vec![
        (
            "pam_core",
            "pam-core, paper model",
            "`pam_lab::identify::fit::fit` with `static_shape: false`; 8 parameters".to_string(),
            e.paper,
        ),
        (
            "pam_core_memory",
            "pam-core, paper model + non-local memory",
            format!(
                "same parameters; memory {} chosen on the training cycles",
                memory_text(&models.memory)
            ),
            e.memory,
        ),
        (
            "pam_core_fit",
            "pam-core, fit's model (paper + static shape)",
            format!(
                "`pam_lab::identify::fit::fit` as `pam-lab fit` runs it; {}",
                shape_kind(models.shape)
            ),
            e.fit,
        ),
        (
            "pam_core_fit_memory",
            "pam-core, fit's model + non-local memory",
            format!(
                "same model; memory {} chosen on the training cycles",
                memory_text(&models.fit_memory)
            ),
            e.fit_memory,
        ),
        (
            "pi16",
            "Prandtl–Ishlinskii, 16 play operators",
            format!("least squares per load; {} coefficients", L * (N + 2)),
            e.pi,
        ),
        (
            "gpi4",
            "generalised Prandtl–Ishlinskii, 4 plays + cubic input",
            format!(
                "least squares per load; {} coefficients; largest threshold {} MPa chosen on the training cycles",
                L * (GPI_N + 4),
                models.gpi.thresholds_mpa[GPI_N - 1]
            ),
            e.gpi,
        ),
        (
            "preisach16",
            "Preisach, 16 × 16 half-grid (136 relays)",
            format!(
                "least squares per load; {} coefficients",
                L * (N * (N + 1) / 2 + 2)
            ),
            e.preisach,
        ),
    ]
}

/// A memory's parameters, for a table's "identified" column.
pub(crate) fn memory_text(m: &NonLocalMemory) -> String {
    if m.merge_span >= 1.0 {
        format!("`shape` = {}", m.shape)
    } else {
        format!("`shape` = {}, `merge_span` = {}", m.shape, m.merge_span)
    }
}

/// What fit's static shape is, for a table's "identified" column.
pub(crate) fn shape_kind(shape: Option<ConstraintShape>) -> &'static str {
    match shape {
        Some(s) if !s.table.is_neutral() && s.coefficients_f64() != [0.0; 10] => {
            "8 parameters, a stroke table (66 knots) and its ends' shifts (6)"
        }
        Some(s) if !s.table.is_neutral() => "8 parameters and a stroke table (66 knots)",
        Some(_) => "8 parameters and a polynomial shape correction",
        None => "8 parameters (fit kept no static shape)",
    }
}

/// A comparison's markdown: `intro`, then the table.
pub(crate) fn table_md(intro: &str, rows: &[Row]) -> String {
    let mut md = format!("{intro}\n\n");
    md.push_str(
        "| model | identified | held-out RMS (%) | held-out max (%) | training RMS (%) |\n",
    );
    md.push_str("|---|---|---:|---:|---:|\n");
    for (_, name, how, e) in rows {
        let _ = writeln!(
            md,
            "| {name} | {how} | {:.3} | {:.3} | {:.3} |",
            100.0 * e.test_rms(),
            100.0 * e.test_max,
            100.0 * e.train_rms()
        );
    }
    md
}

/// pam-lab's two fits of `record` with `holdout` ([`PamFit`]); a fit that
/// fails (said on stderr) gives `Params::DEFAULT` without a shape.
pub(crate) fn fitted(record: &pam_lab::record::Record, holdout: Holdout) -> PamFit {
    let run = |static_shape: bool| {
        let cfg = FitConfig {
            holdout,
            static_shape,
            ..FitConfig::default()
        };
        pam_lab::identify::fit::fit(record, &cfg)
            .map(|r| (r.params, r.constraint_shape))
            .unwrap_or_else(|e| {
                eprintln!(
                    "pam-lab fit of {} failed ({e}); using Params::DEFAULT",
                    record.source
                );
                (Params::DEFAULT, None)
            })
    };
    let (paper, _) = run(false);
    let (fit, shape) = run(true);
    PamFit { paper, fit, shape }
}

/// Held-out loads: every model identified without [`HELDOUT_GRID`]'s loads
/// (all their cycles) and tested there; and the same models on a slow load
/// sweep ([`load_sweep`]).
pub(crate) fn held_out_loads(record: &pam_lab::record::Record) -> [Comparison; 2] {
    let samples = &record.samples;
    let heldout: Vec<bool> = samples
        .iter()
        .map(|s| HELDOUT_GRID.contains(&grid_index(s.load_n as f32)))
        .collect();
    let n_test = heldout.iter().filter(|&&h| h).count();
    let train_record = pam_lab::record::Record::from_samples(
        "characterisation run without the held-out loads",
        samples
            .iter()
            .zip(&heldout)
            .filter(|(_, &h)| !h)
            .map(|(s, _)| *s)
            .collect(),
    );
    let pam = fitted(&train_record, Holdout::None);
    let loads: Vec<String> = HELDOUT_GRID
        .iter()
        .map(|&g| format!("{}", MIN_LOAD_N + LOAD_STEP_N * g as f32))
        .collect();
    let models = identify_models(samples, &heldout, &pam);
    let at_loads = Comparison::new(
        "held_out_loads",
        &format!(
            "**Held-out loads.** The same run, every model identified without the {} N loads \
             (all their cycles: {} held-out samples, {} training samples) and tested there. \
             The per-load tables take, at a load they were not trained at, the coefficients \
             interpolated linearly from the trained loads on each side; pam-core's load family \
             evaluates any load.",
            loads.join(" and "),
            n_test,
            samples.len() - n_test
        ),
        rows(&models, &score(&models, samples, &heldout, None)),
    );
    let sweep = load_sweep();
    let on_sweep = Comparison::new(
        "load_sweep",
        &format!(
            "**A slow load sweep.** The models of the held-out-load table (identified without \
             the {} N loads), on a run of the same rig whose hung load moves continuously: \
             {} ({} samples, all held out).",
            loads.join(" and "),
            LOAD_SWEEP,
            sweep.len()
        ),
        rows(&models, &score(&models, samples, &heldout, Some(&sweep))),
    );
    [at_loads, on_sweep]
}

/// The load sweep's protocol, as the table says it.
pub(crate) const LOAD_SWEEP: &str = "the load from 100 to 600 N and back at 2.5 N/s, \
    the pressure cycling 0 → 0.5 → 0 MPa at 0.05 MPa/s with a reversal inside the loop \
    (0.35 → 0.15 MPa) every other cycle, 25 Hz, the hung load logged";

/// [`LOAD_SWEEP`] on the reference rig (seed `SEED + 2`).
pub(crate) fn load_sweep() -> Vec<Sample> {
    let rate_hz = 25.0;
    let dt = 1.0 / rate_hz;
    let (lo, hi, load_rate) = (100.0, 600.0, 2.5);
    let sweep_s = 2.0 * (hi - lo) / load_rate;
    let load_at = |t: f64| {
        let half = sweep_s / 2.0;
        if t <= half {
            lo + load_rate * t
        } else {
            hi - load_rate * (t - half)
        }
    };
    // One pressure cycle: knots (MPa) at 0.05 MPa/s; every other cycle
    // reverses inside the loop.
    let full: [f64; 3] = [0.0, 0.5, 0.0];
    let inner: [f64; 5] = [0.0, 0.35, 0.15, 0.5, 0.0];
    let ramp = 0.05;
    let mut rig = Rig::reference(lo, SEED + 2);
    let mut out = Vec::new();
    let (mut t, mut cycle) = (0.0, 0usize);
    while t < sweep_s {
        let knots: &[f64] = if cycle % 2 == 0 { &full } else { &inner };
        for w in knots.windows(2) {
            let n = ((w[1] - w[0]).abs() / ramp / dt).round() as usize;
            for k in 0..n {
                let load = load_at(t);
                rig.set_load_n(load);
                let mut s = rig.measure();
                s.load_n = load;
                out.push(s);
                rig.advance_regulated(w[0] + (w[1] - w[0]) * (k + 1) as f64 / n as f64, dt);
                t += dt;
            }
        }
        cycle += 1;
    }
    let record = host_sim::to_record("a slow load sweep", &out);
    record.samples
}

/// The other protocol: the models of the first table (training cycles of
/// the characterisation run) on an isotonic run of the same rig with a
/// fast cycle ([`IsotonicProtocol::WITH_FAST_CYCLE`]).
pub(crate) fn other_protocol(models: &Models, samples: &[Sample], heldout: &[bool]) -> Comparison {
    let run = isotonic_run_on(
        Rig::reference(LOADS_N[0], SEED + 1),
        &IsotonicProtocol::WITH_FAST_CYCLE,
    );
    let test = host_sim::to_record("isotonic run with a fast cycle", &run);
    Comparison::new(
        "other_protocol",
        &format!(
            "**Another protocol.** The models of the first table, on another run of the same \
             rig (`isotonic_run_on(Rig::reference(100.0, {}), &IsotonicProtocol::WITH_FAST_CYCLE)`: \
             the same loads, 25 Hz, two slow cycles, reversals inside the loop, then one full cycle \
             at 0.2 MPa/s, four times the training ramps; {} samples, all held out).",
            SEED + 1,
            test.samples.len()
        ),
        rows(models, &score(models, samples, heldout, Some(&test.samples))),
    )
}

/// A second muscle of the reference design: [`second_muscle`].
pub(crate) fn other_muscle() -> Comparison {
    let protocol = IsotonicProtocol {
        loads_n: &LOADS_N,
        moves: &CHARACTERISATION_MOVES,
        settle_s: 2.0,
        log_rate_hz: 50.0,
    };
    let rig = Rig::new(second_muscle(), PneumaticParams::DEFAULT, LOADS_N[0], SEED);
    let record = host_sim::to_record("a second muscle", &isotonic_run_on(rig, &protocol));
    let holdout = Holdout::EveryKthCycle(4);
    let split = split_branches(&record.samples, &SplitConfig::default());
    let heldout = heldout_mask(holdout, &split.cycle);
    let n_test = heldout.iter().filter(|&&h| h).count();
    let pam = fitted(&record, holdout);
    Comparison::new(
        "other_muscle",
        &format!(
            "**Another muscle.** A second specimen of the reference design, identified and \
             tested on its own characterisation run as the first table is ({}; {} samples, \
             every 4th pressure cycle held out: {} held-out samples).",
            SECOND_MUSCLE,
            record.samples.len(),
            n_test
        ),
        compare(&record.samples, &heldout, &pam, None),
    )
}

/// The second muscle's difference from the reference, as the table says it.
pub(crate) const SECOND_MUSCLE: &str = "35 cm instead of 30 cm, braid angle 21° instead of 20°, \
    rubber 20 % stiffer, friction 30 % higher";

/// The second muscle: [`SECOND_MUSCLE`].
pub(crate) fn second_muscle() -> MuscleParams {
    let d = MuscleParams::DEFAULT;
    MuscleParams {
        rest_length_m: 0.35,
        braid_angle_rad: 21f64.to_radians(),
        rubber_stiffness_n: 1.2 * d.rubber_stiffness_n,
        friction_base_n: 1.3 * d.friction_base_n,
        friction_ratio: 1.3 * d.friction_ratio,
        ..d
    }
}

/// The characterisation run's pressure moves (`PRESSURE_KNOTS_MPA` at
/// `RAMP_MPA_PER_S`) for [`isotonic_run_on`].
pub(crate) const CHARACTERISATION_MOVES: [(f64, f64); 10] = {
    let mut m = [(0.0, 0.0); 10];
    let mut i = 0;
    while i < 10 {
        m[i] = (PRESSURE_KNOTS_MPA[i + 1], RAMP_MPA_PER_S);
        i += 1;
    }
    m
};
