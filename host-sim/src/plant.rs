//! The simulated McKibben muscle: a Tondu–Lopez static force model, a rubber
//! bladder, Maxwell-slip friction with non-local memory, and the moving mass of
//! the load — deliberately **independent of pam-core's equations** (no cubic,
//! no ellipse), so that a controller built on pam-core's model is tested
//! against a different description of the same kind of muscle.
//!
//! # Force balance (all forces in N, contraction `ε` as a fraction of `L0`)
//!
//! ```text
//! m·L0·ε̈ = T_act(P, ε) + T_bladder(ε) − F_slip − c·ε̇ − L
//! ```
//!
//! * `T_act = π r0² · P_eff(P) · (a (1 − kε)² − b)`, `a = 3/tan²α0`,
//!   `b = 1/sin²α0` — Tondu & Lopez, IEEE Control Syst. Mag. 20(2), 2000,
//!   eq. (4) (with the end-effect factor `k`). `P` is gauge pressure.
//! * `P_eff = P − p_b·(1 − e^{−P/p_b})`: the part of the pressure the rubber
//!   bladder absorbs before it presses on the braid (a smooth threshold,
//!   `≈ P²/2p_b` at low pressure, `P − p_b` at high pressure). Phenomenological;
//!   it produces the slow start of real isotonic records (Chou & Hannaford
//!   1996 call it the threshold pressure of the bladder).
//! * `T_bladder`: the unpressurised muscle is a spring about its slack
//!   contraction `ε_s`: stiff when stretched below it (braid locking, `K_stretch`),
//!   soft when contracted above it (rubber, `K_rubber`, resisting contraction).
//! * `F_slip`: braid–bladder friction as `N` Maxwell-slip elements (Vo Minh,
//!   Tjahjowidodo, Ramon & Van Brussel, IEEE/ASME T-Mech 16(1), 2011): each
//!   element has a state `z_i ∈ [−1, 1]` that moves by `Δε/δ_i` and saturates
//!   (slips) at ±1; the force is `Σ w_i z_i · F_sat`, with the saturation force
//!   growing with the active force (friction between braid and bladder grows
//!   with the contact pressure): `F_sat = F_c0 + μ·T_act`. The element states
//!   are the non-local memory: a reversal inside the loop follows a minor loop
//!   and returns to the major loop, without a jump.
//! * `c·ε̇`: viscous damping of the bladder and the load guide.
//!
//! Isotonically the static curve is `T_act + T_bladder ∓ F_sat = L`: pressure
//! needed rises with load, the contraction branch needs more pressure than the
//! expansion branch.

use core::f64::consts::PI;

/// Standard gravity, m/s².
pub const G_MPS2: f64 = 9.806_65;

/// Number of Maxwell-slip elements.
pub const SLIP_ELEMENTS: usize = 8;

/// Physical parameters of the simulated muscle and its load guide.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MuscleParams {
    /// Rest (reference) length `L0`, m: contraction is `(L0 − L)/L0`.
    pub rest_length_m: f64,
    /// Inner radius `r0` at `ε = 0`, m.
    pub radius_m: f64,
    /// Braid angle `α0` at `ε = 0`, rad.
    pub braid_angle_rad: f64,
    /// Tondu–Lopez end-effect factor `k` (1 = ideal cylinder).
    pub end_factor: f64,
    /// `p_b`: bladder threshold pressure scale, MPa.
    pub bladder_pressure_mpa: f64,
    /// `ε_s`: contraction of the unloaded, unpressurised muscle.
    pub slack_contraction: f64,
    /// Stiffness when stretched below `ε_s`, N per unit contraction.
    pub stretch_stiffness_n: f64,
    /// Stiffness of the rubber resisting contraction above `ε_s`, N per unit contraction.
    pub rubber_stiffness_n: f64,
    /// `F_c0`: friction saturation force at zero active force, N.
    pub friction_base_n: f64,
    /// `μ`: friction saturation force per newton of active force.
    pub friction_ratio: f64,
    /// `μ_L`: friction saturation force per newton of hung load, from the
    /// load's own path (a rope over a pulley whose bearing carries the
    /// load, a guided carriage): 0 for none. The braid's friction (`μ`,
    /// with the active force) grows with the pressure, and every load is
    /// swept over the same pressures, so at one point of the stroke it
    /// leaves the loop's pressure height nearly the same at every load
    /// ([`MuscleParams::loop_height_mpa`]); this one grows it with the load.
    pub load_friction_ratio: f64,
    /// `δ_i`: break-away contraction of each slip element (fraction of `L0`).
    pub slip_contraction: [f64; SLIP_ELEMENTS],
    /// `w_i`: weight of each slip element (they sum to 1).
    pub slip_weight: [f64; SLIP_ELEMENTS],
    /// Viscous damping `c`, N per unit contraction per second.
    pub damping_n_s: f64,
    /// `K_c`: stiffness of the rubber's slow (Maxwell) arm, N per unit
    /// contraction; 0 for none. The arm resists a change of contraction at
    /// first and relaxes with [`MuscleParams::creep_time_s`], so after a
    /// pressure step the muscle moves part of the way at once and creeps the
    /// rest (a standard linear solid for the bladder rubber).
    pub creep_stiffness_n: f64,
    /// `τ_c`: relaxation time of the slow arm, s (> 0).
    pub creep_time_s: f64,
    /// Moving mass besides the hung load (muscle end, guide, load cell), kg.
    pub moving_mass_kg: f64,
    /// Dead volume of the muscle's fittings and tube, m³.
    pub dead_volume_m3: f64,
}

