//! Rigs with one effect each, for the end-to-end run ([`crate::end_to_end`]).
//!
//! Every rig is host-sim's own plant ([`crate::plant`]: Tondu–Lopez muscle,
//! Maxwell-slip friction, viscous damping, a slow rubber arm), with one
//! physical parameter turned up so that the effect pam-core names shows in
//! the rig's records. None of them is built from pam-core's effect
//! equations: what `pam-lab diagnose` finds is found in physics it did not
//! see.

use crate::plant::{MuscleParams, SLIP_ELEMENTS};

/// A rig and the effect it was built to show.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EffectRig {
    /// Short name, used in file names.
    pub name: &'static str,
    /// The effect turned up, as pam-core names it (`none`: the paper's
    /// model is all the rig has beyond its static shape).
    pub effect: &'static str,
    /// What was changed in the plant.
    pub change: &'static str,
    /// The muscle.
    pub muscle: MuscleParams,
}

/// The width rig's muscle: the reference's braid friction mostly moved
/// into the load's path (`F_c0` 20 → 5 N, `μ` 0.11 → 0.05, `μ_L` 0 →
/// 0.2). Friction with the active force alone does not make a width that
/// grows with the load: every load sweeps the same pressures, so at one
/// point of the stroke it adds the same pressure (the reference's loop at
/// mid-stroke is 0.051 MPa high at 100 N and 0.044 at 600 N; with `μ`
/// 0.25, this rig's earlier friction, 0.081 and 0.079). Friction with the
/// load does: 0.039 MPa at 100 N, 0.090 at 600 N
/// ([`MuscleParams::loop_height_mpa`], the test below).
pub const WIDTH_MUSCLE: MuscleParams = MuscleParams {
    friction_base_n: 5.0,
    friction_ratio: 0.05,
    load_friction_ratio: 0.2,
    ..MuscleParams::DEFAULT
};

/// The rigs: one without an effect beyond the paper's model, then memory,
/// rate dependence, creep and load-dependent width.
pub fn effect_rigs() -> [EffectRig; 5] {
    let reference = MuscleParams::DEFAULT;
    [
        EffectRig {
            name: "coulomb",
            effect: "none",
            change: "all 8 slip elements break away at 0.15 % (one Coulomb friction: at a reversal the contraction holds while the pressure crosses the loop, then follows the other branch; the paper's model jumps to the other branch at the reversal's pressure instead)",
            muscle: MuscleParams {
                slip_contraction: [0.0015; SLIP_ELEMENTS],
                ..reference
            },
        },
        EffectRig {
            name: "memory",
            effect: "non_local_memory",
            change: "none: the reference muscle, whose slip elements break away at 0.15-2.5 % (minor loops inside the major loop)",
            muscle: reference,
        },
        EffectRig {
            name: "rate",
            effect: "rate_dependence",
            change: "viscous damping 300 -> 1500 N per unit contraction per second",
            muscle: MuscleParams {
                damping_n_s: 1500.0,
                ..reference
            },
        },
        EffectRig {
            name: "creep",
            effect: "creep",
            change: "a slow rubber arm, 4000 N per unit contraction relaxing in 1.5 s",
            muscle: MuscleParams {
                creep_stiffness_n: 4000.0,
                creep_time_s: 1.5,
                ..reference
            },
        },
        EffectRig {
            name: "width",
            effect: "load_dependent_width",
            change: "friction mostly in the load's path, proportional to the load (F_c0 20 -> 5 N, mu 0.11 -> 0.05, mu_L 0 -> 0.2): the loop's height at mid-stroke 0.039 MPa at 100 N, 0.090 at 600 N",
            muscle: WIDTH_MUSCLE,
        },
    ]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_are_unique_and_only_one_rig_is_the_reference() {
        let rigs = effect_rigs();
        for (i, a) in rigs.iter().enumerate() {
            for b in &rigs[i + 1..] {
                assert_ne!(a.name, b.name);
                assert_ne!(a.muscle, b.muscle);
            }
        }
        let reference = rigs
            .iter()
            .filter(|r| r.muscle == MuscleParams::DEFAULT)
            .count();
        assert_eq!(reference, 1);
    }

    /// The loop's height at the contraction the frictionless muscle has
    /// at 0.25 MPa (mid-stroke), at 100 N and at 600 N.
    fn heights(m: &MuscleParams) -> (f64, f64) {
        let at = |load: f64| m.loop_height_mpa(load, m.static_contraction(0.25, load));
        (at(100.0), at(600.0))
    }

    #[test]
    fn only_the_width_rigs_loop_grows_with_the_load() {
        let (lo, hi) = heights(&WIDTH_MUSCLE);
        assert!(hi > 2.0 * lo, "{lo} -> {hi}");
        assert!(
            (lo - 0.039).abs() < 0.002 && (hi - 0.090).abs() < 0.002,
            "{lo} -> {hi}"
        );
        // Friction with the active force (the reference's, and more of it)
        // leaves the height within 15 % over the loads.
        let braid = MuscleParams {
            friction_base_n: 5.0,
            friction_ratio: 0.25,
            ..MuscleParams::DEFAULT
        };
        for m in [MuscleParams::DEFAULT, braid] {
            let (lo, hi) = heights(&m);
            assert!((hi / lo - 1.0).abs() < 0.15, "{lo} -> {hi}");
        }
    }
}
