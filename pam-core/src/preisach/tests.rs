use super::*;

/// Relay-by-relay reference Preisach.
struct Relays<const N: usize> {
    lo: f32,
    step: f32,
    s: [[bool; N]; N],
}

#[allow(clippy::needless_range_loop)]
impl<const N: usize> Relays<N> {
    fn update(&mut self, p: f32) {
        for i in 0..N {
            let alpha = self.lo + (i + 1) as f32 * self.step;
            for j in 0..=i {
                let beta = self.lo + j as f32 * self.step;
                if p >= alpha {
                    self.s[i][j] = true;
                }
                if p <= beta {
                    self.s[i][j] = false;
                }
            }
        }
    }
}

/// A pseudo-random number in `[0, 1)`.
fn uniform(seed: &mut u32) -> f32 {
    *seed = seed.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
    (*seed >> 8) as f32 / (1u32 << 24) as f32
}

const N: usize = 8;

/// Weights `w_ij` from `weight(i, j)`, lo 0.01, Δ 0.06 MPa, range to 0.5 MPa.
fn table(bias: f32, linear: f32, weight: impl Fn(usize, usize) -> f32) -> PreisachTable<N, 1> {
    let mut w = [[0.0f32; N]; N];
    for (i, row) in w.iter_mut().enumerate() {
        for (j, v) in row.iter_mut().enumerate() {
            *v = weight(i, j);
        }
    }
    PreisachTable {
        lo_mpa: 0.01,
        step_mpa: 0.06,
        max_pressure_mpa: 0.5,
        min_load_n: 100.0,
        load_step_n: 100.0,
        grid: [PreisachCoeffs::from_weights(bias, linear, &w)],
    }
}

#[test]
#[allow(clippy::needless_range_loop)]
fn rows_are_exactly_the_relays() {
    let t = table(0.02, 0.05, |i, j| 0.001 * (1 + i * N + j) as f32);
    assert!(t.validate().is_ok());
    let mut m = Preisach::new(&t, 100.0, 0.0);
    let mut r = Relays::<N> {
        lo: 0.01,
        step: 0.06,
        s: [[false; N]; N],
    };
    // A pseudo-random walk with exact grid hits, reversals everywhere.
    let mut seed = 12345u32;
    let mut p = 0.0f32;
    for k in 0..5000 {
        let d = (uniform(&mut seed) - 0.5) * 0.2;
        p = (p + d).clamp(-0.05, 0.55);
        if k % 97 == 0 {
            // Reversals just beside the thresholds.
            p = 0.0101 + 0.06 * (k % 9) as f32;
        }
        let x = m.step(&t, p, 100.0);
        r.update(p);
        let mut want = 0.02 + 0.05 * p;
        for i in 0..N {
            for j in 0..=i {
                assert_eq!(m.relay(i, j), r.s[i][j], "step {k} p {p} relay ({i},{j})");
                if r.s[i][j] {
                    want += t.grid[0].weight(i, j);
                }
            }
        }
        assert!((x - want).abs() < 1e-5, "step {k}: {x} vs {want}");
        // The inverse's invariant: in every column `j` the rows with relay
        // `j` on are `j, j + 1, …` without a gap.
        let on = m.rows_on();
        for j in 0..N {
            let first_without = (j..N).find(|&i| usize::from(on[i]) <= j).unwrap_or(N);
            assert!(
                (first_without..N).all(|i| usize::from(on[i]) <= j),
                "step {k}: column {j} has a gap in {on:?}"
            );
        }
    }
}

#[test]
fn a_non_finite_pressure_holds_the_relays() {
    let t = PreisachTable::<4, 1> {
        lo_mpa: 0.0,
        step_mpa: 0.1,
        max_pressure_mpa: 0.4,
        min_load_n: 100.0,
        load_step_n: 100.0,
        grid: [PreisachCoeffs::from_weights(0.0, 0.0, &[[0.01f32; 4]; 4])],
    };
    let mut m = Preisach::new(&t, 100.0, 0.25);
    let before = m.step(&t, 0.25, 100.0);
    assert_eq!(*m.rows_on(), [1, 2, 0, 0]);
    assert_eq!(m.step(&t, f32::NAN, 100.0), before);
    assert_eq!(m.step(&t, f32::INFINITY, 100.0), before);
}

