//! The hysteresis model at one load, eqs. (25)–(26), on the per-sample `f32`
//! path: the constraint model (eq. 21) plus (contraction branch) or minus
//! (expansion branch) the ellipse offset of eqs. (22)–(24)
//! ([`crate::ellipse`]), with forward and inverse evaluation.
//!
//! # Clamps (all documented, none fails)
//! * Contraction outside `[R_i, Rx_i]` is clamped to it; NaN maps to `R_i`.
//! * Pressure out of the forward evaluation is clamped to `[0, Pmax]`: near
//!   `R_i` the ellipse's vertical tangent pulls the expansion branch below zero
//!   (a muscle cannot hold negative gauge pressure), and near `Rx_i` it pushes
//!   the contraction branch above `Pmax` (the supply cannot give more).
//! * Pressure into the inverse is clamped to `[0, Pmax]`; NaN maps to 0.
//!
//! # Inverse at the branch ends
//! Clamped as above, each branch is continuous but not strictly monotone at
//! its ends: the expansion branch is flat at 0 from `R_i` to where it crosses
//! zero, the contraction branch reaches `Pmax` before `Rx_i`. The inverse works
//! on the branch's monotone hull (its running maximum from `R_i`) and returns
//! the *largest* contraction whose hull pressure does not exceed the pressure
//! asked for. So `contraction(Pmax, ·)` is `Rx_i`, `contraction(0, Expansion)`
//! is where the expansion branch leaves zero (the dip is about
//! `2·be²/(ae·CM'(R)²)`: 4.9·10⁻⁴ of contraction at 100 N and 3.4·10⁻⁴ at
//! 600 N for the default muscle), and where a branch is strictly increasing
//! `pressure_mpa(contraction(p)) = p` within [`INVERSE_TOLERANCE_MPA`], up to
//! and including `Pmax`.
//!
//! The exact inverse is non-decreasing in pressure. The evaluated one is
//! piecewise (one table interval, one Newton step each) and may step back at
//! a table node by a few `f32` rounding errors of the Newton step: at most
//! [`INVERSE_STEP_BACK`] of contraction (1.0·10⁻⁵ measured on 2·10⁶-point
//! pressure grids at 100–600 N; checked by a unit test).
//!
//! # Cost
//! Building a model solves the inverse precisely at
//! [`INVERSE_INTERVALS`]` + 1` pressures per branch (at most
//! [`BUILD_UNITS_MAX`] work units of a few dozen `f32` operations each). At
//! start-up that happens at once; after a load switch [`crate::Tracker`] can
//! spread it over several control periods, during which the new model
//! evaluates forward at full speed and its inverse falls back to a slower
//! table-free solve ([`LoadModel::inverse_ready`]). Per sample, the inverse is one
//! table look-up indexed directly by pressure (no search), a linear
//! interpolation and one Newton step kept inside the table interval: fixed
//! work, two divisions and one square root.

use crate::branch::Branch;
use crate::load_family::LoadCubic;
use crate::math::{clamp, sqrt};

/// The constraint model and the ellipse offset at one contraction, with
/// their slopes ([`LoadModel::branch_parts`]): the branch with the offset
/// times `k` is `cubic + k·offset`, its slope `cubic_slope + k·offset_slope`
/// (evaluated in that order, bit for bit [`LoadModel::branch_and_slope`]).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(crate) struct BranchParts {
    /// `CM(x)`, eq. (21).
    pub cubic: f32,
    /// `y_hys(x)`, eq. (24) (0 outside the ellipse).
    pub offset: f32,
    /// `CM'(x)`.
    pub cubic_slope: f32,
    /// `y_hys'(x)` (0 outside the ellipse).
    pub offset_slope: f32,
}

impl BranchParts {
    /// Branch pressure and slope with the offset times `k`.
    #[inline(always)]
    pub(crate) fn at(&self, k: f32) -> (f32, f32) {
        (
            self.cubic + k * self.offset,
            self.cubic_slope + k * self.offset_slope,
        )
    }
}

/// Intervals of the inverse table per branch, uniform in pressure over
/// `[0, Pmax]`.
pub const INVERSE_INTERVALS: usize = 64;

/// Contraction knots of the forward hull used while building the inverse table.
const BUILD_KNOTS: usize = 33;

/// Safeguarded Newton iterations per table entry while building.
const BUILD_ITERATIONS: usize = 12;

/// Bisection steps of the inverse while the tables are being built
/// ([`LoadModel::inverse_ready`]): a stroke of 0.2 over 2¹² is 5·10⁻⁵.
pub const FALLBACK_BISECTION_STEPS: usize = 12;

/// A Newton step of the table build that moves contraction by less than
/// this ends the entry (a few `f32` ulps of a contraction near 0.1; the
/// table is then as precise as `f32` allows).
const BUILD_CONVERGED: f32 = 1e-7;

/// Work units a complete build of a load's inverse tables can take at most:
/// per branch one per hull knot, and per table entry one for the bracket
/// and up to a fixed number of Newton steps.
pub const BUILD_UNITS_MAX: usize =
    2 * (BUILD_KNOTS + (INVERSE_INTERVALS + 1) * (1 + BUILD_ITERATIONS));

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Stage {
    Hull,
    Bracket,
    Solve,
    Done,
}

