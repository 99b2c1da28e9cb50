//! Record-level checks for a command's purpose, physical limits per
//! sample, and warnings of units that look wrong.

use super::*;

/// What a command needs of a record beyond valid samples.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Purpose {
    /// Identify the model (`fit`): pressure and contraction must vary, and
    /// two loads are checked by the fit itself.
    Fit,
    /// Diagnose: as [`Purpose::Fit`], and at least [`DIAGNOSE_MIN_SAMPLES`].
    Diagnose,
    /// Drive a model (`simulate`): the pressure must vary.
    Simulate,
}

/// One channel of a sample.
type Channel = fn(&Sample) -> f64;

/// Fewest samples `diagnose` works on.
pub const DIAGNOSE_MIN_SAMPLES: usize = 100;

/// Record-level checks, before any work: time advances, the channels the
/// command needs vary, no sensor is stuck for a long stretch while the
/// others move (at least 200 samples and a tenth of the record).
pub fn check_record(record: &Record, purpose: Purpose) -> Result<(), DataError> {
    let s = &record.samples;
    let err = |line: u64, column: Option<&str>, kind| DataError {
        file: record.source.clone(),
        line,
        column: column.map(str::to_string),
        kind,
    };
    let (Some(first), Some(last)) = (s.first(), s.last()) else {
        return Err(err(0, None, DataErrorKind::NoSamples));
    };
    if s.len() > 1 && last.t_s <= first.t_s {
        return Err(err(0, Some("t_s"), DataErrorKind::TimeNeverAdvances));
    }
    if purpose == Purpose::Diagnose && s.len() < DIAGNOSE_MIN_SAMPLES {
        return Err(err(
            0,
            None,
            DataErrorKind::TooFewSamples(format!(
                "{} samples, diagnose needs at least {DIAGNOSE_MIN_SAMPLES}",
                s.len()
            )),
        ));
    }
    let constant = |f: fn(&Sample) -> f64| s.iter().all(|x| f(x) == f(first));
    let mut need: Vec<(&str, Channel)> = vec![("pressure_mpa", |x| x.pressure_mpa)];
    if purpose != Purpose::Simulate {
        need.push(("contraction", |x| x.contraction));
    }
    for (name, f) in need {
        if s.len() > 1 && constant(f) {
            return Err(err(
                0,
                Some(name),
                DataErrorKind::Constant { value: f(first) },
            ));
        }
    }
    // A stuck sensor: one exact value for a long run while another channel
    // moves. (Quantised readings repeat on holds, but then nothing moves.)
    let min_run = (s.len() / 10).max(200);
    let channels: [(&str, Channel, Channel, &str, f64); 2] = [
        (
            "contraction",
            |x| x.contraction,
            |x| x.pressure_mpa,
            "MPa of pressure",
            0.05,
        ),
        (
            "pressure_mpa",
            |x| x.pressure_mpa,
            |x| x.contraction,
            "of contraction",
            0.02,
        ),
    ];
    // A record whose contraction is held at two or more exact values
    // throughout (each for at least 200 samples) is an isometric protocol whose
    // lengths were set, not measured (`pam-lab import` writes held lengths
    // so): nothing there can be a stuck length sensor.
    let held_protocol = {
        let (mut runs_ok, mut runs) = (true, 0);
        let mut start = 0;
        for i in 1..=s.len() {
            if i < s.len() && s[i].contraction == s[start].contraction {
                continue;
            }
            runs_ok &= i - start >= 200;
            runs += 1;
            start = i;
        }
        runs_ok && runs >= 2
    };
    for (name, f, other, what, threshold) in channels {
        if name == "contraction" && held_protocol {
            continue;
        }
        let mut start = 0;
        for i in 1..=s.len() {
            if i < s.len() && f(&s[i]) == f(&s[start]) {
                continue;
            }
            let n = i - start;
            if n >= min_run {
                let (lo, hi) = s[start..i]
                    .iter()
                    .map(other)
                    .fold((f64::MAX, f64::MIN), |(a, b), v| (a.min(v), b.max(v)));
                if hi - lo >= threshold && !(name == "contraction" && held_length(&s[start..i])) {
                    return Err(err(
                        record.line(start),
                        Some(name),
                        DataErrorKind::Stuck {
                            value: f(&s[start]),
                            until_line: record.line(i - 1),
                            samples: n,
                            fraction: n as f64 / s.len() as f64,
                            moved: format!("{:.3} {what} moved", hi - lo),
                        },
                    ));
                }
            }
            start = i;
        }
    }
    Ok(())
}

/// Highest pressure a pneumatic muscle is commonly run at, MPa (Festo's
/// are rated to 0.8 MPa): a record above it is more likely in bar.
pub const PNEUMATIC_TOP_MPA: f64 = 1.0;

/// Slowest pressure rate, MPa/s, that a record's fastest stretch reaches
/// on any rig that shows a hysteresis loop:
/// 1 kPa/s, a 0.5 MPa sweep in over 8 minutes. A record logged in
/// milliseconds shows its rates 1000× too slow (a 0.1 MPa/s ramp as
/// 0.0001).
pub const SLOWEST_FAST_RATE_MPA_PER_S: f64 = 0.001;

