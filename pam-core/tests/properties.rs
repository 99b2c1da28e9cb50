//! Property tests over the whole f32 domain (NaN, ±inf, subnormals and
//! out-of-range values included) for every public evaluation function.

use pam_core::load_model::INVERSE_TOLERANCE_MPA;
use pam_core::{blob, Branch, Coeffs, Params, Tracker, TrackerConfig};
use proptest::prelude::*;

mod common;
use common::{any_f32, coeffs};

fn branch() -> impl Strategy<Value = Branch> {
    prop_oneof![Just(Branch::Contraction), Just(Branch::Expansion)]
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(2000))]

    #[test]
    fn forward_is_finite_and_within_zero_to_pmax(x in any_f32(), load in any_f32(), br in branch()) {
        let m = coeffs().load_model_clamped(load);
        let p = m.pressure_mpa(x, br);
        prop_assert!(p.is_finite());
        let pmax = Params::DEFAULT.points.max_pressure_mpa;
        prop_assert!((0.0..=pmax).contains(&p), "p = {p}");
        let cm = m.constraint_pressure_mpa(x);
        prop_assert!(cm.is_finite());
        prop_assert!(m.offset_mpa(x).is_finite() && m.offset_mpa(x) >= 0.0);
    }

    #[test]
    fn inverse_is_finite_and_within_the_stroke(p in any_f32(), load in any_f32(), br in branch()) {
        let m = coeffs().load_model_clamped(load);
        let x = m.contraction(p, br);
        prop_assert!(x.is_finite());
        prop_assert!(x >= m.root_contraction() && x <= m.max_contraction());
    }

    #[test]
    fn forward_of_inverse_is_identity(t in 0.0f32..=1.0, load in 100.0f32..=600.0, br in branch()) {
        let m = coeffs().load_model(load).unwrap();
        // The whole operating range, Pmax included.
        let p = t * m.max_pressure_mpa();
        let x = m.contraction(p, br);
        let back = m.pressure_mpa(x, br);
        // Where the branch is increasing (everywhere on the default muscle's
        // clamped branches, up to and including Pmax) the round trip is exact
        // to the stated tolerance.
        prop_assert!((back - p).abs() <= INVERSE_TOLERANCE_MPA, "p {p} -> x {x} -> {back}");
    }

    #[test]
    fn inverse_of_forward_is_identity_where_monotone(t in 0.05f32..0.95, load in 100.0f32..=600.0, br in branch()) {
        let m = coeffs().load_model(load).unwrap();
        let x = m.root_contraction() + t * (m.max_contraction() - m.root_contraction());
        let p = m.pressure_mpa(x, br);
        // Away from the clamped ends the branch is strictly increasing, so the
        // contraction comes back; the error is the pressure tolerance over the slope.
        prop_assume!(p > 0.0 && p < m.max_pressure_mpa());
        let back = m.contraction(p, br);
        prop_assert!((back - x).abs() <= 2e-3, "x {x} -> p {p} -> {back}");
    }

    #[test]
    fn load_model_errors_never_panic(load in any_f32()) {
        let c = coeffs();
        match c.load_model(load) {
            Ok(m) => prop_assert!(c.load_in_range(load) && m.load_n() == load),
            Err(_) => prop_assert!(!c.load_in_range(load)),
        }
    }

    #[test]
    fn arbitrary_params_never_panic(v in proptest::collection::vec(any_f32(), 14)) {
        let p = Params {
            min_load_n: v[0], max_load_n: v[1], load_step_n: v[2],
            points: pam_core::CriticalPoints {
                root_contraction: v[3], max_contraction: v[4], max_pressure_mpa: v[5],
                tangency: pam_core::Point { contraction: v[6], pressure_mpa: v[7] },
                inflection: pam_core::Point { contraction: v[8], pressure_mpa: v[9] },
            },
            root_regression_per_step: v[10], max_regression_per_step: v[11],
            c_growth_per_step: v[12], ellipse_height_mpa: v[13],
        };
        if let Ok(c) = Coeffs::new(p) {
            let m = c.load_model_clamped(v[0]);
            prop_assert!(m.pressure_mpa(v[3], Branch::Contraction).is_finite());
            prop_assert!(m.contraction(v[5], Branch::Expansion).is_finite());
        }
    }

    #[test]
    fn arbitrary_blobs_never_panic(bytes in proptest::collection::vec(any::<u8>(), 0..130)) {
        let _ = blob::decode(&bytes);
        let _ = blob::decode_model(&bytes);
        let _ = blob::framed_len(&bytes);
    }

    /// A version-2 frame around arbitrary payload bytes (so the CRC passes
    /// and the flags and fields are what gets tested): never panics, and
    /// what decodes re-encodes to the same bytes.
    #[test]
    fn framed_v2_payloads_decode_or_are_refused(payload in proptest::collection::vec(any::<u8>(), blob::PAYLOAD_V2_LEN)) {
        let mut b = [0u8; blob::BLOB_V2_LEN];
        b[0..4].copy_from_slice(&blob::BLOB_MAGIC);
        b[4..6].copy_from_slice(&blob::BLOB_VERSION_V2.to_le_bytes());
        b[6..8].copy_from_slice(&(blob::PAYLOAD_V2_LEN as u16).to_le_bytes());
        b[8..8 + blob::PAYLOAD_V2_LEN].copy_from_slice(&payload);
        let crc = blob::crc32(&b[..8 + blob::PAYLOAD_V2_LEN]);
        b[8 + blob::PAYLOAD_V2_LEN..].copy_from_slice(&crc.to_le_bytes());
        if let Ok((c, e)) = blob::decode_model(&b) {
            prop_assert_eq!(&blob::encode_v2(c.params(), &e)[..], &b[..]);
        }
    }

    #[test]
    fn tracker_never_panics(samples in proptest::collection::vec((any_f32(), any_f32()), 1..200)) {
        let c = coeffs();
        let mut t = Tracker::new(&c, TrackerConfig::DEFAULT_PRESSURE, 100.0, Branch::Contraction).unwrap();
        for (d, l) in samples {
            t.update(&c, d, l);
            prop_assert!(c.load_in_range(t.load_n()));
        }
    }

    #[test]
    fn tracker_never_flips_on_noise_below_the_deadband(
        level in 0.0f32..=0.501,
        noise in proptest::collection::vec(-0.5f32..0.5, 1..500),
        br in branch(),
    ) {
        let c = coeffs();
        let cfg = TrackerConfig::DEFAULT_PRESSURE;
        let mut t = Tracker::new(&c, cfg, 200.0, br).unwrap();
        // Peak-to-peak noise strictly below the deadband.
        for n in noise {
            let u = t.update(&c, level + n * 0.99 * cfg.direction_deadband, 200.0);
            prop_assert!(u.branch_switch.is_none());
        }
        prop_assert_eq!(t.branch(), br);
    }
}