#[test]
fn a_load_switch_interpolates_and_small_changes_do_not() {
    let c = |bias: f32| PreisachCoeffs::<2>::from_weights(bias, 0.1, &[[0.01; 2]; 2]);
    let t = PreisachTable::<2, 2> {
        lo_mpa: 0.0,
        step_mpa: 0.2,
        max_pressure_mpa: 0.4,
        min_load_n: 100.0,
        load_step_n: 100.0,
        grid: [c(0.01), c(0.03)],
    };
    let mut m = Preisach::new(&t, 100.0, 0.0);
    assert!((m.step(&t, 0.0, 100.0 + 0.9 * LOAD_THRESHOLD_N) - 0.01).abs() < 1e-7);
    assert!((m.step(&t, 0.0, 150.0) - 0.02).abs() < 1e-6);
    assert_eq!(m.load_n(), 150.0);
    // Beyond the grid: the last load; a NaN load is ignored.
    assert!((m.step(&t, 0.0, 900.0) - 0.03).abs() < 1e-6);
    assert!((m.step(&t, 0.0, f32::NAN) - 0.03).abs() < 1e-6);
}

#[test]
fn a_load_switch_is_made_a_few_rows_an_update_then_used_whole() {
    // Eight rows, two loads with different weights: the switch takes four
    // updates, the old coefficients are used until it is complete, then
    // the new ones exactly as made at once.
    let c = |s: f32| {
        let w: [[f32; N]; N] =
            core::array::from_fn(|i| core::array::from_fn(|j| s * (1 + i + j) as f32));
        PreisachCoeffs::from_weights(0.01 * s, 0.1 * s, &w)
    };
    let t = PreisachTable::<N, 2> {
        lo_mpa: 0.01,
        step_mpa: 0.06,
        max_pressure_mpa: 0.5,
        min_load_n: 100.0,
        load_step_n: 100.0,
        grid: [c(0.001), c(0.002)],
    };
    let mut spread = Preisach::new(&t, 100.0, 0.0);
    let mut at_once = spread.switch_loads_at_once();
    let before = spread.step(&t, 0.3, 100.0);
    at_once.step(&t, 0.3, 100.0);
    let updates = N / LOAD_SWITCH_ROWS_PER_UPDATE;
    for k in 0..updates {
        let x = spread.step(&t, 0.3, 170.0);
        let y = at_once.step(&t, 0.3, 170.0);
        if k + 1 < updates {
            assert!(spread.switching() && spread.load_n() == 100.0, "{k}");
            assert_eq!(x, before, "{k}: the old load's coefficients, whole");
        } else {
            assert!(!spread.switching() && spread.load_n() == 170.0);
            assert_eq!(x, y, "the new load's, as made at once");
        }
    }
    for k in 0..50 {
        let p = 0.01 * k as f32;
        assert_eq!(spread.step(&t, p, 170.0), at_once.step(&t, p, 170.0), "{p}");
    }
    // A load that moves on before a switch is complete restarts it there.
    spread.step(&t, 0.3, 100.0);
    spread.step(&t, 0.3, 130.0);
    assert!(spread.switching() && spread.load_n() == 170.0);
}

#[test]
fn grid_position_is_clamped() {
    assert_eq!(grid_position(50.0, 100.0, 100.0, 6), (0, 0.0));
    assert_eq!(grid_position(600.0, 100.0, 100.0, 6), (4, 1.0));
    assert_eq!(grid_position(f32::NAN, 100.0, 100.0, 6), (0, 0.0));
    let (k, t) = grid_position(250.0, 100.0, 100.0, 6);
    assert_eq!(k, 1);
    assert!((t - 0.5).abs() < 1e-6);
    assert_eq!(grid_position(100.0, 100.0, 100.0, 1), (0, 0.0));
}

#[test]
fn validation_refuses_what_the_model_cannot_run() {
    let good = table(0.0, 0.1, |_, _| 0.01);
    assert!(good.validate().is_ok());
    let mut t = good;
    t.step_mpa = 0.0;
    assert!(t.validate().is_err());
    let mut t = good;
    t.lo_mpa = f32::NAN;
    assert!(t.validate().is_err());
    let mut t = good;
    t.max_pressure_mpa = 0.4; // below the top threshold 0.01 + 8·0.06
    assert!(t.validate().is_err());
    let mut t = good;
    t.load_step_n = -1.0;
    assert!(t.validate().is_err());
    let mut t = good;
    t.grid[0].everett[3][2] = f32::INFINITY;
    assert!(t.validate().is_err());
    let mut t = good;
    t.grid[0].everett[3][2] = 1e30;
    assert!(t.validate().is_err());
    let mut t = good;
    t.grid[0].linear = -1e3;
    assert!(t.validate().is_err());
}

