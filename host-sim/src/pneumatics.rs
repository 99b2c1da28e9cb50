//! Valve flow and chamber pressure dynamics.
//!
//! * Flow through an orifice by ISO 6358: `q = C·ρ0·p_up·√(T0/T)·φ(r)`,
//!   `φ = 1` when choked (`r = p_down/p_up ≤ b`), else
//!   `φ = √(1 − ((r − b)/(1 − b))²)`; `C` sonic conductance, `b` critical
//!   pressure ratio. Pressures absolute.
//! * Chamber, polytropic (`n` between isothermal 1 and adiabatic 1.4; Richer &
//!   Hurmuzlu, J. Dyn. Sys. Meas. Control 122(3), 2000):
//!   `dp/dt = (n·R·T·(q_in − q_out) − n·p·dV/dt)/V`.

/// Atmospheric pressure, Pa.
pub const P_ATM_PA: f64 = 101_325.0;
/// Specific gas constant of air, J/(kg·K).
pub const R_AIR: f64 = 287.05;
/// Supply temperature, K.
pub const T_SUPPLY_K: f64 = 293.15;
/// ISO 6358 reference density, kg/m³.
pub const RHO0_KG_M3: f64 = 1.185;

/// Pneumatic parameters of the rig.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PneumaticParams {
    /// Supply gauge pressure, MPa.
    pub supply_mpa: f64,
    /// Exhaust gauge pressure, MPa (0: atmosphere).
    pub exhaust_mpa: f64,
    /// Sonic conductance of a fully open valve path, m³/(s·Pa).
    pub conductance_m3_s_pa: f64,
    /// Critical pressure ratio `b`.
    pub critical_ratio: f64,
    /// Polytropic exponent `n`.
    pub polytropic: f64,
}

impl PneumaticParams {
    /// 0.6 MPa supply, atmosphere exhaust, a valve of the size of a 1/8"
    /// proportional valve (`C` = 1.2 L/(s·bar), `b` = 0.3; datasheet values
    /// of that class are 1–2 L/(s·bar), 0.2–0.4), `n` = 1.2.
    pub const DEFAULT: PneumaticParams = PneumaticParams {
        supply_mpa: 0.6,
        exhaust_mpa: 0.0,
        conductance_m3_s_pa: 1.2e-8,
        critical_ratio: 0.3,
        polytropic: 1.2,
    };
}

/// Mass flow from `p_up_pa` to `p_down_pa` (absolute) through conductance
/// `c_m3_s_pa`, kg/s; negative when the pressures are the other way round.
pub fn iso6358_flow_kg_s(c_m3_s_pa: f64, b: f64, p_up_pa: f64, p_down_pa: f64) -> f64 {
    if p_up_pa < p_down_pa {
        return -iso6358_flow_kg_s(c_m3_s_pa, b, p_down_pa, p_up_pa);
    }
    if p_up_pa <= 0.0 || p_up_pa.is_nan() {
        return 0.0;
    }
    let r = p_down_pa / p_up_pa;
    let phi = if r <= b {
        1.0
    } else {
        let u = (r - b) / (1.0 - b);
        (1.0 - u * u).max(0.0).sqrt()
    };
    c_m3_s_pa * RHO0_KG_M3 * p_up_pa * phi
}

/// Openings of the two valve paths, each 0 (closed) to 1 (fully open).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ValveOpening {
    /// Supply → muscle.
    pub inlet: f64,
    /// Muscle → exhaust.
    pub exhaust: f64,
}

/// The muscle's air: gauge pressure with polytropic dynamics.
#[derive(Clone, Debug)]
pub struct Chamber {
    params: PneumaticParams,
    pressure_pa: f64,
    last_volume_m3: Option<f64>,
}

impl Chamber {
    /// A chamber at gauge `pressure_mpa`.
    pub fn new(params: PneumaticParams, pressure_mpa: f64) -> Chamber {
        Chamber {
            params,
            pressure_pa: pressure_mpa * 1e6 + P_ATM_PA,
            last_volume_m3: None,
        }
    }

    /// Gauge pressure, MPa.
    pub fn pressure_mpa(&self) -> f64 {
        (self.pressure_pa - P_ATM_PA) * 1e-6
    }

    /// The parameters.
    pub fn params(&self) -> &PneumaticParams {
        &self.params
    }

    /// Change the supply gauge pressure, MPa (0: supply lost, the inlet
    /// opens to atmosphere and vents the muscle backwards).
    pub fn set_supply_mpa(&mut self, supply_mpa: f64) {
        self.params.supply_mpa = supply_mpa;
    }