mod memory_inverse {
    use super::*;
    use pam_core::effects::{NonLocalMemory, Reversal, ReversalStack};

    /// A stack left by a pressure history through `turns` (alternating
    /// direction, starting upwards from 0 MPa): at each turn the curve's
    /// contraction there is pushed as the reversal, as a controller or the
    /// simulator does.
    fn history(
        mem: &NonLocalMemory,
        m: &pam_core::LoadModel,
        turns: &[f32],
    ) -> (ReversalStack<8>, Branch) {
        let mut stack = ReversalStack::<8>::default();
        let mut br = Branch::Contraction;
        let mut last = 0.0f32;
        for &p in turns {
            let rising = p > last;
            if rising != (br == Branch::Contraction) {
                // The pressure turned at `last`: push it on the old branch's curve.
                let x = stack.contraction(mem, m, last, br, 1.0);
                stack.push(Reversal {
                    pressure_mpa: last,
                    contraction: x,
                });
                br = br.opposite();
            }
            stack.contraction(mem, m, p, br, 1.0);
            last = p;
        }
        (stack, br)
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(3000))]

        /// The memory inverse undoes the memory's forward curve: at the
        /// pressure it returns, the curve (with its own wiping-out) is at the
        /// contraction asked for, wherever the curve reaches it without a
        /// jump.
        #[test]
        fn memory_inverse_reaches_the_contraction(
            turns in proptest::collection::vec(0.0f32..=0.5, 0..10),
            t in 0.0f32..=1.0,
            load in 100.0f32..=600.0,
            // Up to 4: beyond it a minor loop bends back on itself (not
            // monotone in pressure), so a contraction has several pressures
            // and the one the inverse picks may lie where a wipe-out moves
            // the curve (seen at shape 19.9: 1.9e-3 off). The finiteness
            // test below covers every shape.
            shape in 0.5f32..=4.0,
            merge_span in prop_oneof![Just(1.0f32), 0.02f32..=1.0],
            br in branch(),
        ) {
            let m = coeffs().load_model(load).unwrap();
            let mem = NonLocalMemory { shape, merge_span };
            let (stack, last_br) = history(&mem, &m, &turns);
            // Keep going on the current branch or reverse at the last point.
            let mut stack = stack;
            if br != last_br {
                let p = *turns.last().unwrap_or(&0.0);
                let x = stack.contraction(&mem, &m, p, last_br, 1.0);
                stack.push(Reversal { pressure_mpa: p, contraction: x });
            }
            let x_ref = m.root_contraction() + t * (m.max_contraction() - m.root_contraction());
            let p = stack.inverse_pressure_mpa(&mem, &m, x_ref, br, 1.0);
            prop_assert!(p.is_finite() && (0.0..=m.max_pressure_mpa()).contains(&p), "p {p}");
            // The cached loop gives the same answer.
            prop_assert_eq!(stack.inverse_pressure_mpa(&mem, &m, x_ref, br, 1.0), p);
            let at = |p: f32| {
                let mut trial = stack;
                trial.contraction(&mem, &m, p, br, 1.0)
            };
            // Wherever the curve passes through x_ref continuously (two
            // neighbouring grid pressures bracket it without a jump; the
            // branch inverse jumps where a clamped branch is flat, and a
            // minor loop with a large shape need not be monotone), the
            // inverse finds a pressure where the curve is at x_ref.
            let pmax = m.max_pressure_mpa();
            let grid: Vec<f32> = (0..=500).map(|i| at(pmax * i as f32 / 500.0)).collect();
            // (Not at the grid's ends: a clamped branch reaches Pmax before
            // Rx, where the curve is flat in pressure.)
            let inner = &grid[1..grid.len() - 1];
            let crosses = inner.windows(2).any(|w| {
                (w[0] - x_ref) * (w[1] - x_ref) <= 0.0 && (w[1] - w[0]).abs() < 2e-3
            });
            let x = at(p);
            let ok = !crosses || (x - x_ref).abs() <= 1e-3;
            prop_assert!(ok, "x_ref {x_ref} -> p {p} -> x {x}; stack {:?}", stack.points());
        }

        #[test]
        fn memory_inverse_is_finite_on_any_input(
            x in any_f32(),
            load in any_f32(),
            turns in proptest::collection::vec(any_f32(), 0..6),
            br in branch(),
        ) {
            let m = coeffs().load_model_clamped(load);
            let mem = NonLocalMemory::with_shape(2.0);
            let mut stack = ReversalStack::<8>::default();
            for (i, &p) in turns.iter().enumerate() {
                stack.push(Reversal { pressure_mpa: p, contraction: 0.01 * i as f32 });
            }
            let p = stack.inverse_pressure_mpa(&mem, &m, x, br, 1.0);
            prop_assert!(p.is_finite() && (0.0..=m.max_pressure_mpa()).contains(&p), "p {p}");
        }
    }
}
