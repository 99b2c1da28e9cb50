//! The kind of test a record is and the samples it leaves slack.

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