    /// Net mass flow into the chamber for `opening`, kg/s.
    pub fn net_flow_kg_s(&self, opening: ValveOpening) -> f64 {
        let p = &self.params;
        let supply = p.supply_mpa * 1e6 + P_ATM_PA;
        let exhaust = p.exhaust_mpa * 1e6 + P_ATM_PA;
        let c = p.conductance_m3_s_pa;
        let q_in = iso6358_flow_kg_s(
            c * opening.inlet.clamp(0.0, 1.0),
            p.critical_ratio,
            supply,
            self.pressure_pa,
        );
        let q_out = iso6358_flow_kg_s(
            c * opening.exhaust.clamp(0.0, 1.0),
            p.critical_ratio,
            self.pressure_pa,
            exhaust,
        );
        q_in - q_out
    }

    /// Advance by `dt_s` with the valve at `opening` and the chamber volume
    /// now `volume_m3` (its change since the last step is the `dV/dt` term).
    /// Sub-steps internally so that a wide-open valve into a small volume
    /// stays stable; the pressure stays between exhaust and supply.
    pub fn step(&mut self, opening: ValveOpening, volume_m3: f64, dt_s: f64) {
        let n = self.params.polytropic;
        let dv = volume_m3 - self.last_volume_m3.unwrap_or(volume_m3);
        self.last_volume_m3 = Some(volume_m3);
        // Volume work, applied once per step: p·V^n constant for the change.
        if dv != 0.0 && volume_m3 > 0.0 {
            self.pressure_pa *= ((volume_m3 - dv) / volume_m3).powf(n);
        }
        let before_flow_pa = self.pressure_pa;
        const SUB: usize = 4;
        let h = dt_s / SUB as f64;
        for _ in 0..SUB {
            let q = self.net_flow_kg_s(opening);
            self.pressure_pa += n * R_AIR * T_SUPPLY_K * q / volume_m3 * h;
        }
        let lo = self.params.exhaust_mpa.min(0.0) * 1e6 + P_ATM_PA;
        // Flow moves the pressure toward supply or exhaust, never past the
        // higher of the supply and where it started (after a supply drop the
        // chamber empties through the flow, not in one step).
        let hi = (self.params.supply_mpa * 1e6 + P_ATM_PA).max(before_flow_pa);
        self.pressure_pa = self.pressure_pa.clamp(lo * 0.5, hi);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn flow_is_choked_then_falls_to_zero() {
        let c = 1e-8;
        let up = 700e3;
        let choked = iso6358_flow_kg_s(c, 0.3, up, 100e3);
        assert!((choked - c * RHO0_KG_M3 * up).abs() < 1e-12);
        assert_eq!(iso6358_flow_kg_s(c, 0.3, up, 0.2 * up), choked);
        let sub = iso6358_flow_kg_s(c, 0.3, up, 0.8 * up);
        assert!(sub > 0.0 && sub < choked);
        assert_eq!(iso6358_flow_kg_s(c, 0.3, up, up), 0.0);
        assert_eq!(iso6358_flow_kg_s(c, 0.3, 100e3, up), -choked);
    }

    #[test]
    fn open_inlet_fills_to_supply_and_exhaust_empties() {
        let mut ch = Chamber::new(PneumaticParams::DEFAULT, 0.0);
        let v = 200e-6;
        let full_in = ValveOpening {
            inlet: 1.0,
            exhaust: 0.0,
        };
        let mut t_half = None;
        for k in 0..20_000 {
            ch.step(full_in, v, 1e-4);
            if t_half.is_none() && ch.pressure_mpa() > 0.3 {
                t_half = Some(k as f64 * 1e-4);
            }
        }
        assert!((ch.pressure_mpa() - 0.6).abs() < 1e-3);
        // A 1/8" valve fills 0.2 L to 0.3 MPa in tens of milliseconds.
        let t = t_half.unwrap();
        assert!(t > 0.005 && t < 0.2, "{t}");
        let out = ValveOpening {
            inlet: 0.0,
            exhaust: 1.0,
        };
        for _ in 0..50_000 {
            ch.step(out, v, 1e-4);
        }
        assert!(ch.pressure_mpa().abs() < 2e-3, "{}", ch.pressure_mpa());
    }

    #[test]
    fn closed_chamber_pressure_drops_when_volume_grows() {
        let mut ch = Chamber::new(PneumaticParams::DEFAULT, 0.3);
        ch.step(ValveOpening::default(), 200e-6, 1e-3);
        ch.step(ValveOpening::default(), 220e-6, 1e-3);
        let abs = 0.3e6 + P_ATM_PA;
        let want = abs * (200.0f64 / 220.0).powf(1.2) - P_ATM_PA;
        assert!((ch.pressure_mpa() * 1e6 - want).abs() < 1.0);
    }
}
