//! Every benchmarked model identified on a record's training samples, and
//! the errors of all of them on a record.

use super::*;

/// The models of one comparison.
pub(crate) struct Models {
    /// pam-core's paper model (pam-lab's fit with `--no-static-shape`).
    pub(crate) coeffs: Coeffs,
    /// The non-local memory on the paper model, chosen on the training
    /// samples.
    pub(crate) memory: NonLocalMemory,
    /// The model pam-lab's fit writes: its parameters and static shape.
    pub(crate) fit: Coeffs,
    pub(crate) shape: Option<ConstraintShape>,
    /// The non-local memory on fit's model, chosen on the training
    /// samples.
    pub(crate) fit_memory: NonLocalMemory,
    pub(crate) pi: PiTable<N, L>,
    /// GPI-4 at the largest threshold the training samples chose.
    pub(crate) gpi: GpiTable<GPI_N, L>,
    pub(crate) preisach: PreisachTable<N, L>,
}

/// The errors of each of [`Models`].
pub(crate) struct Scores {
    pub(crate) paper: Errors,
    pub(crate) memory: Errors,
    pub(crate) fit: Errors,
    pub(crate) fit_memory: Errors,
    pub(crate) pi: Errors,
    pub(crate) gpi: Errors,
    pub(crate) preisach: Errors,
}

/// The non-local memory of [`MEMORY_SHAPES`] × [`MEMORY_MERGE_SPANS`]
/// with the least training RMS on `coeffs` with the static shape `shape`
/// (a grid where pam-lab's diagnose fits the two by least squares).
fn best_memory(
    coeffs: &Coeffs,
    shape: Option<ConstraintShape>,
    train: &[Sample],
    heldout: &[bool],
) -> NonLocalMemory {
    MEMORY_SHAPES
        .iter()
        .flat_map(|&k| {
            MEMORY_MERGE_SPANS.iter().map(move |&m| NonLocalMemory {
                shape: k,
                merge_span: m,
            })
        })
        .map(|memory| {
            let rms =
                effects_errors(coeffs, with_memory(shape, memory), train, heldout).train_rms();
            (memory, rms)
        })
        .min_by(|a, b| a.1.total_cmp(&b.1))
        .expect("memories")
        .0
}

/// The effects of a pam-core model with the static shape `shape` and the
/// non-local memory `memory`.
pub(crate) fn with_memory(shape: Option<ConstraintShape>, memory: NonLocalMemory) -> Effects {
    Effects {
        memory: Some(memory),
        shape,
        ..Effects::NONE
    }
}

/// Every model identified on `train`'s samples outside `heldout`, pam-core's
/// models `pam` given: the memory's shape and GPI-4's largest threshold
/// chosen by training RMS; a grid load without training samples
/// interpolated from its neighbours ([`fill_untrained`]; none where every
/// grid load trains).
pub(crate) fn identify_models(train: &[Sample], heldout: &[bool], pam: &PamFit) -> Models {
    let trained = trained_grid(train, heldout);
    let lerp = |a: f32, b: f32, t: f32| a + t * (b - a);
    let coeffs = Coeffs::new(pam.paper).expect("pam-lab returns valid parameters");
    let memory = best_memory(&coeffs, None, train, heldout);
    let fit = Coeffs::new(pam.fit).expect("pam-lab returns valid parameters");
    let fit_memory = best_memory(&fit, pam.shape, train, heldout);

    let mut pi = identify_pi(train, heldout);
    fill_untrained(&mut pi.grid, &trained, |a, b, t| PiCoeffs {
        bias: lerp(a.bias, b.bias, t),
        linear: lerp(a.linear, b.linear, t),
        weights: lerp_arr(&a.weights, &b.weights, t),
    });
    let gpi = GPI_MAX_THRESHOLDS_MPA
        .iter()
        .map(|&r| {
            let mut t = identify_gpi(train, heldout, r);
            fill_untrained(&mut t.grid, &trained, |a, b, t| GpiCoeffs {
                bias: lerp(a.bias, b.bias, t),
                cubic: lerp_arr(&a.cubic, &b.cubic, t),
                weights: lerp_arr(&a.weights, &b.weights, t),
            });
            let rms = gpi_errors(&t, train, heldout).train_rms();
            (t, rms)
        })
        .min_by(|a, b| a.1.total_cmp(&b.1))
        .expect("thresholds")
        .0;
    let preisach = identify_preisach(train, heldout);
    Models {
        coeffs,
        memory,
        fit,
        shape: pam.shape,
        fit_memory,
        pi,
        gpi,
        preisach,
    }
}

/// Each model's errors: its training part from `train` outside `heldout`,
/// its held-out part from `test` (every sample held out) or from `train`'s
/// held-out samples.
pub(crate) fn score(
    m: &Models,
    train: &[Sample],
    heldout: &[bool],
    test: Option<&[Sample]>,
) -> Scores {
    let all = test.map(|t| vec![true; t.len()]);
    let both = |f: &dyn Fn(&[Sample], &[bool]) -> Errors| {
        merged(
            f(train, heldout),
            test.zip(all.as_deref()).map(|(t, h)| f(t, h)),
        )
    };
    Scores {
        paper: both(&|s, h| paper_errors(&m.coeffs, s, h)),
        memory: both(&|s, h| effects_errors(&m.coeffs, with_memory(None, m.memory), s, h)),
        fit: both(&|s, h| {
            let effects = Effects {
                shape: m.shape,
                ..Effects::NONE
            };
            effects_errors(&m.fit, effects, s, h)
        }),
        fit_memory: both(&|s, h| effects_errors(&m.fit, with_memory(m.shape, m.fit_memory), s, h)),
        pi: both(&|s, h| pi_errors(&m.pi, s, h)),
        gpi: both(&|s, h| gpi_errors(&m.gpi, s, h)),
        preisach: both(&|s, h| preisach_errors(&m.preisach, s, h)),
    }
}