#[test]
fn the_inverse_returns_the_pressure_the_model_was_driven_to() {
    // Non-negative weights and a positive linear term: the output rises
    // with the pressure on every path, so the pressure that reaches a
    // contraction is unique, and it is the one the model was driven to.
    let t = table(0.01, 0.05, |i, j| {
        0.002 + 0.0005 * ((i * 7 + j * 3) % 5) as f32
    });
    let mut m = Preisach::new(&t, 100.0, 0.0);
    let mut seed = 777u32;
    let mut worst = 0.0f32;
    for k in 0..20_000 {
        // Anywhere in the range, thresholds included.
        let target = if k % 13 == 0 {
            0.01 + 0.06 * (k % 9) as f32
        } else {
            0.5 * uniform(&mut seed)
        };
        let mut moved = m;
        moved.update_state(target);
        let x = moved.output();
        let p = m.inverse_pressure_mpa(x);
        assert!((0.0..=0.5).contains(&p), "{k}: {p}");
        let mut reached = m;
        reached.update_state(p);
        assert_eq!(reached.rows_on(), moved.rows_on(), "{k}: {p} vs {target}");
        worst = worst.max((p - target).abs());
        m = moved;
    }
    // The output's rounding (about 10⁻⁷ of contraction) over the linear
    // term's 0.05 per MPa: a few 10⁻⁶ MPa.
    assert!(worst < 1e-5, "{worst}");
}

#[test]
fn the_inverse_finds_the_first_crossing_with_signed_weights() {
    // Signed weights (an unconstrained least-squares fit): the staircase
    // can step down. The answer still reaches the contraction, and
    // nothing between the present pressure and it does (checked on a
    // fine grid of the path).
    let t = table(0.02, 0.04, |i, j| {
        0.004 * (((i * 5 + j * 11) % 7) as f32 - 2.5)
    });
    let mut m = Preisach::new(&t, 100.0, 0.0);
    let mut seed = 99u32;
    for k in 0..3000 {
        let x_now = m.output();
        let x = x_now + (uniform(&mut seed) - 0.5) * 0.05;
        let p = m.inverse_pressure_mpa(x);
        let p0 = m.last_mpa().clamp(0.0, 0.5);
        let at = |q: f32| {
            let mut s = m;
            s.update_state(q);
            s.output()
        };
        if x >= x_now {
            assert!(p >= p0);
            assert!(at(p) >= x - 1e-6 || p == 0.5, "{k}: {} < {x}", at(p));
            for s in 0..200 {
                let q = p0 + (p - p0) * s as f32 / 200.0;
                assert!(at(q) < x + 1e-6, "{k}: reached at {q} before {p}");
            }
        } else {
            assert!(p <= p0);
            assert!(at(p) <= x + 1e-6 || p == 0.0, "{k}: {} > {x}", at(p));
            for s in 0..200 {
                let q = p0 - (p0 - p) * s as f32 / 200.0;
                assert!(at(q) > x - 1e-6, "{k}: reached at {q} before {p}");
            }
        }
        m.update_state(p);
    }
}

#[test]
fn the_inverse_never_returns_nan_or_leaves_the_range() {
    let t = table(0.0, 0.1, |_, _| 0.01);
    let mut m = Preisach::new(&t, 100.0, 0.3);
    for x in [f32::NAN, f32::INFINITY, f32::NEG_INFINITY, -10.0, 10.0] {
        let p = m.inverse_pressure_mpa(x);
        assert!((0.0..=0.5).contains(&p), "{x}: {p}");
    }
    // Beyond the model's reach: the ends of the range.
    assert_eq!(m.inverse_pressure_mpa(10.0), 0.5);
    assert_eq!(m.inverse_pressure_mpa(-10.0), 0.0);
    // A NaN contraction holds the pressure.
    assert_eq!(m.inverse_pressure_mpa(f32::NAN), 0.3);
    m.update_state(0.7);
    assert_eq!(m.inverse_pressure_mpa(f32::NAN), 0.5);
}

#[test]
fn the_stroke_is_the_output_empty_and_at_the_top_of_the_range() {
    let t = table(0.02, 0.05, |i, j| 0.001 * (1 + i + j) as f32);
    let empty = Preisach::new(&t, 100.0, 0.0);
    let (lo, hi) = empty.stroke();
    assert_eq!(lo, empty.output());
    let full = Preisach::new(&t, 100.0, t.max_pressure_mpa);
    assert!((hi - full.output()).abs() < 1e-6, "{hi} {}", full.output());
    assert!(lo < hi);
}