/// Progress of the inverse tables' construction, resumable so that it can
/// be spread over several control periods ([`crate::Tracker`] builds the
/// next load's tables while the active model keeps running). One work unit
/// is one forward evaluation, one table bracket or one Newton step: at most
/// a few dozen `f32` operations, one division and one square root.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct TableBuild {
    stage: Stage,
    branch: Branch,
    /// The branch's monotone hull on the knots.
    hull: [f32; BUILD_KNOTS],
    running: f32,
    /// Hull knot (stage `Hull`), then the bracket cursor.
    j: usize,
    /// Table entry being solved.
    k: usize,
    p: f32,
    lo: f32,
    hi: f32,
    x: f32,
    iteration: u8,
}

impl TableBuild {
    pub(crate) fn new() -> TableBuild {
        TableBuild {
            stage: Stage::Hull,
            branch: Branch::Contraction,
            hull: [0.0; BUILD_KNOTS],
            running: 0.0,
            j: 0,
            k: 0,
            p: 0.0,
            lo: 0.0,
            hi: 0.0,
            x: 0.0,
            iteration: 0,
        }
    }

    /// [`Self::new`] in place, without clearing the hull: the build writes
    /// every hull knot before it reads one (stage `Hull`), so only the
    /// cursor needs resetting (a load switch then costs no 33-float clear
    /// and copy).
    pub(crate) fn restart(&mut self) {
        self.stage = Stage::Hull;
        self.branch = Branch::Contraction;
        self.running = 0.0;
        self.j = 0;
        self.k = 0;
        self.p = 0.0;
        self.lo = 0.0;
        self.hi = 0.0;
        self.x = 0.0;
        self.iteration = 0;
    }
}

/// A [`LoadModel`]'s coefficients, without its tables.
#[derive(Clone, Copy, Debug)]
struct ModelCoefficients {
    load_n: f32,
    root: f32,
    max_contraction: f32,
    /// `a_i`, `b`, `c_i` of eq. (21).
    abc: [f32; 3],
    height_mpa: f32,
    centre: f32,
    ellipse_k2: f32,
    max_pressure_mpa: f32,
}

/// The load family (eqs. 16–19) in `f32`, for building a [`LoadModel`] at
/// any load on the chip without soft-float `f64`: made once from the
/// validated `f64` [`LoadFamily`](crate::LoadFamily).
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub(crate) struct FamilyF32 {
    min_load_n: f32,
    max_load_n: f32,
    steps_per_n: f32,
    root: f32,
    max_contraction: f32,
    b: f32,
    c: f32,
    root_regression_per_step: f32,
    max_regression_per_step: f32,
    c_growth_per_step: f32,
    height_mpa: f32,
    max_pressure_mpa: f32,
}

impl FamilyF32 {
    pub(crate) fn new(f: &crate::LoadFamily) -> FamilyF32 {
        FamilyF32 {
            min_load_n: f.min_load_n as f32,
            max_load_n: f.max_load_n as f32,
            steps_per_n: (1.0 / f.load_step_n) as f32,
            root: f.root_contraction as f32,
            max_contraction: f.max_contraction as f32,
            b: f.b as f32,
            c: f.c as f32,
            root_regression_per_step: f.root_regression_per_step as f32,
            max_regression_per_step: f.max_regression_per_step as f32,
            c_growth_per_step: f.c_growth_per_step as f32,
            height_mpa: f.ellipse_height_mpa as f32,
            max_pressure_mpa: f.max_pressure_mpa as f32,
        }
    }

    /// The model at `load_n` (clamped to the calibrated range, NaN → the
    /// minimum load) without its inverse tables, eqs. (16)–(21) and (24):
    /// fixed work, four divisions.
    pub(crate) fn model_without_tables(&self, load_n: f32) -> LoadModel {
        let c = self.coefficients(load_n);
        LoadModel::from_coefficients(c)
    }

    /// [`Self::model_without_tables`] written into `model`, whose inverse
    /// tables are left as they are and marked not ready: a table build
    /// writes every entry before [`LoadModel::inverse_ready`] is true again
    /// and reads none, so a load switch does not clear and copy the two
    /// tables (130 `f32`) the build overwrites.
    pub(crate) fn set_model_without_tables(&self, model: &mut LoadModel, load_n: f32) {
        let c = self.coefficients(load_n);
        model.set_coefficients(c);
    }

    /// The model's coefficients at `load_n` (clamped to the calibrated
    /// range).
    #[inline(always)]
    fn coefficients(&self, load_n: f32) -> ModelCoefficients {
        let load_n = clamp(load_n, self.min_load_n, self.max_load_n);
        let s = (load_n - self.min_load_n) * self.steps_per_n;
        // eqs. (17), (18), (19)
        let root = self.root - self.root_regression_per_step * s;
        let rx = self.max_contraction - self.max_regression_per_step * s;
        let c = self.c + self.c_growth_per_step * s;
        let (b, pmax) = (self.b, self.max_pressure_mpa);
        // eq. (16): the amplitude that puts CM_i(Rx_i) = Pmax.
        let a = ((pmax + c * root) / (rx * rx) - (c + b * root) / rx + b) / (rx - root);
        // eq. (24): ae_i = (Rx_i − R_i)/2, centre R_i + ae_i (corrected).
        let half_width = 0.5 * (rx - root);
        let k = self.height_mpa / half_width;
        ModelCoefficients {
            load_n,
            root,
            max_contraction: rx,
            abc: [a, b, c],
            height_mpa: self.height_mpa,
            centre: root + half_width,
            ellipse_k2: k * k,
            max_pressure_mpa: pmax,
        }
    }

