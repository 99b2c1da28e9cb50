//! Splitting a record into contraction- and expansion-branch samples.
//!
//! Both isotonic tests (load held, pressure swept) and isometric tests
//! (contraction held, force recorded) sweep the pressure, so the branch is the
//! direction of the pressure: rising on the contraction branch, falling on the
//! expansion branch.
//!
//! The split works offline, on the whole record:
//! 1. the noise of pressure and contraction is estimated from the median
//!    absolute second difference (robust to steps, holds and ramps);
//! 2. the pressure is smoothed with a centred moving average;
//! 3. a reversal is found when the smoothed pressure moves back from its last
//!    extreme by more than a deadband (default: 6 × the pressure noise, at
//!    least 1 kPa), so noise during holds never flips the branch and slow
//!    drifts only do once they exceed the deadband, as a real reversal would;
//! 4. because the record is known in advance, the branch switches at the
//!    extreme itself, not where the reversal was detected (no detection lag);
//! 5. samples just after a switch whose smoothed pressure is still within the
//!    guard band of the extreme are left unlabelled: there the direction is
//!    not known from the data (turning point, noise).
//!
//! Each switch to the contraction branch starts a new cycle; cycles are what
//! the fit holds out.

use pam_core::Branch;

use crate::record::{noise_std, Sample};

/// Tuning of the split; `None` fields are derived from the data.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SplitConfig {
    /// Reversal deadband on the smoothed pressure, MPa.
    pub deadband_mpa: Option<f64>,
    /// Width of the centred moving average, samples (odd; 1 = no smoothing).
    pub smooth_samples: usize,
    /// Band around a turning point left unlabelled, MPa (default: the deadband).
    pub guard_mpa: Option<f64>,
}

impl Default for SplitConfig {
    fn default() -> Self {
        SplitConfig {
            deadband_mpa: None,
            smooth_samples: 5,
            guard_mpa: None,
        }
    }
}

/// The result of [`split_branches`].
#[derive(Clone, Debug, PartialEq)]
pub struct Split {
    /// Branch of each sample; `None` near turning points.
    pub branch: Vec<Option<Branch>>,
    /// Cycle number of each sample (incremented at each switch to the
    /// contraction branch).
    pub cycle: Vec<u32>,
    /// Sample indices where the branch switches (the turning points).
    pub turning_points: Vec<usize>,
    /// Estimated pressure noise (standard deviation), MPa.
    pub pressure_noise_mpa: f64,
    /// Estimated contraction noise (standard deviation).
    pub contraction_noise: f64,
    /// The deadband used, MPa.
    pub deadband_mpa: f64,
}

impl Split {
    /// Number of labelled samples on `branch`.
    pub fn count(&self, branch: Branch) -> usize {
        self.branch.iter().filter(|b| **b == Some(branch)).count()
    }

    /// Number of cycles.
    pub fn cycles(&self) -> u32 {
        self.cycle.last().map_or(0, |c| c + 1)
    }
}

/// Centred moving average of width `w` (odd), shrinking at the ends.
pub fn moving_average(x: &[f64], w: usize) -> Vec<f64> {
    let h = w.max(1) / 2;
    let n = x.len();
    let mut prefix = Vec::with_capacity(n + 1);
    prefix.push(0.0);
    for v in x {
        prefix.push(prefix.last().copied().unwrap_or(0.0) + v);
    }
    (0..n)
        .map(|i| {
            let lo = i.saturating_sub(h);
            let hi = (i + h + 1).min(n);
            (prefix[hi] - prefix[lo]) / (hi - lo) as f64
        })
        .collect()
}

