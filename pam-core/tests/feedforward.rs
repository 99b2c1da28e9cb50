//! Property tests of [`ModelInverse`]: the forward [`Simulator`] fed the
//! pressures the inverse commands reproduces the desired contraction, for
//! each effect and their combinations, with random parameters within the
//! effects' validation ranges (restricted where stated), and the inverse is
//! finite and within `[0, Pmax]` on any input.

use pam_core::effects::{
    ConstraintShape, Creep, Effects, LoadDependentWidth, NonLocalMemory, PressureDelay,
    PressureLag, RateDependence, MAX_OFFSET_SCALE,
};
use pam_core::{Branch, InverseState, ModelInverse, Simulator, TrackerConfig};
use proptest::prelude::*;

mod common;
use common::{any_f32, coeffs};

/// Control period of the round trips, s (the firmware's 1 kHz).
const DT_S: f32 = 1e-3;

/// Tolerance of the round trip without the rate effect (contraction): the
/// shape's Newton inverse resolves 2·10⁻⁶ of the stroke, the memory's
/// bisection 2·10⁻⁸, the memory's
/// closed form and `f32` rounding leave more.
const TOL: f32 = 2e-4;

/// The periods from a branch switch (a new minor loop) whose errors
/// [`round_trip_by_period`] keeps apart: with the width or the rate effect
/// a new loop's ends start one Newton step from the table inverse and are
/// searched for over the next periods (`ReversalStack::segment_with`).
const NEW_LOOP_PERIODS: usize = 4;

/// Tolerance of the round trip without the rate effect in each of a new
/// minor loop's first [`NEW_LOOP_PERIODS`] periods, where the width puts
/// the offset scale away from 1: the loop's ends start one Newton step from
/// the table inverse and take one more per period until they are within
/// the scaled inverse's resolution (`ReversalStack::segment_with`). About
/// 1.5 times the largest errors measured on 339 random models with the
/// memory and the width (`measure_the_new_loops_first_periods`: 2.9·10⁻²,
/// 9.5·10⁻³, 2.2·10⁻³, 2.3·10⁻⁴; medians 5.9·10⁻⁵, 1.5·10⁻⁷ and below,
/// where the exact ends gave 1.4·10⁻⁶ at most).
const TOL_NEW_LOOP: [f32; NEW_LOOP_PERIODS] = [4e-2, 1.5e-2, 3.5e-3, 3.5e-4];

/// RMS tolerance with the rate effect, which the inverse follows only
/// approximately: its rate is that of the desired motion (the constraint
/// pressure), the model's that of the pressure it is given. The test asks
/// for this, or at most twice the error of the inverse that leaves the
/// rate out (see the test for the measured spread: 1 245 of 1 450 random
/// models within this, 7 worse with the rate term than without).
const TOL_RATE: f32 = 1e-3;

fn memory() -> impl Strategy<Value = Option<NonLocalMemory>> {
    // Shape up to 4: beyond, a minor loop bends back on itself (not
    // monotone in pressure), so a contraction has several pressures (the
    // same restriction as the memory inverse's own property test).
    prop_oneof![
        Just(None),
        (0.5f32..=4.0, prop_oneof![Just(1.0f32), 0.02f32..=1.0])
            .prop_map(|(shape, merge_span)| Some(NonLocalMemory { shape, merge_span })),
    ]
}

