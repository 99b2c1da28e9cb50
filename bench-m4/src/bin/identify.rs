//! Identification of the benchmark's models on one data set, and their
//! held-out accuracy.
//!
//! ```text
//! cargo run -p bench-m4 --features host --bin identify --release
//! ```
//!
//! Data: host-sim's characterisation run of the reference rig
//! (`host_sim::characterisation_run(SEED)`: loads 100…600 N, at each two full
//! cycles 0 → 0.5 → 0 MPa and partial cycles reversing inside the loop, 50 Hz,
//! sensor noise). Split: pam-lab's rule, the branch split's cycles (a new
//! cycle at each switch to rising pressure) with every 4th cycle held out
//! (`Holdout::EveryKthCycle(4)`, pam-lab's default), so held-out data come
//! from every load and every part of the protocol.
//!
//! Every model predicts contraction from the measured pressure and load,
//! sample by sample over the whole record (a model's state depends only on
//! the pressure history, never on measured contraction); coefficients are
//! identified from the training samples only; errors are reported on the
//! held-out samples.
//!
//! * pam-core, paper model: `pam_lab::identify::fit::fit` (Levenberg–Marquardt on the
//!   training part, same split), then pam-core's `Tracker` + branch inverse
//!   driven by pressure (`pam_lab::evaluate::simulate::simulate`).
//! * pam-core + non-local memory: the same parameters in
//!   `pam_core::Simulator` with `NonLocalMemory`; its `shape` chosen on the
//!   training samples from a grid.
//! * Prandtl–Ishlinskii, 16 play operators: thresholds `r_i = i·0.25/16`
//!   MPa (`i = 1…16`), plus bias and linear term; weights by linear least
//!   squares (signed, a tiny ridge) per grid load.
//! * Preisach, 16 × 16 half-grid (136 relays): `β_j = 0.01 + 0.03·j`,
//!   `α_i = 0.01 + 0.03·(i + 1)` MPa, plus bias and linear term; weights by
//!   linear least squares (signed, a small ridge: relays the data never
//!   switch get weight 0) per grid load.
//!
//! Writes `bench-m4/src/identified.rs` (the tables the bench image runs),
//! `bench-m4/accuracy.md` and `bench-m4/accuracy.tsv`.

use std::fmt::Write as _;
use std::path::PathBuf;

use bench_m4::{
    GeneralizedPi, GpiCoeffs, GpiTable, PiCoeffs, PiTable, PrandtlIshlinskii, Preisach,
    PreisachCoeffs, PreisachTable,
};
use host_sim::characterisation::{
    isotonic_run_on, IsotonicProtocol, LOADS_N, PRESSURE_KNOTS_MPA, RAMP_MPA_PER_S,
};
use host_sim::plant::MuscleParams;
use host_sim::pneumatics::PneumaticParams;
use host_sim::Rig;
use nalgebra::{DMatrix, DVector};
use pam_core::effects::{Effects, NonLocalMemory};
use pam_core::Simulator;
use pam_core::{Coeffs, Params, TrackerConfig};
use pam_lab::export::model_file::{f32_literal, params_literal, ParamsLayout};
use pam_lab::identify::fit::{heldout_mask, FitConfig, Holdout};
use pam_lab::record::split::{split_branches, SplitConfig};
use pam_lab::record::Sample;