impl MuscleParams {
    /// The reference muscle: a 23 mm bore, 300 mm McKibben muscle, 100–600 N
    /// at 0–0.5 MPa.
    ///
    /// Origin: `r0`, `α0`, `k` are of the order Tondu & Lopez (2000) report
    /// for their muscles (`α0` = 20°, `k` ≈ 1); `r0`, `p_b` and `K_rubber`
    /// were then fitted (least squares, by hand-run script) to shape targets:
    /// 2 % contraction at 0 MPa and 25 % at 0.5 MPa under 100 N, about 16 %
    /// at 0.5 MPa under 600 N, and the mid-stroke shape of isotonic records of
    /// a 100–300 N muscle (4–5 % at 0.1 MPa, 13 % at 0.25 MPa under 100 N).
    /// Friction (`F_c0`, `μ`, `δ_i`) gives a loop about 0.04 MPa high at mid
    /// stroke under 100 N (the paper's `2·be`). Checked by the unit tests below.
    pub const DEFAULT: MuscleParams = MuscleParams {
        rest_length_m: 0.30,
        radius_m: 0.0115,
        braid_angle_rad: 20.0 * PI / 180.0,
        end_factor: 1.0,
        bladder_pressure_mpa: 0.271,
        slack_contraction: 0.023,
        stretch_stiffness_n: 33_333.0,
        rubber_stiffness_n: 1_728.0,
        friction_base_n: 20.0,
        friction_ratio: 0.11,
        load_friction_ratio: 0.0,
        slip_contraction: [0.0015, 0.0025, 0.004, 0.006, 0.009, 0.013, 0.018, 0.025],
        slip_weight: [0.125; SLIP_ELEMENTS],
        damping_n_s: 300.0,
        creep_stiffness_n: 0.0,
        creep_time_s: 2.0,
        moving_mass_kg: 3.0,
        dead_volume_m3: 20e-6,
    };

    /// A 10 mm bore muscle of the kind sold for small orthoses (the size of a
    /// Festo DMSP-10: about 630 N at 0.6 MPa and zero contraction, 25 %
    /// stroke), at `rest_length_m`. The reference muscle's braid, scaled:
    /// the radius to 5 mm, the rubber, stretch and friction forces with the
    /// cross-section (× 0.19), the dead volume to a short 4 mm tube.
    pub fn small_bore_10mm(rest_length_m: f64) -> MuscleParams {
        let d = MuscleParams::DEFAULT;
        let area_ratio = (0.005 / d.radius_m).powi(2);
        MuscleParams {
            rest_length_m,
            radius_m: 0.005,
            stretch_stiffness_n: d.stretch_stiffness_n * area_ratio,
            rubber_stiffness_n: d.rubber_stiffness_n * area_ratio,
            friction_base_n: d.friction_base_n * area_ratio,
            damping_n_s: d.damping_n_s * area_ratio,
            moving_mass_kg: 0.5,
            dead_volume_m3: 4e-6,
            ..d
        }
    }

    /// `a = 3/tan²α0` of the Tondu–Lopez model.
    pub fn tl_a(&self) -> f64 {
        let t = self.braid_angle_rad.tan();
        3.0 / (t * t)
    }