fn rate() -> impl Strategy<Value = Option<RateDependence>> {
    // Exponents from 0.5 (what `pam-lab diagnose` fits: 0.5, 0.75, 1):
    // below that the law is so steep near zero rate that the inverse's
    // rate (of the constraint pressure) and the model's (of the commanded
    // pressure, which steps at a branch switch) give scales far apart
    // around every reversal, and the inverse can track worse than one
    // that leaves the rate out (measured: n = 0.3, RMS 0.0039 against
    // 0.0009). The saturation from 0.2 MPa/s (diagnose fits it above the
    // record's fastest ramp, 0.2 MPa/s on the example protocol).
    // Restricted to filter times from the default 0.3 s and growth up to 2
    // at 1 MPa/s: the model driven by a pressure that carries its own rate
    // term feeds that term back through its rate filter, with a gain of
    // about offset × d(scale)/d(rate) / filter time per period; a short
    // filter with a steep law (0.05 s, 4.7·√ṗ) makes that loop ring, and
    // no feedforward reproduces it sample by sample.
    prop_oneof![
        Just(None),
        (
            0.2f32..=2.0,
            0.0f32..=2.0,
            prop_oneof![Just(0.5f32), Just(0.75), Just(1.0), 0.5f32..=1.5],
            0.3f32..=1.0,
            0.2f32..=pam_core::effects::rate::MAX_RATE_MPA_PER_S,
        )
            .prop_map(|(a, b, n, tau, sat)| Some(RateDependence {
                scale_at_rest: a,
                scale_per_mpa_per_s: b,
                exponent: n,
                filter_time_s: tau,
                max_rate_mpa_per_s: sat,
            })),
    ]
}

fn creep() -> impl Strategy<Value = Option<Creep>> {
    // Gain up to 0.5: the inverse's static contraction overshoots the
    // desired one by `g(1 − k)/(1 − g(1 − k))` times the lag's distance from
    // it, which for a larger gain leaves the stroke on these excursions
    // (then the step is commanded as far as the stroke goes and the output
    // lags: no round trip to check). `creep_at_any_gain_round_trips_small_steps`
    // covers the rest of the range.
    prop_oneof![
        Just(None),
        (0.0f32..=0.5, 0.02f32..=100.0).prop_map(|(gain, tau)| Some(Creep {
            gain,
            time_constant_s: tau
        })),
    ]
}

fn width() -> impl Strategy<Value = Option<LoadDependentWidth>> {
    prop_oneof![
        Just(None),
        (0.0f32..=MAX_OFFSET_SCALE, -1.0f32..=1.0).prop_map(|(a, b)| Some(LoadDependentWidth {
            scale_at_min_load: a,
            scale_per_step: b,
        })),
    ]
}

fn shape() -> impl Strategy<Value = Option<ConstraintShape>> {
    prop_oneof![
        Just(None),
        (
            (-0.9f32..=0.9, -1.0f32..=1.0, -0.3f32..=0.3, -0.3f32..=0.3),
            (
                -0.2f32..=0.2,
                -0.2f32..=0.2,
                -0.05f32..=0.05,
                -0.05f32..=0.05
            ),
        )
            .prop_map(|((b, t, bs, ts), (rs, es, rss, ess))| {
                // |bulge| + |tilt| + |end_shift − root_shift| <= 0.9.
                let room = 0.9 - (es - rs).abs();
                let bulge = b * room / 0.9;
                let tilt = t * (room - bulge.abs());
                Some(ConstraintShape {
                    bulge,
                    tilt,
                    bulge_per_step: bs,
                    tilt_per_step: ts,
                    root_shift: rs,
                    end_shift: es,
                    root_shift_per_step: rss,
                    end_shift_per_step: ess,
                    ..ConstraintShape::NEUTRAL
                })
            }),
    ]
}

/// Run the inverse and the simulator along the desired contractions through
/// `turns` (fractions of the stroke), moving `speed` of the stroke per
/// second; returns the largest `|x − x_ref|` and its RMS, or `None` where
/// a desired contraction needs a pressure outside `[0, Pmax]`.
fn round_trip(effects: Effects, load_n: f32, turns: &[f32], speed: f32) -> Option<(f32, f32)> {
    round_trip_with(effects, effects, load_n, turns, speed)
}