/// Seed of the characterisation run (sensor noise only).
const SEED: u64 = 1;
/// Operators / grid size of the baselines.
const N: usize = 16;
/// Grid loads: 100, 200, …, 600 N.
const L: usize = 6;
const MIN_LOAD_N: f32 = 100.0;
const LOAD_STEP_N: f32 = 100.0;
/// Largest play threshold, MPa (half the 0–0.5 MPa input range).
const PI_MAX_THRESHOLD_MPA: f32 = 0.25;
/// Play operators of the generalised PI baseline.
const GPI_N: usize = 4;
/// Candidate largest play thresholds of the generalised PI, MPa (chosen on
/// the training samples; thresholds `r_i = i·r_max/GPI_N`).
const GPI_MAX_THRESHOLDS_MPA: [f32; 6] = [0.04, 0.06, 0.08, 0.12, 0.16, 0.25];
/// Preisach grid: lowest switch-down threshold and spacing, MPa.
const PREISACH_LO_MPA: f32 = 0.01;
const PREISACH_STEP_MPA: f32 = 0.03;
/// Ridge on the relative scale of the normal equations' diagonal.
const RIDGE: f64 = 1e-6;
/// Grid loads left out of training for the held-out-load table (300 and
/// 500 N): every model is identified without them and tested there.
const HELDOUT_GRID: [usize; 2] = [2, 4];
/// Candidate shapes of the non-local memory (chosen on training data).
const MEMORY_SHAPES: [f32; 8] = [0.25, 0.5, 0.75, 1.0, 1.5, 2.0, 3.0, 5.0];

fn grid_index(load_n: f32) -> usize {
    let k = ((load_n - MIN_LOAD_N) / LOAD_STEP_N).round();
    k.clamp(0.0, (L - 1) as f32) as usize
}

/// Normal equations per grid load.
struct Normal {
    ata: Vec<DMatrix<f64>>,
    aty: Vec<DVector<f64>>,
    rows: Vec<usize>,
}

impl Normal {
    fn new(m: usize) -> Normal {
        Normal {
            ata: vec![DMatrix::zeros(m, m); L],
            aty: vec![DVector::zeros(m); L],
            rows: vec![0; L],
        }
    }

    fn add(&mut self, g: usize, row: &[f64], y: f64) {
        let ata = &mut self.ata[g];
        let m = row.len();
        for i in 0..m {
            let ri = row[i];
            if ri == 0.0 {
                continue;
            }
            for j in i..m {
                ata[(i, j)] += ri * row[j];
            }
            self.aty[g][i] += ri * y;
        }
        self.rows[g] += 1;
    }

    /// Least squares with a ridge `RIDGE·mean(diag)` on every column but the bias.
    fn solve(&self, g: usize) -> Vec<f64> {
        let mut a = self.ata[g].clone();
        let m = a.nrows();
        for i in 0..m {
            for j in 0..i {
                a[(i, j)] = a[(j, i)];
            }
        }
        let mean_diag = (0..m).map(|i| a[(i, i)]).sum::<f64>() / m as f64;
        for i in 1..m {
            a[(i, i)] += RIDGE * mean_diag;
        }
        let b = self.aty[g].clone();
        let x = match a.clone().cholesky() {
            Some(c) => c.solve(&b),
            None => a
                .svd(true, true)
                .solve(&b, 1e-12)
                .expect("SVD least squares"),
        };
        x.iter().copied().collect()
    }
}

#[derive(Clone, Copy, Default)]
struct Errors {
    train_sq: f64,
    train_n: usize,
    test_sq: f64,
    test_max: f64,
    test_n: usize,
}

impl Errors {
    fn add(&mut self, heldout: bool, e: f64) {
        if heldout {
            self.test_sq += e * e;
            self.test_max = self.test_max.max(e.abs());
            self.test_n += 1;
        } else {
            self.train_sq += e * e;
            self.train_n += 1;
        }
    }
    fn train_rms(&self) -> f64 {
        (self.train_sq / self.train_n.max(1) as f64).sqrt()
    }
    fn test_rms(&self) -> f64 {
        (self.test_sq / self.test_n.max(1) as f64).sqrt()
    }
}

fn pi_thresholds() -> [f32; N] {
    core::array::from_fn(|i| (i + 1) as f32 * PI_MAX_THRESHOLD_MPA / N as f32)
}

