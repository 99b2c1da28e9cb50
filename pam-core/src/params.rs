//! What a user sets: the paper's critical points and load factors.
//!
//! [`Params`] is plain data (it is what the model file and the firmware blob
//! carry); [`crate::Coeffs::new`] validates it once and precomputes the rest.

/// A point on the pressure–contraction plane.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Point {
    /// Contraction, fraction of rest length.
    pub contraction: f32,
    /// Pressure, MPa.
    pub pressure_mpa: f32,
}

/// The four critical points of the constraint model at the minimum load that
/// the paper's GUI takes (Fig. 2; initial conditions of eq. 7).
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct CriticalPoints {
    /// First real root `R1`: contraction at zero pressure (the minimum contraction).
    ///
    /// Eq. (4) of the paper (`R1 ≠ 0`, add an epsilon) is not applied: `c1`
    /// comes from eq. (14), `c = C − bR`, not from eq. (20)'s `−D1/R1`, so
    /// nothing divides by `R1` and `R1 = 0` is valid.
    pub root_contraction: f32,
    /// `Rx1`: contraction at the maximum operating pressure.
    pub max_contraction: f32,
    /// `Pmax`: maximum operating pressure, MPa.
    pub max_pressure_mpa: f32,
    /// Tangency point `(x_tan, y_tan)`: an interior point the cubic passes
    /// through (the third condition on eq. 7), nothing more.
    ///
    /// The paper also writes `x_tan = b/(2a)`, `y_inf = y_tan` and
    /// `x_inf = x_tan − h` with `h = √(b² − 4ac)/(2a)`. These cannot hold for a
    /// model with one real root: that needs `b² − 4ac < 0` (eq. 3), which
    /// makes `h` imaginary. pam-core therefore does not impose them; on
    /// [`Params::DEFAULT`] `x_tan` is 0.068 while the fitted cubic's `b/(2a)`
    /// is 0.174 (checked by a unit test in [`crate::constraint`]).
    pub tangency: Point,
    /// Inflection point `(x_inf, y_inf)`.
    pub inflection: Point,
}

/// Everything that defines a muscle's model: the critical points at the
/// minimum load, the linear load factors of eqs. (17)–(19), and the ellipse
/// height of eq. (24).
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Params {
    /// Minimum calibrated load, N: the load of the critical points (`i = 1`).
    pub min_load_n: f32,
    /// Maximum calibrated load, N. Loads above it are refused or clamped.
    pub max_load_n: f32,
    /// Load step `ΔL` of the regression and growth factors, N (the paper: 100 N).
    pub load_step_n: f32,
    /// Critical points at `min_load_n`.
    pub points: CriticalPoints,
    /// `RG_L`: regression of the first real root per load step (eq. 17).
    pub root_regression_per_step: f32,
    /// `RG_U`: regression of the maximum contraction per load step (eq. 18).
    pub max_regression_per_step: f32,
    /// `GR_c`: growth of the quadratic's constant `c` per load step (eq. 19).
    pub c_growth_per_step: f32,
    /// `be`: height of the ellipse offset, MPa (eq. 24; the paper uses 0.02).
    pub ellipse_height_mpa: f32,
}

impl Params {
    /// Number of `f32` fields: what the model file, the blob and validation walk.
    pub const FIELD_COUNT: usize = 14;

    /// Every field as `(name, value)`, in declaration order (the order of the
    /// coefficient blob, [`crate::blob`]). Names are the model file's keys.
    pub fn named_fields(&self) -> [(&'static str, f32); Params::FIELD_COUNT] {
        [
            ("min_load_n", self.min_load_n),
            ("max_load_n", self.max_load_n),
            ("load_step_n", self.load_step_n),
            ("root_contraction", self.points.root_contraction),
            ("max_contraction", self.points.max_contraction),
            ("max_pressure_mpa", self.points.max_pressure_mpa),
            ("tangency.contraction", self.points.tangency.contraction),
            ("tangency.pressure_mpa", self.points.tangency.pressure_mpa),
            ("inflection.contraction", self.points.inflection.contraction),
            (
                "inflection.pressure_mpa",
                self.points.inflection.pressure_mpa,
            ),
            ("root_regression_per_step", self.root_regression_per_step),
            ("max_regression_per_step", self.max_regression_per_step),
            ("c_growth_per_step", self.c_growth_per_step),
            ("ellipse_height_mpa", self.ellipse_height_mpa),
        ]
    }

    /// The built-in reference muscle: host-sim's simulated 100–600 N
    /// McKibben muscle (Tondu–Lopez force, bladder threshold, Maxwell-slip
    /// friction: `host_sim::plant::MuscleParams::DEFAULT`) driven to 0.5 MPa.
    ///
    /// Origin: the paper's model alone (no static shape) identified by
    /// `pam-lab fit` from that rig's characterisation run,
    /// `host_sim::characterisation_run(1)`, as the main job writes it, and
    /// copied from the `model_params.rs` the fit writes (the `f32` values as
    /// printed there):
    ///
    /// ```sh
    /// cargo run --release -p host-sim     # writes target/host-sim-report/characterisation.csv
    /// cargo run --release -p pam-lab -- fit target/host-sim-report/characterisation.csv --no-static-shape -o fit/
    /// ```
    ///
    /// `host-sim/tests/default_coeffs.rs` re-runs that fit and fails if any
    /// parameter here drifts from it. The cubic-plus-ellipse is not that
    /// plant's shape: held out, the fit's contraction error is 0.011 RMS
    /// (see pam-lab/README.md). Regenerate after any change to the rig or to
    /// the fit.
    pub const DEFAULT: Params = Params {
        min_load_n: 100.0,
        max_load_n: 600.0,
        load_step_n: 100.0,
        points: CriticalPoints {
            root_contraction: 0.015122114,
            max_contraction: 0.22982769,
            max_pressure_mpa: 0.50096667,
            tangency: Point {
                contraction: 0.068183854,
                pressure_mpa: 0.19352181,
            },
            inflection: Point {
                contraction: 0.12124559,
                pressure_mpa: 0.24306448,
            },
        },
        root_regression_per_step: 0.005341328,
        max_regression_per_step: 0.016383935,
        c_growth_per_step: 0.15466118,
        ellipse_height_mpa: 0.030233167,
    };
}
