//! Non-local memory: a reversal inside the loop follows a minor loop back to
//! where the previous reversal was, instead of jumping to the other branch
//! (the paper's conclusion names this as its missing effect).
//!
//! The memory is a stack of reversal points `(pressure, contraction)` of fixed
//! capacity `N`, with the wiping-out (Madelung) rules:
//!
//! 1. at a reversal the turning point is pushed;
//! 2. the curve from the top point `r` heads for the point below it `t` (or,
//!    for the first point, for the end of the major loop: 0 MPa falling,
//!    `Pmax` rising) and reaches it exactly;
//! 3. when the pressure passes `t` the minor loop has closed: `r` and `t` are
//!    wiped out and the curve from before the minor loop continues.
//!
//! The curve between `r` and `t` is the branch of the current direction plus
//! an offset in contraction that moves from `d_r` (the offset of `r` from the
//! branch) to `d_t` (that of `t`):
//! `x(p) = x_branch(p) + d_t + (d_r − d_t)·s^shape`, `s = (p − p_t)/(p_r − p_t)`.
//! `shape → ∞` is the paper's jump to the branch; `shape = 1` blends linearly.
//!
//! When the stack is full the oldest point is dropped (its loop then closes
//! on the major loop instead): memory of at most `N` nested reversals.

use crate::branch::Branch;
use crate::error::Error;
use crate::hysteresis::LoadModel;
use crate::math::clamp;

use super::branch_contraction;

/// Parameters of the non-local memory.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct NonLocalMemory {
    /// Exponent of the minor-loop blend, in `[0.05, 50]`: small values hold
    /// the reversal's offset long (a flat start), large values approach the
    /// paper's jump to the branch.
    pub shape: f32,
}

impl NonLocalMemory {
    /// Finite and in `[0.05, 50]`.
    pub fn validate(&self) -> Result<(), Error> {
        if !self.shape.is_finite() {
            return Err(Error::NonFinite("memory.shape"));
        }
        if !(self.shape >= 0.05 && self.shape <= 50.0) {
            return Err(Error::OutOfRange("memory.shape", "must be in [0.05, 50]"));
        }
        Ok(())
    }
}

/// A reversal point.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Reversal {
    /// Pressure at the turning point, MPa.
    pub pressure_mpa: f32,
    /// Contraction at the turning point.
    pub contraction: f32,
}

/// Fixed-capacity stack of reversal points with wiping-out.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ReversalStack<const N: usize> {
    points: [Reversal; N],
    len: usize,
}

impl<const N: usize> Default for ReversalStack<N> {
    fn default() -> Self {
        ReversalStack {
            points: [Reversal::default(); N],
            len: 0,
        }
    }
}

impl<const N: usize> ReversalStack<N> {
    /// Remembered reversal points, oldest first.
    pub fn points(&self) -> &[Reversal] {
        self.points.get(..self.len).unwrap_or(&[])
    }

    /// Forget everything (back on the major loop).
    pub fn clear(&mut self) {
        self.len = 0;
    }

    /// Push a reversal; non-finite points are refused; when full the oldest
    /// point is dropped. `N = 0` remembers nothing.
    pub fn push(&mut self, r: Reversal) {
        if !(r.pressure_mpa.is_finite() && r.contraction.is_finite()) || N == 0 {
            return;
        }
        if self.len >= N {
            self.points.copy_within(1.., 0);
            self.len = N - 1;
        }
        if let Some(slot) = self.points.get_mut(self.len) {
            *slot = r;
            self.len += 1;
        }
    }

    fn top2(&self) -> (Option<Reversal>, Option<Reversal>) {
        let top = self.len.checked_sub(1).and_then(|i| self.points.get(i));
        let below = self.len.checked_sub(2).and_then(|i| self.points.get(i));
        (top.copied(), below.copied())
    }

    /// Apply the wiping-out rule for `pressure_mpa` moving on `branch`:
    /// pop every closed minor loop.
    pub fn wipe_out(&mut self, pressure_mpa: f32, branch: Branch) {
        // Each pass pops two points, so N/2 + 1 passes bound the loop.
        for _ in 0..N / 2 + 1 {
            let (_, Some(target)) = self.top2() else {
                return;
            };
            let passed = match branch {
                Branch::Contraction => pressure_mpa > target.pressure_mpa,
                Branch::Expansion => pressure_mpa < target.pressure_mpa,
            };
            if !passed {
                return;
            }
            self.len -= 2;
        }
    }