fn identify_pi(samples: &[Sample], heldout: &[bool]) -> PiTable<N, L> {
    let thresholds_mpa = pi_thresholds();
    // Identity coefficients: only the state sequence matters while fitting.
    let zero = PiCoeffs {
        bias: 0.0,
        linear: 0.0,
        weights: [0.0; N],
    };
    let mut table = PiTable {
        thresholds_mpa,
        min_load_n: MIN_LOAD_N,
        load_step_n: LOAD_STEP_N,
        grid: [zero; L],
    };
    let first = &samples[0];
    let mut m = PrandtlIshlinskii::new(&table, first.load_n as f32, first.pressure_mpa as f32);
    let mut ne = Normal::new(N + 2);
    let mut row = vec![0.0; N + 2];
    for (s, &h) in samples.iter().zip(heldout) {
        m.update_load(&table, s.load_n as f32);
        m.update_state(s.pressure_mpa as f32);
        if h {
            continue;
        }
        row[0] = 1.0;
        row[1] = f64::from(m.last_mpa());
        for (r, &z) in row[2..].iter_mut().zip(m.plays()) {
            *r = f64::from(z);
        }
        ne.add(grid_index(m.load_n()), &row, s.contraction);
    }
    for g in 0..L {
        let x = ne.solve(g);
        table.grid[g] = PiCoeffs {
            bias: x[0] as f32,
            linear: x[1] as f32,
            weights: core::array::from_fn(|i| x[i + 2] as f32),
        };
    }
    table
}

fn identify_gpi(
    samples: &[Sample],
    heldout: &[bool],
    max_threshold_mpa: f32,
) -> GpiTable<GPI_N, L> {
    let thresholds_mpa: [f32; GPI_N] =
        core::array::from_fn(|i| (i + 1) as f32 * max_threshold_mpa / GPI_N as f32);
    let zero = GpiCoeffs {
        bias: 0.0,
        cubic: [0.0; 3],
        weights: [0.0; GPI_N],
    };
    let mut table = GpiTable {
        thresholds_mpa,
        min_load_n: MIN_LOAD_N,
        load_step_n: LOAD_STEP_N,
        grid: [zero; L],
    };
    let first = &samples[0];
    let mut m = GeneralizedPi::new(&table, first.load_n as f32, first.pressure_mpa as f32);
    let mut ne = Normal::new(GPI_N + 4);
    let mut row = vec![0.0; GPI_N + 4];
    for (s, &h) in samples.iter().zip(heldout) {
        m.update_load(&table, s.load_n as f32);
        m.update_state(s.pressure_mpa as f32);
        if h {
            continue;
        }
        let p = f64::from(m.last_mpa());
        row[0] = 1.0;
        row[1] = p;
        row[2] = p * p;
        row[3] = p * p * p;
        for (r, &z) in row[4..].iter_mut().zip(m.plays()) {
            *r = f64::from(z);
        }
        ne.add(grid_index(m.load_n()), &row, s.contraction);
    }
    for g in 0..L {
        let x = ne.solve(g);
        table.grid[g] = GpiCoeffs {
            bias: x[0] as f32,
            cubic: [x[1] as f32, x[2] as f32, x[3] as f32],
            weights: core::array::from_fn(|i| x[i + 4] as f32),
        };
    }
    table
}

/// The first sample's load (N) and pressure (MPa): where a baseline starts.
fn start(samples: &[Sample]) -> (f32, f32) {
    samples
        .first()
        .map_or((0.0, 0.0), |s| (s.load_n as f32, s.pressure_mpa as f32))
}

/// A baseline's errors over `samples`: `step(pressure MPa, load N)` gives
/// its contraction, sample by sample.
fn baseline_errors(
    samples: &[Sample],
    heldout: &[bool],
    mut step: impl FnMut(f32, f32) -> f32,
) -> Errors {
    let mut e = Errors::default();
    for (s, &h) in samples.iter().zip(heldout) {
        let x = step(s.pressure_mpa as f32, s.load_n as f32);
        e.add(h, f64::from(x) - s.contraction);
    }
    e
}

fn gpi_errors(table: &GpiTable<GPI_N, L>, samples: &[Sample], heldout: &[bool]) -> Errors {
    let (l0, p0) = start(samples);
    let mut m = GeneralizedPi::new(table, l0, p0);
    baseline_errors(samples, heldout, |p, l| m.step(table, p, l))
}

