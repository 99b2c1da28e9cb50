//! A simulated muscle, `no_std`, for the QEMU image and host tests: chamber
//! pressure fed by an inlet/exhaust valve pair, and a contraction with
//! hysteresis and a first-order lag. Plus [`SimBus`], the signals between
//! it and the simulated sensors and PWM channels of [`crate::sim_io`].
//!
//! # The muscle
//! * Chamber: `dp/dt = k_fill·e(d_in)·(p_supply − p) − k_vent·e(d_ex)·p`,
//!   where `e(d) = (d − d_dead)/(1 − d_dead)` clamped to `[0, 1]` is the
//!   effective opening of an on/off valve at PWM duty `d` whose opening
//!   time takes `d_dead` of each PWM period. Explicit Euler; `p` clamped to
//!   `[0, p_supply]`.
//! * Equilibrium contraction: a play operator between the two branches of
//!   the *plant's own* hysteresis model — it follows the contraction branch
//!   while the pressure rises, the expansion branch while it falls, and stays
//!   put in between (`x_eq = clamp(x_eq, x_C(p), x_E(p))`, with `x_C`, `x_E`
//!   the branch inverses of eqs. 25/26). Its outer loop is the model's loop.
//! * Contraction: `dx/dt = (x_eq − x)/τ` (the mass–damper of the orthosis).
//! * With effects ([`MusclePlant::with_effects`]) the equilibrium is
//!   pam-core's [`Simulator`] instead of the play operator: the plant's
//!   hysteresis model with memory, rate dependence, creep, load-dependent
//!   width or a shape correction, driven by the chamber pressure.
//!
//! The plant is built from parameters that differ from the controller's (see
//! [`crate::scenario`]), so the feedforward is not exact.

use core::cell::Cell;

use crate::controller::SensorId;
use crate::hal::{Counts, PressureCalibration, SensorErrorKind};
use crate::sim_io::{SensorSource, PWM_MAX_DUTY};
use pam_core::{clamp, Branch, Coeffs, Effects, LoadModel, Simulator, TrackerConfig};

/// Physical constants of the simulated muscle and valves.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PlantConfig {
    /// Supply pressure, MPa gauge.
    pub supply_mpa: f32,
    /// Fill rate constant `k_fill` with the inlet fully open, 1/s.
    pub fill_rate_per_s: f32,
    /// Vent rate constant `k_vent` with the exhaust fully open, 1/s.
    pub vent_rate_per_s: f32,
    /// Fraction of a PWM period an on/off valve needs to open, `d_dead`.
    pub valve_dead_duty: f32,
    /// Time constant of the contraction, s.
    pub lag_s: f32,
}

impl PlantConfig {
    /// A 0.6 MPa supply, valves that fill a 30 ml muscle in about 0.1 s,
    /// 5 % valve dead duty, 30 ms mechanical lag.
    pub const DEFAULT: PlantConfig = PlantConfig {
        supply_mpa: 0.6,
        fill_rate_per_s: 20.0,
        vent_rate_per_s: 20.0,
        valve_dead_duty: 0.05,
        lag_s: 0.03,
    };
}

/// The simulated muscle.
#[derive(Clone, Debug)]
pub struct MusclePlant {
    model: LoadModel,
    config: PlantConfig,
    pressure_mpa: f32,
    equilibrium: f32,
    contraction: f32,
    /// The model with effects, when the plant has them.
    effects: Option<EffectsPlant>,
}

/// The equilibrium of a plant with effects.
#[derive(Clone, Debug)]
struct EffectsPlant {
    sim: Simulator<8>,
    t_s: f32,
}

impl MusclePlant {
    /// A muscle at rest (zero pressure, at the root contraction of `model`).
    pub fn new(model: LoadModel, config: PlantConfig) -> MusclePlant {
        let x0 = model.root_contraction();
        MusclePlant {
            model,
            config,
            pressure_mpa: 0.0,
            equilibrium: x0,
            contraction: x0,
            effects: None,
        }
    }

    /// A muscle at rest whose equilibrium contraction is pam-core's
    /// [`Simulator`] of `coeffs` with `effects` at `load_n` (its branch
    /// switching driven by the chamber pressure).
    pub fn with_effects(
        coeffs: Coeffs,
        effects: Effects,
        load_n: f32,
        config: PlantConfig,
    ) -> Result<MusclePlant, pam_core::Error> {
        let sim = Simulator::new(coeffs, effects, TrackerConfig::DEFAULT_PRESSURE, load_n)?;
        let mut plant = MusclePlant::new(coeffs.load_model(load_n)?, config);
        plant.effects = Some(EffectsPlant { sim, t_s: 0.0 });
        Ok(plant)
    }