/// [`round_trip`] with the inverse of the model with `inverted`.
fn round_trip_with(
    effects: Effects,
    inverted: Effects,
    load_n: f32,
    turns: &[f32],
    speed: f32,
) -> Option<(f32, f32)> {
    round_trip_by_period(effects, inverted, load_n, turns, speed).map(|r| (r.worst, r.rms))
}

/// What [`round_trip_by_period`] measures.
struct RoundTrip {
    /// The largest `|x − x_ref|` outside the first [`NEW_LOOP_PERIODS`]
    /// periods of each minor loop.
    worst: f32,
    /// Its RMS over every period.
    rms: f32,
    /// The largest `|x − x_ref|` in the `k`-th period of a minor loop
    /// (from the branch switch that starts it), `k` < [`NEW_LOOP_PERIODS`].
    new_loop: [f32; NEW_LOOP_PERIODS],
}

/// [`round_trip_with`], with the errors of each minor loop's first periods
/// apart.
fn round_trip_by_period(
    effects: Effects,
    inverted: Effects,
    load_n: f32,
    turns: &[f32],
    speed: f32,
) -> Option<RoundTrip> {
    let c = coeffs();
    let inverse = ModelInverse::new(inverted, DT_S).unwrap();
    let mut state = InverseState::<8>::default();
    let mut sim = Simulator::<8>::new(c, effects, TrackerConfig::DEFAULT_PRESSURE, load_n).unwrap();
    let model = c.load_model(load_n).unwrap();
    let (r, s) = (
        model.root_contraction(),
        model.max_contraction() - model.root_contraction(),
    );
    let step = speed * DT_S;
    let mut u = turns.first().copied().unwrap_or(0.5);
    let mut branch = Branch::Contraction;
    let mut k = 0u32;
    let mut worst = 0.0f32;
    let mut sum_sq = 0.0f64;
    let mut new_loop = [0.0f32; NEW_LOOP_PERIODS];
    // Periods since the last branch switch (none before the first).
    let mut since_switch = NEW_LOOP_PERIODS;
    for &target in turns.iter().skip(1) {
        let dir = if target > u {
            Branch::Contraction
        } else {
            Branch::Expansion
        };
        while (target - u).abs() > 1e-7 {
            u += (target - u).clamp(-step, step);
            let switch = dir != branch;
            branch = dir;
            since_switch = if switch {
                0
            } else {
                since_switch.saturating_add(1)
            };
            let x_ref = r + s * u;
            let p = inverse.pressure_mpa(
                &mut state,
                c.params(),
                &model,
                load_n,
                x_ref,
                branch,
                switch,
            );
            let x = sim.step_on_branch(k as f32 * DT_S, p, load_n, branch);
            k += 1;
            // A wide loop (width or rate scale up to 4) puts a branch
            // beyond [0, Pmax] over part of the stroke, where no pressure
            // holds x_ref and the inverse commands the nearest end; from
            // there the memories of the inverse and the model differ.
            if !(p > 0.0 && p < model.max_pressure_mpa()) {
                return None;
            }
            match new_loop.get_mut(since_switch) {
                Some(w) => *w = w.max((x - x_ref).abs()),
                None => worst = worst.max((x - x_ref).abs()),
            }
            sum_sq += f64::from(x - x_ref).powi(2);
        }
    }
    Some(RoundTrip {
        worst,
        rms: (sum_sq / f64::from(k.max(1))).sqrt() as f32,
        new_loop,
    })
}

/// 0.5 of the stroke first, then turning points within `[0.3, 0.7]` (away
/// from the stroke ends, where a branch clamped at `Pmax` is flat in
/// pressure and the model has no inverse).
fn turns() -> impl Strategy<Value = Vec<f32>> {
    proptest::collection::vec(0.3f32..=0.7, 1..7).prop_map(|mut v| {
        v.insert(0, 0.5);
        v
    })
}

