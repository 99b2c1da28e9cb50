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
    PreisachTable,
};
use host_sim::characterisation::{
    isotonic_run_on, IsotonicProtocol, LOADS_N, PRESSURE_KNOTS_MPA, RAMP_MPA_PER_S,
};
use host_sim::plant::MuscleParams;
use host_sim::pneumatics::PneumaticParams;
use host_sim::Rig;
use pam_core::effects::{ConstraintShape, Effects, NonLocalMemory};
use pam_core::Simulator;
use pam_core::{Coeffs, Params, TrackerConfig};
use pam_lab::export::model_file::{
    constraint_shape_literal, f32_literal, params_literal, ParamsLayout,
};
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
/// Preisach pressure range, MPa: the characterisation run's highest
/// pressure (the top threshold, 0.01 + 16·0.03, is below it).
const PREISACH_MAX_MPA: f32 = 0.5;
/// Ridge on the relative scale of the normal equations' diagonal.
const RIDGE: f64 = 1e-6;
/// Candidate shapes of the non-local memory (chosen on training data, with
/// a merge span from [`MEMORY_MERGE_SPANS`]): `NonLocalMemory::shape`'s
/// range, 0.05–50, at about two per octave.
const MEMORY_SHAPES: [f32; 12] = [
    0.1, 0.25, 0.5, 0.75, 1.0, 1.5, 2.0, 3.0, 5.0, 10.0, 20.0, 50.0,
];
/// Candidate merge spans of the non-local memory, contraction (1: none).
const MEMORY_MERGE_SPANS: [f32; 5] = [0.005, 0.01, 0.02, 0.04, 1.0];

/// A non-local memory as a Rust expression.
fn memory_literal(m: &NonLocalMemory) -> String {
    format!(
        "NonLocalMemory {{\n    shape: {},\n    merge_span: {},\n}}",
        f32_literal(m.shape),
        f32_literal(m.merge_span)
    )
}

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

    // pam-core: pam-lab's fits on the same split.
    let pam = fitted(&record, holdout);
    let models = identify_models(samples, &heldout, &pam);
    let e = score(&models, samples, &heldout, None);
    let (shape, pi, gpi, pr) = (models.memory, &models.pi, &models.gpi, &models.preisach);

    // identified.rs
    let mut src = String::new();
    src.push_str(
        "//! @generated by `cargo run -p bench-m4 --features host --bin identify --release`\n\
         //! (bench-m4/src/bin/identify/): the models identified on\n\
         //! `host_sim::characterisation_run(1)`, training cycles only. Do not edit.\n\
         #![allow(clippy::all, clippy::pedantic)]\n\n\
         use crate::{GpiCoeffs, GpiTable, PiCoeffs, PiTable, PreisachCoeffs, PreisachTable};\n\
         use pam_core::effects::NonLocalMemory;\n         use pam_core::{CriticalPoints, Params, Point};\n\n",
    );
    let layout = ParamsLayout {
        type_prefix: "",
        inline_points: true,
    };
    let constants = [
        (
            "pam-core's paper model: pam_lab::identify::fit::fit with static_shape: false.",
            "PAM_PARAMS",
            "Params",
            params_literal(&pam.paper, layout),
        ),
        (
            "The non-local memory on the paper model (chosen on the training samples).",
            "MEMORY",
            "NonLocalMemory",
            memory_literal(&shape),
        ),
        (
            "The model pam-lab's fit writes: its parameters (pam_lab::identify::fit::fit as `pam-lab fit` runs it) ...",
            "PAM_FIT_PARAMS",
            "Params",
            params_literal(&pam.fit, layout),
        ),
        (
            "... and its static shape.",
            "PAM_FIT_SHAPE",
            "Option<pam_core::effects::ConstraintShape>",
            pam.shape.as_ref().map_or("None".to_string(), |c| {
                format!("Some({})", constraint_shape_literal(c))
            }),
        ),
        (
            "The non-local memory on fit's model (chosen on the training samples).",
            "FIT_MEMORY",
            "NonLocalMemory",
            memory_literal(&models.fit_memory),
        ),
    ];
    for (doc, name, ty, value) in constants {
        let _ = writeln!(src, "/// {doc}\npub const {name}: {ty} = {value};\n");
    }
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
        "/// Preisach, {N} × {N} half-grid (its discrete Everett function), at {L} loads.\npub const PREISACH16: PreisachTable<{N}, {L}> = PreisachTable {{\n    lo_mpa: {},\n    step_mpa: {},\n    max_pressure_mpa: {},\n    min_load_n: {},\n    load_step_n: {},\n    grid: [",
        f32_literal(pr.lo_mpa),
        f32_literal(pr.step_mpa),
        f32_literal(pr.max_pressure_mpa),
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
    let rows = rows(&models, &e);
    let intro = format!(
        "Held-out accuracy on `host_sim::characterisation_run({SEED})` ({} samples, 100–600 N; \
         every 4th pressure cycle held out: {} held-out samples, {} training samples). \
         Contraction error = predicted − measured, in % of rest length \
         (the measurement noise alone is about 0.03 %).",
        samples.len(),
        n_test,
        samples.len() - n_test
    );
    let [at_loads, on_sweep] = held_out_loads(&record);
    let comparisons = [
        Comparison::new("cycles", &intro, rows),
        at_loads,
        on_sweep,
        other_protocol(&models, samples, &heldout),
        other_muscle(),
    ];
    let mut md = String::new();
    let mut tsv = String::from(
        "# comparison\tmodel\theldout_rms\theldout_max\ttrain_rms (contraction, fraction; regenerate: bench-m4/run.sh)\n",
    );
    for c in &comparisons {
        if !md.is_empty() {
            md.push('\n');
        }
        md.push_str(&c.md);
        for (key, _, _, e) in &c.rows {
            let _ = writeln!(
                tsv,
                "{}\t{key}\t{:.6}\t{:.6}\t{:.6}",
                c.key,
                e.test_rms(),
                e.test_max,
                e.train_rms()
            );
        }
    }
    std::fs::write(root.join("accuracy.md"), &md).expect("write accuracy.md");
    std::fs::write(root.join("accuracy.tsv"), &tsv).expect("write accuracy.tsv");
    print!("{md}");
}
