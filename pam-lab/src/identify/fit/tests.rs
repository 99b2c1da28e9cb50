//! Tests of the fit.

use super::*;
use crate::synth::{generate, Protocol};

fn fixed() -> Fixed {
    Fixed {
        pmax: 0.5,
        min_load_n: 100.0,
        max_load_n: 600.0,
        load_step_n: 100.0,
    }
}

#[test]
fn the_anchor_is_a_valid_model_for_any_stroke() {
    let f = fixed();
    for (r1, rx1) in [(0.0, 0.2), (-0.3, 0.9), (0.1, 0.1011), (0.5, 0.95)] {
        for be in [0.0, 0.01, 0.2] {
            let a = anchor(r1, rx1, be, f.pmax);
            assert!(feasible(&a, &f), "{r1} {rx1} {be}");
            Coeffs::new(export(&a, &f)).unwrap();
        }
    }
}

#[test]
fn the_projection_always_lands_on_a_valid_model() {
    // Points far outside the feasible set in every direction.
    let f = fixed();
    let a = anchor(0.02, 0.22, 0.02, f.pmax);
    let mut rng = crate::synth::Rng::new(5);
    for _ in 0..2000 {
        let t: Vec<f64> = (0..NP)
            .map(|j| a[j] + param_scale(j, &f) * 20.0 * (rng.uniform() - 0.5))
            .collect();
        let (p, inside) = project(&t, &a, &f);
        assert!(feasible(&p, &f));
        assert_eq!(inside, feasible(&t, &f));
    }
}

#[test]
fn theta_parametrisation_round_trips_through_export() {
    let coeffs = Coeffs::new(Params::DEFAULT).unwrap();
    let fam = *coeffs.family();
    let m = fam.at_load(fam.min_load_n);
    let s = fam.max_contraction - fam.root_contraction;
    let theta = [
        fam.root_contraction,
        fam.max_contraction,
        m.cubic.eval(fam.root_contraction + U1 * s),
        m.cubic.eval(fam.root_contraction + U2 * s),
        fam.root_regression_per_step,
        fam.max_regression_per_step,
        fam.c_growth_per_step,
        fam.ellipse_height_mpa,
    ];
    let fx = Fixed {
        pmax: fam.max_pressure_mpa,
        min_load_n: fam.min_load_n,
        max_load_n: fam.max_load_n,
        load_step_n: fam.load_step_n,
    };
    let back = family(&theta, &fx);
    assert!(
        (back.b - fam.b).abs() < 1e-6 * fam.b.abs(),
        "{back:?} {fam:?}"
    );
    assert!((back.c - fam.c).abs() < 1e-6 * fam.c.abs().max(1.0));
    let c2 = Coeffs::new(export(&theta, &fx)).unwrap();
    let (m1, m2) = (
        coeffs.load_model(300.0).unwrap(),
        c2.load_model(300.0).unwrap(),
    );
    for k in 0..=50 {
        let x = 0.02 + 0.2 * k as f32 / 50.0;
        let d = m1.pressure_mpa(x, Branch::Contraction) - m2.pressure_mpa(x, Branch::Contraction);
        assert!(d.abs() < 1e-4, "x {x}: {d}");
    }
}

#[test]
fn holdout_parses_and_masks() {
    assert_eq!("every:4".parse(), Ok(Holdout::EveryKthCycle(4)));
    assert_eq!("tail:0.2".parse(), Ok(Holdout::Tail(0.2)));
    assert_eq!("none".parse(), Ok(Holdout::None));
    assert!("every:1".parse::<Holdout>().is_err());
    assert!("tail:1.5".parse::<Holdout>().is_err());
    assert_eq!(
        heldout_mask(Holdout::EveryKthCycle(2), &[0, 0, 1, 1, 2, 3]),
        vec![false, false, true, true, false, true]
    );
    assert_eq!(
        heldout_mask(Holdout::Tail(0.25), &[0; 8]),
        vec![false, false, false, false, false, false, true, true]
    );
}