    /// Whether the model this builds at `load_n` has finite coefficients
    /// and a non-empty stroke in `f32` (the `f64` family can hold values
    /// whose `f32` evaluation overflows: fuzz `effects` found a calibrated
    /// range up to 1.9·10³¹ N whose model was NaN on the chip's path).
    pub(crate) fn model_is_finite(&self, load_n: f32) -> bool {
        let m = self.model_without_tables(load_n);
        [
            m.root,
            m.max_contraction,
            m.a,
            m.b,
            m.c,
            m.centre,
            m.ellipse_k2,
        ]
        .iter()
        .all(|v| v.is_finite())
            && m.max_contraction > m.root
    }

    /// The complete model at `load_n` (clamped), tables built at once.
    pub(crate) fn model(&self, load_n: f32) -> LoadModel {
        let mut m = self.model_without_tables(load_n);
        m.build_tables();
        m
    }
}

/// Bound on `|pressure_mpa(contraction(p, br), br) − p|` on the strictly
/// increasing part of a branch, MPa; checked by the unit and property tests.
pub const INVERSE_TOLERANCE_MPA: f32 = 2e-4;

/// Bound on how far [`LoadModel::contraction`] can step back (decrease) as the
/// pressure rises across a table node, in contraction; checked by the tests.
pub const INVERSE_STEP_BACK: f32 = 2e-5;

/// The hysteresis model at one load, ready for per-sample evaluation.
///
/// Built by [`crate::Coeffs::load_model`]; holds `f32` coefficients and the inverse
/// tables (about 560 bytes), no references.
#[derive(Clone, Debug, PartialEq)]
pub struct LoadModel {
    load_n: f32,
    /// `R_i`.
    root: f32,
    /// `Rx_i`.
    max_contraction: f32,
    /// `a_i`, `b`, `c_i` of eq. (21).
    a: f32,
    b: f32,
    c: f32,
    /// `be` of eq. (24), MPa.
    height_mpa: f32,
    /// `h_i` of eq. (24).
    centre: f32,
    /// `(be/ae_i)²`, MPa² (`ae_i` of eq. 24): the ellipse in the form
    /// `y_hys = √((be/ae_i)²·(x − R_i)(Rx_i − x))`, eq. (24) with
    /// `ae_i² − (x − h_i)² = (x − R_i)(Rx_i − x)`.
    ellipse_k2: f32,
    max_pressure_mpa: f32,
    /// `INVERSE_INTERVALS / Pmax`: table index per MPa.
    intervals_per_mpa: f32,
    /// Contraction at pressures `k·Pmax/INVERSE_INTERVALS` on each branch,
    /// `[contraction, expansion]`; the last entry is the left limit at `Pmax`.
    inverse_table: [[f32; INVERSE_INTERVALS + 1]; 2],
    /// Both inverse tables are complete (else [`Self::contraction`] solves
    /// by bisection, see [`Self::inverse_ready`]).
    tables_ready: bool,
}

impl LoadModel {
    /// The `f32` model of `at` with its inverse tables (the load family's
    /// `f64` construction rounded once): the host path.
    pub(crate) fn new(at: &LoadCubic) -> LoadModel {
        let ellipse = at.ellipse();
        let mut model = LoadModel::from_coefficients(ModelCoefficients {
            load_n: at.load_n as f32,
            root: at.cubic.root as f32,
            max_contraction: at.max_contraction as f32,
            abc: [at.cubic.a as f32, at.cubic.b as f32, at.cubic.c as f32],
            height_mpa: at.ellipse_height_mpa as f32,
            // eq. (24), centre corrected to R_i + ae_i (see `Ellipse::centre`).
            centre: ellipse.centre() as f32,
            ellipse_k2: ellipse.k2() as f32,
            max_pressure_mpa: at.max_pressure_mpa as f32,
        });
        model.build_tables();
        model
    }

    /// The model without its inverse tables (all entries `R_i`): the start
    /// of a [`TableBuild`].
    fn from_coefficients(c: ModelCoefficients) -> LoadModel {
        let mut model = LoadModel {
            load_n: 0.0,
            root: c.root,
            max_contraction: 0.0,
            a: 0.0,
            b: 0.0,
            c: 0.0,
            height_mpa: 0.0,
            centre: 0.0,
            ellipse_k2: 0.0,
            max_pressure_mpa: 0.0,
            intervals_per_mpa: 0.0,
            inverse_table: [[c.root; INVERSE_INTERVALS + 1]; 2],
            tables_ready: false,
        };
        model.set_coefficients(c);
        model
    }

    /// The coefficients of `c`, the inverse tables marked not ready (their
    /// entries left as they are: a [`TableBuild`] overwrites every one
    /// before they are used).
    #[inline(always)]
    fn set_coefficients(&mut self, c: ModelCoefficients) {
        let [a, b, cc] = c.abc;
        self.load_n = c.load_n;
        self.root = c.root;
        self.max_contraction = c.max_contraction;
        self.a = a;
        self.b = b;
        self.c = cc;
        self.height_mpa = c.height_mpa;
        self.centre = c.centre;
        self.ellipse_k2 = c.ellipse_k2;
        self.max_pressure_mpa = c.max_pressure_mpa;
        self.intervals_per_mpa = INVERSE_INTERVALS as f32 / c.max_pressure_mpa;
        self.tables_ready = false;
    }

