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

/// The rigs: one without an effect beyond the paper's model, then memory,
/// rate dependence, creep and load-dependent width.
pub fn effect_rigs() -> [EffectRig; 5] {
    let reference = MuscleParams::DEFAULT;
    [
        EffectRig {
            name: "coulomb",
            effect: "none",
            change: "all 8 slip elements break away at 0.15 % (one Coulomb friction: a reversal crosses to the other branch at once, as the paper's model switches)",
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
            change: "friction mostly proportional to the active force (F_c0 20 -> 5 N, mu 0.11 -> 0.25)",
            muscle: MuscleParams {
                friction_base_n: 5.0,
                friction_ratio: 0.25,
                ..reference
            },
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
}
