//! Test rigs with one hidden effect each, writing measured-format CSV.
//!
//! The plants are built independently of `pam_core::effects`, so that a test
//! that names the effect is not circular:
//!
//! * the paper's branches come from an `f64` bisection of eqs. (21)–(26)
//!   written here (only the load family's cubic is taken from pam-core);
//! * `NonLocalMemory`: a Prandtl–Ishlinskii (Maxwell-slip) friction of
//!   [`PLAY_OPERATORS`] play operators with thresholds spread over
//!   `(0, 0.1]` MPa, whose normalised output `F ∈ [−1, 1]` replaces the
//!   branch sign: the muscle sits where `cubic(x) + F·be·ellipse(x) = p`.
//!   Its memory (wiping-out, congruent minor loops) comes from the play
//!   operators' states, not from a list of turning points, and a reversal
//!   crosses between the branches over `0.2` MPa of pressure instead of
//!   jumping: neither the paper's jump nor the effect model's blend of
//!   offsets between turning points;
//! * `Rate`: ellipse height `be0 + c·|ṗ|^0.7` from the plant's own rate
//!   (a viscous friction with a sub-linear law), not a linear factor;
//! * `Creep`: a chain of two Kelvin–Voigt elements (1.5 s and 6 s), not one
//!   first-order lag;
//! * `Width`: ellipse height `be0·(L/100 N)^1.3` (friction growing faster
//!   than the load), not linear in load;
//! * `None`: the paper's model with its jump to the other branch;
//! * `WidthAndCreep`, `MemoryAndRate`: two of the above at once;
//! * `TonduLopez`: a static curve outside the cubic family (the Tondu–Lopez
//!   force law, solved in closed form) with the memory plant's friction.
//!
//! The protocol follows the examples' README: at 100, 200 and 300 N, two full
//! cycles at 0.05 MPa/s, partial cycles reversing inside the loop, full cycles
//! at 0.02 and 0.2 MPa/s, pressure steps to three levels with 8 s holds; then
//! full cycles at random loads between 100 and 350 N (each of 100, 150, …,
//! 350 N at most once, in a random order). Sampled at 50 Hz with
//! 0.001 MPa pressure noise and 0.0008 contraction noise. A second protocol
//! ([`protocol_b`], [`csv_b`]) shares nothing with it but the noise: 100 Hz,
//! sinusoidal cycles, decaying oscillations, random reversals, steps, loads
//! 80–480 N.

#![allow(dead_code)]

use pam_core::{Branch, Coeffs, Params};

/// Which effect the rig has.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Plant {
    /// The paper's model only.
    None,
    /// Minor loops with non-local memory (a Prandtl–Ishlinskii friction).
    NonLocalMemory,
    /// Loop height grows with the pressure rate.
    Rate,
    /// Slow relaxation after steps.
    Creep,
    /// Loop height grows with load.
    Width,
    /// Two effects at once: the width plant's load law and the creep
    /// plant's two lags.
    WidthAndCreep,
    /// Two effects at once: the memory plant's friction, its height growing
    /// with the pressure rate as in the rate plant.
    MemoryAndRate,
    /// A muscle outside the cubic family: the Tondu–Lopez static law
    /// `F = p·S·(a·(1 − ε)² − b)` (a steep start, a saturating end) with
    /// the memory plant's Prandtl–Ishlinskii friction.
    TonduLopez,
}

impl Plant {
    /// Every plant.
    pub const ALL: [Plant; 8] = [
        Plant::None,
        Plant::NonLocalMemory,
        Plant::Rate,
        Plant::Creep,
        Plant::Width,
        Plant::WidthAndCreep,
        Plant::MemoryAndRate,
        Plant::TonduLopez,
    ];