/// The round trip's random cases as the property test draws them: each
/// effect or none, the load, the set-point's turning points and speed.
#[allow(clippy::type_complexity)]
fn round_trip_cases() -> (
    impl Strategy<Value = Option<NonLocalMemory>>,
    impl Strategy<Value = Option<RateDependence>>,
    impl Strategy<Value = Option<Creep>>,
    impl Strategy<Value = Option<LoadDependentWidth>>,
    impl Strategy<Value = Option<ConstraintShape>>,
    std::ops::RangeInclusive<f32>,
    impl Strategy<Value = Vec<f32>>,
    std::ops::RangeInclusive<f32>,
) {
    (
        memory(),
        rate(),
        creep(),
        width(),
        shape(),
        100.0f32..=600.0,
        turns(),
        0.05f32..=1.0,
    )
}

proptest! {
    // A fixed seed: the rate term's check is an envelope measured over
    // random models (below), not a bound that holds for every model, so
    // the cases are the same on every run.
    #![proptest_config(ProptestConfig {
        cases: 300,
        rng_seed: proptest::test_runner::RngSeed::Fixed(0x7061_6d14),
        ..ProptestConfig::default()
    })]

    /// Each effect alone and any combination.
    #[test]
    fn the_simulator_reproduces_the_desired_contraction(
        memory in memory(),
        rate in rate(),
        creep in creep(),
        width in width(),
        shape in shape(),
        load_n in 100.0f32..=600.0,
        turns in turns(),
        speed in 0.05f32..=1.0,
    ) {
        let effects = Effects { memory, rate, creep, width, shape, pressure_lag: None, pressure_delay: None };
        let r = round_trip_by_period(effects, effects, load_n, &turns, speed);
        prop_assume!(r.is_some(), "a pressure outside [0, Pmax] is needed");
        let Some(RoundTrip { worst, rms, new_loop }) = r else { return Ok(()) };
        if rate.is_none() {
            prop_assert!(worst <= TOL, "{worst} > {TOL}: {effects:?}");
            // A new loop's first periods: exact ends at the paper's scale
            // (without the width), searched for over periods with it.
            for (k, e) in new_loop.into_iter().enumerate() {
                let tol = if width.is_some() { TOL_NEW_LOOP[k] } else { TOL };
                prop_assert!(e <= tol, "period {k} of a new loop: {e} > {tol}: {effects:?}");
            }
        } else {
            // Approximate (see `TOL_RATE`). Measured over 1 450 random
            // models of these strategies (3 000 cases, seeds 1–3 of
            // `measure_the_rate_inverse_against_the_one_without_it`, with
            // the rate filter's state bounded at the saturation): the RMS
            // is a median 0.027 of the inverse's that leaves the rate
            // effect out, worse than it in 7 models (0.48 %: a saturated
            // or very wide loop, where the model's rate of the commanded
            // pressure, which steps at a branch switch, and the inverse's
            // rate of the constraint pressure part most), at most 1.37x;
            // 1 245 within `TOL_RATE`. Checked: within the tolerance, or
            // within twice that error.
            let without = Effects { rate: None, ..effects };
            let rms_without = round_trip_with(effects, without, load_n, &turns, speed)
                .map_or(f32::INFINITY, |r| r.1);
            prop_assert!(
                rms <= TOL_RATE.max(2.0 * rms_without),
                "rms {rms} (worst {worst}), without the rate effect {rms_without}: {effects:?}"
            );
        }
    }

    /// Creep over its whole validated gain on excursions small enough that
    /// the static contraction stays in the stroke.
    #[test]
    fn creep_at_any_gain_round_trips_small_steps(
        gain in 0.0f32..=0.95,
        tau in 0.02f32..=100.0,
        memory in memory(),
        load_n in 100.0f32..=600.0,
        turns in proptest::collection::vec(0.48f32..=0.52, 1..5),
    ) {
        let effects = Effects {
            memory,
            creep: Some(Creep { gain, time_constant_s: tau }),
            ..Effects::NONE
        };
        let mut t = vec![0.5];
        t.extend(turns);
        let r = round_trip(effects, load_n, &t, 0.2);
        prop_assume!(r.is_some(), "a pressure outside [0, Pmax] is needed");
        let Some((worst, _)) = r else { return Ok(()) };
        prop_assert!(worst <= TOL, "{worst}: {effects:?}");
    }

    /// The pressure lag over the time constants of a line, with the other
    /// bounded effects, on a sweep without a reversal (at a reversal the
    /// model's pressure steps by the loop's height, which a lag cannot
    /// follow within a period: the command is clamped there, and the case
    /// is left out).
    #[test]
    fn a_pressure_lag_round_trips(
        tau in 0.001f32..=0.05,
        memory in memory(),
        creep in creep(),
        shape in shape(),
        load_n in 100.0f32..=600.0,
        target in 0.55f32..=0.7,
        speed in 0.05f32..=0.3,
    ) {
        let effects = Effects {
            memory,
            creep,
            shape,
            pressure_lag: Some(PressureLag { time_constant_s: tau }),
            ..Effects::NONE
        };
        let r = round_trip(effects, load_n, &[0.5, target], speed);
        prop_assume!(r.is_some(), "a pressure outside [0, Pmax] is needed");
        let Some((worst, _)) = r else { return Ok(()) };
        prop_assert!(worst <= TOL, "{worst}: {effects:?}");
    }

    /// Any input: finite, within `[0, Pmax]`.
    #[test]
    fn the_inverse_is_finite_on_any_input(
        memory in memory(),
        rate in rate(),
        creep in creep(),
        width in width(),
        shape in shape(),
        lag in proptest::option::of(0.001f32..=0.5),
        delay in proptest::option::of(0.0005f32..=0.1),
        load in any_f32(),
        xs in proptest::collection::vec((any_f32(), any::<bool>(), any::<bool>()), 1..40),
    ) {
        let pressure_lag = lag.map(|time_constant_s| PressureLag { time_constant_s });
        let pressure_delay = delay.map(|delay_s| PressureDelay { delay_s });
        let effects = Effects { memory, rate, creep, width, shape, pressure_lag, pressure_delay };
        let c = coeffs();
        let inverse = ModelInverse::new(effects, DT_S).unwrap();
        let mut state = InverseState::<4>::default();
        let model = c.load_model_clamped(load);
        for (x, rising, switch) in xs {
            let br = if rising { Branch::Contraction } else { Branch::Expansion };
            let p = inverse.pressure_mpa(&mut state, c.params(), &model, load, x, br, switch);
            prop_assert!(p.is_finite() && (0.0..=model.max_pressure_mpa()).contains(&p), "{p}");
        }
    }
}

