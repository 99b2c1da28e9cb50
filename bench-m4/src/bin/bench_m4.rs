//! The bench image: runs each measured call between two marker functions; the
//! `insn_count` QEMU plugin counts the instructions executed in between.
//! Names go out through semihosting in the same order as the plugin's regions.
//!
//! Every measured call goes through one `#[no_mangle] #[inline(never)]`
//! function `bench_<group>` (the `empty` group calls an empty one), so the
//! call overhead is subtracted with the markers' and the code reachable from
//! each `bench_<group>` is attributable (report.py sums it from the
//! disassembly). The image also prints `ram <model> <bytes>` (state and
//! coefficients that live in RAM) and `table <model> <bytes>` (constant
//! per-load tables in flash).
#![no_std]
#![no_main]

use core::hint::black_box;
use core::mem::size_of;
use core::sync::atomic::{AtomicU32, Ordering};

use bench_m4::identified::{
    FIT_MEMORY, GPI4, MEMORY, PAM_FIT_PARAMS, PAM_FIT_SHAPE, PAM_PARAMS, PI16, PREISACH16,
};
use bench_m4::{GeneralizedPi, GpiTable, PiTable, PrandtlIshlinskii, Preisach, PreisachTable};
use cortex_m_rt::entry;
use cortex_m_semihosting::{debug, hprintln};
use firmware::controller::{AdaptationConfig, Controller, ControllerConfig, Feedforward, Io, Step};
use firmware::hal::{PressureCalibration, ValvePair, ValvePairConfig};
use firmware::plant::SimBus;
use firmware::scenario::SimIo;
use firmware::sim_io::{SimContraction, SimLoad, SimPressure, SimPwm};
use pam_core::effects::{
    ConstraintShape, Creep, Effects, LoadDependentWidth, NonLocalMemory, PressureLag,
    RateDependence, ReversalStack, StrokeTable,
};
use pam_core::Simulator;
use pam_core::{Branch, Coeffs, LoadModel, Tracker, TrackerConfig};

static STARTS: AtomicU32 = AtomicU32::new(0);
static ENDS: AtomicU32 = AtomicU32::new(0);

/// Start of a measured region. Its body differs from the end marker's (another
/// static), so LTO cannot fold the two into one address.
#[no_mangle]
#[inline(never)]
pub extern "C" fn bench_marker_start() {
    STARTS.fetch_add(1, Ordering::Relaxed);
}

/// End of a measured region.
#[no_mangle]
#[inline(never)]
pub extern "C" fn bench_marker_end() {
    ENDS.fetch_add(3, Ordering::Relaxed);
}

#[inline(always)]
fn measure<R>(f: impl FnOnce() -> R) -> R {
    bench_marker_start();
    let r = f();
    bench_marker_end();
    r
}

/// Run `f` once per input between markers; announce the group first.
fn group<T: Copy, R>(name: &str, inputs: &[T], mut f: impl FnMut(T) -> R) {
    hprintln!("group {} {}", name, inputs.len());
    for &x in inputs {
        black_box(measure(|| f(black_box(x))));
    }
}

fn fail(why: &str) -> ! {
    hprintln!("{}", why);
    debug::exit(debug::EXIT_FAILURE);
    loop {
        cortex_m::asm::wfi();
    }
}

// ---- the measured functions: one symbol each ----

type Pi16 = PrandtlIshlinskii<16>;
type Pi16Table = PiTable<16, 6>;
type Gpi4 = GeneralizedPi<4>;
type Gpi4Table = GpiTable<4, 6>;
type Preisach16 = Preisach<16>;
type Preisach16Table = PreisachTable<16, 6>;

#[no_mangle]
#[inline(never)]
fn bench_empty(x: f32) -> f32 {
    x
}

#[no_mangle]
#[inline(never)]
fn bench_forward_contraction(m: &LoadModel, x: f32, br: Branch) -> f32 {
    m.pressure_mpa(x, br)
}

#[no_mangle]
#[inline(never)]
fn bench_forward_expansion(m: &LoadModel, x: f32, br: Branch) -> f32 {
    m.pressure_mpa(x, br)
}

#[no_mangle]
#[inline(never)]
fn bench_inverse_contraction(m: &LoadModel, p: f32, br: Branch) -> f32 {
    m.contraction(p, br)
}

#[no_mangle]
#[inline(never)]
fn bench_inverse_expansion(m: &LoadModel, p: f32, br: Branch) -> f32 {
    m.contraction(p, br)
}

#[no_mangle]
#[inline(never)]
fn bench_tracker_update(t: &mut Tracker, c: &Coeffs, drive: f32, load_n: f32) -> bool {
    t.update(c, drive, load_n).branch_switch.is_some()
}