    /// Every effect the rig has, by the names `pam-lab diagnose` gives them
    /// (empty: none).
    pub fn expected_effects(self) -> &'static [&'static str] {
        match self {
            Plant::None => &[],
            Plant::NonLocalMemory => &["non_local_memory"],
            Plant::Rate => &["rate_dependence"],
            Plant::Creep => &["creep"],
            Plant::Width => &["load_dependent_width"],
            Plant::WidthAndCreep => &["load_dependent_width", "creep"],
            Plant::MemoryAndRate => &["non_local_memory", "rate_dependence"],
            Plant::TonduLopez => &["constraint_shape", "non_local_memory"],
        }
    }

    /// The name `pam-lab diagnose` should give it.
    pub fn expected_name(self) -> &'static str {
        match self {
            Plant::None => "none",
            Plant::NonLocalMemory => "non_local_memory",
            Plant::Rate => "rate_dependence",
            Plant::Creep => "creep",
            Plant::Width => "load_dependent_width",
            Plant::WidthAndCreep => "load_dependent_width+creep",
            Plant::MemoryAndRate => "non_local_memory+rate_dependence",
            Plant::TonduLopez => "constraint_shape+non_local_memory",
        }
    }
}

const HZ: f64 = 50.0;

/// Play operators of the memory plant's Prandtl–Ishlinskii friction.
pub const PLAY_OPERATORS: usize = 24;
const DT: f64 = 1.0 / HZ;

/// SplitMix64 + Box–Muller: deterministic noise without a dependency.
struct Rng(u64);
impl Rng {
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }
    fn uniform(&mut self) -> f64 {
        (self.next() >> 11) as f64 / (1u64 << 53) as f64
    }
    fn normal(&mut self) -> f64 {
        let u1 = self.uniform().max(1e-300);
        let u2 = self.uniform();
        (-2.0 * u1.ln()).sqrt() * (2.0 * std::f64::consts::PI * u2).cos()
    }
}

/// The true (noise-free) drive: `(t_s, load_n, pressure_mpa)` at 50 Hz.
/// `short` keeps one full cycle per load, the 0.02 MPa/s cycle only at the
/// first load (for quick tests).
pub fn protocol(seed: u64, short: bool) -> Vec<(f64, f64, f64)> {
    let mut out = Vec::new();
    let mut p = 0.0f64;
    let mut rng = Rng(seed ^ 0x5EED);
    // Time is the sample count over 50 Hz.
    let ramp = |out: &mut Vec<(f64, f64, f64)>, p: &mut f64, load: f64, to: f64, rate: f64| {
        let n = ((to - *p).abs() / (rate * DT)).ceil().max(1.0) as usize;
        let from = *p;
        for k in 1..=n {
            *p = from + (to - from) * k as f64 / n as f64;
            out.push((out.len() as f64 * DT, load, *p));
        }
    };
    for (i, &load) in [100.0, 200.0, 300.0].iter().enumerate() {
        let cycles = if short { 1 } else { 2 };
        for _ in 0..cycles {
            ramp(&mut out, &mut p, load, 0.5, 0.05);
            ramp(&mut out, &mut p, load, 0.0, 0.05);
        }
        // Partial cycles reversing inside the loop.
        for to in [0.3, 0.15, 0.4, 0.25, 0.45, 0.1, 0.35, 0.0] {
            ramp(&mut out, &mut p, load, to, 0.05);
        }
        if !short || i == 0 {
            ramp(&mut out, &mut p, load, 0.5, 0.02);
            ramp(&mut out, &mut p, load, 0.0, 0.02);
        }
        ramp(&mut out, &mut p, load, 0.5, 0.2);
        ramp(&mut out, &mut p, load, 0.0, 0.2);
        // Steps with 8 s holds (a step is one sample long).
        for level in [0.25, 0.4, 0.1] {
            p = level;
            for _ in 0..(8.0 * HZ) as usize {
                out.push((out.len() as f64 * DT, load, p));
            }
        }
        ramp(&mut out, &mut p, load, 0.0, 0.05);
    }
    // Random loads as a balanced design: the six loads 100, 150, …, 350 N
    // in a random order, each once (Fisher–Yates), so that the held-out
    // blocks see loads other than the training blocks' midpoint.
    let mut loads: Vec<f64> = (0..6).map(|k| 100.0 + 50.0 * f64::from(k)).collect();
    for i in (1..loads.len()).rev() {
        let j = ((rng.uniform() * (i + 1) as f64) as usize).min(i);
        loads.swap(i, j);
    }
    for &load in &loads {
        ramp(&mut out, &mut p, load, 0.5, 0.05);
        ramp(&mut out, &mut p, load, 0.0, 0.05);
    }
    out
}