#[test]
fn without_effects_the_inverse_is_the_paper_model() {
    let c = coeffs();
    let inverse = ModelInverse::new(Effects::NONE, DT_S).unwrap();
    let mut state = InverseState::<4>::default();
    let m = c.load_model(300.0).unwrap();
    for k in 0..=100 {
        let x =
            m.root_contraction() + (m.max_contraction() - m.root_contraction()) * k as f32 / 100.0;
        for br in [Branch::Contraction, Branch::Expansion] {
            let p = inverse.pressure_mpa(&mut state, c.params(), &m, 300.0, x, br, false);
            assert_eq!(p, m.pressure_mpa(x, br));
        }
    }
}

/// A pressure delay leads the command as a lag of the delay's length does
/// (the delay's first-order lead: the feedforward has no future
/// set-point), and with a lag beside it as one lag of the two summed: on a
/// ramp the command runs ahead of the model's pressure by the ramp's rate
/// times the delay.
#[test]
fn a_pressure_delay_leads_the_command_as_a_lag_of_its_length() {
    let c = coeffs();
    let m = c.load_model(300.0).unwrap();
    let with = |pressure_lag, pressure_delay| {
        let inverse = ModelInverse::new(
            Effects {
                pressure_lag,
                pressure_delay,
                ..Effects::NONE
            },
            DT_S,
        )
        .unwrap();
        let mut state = InverseState::<4>::default();
        (0..=400)
            .map(|k| {
                let x = m.root_contraction()
                    + (m.max_contraction() - m.root_contraction()) * 0.2 * (1.0 + k as f32 / 400.0);
                (
                    inverse.pressure_mpa(
                        &mut state,
                        c.params(),
                        &m,
                        300.0,
                        x,
                        Branch::Contraction,
                        false,
                    ),
                    m.pressure_mpa(x, Branch::Contraction),
                )
            })
            .collect::<Vec<_>>()
    };
    let delayed = with(None, Some(PressureDelay { delay_s: 0.012 }));
    let lagged = with(
        Some(PressureLag {
            time_constant_s: 0.012,
        }),
        None,
    );
    assert_eq!(delayed, lagged);
    let both = with(
        Some(PressureLag {
            time_constant_s: 0.008,
        }),
        Some(PressureDelay { delay_s: 0.004 }),
    );
    for (a, b) in both.iter().zip(&lagged) {
        assert!((a.0 - b.0).abs() < 1e-6, "{a:?} {b:?}");
    }
    // Ahead of the model's pressure by about its rate times the delay.
    let rate = (delayed[300].1 - delayed[299].1) / DT_S;
    let lead = delayed[300].0 - delayed[300].1;
    assert!(
        (lead - 0.012 * rate).abs() < 0.1 * (0.012 * rate).abs(),
        "{lead} vs {}",
        0.012 * rate
    );
}