fn identify_preisach(samples: &[Sample], heldout: &[bool]) -> PreisachTable<N, L> {
    let zero = PreisachCoeffs {
        bias: 0.0,
        linear: 0.0,
        everett: [[0.0; N]; N],
    };
    let mut table = PreisachTable {
        lo_mpa: PREISACH_LO_MPA,
        step_mpa: PREISACH_STEP_MPA,
        min_load_n: MIN_LOAD_N,
        load_step_n: LOAD_STEP_N,
        grid: [zero; L],
    };
    let relays = N * (N + 1) / 2;
    let first = &samples[0];
    let mut m = Preisach::new(&table, first.load_n as f32, first.pressure_mpa as f32);
    let mut ne = Normal::new(relays + 2);
    let mut row = vec![0.0; relays + 2];
    for (s, &h) in samples.iter().zip(heldout) {
        m.update_load(&table, s.load_n as f32);
        m.update_state(s.pressure_mpa as f32);
        if h {
            continue;
        }
        row[0] = 1.0;
        row[1] = f64::from(m.last_mpa());
        let mut c = 2;
        for i in 0..N {
            for j in 0..=i {
                row[c] = if m.relay(i, j) { 1.0 } else { 0.0 };
                c += 1;
            }
        }
        ne.add(grid_index(m.load_n()), &row, s.contraction);
    }
    for g in 0..L {
        let x = ne.solve(g);
        let mut w = [[0.0f32; N]; N];
        let mut c = 2;
        for (i, wr) in w.iter_mut().enumerate() {
            for v in wr.iter_mut().take(i + 1) {
                *v = x[c] as f32;
                c += 1;
            }
        }
        table.grid[g] = PreisachCoeffs::from_weights(x[0] as f32, x[1] as f32, &w);
    }
    table
}

fn memory_errors(coeffs: &Coeffs, shape: f32, samples: &[Sample], heldout: &[bool]) -> Errors {
    let effects = Effects {
        memory: Some(NonLocalMemory::with_shape(shape)),
        ..Effects::NONE
    };
    let mut sim = Simulator::<16>::new(
        *coeffs,
        effects,
        TrackerConfig::DEFAULT_PRESSURE,
        samples[0].load_n as f32,
    )
    .expect("valid simulator");
    let mut e = Errors::default();
    for (s, &h) in samples.iter().zip(heldout) {
        let x = sim.step(s.t_s as f32, s.pressure_mpa as f32, s.load_n as f32);
        e.add(h, f64::from(x) - s.contraction);
    }
    e
}

/// Grid loads with training samples (by the grid the tables use).
fn trained_grid(samples: &[Sample], heldout: &[bool]) -> [bool; L] {
    let mut trained = [false; L];
    for (s, &h) in samples.iter().zip(heldout) {
        if !h {
            trained[grid_index(s.load_n as f32)] = true;
        }
    }
    trained
}

/// Every grid load without training samples takes the coefficients
/// interpolated linearly from the nearest trained grid loads on each side
/// (the nearest one's where only one side has one): what the table's own
/// `at_load` does between its grid loads, over the wider gap. The models
/// are linear in their coefficients, so this is their prediction
/// interpolated across load.
fn fill_untrained<T: Copy>(grid: &mut [T; L], trained: &[bool; L], mix: impl Fn(&T, &T, f32) -> T) {
    for g in 0..L {
        if trained[g] {
            continue;
        }
        let below = (0..g).rev().find(|&k| trained[k]);
        let above = (g + 1..L).find(|&k| trained[k]);
        grid[g] = match (below, above) {
            (Some(a), Some(b)) => mix(&grid[a], &grid[b], (g - a) as f32 / (b - a) as f32),
            (Some(a), None) => grid[a],
            (None, Some(b)) => grid[b],
            (None, None) => grid[g],
        };
    }
}

fn lerp_arr<const K: usize>(a: &[f32; K], b: &[f32; K], t: f32) -> [f32; K] {
    core::array::from_fn(|i| a[i] + t * (b[i] - a[i]))
}