    /// Contraction at `pressure_mpa` on `branch` with the memory, after
    /// [`Self::wipe_out`]; `offset_scale` is the factor on the ellipse offset
    /// (1 for the paper's model). Within the stroke, never NaN.
    pub fn contraction(
        &mut self,
        params: &NonLocalMemory,
        model: &LoadModel,
        pressure_mpa: f32,
        branch: Branch,
        offset_scale: f32,
    ) -> f32 {
        let p = clamp(pressure_mpa, 0.0, model.max_pressure_mpa());
        self.wipe_out(p, branch);
        let x_branch = branch_contraction(model, p, branch, offset_scale);
        let (Some(origin), target) = self.top2() else {
            return x_branch;
        };
        let d_r = origin.contraction
            - branch_contraction(model, origin.pressure_mpa, branch, offset_scale);
        let (p_t, d_t) = match target {
            Some(t) => (
                t.pressure_mpa,
                t.contraction - branch_contraction(model, t.pressure_mpa, branch, offset_scale),
            ),
            // The first reversal's curve closes on the end of the major loop.
            None => match branch {
                Branch::Contraction => (model.max_pressure_mpa(), 0.0),
                Branch::Expansion => (0.0, 0.0),
            },
        };
        let span = origin.pressure_mpa - p_t;
        let s = if span.abs() > 1e-6 {
            clamp((p - p_t) / span, 0.0, 1.0)
        } else {
            0.0
        };
        let w = libm::powf(s, params.shape);
        let x = x_branch + d_t + (d_r - d_t) * w;
        clamp(x, model.root_contraction(), model.max_contraction())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{Coeffs, Params};

    fn model() -> LoadModel {
        Coeffs::new(Params::DEFAULT)
            .unwrap()
            .load_model(200.0)
            .unwrap()
    }

    const MEM: NonLocalMemory = NonLocalMemory { shape: 1.0 };

    #[test]
    fn empty_stack_is_the_paper_model() {
        let m = model();
        let mut s = ReversalStack::<8>::default();
        for p in [0.0, 0.1, 0.3, 0.5] {
            for br in [Branch::Contraction, Branch::Expansion] {
                assert_eq!(s.contraction(&MEM, &m, p, br, 1.0), m.contraction(p, br));
            }
        }
    }

    #[test]
    fn reversal_inside_the_loop_starts_where_it_turned_and_closes_on_the_previous_point() {
        let m = model();
        let mut s = ReversalStack::<8>::default();
        // Up the major branch to 0.2 MPa, then back down.
        let bottom = Reversal {
            pressure_mpa: 0.05,
            contraction: m.contraction(0.05, Branch::Contraction),
        };
        s.push(bottom);
        let top = Reversal {
            pressure_mpa: 0.3,
            contraction: m.contraction(0.3, Branch::Contraction),
        };
        s.push(top);
        // No jump: at the turning point the contraction is where it was.
        let at_top = s.contraction(&MEM, &m, 0.3, Branch::Expansion, 1.0);
        assert!((at_top - top.contraction).abs() < 1e-5);
        // The paper's model would jump to the expansion branch here.
        assert!(m.contraction(0.3, Branch::Expansion) - top.contraction > 0.01);
        // It closes on the previous reversal point.
        let at_bottom = s.contraction(&MEM, &m, 0.05, Branch::Expansion, 1.0);
        assert!((at_bottom - bottom.contraction).abs() < 1e-5);
        // Passing it wipes both points out: back on the major branch.
        let below = s.contraction(&MEM, &m, 0.04, Branch::Expansion, 1.0);
        assert!(s.points().is_empty());
        assert_eq!(below, m.contraction(0.04, Branch::Expansion));
    }

    #[test]
    fn full_stack_drops_the_oldest() {
        let mut s = ReversalStack::<3>::default();
        for k in 0..5 {
            s.push(Reversal {
                pressure_mpa: k as f32,
                contraction: 0.0,
            });
        }
        let p: [f32; 3] = core::array::from_fn(|i| s.points()[i].pressure_mpa);
        assert_eq!(p, [2.0, 3.0, 4.0]);
        s.push(Reversal {
            pressure_mpa: f32::NAN,
            contraction: 0.0,
        });
        assert_eq!(s.points().len(), 3);
        let mut none = ReversalStack::<0>::default();
        none.push(Reversal::default());
        assert!(none.points().is_empty());
    }

    #[test]
    fn validation() {
        assert_eq!(MEM.validate(), Ok(()));
        assert!(NonLocalMemory { shape: 0.0 }.validate().is_err());
        assert_eq!(
            NonLocalMemory { shape: f32::NAN }.validate(),
            Err(Error::NonFinite("memory.shape"))
        );
    }
}
