//! The comparisons beyond held-out cycles: held-out loads, another protocol,
//! another muscle; each a markdown table.

use super::*;

/// Grid loads left out of training for the held-out-load table (300 and
/// 500 N): every model is identified without them and tested there.
pub(crate) const HELDOUT_GRID: [usize; 2] = [2, 4];

/// One row of a comparison table: the model, how it was identified, its
/// errors.
pub(crate) type Row = (&'static str, String, Errors);

/// Every model identified on `train`'s samples outside `heldout` (pam-core's
/// parameters `params` given; the memory's shape and GPI-4's threshold
/// chosen on the training samples; a grid load without training samples
/// interpolated, [`fill_untrained`]), then scored on `test` (every sample
/// held out) or on `train`'s held-out samples.
pub(crate) fn compare(
    train: &[Sample],
    heldout: &[bool],
    params: Params,
    test: Option<&[Sample]>,
) -> Vec<Row> {
    let trained = trained_grid(train, heldout);
    let lerp = |a: f32, b: f32, t: f32| a + t * (b - a);
    let all = test.map(|t| vec![true; t.len()]);
    let on_test =
        |f: &dyn Fn(&[Sample], &[bool]) -> Errors| test.zip(all.as_deref()).map(|(t, h)| f(t, h));

    let coeffs = Coeffs::new(params).expect("pam-lab returns valid parameters");
    let paper = merged(
        paper_errors(&coeffs, train, heldout),
        on_test(&|s, h| paper_errors(&coeffs, s, h)),
    );
    let (shape, memory) = MEMORY_SHAPES
        .iter()
        .map(|&sh| (sh, memory_errors(&coeffs, sh, train, heldout)))
        .min_by(|a, b| a.1.train_rms().total_cmp(&b.1.train_rms()))
        .expect("shapes");
    let memory = merged(memory, on_test(&|s, h| memory_errors(&coeffs, shape, s, h)));

    let mut pi = identify_pi(train, heldout);
    fill_untrained(&mut pi.grid, &trained, |a, b, t| PiCoeffs {
        bias: lerp(a.bias, b.bias, t),
        linear: lerp(a.linear, b.linear, t),
        weights: lerp_arr(&a.weights, &b.weights, t),
    });
    let pi_err = merged(
        pi_errors(&pi, train, heldout),
        on_test(&|s, h| pi_errors(&pi, s, h)),
    );

    let (gpi, gpi_err) = GPI_MAX_THRESHOLDS_MPA
        .iter()
        .map(|&r| {
            let mut t = identify_gpi(train, heldout, r);
            fill_untrained(&mut t.grid, &trained, |a, b, t| GpiCoeffs {
                bias: lerp(a.bias, b.bias, t),
                cubic: lerp_arr(&a.cubic, &b.cubic, t),
                weights: lerp_arr(&a.weights, &b.weights, t),
            });
            let e = gpi_errors(&t, train, heldout);
            (t, e)
        })
        .min_by(|a, b| a.1.train_rms().total_cmp(&b.1.train_rms()))
        .expect("thresholds");
    let gpi_err = merged(gpi_err, on_test(&|s, h| gpi_errors(&gpi, s, h)));

    let mut pr = identify_preisach(train, heldout);
    fill_untrained(&mut pr.grid, &trained, |a, b, t| PreisachCoeffs {
        bias: lerp(a.bias, b.bias, t),
        linear: lerp(a.linear, b.linear, t),
        everett: core::array::from_fn(|i| lerp_arr(&a.everett[i], &b.everett[i], t)),
    });
    let pr_err = merged(
        preisach_errors(&pr, train, heldout),
        on_test(&|s, h| preisach_errors(&pr, s, h)),
    );

    vec![
        (
            "pam-core, paper model",
            "`pam_lab::identify::fit::fit`; 8 parameters".to_string(),
            paper,
        ),
        (
            "pam-core + non-local memory",
            format!("same parameters; memory `shape` = {shape}"),
            memory,
        ),
        (
            "Prandtl–Ishlinskii, 16 play operators",
            "least squares per load".to_string(),
            pi_err,
        ),
        (
            "generalised Prandtl–Ishlinskii, 4 plays + cubic input",
            format!(
                "least squares per load; largest threshold {} MPa",
                gpi.thresholds_mpa[GPI_N - 1]
            ),
            gpi_err,
        ),
        (
            "Preisach, 16 × 16 half-grid (136 relays)",
            "least squares per load".to_string(),
            pr_err,
        ),
    ]
}

/// A comparison's markdown: `intro`, then the table.
pub(crate) fn table_md(intro: &str, rows: &[Row]) -> String {
    let mut md = format!("{intro}\n\n");
    md.push_str(
        "| model | identified | held-out RMS (%) | held-out max (%) | training RMS (%) |\n",
    );
    md.push_str("|---|---|---:|---:|---:|\n");
    for (name, how, e) in rows {
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

/// pam-lab's fit of `record` with `holdout`, or `Params::DEFAULT` (said on
/// stderr) when it fails.
pub(crate) fn fitted(record: &pam_lab::record::Record, holdout: Holdout) -> Params {
    let cfg = FitConfig {
        holdout,
        ..FitConfig::default()
    };
    pam_lab::identify::fit::fit(record, &cfg)
        .map(|r| r.params)
        .unwrap_or_else(|e| {
            eprintln!(
                "pam-lab fit of {} failed ({e}); using Params::DEFAULT",
                record.source
            );
            Params::DEFAULT
        })
}

/// Held-out loads: every model identified without [`HELDOUT_GRID`]'s loads
/// (all their cycles) and tested there.
pub(crate) fn held_out_loads(record: &pam_lab::record::Record) -> String {
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
    let params = fitted(&train_record, Holdout::None);
    let loads: Vec<String> = HELDOUT_GRID
        .iter()
        .map(|&g| format!("{}", MIN_LOAD_N + LOAD_STEP_N * g as f32))
        .collect();
    table_md(
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
        &compare(samples, &heldout, params, None),
    )
}

/// The other protocol: the models of the first table (training cycles of
/// the characterisation run) on an isotonic run of the same rig with a
/// fast cycle ([`IsotonicProtocol::WITH_FAST_CYCLE`]).
pub(crate) fn other_protocol(samples: &[Sample], heldout: &[bool], params: Params) -> String {
    let run = isotonic_run_on(
        Rig::reference(LOADS_N[0], SEED + 1),
        &IsotonicProtocol::WITH_FAST_CYCLE,
    );
    let test = host_sim::to_record("isotonic run with a fast cycle", &run);
    table_md(
        &format!(
            "**Another protocol.** The models of the first table, on another run of the same \
             rig (`isotonic_run_on(Rig::reference(100.0, {}), &IsotonicProtocol::WITH_FAST_CYCLE)`: \
             the same loads, 25 Hz, two slow cycles, reversals inside the loop, then one full cycle \
             at 0.2 MPa/s, four times the training ramps; {} samples, all held out).",
            SEED + 1,
            test.samples.len()
        ),
        &compare(samples, heldout, params, Some(&test.samples)),
    )
}

/// A second muscle of the reference design: [`second_muscle`].
pub(crate) fn other_muscle() -> String {
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
    let params = fitted(&record, holdout);
    table_md(
        &format!(
            "**Another muscle.** A second specimen of the reference design, identified and \
             tested on its own characterisation run as the first table is ({}; {} samples, \
             every 4th pressure cycle held out: {} held-out samples).",
            SECOND_MUSCLE,
            record.samples.len(),
            n_test
        ),
        &compare(&record.samples, &heldout, params, None),
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