/// The paper's model as a pressure-driven predictor: tracker + branch inverse.
#[no_mangle]
#[inline(never)]
fn bench_paper_model_step(t: &mut Tracker, c: &Coeffs, p: f32, load_n: f32) -> f32 {
    t.update(c, p, load_n);
    t.model().contraction(p, t.branch())
}

#[no_mangle]
#[inline(never)]
fn bench_simulator_step(s: &mut Simulator<16>, t_s: f32, p: f32, load_n: f32) -> f32 {
    s.step(t_s, p, load_n)
}

#[no_mangle]
#[inline(never)]
fn bench_nonlocal_memory_step(s: &mut Simulator<16>, t_s: f32, p: f32, load_n: f32) -> f32 {
    s.step(t_s, p, load_n)
}

#[no_mangle]
#[inline(never)]
fn bench_fit_model_step(s: &mut Simulator<16>, t_s: f32, p: f32, load_n: f32) -> f32 {
    s.step(t_s, p, load_n)
}

#[no_mangle]
#[inline(never)]
fn bench_fit_memory_step(s: &mut Simulator<16>, t_s: f32, p: f32, load_n: f32) -> f32 {
    s.step(t_s, p, load_n)
}

#[no_mangle]
#[inline(never)]
fn bench_pi16_step(m: &mut Pi16, t: &Pi16Table, p: f32, load_n: f32) -> f32 {
    m.step(t, p, load_n)
}

#[no_mangle]
#[inline(never)]
fn bench_gpi4_step(m: &mut Gpi4, t: &Gpi4Table, p: f32, load_n: f32) -> f32 {
    m.step(t, p, load_n)
}

#[no_mangle]
#[inline(never)]
fn bench_tracker_load_switch(t: &mut Tracker, c: &Coeffs, drive: f32, load_n: f32) -> bool {
    t.update(c, drive, load_n).load_switch.is_some()
}

#[no_mangle]
#[inline(never)]
fn bench_memory_wipe_out(s: &mut Simulator<16>, t_s: f32, p: f32, load_n: f32) -> f32 {
    s.step(t_s, p, load_n)
}

#[no_mangle]
#[inline(never)]
fn bench_memory_inverse(
    s: &mut ReversalStack<8>,
    mem: &NonLocalMemory,
    m: &LoadModel,
    x: f32,
    br: Branch,
) -> f32 {
    s.inverse_pressure_mpa(mem, m, x, br, 1.0)
}

/// The controller over the representative run ([`run_controller`]), one
/// symbol for every feedforward (chosen at run time in the configuration).
#[no_mangle]
#[inline(never)]
fn bench_controller_run(c: &mut Controller, io: &mut SimIo<'_>, x_ref: f32) -> Step {
    c.step(io, x_ref)
}

#[no_mangle]
#[inline(never)]
fn bench_preisach16_step(m: &mut Preisach16, t: &Preisach16Table, p: f32, load_n: f32) -> f32 {
    m.step(t, p, load_n)
}

/// A feedforward period of the Preisach model: the pressure that reaches
/// `x` from the present state, and the state moved there.
#[no_mangle]
#[inline(never)]
fn bench_preisach16_feedforward(m: &mut Preisach16, x: f32) -> f32 {
    let p = m.inverse_pressure_mpa(x);
    m.update_state(p);
    p
}

#[no_mangle]
#[inline(never)]
fn bench_controller_step(c: &mut Controller, io: &mut SimIo<'_>, x_ref: f32) -> f32 {
    c.step(io, x_ref).pressure_cmd_mpa
}

/// A controller run: the set-point's turning points (contraction) and the
/// load schedule (from period, load in N).
struct Run {
    turns: [f32; 9],
    loads: [(usize, f32); 3],
}

/// The representative controller run: reversals, nested minor loops and
/// their wipe-outs, two load switches.
const RUN: Run = Run {
    turns: [0.06, 0.14, 0.10, 0.13, 0.08, 0.15, 0.09, 0.12, 0.07],
    loads: [(0, 200.0), (600, 450.0), (1400, 300.0)],
};
/// A run whose turns close an inner loop while an outer one is remembered:
/// passing 0.11 on the way to 0.08 wipes out the loop 0.11–0.125 and
/// exposes the loop 0.13 → 0.10 mid-sweep (the representative run's load
/// switches clear the memory before such a wipe-out).
const NESTED_RUN: Run = Run {
    turns: [0.06, 0.14, 0.10, 0.13, 0.11, 0.125, 0.08, 0.15, 0.06],
    loads: [(0, 200.0), (1200, 450.0), (1700, 300.0)],
};
/// Set-point speed, contraction per period (0.2 per second at 1 kHz).
const RUN_SPEED: f32 = 2e-4;
/// Periods of the run (the set-point's path length over its speed).
const RUN_LEN: usize = 2050;
/// Step classes in the run.
const REVERSAL: u8 = 1;
const LOAD_SWITCH: u8 = 2;

