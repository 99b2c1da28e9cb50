//! Simulated sensors: what the firmware reads, with noise, quantization,
//! offset and injectable faults. All randomness comes from a seeded ChaCha
//! generator, so every run is reproducible.

use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// Seeded Gaussian noise source (Box–Muller).
#[derive(Clone, Debug)]
pub struct Noise {
    rng: ChaCha8Rng,
    spare: Option<f64>,
}

impl Noise {
    /// A noise source from `seed`.
    pub fn new(seed: u64) -> Noise {
        Noise {
            rng: ChaCha8Rng::seed_from_u64(seed),
            spare: None,
        }
    }

    /// A standard normal sample.
    pub fn gaussian(&mut self) -> f64 {
        if let Some(s) = self.spare.take() {
            return s;
        }
        // u1 in (0, 1] so ln is finite.
        let u1 = 1.0 - self.rng.random::<f64>();
        let u2 = self.rng.random::<f64>();
        let r = (-2.0 * u1.ln()).sqrt();
        let (s, c) = (2.0 * core::f64::consts::PI * u2).sin_cos();
        self.spare = Some(r * s);
        r * c
    }

    /// A uniform sample in `[0, 1)`.
    pub fn uniform(&mut self) -> f64 {
        self.rng.random::<f64>()
    }
}

/// A fault injected into the pressure sensor.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum PressureFault {
    /// Working normally.
    None,
    /// Output stuck at a raw code.
    StuckAt(u16),
    /// Open wire: the ADC reads its lowest code.
    OpenWire,
    /// Short to supply: the ADC reads its highest code.
    ShortToRail,
    /// Extra offset (drift), MPa.
    Drift(f64),
}

/// Ratiometric 0–1 MPa gauge pressure transducer (0.5–4.5 V on a 5 V,
/// 12-bit ADC: codes 410–3686 span the range), like the MPX/ADP series.
#[derive(Clone, Debug)]
pub struct PressureSensorSim {
    /// Full-scale pressure, MPa.
    pub full_scale_mpa: f64,
    /// Code at 0 MPa.
    pub zero_code: f64,
    /// Code at full scale.
    pub span_code: f64,
    /// ADC maximum code.
    pub max_code: u16,
    /// RMS noise, MPa.
    pub noise_mpa: f64,
    /// Zero offset, MPa (what calibration must remove).
    pub offset_mpa: f64,
    /// Injected fault.
    pub fault: PressureFault,
    noise: Noise,
}

impl PressureSensorSim {
    /// The rig's transducer: 0–1 MPa, 0.8 kPa RMS noise, +3 kPa offset.
    pub fn new(seed: u64) -> PressureSensorSim {
        PressureSensorSim {
            full_scale_mpa: 1.0,
            zero_code: 409.5,
            span_code: 3276.0,
            max_code: 4095,
            noise_mpa: 0.0008,
            offset_mpa: 0.003,
            fault: PressureFault::None,
            noise: Noise::new(seed),
        }
    }

    /// Ideal calibration: MPa per code.
    pub fn mpa_per_code(&self) -> f64 {
        self.full_scale_mpa / self.span_code
    }

    /// Read the raw ADC code for true gauge `pressure_mpa`.
    pub fn read_code(&mut self, pressure_mpa: f64) -> u16 {
        let extra = match self.fault {
            PressureFault::StuckAt(c) => return c,
            PressureFault::OpenWire => return 0,
            PressureFault::ShortToRail => return self.max_code,
            PressureFault::Drift(d) => d,
            PressureFault::None => 0.0,
        };
        let p = pressure_mpa + self.offset_mpa + extra + self.noise_mpa * self.noise.gaussian();
        let code = self.zero_code + p / self.full_scale_mpa * self.span_code;
        code.round().clamp(0.0, f64::from(self.max_code)) as u16
    }