    /// Both inverse tables at once (construction on the host or at boot).
    fn build_tables(&mut self) {
        let mut build = TableBuild::new();
        while !self.advance_build(&mut build, u16::MAX) {}
    }

    /// Advance an inverse-table build of this model by at most `units` work
    /// units (one forward evaluation or one Newton step each, see
    /// [`TableBuild`]); `true` once both tables are complete.
    pub(crate) fn advance_build(&mut self, build: &mut TableBuild, units: u16) -> bool {
        for _ in 0..units {
            if self.build_unit(build) {
                return true;
            }
        }
        build.stage == Stage::Done
    }

    /// Contraction of hull knot `j` (the last knot is exactly `Rx_i`).
    #[inline(always)]
    fn knot(&self, j: usize) -> f32 {
        if j + 1 >= BUILD_KNOTS {
            self.max_contraction
        } else {
            self.root + (self.max_contraction - self.root) / (BUILD_KNOTS - 1) as f32 * j as f32
        }
    }

    /// One work unit of the table build; `true` when the build is done.
    ///
    /// The table of a branch: the branch's monotone hull (running maximum)
    /// on [`BUILD_KNOTS`] contraction knots, one knot per unit; then per
    /// entry `k` (pressure `k·Pmax/INVERSE_INTERVALS`), the bracket from the
    /// hull, `sup{x : hull(x) <= p_k}` (the last entry: the left limit at
    /// the hull's top, `inf{x : hull(x) >= top}`), one unit, then a
    /// bracketed Newton iteration with bisection fallback per unit, at most
    /// [`BUILD_ITERATIONS`], stopping once a step moves less than
    /// [`BUILD_CONVERGED`].
    fn build_unit(&mut self, b: &mut TableBuild) -> bool {
        match b.stage {
            Stage::Done => return true,
            Stage::Hull => {
                let p = self.pressure_mpa(self.knot(b.j), b.branch);
                b.running = if p > b.running { p } else { b.running };
                if let Some(h) = b.hull.get_mut(b.j) {
                    *h = b.running;
                }
                b.j += 1;
                if b.j >= BUILD_KNOTS {
                    b.stage = Stage::Bracket;
                    b.k = 0;
                    b.j = 0;
                }
            }
            Stage::Bracket => {
                let last = b.k >= INVERSE_INTERVALS;
                let top = b.running;
                let (p, j) = if last {
                    let j = b
                        .hull
                        .iter()
                        .position(|&h| h >= top)
                        .unwrap_or(BUILD_KNOTS - 1);
                    (top, j)
                } else {
                    let p = self.max_pressure_mpa * b.k as f32 / INVERSE_INTERVALS as f32;
                    // The largest j with hull[j] <= p (or 0): p grows with k
                    // and the hull is non-decreasing, so the cursor only
                    // moves forward. The crossing lies in [j, j + 1].
                    while b.hull.get(b.j + 1).is_some_and(|&h| h <= p) {
                        b.j += 1;
                    }
                    (p, b.j + 1)
                };
                if j == 0 {
                    self.finish_entry(b, self.root);
                } else if j >= BUILD_KNOTS {
                    self.finish_entry(b, self.max_contraction);
                } else {
                    b.p = p;
                    b.lo = self.knot(j - 1);
                    b.hi = self.knot(j);
                    b.x = 0.5 * (b.lo + b.hi);
                    b.iteration = 0;
                    b.stage = Stage::Solve;
                }
            }
            Stage::Solve => {
                // Bracketed Newton with bisection fallback for branch(x) = p
                // in [lo, hi], where branch(lo) <= p and branch(hi) > p (or
                // >= p for the last entry, the left-limit case).
                let upper = b.k >= INVERSE_INTERVALS;
                let (g, dg) = self.branch_and_slope(b.x, b.branch.offset_sign());
                let below = if upper { g < b.p } else { g <= b.p };
                if below {
                    b.lo = b.x;
                } else {
                    b.hi = b.x;
                }
                let next = b.x + (b.p - g) / dg;
                let next = if next > b.lo && next < b.hi {
                    next
                } else {
                    0.5 * (b.lo + b.hi)
                };
                let moved = (next - b.x).abs();
                b.x = next;
                b.iteration += 1;
                if upper {
                    if usize::from(b.iteration) >= BUILD_ITERATIONS {
                        self.finish_entry(b, b.hi);
                    }
                } else if usize::from(b.iteration) >= BUILD_ITERATIONS || moved <= BUILD_CONVERGED {
                    self.finish_entry(b, b.x);
                }
            }
        }
        b.stage == Stage::Done
    }

    /// Store entry `k` of the table being built and move on.
    fn finish_entry(&mut self, b: &mut TableBuild, x: f32) {
        let table = match b.branch {
            Branch::Contraction => &mut self.inverse_table[0],
            Branch::Expansion => &mut self.inverse_table[1],
        };
        if let Some(slot) = table.get_mut(b.k) {
            *slot = x;
        }
        b.k += 1;
        b.stage = if b.k <= INVERSE_INTERVALS {
            Stage::Bracket
        } else if b.branch == Branch::Contraction {
            *b = TableBuild {
                branch: Branch::Expansion,
                ..TableBuild::new()
            };
            Stage::Hull
        } else {
            self.tables_ready = true;
            Stage::Done
        };
    }

    /// The load this model is for, N.
    pub fn load_n(&self) -> f32 {
        self.load_n
    }