#[test]
fn a_bad_period_or_effect_is_refused() {
    assert!(ModelInverse::new(Effects::NONE, 0.0).is_err());
    assert!(ModelInverse::new(Effects::NONE, f32::NAN).is_err());
    assert!(ModelInverse::new(Effects::NONE, 2.0).is_err());
    let bad = Effects {
        creep: Some(Creep {
            gain: 1.5,
            time_constant_s: 1.0,
        }),
        ..Effects::NONE
    };
    assert!(ModelInverse::new(bad, DT_S).is_err());
}

/// Not a check: measures the spread quoted at `TOL_RATE` and in
/// `the_simulator_reproduces_the_desired_contraction` (how the inverse with
/// the rate term compares with the one that leaves it out, over random
/// models of these strategies, seeds 1..=`PAM_RATE_SEEDS`, 1 000 cases
/// each). Run: `cargo test --release -p pam-core --test feedforward --
/// --ignored measure_the_rate_inverse --nocapture`.
#[test]
#[ignore]
fn measure_the_rate_inverse_against_the_one_without_it() {
    use proptest::strategy::ValueTree;
    use proptest::test_runner::{Config, RngAlgorithm, TestRng, TestRunner};
    let seeds: u64 = std::env::var("PAM_RATE_SEEDS")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(3);
    let strategy = round_trip_cases();
    let mut ratios = Vec::new();
    let mut within = 0usize;
    for seed in 1..=seeds {
        let mut bytes = [0u8; 32];
        bytes[..8].copy_from_slice(&seed.to_le_bytes());
        let rng = TestRng::from_seed(RngAlgorithm::ChaCha, &bytes);
        let mut runner = TestRunner::new_with_rng(Config::default(), rng);
        for _ in 0..1000 {
            let (memory, rate, creep, width, shape, load_n, turns, speed) =
                strategy.new_tree(&mut runner).unwrap().current();
            if rate.is_none() {
                continue;
            }
            let effects = Effects {
                memory,
                rate,
                creep,
                width,
                shape,
                pressure_lag: None,
                pressure_delay: None,
            };
            let Some((_, rms)) = round_trip(effects, load_n, &turns, speed) else {
                continue;
            };
            let without = Effects {
                rate: None,
                ..effects
            };
            let Some((_, rms_without)) = round_trip_with(effects, without, load_n, &turns, speed)
            else {
                continue;
            };
            if rms <= TOL_RATE {
                within += 1;
            }
            ratios.push(f64::from(rms) / f64::from(rms_without).max(1e-12));
        }
    }
    ratios.sort_by(f64::total_cmp);
    let n = ratios.len();
    let worse = ratios.iter().filter(|r| **r > 1.0).count();
    println!(
        "{n} models with a rate law: RMS ratio to the inverse without it: median {:.3}, \
         worse in {worse} ({:.2} %), at most {:.2}x; within TOL_RATE {within}",
        ratios.get(n / 2).copied().unwrap_or(f64::NAN),
        100.0 * worse as f64 / n.max(1) as f64,
        ratios.last().copied().unwrap_or(f64::NAN),
    );
    assert!(n > 0, "no model with a rate law ran");
}