    /// Read in MPa with the ideal (offset-free) calibration, as a test rig's
    /// data logger would record it.
    pub fn read_mpa(&mut self, pressure_mpa: f64) -> f64 {
        let c = self.read_code(pressure_mpa);
        (f64::from(c) - self.zero_code) * self.mpa_per_code()
    }
}

/// Contraction sensor: a linear position sensor over the muscle's end
/// (resolution 30 µm on a 300 mm muscle = 1e-4 contraction), with noise.
#[derive(Clone, Debug)]
pub struct ContractionSensorSim {
    /// Quantization step, fraction of rest length.
    pub step: f64,
    /// RMS noise, fraction of rest length.
    pub noise: f64,
    /// Offset, fraction of rest length.
    pub offset: f64,
    rng: Noise,
}

impl ContractionSensorSim {
    /// 1e-4 steps, 3e-4 RMS noise, no offset.
    pub fn new(seed: u64) -> ContractionSensorSim {
        ContractionSensorSim {
            step: 1e-4,
            noise: 3e-4,
            offset: 0.0,
            rng: Noise::new(seed),
        }
    }

    /// Raw position count for a true `contraction`.
    pub fn read_count(&mut self, contraction: f64) -> i32 {
        let x = contraction + self.offset + self.noise * self.rng.gaussian();
        (x / self.step).round() as i32
    }

    /// Read as a fraction of rest length.
    pub fn read(&mut self, contraction: f64) -> f64 {
        f64::from(self.read_count(contraction)) * self.step
    }
}

/// Load cell in series with the muscle: 0.5 N resolution, 1.5 N RMS noise.
#[derive(Clone, Debug)]
pub struct LoadCellSim {
    /// Resolution, N.
    pub step_n: f64,
    /// RMS noise, N.
    pub noise_n: f64,
    rng: Noise,
}

impl LoadCellSim {
    /// The rig's load cell.
    pub fn new(seed: u64) -> LoadCellSim {
        LoadCellSim {
            step_n: 0.5,
            noise_n: 1.5,
            rng: Noise::new(seed),
        }
    }

    /// Read the load for a true `load_n`.
    pub fn read_n(&mut self, load_n: f64) -> f64 {
        let l = load_n + self.noise_n * self.rng.gaussian();
        (l / self.step_n).round() * self.step_n
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn gaussian_has_unit_variance_and_is_seeded() {
        let mut n = Noise::new(7);
        let xs: Vec<f64> = (0..20_000).map(|_| n.gaussian()).collect();
        let mean = xs.iter().sum::<f64>() / xs.len() as f64;
        let var = xs.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / xs.len() as f64;
        assert!(mean.abs() < 0.03, "{mean}");
        assert!((var - 1.0).abs() < 0.05, "{var}");
        let mut again = Noise::new(7);
        assert_eq!(again.gaussian(), xs[0]);
    }

    #[test]
    fn pressure_codes_quantize_offset_and_faults() {
        let mut s = PressureSensorSim::new(1);
        s.noise_mpa = 0.0;
        // 0.25 MPa + 3 kPa offset → 409.5 + 0.253·3276 = 1238.3.
        assert_eq!(s.read_code(0.25), 1238);
        assert!((s.read_mpa(0.25) - 0.253).abs() < s.mpa_per_code());
        s.fault = PressureFault::OpenWire;
        assert_eq!(s.read_code(0.25), 0);
        s.fault = PressureFault::ShortToRail;
        assert_eq!(s.read_code(0.25), 4095);
        s.fault = PressureFault::StuckAt(1000);
        assert_eq!(s.read_code(0.4), 1000);
        s.fault = PressureFault::Drift(0.05);
        assert!((s.read_mpa(0.25) - 0.303).abs() < s.mpa_per_code());
    }

    #[test]
    fn contraction_and_load_are_quantized() {
        let mut c = ContractionSensorSim::new(2);
        c.noise = 0.0;
        assert_eq!(c.read_count(0.12345), 1235);
        let mut l = LoadCellSim::new(3);
        l.noise_n = 0.0;
        assert_eq!(l.read_n(100.2), 100.0);
    }
}
