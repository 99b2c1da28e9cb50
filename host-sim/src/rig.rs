//! The simulated test rig: muscle, chamber, valve, load and sensors, stepped
//! together at a fixed plant rate.

use crate::plant::{Muscle, MuscleParams};
use crate::pneumatics::{Chamber, PneumaticParams, ValveOpening};
use crate::sensors::{ContractionSensorSim, LoadCellSim, PressureSensorSim};

/// Plant integration step, s (2 kHz; see [`Muscle::step`] for the bound).
pub const PLANT_DT_S: f64 = 5e-4;

/// A sample in the project's CSV format `t_s,load_n,pressure_mpa,contraction`.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Sample {
    /// Time, s.
    pub t_s: f64,
    /// Load hung on the muscle, N (as the load cell reads it).
    pub load_n: f64,
    /// Measured gauge pressure, MPa.
    pub pressure_mpa: f64,
    /// Measured contraction, fraction of rest length.
    pub contraction: f64,
}

/// The rig's true state, for traces and assertions (what no sensor gives).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct TrueState {
    /// Time, s.
    pub t_s: f64,
    /// Gauge pressure, MPa.
    pub pressure_mpa: f64,
    /// Contraction.
    pub contraction: f64,
    /// Load, N.
    pub load_n: f64,
}

/// The whole simulated rig.
#[derive(Clone, Debug)]
pub struct Rig {
    /// The muscle.
    pub muscle: Muscle,
    /// The muscle's air.
    pub chamber: Chamber,
    /// Pressure transducer.
    pub pressure_sensor: PressureSensorSim,
    /// Contraction sensor.
    pub contraction_sensor: ContractionSensorSim,
    /// Load cell.
    pub load_cell: LoadCellSim,
    /// Valve path openings now.
    pub opening: ValveOpening,
    load_n: f64,
    t_s: f64,
    /// The isometric clamp, when the muscle is held rather than loaded.
    clamp: Option<IsometricClamp>,
}

/// An isometric test's clamp: both ends of the muscle are held by a fixture
/// with a stiff load cell, so the muscle pulls on a spring instead of
/// lifting a weight. A real fixture and load cell are stiff, not rigid: the
/// contraction moves by `force/(stiffness·rest length)` (about 0.0013 at
/// 800 N), which also lets the braid's friction act as it does on a real
/// rig. The fixture holds the length both ways; a slack muscle buckles
/// rather than pushes, so the logged force is never below 0 N.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct IsometricClamp {
    /// Contraction at which the fixture holds the muscle.
    pub hold_contraction: f64,
    /// Stiffness of clamp and load cell, N/m.
    pub stiffness_n_per_m: f64,
}

impl IsometricClamp {
    /// The fixture's force on the muscle at `contraction`, N (positive:
    /// tension, holding the muscle back; negative: holding it out).
    pub fn force_n(&self, contraction: f64, rest_length_m: f64) -> f64 {
        self.stiffness_n_per_m * (contraction - self.hold_contraction) * rest_length_m
    }
}

impl Rig {
    /// A rig with `muscle` and `pneumatics` at rest under `load_n`, sensors
    /// seeded from `seed`.
    pub fn new(muscle: MuscleParams, pneumatics: PneumaticParams, load_n: f64, seed: u64) -> Rig {
        Rig {
            muscle: Muscle::new(muscle, load_n),
            chamber: Chamber::new(pneumatics, 0.0),
            pressure_sensor: PressureSensorSim::new(seed.wrapping_mul(3).wrapping_add(1)),
            contraction_sensor: ContractionSensorSim::new(seed.wrapping_mul(3).wrapping_add(2)),
            load_cell: LoadCellSim::new(seed.wrapping_mul(3).wrapping_add(3)),
            opening: ValveOpening::default(),
            load_n,
            t_s: 0.0,
            clamp: None,
        }
    }