    /// `b = 1/sin²α0` of the Tondu–Lopez model.
    pub fn tl_b(&self) -> f64 {
        let s = self.braid_angle_rad.sin();
        1.0 / (s * s)
    }

    /// Pressure acting on the braid after the bladder's share, MPa.
    pub fn effective_pressure_mpa(&self, pressure_mpa: f64) -> f64 {
        let p = pressure_mpa.max(0.0);
        let pb = self.bladder_pressure_mpa;
        p - pb * (1.0 - (-p / pb).exp())
    }

    /// Tondu–Lopez active tension at gauge `pressure_mpa` and `contraction`, N
    /// (eq. 4 of Tondu & Lopez 2000, on the effective pressure). Not below
    /// zero: past the free contraction the braid no longer pulls.
    pub fn active_tension_n(&self, pressure_mpa: f64, contraction: f64) -> f64 {
        let area_m2 = PI * self.radius_m * self.radius_m;
        let g = self.tl_a() * (1.0 - self.end_factor * contraction).powi(2) - self.tl_b();
        (area_m2 * self.effective_pressure_mpa(pressure_mpa) * 1e6 * g).max(0.0)
    }

    /// Passive bladder/braid tension at `contraction`, N (positive pulls).
    pub fn bladder_tension_n(&self, contraction: f64) -> f64 {
        let d = self.slack_contraction - contraction;
        if d > 0.0 {
            self.stretch_stiffness_n * d
        } else {
            self.rubber_stiffness_n * d
        }
    }

    /// Friction saturation force `F_sat = F_c0 + μ·T_act + μ_L·L`, N, under
    /// the hung load `load_n` (`L`, not below 0).
    pub fn friction_saturation_n(&self, active_tension_n: f64, load_n: f64) -> f64 {
        self.friction_base_n
            + self.friction_ratio * active_tension_n
            + self.load_friction_ratio * load_n.max(0.0)
    }

    /// The loop's height at `contraction` under `load_n`, MPa: the pressure
    /// the contraction branch needs there minus the expansion branch's,
    /// friction fully slipping (the loop's height away from reversals, as
    /// the paper's `2·be` is at mid-stroke). By bisection on each branch's
    /// static contraction over 0–1 MPa.
    pub fn loop_height_mpa(&self, load_n: f64, contraction: f64) -> f64 {
        let pressure_at = |sign: f64| {
            let (mut lo, mut hi) = (0.0, 1.0);
            for _ in 0..50 {
                let mid = 0.5 * (lo + hi);
                if self.static_contraction_with_friction(mid, load_n, sign) < contraction {
                    lo = mid;
                } else {
                    hi = mid;
                }
            }
            0.5 * (lo + hi)
        };
        pressure_at(1.0) - pressure_at(-1.0)
    }

    /// Inner volume at `contraction`, m³: the braid's cylinder,
    /// `V = π r0² L0 (1 − ε)(1 − cos²α0 (1 − ε)²)/sin²α0`, plus the dead volume.
    pub fn volume_m3(&self, contraction: f64) -> f64 {
        let (s, c) = self.braid_angle_rad.sin_cos();
        let l = 1.0 - contraction;
        let v0 = PI * self.radius_m * self.radius_m * self.rest_length_m;
        v0 * l * (1.0 - c * c * l * l) / (s * s) + self.dead_volume_m3
    }

    /// Static contraction with no friction (the centre line of the loop) at
    /// `pressure_mpa` under `load_n`, by bisection on the force balance.
    pub fn static_contraction(&self, pressure_mpa: f64, load_n: f64) -> f64 {
        self.static_contraction_with_friction(pressure_mpa, load_n, 0.0)
    }

    /// Static contraction with fully slipping friction: `sign = +1` on the
    /// contraction branch (friction opposes shortening), `−1` on expansion.
    pub fn static_contraction_with_friction(
        &self,
        pressure_mpa: f64,
        load_n: f64,
        sign: f64,
    ) -> f64 {
        let net = |x: f64| {
            let act = self.active_tension_n(pressure_mpa, x);
            act + self.bladder_tension_n(x)
                - sign * self.friction_saturation_n(act, load_n)
                - load_n
        };
        let (mut lo, mut hi) = (-0.2, 0.6);
        for _ in 0..60 {
            let mid = 0.5 * (lo + hi);
            if net(mid) > 0.0 {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        0.5 * (lo + hi)
    }
}

/// State of the simulated muscle.
#[derive(Clone, Debug)]
pub struct Muscle {
    params: MuscleParams,
    contraction: f64,
    velocity_per_s: f64,
    slip: [f64; SLIP_ELEMENTS],
    /// Rest position of the rubber's slow arm (its dashpot), contraction.
    creep_rest: f64,
}

/// What the muscle does in one step, for traces.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct MuscleForces {
    /// Active Tondu–Lopez tension, N.
    pub active_n: f64,
    /// Friction force of the slip elements, N (positive opposes contraction).
    pub friction_n: f64,
}

impl Muscle {
    /// A muscle at rest under `load_n` with zero pressure, friction relaxed.
    pub fn new(params: MuscleParams, load_n: f64) -> Muscle {
        let contraction = params.static_contraction(0.0, load_n);
        Muscle {
            params,
            contraction,
            velocity_per_s: 0.0,
            slip: [0.0; SLIP_ELEMENTS],
            creep_rest: contraction,
        }
    }