/// Measures a new minor loop's first periods against the rest of the round
/// trip, over random models of these strategies with the memory and the
/// width or the rate effect (those whose new loops search for their ends,
/// `ReversalStack::segment_with`): the largest error in each of the
/// [`NEW_LOOP_PERIODS`] periods from a branch switch, and elsewhere. Run:
/// `cargo test --release -p pam-core --test feedforward -- --ignored
/// measure_the_new_loops --nocapture`.
#[test]
#[ignore]
fn measure_the_new_loops_first_periods() {
    use proptest::strategy::ValueTree;
    use proptest::test_runner::{Config, RngAlgorithm, TestRng, TestRunner};
    let strategy = round_trip_cases();
    // [without a rate law, with one]
    let mut by_period = [
        [(); NEW_LOOP_PERIODS].map(|_| Vec::new()),
        [(); NEW_LOOP_PERIODS].map(|_| Vec::new()),
    ];
    let mut elsewhere = [Vec::new(), Vec::new()];
    for seed in 1..=3u64 {
        let mut bytes = [0u8; 32];
        bytes[..8].copy_from_slice(&seed.to_le_bytes());
        let rng = TestRng::from_seed(RngAlgorithm::ChaCha, &bytes);
        let mut runner = TestRunner::new_with_rng(Config::default(), rng);
        for _ in 0..1000 {
            let (memory, rate, creep, width, shape, load_n, turns, speed) =
                strategy.new_tree(&mut runner).unwrap().current();
            if memory.is_none() || (rate.is_none() && width.is_none()) {
                continue;
            }
            let effects = Effects {
                memory,
                rate,
                creep,
                width,
                shape,
                pressure_lag: None,
                pressure_delay: None,
            };
            let Some(r) = round_trip_by_period(effects, effects, load_n, &turns, speed) else {
                continue;
            };
            let with_rate = usize::from(rate.is_some());
            for (v, e) in by_period[with_rate].iter_mut().zip(r.new_loop) {
                v.push(e);
            }
            elsewhere[with_rate].push(r.worst);
        }
    }
    let stats = |v: &mut Vec<f32>| {
        v.sort_by(f32::total_cmp);
        let q = |f: f64| {
            v.get(((v.len() as f64 - 1.0) * f) as usize)
                .copied()
                .unwrap_or(f32::NAN)
        };
        format!(
            "median {:.1e}, 99 % {:.1e}, max {:.1e}",
            q(0.5),
            q(0.99),
            q(1.0)
        )
    };
    for (i, what) in ["the width (no rate law)", "a rate law"]
        .into_iter()
        .enumerate()
    {
        println!("{} models with the memory and {what}", elsewhere[i].len());
        for (k, v) in by_period[i].iter_mut().enumerate() {
            println!("  period {k} of a new loop: {}", stats(v));
        }
        println!("  elsewhere: {}", stats(&mut elsewhere[i]));
    }
}