/// The run's set-point at each period.
fn run_setpoints(run: &Run) -> [f32; RUN_LEN] {
    let mut out = [0.0f32; RUN_LEN];
    let mut x = run.turns[0];
    let mut next = 1;
    for v in out.iter_mut() {
        if let Some(&target) = run.turns.get(next) {
            let d = target - x;
            if d.abs() <= RUN_SPEED {
                x = target;
                next += 1;
            } else {
                x += RUN_SPEED * d.signum();
            }
        }
        *v = x;
    }
    out
}

fn run_load(run: &Run, k: usize) -> f32 {
    let mut load = run.loads[0].1;
    for &(from, l) in &run.loads {
        if k >= from {
            load = l;
        }
    }
    // ±0.2 N of load-cell noise (a frozen reading would be a stuck sensor).
    load + if k.is_multiple_of(2) { 0.2 } else { -0.2 }
}

/// One pass of the representative run on a fresh copy of `base`: a plant
/// that follows the model (pressure lags the command by a first-order lag
/// of 3 periods, contraction is the active model's at that pressure: the
/// paper model's on the tracker's branch, or for a controller running the
/// Preisach model `preisach`, that model's relays driven by the plant's
/// pressure and load). With `select`, the steps whose class (from a
/// previous pass) matches are measured; the classes of this pass are
/// written to `classes`.
fn run_controller(
    run: &Run,
    base: &Controller,
    preisach: Option<&Preisach16Table>,
    bus: &SimBus,
    io: &mut SimIo<'_>,
    select: Option<(&[u8; RUN_LEN], u8)>,
    classes: &mut [u8; RUN_LEN],
) {
    let mut c = base.clone();
    let cal = PressureCalibration::ADC12_0_1MPA;
    let refs = run_setpoints(run);
    let mut p = 0.15f32;
    let mut relays = base.preisach().map(|m| *m.model());
    // The plant's contraction at `p` under `load_n` (on `branch`, the
    // tracker's own when `None`, for the paper model).
    let mut contraction_at = |c: &Controller, p: f32, load_n: f32, branch: Option<Branch>| match (
        c.tracker(),
        relays.as_mut(),
        preisach,
    ) {
        (Some(t), _, _) => t.model().contraction(p, branch.unwrap_or(t.branch())),
        (None, Some(r), Some(table)) => r.step(table, p, load_n),
        _ => fail("a Preisach controller's bench run needs its table"),
    };
    let mut x = contraction_at(&c, p, run_load(run, 0), Some(Branch::Contraction));
    for (k, (&x_ref, class)) in refs.iter().zip(classes.iter_mut()).enumerate() {
        bus.pressure_counts.set(cal.to_counts(p));
        bus.contraction.set(x);
        bus.load_n.set(run_load(run, k));
        let measured = match select {
            Some((sel, mask)) => sel
                .get(k)
                .is_some_and(|&s| s & mask != 0 || mask == u8::MAX),
            None => false,
        };
        let step = if measured {
            measure(|| bench_controller_run(&mut c, black_box(&mut *io), black_box(x_ref)))
        } else {
            bench_controller_run(&mut c, &mut *io, x_ref)
        };
        if step.fault.is_some() {
            fail("controller faulted in the run");
        }
        // A reversal: the tracker switched branch (the paper model), or
        // the set-point turned (the Preisach model, which has no branch).
        let turned = k > 0 && k + 1 < RUN_LEN && {
            let (before, after) = (refs[k] - refs[k - 1], refs[k + 1] - refs[k]);
            before * after < 0.0
        };
        let reversal = match c.preisach() {
            None => step.tracker.branch_switch.is_some(),
            Some(_) => turned,
        };
        *class = u8::from(reversal) * REVERSAL
            + u8::from(
                step.tracker.load_switch.is_some()
                    || c.tracker().is_some_and(|t| !t.inverse_ready())
                    || c.preisach().is_some_and(|m| m.model().switching()),
            ) * LOAD_SWITCH;
        p += (step.pressure_cmd_mpa - p) / 3.0;
        x = contraction_at(&c, p, run_load(run, k + 1), None);
    }
}