    /// `R_i`: contraction at zero pressure on the constraint model.
    pub fn root_contraction(&self) -> f32 {
        self.root
    }

    /// `Rx_i`: contraction at `Pmax`.
    pub fn max_contraction(&self) -> f32 {
        self.max_contraction
    }

    /// `Pmax`, MPa.
    pub fn max_pressure_mpa(&self) -> f32 {
        self.max_pressure_mpa
    }

    /// `be`, the ellipse height, MPa.
    pub fn ellipse_height_mpa(&self) -> f32 {
        self.height_mpa
    }

    /// Constraint model `CM_ij = (x_j − R_i)(a_i x_j² − b x_j + c_i)`, eq. (21),
    /// with `x` clamped to `[R_i, Rx_i]` (NaN → `R_i`).
    #[inline]
    pub fn constraint_pressure_mpa(&self, contraction: f32) -> f32 {
        let x = clamp(contraction, self.root, self.max_contraction);
        self.cubic(x)
    }

    #[inline(always)]
    fn cubic(&self, x: f32) -> f32 {
        (x - self.root) * ((self.a * x - self.b) * x + self.c)
    }

    /// Ellipse offset `y_hys = k + be·√(1 − (x − h)²/ae²)` with `k = 0`,
    /// eqs. (23)–(24); zero outside `[R_i, Rx_i]`.
    #[inline]
    pub fn offset_mpa(&self, contraction: f32) -> f32 {
        let w = self.radicand(contraction);
        // Outside the ellipse (and for NaN) the radicand is not positive: no offset.
        if w > 0.0 {
            sqrt(w)
        } else {
            0.0
        }
    }

    /// `be²·(1 − (x − h)²/ae²) = (be/ae)²·(x − R_i)(Rx_i − x)`, the square of
    /// the ellipse offset, eq. (24). In this form it is exactly zero at both
    /// stroke ends and positive exactly for `R_i < x < Rx_i` (when `be > 0`);
    /// not positive outside, and NaN for NaN.
    #[inline(always)]
    fn radicand(&self, x: f32) -> f32 {
        self.ellipse_k2 * ((x - self.root) * (self.max_contraction - x))
    }

    /// Forward model, eqs. (25) and (26): the pressure that holds `contraction`
    /// on `branch`, `HMC = CM + y_hys`, `HME = CM − y_hys` (the paper prints
    /// `HMC` for both). Clamped as the module docs say; never NaN.
    #[inline]
    pub fn pressure_mpa(&self, contraction: f32, branch: Branch) -> f32 {
        let w = self.radicand(contraction);
        let p = if w > 0.0 {
            // A positive radicand means R_i < x < Rx_i (see `radicand`): the
            // contraction clamp would not change x, so it is skipped. Finite.
            self.cubic(contraction) + branch.offset_sign() * sqrt(w)
        } else {
            // Outside the ellipse (or NaN, or `be = 0`): no offset, and the
            // contraction clamped to the stroke as documented.
            self.cubic(clamp(contraction, self.root, self.max_contraction))
        };
        clamp(p, 0.0, self.max_pressure_mpa)
    }

    /// `CM(x) + k·y_hys(x)` for `x` in `[R_i, Rx_i]` (the caller's
    /// guarantee), without the clamps and the radicand's test of
    /// [`Self::constraint_pressure_mpa`] and [`Self::offset_mpa`]: inside
    /// the stroke the contraction clamp is the identity and the radicand is
    /// not negative (`(be/ae)²` times two factors `>= 0`; where it is 0 the
    /// offset is 0 either way), so for such `x` this is
    /// `constraint_pressure_mpa(x) + k·offset_mpa(x)` bit for bit. The
    /// bisections' step (`k` = ±1: the branch; else the scaled offset).
    #[inline(always)]
    pub(crate) fn branch_in_stroke(&self, x: f32, k: f32) -> f32 {
        self.cubic(x) + k * sqrt(self.radicand(x))
    }

    /// Unclamped branch pressure and its slope with respect to contraction.
    pub(crate) fn branch_and_slope(&self, x: f32, sign: f32) -> (f32, f32) {
        let q = (self.a * x - self.b) * x + self.c;
        let dq = 2.0 * self.a * x - self.b;
        let w = self.radicand(x);
        let (y, dy) = if w > 0.0 {
            let y = sqrt(w);
            // d/dx √(k²(x − R)(Rx − x)) = k²(h − x)/√(…), h = (R + Rx)/2.
            (y, self.ellipse_k2 * (self.centre - x) / y)
        } else {
            (0.0, 0.0)
        };
        (
            (x - self.root) * q + sign * y,
            q + (x - self.root) * dq + sign * dy,
        )
    }

    /// The parts of [`Self::branch_and_slope`] at `x` that do not depend
    /// on the factor on the offset, the same operations in the same order
    /// (`BranchParts::at` is it bit for bit; the test
    /// `branch_parts_are_branch_and_slope_bit_for_bit`): a caller that
    /// evaluates one contraction at several factors (a remembered reversal
    /// moved to each period's offset scale) computes them once.
    pub(crate) fn branch_parts(&self, x: f32) -> BranchParts {
        let q = (self.a * x - self.b) * x + self.c;
        let dq = 2.0 * self.a * x - self.b;
        let w = self.radicand(x);
        let (y, dy) = if w > 0.0 {
            let y = sqrt(w);
            // d/dx √(k²(x − R)(Rx − x)) = k²(h − x)/√(…), h = (R + Rx)/2.
            (y, self.ellipse_k2 * (self.centre - x) / y)
        } else {
            (0.0, 0.0)
        };
        BranchParts {
            cubic: (x - self.root) * q,
            offset: y,
            cubic_slope: q + (x - self.root) * dq,
            offset_slope: dy,
        }
    }

