//! The closed loop of the fault suite and of the false-trip survey: the
//! firmware's [`Controller`] on the rig through the mock HALs, one control
//! period at a time, with the faults the mocks cannot express — valves
//! stuck open or closed, a stalled control loop and the independent
//! watchdog that resets it, a panic in the control step.
//!
//! The watchdog and the panic path are models of the board image
//! (`firmware/src/main.rs`, `firmware/src/board.rs`): the host cannot run
//! the chip's IWDG or its panic handler. What they do, modelled here:
//!
//! * **Watchdog**: fed after every completed step; a stall of more than
//!   [`WATCHDOG_PERIODS`] periods resets the chip. During the reset and
//!   boot ([`BOOT_PERIODS`]) the valve pins are not driven: both valves
//!   de-energise (the pair is normally closed, so the muscle holds its air);
//!   then boot writes the safe state and, seeing the watchdog's reset flag,
//!   latches it ([`Controller::latch`] with [`Fault::Watchdog`]).
//! * **Panic / HardFault**: the handler writes the exhaust-safe duties to
//!   both channels before anything else (here: straight to the PWM mocks,
//!   as the board's handler writes the pins), then waits for the watchdog,
//!   which resets into the latched boot above.

use crate::hal_mocks::{
    rig_io, valve_opening, RigIo, RigPwm, SharedRig, SharedSensors, SimIo, ValveKind,
};
use crate::pneumatics::ValveOpening;
use crate::rig::Rig;
use firmware::controller::{Controller, ControllerConfig, Fault, Step};
use firmware::hal::Valve;
use firmware::sim_io::PWM_MAX_DUTY;
use pam_core::{Coeffs, Params};
use std::cell::RefCell;
use std::rc::Rc;

/// The board image's IWDG timeout in control periods (`wiring::WATCHDOG_MS`
/// at 1 kHz, nominal LSI).
pub const WATCHDOG_PERIODS: usize = firmware::wiring::WATCHDOG_MS as usize;
/// Periods from a watchdog reset to boot writing the safe state (clock
/// start-up and `board::init`; an estimate, the board was not measured).
pub const BOOT_PERIODS: usize = 5;

/// What the valve hardware does, whatever it is told.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ValveFaults {
    /// The inlet is open whatever its duty.
    pub inlet_stuck_open: bool,
    /// The exhaust is closed whatever its duty.
    pub exhaust_stuck_closed: bool,
}

/// Where the control loop is.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LoopState {
    /// Stepping every period.
    Running,
    /// Not stepping (an endless loop, a deadlock): valves at their last
    /// duties; the watchdog is not fed.
    Stalled,
    /// Reset by the watchdog; boot writes the safe state at `boot_at`.
    Resetting {
        /// Period at which boot runs.
        boot_at: usize,
    },
}

/// The closed loop.
pub struct Harness {
    /// The rig.
    pub rig: SharedRig,
    /// The firmware's controller (replaced at a watchdog boot).
    pub ctl: Controller,
    /// Its hardware.
    pub io: SimIo,
    /// The rig's sensors (injection and the last reads).
    pub sensors: SharedSensors,
    /// Inlet channel.
    pub inlet: RigPwm,
    /// Exhaust channel.
    pub exhaust: RigPwm,
    /// Valve hardware faults.
    pub valves: ValveFaults,
    /// The control loop's state.
    pub state: LoopState,
    /// Periods since the watchdog was last fed.
    pub since_feed: usize,
    /// Period of the last watchdog reset.
    pub watchdog_reset_at: Option<usize>,
    /// Periods run.
    pub k: usize,
    cfg: ControllerConfig,
    load_n: f32,
}

impl Harness {
    /// The reference rig at `load_n` with sensor noise from `seed`, the
    /// firmware's controller with `cfg` and `Params::DEFAULT`.
    ///
    /// # Panics
    /// If the firmware refuses the configuration (a bench set-up error).
    pub fn new(cfg: ControllerConfig, load_n: f64, seed: u64) -> Harness {
        let rig: SharedRig = Rc::new(RefCell::new(Rig::reference(load_n, seed)));
        let coeffs = Coeffs::new(Params::DEFAULT).expect("default parameters");
        let ctl = Controller::new(coeffs, cfg, load_n as f32).expect("controller config");
        let RigIo {
            io,
            sensors,
            inlet,
            exhaust,
        } = rig_io(&rig).expect("valve config");
        Harness {
            rig,
            ctl,
            io,
            sensors,
            inlet,
            exhaust,
            valves: ValveFaults::default(),
            state: LoopState::Running,
            since_feed: 0,
            watchdog_reset_at: None,
            k: 0,
            cfg,
            load_n: load_n as f32,
        }
    }

    /// The valves are in the configured safe state as commanded: inlet
    /// duty 0, exhaust duty full.
    pub fn valves_commanded_safe(&self) -> bool {
        self.inlet.duty.get() == 0 && self.exhaust.duty.get() == PWM_MAX_DUTY
    }