/// One row of a comparison table: the model, how it was identified, its
/// errors.
type Row = (&'static str, String, Errors);

/// Errors with the training part of `train` and the held-out part of
/// `test` (a run on another record, every sample held out), or `train`'s
/// own held-out part.
fn merged(train: Errors, test: Option<Errors>) -> Errors {
    match test {
        Some(t) => Errors {
            test_sq: t.test_sq,
            test_max: t.test_max,
            test_n: t.test_n,
            ..train
        },
        None => train,
    }
}

fn paper_errors(coeffs: &Coeffs, samples: &[Sample], heldout: &[bool]) -> Errors {
    let sim = pam_lab::evaluate::simulate::simulate(
        coeffs,
        &pam_core::Effects::NONE,
        TrackerConfig::DEFAULT_PRESSURE,
        samples,
    );
    let mut e = Errors::default();
    for (s, &h) in sim.iter().zip(heldout) {
        e.add(h, s.error());
    }
    e
}

fn pi_errors(table: &PiTable<N, L>, samples: &[Sample], heldout: &[bool]) -> Errors {
    let (l0, p0) = start(samples);
    let mut m = PrandtlIshlinskii::new(table, l0, p0);
    baseline_errors(samples, heldout, |p, l| m.step(table, p, l))
}

fn preisach_errors(table: &PreisachTable<N, L>, samples: &[Sample], heldout: &[bool]) -> Errors {
    let (l0, p0) = start(samples);
    let mut m = Preisach::new(table, l0, p0);
    baseline_errors(samples, heldout, |p, l| m.step(table, p, l))
}

/// Every model identified on `train`'s samples outside `heldout` (pam-core's
/// parameters `params` given; the memory's shape and GPI-4's threshold
/// chosen on the training samples; a grid load without training samples
/// interpolated, [`fill_untrained`]), then scored on `test` (every sample
/// held out) or on `train`'s held-out samples.
fn compare(
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
fn table_md(intro: &str, rows: &[Row]) -> String {
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
fn fitted(record: &pam_lab::record::Record, holdout: Holdout) -> Params {
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
fn held_out_loads(record: &pam_lab::record::Record) -> String {
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
fn other_protocol(samples: &[Sample], heldout: &[bool], params: Params) -> String {
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
fn other_muscle() -> String {
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
const SECOND_MUSCLE: &str = "35 cm instead of 30 cm, braid angle 21° instead of 20°, \
    rubber 20 % stiffer, friction 30 % higher";

/// The second muscle: [`SECOND_MUSCLE`].
fn second_muscle() -> MuscleParams {
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
const CHARACTERISATION_MOVES: [(f64, f64); 10] = {
    let mut m = [(0.0, 0.0); 10];
    let mut i = 0;
    while i < 10 {
        m[i] = (PRESSURE_KNOTS_MPA[i + 1], RAMP_MPA_PER_S);
        i += 1;
    }
    m
};

// ---------------------------------------------------------------------------
// Output

fn arr(xs: &[f32]) -> String {
    let v: Vec<String> = xs.iter().map(|&x| f32_literal(x)).collect();
    format!("[{}]", v.join(", "))
}

fn main() {
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    let record = host_sim::to_record(
        "host_sim::characterisation_run(1)",
        &host_sim::characterisation_run(SEED),
    );
    let samples = &record.samples;
    let holdout = Holdout::EveryKthCycle(4);
    let split = split_branches(samples, &SplitConfig::default());
    let heldout = heldout_mask(holdout, &split.cycle);
    let n_test = heldout.iter().filter(|&&h| h).count();
    eprintln!(
        "{} samples, {} cycles, {} held out",
        samples.len(),
        split.cycles(),
        n_test
    );

    // pam-core: pam-lab's fit on the same split.
    let cfg = FitConfig {
        holdout,
        ..FitConfig::default()
    };
    let (params, pam_source) = match pam_lab::identify::fit::fit(&record, &cfg) {
        Ok(report) => {
            assert_eq!(report.heldout, heldout, "pam-lab held out the same samples");
            (
                report.params,
                "`pam_lab::identify::fit::fit` on the training cycles",
            )
        }
        Err(e) => {
            eprintln!("pam-lab fit failed ({e}); using Params::DEFAULT");
            (Params::DEFAULT, "`Params::DEFAULT` (pam-lab's fit failed)")
        }
    };
    let coeffs = Coeffs::new(params).expect("pam-lab returns valid parameters");
    let paper = paper_errors(&coeffs, samples, &heldout);

    // Non-local memory: shape chosen on the training samples.
    let (shape, memory) = MEMORY_SHAPES
        .iter()
        .map(|&sh| (sh, memory_errors(&coeffs, sh, samples, &heldout)))
        .min_by(|a, b| a.1.train_rms().total_cmp(&b.1.train_rms()))
        .expect("shapes");

    // Baselines.
    let pi = identify_pi(samples, &heldout);
    let pi_err = pi_errors(&pi, samples, &heldout);
    let (gpi, gpi_err) = GPI_MAX_THRESHOLDS_MPA
        .iter()
        .map(|&r| {
            let t = identify_gpi(samples, &heldout, r);
            let e = gpi_errors(&t, samples, &heldout);
            (t, e)
        })
        .min_by(|a, b| a.1.train_rms().total_cmp(&b.1.train_rms()))
        .expect("thresholds");
    let pr = identify_preisach(samples, &heldout);
    let pr_err = preisach_errors(&pr, samples, &heldout);

    // identified.rs
    let mut src = String::new();
    src.push_str(
        "//! @generated by `cargo run -p bench-m4 --features host --bin identify --release`\n\
         //! (bench-m4/src/bin/identify.rs): the models identified on\n\
         //! `host_sim::characterisation_run(1)`, training cycles only. Do not edit.\n\
         #![allow(clippy::all, clippy::pedantic)]\n\n\
         use crate::{GpiCoeffs, GpiTable, PiCoeffs, PiTable, PreisachCoeffs, PreisachTable};\n\
         use pam_core::{CriticalPoints, Params, Point};\n\n",
    );
    let _ = writeln!(
        src,
        "/// pam-core's parameters: {}.\npub const PAM_PARAMS: Params = {};\n",
        pam_source.replace('`', ""),
        params_literal(
            &params,
            ParamsLayout {
                type_prefix: "",
                inline_points: true,
            }
        )
    );
    let _ = writeln!(
        src,
        "/// Shape of the non-local memory (chosen on the training samples).\npub const MEMORY_SHAPE: f32 = {};\n",
        f32_literal(shape)
    );
    let _ = writeln!(
        src,
        "/// Prandtl–Ishlinskii, {N} play operators, at {L} loads.\npub const PI16: PiTable<{N}, {L}> = PiTable {{\n    thresholds_mpa: {},\n    min_load_n: {},\n    load_step_n: {},\n    grid: [",
        arr(&pi.thresholds_mpa),
        f32_literal(pi.min_load_n),
        f32_literal(pi.load_step_n)
    );
    for c in &pi.grid {
        let _ = writeln!(
            src,
            "        PiCoeffs {{\n            bias: {},\n            linear: {},\n            weights: {},\n        }},",
            f32_literal(c.bias),
            f32_literal(c.linear),
            arr(&c.weights)
        );
    }
    src.push_str("    ],\n};\n\n");
    let _ = writeln!(
        src,
        "/// Generalised Prandtl–Ishlinskii, {GPI_N} play operators and a cubic input nonlinearity, at {L} loads.\npub const GPI4: GpiTable<{GPI_N}, {L}> = GpiTable {{\n    thresholds_mpa: {},\n    min_load_n: {},\n    load_step_n: {},\n    grid: [",
        arr(&gpi.thresholds_mpa),
        f32_literal(gpi.min_load_n),
        f32_literal(gpi.load_step_n)
    );
    for c in &gpi.grid {
        let _ = writeln!(
            src,
            "        GpiCoeffs {{\n            bias: {},\n            cubic: {},\n            weights: {},\n        }},",
            f32_literal(c.bias),
            arr(&c.cubic),
            arr(&c.weights)
        );
    }
    src.push_str("    ],\n};\n\n");
    let _ = writeln!(
        src,
        "/// Preisach, {N} × {N} half-grid (row prefix sums), at {L} loads.\npub const PREISACH16: PreisachTable<{N}, {L}> = PreisachTable {{\n    lo_mpa: {},\n    step_mpa: {},\n    min_load_n: {},\n    load_step_n: {},\n    grid: [",
        f32_literal(pr.lo_mpa),
        f32_literal(pr.step_mpa),
        f32_literal(pr.min_load_n),
        f32_literal(pr.load_step_n)
    );
    for c in &pr.grid {
        let _ = writeln!(
            src,
            "        PreisachCoeffs {{\n            bias: {},\n            linear: {},\n            everett: [",
            f32_literal(c.bias),
            f32_literal(c.linear)
        );
        for row in &c.everett {
            let _ = writeln!(src, "                {},", arr(row));
        }
        src.push_str("            ],\n        },\n");
    }
    src.push_str("    ],\n};\n");
    std::fs::write(root.join("src/identified.rs"), src).expect("write identified.rs");

    // accuracy.md / accuracy.tsv
    let rows = [
        (
            "pam_core",
            "pam-core, paper model (tracker + inverse, pressure drive)",
            format!("{pam_source}; 8 parameters"),
            paper,
        ),
        (
            "pam_core_memory",
            "pam-core + non-local memory (`Simulator<16>`)",
            format!("same parameters; memory `shape` = {shape} chosen on the training cycles"),
            memory,
        ),
        (
            "pi16",
            "Prandtl–Ishlinskii, 16 play operators",
            format!("least squares per load; {} coefficients", L * (N + 2)),
            pi_err,
        ),
        (
            "gpi4",
            "generalised Prandtl–Ishlinskii, 4 plays + cubic input",
            format!(
                "least squares per load; {} coefficients; largest threshold {} MPa chosen on the training cycles",
                L * (GPI_N + 4),
                gpi.thresholds_mpa[GPI_N - 1]
            ),
            gpi_err,
        ),
        (
            "preisach16",
            "Preisach, 16 × 16 half-grid (136 relays)",
            format!(
                "least squares per load; {} coefficients",
                L * (N * (N + 1) / 2 + 2)
            ),
            pr_err,
        ),
    ];
    let intro = format!(
        "Held-out accuracy on `host_sim::characterisation_run({SEED})` ({} samples, 100–600 N; \
         every 4th pressure cycle held out: {} held-out samples, {} training samples). \
         Contraction error = predicted − measured, in % of rest length \
         (the measurement noise alone is about 0.03 %).",
        samples.len(),
        n_test,
        samples.len() - n_test
    );
    let table: Vec<Row> = rows
        .iter()
        .map(|(_, name, how, e)| (*name, how.clone(), *e))
        .collect();
    let mut md = table_md(&intro, &table);
    let mut tsv = String::from(
        "# model\theldout_rms\theldout_max\ttrain_rms (contraction, fraction; regenerate: bench-m4/run.sh)\n",
    );
    for (key, _, _, e) in &rows {
        let _ = writeln!(
            tsv,
            "{key}\t{:.6}\t{:.6}\t{:.6}",
            e.test_rms(),
            e.test_max,
            e.train_rms()
        );
    }
    for more in [
        held_out_loads(&record),
        other_protocol(samples, &heldout, params),
        other_muscle(),
    ] {
        md.push('\n');
        md.push_str(&more);
    }
    std::fs::write(root.join("accuracy.md"), &md).expect("write accuracy.md");
    std::fs::write(root.join("accuracy.tsv"), &tsv).expect("write accuracy.tsv");
    print!("{md}");
}