    /// The parameters.
    pub fn params(&self) -> &MuscleParams {
        &self.params
    }

    /// Change the parameters, keeping the state (a muscle that wears while
    /// it works, `crate::wear`).
    pub fn set_params(&mut self, params: MuscleParams) {
        self.params = params;
    }

    /// Contraction, fraction of rest length.
    pub fn contraction(&self) -> f64 {
        self.contraction
    }

    /// Contraction rate, 1/s.
    pub fn velocity_per_s(&self) -> f64 {
        self.velocity_per_s
    }

    /// Inner volume now, m³.
    pub fn volume_m3(&self) -> f64 {
        self.params.volume_m3(self.contraction)
    }

    /// Mount the muscle at `contraction`, at rest (an isometric fixture is
    /// set to its length before the test).
    pub fn mount_at(&mut self, contraction: f64) {
        self.contraction = contraction;
        self.velocity_per_s = 0.0;
        self.slip = [0.0; SLIP_ELEMENTS];
        self.creep_rest = contraction;
    }

    /// Advance by `dt_s` at gauge `pressure_mpa` under `load_n` (semi-implicit
    /// Euler; keep `dt_s` ≤ 0.5 ms for the stiff stretch spring).
    pub fn step(&mut self, pressure_mpa: f64, load_n: f64, dt_s: f64) -> MuscleForces {
        let p = &self.params;
        let active_n = p.active_tension_n(pressure_mpa, self.contraction);
        let sat_n = p.friction_saturation_n(active_n, load_n);
        let friction_n: f64 = self
            .slip
            .iter()
            .zip(p.slip_weight.iter())
            .map(|(z, w)| z * w)
            .sum::<f64>()
            * sat_n;
        // The slow arm pulls back towards where it has relaxed to.
        let creep_n = p.creep_stiffness_n * (self.contraction - self.creep_rest);
        let net_n = active_n + p.bladder_tension_n(self.contraction)
            - friction_n
            - creep_n
            - p.damping_n_s * self.velocity_per_s
            - load_n;
        // A hung load: its mass moves with the muscle end.
        let mass_kg = p.moving_mass_kg + load_n.max(0.0) / G_MPS2;
        let accel = net_n / (mass_kg * p.rest_length_m);
        self.velocity_per_s += accel * dt_s;
        let d = self.velocity_per_s * dt_s;
        self.contraction += d;
        // Maxwell-slip: each element sticks (z moves with the motion) until it
        // saturates, then slips.
        for (z, delta) in self.slip.iter_mut().zip(p.slip_contraction.iter()) {
            *z = (*z + d / delta).clamp(-1.0, 1.0);
        }
        // The slow arm's dashpot: τ_c·q̇ = x − q (exact for a step of x).
        if p.creep_stiffness_n > 0.0 && p.creep_time_s > 0.0 {
            let a = 1.0 - (-dt_s / p.creep_time_s).exp();
            self.creep_rest += a * (self.contraction - self.creep_rest);
        }
        MuscleForces {
            active_n,
            friction_n,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const P: MuscleParams = MuscleParams::DEFAULT;

    #[test]
    fn static_curve_matches_the_reference_muscle_shape() {
        // 2 % at 0 MPa and ~25 % at 0.5 MPa under 100 N.
        let x0 = P.static_contraction(0.0, 100.0);
        assert!((x0 - 0.020).abs() < 0.002, "{x0}");
        let x5 = P.static_contraction(0.5, 100.0);
        assert!((x5 - 0.25).abs() < 0.01, "{x5}");
        // Heavier loads: less contraction everywhere, ~16 % at 0.5 MPa under 600 N.
        let x600 = P.static_contraction(0.5, 600.0);
        assert!((x600 - 0.16).abs() < 0.01, "{x600}");
        for p in [0.0, 0.1, 0.2, 0.3, 0.4, 0.5] {
            let mut prev = f64::INFINITY;
            for load in [100.0, 200.0, 300.0, 400.0, 500.0, 600.0] {
                let x = P.static_contraction(p, load);
                assert!(x < prev, "{p} MPa {load} N");
                prev = x;
            }
        }
    }

    #[test]
    fn contraction_branch_needs_more_pressure() {
        for load in [100.0, 350.0, 600.0] {
            for p in [0.15, 0.25, 0.35, 0.45] {
                let up = P.static_contraction_with_friction(p, load, 1.0);
                let down = P.static_contraction_with_friction(p, load, -1.0);
                assert!(up < down, "{load} N {p} MPa: {up} vs {down}");
            }
        }
    }

    #[test]
    fn volume_grows_with_contraction() {
        let v0 = P.volume_m3(0.0);
        let v25 = P.volume_m3(0.25);
        // 125 mL braid cylinder plus 20 mL dead volume at rest length.
        assert!((v0 - 145e-6).abs() < 3e-6, "{v0}");
        assert!(v25 > 2.0 * v0, "{v25}");
    }

    #[test]
    fn dynamic_muscle_settles_on_the_static_branch() {
        let mut m = Muscle::new(P, 200.0);
        // Slow ramp 0 → 0.3 MPa: ends on the contraction branch.
        let dt = 2.5e-4;
        let n = (10.0 / dt) as usize;
        for i in 0..n {
            m.step(0.3 * i as f64 / n as f64, 200.0, dt);
        }
        for _ in 0..4000 {
            m.step(0.3, 200.0, dt);
        }
        let up = P.static_contraction_with_friction(0.3, 200.0, 1.0);
        assert!(
            (m.contraction() - up).abs() < 0.004,
            "{} vs {up}",
            m.contraction()
        );
    }

    #[test]
    fn creep_arm_makes_a_pressure_step_settle_slowly() {
        // After a step 0.1 -> 0.3 MPa under 200 N the reference muscle is
        // settled within 0.5 s; with a slow arm a quarter of the move or
        // more is still to come at 0.5 s, and it arrives within ~5 τ_c.
        let dt = 2.5e-4;
        let response = |params: MuscleParams, secs: f64| {
            let mut m = Muscle::new(params, 200.0);
            for _ in 0..(4.0 / dt) as usize {
                m.step(0.1, 200.0, dt);
            }
            let before = m.contraction();
            for _ in 0..(secs / dt) as usize {
                m.step(0.3, 200.0, dt);
            }
            m.contraction() - before
        };
        let creepy = MuscleParams {
            creep_stiffness_n: 4000.0,
            creep_time_s: 1.5,
            ..P
        };
        let (plain_half, plain_end) = (response(P, 0.5), response(P, 10.0));
        assert!((plain_half - plain_end).abs() < 0.05 * plain_end);
        let (creep_half, creep_end) = (response(creepy, 0.5), response(creepy, 10.0));
        assert!(
            creep_end - creep_half > 0.25 * creep_end,
            "{creep_half} {creep_end}"
        );
        assert!(
            (creep_end - plain_end).abs() < 0.05 * plain_end,
            "{creep_end} {plain_end}"
        );
    }

    #[test]
    fn partial_reversal_has_no_jump_and_memory() {
        // Non-local memory: reverse at 0.3 MPa, come back to 0.3 MPa: the
        // muscle returns near where it left (minor loop closes), not on a jump.
        let mut m = Muscle::new(P, 100.0);
        let dt = 2.5e-4;
        let ramp = |m: &mut Muscle, from: f64, to: f64, secs: f64| {
            let n = (secs / dt) as usize;
            for i in 0..=n {
                m.step(from + (to - from) * i as f64 / n as f64, 100.0, dt);
            }
        };
        ramp(&mut m, 0.0, 0.3, 6.0);
        let at_top = m.contraction();
        ramp(&mut m, 0.3, 0.28, 0.4);
        // A small pressure drop inside the loop barely moves the muscle.
        assert!((m.contraction() - at_top).abs() < 0.004);
        ramp(&mut m, 0.28, 0.3, 0.4);
        assert!((m.contraction() - at_top).abs() < 0.002);
    }
}