    /// Chamber pressure, MPa gauge.
    pub fn pressure_mpa(&self) -> f32 {
        self.pressure_mpa
    }

    /// Contraction, fraction of rest length.
    pub fn contraction(&self) -> f32 {
        self.contraction
    }

    /// The model of the load the muscle carries.
    pub fn model(&self) -> &LoadModel {
        &self.model
    }

    /// Change the load (its model).
    pub fn set_model(&mut self, model: LoadModel) {
        self.model = model;
    }

    fn opening(&self, duty: f32) -> f32 {
        let dead = self.config.valve_dead_duty;
        clamp((duty - dead) / (1.0 - dead), 0.0, 1.0)
    }

    /// Advance by `dt_s` with the inlet and exhaust at the given duty
    /// fractions.
    pub fn step(&mut self, inlet_duty: f32, exhaust_duty: f32, dt_s: f32) {
        let c = &self.config;
        let dp = c.fill_rate_per_s * self.opening(inlet_duty) * (c.supply_mpa - self.pressure_mpa)
            - c.vent_rate_per_s * self.opening(exhaust_duty) * self.pressure_mpa;
        self.pressure_mpa = clamp(self.pressure_mpa + dp * dt_s, 0.0, c.supply_mpa);
        if let Some(e) = &mut self.effects {
            e.t_s += dt_s;
            self.equilibrium = e.sim.step(e.t_s, self.pressure_mpa, self.model.load_n());
        } else {
            self.play();
        }
        let k = clamp(dt_s / self.config.lag_s, 0.0, 1.0);
        self.contraction += (self.equilibrium - self.contraction) * k;
    }

    /// The play operator between the branches.
    fn play(&mut self) {
        let a = self
            .model
            .contraction(self.pressure_mpa, Branch::Contraction);
        let b = self.model.contraction(self.pressure_mpa, Branch::Expansion);
        let (lo, hi) = if a <= b { (a, b) } else { (b, a) };
        self.equilibrium = clamp(self.equilibrium, lo, hi);
    }
}

/// A small deterministic noise source (a 32-bit LCG), so the simulated
/// sensors dither like real converters.
#[derive(Clone, Copy, Debug)]
pub struct Noise(u32);

impl Noise {
    /// Seeded generator.
    pub const fn new(seed: u32) -> Noise {
        Noise(seed)
    }

    /// Uniform in `[-1, 1)`.
    pub fn sample(&mut self) -> f32 {
        // Numerical Recipes' LCG constants; the top 24 bits are used.
        self.0 = self.0.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
        (self.0 >> 8) as f32 / (1u32 << 23) as f32 - 1.0
    }
}

/// The signals between a simulated muscle and the controller: what the
/// sensors return and what the PWM channels were set to. Interior mutability
/// lets the sensor and valve objects share it by `&`: it is the
/// [`SensorSource`] of [`crate::sim_io`]'s sensors (`SimPressure { source:
/// &bus, .. }`, `SimContraction(&bus)`, `SimLoad(&bus)`), and its duty cells
/// are the registers of its [`crate::sim_io::SimPwm`]s
/// (`SimPwm::new(&bus.inlet_duty)`).
#[derive(Debug)]
pub struct SimBus {
    /// Code the pressure sensor returns.
    pub pressure_counts: Cell<Counts>,
    /// Contraction the position sensor returns.
    pub contraction: Cell<f32>,
    /// Load the load cell returns, N.
    pub load_n: Cell<f32>,
    /// A sensor that fails its reads with this kind, if any.
    pub failing: Cell<Option<(SensorId, SensorErrorKind)>>,
    /// Inlet PWM duty, of [`PWM_MAX_DUTY`].
    pub inlet_duty: Cell<u16>,
    /// Exhaust PWM duty, of [`PWM_MAX_DUTY`].
    pub exhaust_duty: Cell<u16>,
}

impl SimBus {
    /// All readings zero, nothing failing, valves closed.
    pub const fn new() -> SimBus {
        SimBus {
            pressure_counts: Cell::new(Counts(0)),
            contraction: Cell::new(0.0),
            load_n: Cell::new(0.0),
            failing: Cell::new(None),
            inlet_duty: Cell::new(0),
            exhaust_duty: Cell::new(0),
        }
    }

