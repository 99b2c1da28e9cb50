//! The fit's options, its progress reports and its errors; which samples
//! are held out.

use super::*;

/// Which part of the record is held out of the fit.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Holdout {
    /// Nothing held out (the report is then on the training data).
    None,
    /// Every `k`-th cycle (cycles `k−1, 2k−1, …`): held-out data from every
    /// load and every part of the protocol.
    EveryKthCycle(u32),
    /// The last fraction of the record (a contiguous later part).
    Tail(f64),
}

impl std::str::FromStr for Holdout {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        let bad = || {
            format!("holdout `{s}`: expected `none`, `every:K` (K >= 2) or `tail:F` (0 < F < 1)")
        };
        if s == "none" {
            return Ok(Holdout::None);
        }
        let (kind, v) = s.split_once(':').ok_or_else(bad)?;
        match kind {
            "every" => match v.parse::<u32>() {
                Ok(k) if k >= 2 => Ok(Holdout::EveryKthCycle(k)),
                _ => Err(bad()),
            },
            "tail" => match v.parse::<f64>() {
                Ok(f) if f > 0.0 && f < 1.0 => Ok(Holdout::Tail(f)),
                _ => Err(bad()),
            },
            _ => Err(bad()),
        }
    }
}

impl std::fmt::Display for Holdout {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Holdout::None => write!(f, "none"),
            Holdout::EveryKthCycle(k) => write!(f, "every:{k}"),
            Holdout::Tail(x) => write!(f, "tail:{x}"),
        }
    }
}

/// Fit settings.
#[derive(Clone, Debug, PartialEq)]
pub struct FitConfig {
    /// `Pmax`, MPa; `None` measures it (the top of the smoothed pressure).
    pub max_pressure_mpa: Option<f64>,
    /// Load step `ΔL` of the regression and growth factors, N.
    pub load_step_n: f64,
    /// What to hold out.
    pub holdout: Holdout,
    /// Branch split settings.
    pub split: SplitConfig,
    /// Width of the load bins for grouping and reports, N.
    pub load_bin_n: f64,
    /// Fewest training samples per branch in a load bin for it to count.
    pub min_samples_per_group: usize,
    /// Iteration budget of the optimiser (in units of residual evaluations
    /// per parameter, as MINPACK's `patience`).
    pub patience: usize,
    /// The kind of test; `None` detects it from the record.
    pub test: Option<TestKind>,
    /// Fit pam-core's static-shape correction with the paper's parameters
    /// where the cubic alone leaves a systematic misfit (above twice the
    /// noise) and the shape earns its parameters.
    pub static_shape: bool,
}

impl Default for FitConfig {
    fn default() -> Self {
        FitConfig {
            max_pressure_mpa: None,
            load_step_n: 100.0,
            holdout: Holdout::EveryKthCycle(4),
            split: SplitConfig::default(),
            load_bin_n: 25.0,
            min_samples_per_group: 50,
            patience: 100,
            test: None,
            static_shape: true,
        }
    }
}

/// Progress of a long fit, for display.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Progress {
    /// A stage started.
    Stage(&'static str),
    /// The optimiser evaluated the residuals: the evaluation count and the
    /// cost `½·Σr²` of the current parameters.
    Evaluation {
        /// Residual evaluations so far.
        count: usize,
        /// `½·Σr²`.
        cost: f64,
    },
}

/// Why a fit failed.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum FitError {
    /// A setting is out of its range; nothing was read or computed.
    #[error("invalid setting `{option}`: {why}")]
    Config {
        /// The setting (its command-line name).
        option: &'static str,
        /// What is allowed.
        why: String,
    },
    /// The record cannot identify the model (too few samples, one load
    /// only, a channel that does not vary…).
    #[error(transparent)]
    Data(#[from] DataError),
    /// No valid model could be made from the record's ranges (for example
    /// a stroke outside `(-1, 1)`); pam-core's reason is given.
    #[error("{source_name}: no valid model fits this record's ranges: {error}")]
    Invalid {
        /// The record.
        source_name: String,
        /// What pam-core said of the closest candidate.
        error: pam_core::Error,
    },
    /// The optimiser failed numerically.
    #[error("{source_name}: the optimiser failed: {why}")]
    Optimiser {
        /// The record.
        source_name: String,
        /// What happened.
        why: String,
    },
    /// The fitted model's files could not be made or did not read back.
    #[error("{source_name}: the model files could not be made: {why}")]
    Export {
        /// The record.
        source_name: String,
        /// What happened.
        why: String,
    },
}

