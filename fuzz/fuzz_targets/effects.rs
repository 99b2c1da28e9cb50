//! `Simulator::step` (pam-core's per-sample model with non-local memory,
//! rate dependence, creep, load-dependent width and constraint shape) over arbitrary
//! `(t_s, pressure_mpa, load_n)` samples, with perturbed effect parameters.
//!
//! Asserts after every sample: the prediction is finite and inside the
//! range `Simulator::stroke` gives (as `Simulator::step` documents), equals
//! `last_contraction`, the offset scale is in `[0, MAX_OFFSET_SCALE]`, the
//! reversal memory holds at most `N` points and the active load is in range.
#![no_main]

use libfuzzer_sys::fuzz_target;
use pam_core::effects::MAX_OFFSET_SCALE;
use pam_core::Simulator;
use pam_fuzz::Floats;

const N: usize = 4;

fuzz_target!(|data: &[u8]| {
    let mut f = Floats::new(data);
    let coeffs = f.coeffs();
    let p = *coeffs.params();
    let effects = f.effects();
    let config = f.tracker_config();
    let initial_load_n = f.around(p.min_load_n, p.max_load_n);
    let Ok(mut sim) = Simulator::<N>::new(coeffs, effects, config, initial_load_n) else {
        return; // effect parameters refused by validation
    };
    let mut t_s = 0.0f32;
    while !f.is_empty() {
        // Mostly advancing time (the path the rate and creep filters take),
        // sometimes any value.
        let sel = f.byte();
        t_s = if sel % 4 == 0 {
            f.raw()
        } else {
            t_s + f32::from(sel) * 1e-3
        };
        let pressure_mpa = f.around(0.0, p.points.max_pressure_mpa);
        let load_n = f.around(p.min_load_n, p.max_load_n);
        let x = sim.step(t_s, pressure_mpa, load_n);

        let (lo, hi) = sim.stroke();
        assert!(
            x.is_finite() && x >= lo && x <= hi,
            "step({t_s:e}, {pressure_mpa:e}, {load_n:e}) = {x:e} outside [{lo}, {hi}]"
        );
        assert_eq!(x.to_bits(), sim.last_contraction().to_bits());
        let s = sim.offset_scale();
        assert!((0.0..=MAX_OFFSET_SCALE).contains(&s), "offset scale {s}");
        assert!(sim.reversals().len() <= N);
        assert!(coeffs.load_in_range(sim.tracker().load_n()));
    }
});