    /// Publish the plant's state to the sensors, with noise of the given
    /// amplitudes (pressure in MPa, contraction, load in N).
    pub fn publish(
        &self,
        plant: &MusclePlant,
        load_n: f32,
        calibration: &PressureCalibration,
        noise: &mut Noise,
        amplitude: (f32, f32, f32),
    ) {
        self.pressure_counts
            .set(calibration.to_counts(plant.pressure_mpa() + amplitude.0 * noise.sample()));
        self.contraction
            .set(plant.contraction() + amplitude.1 * noise.sample());
        self.load_n.set(load_n + amplitude.2 * noise.sample());
    }

    /// Inlet and exhaust duty fractions.
    pub fn duties(&self) -> (f32, f32) {
        let max = f32::from(PWM_MAX_DUTY);
        (
            f32::from(self.inlet_duty.get()) / max,
            f32::from(self.exhaust_duty.get()) / max,
        )
    }

    fn fails(&self, sensor: SensorId) -> Result<(), SensorErrorKind> {
        match self.failing.get() {
            Some((s, kind)) if s == sensor => Err(kind),
            _ => Ok(()),
        }
    }
}

impl Default for SimBus {
    fn default() -> Self {
        SimBus::new()
    }
}

/// The values published last, or the injected failure of the sensor read.
impl SensorSource for SimBus {
    fn pressure_counts(&self) -> Result<Counts, SensorErrorKind> {
        self.fails(SensorId::Pressure)?;
        Ok(self.pressure_counts.get())
    }
    fn contraction(&self) -> Result<f32, SensorErrorKind> {
        self.fails(SensorId::Contraction)?;
        Ok(self.contraction.get())
    }
    fn load_n(&self) -> Result<f32, SensorErrorKind> {
        self.fails(SensorId::Load)?;
        Ok(self.load_n.get())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use pam_core::{Coeffs, Params};

    fn plant() -> MusclePlant {
        let model = Coeffs::new(Params::DEFAULT)
            .unwrap()
            .load_model(200.0)
            .unwrap();
        MusclePlant::new(model, PlantConfig::DEFAULT)
    }

    #[test]
    fn fills_to_supply_and_vents_to_zero() {
        let mut m = plant();
        for _ in 0..2000 {
            m.step(1.0, 0.0, 1e-3);
        }
        assert!((m.pressure_mpa() - 0.6).abs() < 1e-3);
        assert!((m.contraction() - m.model().max_contraction()).abs() < 1e-3);
        for _ in 0..2000 {
            m.step(0.0, 1.0, 1e-3);
        }
        assert!(m.pressure_mpa() < 1e-3);
        // Below the dead duty nothing flows.
        let p = m.pressure_mpa();
        m.step(0.04, 0.0, 1e-3);
        assert_eq!(m.pressure_mpa(), p);
    }

    #[test]
    fn contraction_shows_hysteresis() {
        // Settle at 0.25 MPa from below, then from above: the muscle is
        // shorter when reached from above (it stays on the expansion branch).
        let hold = |m: &mut MusclePlant, target: f32| {
            for _ in 0..5000 {
                let e = target - m.pressure_mpa();
                let (i, x) = if e > 0.0 {
                    (e * 50.0, 0.0)
                } else {
                    (0.0, -e * 50.0)
                };
                m.step(i, x, 1e-3);
            }
        };
        let mut m = plant();
        hold(&mut m, 0.25);
        let from_below = m.contraction();
        hold(&mut m, 0.45);
        hold(&mut m, 0.25);
        let from_above = m.contraction();
        assert!(from_above > from_below + 0.01, "{from_below} {from_above}");
        let model = m.model();
        assert!((from_below - model.contraction(0.25, Branch::Contraction)).abs() < 2e-3);
        assert!((from_above - model.contraction(0.25, Branch::Expansion)).abs() < 2e-3);
    }

    #[test]
    fn noise_is_in_range_and_not_constant() {
        let mut n = Noise::new(1);
        let mut prev = n.sample();
        for _ in 0..10_000 {
            let v = n.sample();
            assert!((-1.0..1.0).contains(&v));
            assert_ne!(v, prev);
            prev = v;
        }
    }
}