impl FitConfig {
    /// Check every setting before any work is done.
    pub fn validate(&self) -> Result<(), FitError> {
        let bad = |option: &'static str, why: &str| {
            Err(FitError::Config {
                option,
                why: why.to_string(),
            })
        };
        if let Some(p) = self.max_pressure_mpa {
            if !(p.is_finite() && p > 0.0 && p <= 10.0) {
                return bad("--pmax", "must be a number in (0, 10] MPa");
            }
        }
        if !(self.load_step_n.is_finite() && self.load_step_n >= 1e-3) {
            return bad("--load-step", "must be a finite number of newtons >= 0.001");
        }
        if !(self.load_bin_n.is_finite() && self.load_bin_n >= 1e-3) {
            return bad("--load-bin", "must be a finite number of newtons >= 0.001");
        }
        if let Some(d) = self.split.deadband_mpa {
            if !(d.is_finite() && d >= 0.0) {
                return bad("--deadband", "must be a finite pressure >= 0 MPa");
            }
        }
        if let Some(g) = self.split.guard_mpa {
            if !(g.is_finite() && g >= 0.0) {
                return bad("--guard", "must be a finite pressure >= 0 MPa");
            }
        }
        if self.split.smooth_samples == 0 {
            return bad("--smooth", "must be at least 1 sample");
        }
        if self.min_samples_per_group == 0 {
            return bad("--min-samples", "must be at least 1");
        }
        if self.patience == 0 {
            return bad("--patience", "must be at least 1");
        }
        if let Holdout::Tail(f) = self.holdout {
            if !(f > 0.0 && f < 1.0) {
                return bad("--holdout", "tail fraction must be in (0, 1)");
            }
        }
        if let Holdout::EveryKthCycle(k) = self.holdout {
            if k < 2 {
                return bad("--holdout", "every:K needs K >= 2");
            }
        }
        Ok(())
    }
}

/// Which samples of a record of `n` with cycles `cycle` are held out.
pub fn heldout_mask(holdout: Holdout, cycle: &[u32]) -> Vec<bool> {
    let n = cycle.len();
    match holdout {
        Holdout::None => vec![false; n],
        Holdout::EveryKthCycle(k) => cycle.iter().map(|c| k >= 2 && c % k == k - 1).collect(),
        Holdout::Tail(f) => {
            let first = ((1.0 - f) * n as f64).round() as usize;
            (0..n).map(|i| i >= first).collect()
        }
    }
}

/// Mistakes a record shows against the options, before any work: a
/// `--test` the record contradicts, a `--pmax` below most of the samples,
/// and (isotonic records) a contraction that falls as the pressure rises.
pub(super) fn check_against_record(
    record: &Record,
    cfg: &FitConfig,
    detected: TestKind,
) -> Result<(), FitError> {
    let samples = &record.samples;
    if let Some(given) = cfg.test {
        let pure = |k| matches!(k, TestKind::Isotonic | TestKind::Isometric);
        if pure(given) && pure(detected) && given != detected {
            let (holds, moves) = match detected {
                TestKind::Isotonic => ("load", "contraction"),
                _ => ("contraction", "load"),
            };
            return Err(FitError::Config {
                option: "--test",
                why: format!(
                    "`{given}`, but in {} the {holds} holds while the {moves} moves: it is \
                     {detected} (leave --test out to detect it, or check the columns)",
                    record.source
                ),
            });
        }
    }
    if let Some(pmax) = cfg.max_pressure_mpa {
        let above = samples.iter().filter(|s| s.pressure_mpa > pmax).count();
        let top = samples
            .iter()
            .map(|s| s.pressure_mpa)
            .fold(f64::MIN, f64::max);
        if 2 * above > samples.len() {
            return Err(FitError::Config {
                option: "--pmax",
                why: format!(
                    "{pmax} MPa, but {:.0} % of the samples of {} lie above it (its top is {} \
                     MPa): Pmax is where the loop closes, at the top of the record; leave \
                     --pmax out to measure it",
                    100.0 * above as f64 / samples.len() as f64,
                    record.source,
                    crate::record::num(top)
                ),
            });
        }
    }
    let test = cfg.test.unwrap_or(detected);
    if test == TestKind::Isotonic {
        let r = crate::record::correlation(samples, |s| s.pressure_mpa, |s| s.contraction);
        if r < -0.5 {
            return Err(FitError::Data(DataError {
                file: record.source.clone(),
                line: 0,
                column: Some("contraction".into()),
                kind: DataErrorKind::Implausible(format!(
                    "falls as the pressure rises (correlation {r:.2} over the record): a muscle \
                     shortens when pressurised, so contraction = (rest length − length)/rest \
                     length rises with pressure; is its sign flipped?"
                )),
            }));
        }
    }
    Ok(())
}