    /// Hold the muscle in `clamp` (an isometric test); `None` hangs the
    /// load of [`Rig::set_load_n`] again. While clamped the load is the
    /// clamp's force.
    pub fn set_clamp(&mut self, clamp: Option<IsometricClamp>) {
        self.clamp = clamp;
        if let Some(c) = clamp {
            self.muscle.mount_at(c.hold_contraction);
        }
    }

    /// The reference rig: [`MuscleParams::DEFAULT`], [`PneumaticParams::DEFAULT`].
    pub fn reference(load_n: f64, seed: u64) -> Rig {
        Rig::new(
            MuscleParams::DEFAULT,
            PneumaticParams::DEFAULT,
            load_n,
            seed,
        )
    }

    /// Set the load (a step: the hung weight changes).
    pub fn set_load_n(&mut self, load_n: f64) {
        self.load_n = load_n;
    }

    /// Change the supply pressure, MPa gauge (fault injection: 0 is a lost
    /// supply).
    pub fn set_supply_mpa(&mut self, supply_mpa: f64) {
        self.chamber.set_supply_mpa(supply_mpa);
    }

    /// Time, s.
    pub fn t_s(&self) -> f64 {
        self.t_s
    }

    /// True state now.
    pub fn true_state(&self) -> TrueState {
        TrueState {
            t_s: self.t_s,
            pressure_mpa: self.chamber.pressure_mpa(),
            contraction: self.muscle.contraction(),
            load_n: self.load_n,
        }
    }

    /// Advance by `duration_s` in plant steps with the valve at `self.opening`.
    pub fn advance(&mut self, duration_s: f64) {
        let n = (duration_s / PLANT_DT_S).round().max(1.0) as usize;
        let dt = duration_s / n as f64;
        for _ in 0..n {
            self.plant_step(dt);
        }
    }

    fn plant_step(&mut self, dt: f64) {
        if let Some(c) = self.clamp {
            self.load_n = c.force_n(
                self.muscle.contraction(),
                self.muscle.params().rest_length_m,
            );
        }
        let p = self.chamber.pressure_mpa();
        self.muscle.step(p, self.load_n, dt);
        let v = self.muscle.volume_m3();
        self.chamber.step(self.opening, v, dt);
        self.t_s += dt;
    }

    /// Advance by `duration_s` with the rig's own pressure regulator (the
    /// test bench's, not the firmware's) holding `pressure_mpa`: a
    /// proportional valve opened in proportion to the pressure error,
    /// fully open at 20 kPa error.
    pub fn advance_regulated(&mut self, pressure_mpa: f64, duration_s: f64) {
        let n = (duration_s / PLANT_DT_S).round().max(1.0) as usize;
        let dt = duration_s / n as f64;
        for _ in 0..n {
            let e = (pressure_mpa - self.chamber.pressure_mpa()) / 0.02;
            self.opening = ValveOpening {
                inlet: e.clamp(0.0, 1.0),
                exhaust: (-e).clamp(0.0, 1.0),
            };
            self.plant_step(dt);
        }
    }

    /// One measured sample, as a data logger records it.
    pub fn measure(&mut self) -> Sample {
        let s = self.true_state();
        let load_n = self.load_cell.read_n(s.load_n);
        Sample {
            t_s: s.t_s,
            // Clamped, a slack muscle reads 0 N, never a push.
            load_n: if self.clamp.is_some() {
                load_n.max(0.0)
            } else {
                load_n
            },
            pressure_mpa: self.pressure_sensor.read_mpa(s.pressure_mpa),
            contraction: self.contraction_sensor.read(s.contraction),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn regulator_tracks_a_slow_ramp() {
        let mut rig = Rig::reference(100.0, 1);
        for k in 0..200 {
            rig.advance_regulated(0.5 * k as f64 / 200.0, 0.05);
        }
        let s = rig.true_state();
        assert!((s.pressure_mpa - 0.4975).abs() < 0.01, "{s:?}");
        assert!(s.contraction > 0.2, "{s:?}");
    }
}
