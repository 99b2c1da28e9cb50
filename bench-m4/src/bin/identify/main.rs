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

mod baselines;
mod comparisons;
mod errors;
mod models;

use baselines::*;
use comparisons::*;
use errors::*;
use models::*;

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
/// Candidate shapes of the non-local memory (chosen on training data).
const MEMORY_SHAPES: [f32; 8] = [0.25, 0.5, 0.75, 1.0, 1.5, 2.0, 3.0, 5.0];

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
    let models = identify_models(samples, &heldout, params);
    let e = score(&models, samples, &heldout, None);
    let (shape, pi, gpi, pr) = (
        models.memory_shape,
        &models.pi,
        &models.gpi,
        &models.preisach,
    );

    // identified.rs
    let mut src = String::new();
    src.push_str(
        "//! @generated by `cargo run -p bench-m4 --features host --bin identify --release`\n\
         //! (bench-m4/src/bin/identify/): the models identified on\n\
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
            e.paper,
        ),
        (
            "pam_core_memory",
            "pam-core + non-local memory (`Simulator<16>`)",
            format!("same parameters; memory `shape` = {shape} chosen on the training cycles"),
            e.memory,
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
                gpi.thresholds_mpa[GPI_N - 1]
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
        other_protocol(&models, samples, &heldout),
        other_muscle(),
    ] {
        md.push('\n');
        md.push_str(&more);
    }
    std::fs::write(root.join("accuracy.md"), &md).expect("write accuracy.md");
    std::fs::write(root.join("accuracy.tsv"), &tsv).expect("write accuracy.tsv");
    print!("{md}");
}