/// Centred running median of `2·half + 1` samples (shrinking at the ends).
///
/// Unlike a moving average it keeps steps sharp, so smoothing a pressure
/// with it does not fake a lag or a creep after a step.
pub fn running_median(x: &[f64], half: usize) -> Vec<f64> {
    let n = x.len();
    let mut window = Vec::with_capacity(2 * half + 1);
    (0..n)
        .map(|i| {
            let (a, b) = (i.saturating_sub(half), (i + half).min(n - 1));
            window.clear();
            window.extend_from_slice(&x[a..=b]);
            window.sort_by(f64::total_cmp);
            window[window.len() / 2]
        })
        .collect()
}

/// Held-out mask by load blocks (runs of one load, within 1 N), for any
/// protocol: blocks alternate training (even) and held out (odd), except
/// that the blocks at the record's lowest and highest load always train, so
/// that no held-out sample lies beyond the training loads (the load family
/// would extrapolate there, and its error would be charged to the effects).
/// When that leaves nothing held out (one or two loads), the last 30 % of
/// every block is held out instead.
pub fn holdout_by_load_block(loads_n: &[f64]) -> Vec<bool> {
    let n = loads_n.len();
    let mut block_of = Vec::with_capacity(n);
    let mut block_load = Vec::new();
    let mut last = f64::NAN;
    for &l in loads_n {
        if last.is_nan() || (l - last).abs() > 1.0 {
            block_load.push(l);
            last = l;
        }
        block_of.push(block_load.len() - 1);
    }
    let (lo, hi) = block_load
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &l| {
            (a.min(l), b.max(l))
        });
    let extreme = |l: f64| (l - lo).abs() <= 1.0 || (l - hi).abs() <= 1.0;
    let held: Vec<bool> = block_load
        .iter()
        .enumerate()
        .map(|(k, &l)| k % 2 == 1 && !extreme(l))
        .collect();
    let out: Vec<bool> = block_of.iter().map(|&k| held[k]).collect();
    if out.iter().any(|h| *h) {
        return out;
    }
    // Every block's tail.
    let mut start = vec![0usize; block_load.len()];
    let mut len = vec![0usize; block_load.len()];
    for (i, &k) in block_of.iter().enumerate() {
        if len[k] == 0 {
            start[k] = i;
        }
        len[k] += 1;
    }
    block_of
        .iter()
        .enumerate()
        .map(|(i, &k)| (i - start[k]) as f64 >= 0.7 * len[k] as f64)
        .collect()
}

/// Held-out mask for a diagnosis, for any protocol: the record is cut into
/// segments at every cycle start (`cycle`, from [`split_branches`]) and
/// every load change (more than 1 N), and one segment in `k` is held out,
/// drawn by a fixed hash of its number (the same record always gets the
/// same mask). A fixed pattern (every `k`-th) would lock onto a protocol
/// that repeats the same sequence of cycles at every load and hold out,
/// say, every full cycle; a drawn one mixes every kind of cycle and every
/// load into both parts. The record's first segment always trains. A
/// record where that holds out under a tenth of the samples (few cycles)
/// falls back to [`holdout_by_load_block`] (whose mask is not covered:
/// its blocks are not whole segments). Otherwise each mask in `cover` (a
/// regime: fast ramps, holds after a step) is then made sure to be held
/// out as well ([`cover_regime`]), none of them losing its last training
/// segment to another's cover. Returns the mask and, per mask in `cover`,
/// the number of segments moved to the held-out part for it.
pub fn holdout_by_segment(
    loads_n: &[f64],
    cycle: &[u32],
    k: usize,
    cover: &[&[bool]],
) -> (Vec<bool>, Vec<usize>) {
    let segment = segments(loads_n, cycle);
    let n = segment.len();
    let mut out: Vec<bool> = segment
        .iter()
        .map(|&s| s > 0 && splitmix(s) % (k.max(2) as u64) == 0)
        .collect();
    if (out.iter().filter(|h| **h).count() as f64) < 0.1 * n as f64 {
        return (holdout_by_load_block(&loads_n[..n]), vec![0; cover.len()]);
    }
    let moved = cover
        .iter()
        .map(|regime| cover_regime(&mut out, &segment, loads_n, regime, cover, k))
        .collect();
    (out, moved)
}