/// The paper's branches, eqs. (21)–(26), inverted in `f64` by bisection.
/// The branch itself is pam-core's (one model, one home); what each plant
/// adds to it (its effect) is this file's own.
struct Muscle {
    coeffs: Coeffs,
    pmax: f64,
}

impl Muscle {
    fn new(params: Params) -> Muscle {
        Muscle {
            coeffs: Coeffs::new(params).expect("plant parameters are valid"),
            pmax: f64::from(params.points.max_pressure_mpa),
        }
    }

    /// Contraction on a branch (`sign` +1 contraction, −1 expansion) at
    /// pressure `p` with ellipse height `be` at `load` (a negative `be`
    /// flips the branch; between `±be` lies between the branches).
    fn branch_x(&self, load: f64, p: f64, sign: f64, be: f64) -> f64 {
        let at = self.coeffs.load_cubic(load as f32);
        let (r, rx) = (at.cubic.root, at.max_contraction);
        // The offset on the contraction branch scaled to `sign·be`.
        let scale = sign * be / at.ellipse_height_mpa;
        let g = |x: f64| at.pressure_and_slope(x, Branch::Contraction, scale).0;
        let p = p.clamp(0.0, self.pmax);
        let (mut lo, mut hi) = (r, rx);
        for _ in 0..50 {
            let mid = 0.5 * (lo + hi);
            if g(mid) <= p {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        0.5 * (lo + hi)
    }
}

/// Contraction of a Tondu–Lopez muscle holding `load` N at the effective
/// pressure `q` MPa: the static law `load = q·S·(a·(1 − ε)² − b)` shifted so
/// that `ε = 0` at `q = 0` (a pre-stretched muscle), solved for `ε`
/// in closed form; `S` = 1500 N/MPa, `a` = 1.25, `b` = 0.75; plus a slack
/// of 0.01.
fn tondu_lopez_x(load: f64, q: f64) -> f64 {
    let (s, a, b) = (1500.0, 1.25, 0.75);
    let q = q.max(0.0);
    let g = 1.0 / (q * s / load.max(1.0) + 1.0 / (a - b));
    0.01 + 1.0 - ((b + g) / a).sqrt()
}

fn params_for(plant: Plant) -> Params {
    let mut p = Params::DEFAULT;
    // Steeper through the middle of the stroke than the default muscle (whose
    // flat stretch turns 0.001 MPa of noise into 0.015 of contraction), like
    // the examples' rigs.
    p.points.tangency.pressure_mpa = 0.17;
    p.points.inflection.pressure_mpa = 0.28;
    // Each rig's muscle differs a little.
    match plant {
        Plant::None => {}
        Plant::NonLocalMemory => {
            p.ellipse_height_mpa = 0.025;
            p.points.max_contraction = 0.26;
        }
        Plant::Rate => {
            p.points.root_contraction = 0.02;
        }
        Plant::Creep => {
            p.points.inflection.pressure_mpa = 0.27;
        }
        Plant::Width => {
            p.root_regression_per_step = 0.004;
        }
        Plant::WidthAndCreep => {
            p.root_regression_per_step = 0.003;
            p.points.inflection.pressure_mpa = 0.27;
        }
        Plant::MemoryAndRate => {
            p.points.max_contraction = 0.26;
        }
        Plant::TonduLopez => {}
    }
    p
}

/// True contraction of `plant` along `drive` (any sample rate: the time
/// steps are taken from the drive).
pub fn respond(plant: Plant, drive: &[(f64, f64, f64)]) -> Vec<f64> {
    respond_with(plant, params_for(plant), drive)
}

fn respond_with(plant: Plant, params: Params, drive: &[(f64, f64, f64)]) -> Vec<f64> {
    let m = Muscle::new(params);
    let be0 = f64::from(params.ellipse_height_mpa);
    let mut out = Vec::with_capacity(drive.len());
    let mut sign = 1.0f64;
    let mut last_p = drive.first().map_or(0.0, |d| d.2);
    // Memory plant: play operators, threshold `r_i = 0.1·i/N` MPa, equal
    // weights; each state starts at the first pressure (a relaxed muscle).
    let p0 = drive.first().map_or(0.0, |d| d.2);
    let thresholds: Vec<f64> = (1..=PLAY_OPERATORS)
        .map(|i| 0.1 * i as f64 / PLAY_OPERATORS as f64)
        .collect();
    let full_friction: f64 = thresholds.iter().sum();
    let mut plays: Vec<f64> = vec![p0; PLAY_OPERATORS];
    // Rate plant: the plant's own smoothed rate (0.1 s viscous time).
    let mut rate = 0.0f64;
    // Creep plant: two Kelvin–Voigt deficits and the previous static value.
    let mut deficits = [0.0f64; 2];
    let mut last_static: Option<f64> = None;
    let mut last_t = drive.first().map_or(0.0, |d| d.0 - DT);
    for &(t, load, p) in drive {
        let dt = (t - last_t).max(1e-6);
        last_t = t;
        let dp = p - last_p;
        if dp.abs() > 1e-12 {
            sign = dp.signum();
        }
        last_p = p;
        rate += (dp / dt - rate) * (dt / (0.1 + dt));
        let rate_be = (0.010 + 0.0926 * rate.abs().powf(0.7)).min(0.1);
        let mut friction = || {
            let mut f = 0.0;
            for (y, r) in plays.iter_mut().zip(&thresholds) {
                *y = y.clamp(p - r, p + r);
                f += p - *y;
            }
            f / full_friction
        };
        let width_be = 0.008 * (load / 100.0).powf(1.3);
        let x = match plant {
            Plant::None | Plant::Creep => m.branch_x(load, p, sign, be0),
            Plant::Width | Plant::WidthAndCreep => m.branch_x(load, p, sign, width_be),
            Plant::Rate => m.branch_x(load, p, sign, rate_be),
            Plant::NonLocalMemory => m.branch_x(load, p, 1.0, be0 * friction()),
            Plant::MemoryAndRate => m.branch_x(load, p, 1.0, 1.5 * rate_be * friction()),
            Plant::TonduLopez => tondu_lopez_x(load, p - 0.02 * friction()),
        };
        let x = if matches!(plant, Plant::Creep | Plant::WidthAndCreep) {
            let dx = last_static.map_or(0.0, |s| x - s);
            last_static = Some(x);
            let mut out_x = x;
            for (d, (a, tau)) in deficits.iter_mut().zip([(0.12, 1.5), (0.08, 6.0)]) {
                *d = (*d + a * dx) * (-dt / tau).exp();
                out_x -= *d;
            }
            out_x
        } else {
            x
        };
        out.push(x);
    }
    out
}

/// Measured-format CSV of `plant` along the protocol, with noise.
pub fn csv(plant: Plant, seed: u64, short: bool) -> String {
    let drive = protocol(seed, short);
    let x = respond(plant, &drive);
    to_csv(&drive, &x, seed, plant as u64)
}

/// [`csv`] of a muscle whose loop closes at `pmax_mpa`, above the
/// protocol's 0.5 MPa top: the record's top reversal lies inside the loop
/// (a rig run below its muscle's maximum operating pressure).
pub fn csv_below_pmax(plant: Plant, seed: u64, pmax_mpa: f64) -> String {
    let drive = protocol(seed, true);
    let mut params = params_for(plant);
    params.points.max_pressure_mpa = pmax_mpa as f32;
    let x = respond_with(plant, params, &drive);
    to_csv(&drive, &x, seed, plant as u64 ^ 0x50)
}

/// The second rig protocol, unlike the examples' in every respect the
/// diagnosis could lean on: sampled at 100 Hz; six load blocks at 80 N,
/// 480 N and four loads drawn between them (to 10 N), in a random order;
/// in each block one sinusoidal full cycle 0 → 0.5 → 0 MPa (period drawn
/// in 8–16 s, so the pressure turns smoothly at its peaks), a decaying
/// oscillation about 0.25 MPa (amplitude 0.24 → 0.03 over four 4 s
/// periods: nested minor loops), six ramps to random pressures at random
/// rates (0.02–0.2 MPa/s: random reversals), two steps to random levels
/// held 5 s, and a ramp back to 0.
pub fn protocol_b(seed: u64) -> Vec<(f64, f64, f64)> {
    const DT_B: f64 = 0.01;
    let mut out: Vec<(f64, f64, f64)> = Vec::new();
    let mut p = 0.0f64;
    let mut rng = Rng(seed ^ 0xB0B0);
    let push = |out: &mut Vec<(f64, f64, f64)>, load: f64, p: f64| {
        out.push((out.len() as f64 * DT_B, load, p));
    };
    let ramp = |out: &mut Vec<(f64, f64, f64)>, p: &mut f64, load: f64, to: f64, rate: f64| {
        let n = ((to - *p).abs() / (rate * DT_B)).ceil().max(1.0) as usize;
        let from = *p;
        for k in 1..=n {
            *p = from + (to - from) * k as f64 / n as f64;
            push(out, load, *p);
        }
    };
    let mut loads = vec![80.0, 480.0];
    for _ in 0..4 {
        loads.push((80.0 + 400.0 * rng.uniform()).round_to(10.0));
    }
    for i in (1..loads.len()).rev() {
        let j = ((rng.uniform() * (i + 1) as f64) as usize).min(i);
        loads.swap(i, j);
    }
    let two_pi = 2.0 * std::f64::consts::PI;
    for &load in &loads {
        ramp(&mut out, &mut p, load, 0.0, 0.1);
        // A sinusoidal full cycle.
        let period = 8.0 + 8.0 * rng.uniform();
        let n = (period / DT_B).round() as usize;
        for k in 1..=n {
            p = 0.25 * (1.0 - (two_pi * k as f64 / n as f64).cos());
            push(&mut out, load, p);
        }
        // A decaying oscillation about 0.25 MPa.
        ramp(&mut out, &mut p, load, 0.25, 0.05);
        let n = (16.0 / DT_B) as usize;
        let decay = (0.03f64 / 0.24).ln() / n as f64;
        for k in 1..=n {
            let a = 0.24 * (decay * k as f64).exp();
            p = 0.25 + a * (two_pi * k as f64 * DT_B / 4.0).sin();
            push(&mut out, load, p);
        }
        // Random reversals.
        for _ in 0..6 {
            let to = 0.02 + 0.46 * rng.uniform();
            let rate = 0.02 + 0.18 * rng.uniform();
            ramp(&mut out, &mut p, load, to, rate);
        }
        // Steps with holds.
        for _ in 0..2 {
            p = 0.05 + 0.4 * rng.uniform();
            for _ in 0..(5.0 / DT_B) as usize {
                push(&mut out, load, p);
            }
        }
        ramp(&mut out, &mut p, load, 0.0, 0.05);
    }
    out
}

trait RoundTo {
    fn round_to(self, step: f64) -> f64;
}

impl RoundTo for f64 {
    fn round_to(self, step: f64) -> f64 {
        (self / step).round() * step
    }
}

/// Measured-format CSV of `plant` along [`protocol_b`], with the same
/// sensor noise as [`csv`]; the muscle's calibrated loads reach down to
/// 50 N.
pub fn csv_b(plant: Plant, seed: u64) -> String {
    let drive = protocol_b(seed);
    let mut params = params_for(plant);
    params.min_load_n = 50.0;
    let x = respond_with(plant, params, &drive);
    to_csv(&drive, &x, seed, plant as u64 ^ 0xB)
}

fn to_csv(drive: &[(f64, f64, f64)], x: &[f64], seed: u64, salt: u64) -> String {
    let mut rng = Rng(seed.wrapping_mul(0x2545_F491_4F6C_DD1D) ^ salt);
    let mut s = String::from("t_s,load_n,pressure_mpa,contraction\n");
    for (&(t, load, p), x) in drive.iter().zip(x) {
        let pm = p + 0.001 * rng.normal();
        let xm = x + 0.0008 * rng.normal();
        s.push_str(&format!("{t:.3},{load:.1},{pm:.5},{xm:.5}\n"));
    }
    s
}