    /// The board's panic handler: the exhaust-safe duties straight to both
    /// channels, then nothing more runs until the watchdog resets the chip.
    pub fn panic_handler(&mut self) {
        self.inlet.duty.set(0);
        self.exhaust.duty.set(PWM_MAX_DUTY);
        self.state = LoopState::Stalled;
    }

    /// One control period with `reference` as the set-point, then the
    /// plant for one period. Returns the step, if the controller ran.
    pub fn period(&mut self, reference: f32) -> Option<Step> {
        let step = match self.state {
            LoopState::Running => {
                let s = self.ctl.step(&mut self.io, reference);
                // Fed only after a completed step.
                self.since_feed = 0;
                Some(s)
            }
            LoopState::Stalled => {
                self.since_feed += 1;
                if self.since_feed > WATCHDOG_PERIODS {
                    self.watchdog_reset_at = Some(self.k);
                    self.state = LoopState::Resetting {
                        boot_at: self.k + BOOT_PERIODS,
                    };
                    // Reset: pins undriven, both coils de-energised.
                    self.inlet.duty.set(0);
                    self.exhaust.duty.set(0);
                }
                None
            }
            LoopState::Resetting { boot_at } => {
                if self.k >= boot_at {
                    self.boot_after_watchdog();
                }
                None
            }
        };
        self.advance_plant();
        self.k += 1;
        step
    }

    /// Boot after a watchdog reset, as the board image does: valves safe,
    /// a new controller, latched with [`Fault::Watchdog`].
    fn boot_after_watchdog(&mut self) {
        let _ = self.io.valve.set_safe(self.cfg.safety.safe_state);
        let coeffs = Coeffs::new(Params::DEFAULT).expect("default parameters");
        let mut ctl = Controller::new(coeffs, self.cfg, self.load_n).expect("controller config");
        ctl.latch(Fault::Watchdog);
        self.ctl = ctl;
        self.since_feed = 0;
        self.state = LoopState::Running;
    }

    fn advance_plant(&mut self) {
        let mut opening = valve_opening(
            ValveKind::PAIR,
            self.inlet.fraction(),
            self.exhaust.fraction(),
        );
        if self.valves.inlet_stuck_open {
            opening.inlet = 1.0;
        }
        if self.valves.exhaust_stuck_closed {
            opening.exhaust = 0.0;
        }
        let dt = f64::from(self.cfg.dt_s);
        let mut r = self.rig.borrow_mut();
        r.opening = ValveOpening { ..opening };
        r.advance(dt);
    }
}

/// What the false-trip survey measured on normal runs.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Survey {
    /// Runs (scenario × seed).
    pub runs: usize,
    /// Control periods run.
    pub periods: usize,
    /// Trips (entries into the safe state) of any kind.
    pub trips: usize,
    /// The faults tripped, with scenario and seed.
    pub tripped: Vec<(&'static str, u64, Fault)>,
    /// Largest distance of the measured contraction outside the model's
    /// band over all periods.
    pub max_model_excess: f32,
    /// Periods with the distance beyond the configured bound.
    pub periods_beyond_bound: usize,
    /// Longest run of periods beyond the bound.
    pub longest_beyond_bound: usize,
}

/// The paper's three scenarios, as the main job runs them, on seeds
/// `seeds`, with `cfg`: every trip counted.
pub fn survey(cfg: ControllerConfig, seeds: std::ops::RangeInclusive<u64>) -> Survey {
    use crate::scenarios::Scenario;
    let mut out = Survey::default();
    for seed in seeds {
        let scenarios = [
            Scenario::triangle(8, 4.0),
            Scenario::random_step_load(90.0, 4.0, seed),
            Scenario::cyclic_load_change(12, 4.0),
        ];
        for sc in &scenarios {
            let mut h = Harness::new(cfg, sc.load_at(0.0), seed);
            let dt = f64::from(cfg.dt_s);
            let n = (sc.duration_s / dt).round() as usize;
            let mut run = 0;
            for k in 0..n {
                let t = k as f64 * dt;
                h.rig.borrow_mut().set_load_n(sc.load_at(t));
                let Some(s) = h.period(sc.reference_at(t) as f32) else {
                    continue;
                };
                if let Some(f) = s.new_fault {
                    out.trips += 1;
                    out.tripped.push((sc.name, seed, f));
                }
                out.max_model_excess = out.max_model_excess.max(s.model_excess);
                if s.model_excess > cfg.safety.implausible_contraction {
                    out.periods_beyond_bound += 1;
                    run += 1;
                    out.longest_beyond_bound = out.longest_beyond_bound.max(run);
                } else {
                    run = 0;
                }
            }
            out.runs += 1;
            out.periods += n;
        }
    }
    out
}