    /// Where the expansion branch with the offset scaled by `offset_scale`
    /// (`CM(x) − scale·y_hys(x)`, eq. 26) crosses 0 MPa, estimated from the
    /// branch's leading terms at `R_i`: `CM(x) ≈ q(R_i)·(x − R_i)` and
    /// `y_hys(x) ≈ √(k²(Rx_i − R_i)(x − R_i))` put it at
    /// `R_i + scale²·k²(Rx_i − R_i)/q(R_i)²`, within the stroke. Where a
    /// Newton iteration for that crossing starts without the inverse tables
    /// (below it the branch's slope is not positive: a step from elsewhere
    /// does not reach it). Never NaN for a validated model.
    pub(crate) fn zero_pressure_expansion_estimate(&self, offset_scale: f32) -> f32 {
        let q = (self.a * self.root - self.b) * self.root + self.c;
        let u = offset_scale * offset_scale * self.ellipse_k2 * (self.max_contraction - self.root)
            / (q * q);
        let x = self.root + u;
        if x >= self.root && x <= self.max_contraction {
            x
        } else {
            0.5 * (self.root + self.max_contraction)
        }
    }

    /// Whether the inverse tables are complete. A model whose tables a
    /// [`crate::Tracker`] is still building (after a load switch with a
    /// build budget) evaluates forward at full speed, but its
    /// [`Self::contraction`] falls back to [`FALLBACK_BISECTION_STEPS`]
    /// bisection steps on the forward model (about six times the table
    /// inverse's cost).
    pub fn inverse_ready(&self) -> bool {
        self.tables_ready
    }