/// Samples of the moving mean the pressure rate is taken over (the rate
/// of single samples is the sensor's noise over one step).
const RATE_WINDOW: usize = 25;

/// The pressure's fastest rate, MPa/s, between [`RATE_WINDOW`]-sample
/// moving means a window apart (the means average the sensor's noise
/// away: a record with one pressure step among hours of holds still shows
/// that step); `None` on a record too short for two windows.
fn fast_pressure_rate(s: &[Sample]) -> Option<f64> {
    let k = RATE_WINDOW;
    if s.len() < 2 * k {
        return None;
    }
    let mut sum = vec![0.0; s.len() + 1];
    for (i, x) in s.iter().enumerate() {
        sum[i + 1] = sum[i] + x.pressure_mpa;
    }
    let mean = |i: usize| (sum[i + k] - sum[i]) / k as f64;
    (0..s.len() - 2 * k + 1)
        .filter_map(|i| {
            let dt = s[i + k].t_s - s[i].t_s;
            (dt > 0.0).then(|| (mean(i + k) - mean(i)).abs() / dt)
        })
        .filter(|r| r.is_finite())
        .reduce(f64::max)
}

/// Units a record's values suggest were not the format's, said as
/// warnings (the values are possible, so not refused): a pressure whose
/// top (99th percentile) is above [`PNEUMATIC_TOP_MPA`] (bar for MPa); a
/// time step of a second or more where the pressure's fastest stretch
/// stays under [`SLOWEST_FAST_RATE_MPA_PER_S`], or over a record of hours
/// (milliseconds for seconds: a rig that shows a hysteresis loop samples
/// far faster and ramps faster).
pub fn unit_warnings(record: &Record) -> Vec<String> {
    let s = &record.samples;
    let mut out = Vec::new();
    if s.len() < 3 {
        return out;
    }
    let mut p: Vec<f64> = s.iter().map(|x| x.pressure_mpa).collect();
    p.sort_by(f64::total_cmp);
    let p99 = p[(p.len() - 1) * 99 / 100];
    if p99 > PNEUMATIC_TOP_MPA {
        out.push(format!(
            "{}: column `pressure_mpa` reaches {} MPa: a pneumatic muscle works below about {} \
             MPa; if the column is in bar, divide it by 10; if in psi, multiply it by 0.006895 \
             (a hydraulic muscle: ignore this)",
            record.source,
            num(p99),
            PNEUMATIC_TOP_MPA
        ));
    }
    let mut dt: Vec<f64> = s.windows(2).map(|w| w[1].t_s - w[0].t_s).collect();
    dt.sort_by(f64::total_cmp);
    let median_dt = dt[dt.len() / 2];
    let hours = (s[s.len() - 1].t_s - s[0].t_s) / 3600.0;
    let fast_rate = fast_pressure_rate(s);
    let slow = fast_rate.is_some_and(|r| r < SLOWEST_FAST_RATE_MPA_PER_S);
    if median_dt >= 1.0 && (hours >= 5.0 || slow) {
        let rate = match fast_rate {
            Some(r) if slow => format!(", its pressure never faster than {} MPa/s", num(r)),
            _ => String::new(),
        };
        out.push(format!(
            "{}: column `t_s` steps {} s per sample over {:.1} h{rate}: if the column is in \
             milliseconds, divide it by 1000 (the effects' time constants depend on it)",
            record.source,
            num(median_dt),
            hours
        ));
    }
    out
}

/// Whether a stretch of constant contraction while the pressure moves is
/// an isometric hold, not a stuck sensor: at a held length the muscle
/// answers the pressure with force, so the load moves well above its noise
/// (5×) and in step with the pressure (correlation at least 0.5). A stuck
/// contraction sensor on an isotonic rig shows a hung load that does not
/// follow the pressure.
fn held_length(run: &[Sample]) -> bool {
    if run.len() < 3 {
        return false;
    }
    let load_noise = noise_std(run.iter().map(|s| s.load_n));
    let (lo, hi) = run.iter().fold((f64::MAX, f64::MIN), |(a, b), s| {
        (a.min(s.load_n), b.max(s.load_n))
    });
    if !(hi - lo > 5.0 * load_noise && hi > lo) {
        return false;
    }
    correlation(run, |s| s.pressure_mpa, |s| s.load_n) >= 0.5
}

/// The physical limits every sample must meet: `(column, value, allowed)` of
/// the first violation.
pub fn check_physical(s: &Sample) -> Result<(), (&'static str, f64, &'static str)> {
    if !(s.load_n >= 0.0 && s.load_n <= MAX_LOAD_N) {
        return Err((
            "load_n",
            s.load_n,
            "a muscle only pulls: 0 <= load_n <= 100000 N",
        ));
    }
    if !(s.pressure_mpa >= MIN_PRESSURE_MPA && s.pressure_mpa <= MAX_PRESSURE_MPA) {
        return Err((
            "pressure_mpa",
            s.pressure_mpa,
            "gauge pressure between vacuum (-0.101325 MPa) and 10 MPa",
        ));
    }
    if !(s.contraction > -1.0 && s.contraction < 1.0) {
        return Err((
            "contraction",
            s.contraction,
            "a fraction of rest length strictly between -1 and 1",
        ));
    }
    Ok(())
}