/// The representative run of `base` once unmeasured (its periods'
/// classes), then measured: every period (`ctl_run_NAME`), the reversal
/// periods and the load-switch periods.
fn controller_groups(
    name: &str,
    base: &Controller,
    preisach: Option<&Preisach16Table>,
    bus: &SimBus,
    io: &mut SimIo<'_>,
) {
    let mut classes = [0u8; RUN_LEN];
    run_controller(&RUN, base, preisach, bus, io, None, &mut classes);
    let sel = classes;
    for (what, mask) in [
        ("run", u8::MAX),
        ("reversal", REVERSAL),
        ("load_switch", LOAD_SWITCH),
    ] {
        let n = sel
            .iter()
            .filter(|&&c| mask == u8::MAX || c & mask != 0)
            .count();
        hprintln!("group ctl_{}_{} {}", what, name, n);
        run_controller(
            &RUN,
            base,
            preisach,
            bus,
            io,
            Some((&sel, mask)),
            &mut classes,
        );
    }
    // Every period of the nested run.
    hprintln!("group ctl_nested_{} {}", name, RUN_LEN);
    let all = [0u8; RUN_LEN];
    run_controller(
        &NESTED_RUN,
        base,
        preisach,
        bus,
        io,
        Some((&all, u8::MAX)),
        &mut classes,
    );
}