    /// The inverse without tables: the largest contraction of the stroke at
    /// which the (clamped) branch pressure does not exceed `pressure_mpa`
    /// (clamped to `[0, Pmax]`, NaN → 0), by [`FALLBACK_BISECTION_STEPS`]
    /// bisection steps on the forward model. Where the branch increases this
    /// is the table inverse's answer to the bisection's resolution.
    #[inline(never)]
    fn contraction_without_tables(&self, pressure_mpa: f32, branch: Branch) -> f32 {
        let p = clamp(pressure_mpa, 0.0, self.max_pressure_mpa);
        if p >= self.max_pressure_mpa {
            return self.max_contraction;
        }
        let sign = branch.offset_sign();
        let (mut lo, mut hi) = (self.root, self.max_contraction);
        for _ in 0..FALLBACK_BISECTION_STEPS {
            let mid = 0.5 * (lo + hi);
            // `pressure_mpa(mid, branch) <= p` without its clamps: `mid`
            // lies in `[R_i, Rx_i]` (see `branch_in_stroke`), and with `p`
            // in `[0, Pmax)` the clamped pressure is at most `p` exactly
            // where the unclamped one is. The same comparison, the same
            // result, fewer instructions per step.
            if self.branch_in_stroke(mid, sign) <= p {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        0.5 * (lo + hi)
    }

    /// The table inverse's interpolation alone, before its Newton step
    /// (the tables must be complete, see [`Self::inverse_ready`]; `R_i`
    /// otherwise): within a table interval of [`Self::contraction`], where
    /// an iteration that takes its own steps starts (the scaled inverse,
    /// whose first step moves it to the scaled branch anyway).
    pub(crate) fn contraction_interpolated(&self, pressure_mpa: f32, branch: Branch) -> f32 {
        let p = clamp(pressure_mpa, 0.0, self.max_pressure_mpa);
        if p >= self.max_pressure_mpa {
            return self.max_contraction;
        }
        self.table_interpolation(p, branch)
            .map_or(self.root, |(x, _, _, _)| x)
    }

    /// For `p` in `[0, Pmax)`: the interpolated contraction, the table
    /// interval's ends and its index, from the complete tables.
    #[inline(always)]
    fn table_interpolation(&self, p: f32, branch: Branch) -> Option<(f32, f32, f32, usize)> {
        let table = match branch {
            Branch::Contraction => &self.inverse_table[0],
            Branch::Expansion => &self.inverse_table[1],
        };
        let t = p * self.intervals_per_mpa;
        // `as` saturates, and `min` keeps k + 1 inside the table.
        let k = (t as usize).min(INVERSE_INTERVALS - 1);
        let frac = t - k as f32;
        let (x_lo, x_hi) = match (table.get(k), table.get(k + 1)) {
            (Some(&a), Some(&b)) => (a, b),
            _ => return None, // unreachable: k < INVERSE_INTERVALS
        };
        // Where the ellipse's vertical tangent meets the stroke end (contraction
        // branch at R_i, expansion branch at Rx_i), pressure goes as the square
        // root of the distance to the end, so contraction goes as the square of
        // the pressure: interpolate quadratically there, linearly elsewhere.
        let w = match branch {
            Branch::Contraction if k == 0 => frac * frac,
            Branch::Expansion if k == INVERSE_INTERVALS - 1 => 1.0 - (1.0 - frac) * (1.0 - frac),
            _ => frac,
        };
        Some((x_lo + w * (x_hi - x_lo), x_lo, x_hi, k))
    }

    /// Inverse model: the contraction at which `branch` has `pressure_mpa`.
    ///
    /// Returns a value in `[R_i, Rx_i]`, never NaN; see the module docs for
    /// the branch ends. Fixed work: one table look-up, one interpolation, one
    /// Newton step (two divisions, one square root).
    pub fn contraction(&self, pressure_mpa: f32, branch: Branch) -> f32 {
        if !self.tables_ready {
            return self.contraction_without_tables(pressure_mpa, branch);
        }
        let p = clamp(pressure_mpa, 0.0, self.max_pressure_mpa);
        if p >= self.max_pressure_mpa {
            return self.max_contraction;
        }
        let Some((x, x_lo, x_hi, k)) = self.table_interpolation(p, branch) else {
            return self.root;
        };
        let (g, dg) = self.branch_and_slope(x, branch.offset_sign());
        // One Newton step, kept inside [x_lo, x_hi] (a step that leaves it:
        // dg = 0 or ±inf, NaN, is not taken). In the expansion branch's last
        // interval the step is taken in `s = sqrt(Rx_i − x)`, in which the
        // branch is nearly linear; in `x` it stalls against the ellipse's
        // vertical tangent and misses the tolerance next to Pmax. (At `R_i`
        // on the contraction branch the same change of variable loses more
        // to `f32` rounding of `x − R_i` than it gains: the `x` step holds
        // the tolerance there.)
        let next = match branch {
            Branch::Expansion if k == INVERSE_INTERVALS - 1 => {
                let s = sqrt(x_hi - x);
                let s_next = s - (p - g) / (2.0 * s * dg);
                x_hi - s_next * s_next
            }
            _ => x + (p - g) / dg,
        };
        if next >= x_lo && next <= x_hi {
            next
        } else {
            x
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::params::Params;
    use crate::Coeffs;

    fn model(load_n: f32) -> LoadModel {
        Coeffs::new(Params::DEFAULT)
            .unwrap()
            .load_model(load_n)
            .unwrap()
    }

    #[test]
    fn both_branches_meet_the_constraint_model_at_the_stroke_ends() {
        for load in [100.0, 250.0, 600.0] {
            let m = model(load);
            for x in [m.root_contraction(), m.max_contraction()] {
                let cm = m.constraint_pressure_mpa(x);
                for br in [Branch::Contraction, Branch::Expansion] {
                    let p = m.pressure_mpa(x, br);
                    assert!(
                        (p - cm).abs() < 1e-5,
                        "{load} N, x {x}, {br:?}: {p} vs {cm}"
                    );
                }
            }
            assert!(m.constraint_pressure_mpa(m.root_contraction()).abs() < 1e-6);
            let pmax = Params::DEFAULT.points.max_pressure_mpa;
            assert!((m.constraint_pressure_mpa(m.max_contraction()) - pmax).abs() < 1e-5);
        }
    }

    #[test]
    fn offset_peaks_at_the_centre_with_the_ellipse_height() {
        let m = model(300.0);
        let mid = 0.5 * (m.root_contraction() + m.max_contraction());
        let be = Params::DEFAULT.ellipse_height_mpa;
        assert!((m.offset_mpa(mid) - be).abs() < 1e-6);
        let up = m.pressure_mpa(mid, Branch::Contraction);
        let down = m.pressure_mpa(mid, Branch::Expansion);
        assert!((up - down - 2.0 * be).abs() < 1e-5, "loop height 2·be");
    }

    #[test]
    fn paper_relation_between_loads_heavier_needs_more_pressure() {
        let (light, heavy) = (model(100.0), model(300.0));
        for x in [0.05, 0.1, 0.15] {
            assert!(heavy.constraint_pressure_mpa(x) > light.constraint_pressure_mpa(x));
        }
    }

    #[test]
    fn inverse_at_branch_ends() {
        let m = model(200.0);
        let pmax = Params::DEFAULT.points.max_pressure_mpa;
        assert_eq!(
            m.contraction(pmax, Branch::Contraction),
            m.max_contraction()
        );
        assert!((m.contraction(0.0, Branch::Contraction) - m.root_contraction()).abs() < 1e-5);
        // The expansion branch rests where it leaves zero pressure.
        let x0 = m.contraction(0.0, Branch::Expansion);
        assert!(x0 > m.root_contraction());
        assert!(m.pressure_mpa(x0 - 1e-5, Branch::Expansion) == 0.0);
        assert!(m.pressure_mpa(x0 + 1e-5, Branch::Expansion) > 0.0);
        // The expansion branch does dip below zero (clamped) right after R_i.
        let e = m.constraint_pressure_mpa(m.root_contraction() + 1e-5)
            - m.offset_mpa(m.root_contraction() + 1e-5);
        assert!(e < 0.0);
        // NaN pressure reads as zero pressure.
        assert_eq!(
            m.contraction(f32::NAN, Branch::Contraction),
            m.contraction(0.0, Branch::Contraction)
        );
    }

    #[test]
    fn inverse_round_trip_on_a_dense_grid_up_to_pmax() {
        let pmax = Params::DEFAULT.points.max_pressure_mpa;
        for load in [100.0, 175.0, 350.0, 600.0] {
            let m = model(load);
            for br in [Branch::Contraction, Branch::Expansion] {
                let mut worst = 0.0f32;
                // The last 200 points sit within 1e-3 MPa of Pmax, where the
                // expansion branch meets the ellipse's vertical tangent.
                let near_pmax = (0..=200).map(|i| pmax - 1e-3 * i as f32 / 200.0);
                for p in (1..=20_000)
                    .map(|i| pmax * i as f32 / 20_000.0)
                    .chain(near_pmax)
                {
                    let x = m.contraction(p, br);
                    worst = worst.max((m.pressure_mpa(x, br) - p).abs());
                }
                assert!(
                    worst <= INVERSE_TOLERANCE_MPA,
                    "{load} N {br:?}: worst {worst}"
                );
            }
        }
    }

    #[test]
    fn inverse_steps_back_by_at_most_the_stated_bound() {
        let pmax = Params::DEFAULT.points.max_pressure_mpa;
        for load in [100.0, 200.0, 350.0, 600.0] {
            let m = model(load);
            for br in [Branch::Contraction, Branch::Expansion] {
                let mut highest = f32::NEG_INFINITY;
                let mut worst = 0.0f32;
                for i in 0..=200_000 {
                    let x = m.contraction(pmax * i as f32 / 200_000.0, br);
                    worst = worst.max(highest - x);
                    highest = highest.max(x);
                }
                assert!(worst <= INVERSE_STEP_BACK, "{load} N {br:?}: {worst}");
            }
        }
    }

    #[test]
    fn expansion_zero_crossing_follows_the_stated_estimate() {
        // The module docs: the expansion branch leaves zero about
        // 2·be²/(ae·CM'(R)²) after R_i.
        for load in [100.0, 600.0] {
            let m = model(load);
            let r = m.root_contraction();
            let h = 1e-4;
            let slope = (m.constraint_pressure_mpa(r + h) - m.constraint_pressure_mpa(r)) / h;
            let ae = 0.5 * (m.max_contraction() - r);
            let be = m.ellipse_height_mpa();
            let estimate = 2.0 * be * be / (ae * slope * slope);
            let dip = m.contraction(0.0, Branch::Expansion) - r;
            assert!(
                (dip / estimate - 1.0).abs() < 0.05,
                "{load} N: dip {dip}, estimate {estimate}"
            );
        }
    }

    #[test]
    fn branch_parts_are_branch_and_slope_bit_for_bit() {
        for load in [100.0f32, 350.0, 600.0] {
            let m = model(load);
            let (lo, hi) = (m.root_contraction(), m.max_contraction());
            for i in 0..=200 {
                let x = lo + (hi - lo) * (i as f32 / 200.0);
                let parts = m.branch_parts(x);
                for k in [-4.0f32, -1.3, -1.0, -0.0, 0.0, 0.4, 1.0, 2.2, 4.0] {
                    let (g, s) = m.branch_and_slope(x, k);
                    let (pg, ps) = parts.at(k);
                    assert_eq!((g.to_bits(), s.to_bits()), (pg.to_bits(), ps.to_bits()));
                }
            }
        }
    }

    #[test]
    fn the_inverse_without_tables_agrees_with_the_tables() {
        let coeffs = Coeffs::new(Params::DEFAULT).unwrap();
        let family = FamilyF32::new(coeffs.family());
        for load in [100.0, 250.0, 420.0, 600.0] {
            let (full, bare) = (family.model(load), family.model_without_tables(load));
            assert!(full.inverse_ready() && !bare.inverse_ready());
            for i in 0..=1000 {
                let p = 0.5 * i as f32 / 1000.0;
                for br in [Branch::Contraction, Branch::Expansion] {
                    let (a, b) = (full.contraction(p, br), bare.contraction(p, br));
                    // The bisection's resolution: stroke / 2^12.
                    assert!(
                        (a - b).abs() < 1e-4,
                        "{load} N, {p} MPa, {br:?}: {a} vs {b}"
                    );
                }
            }
        }
    }

    #[test]
    fn the_inverse_without_tables_is_the_bisection_on_the_forward_model() {
        // What `contraction_without_tables` documents, written plainly: its
        // loop skips the forward model's clamps, and must not change a bit.
        let coeffs = Coeffs::new(Params::DEFAULT).unwrap();
        let family = FamilyF32::new(coeffs.family());
        for load in [100.0, 250.0, 420.0, 600.0] {
            let m = family.model_without_tables(load);
            let reference = |p: f32, br: Branch| {
                let p = clamp(p, 0.0, m.max_pressure_mpa());
                if p >= m.max_pressure_mpa() {
                    return m.max_contraction();
                }
                let (mut lo, mut hi) = (m.root_contraction(), m.max_contraction());
                for _ in 0..FALLBACK_BISECTION_STEPS {
                    let mid = 0.5 * (lo + hi);
                    if m.pressure_mpa(mid, br) <= p {
                        lo = mid;
                    } else {
                        hi = mid;
                    }
                }
                0.5 * (lo + hi)
            };
            for i in 0..=20_000 {
                let p = -0.01 + 0.6 * i as f32 / 20_000.0;
                for br in [Branch::Contraction, Branch::Expansion] {
                    let (a, b) = (m.contraction(p, br), reference(p, br));
                    assert_eq!(a.to_bits(), b.to_bits(), "{load} N, {p} MPa, {br:?}");
                }
            }
            for p in [f32::NAN, f32::INFINITY, f32::NEG_INFINITY] {
                for br in [Branch::Contraction, Branch::Expansion] {
                    assert_eq!(m.contraction(p, br).to_bits(), reference(p, br).to_bits());
                }
            }
        }
    }
}
