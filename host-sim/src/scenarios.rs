//! The paper's test inputs as reference trajectories and load profiles.
//!
//! * [`Scenario::triangle`] — Fig. 6: triangle contraction/expansion input
//!   at a constant load.
//! * [`Scenario::random_step_load`] — Fig. 7: the same kind of triangle
//!   while the load steps at random times to random levels.
//! * [`Scenario::cyclic_load_change`] — Fig. 8: cyclic contraction and
//!   expansion with the load changed between 100 and 600 N from cycle to
//!   cycle.
//!
//! Loads span `[LOAD_MIN_N, LOAD_MAX_N]`, the whole calibrated 100–600 N as
//! in Fig. 8. A load cell with 1.5 N RMS noise at exactly 100 N reads below
//! it half the time; the firmware's `SafetyConfig::load_margin_n` (25 N)
//! accepts such readings and clamps them to the calibrated range.

use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// Lowest load the scenarios hang, N.
pub const LOAD_MIN_N: f64 = 100.0;
/// Highest load the scenarios hang, N.
pub const LOAD_MAX_N: f64 = 600.0;

/// A reference trajectory and a load profile over a fixed duration.
#[derive(Clone, Debug, PartialEq)]
pub struct Scenario {
    /// Short name, used for file names.
    pub name: &'static str,
    /// What it reproduces.
    pub title: &'static str,
    /// Duration, s.
    pub duration_s: f64,
    /// Reference contraction knots `(t_s, contraction)`, linear between them.
    pub reference: Vec<(f64, f64)>,
    /// Load steps `(t_s, load_n)`: the load from each time on; the first is at 0.
    pub loads: Vec<(f64, f64)>,
}

impl Scenario {
    /// Fig. 6: `cycles` triangles between 4 % and 16 % contraction, `period_s`
    /// each, at 200 N, after a 3 s hold at the bottom.
    pub fn triangle(cycles: usize, period_s: f64) -> Scenario {
        let (lo, hi) = (0.04, 0.16);
        let mut reference = vec![(0.0, lo), (3.0, lo)];
        for c in 0..cycles {
            let t0 = 3.0 + c as f64 * period_s;
            reference.push((t0 + 0.5 * period_s, hi));
            reference.push((t0 + period_s, lo));
        }
        let duration_s = 3.0 + cycles as f64 * period_s + 2.0;
        reference.push((duration_s, lo));
        Scenario {
            name: "triangle",
            title: "Fig. 6: triangle contraction/expansion at 200 N",
            duration_s,
            reference,
            loads: vec![(0.0, 200.0)],
        }
    }

    /// Fig. 7: triangles between 5 % and 12 % (reachable at every load) with
    /// the load stepping every 3–6 s to a random level in
    /// `[LOAD_MIN_N, LOAD_MAX_N]` at least 60 N from the last.
    pub fn random_step_load(duration_s: f64, period_s: f64, seed: u64) -> Scenario {
        let (lo, hi) = (0.05, 0.12);
        let mut reference = vec![(0.0, lo), (3.0, lo)];
        let mut t = 3.0;
        while t < duration_s {
            reference.push(((t + 0.5 * period_s).min(duration_s), hi));
            reference.push(((t + period_s).min(duration_s), lo));
            t += period_s;
        }
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let mut loads = vec![(0.0, 150.0)];
        let mut t = 4.0;
        while t < duration_s - 1.0 {
            let last: f64 = loads.last().map(|l| l.1).unwrap_or(150.0);
            let mut next = last;
            while (next - last).abs() < 60.0 {
                next = LOAD_MIN_N + (LOAD_MAX_N - LOAD_MIN_N) * rng.random::<f64>();
                next = (next / 10.0).round() * 10.0;
            }
            loads.push((t, next));
            t += 3.0 + 3.0 * rng.random::<f64>();
        }
        Scenario {
            name: "random_step_load",
            title: "Fig. 7: triangle input with random load steps",
            duration_s,
            reference,
            loads,
        }
    }

    /// Fig. 8: `cycles` contraction/expansion cycles between 3 % and 13 %,
    /// the load changing at each bottom reversal through
    /// 100, 600, 250, 450, 150, 550, … N.
    pub fn cyclic_load_change(cycles: usize, period_s: f64) -> Scenario {
        let (lo, hi) = (0.03, 0.13);
        let levels = [LOAD_MIN_N, LOAD_MAX_N, 250.0, 450.0, 150.0, 550.0, 350.0];
        let mut reference = vec![(0.0, lo), (3.0, lo)];
        let mut loads = vec![(0.0, levels[0])];
        for c in 0..cycles {
            let t0 = 3.0 + c as f64 * period_s;
            reference.push((t0 + 0.5 * period_s, hi));
            reference.push((t0 + period_s, lo));
            if c > 0 {
                loads.push((t0, levels[c % levels.len()]));
            }
        }
        let duration_s = 3.0 + cycles as f64 * period_s + 2.0;
        reference.push((duration_s, lo));
        Scenario {
            name: "cyclic_load_change",
            title: "Fig. 8: cyclic contraction/expansion, load 100-600 N",
            duration_s,
            reference,
            loads,
        }
    }

    /// Reference contraction at `t_s`.
    pub fn reference_at(&self, t_s: f64) -> f64 {
        let r = &self.reference;
        match r.iter().position(|k| k.0 > t_s) {
            Some(0) => r[0].1,
            Some(i) => {
                let (a, b) = (r[i - 1], r[i]);
                a.1 + (b.1 - a.1) * (t_s - a.0) / (b.0 - a.0)
            }
            None => r.last().map(|k| k.1).unwrap_or(0.0),
        }
    }

    /// Load at `t_s`, N.
    pub fn load_at(&self, t_s: f64) -> f64 {
        self.loads
            .iter()
            .take_while(|l| l.0 <= t_s)
            .last()
            .map(|l| l.1)
            .unwrap_or(self.loads[0].1)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn triangle_goes_up_and_down() {
        let s = Scenario::triangle(2, 10.0);
        assert_eq!(s.reference_at(0.0), 0.04);
        assert!((s.reference_at(8.0) - 0.16).abs() < 1e-12);
        assert!((s.reference_at(5.5) - 0.10).abs() < 1e-12);
        assert_eq!(s.reference_at(1e9), 0.04);
        assert_eq!(s.load_at(7.0), 200.0);
    }

    #[test]
    fn random_loads_are_seeded_in_range_and_step() {
        let a = Scenario::random_step_load(60.0, 8.0, 9);
        assert_eq!(a, Scenario::random_step_load(60.0, 8.0, 9));
        assert!(a.loads.len() >= 10, "{}", a.loads.len());
        for w in a.loads.windows(2) {
            assert!((w[1].1 - w[0].1).abs() >= 60.0);
            assert!(w[1].0 - w[0].0 >= 3.0 - 1e-9 || w[0].0 == 0.0);
        }
        assert!(a
            .loads
            .iter()
            .all(|l| l.1 >= LOAD_MIN_N && l.1 <= LOAD_MAX_N));
        assert_eq!(a.load_at(a.loads[2].0), a.loads[2].1);
    }

    #[test]
    fn cyclic_changes_load_each_cycle() {
        let s = Scenario::cyclic_load_change(7, 10.0);
        assert_eq!(s.loads.len(), 7);
        assert_eq!(s.load_at(14.0), 600.0);
        assert_eq!(s.load_at(1.0), 100.0);
        assert!((s.reference_at(8.0) - 0.13).abs() < 1e-12);
    }
}