#[test]
fn noise_free_data_recovers_the_parameters() {
    let truth = Params::DEFAULT;
    let rec = generate(
        &truth,
        &Protocol::quick(&[100.0, 300.0, 600.0]),
        0.0,
        0.0,
        1,
    );
    let r = fit(&rec, &FitConfig::default()).unwrap();
    assert_eq!(r.test_kind, TestKind::Isotonic);
    assert!(r.test.total.pressure_rms_mpa < 1e-3, "{}", r.test.to_text());
    let p = r.params;
    assert!(
        (p.points.root_contraction - truth.points.root_contraction).abs() < 5e-4,
        "{p:?}"
    );
    assert!(
        (p.points.max_contraction - truth.points.max_contraction).abs() < 1e-3,
        "{p:?}"
    );
    assert!(
        (p.ellipse_height_mpa - truth.ellipse_height_mpa).abs() < 1e-3,
        "{p:?}"
    );
    assert!(!r.shape.cubic_cannot_follow(), "{}", r.shape.statement());
}

#[test]
fn a_muscle_of_the_papers_family_gets_no_static_shape() {
    // Noisy records of the paper's own model: the cubic follows them, the
    // stroke table is neither tried nor written (the paper's model, blob
    // version 1).
    for seed in 1..=3 {
        let rec = generate(
            &Params::DEFAULT,
            &Protocol::quick(&[100.0, 300.0, 600.0]),
            0.002,
            0.0005,
            seed,
        );
        let r = fit(&rec, &FitConfig::default()).unwrap();
        assert!(r.constraint_shape.is_none(), "{}", r.shape.statement());
        assert_eq!(r.effects(), pam_core::Effects::NONE);
    }
}

#[test]
fn one_load_only_is_refused_with_a_clear_message() {
    let rec = generate(
        &Params::DEFAULT,
        &Protocol::quick(&[100.0]),
        0.001,
        0.0005,
        3,
    );
    let e = fit(&rec, &FitConfig::default()).unwrap_err();
    let msg = e.to_string();
    assert!(
        msg.starts_with("generated: column `load_n`: too few samples"),
        "{msg}"
    );
    assert!(msg.contains("one load only"), "{msg}");
}

#[test]
fn settings_out_of_range_are_refused_before_any_work() {
    let rec = Record::from_samples("empty", Vec::new());
    let cases: [(&str, FitConfig); 6] = [
        (
            "--load-step",
            FitConfig {
                load_step_n: 0.0,
                ..FitConfig::default()
            },
        ),
        (
            "--load-step",
            FitConfig {
                load_step_n: f64::NAN,
                ..FitConfig::default()
            },
        ),
        (
            "--load-step",
            FitConfig {
                load_step_n: 1e-9,
                ..FitConfig::default()
            },
        ),
        (
            "--load-bin",
            FitConfig {
                load_bin_n: -5.0,
                ..FitConfig::default()
            },
        ),
        (
            "--pmax",
            FitConfig {
                max_pressure_mpa: Some(f64::INFINITY),
                ..FitConfig::default()
            },
        ),
        (
            "--deadband",
            FitConfig {
                split: SplitConfig {
                    deadband_mpa: Some(-1.0),
                    ..SplitConfig::default()
                },
                ..FitConfig::default()
            },
        ),
    ];
    for (option, cfg) in cases {
        match fit(&rec, &cfg) {
            Err(FitError::Config { option: o, .. }) => assert_eq!(o, option),
            other => panic!("{option}: {other:?}"),
        }
    }
}

#[test]
fn degenerate_records_are_refused_with_the_channel_named() {
    let good = generate(
        &Params::DEFAULT,
        &Protocol::quick(&[100.0, 300.0]),
        0.001,
        0.0005,
        3,
    );
    let with = |f: &dyn Fn(&mut Sample)| {
        let mut s = good.samples.clone();
        s.iter_mut().for_each(f);
        Record::from_samples("rec.csv", s)
    };
    for (rec, column) in [
        (with(&|s| s.contraction = 0.0), "contraction"),
        (with(&|s| s.pressure_mpa = 0.2), "pressure_mpa"),
        (with(&|s| s.t_s = 0.0), "t_s"),
        (with(&|s| s.load_n = 200.0), "load_n"),
    ] {
        let e = fit(&rec, &FitConfig::default()).unwrap_err();
        let msg = e.to_string();
        assert!(
            msg.starts_with(&format!("rec.csv: column `{column}`: ")),
            "{column}: {msg}"
        );
    }
}
