//! The kind of test a record is, the samples it leaves slack, and the
//! record-level contradictions of the options.

use super::*;

/// The kind of characterisation test a record is.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum TestKind {
    /// Load held at a few values, pressure swept, contraction measured.
    Isotonic,
    /// Contraction held at a few values, pressure swept, load (force) measured.
    Isometric,
    /// Neither channel holds: load and contraction both move.
    Mixed,
}

impl std::str::FromStr for TestKind {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s {
            "isotonic" => Ok(TestKind::Isotonic),
            "isometric" => Ok(TestKind::Isometric),
            "mixed" => Ok(TestKind::Mixed),
            _ => Err(format!(
                "test `{s}`: expected `isotonic`, `isometric` or `mixed`"
            )),
        }
    }
}

impl std::fmt::Display for TestKind {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            TestKind::Isotonic => "isotonic",
            TestKind::Isometric => "isometric",
            TestKind::Mixed => "mixed",
        })
    }
}

/// Share of samples at which a channel is holding: its smoothed value moves
/// less than `tol` over `lag` samples.
pub(super) fn holding_share(v: &[f64], lag: usize, tol: f64) -> f64 {
    if v.len() <= lag {
        return 1.0;
    }
    let s = crate::record::split::moving_average(v, 9);
    let held = s
        .windows(lag + 1)
        .filter(|w| (w[lag] - w[0]).abs() <= tol)
        .count();
    held as f64 / (s.len() - lag) as f64
}

/// Detect the kind of test: the channel that holds while the pressure
/// sweeps. A channel holds at a sample when it moves by less than 1 % of
/// its range (and 3× its noise) over 1 % of the record; the test is
/// isotonic (isometric) when the load (contraction) holds at a quarter of
/// the samples more than the other channel, else mixed.
pub fn detect_test(samples: &[Sample]) -> TestKind {
    let x: Vec<f64> = samples.iter().map(|s| s.contraction).collect();
    let l: Vec<f64> = samples.iter().map(|s| s.load_n).collect();
    let range = |v: &[f64]| {
        let q = |f| quantile(v.to_vec(), f).unwrap_or(0.0);
        q(0.99) - q(0.01)
    };
    let lag = (samples.len() / 100).clamp(5, 1000);
    let tol = |v: &[f64]| (0.01 * range(v)).max(3.0 * crate::record::noise_std(v.iter().copied()));
    let (hx, hl) = (
        holding_share(&x, lag, tol(&x)),
        holding_share(&l, lag, tol(&l)),
    );
    // One channel holds clearly more often than the other.
    if hl > hx + 0.25 {
        TestKind::Isotonic
    } else if hx > hl + 0.25 {
        TestKind::Isometric
    } else {
        TestKind::Mixed
    }
}

/// The samples of an isometric test where the force is at the load cell's
/// floor (5× its noise, at least 1 % of the record's largest load): a slack
/// muscle held by the fixture, not a muscle in balance with 0 N. Such
/// samples bound the model (pressure below the 0 N curve) but are no sample
/// of it. None in other tests.
pub fn slack_mask(samples: &[Sample], test: TestKind) -> Vec<bool> {
    if test == TestKind::Isometric {
        let max_load = samples.iter().map(|s| s.load_n).fold(0.0, f64::max);
        let noise = crate::record::noise_std(samples.iter().map(|s| s.load_n));
        let floor = (5.0 * noise).max(0.01 * max_load);
        samples.iter().map(|s| s.load_n <= floor).collect()
    } else {
        vec![false; samples.len()]
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