/// The segment number of every sample: a new segment starts at every cycle
/// start and every load change of more than 1 N ([`holdout_by_segment`]).
pub fn segments(loads_n: &[f64], cycle: &[u32]) -> Vec<u64> {
    let n = loads_n.len().min(cycle.len());
    let mut out = Vec::with_capacity(n);
    let mut segment = 0u64;
    for i in 0..n {
        if i > 0 && ((loads_n[i] - loads_n[i - 1]).abs() > 1.0 || cycle[i] != cycle[i - 1]) {
            segment += 1;
        }
        out.push(segment);
    }
    out
}

/// Make sure a regime is held out too: a regime (`regime[i]`: sample `i` is
/// in it) that lies in at least two segments but of whose samples fewer than
/// one in `2k` are held out cannot judge the effect it shows (a record with
/// one fast cycle per load may hold out a single fast-ramp sample). Then
/// training segments holding it are moved to the held-out part, in the
/// order of a fixed hash of their number, until one in `k` of its samples is
/// held out, never the first segment, never the last training segment of
/// a load, and never the last training segment of `regime` or of any regime
/// in `protect` that lies in two segments or more (the other regimes being
/// covered: each keeps training data). A regime already held out at one
/// in `2k` leaves the mask as it is. `heldout` must be constant over each
/// segment. Returns the number of segments moved.
pub fn cover_regime(
    heldout: &mut [bool],
    segment: &[u64],
    loads_n: &[f64],
    regime: &[bool],
    protect: &[&[bool]],
    k: usize,
) -> usize {
    let n = protect.iter().fold(
        heldout
            .len()
            .min(segment.len())
            .min(loads_n.len())
            .min(regime.len()),
        |n, p| n.min(p.len()),
    );
    let k = k.max(2) as f64;
    let Some(&last) = segment[..n].last() else {
        return 0;
    };
    let segs = last as usize + 1;
    // Per segment: samples in the regime, samples, load, held out.
    let mut in_regime = vec![0usize; segs];
    let mut size = vec![0usize; segs];
    let mut load = vec![0.0f64; segs];
    let mut held = vec![false; segs];
    for i in 0..n {
        let s = segment[i] as usize;
        size[s] += 1;
        in_regime[s] += usize::from(regime[i]);
        load[s] = loads_n[i];
        held[s] = heldout[i];
    }
    let total: usize = in_regime.iter().sum();
    let bearing = in_regime.iter().filter(|c| **c > 0).count();
    let mut held_in: usize = (0..segs).filter(|&s| held[s]).map(|s| in_regime[s]).sum();
    if bearing < 2 || total == 0 || (held_in as f64) >= total as f64 / (2.0 * k) {
        return 0;
    }
    // The regime itself and every protected one that lies in two segments
    // or more: per segment whether it bears it, and how many training
    // segments do.
    let mut guarded: Vec<(Vec<bool>, usize)> = std::iter::once(regime)
        .chain(protect.iter().copied())
        .filter_map(|r| {
            let mut bears = vec![false; segs];
            for i in 0..n {
                bears[segment[i] as usize] |= r[i];
            }
            let training = (0..segs).filter(|&s| bears[s] && !held[s]).count();
            (bears.iter().filter(|b| **b).count() >= 2).then_some((bears, training))
        })
        .collect();
    let same_load = |a: f64, b: f64| (a - b).abs() <= 1.0;
    let mut order: Vec<usize> = (1..segs)
        .filter(|&s| !held[s] && in_regime[s] > 0)
        .collect();
    order.sort_by_key(|&s| splitmix(s as u64));
    let mut moved = 0;
    for s in order {
        if (held_in as f64) >= total as f64 / k {
            break;
        }
        let load_trains_elsewhere =
            (0..segs).any(|o| o != s && !held[o] && size[o] > 0 && same_load(load[o], load[s]));
        let last_of_a_regime = guarded
            .iter()
            .any(|(bears, training)| bears[s] && *training <= 1);
        if !load_trains_elsewhere || last_of_a_regime {
            continue;
        }
        held[s] = true;
        held_in += in_regime[s];
        for (bears, training) in &mut guarded {
            if bears[s] {
                *training -= 1;
            }
        }
        moved += 1;
    }
    if moved > 0 {
        for i in 0..n {
            heldout[i] = held[segment[i] as usize];
        }
    }
    moved
}