#[entry]
fn main() -> ! {
    let Ok(coeffs) = Coeffs::new(PAM_PARAMS) else {
        fail("PAM_PARAMS refused");
    };
    let model = coeffs.load_model_clamped(200.0);
    // The hardware square root must agree with the host's: at u = 0.6 of the
    // ellipse's half-width the offset is 0.8·be.
    let half = 0.5 * (model.max_contraction() - model.root_contraction());
    let x = model.root_contraction() + half * 1.6;
    let want = 0.8 * model.ellipse_height_mpa();
    if (model.offset_mpa(x) - want).abs() > 1e-6 {
        fail("sqrt self-check failed");
    }
    let stroke = [
        0.0f32, 0.02, 0.04, 0.06, 0.08, 0.10, 0.12, 0.14, 0.16, 0.18, 0.20, 0.22, 0.24, 0.01, 0.11,
        0.21,
    ];
    let pressures: [f32; 16] = core::array::from_fn(|i| 0.5 * (i as f32 + 0.5) / 16.0);
    // A triangle of pressure samples with one reversal, at a steady load.
    let drive: [f32; 16] = core::array::from_fn(|i| {
        if i < 8 {
            0.1 + 0.01 * i as f32
        } else {
            0.17 - 0.01 * (i - 8) as f32
        }
    });

    group("empty", &[0.0f32; 8], bench_empty);
    group("forward_contraction", &stroke, |x| {
        bench_forward_contraction(&model, x, black_box(Branch::Contraction))
    });
    group("forward_expansion", &stroke, |x| {
        bench_forward_expansion(&model, x, black_box(Branch::Expansion))
    });
    group("inverse_contraction", &pressures, |p| {
        bench_inverse_contraction(&model, p, black_box(Branch::Contraction))
    });
    group("inverse_expansion", &pressures, |p| {
        bench_inverse_expansion(&model, p, black_box(Branch::Expansion))
    });

    let new_tracker = || {
        Tracker::new(
            &coeffs,
            TrackerConfig::DEFAULT_PRESSURE,
            200.0,
            Branch::Contraction,
        )
        .unwrap_or_else(|_| fail("tracker refused"))
    };
    let mut tracker = new_tracker();
    group("tracker_update", &drive, |d| {
        bench_tracker_update(&mut tracker, &coeffs, d, 200.0)
    });
    let mut tracker = new_tracker();
    group("paper_model_step", &drive, |p| {
        bench_paper_model_step(&mut tracker, &coeffs, p, 200.0)
    });

    // Simulator with and without the non-local memory, inside a minor loop:
    // 0 → 0.3 → 0.15 → 0.16 MPa unmeasured (two reversals remembered), then
    // 16 measured samples rising towards 0.3 (the minor loop's curve).
    let warm = |s: &mut Simulator<16>| -> f32 {
        let mut t = 0.0f32;
        for k in 0..=300 {
            t += 0.02;
            s.step(t, 0.001 * k as f32, 200.0);
        }
        for k in 1..=150 {
            t += 0.02;
            s.step(t, 0.3 - 0.001 * k as f32, 200.0);
        }
        for k in 1..=10 {
            t += 0.02;
            s.step(t, 0.15 + 0.001 * k as f32, 200.0);
        }
        t
    };
    let minor: [(f32, f32); 16] =
        core::array::from_fn(|k| (0.02 * (k + 1) as f32, 0.162 + 0.008 * k as f32));
    let new_sim = |effects| {
        Simulator::<16>::new(coeffs, effects, TrackerConfig::DEFAULT_PRESSURE, 200.0)
            .unwrap_or_else(|_| fail("simulator refused"))
    };
    let mut sim = new_sim(Effects::NONE);
    let t0 = warm(&mut sim);
    group("simulator_step", &minor, |(dt, p)| {
        bench_simulator_step(&mut sim, t0 + dt, p, 200.0)
    });
    let memory = Effects {
        memory: Some(MEMORY),
        ..Effects::NONE
    };
    let mut sim_mem = new_sim(memory);
    let t0 = warm(&mut sim_mem);
    if sim_mem.reversals().len() != 2 {
        fail("memory warm-up did not leave two reversals");
    }
    group("nonlocal_memory_step", &minor, |(dt, p)| {
        bench_nonlocal_memory_step(&mut sim_mem, t0 + dt, p, 200.0)
    });

    // The model `pam-lab fit` writes (its parameters with its static
    // shape, the stroke table on this rig), alone and with the memory, in
    // the same minor loop.
    let Ok(fit_coeffs) = Coeffs::new(PAM_FIT_PARAMS) else {
        fail("PAM_FIT_PARAMS refused");
    };
    let new_fit_sim = |effects| {
        Simulator::<16>::new(fit_coeffs, effects, TrackerConfig::DEFAULT_PRESSURE, 200.0)
            .unwrap_or_else(|_| fail("simulator refused fit's model"))
    };
    let mut sim_fit = new_fit_sim(Effects {
        shape: PAM_FIT_SHAPE,
        ..Effects::NONE
    });
    let t0 = warm(&mut sim_fit);
    group("fit_model_step", &minor, |(dt, p)| {
        bench_fit_model_step(&mut sim_fit, t0 + dt, p, 200.0)
    });
    let mut sim_fit_mem = new_fit_sim(Effects {
        shape: PAM_FIT_SHAPE,
        memory: Some(FIT_MEMORY),
        ..Effects::NONE
    });
    let t0 = warm(&mut sim_fit_mem);
    if sim_fit_mem.reversals().len() != 2 {
        fail("fit's memory warm-up did not leave two reversals");
    }
    group("fit_memory_step", &minor, |(dt, p)| {
        bench_fit_memory_step(&mut sim_fit_mem, t0 + dt, p, 200.0)
    });

    // A wipe-out: from the same minor loop (turning points 0.3 and
    // 0.15 MPa), one sample past 0.3 MPa closes it.
    let mut warm_mem = new_sim(memory);
    let t0 = warm(&mut warm_mem);
    let past: [f32; 8] = core::array::from_fn(|i| 0.301 + 0.004 * i as f32);
    hprintln!("group memory_wipe_out {}", past.len());
    for &p in &past {
        let mut s = warm_mem.clone();
        black_box(measure(|| {
            bench_memory_wipe_out(&mut s, black_box(t0 + 0.02), black_box(p), black_box(200.0))
        }));
        if !s.reversals().is_empty() {
            fail("no wipe-out");
        }
    }
    // The memory's inverse (the memory feedforward's per-step work) on
    // that minor loop.
    let mut stack = ReversalStack::<8>::default();
    for &r in warm_mem.reversals() {
        stack.push(r);
    }
    let mem_params = MEMORY;
    let xs: [f32; 16] = core::array::from_fn(|i| 0.03 + 0.012 * i as f32);
    // First call on a loop (its ends: two branch inverses), then cached.
    hprintln!("group memory_inverse_new_loop {}", xs.len());
    for &x in &xs {
        let mut st = stack;
        black_box(measure(|| {
            bench_memory_inverse(
                &mut st,
                &mem_params,
                &model,
                black_box(x),
                black_box(Branch::Contraction),
            )
        }));
    }
    bench_memory_inverse(&mut stack, &mem_params, &model, 0.1, Branch::Contraction);
    group("memory_inverse", &xs, |x| {
        bench_memory_inverse(
            &mut stack,
            &mem_params,
            &model,
            x,
            black_box(Branch::Contraction),
        )
    });

    // A load switch of the tracker with the firmware's build budget: every
    // update from the load step until the new model's tables are complete.
    let mut base = new_tracker();
    base.set_build_budget(firmware::controller::TABLE_BUILD_UNITS_PER_STEP);
    for _ in 0..10 {
        base.update(&coeffs, 0.1, 200.0);
    }
    let mut dry = base.clone();
    let mut n = 0;
    loop {
        n += 1;
        dry.update(&coeffs, 0.1, 450.0);
        if dry.load_n() == 450.0 && dry.inverse_ready() {
            break;
        }
        if n > 1000 {
            fail("the load switch never completed");
        }
    }
    hprintln!("group tracker_load_switch {}", n);
    let mut t = base.clone();
    for _ in 0..n {
        black_box(measure(|| {
            bench_tracker_load_switch(&mut t, &coeffs, black_box(0.1), black_box(450.0))
        }));
    }

    // Baselines on the same triangle as the tracker, at a steady load.
    let pi_table = black_box(&PI16);
    let mut pi = Pi16::new(pi_table, 200.0, 0.0);
    group("pi16_step", &drive, |p| {
        bench_pi16_step(&mut pi, pi_table, p, 200.0)
    });
    let gpi_table = black_box(&GPI4);
    let mut gpi = Gpi4::new(gpi_table, 200.0, 0.0);
    group("gpi4_step", &drive, |p| {
        bench_gpi4_step(&mut gpi, gpi_table, p, 200.0)
    });
    let pr_table = black_box(&PREISACH16);
    let mut pr = Preisach16::new(pr_table, 200.0, 0.0);
    group("preisach16_step", &drive, |p| {
        bench_preisach16_step(&mut pr, pr_table, p, 200.0)
    });
    // Two load switches: the new load's coefficients interpolated a few
    // rows a step (pam-core's `LOAD_SWITCH_ROWS_PER_UPDATE`), every step of
    // each switch measured, the one that completes it too.
    let switch_loads: [f32; 16] = core::array::from_fn(|i| if i < 8 { 450.0 } else { 150.0 });
    group("preisach16_load_switch", &switch_loads, |l| {
        bench_preisach16_step(&mut pr, pr_table, 0.15, l)
    });
    // Its inverse as a feedforward runs it: the contraction the forward
    // model gives on the same triangle, reached period by period; then the
    // slowest path, a contraction beyond reach in each direction (every
    // threshold walked, every relay of a falling path summed).
    let mut ff = Preisach16::new(pr_table, 200.0, 0.0);
    let mut fwd = ff;
    let targets: [f32; 16] = core::array::from_fn(|i| {
        fwd.update_state(drive[i]);
        fwd.output()
    });
    group("preisach16_feedforward", &targets, |x| {
        bench_preisach16_feedforward(&mut ff, x)
    });
    let far: [f32; 8] = core::array::from_fn(|i| if i % 2 == 0 { 1.0 } else { -1.0 });
    group("preisach16_feedforward_far", &far, |x| {
        bench_preisach16_feedforward(&mut ff, x)
    });

    // The firmware's controller with the in-memory simulated sensors and
    // PWM: set-point ramping up then down, sensors a little behind. Every
    // controller here runs its model check from the first period (no pause
    // at the start, `implausible_start_s`): the check is part of the
    // period measured.
    let mut measured = ControllerConfig::DEFAULT;
    measured.safety.implausible_start_s = 0.0;
    let Ok(mut ctl) = Controller::new(coeffs, measured, 200.0) else {
        fail("controller refused");
    };
    let bus = SimBus::new();
    let cal = PressureCalibration::ADC12_0_1MPA;
    let Ok(valve) = ValvePair::new(
        SimPwm::new(&bus.inlet_duty),
        SimPwm::new(&bus.exhaust_duty),
        ValvePairConfig::DEFAULT,
    ) else {
        fail("valve refused");
    };
    let mut io = Io {
        pressure: SimPressure {
            source: &bus,
            calibration: cal,
        },
        contraction: SimContraction(&bus),
        load: SimLoad(&bus),
        valve,
    };
    let refs: [f32; 16] = core::array::from_fn(|i| {
        if i < 8 {
            0.08 + 0.004 * i as f32
        } else {
            0.108 - 0.004 * (i - 8) as f32
        }
    });
    hprintln!("group controller_step {}", refs.len());
    for (i, &x_ref) in refs.iter().enumerate() {
        bus.pressure_counts
            .set(cal.to_counts(0.15 + 0.002 * i as f32));
        bus.contraction.set(x_ref - 0.003);
        bus.load_n.set(200.0 + 0.5 * i as f32);
        black_box(measure(|| {
            bench_controller_step(&mut ctl, black_box(&mut io), black_box(x_ref))
        }));
        if ctl.fault().is_some() {
            fail("controller faulted");
        }
    }

    // The representative run with each feedforward (chosen at run time):
    // every step, the reversal steps, and the load-switch steps (the switch
    // and the table build after it). The effects feedforwards invert a model
    // with one effect each, then all of them (what a blob from `diagnose`
    // gives, `Feedforward::HysteresisEffects`); the rate law's exponent 0.7
    // takes the `powf` path, the slowest the law has.
    let memory_only = Effects {
        memory: Some(MEMORY),
        ..Effects::NONE
    };
    let rate = Effects {
        rate: Some(RateDependence {
            exponent: 0.7,
            ..RateDependence::linear(1.0, 2.0)
        }),
        ..Effects::NONE
    };
    let creep = Effects {
        creep: Some(Creep {
            gain: 0.3,
            time_constant_s: 1.0,
        }),
        ..Effects::NONE
    };
    let width = Effects {
        width: Some(LoadDependentWidth {
            scale_at_min_load: 1.0,
            scale_per_step: 0.2,
        }),
        ..Effects::NONE
    };
    let shape = Effects {
        shape: Some(ConstraintShape {
            bulge: 0.2,
            tilt: 0.1,
            bulge_per_step: 0.02,
            tilt_per_step: 0.0,
            ..pam_core::effects::ConstraintShape::NEUTRAL
        }),
        ..Effects::NONE
    };
    // What `diagnose` names on two of host-sim's rigs (the end-to-end
    // run): the static shape with its stroke ends moving with load, then
    // the memory.
    let shape_memory = Effects {
        memory: memory_only.memory,
        shape: Some(ConstraintShape {
            bulge: 0.2,
            tilt: 0.1,
            bulge_per_step: 0.02,
            tilt_per_step: 0.0,
            root_shift: 0.05,
            end_shift: -0.05,
            root_shift_per_step: -0.01,
            end_shift_per_step: 0.01,
            root_shift_per_step_sq: 0.001,
            end_shift_per_step_sq: -0.001,
            ..ConstraintShape::NEUTRAL
        }),
        ..Effects::NONE
    };
    // What `diagnose` names on the memory + rate plants (pam-lab's
    // DIAGNOSE.md): the memory and the rate law (here linear).
    let memory_rate = Effects {
        memory: memory_only.memory,
        rate: Some(RateDependence::linear(1.0, 2.0)),
        ..Effects::NONE
    };
    // What `diagnose` names on host-sim's rate rig (the end-to-end run):
    // the static shape, then the rate law at an exponent diagnose fits
    // (0.5, 0.75 or 1: square roots, never `powf`), here 0.75.
    let shape_rate = Effects {
        rate: Some(RateDependence {
            exponent: 0.75,
            ..RateDependence::linear(1.0, 2.0)
        }),
        shape: shape_memory.shape,
        ..Effects::NONE
    };
    // What `pam-lab fit` writes for a muscle outside the paper's cubic
    // (host-sim's rigs, the Festo set): the stroke table alone, here the
    // one it writes for host-sim's coulomb rig (seed 1); then with the
    // pressure lag `diagnose` adds where a sensor sits ahead of the muscle
    // (23 ms, blob version 4).
    let table = Effects {
        shape: Some(ConstraintShape {
            table: StrokeTable {
                knots: [
                    [
                        0.04373, 0.2104, 0.3988, 0.4705, 0.5153, 0.5314, 0.5518, 0.6048, 0.6407,
                        0.7922, 0.9484,
                    ],
                    [
                        0.05649, 0.08282, 0.3285, 0.43, 0.5048, 0.545, 0.582, 0.6256, 0.7053,
                        0.7806, 0.9442,
                    ],
                    [
                        0.0711, 0.08282, 0.1863, 0.4206, 0.4372, 0.5606, 0.6012, 0.6517, 0.7364,
                        0.7619, 0.9463,
                    ],
                    [
                        0.08898, 0.1046, 0.1332, 0.3295, 0.4567, 0.5693, 0.6241, 0.6864, 0.6961,
                        0.85, 0.9315,
                    ],
                    [
                        0.1061, 0.1245, 0.1516, 0.2238, 0.4859, 0.5657, 0.6532, 0.716, 0.7865,
                        0.872, 0.9249,
                    ],
                    [
                        0.1251, 0.1496, 0.1796, 0.2148, 0.4402, 0.5839, 0.5939, 0.7781, 0.816,
                        0.8867, 0.9198,
                    ],
                ],
            },
            ..ConstraintShape::NEUTRAL
        }),
        ..Effects::NONE
    };
    let table_lag = Effects {
        pressure_lag: Some(PressureLag {
            time_constant_s: 0.023,
        }),
        ..table
    };
    // What `diagnose` writes for host-sim's coulomb and memory rigs (the
    // end-to-end run): fit's static model, its stroke table, with the
    // memory.
    let table_memory = Effects {
        memory: memory_only.memory,
        ..table
    };
    // The costliest model `diagnose` writes with its default two effects:
    // fit's static model (the stroke table) with the costliest pair, the
    // memory and a rate law (whose factor moves the memory's loop).
    let table_memory_rate = Effects {
        memory: memory_only.memory,
        rate: memory_rate.rate,
        ..table
    };
    // Every effect pam-core has: the five of the rows above and a 20 ms
    // pressure lag.
    let all = Effects {
        memory: memory_only.memory,
        rate: rate.rate,
        creep: creep.creep,
        width: width.width,
        shape: shape.shape,
        pressure_lag: Some(PressureLag {
            time_constant_s: 0.02,
        }),
        // A pressure delay adds no work a period: its lead joins the lag's
        // time constant when the inverse is made.
        pressure_delay: None,
    };
    // The online adaptation with the paper's model, updating on every
    // period it may (no settling time, no transient freeze): its slowest
    // path, the branch inverse and the estimate, on every measured step.
    let adapting = AdaptationConfig {
        settle_periods: 0,
        max_pressure_rate_mpa_per_s: 1.0e6,
        ..AdaptationConfig::DEFAULT
    };
    let feedforwards = [
        ("off", Feedforward::Off, None),
        ("constraint", Feedforward::Constraint, None),
        ("hysteresis", Feedforward::Hysteresis, None),
        ("adapted", Feedforward::Hysteresis, Some(adapting)),
        ("memory", Feedforward::HysteresisMemory(MEMORY), None),
        ("rate", Feedforward::HysteresisEffects(rate), None),
        ("creep", Feedforward::HysteresisEffects(creep), None),
        ("width", Feedforward::HysteresisEffects(width), None),
        ("shape", Feedforward::HysteresisEffects(shape), None),
        (
            "shape_memory",
            Feedforward::HysteresisEffects(shape_memory),
            None,
        ),
        (
            "memory_rate",
            Feedforward::HysteresisEffects(memory_rate),
            None,
        ),
        (
            "shape_rate",
            Feedforward::HysteresisEffects(shape_rate),
            None,
        ),
        ("table", Feedforward::HysteresisEffects(table), None),
        ("table_lag", Feedforward::HysteresisEffects(table_lag), None),
        (
            "table_memory",
            Feedforward::HysteresisEffects(table_memory),
            None,
        ),
        (
            "table_memory_rate",
            Feedforward::HysteresisEffects(table_memory_rate),
            None,
        ),
        ("effects", Feedforward::HysteresisEffects(all), None),
    ];
    for (name, ff, adaptation) in feedforwards {
        let mut cfg = measured;
        cfg.feedforward = black_box(ff);
        cfg.adaptation = black_box(adaptation);
        let Ok(base) = Controller::new(coeffs, cfg, 200.0) else {
            fail("controller refused");
        };
        controller_groups(name, &base, None, &bus, &mut io);
    }
    // The Preisach model pam flashes where it is the more accurate
    // (`pam-lab compare`): bench-m4's identified table, its feedforward.
    let mut cfg = measured;
    cfg.feedforward = black_box(Feedforward::Preisach);
    let Ok(base) = Controller::new_preisach(PREISACH16, cfg, 200.0) else {
        fail("Preisach controller refused");
    };
    controller_groups("preisach", &base, Some(pr_table), &bus, &mut io);

    hprintln!(
        "ram paper_model_step {}",
        size_of::<Coeffs>() + size_of::<Tracker>()
    );
    hprintln!("ram nonlocal_memory_step {}", size_of::<Simulator<16>>());
    hprintln!("ram fit_model_step {}", size_of::<Simulator<16>>());
    hprintln!("ram fit_memory_step {}", size_of::<Simulator<16>>());
    hprintln!("ram pi16_step {}", size_of::<Pi16>());
    hprintln!("table pi16_step {}", size_of::<Pi16Table>());
    hprintln!("ram gpi4_step {}", size_of::<Gpi4>());
    hprintln!("table gpi4_step {}", size_of::<Gpi4Table>());
    hprintln!("ram preisach16_step {}", size_of::<Preisach16>());
    hprintln!("table preisach16_step {}", size_of::<Preisach16Table>());
    hprintln!("ram controller_step {}", size_of::<Controller>());

    hprintln!("done");
    debug::exit(debug::EXIT_SUCCESS);
    loop {
        cortex_m::asm::wfi();
    }
}

#[panic_handler]
fn panic(_: &core::panic::PanicInfo) -> ! {
    debug::exit(debug::EXIT_FAILURE);
    loop {
        cortex_m::asm::wfi();
    }
}