/// SplitMix64's output function: a fixed, well-mixed hash of `x`.
fn splitmix(x: u64) -> u64 {
    let mut z = x.wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// Held-out samples whose load lies outside the training samples' load
/// range (by more than 1 N): where a held-out error would measure the load
/// family's extrapolation.
pub fn extrapolated(loads_n: &[f64], heldout: &[bool]) -> usize {
    let (lo, hi) = loads_n
        .iter()
        .zip(heldout)
        .filter(|(_, h)| !**h)
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), (&l, _)| {
            (a.min(l), b.max(l))
        });
    loads_n
        .iter()
        .zip(heldout)
        .filter(|(&l, &h)| h && (l < lo - 1.0 || l > hi + 1.0))
        .count()
}

/// Label every sample with its branch; see the module docs.
pub fn split_branches(samples: &[Sample], cfg: &SplitConfig) -> Split {
    let n = samples.len();
    let pressure: Vec<f64> = samples.iter().map(|s| s.pressure_mpa).collect();
    let pressure_noise_mpa = noise_std(pressure.iter().copied());
    let contraction_noise = noise_std(samples.iter().map(|s| s.contraction));
    let deadband_mpa = cfg
        .deadband_mpa
        .unwrap_or_else(|| (6.0 * pressure_noise_mpa).max(1e-3));
    let guard = cfg.guard_mpa.unwrap_or(deadband_mpa);
    let ps = moving_average(&pressure, cfg.smooth_samples | 1);

    // Turning points and the branch that starts at each.
    let mut switches: Vec<(usize, Branch)> = Vec::new();
    let mut state: Option<(Branch, usize)> = None; // branch and index of its extreme
    let (mut lo_i, mut hi_i) = (0usize, 0usize);
    for i in 0..n {
        match state {
            None => {
                if ps[i] < ps[lo_i] {
                    lo_i = i;
                }
                if ps[i] > ps[hi_i] {
                    hi_i = i;
                }
                // The first move beyond the deadband sets the starting branch;
                // what came before it was flat within the deadband.
                if ps[i] > ps[lo_i] + deadband_mpa {
                    switches.push((0, Branch::Contraction));
                    state = Some((Branch::Contraction, i));
                } else if ps[i] < ps[hi_i] - deadband_mpa {
                    switches.push((0, Branch::Expansion));
                    state = Some((Branch::Expansion, i));
                }
            }
            Some((branch, ext)) => {
                let (new_ext, reversed) = match branch {
                    Branch::Contraction => (
                        if ps[i] > ps[ext] { i } else { ext },
                        ps[i] < ps[ext] - deadband_mpa,
                    ),
                    Branch::Expansion => (
                        if ps[i] < ps[ext] { i } else { ext },
                        ps[i] > ps[ext] + deadband_mpa,
                    ),
                };
                if reversed {
                    let nb = branch.opposite();
                    switches.push((ext, nb));
                    state = Some((nb, i));
                } else {
                    state = Some((branch, new_ext));
                }
            }
        }
    }
    if switches.is_empty() {
        // Never moved beyond the deadband: no branch is known anywhere.
        return Split {
            branch: vec![None; n],
            cycle: vec![0; n],
            turning_points: Vec::new(),
            pressure_noise_mpa,
            contraction_noise,
            deadband_mpa,
        };
    }

    let mut branch = vec![None; n];
    let mut cycle = vec![0u32; n];
    let mut c = 0u32;
    for (k, &(start, br)) in switches.iter().enumerate() {
        let end = switches.get(k + 1).map_or(n, |s| s.0);
        if br == Branch::Contraction && k > 0 {
            c += 1;
        }
        let p_turn = ps[start];
        let mut in_guard = k > 0;
        for i in start..end {
            // The guard ends for good once the pressure has left the band.
            if in_guard && (ps[i] - p_turn).abs() > guard {
                in_guard = false;
            }
            branch[i] = if in_guard { None } else { Some(br) };
            cycle[i] = c;
        }
    }
    Split {
        branch,
        cycle,
        turning_points: switches.iter().skip(1).map(|s| s.0).collect(),
        pressure_noise_mpa,
        contraction_noise,
        deadband_mpa,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn samples(p: &[f64]) -> Vec<Sample> {
        p.iter()
            .enumerate()
            .map(|(i, &p)| Sample {
                t_s: i as f64 * 0.02,
                load_n: 100.0,
                pressure_mpa: p,
                contraction: 0.1,
            })
            .collect()
    }

    /// Deterministic pseudo-noise, uniform in [-a, a].
    fn noise(i: usize, a: f64) -> f64 {
        let mut rng = crate::rng::Rng::new(i as u64);
        a * (2.0 * rng.uniform() - 1.0)
    }

    #[test]
    fn noise_estimate_is_close_for_uniform_noise_on_a_ramp() {
        let x: Vec<f64> = (0..20_000)
            .map(|i| 1e-4 * i as f64 + noise(i, 0.01))
            .collect();
        let s = noise_std(x.iter().copied());
        // Uniform on [-a, a]: σ = a/√3 = 0.00577; MAD-based estimate within 20 %.
        assert!((s - 0.00577).abs() < 0.2 * 0.00577, "{s}");
    }

    #[test]
    fn triangle_with_noise_and_holds_splits_at_the_peaks() {
        // 0 → 0.5 (250 samples), hold 100 samples with noise, → 0, hold, → 0.5.
        let mut p = Vec::new();
        for i in 0..=250 {
            p.push(0.002 * i as f64);
        }
        p.extend(std::iter::repeat_n(0.5, 100));
        for i in (0..250).rev() {
            p.push(0.002 * i as f64);
        }
        p.extend(std::iter::repeat_n(0.0, 100));
        for i in 1..=250 {
            p.push(0.002 * i as f64);
        }
        let p: Vec<f64> = p
            .iter()
            .enumerate()
            .map(|(i, v)| v + noise(i, 0.002))
            .collect();
        let s = split_branches(&samples(&p), &SplitConfig::default());
        assert_eq!(s.turning_points.len(), 2, "{:?}", s.turning_points);
        // The turning points lie in the holds (the extreme of noisy flat data).
        assert!((250..=351).contains(&s.turning_points[0]));
        assert!((600..=701).contains(&s.turning_points[1]));
        assert_eq!(s.branch[100], Some(Branch::Contraction));
        assert_eq!(s.branch[500], Some(Branch::Expansion));
        assert_eq!(s.branch[800], Some(Branch::Contraction));
        assert_eq!(s.cycle[100], 0);
        assert_eq!(s.cycle[800], 1);
        assert_eq!(s.cycles(), 2);
    }

    #[test]
    fn a_record_starting_downwards_starts_on_expansion() {
        let p: Vec<f64> = (0..200)
            .map(|i| {
                if i < 100 {
                    0.5 - 0.004 * i as f64
                } else {
                    0.1 + 0.004 * (i - 100) as f64
                }
            })
            .collect();
        let s = split_branches(&samples(&p), &SplitConfig::default());
        assert_eq!(s.branch[10], Some(Branch::Expansion));
        assert_eq!(s.branch[190], Some(Branch::Contraction));
    }

    #[test]
    fn slow_drift_within_the_deadband_does_not_flip() {
        // Rise, then a hold that drifts down by 0.8 of the deadband.
        let mut p: Vec<f64> = (0..100).map(|i| 0.003 * i as f64).collect();
        let top = *p.last().unwrap();
        p.extend((0..500).map(|i| top - 0.004 * i as f64 / 500.0));
        let s = split_branches(
            &samples(&p),
            &SplitConfig {
                deadband_mpa: Some(0.005),
                ..SplitConfig::default()
            },
        );
        assert!(s.turning_points.is_empty());
        assert!(s.branch[50..]
            .iter()
            .all(|b| *b == Some(Branch::Contraction)));
    }

    #[test]
    fn flat_record_has_no_branch() {
        let s = split_branches(&samples(&[0.1; 50]), &SplitConfig::default());
        assert!(s.branch.iter().all(Option::is_none));
    }

    #[test]
    fn about_one_segment_in_k_is_held_out_at_every_load() {
        // Four loads of 30 cycles of 10 samples each.
        let loads: Vec<f64> = (0..1200).map(|i| 100.0 * (1 + i / 300) as f64).collect();
        let cycle: Vec<u32> = (0..1200).map(|i| i / 10).collect();
        let h = holdout_by_segment(&loads, &cycle, 3, &[]).0;
        assert!(h[..10].iter().all(|x| !x));
        for block in h.chunks(300) {
            let share = block.iter().filter(|x| **x).count() as f64 / 300.0;
            assert!((0.15..0.55).contains(&share), "{share}");
        }
        // Whole segments only.
        for c in h.chunks(10) {
            assert!(c.iter().all(|x| *x == c[0]));
        }
        assert_eq!(extrapolated(&loads, &h), 0);
        // One cycle per load: too little held out, by load blocks instead.
        let loads = [100.0, 100.0, 200.0, 200.0, 300.0, 300.0];
        let h = holdout_by_segment(&loads, &[0, 0, 1, 1, 2, 2], 3, &[]).0;
        assert_eq!(h, holdout_by_load_block(&loads));
    }

    #[test]
    fn a_regime_the_draw_leaves_in_training_is_held_out_too() {
        // Four loads of 30 cycles of 10 samples; at every load one cycle is
        // fast (the regime), the same cycle number in every load block, as
        // a protocol that repeats itself gives.
        let loads: Vec<f64> = (0..1200).map(|i| 100.0 * (1 + i / 300) as f64).collect();
        let cycle: Vec<u32> = (0..1200).map(|i| i / 10).collect();
        let (drawn, _) = holdout_by_segment(&loads, &cycle, 3, &[]);
        let segment = segments(&loads, &cycle);
        // The fast cycle: at each load, the first training segment past the
        // first cycle, so that the draw holds out none of it.
        let mut fast = vec![false; 1200];
        for block in 0..4 {
            let c = (block * 30 + 1..block * 30 + 30)
                .find(|&c| !drawn[c * 10])
                .unwrap_or(block * 30 + 1);
            fast[c * 10..c * 10 + 10].iter_mut().for_each(|f| *f = true);
        }
        let share = |h: &[bool]| {
            let held = (0..1200).filter(|&i| fast[i] && h[i]).count();
            held as f64 / fast.iter().filter(|f| **f).count() as f64
        };
        assert_eq!(share(&drawn), 0.0);
        let (h, moved) = holdout_by_segment(&loads, &cycle, 3, &[&fast]);
        assert_eq!(moved, vec![2]);
        assert!(share(&h) >= 1.0 / 3.0, "{}", share(&h));
        // Only segments of the regime moved, whole, and to the held-out part.
        for i in 0..1200 {
            assert!(h[i] == drawn[i] || (fast[i] && h[i]), "sample {i}");
        }
        for c in h.chunks(10) {
            assert!(c.iter().all(|x| *x == c[0]));
        }
        assert!(h[..10].iter().all(|x| !x));
        // Every load still trains.
        for block in h.chunks(300) {
            assert!(block.iter().any(|x| !x));
        }
        // Already held out at one in six: left as drawn.
        let mut again = h.clone();
        assert_eq!(cover_regime(&mut again, &segment, &loads, &fast, &[], 3), 0);
        assert_eq!(again, h);
        // A regime in a single segment cannot be in both parts: left alone.
        let mut one = vec![false; 1200];
        let c = (1..30).find(|&c| !drawn[c * 10]).unwrap_or(1);
        one[c * 10..c * 10 + 10].iter_mut().for_each(|f| *f = true);
        let mut kept = drawn.clone();
        assert_eq!(cover_regime(&mut kept, &segment, &loads, &one, &[], 3), 0);
        assert_eq!(kept, drawn);
    }

    #[test]
    fn the_last_training_segment_of_a_load_is_never_moved() {
        // Two loads; at 200 N a single cycle, and it is fast; at 100 N three
        // fast cycles, none held out by the draw.
        let loads: Vec<f64> = (0..40)
            .map(|i| if i < 30 { 100.0 } else { 200.0 })
            .collect();
        let cycle: Vec<u32> = (0..40).map(|i| i / 10).collect();
        let segment = segments(&loads, &cycle);
        let fast = vec![true; 40];
        let mut h = vec![false; 40];
        let moved = cover_regime(&mut h, &segment, &loads, &fast, &[], 3);
        // Segment 0 never moves and the 200 N cycle is its load's only one:
        // the 100 N cycles 1 and 2 move (one alone is a quarter of the
        // regime, short of one in three).
        assert_eq!(moved, 2);
        assert!(h[..10].iter().all(|x| !x));
        assert!(h[10..30].iter().all(|x| *x));
        assert!(h[30..].iter().all(|x| !x));
    }

    /// `count` segments of ten samples at 100 N: loads, cycle numbers and
    /// segment numbers.
    fn ten_sample_segments(count: usize) -> (Vec<f64>, Vec<u32>, Vec<u64>) {
        let loads = vec![100.0; 10 * count];
        let cycle: Vec<u32> = (0..10 * count as u32).map(|i| i / 10).collect();
        let segment = segments(&loads, &cycle);
        (loads, cycle, segment)
    }

    /// Per sample of [`ten_sample_segments`]: whether it lies in `segs`.
    fn in_ten_sample_segments(count: usize, segs: &[usize]) -> Vec<bool> {
        (0..10 * count).map(|i| segs.contains(&(i / 10))).collect()
    }

    #[test]
    fn covering_one_regime_never_takes_the_last_training_segment_of_another() {
        // Eight segments of ten samples at one load; segment 6 held out.
        // Fast ramps in segments 3 and 5, holds in 4, 5 and 7. The fast
        // ramps' cover moves 3 (first in hash order, 3, 5, 7, 4, 1, 2, 6),
        // which leaves 5 their last training segment; the holds' cover
        // would move 5 first, and must take 7 instead.
        let (loads, cycle, segment) = ten_sample_segments(8);
        let in_segments = |segs: &[usize]| in_ten_sample_segments(8, segs);
        let (fast, hold) = (in_segments(&[3, 5]), in_segments(&[4, 5, 7]));
        let mut h = in_segments(&[6]);
        let both: [&[bool]; 2] = [&fast, &hold];
        assert_eq!(cover_regime(&mut h, &segment, &loads, &fast, &both, 3), 1);
        assert_eq!(cover_regime(&mut h, &segment, &loads, &hold, &both, 3), 1);
        assert_eq!(h, in_segments(&[3, 6, 7]));
        // Without the other regime protected, the holds' cover takes 5.
        let mut h = in_segments(&[3, 6]);
        assert_eq!(cover_regime(&mut h, &segment, &loads, &hold, &[], 3), 1);
        assert_eq!(h, in_segments(&[3, 5, 6]));
        // And holdout_by_segment protects every regime it covers.
        let (h, _) = holdout_by_segment(&loads, &cycle, 3, &[&fast, &hold]);
        assert!((0..80).any(|i| fast[i] && !h[i]));
        assert!((0..80).any(|i| hold[i] && !h[i]));
    }

    #[test]
    fn the_first_segment_is_never_moved() {
        // The regime in segments 0 (60 samples), 1, 2 (10 each) at 100 N
        // and 3 (10, the only one at 200 N); segment 4 (100 N) trains
        // without it. Moving 1 and 2 holds out 20 of 90, short of one in
        // three; 3 is its load's only segment, and 0, which would reach
        // it, is the record's first.
        let loads: Vec<f64> = (0..100)
            .map(|i| if (80..90).contains(&i) { 200.0 } else { 100.0 })
            .collect();
        let cycle: Vec<u32> = (0..100)
            .map(|i| if i < 60 { 0 } else { (i - 50) / 10 })
            .collect();
        let segment = segments(&loads, &cycle);
        assert_eq!(segment[59..].first(), Some(&0));
        assert_eq!(segment[99], 4);
        let regime: Vec<bool> = (0..100).map(|i| i < 90).collect();
        let mut h = vec![false; 100];
        assert_eq!(cover_regime(&mut h, &segment, &loads, &regime, &[], 3), 2);
        assert!(h[..60].iter().all(|x| !x));
        assert!(h[60..80].iter().all(|x| *x));
        assert!(h[80..].iter().all(|x| !x));
    }

    #[test]
    fn a_regime_is_covered_only_under_one_in_2k() {
        // Ten segments of ten samples at one load, the regime in 1..=9.
        let (loads, _, segment) = ten_sample_segments(10);
        let regime: Vec<bool> = (0..100).map(|i| i >= 10).collect();
        let in_segments = |segs: &[usize]| in_ten_sample_segments(10, segs);
        // Two segments held out: 2/9 of the regime, over one in six.
        let mut h = in_segments(&[3, 7]);
        assert_eq!(cover_regime(&mut h, &segment, &loads, &regime, &[], 3), 0);
        // One: 1/9, under one in six: segments move until one in three.
        let mut h = in_segments(&[3]);
        assert_eq!(cover_regime(&mut h, &segment, &loads, &regime, &[], 3), 2);
        let held = (0..100).filter(|&i| regime[i] && h[i]).count();
        assert_eq!(held, 30);
        assert!(h[..10].iter().all(|x| !x));
    }

    #[test]
    fn load_blocks_alternate_and_the_extreme_loads_train() {
        let v = [100.0, 100.0, 200.0, 200.0, 300.0, 150.0, 250.0, 250.0];
        let h = holdout_by_load_block(&v);
        assert_eq!(h, vec![false, false, true, true, false, true, false, false]);
        assert_eq!(extrapolated(&v, &h), 0);
        // The highest load in an odd block trains all the same.
        let v = [200.0, 480.0, 80.0, 300.0, 250.0, 250.0];
        let h = holdout_by_load_block(&v);
        assert_eq!(h, vec![false, false, false, true, false, false]);
        assert_eq!(extrapolated(&v, &h), 0);
        assert_eq!(
            extrapolated(&v, &[false, true, false, false, false, false]),
            1
        );
        // One or two loads: every block's last 30 %.
        let one = [100.0; 10];
        assert_eq!(
            holdout_by_load_block(&one),
            [vec![false; 7], vec![true; 3]].concat()
        );
        let two = [[100.0; 10], [300.0; 10]].concat();
        let h = holdout_by_load_block(&two);
        assert_eq!(h.iter().filter(|x| **x).count(), 6);
        assert!(h[7] && h[17] && !h[6] && !h[16]);
    }
}
