//! The project's main job: every scenario on the built-in default muscle,
//! with the firmware's controller (hysteresis-model feedforward + PI) and the
//! PI-only baseline; prints a summary table and writes CSV traces and SVG
//! plots.
//!
//! ```text
//! cargo run --release -p host-sim [-- --out DIR] [--seed N] [--kp MPA] [--ki MPA_PER_S] [--no-end-to-end]
//! ```
//! `--kp` and `--ki` override the controller's PI gains in every arm (for a
//! gain sweep; the defaults are `ControllerConfig::DEFAULT`'s).
//! `--no-end-to-end` leaves out the last part (each effect rig
//! characterised, fitted, diagnosed and tracked with the firmware booted
//! from the blobs: about 100 s of the run's 115 s on two cores).
//! Default output folder: `target/host-sim-report/`.

use host_sim::bench::{run, run_booted, BenchConfig, Mode, Run};
use host_sim::report;
use host_sim::scenarios::Scenario;
use std::path::PathBuf;

/// The scenarios of the main job (longer than the test versions).
fn scenarios(seed: u64) -> Vec<Scenario> {
    vec![
        Scenario::triangle(8, 4.0),
        Scenario::random_step_load(90.0, 4.0, seed),
        Scenario::cyclic_load_change(12, 4.0),
    ]
}

fn main() -> std::process::ExitCode {
    match run_main() {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e}");
            std::process::ExitCode::FAILURE
        }
    }
}

/// The value after `option`, parsed; the error names the option, the text
/// and what is expected.
fn value<T: std::str::FromStr>(
    args: &mut impl Iterator<Item = String>,
    option: &str,
    expected: &str,
) -> Result<T, String> {
    let text = args
        .next()
        .ok_or_else(|| format!("{option} needs {expected}"))?;
    text.parse()
        .map_err(|_| format!("{option} `{text}`: expected {expected}"))
}

/// The report's default folder: `host-sim-report` in the target directory
/// this binary was built into (`target/` of the workspace under cargo),
/// whatever the working directory.
fn default_out() -> PathBuf {
    std::env::current_exe()
        .ok()
        .and_then(|exe| Some(exe.parent()?.parent()?.join("host-sim-report")))
        .unwrap_or_else(|| PathBuf::from("target/host-sim-report"))
}

fn run_main() -> Result<(), Box<dyn std::error::Error>> {
    let mut out = default_out();
    let mut seed = 1u64;
    let mut kp_mpa: Option<f32> = None;
    let mut ki_mpa_per_s: Option<f32> = None;
    let mut end_to_end = true;
    let mut args = std::env::args().skip(1);
    while let Some(a) = args.next() {
        match a.as_str() {
            "--out" => out = PathBuf::from(args.next().ok_or("--out needs a folder")?),
            "--seed" => seed = value(&mut args, "--seed", "a whole number >= 0")?,
            "--kp" => kp_mpa = Some(value(&mut args, "--kp", "a gain in MPa")?),
            "--ki" => ki_mpa_per_s = Some(value(&mut args, "--ki", "a gain in MPa/s")?),
            "--no-end-to-end" => end_to_end = false,
            "-h" | "--help" => {
                println!("usage: host-sim [--out DIR] [--seed N] [--kp MPA] [--ki MPA_PER_S] [--no-end-to-end]");
                return Ok(());
            }
            other => return Err(format!("unknown argument {other:?} (try --help)").into()),
        }
    }
    let mut cfg = BenchConfig::default_with_seed(seed);
    if let Some(kp) = kp_mpa {
        cfg.controller.kp_mpa = kp;
    }
    if let Some(ki) = ki_mpa_per_s {
        cfg.controller.ki_mpa_per_s = ki;
    }
    // Every mode's controller as the bench builds it, before any work or
    // any folder: the bench's runs then cannot meet a refused one.
    for mode in host_sim::bench::Mode::ALL {
        host_sim::bench::controller_config(mode, &cfg)
            .validate()
            .map_err(|e| format!("controller settings refused ({}): {e}", mode.label()))?;
    }
    std::fs::create_dir_all(&out)?;

    println!("host-sim: firmware controller on the simulated McKibben rig (seed {seed})");
    println!("[1/7] characterisation run (isotonic, 100-600 N) ...");
    let samples = host_sim::characterisation_run(seed);
    host_sim::write_samples_csv(&out.join("characterisation.csv"), &samples)?;
    report::plot_characterisation(&out.join("characterisation_loops.svg"), &samples)?;
    println!("      {} samples", samples.len());

    // The Preisach model of the same record, booted from its blob.
    let preisach_blob = host_sim::preisach::identify_blob(&samples)?;
    println!(
        "      Preisach 16 x 16 at 6 loads identified on it: blob {} bytes",
        preisach_blob.len()
    );

    let mut results: Vec<(Scenario, Run, Run, Run, Run)> = Vec::new();
    let list = scenarios(seed);
    for (i, sc) in list.into_iter().enumerate() {
        println!("[{}/7] {} ({:.0} s) ...", i + 2, sc.title, sc.duration_s);
        let pi = run(&sc, Mode::PiOnly, &cfg);
        let ff = run(&sc, Mode::FeedforwardPi, &cfg);
        let mem = run(&sc, Mode::FeedforwardMemoryPi, &cfg);
        let pre = run_booted(&sc, &preisach_blob, Mode::PreisachFeedforwardPi, &cfg)?;
        for r in [&pi, &ff, &mem, &pre] {
            let suffix = match r.mode {
                Mode::PiOnly => "pi",
                Mode::FeedforwardPi => "ff_pi",
                Mode::FeedforwardMemoryPi => "ff_mem_pi",
                Mode::DiagnosedFeedforwardPi => "ff_diag_pi",
                Mode::PreisachFeedforwardPi => "ff_preisach_pi",
            };
            let name = format!("{}_{suffix}.csv", sc.name);
            // 100 Hz in the CSV (every 10th control period) keeps the files small.
            report::write_trace_csv(&out.join(name), &r.trace, 10)?;
        }
        let series = [
            report::Series {
                label: "PI only",
                run: &pi,
                colour: report::RUN_COLOURS[0],
            },
            report::Series {
                label: "model FF + PI",
                run: &ff,
                colour: report::RUN_COLOURS[1],
            },
            report::Series {
                label: "memory FF + PI",
                run: &mem,
                colour: report::RUN_COLOURS[2],
            },
        ];
        report::plot_scenario(
            &out.join(format!("{}.svg", sc.name)),
            sc.title,
            &series,
            cfg.warmup_s,
        )?;
        report::plot_loops(
            &out.join(format!("{}_loops.svg", sc.name)),
            &format!("{}: pressure-contraction, model FF + PI", sc.name),
            &ff,
            cfg.warmup_s,
        )?;
        results.push((sc, pi, ff, mem, pre));
    }

    println!();
    println!("| scenario | controller | RMS error | max error | load steps detected (samples) | max FF jump at switch (MPa) | max chamber change in 10 ms at switch (MPa) |");
    println!("|---|---|---|---|---|---|---|");
    for (sc, pi, ff, mem, pre) in &results {
        for r in [pi, ff, mem, pre] {
            let m = &r.metrics;
            let det: Vec<usize> = m
                .load_steps
                .iter()
                .filter_map(|l| l.detected_after_samples)
                .collect();
            let det = if m.load_steps.is_empty() {
                "no steps".to_string()
            } else {
                format!(
                    "{}/{}, {}-{}",
                    det.len(),
                    m.load_steps.len(),
                    det.iter().min().copied().unwrap_or(0),
                    det.iter().max().copied().unwrap_or(0)
                )
            };
            let ffj = m.max_feedforward_jump_mpa();
            let chj = m
                .switches
                .iter()
                .map(|s| s.chamber_jump_mpa)
                .fold(0.0, f64::max);
            println!(
                "| {} | {} | {:.4} | {:.4} | {} | {:.4} | {:.4} |",
                sc.name,
                r.mode.label(),
                m.rms_error,
                m.max_error,
                det,
                ffj,
                chj
            );
        }
        for r in [ff, mem, pre] {
            println!(
                "| {} | {} / PI | {:.0} % | {:.0} % | | | |",
                sc.name,
                r.mode.label(),
                100.0 * r.metrics.rms_error / pi.metrics.rms_error,
                100.0 * r.metrics.max_error / pi.metrics.max_error
            );
        }
    }
    println!();
    println!("Feedforward jump at a branch switch (MPa), plain model vs non-local memory:");
    println!();
    println!(
        "| scenario | switches | plain FF+PI: largest | FF(mem)+PI: largest | mitigated / plain |"
    );
    println!("|---|---|---|---|---|");
    for (sc, _, ff, mem, _) in &results {
        let (a, b) = (
            ff.metrics.max_feedforward_jump_mpa(),
            mem.metrics.max_feedforward_jump_mpa(),
        );
        println!(
            "| {} | {} / {} | {:.4} | {:.4} | {:.0} % |",
            sc.name,
            ff.metrics.switches.len(),
            mem.metrics.switches.len(),
            a,
            b,
            100.0 * b / a
        );
    }
    println!();
    println!("[5/7] fault injection (host_sim::faults, the runs tests/faults.rs asserts on) ...");
    let runs: Vec<_> = host_sim::faults::CASES
        .iter()
        .map(|&c| host_sim::faults::run_case(c, seed))
        .collect();
    let boot = host_sim::faults::boot(&host_sim::faults::corrupt_blob());
    println!();
    print!("{}", host_sim::faults::table(&runs, &boot));
    println!();
    // False trips of the safety monitor on normal runs: the three
    // scenarios on five seeds with the default configuration.
    let fw = firmware::ControllerConfig::DEFAULT;
    let survey = host_sim::harness::survey(fw, 1..=5);
    println!(
        "False-trip survey (3 scenarios x seeds 1-5, {:.0} s of control): {} trips; model check: largest distance outside the band {:.4} (bound {}), {} periods beyond the bound",
        survey.periods as f64 * f64::from(fw.dt_s),
        survey.trips,
        survey.max_model_excess,
        fw.safety.implausible_contraction,
        survey.periods_beyond_bound
    );
    println!();
    println!("[6/7] the worn muscle: an hour of the scenarios while stroke -15 %, friction +30 %, stiffness -10 % (seeds {seed}-{}) ...", seed + 2);
    let wear = host_sim::wear::Wear::HOUR;
    // One seed a thread: each is an hour of simulated muscle.
    let comparisons = std::thread::scope(|scope| {
        let runs: Vec<_> = (seed..=seed + 2)
            .map(|s| {
                let wear = &wear;
                scope.spawn(move || {
                    host_sim::wear::compare(
                        &BenchConfig::default_with_seed(s),
                        wear,
                        &scenarios(s),
                        firmware::controller::AdaptationConfig::DEFAULT,
                    )
                })
            })
            .collect();
        runs.into_iter()
            .map(|h| {
                h.join()
                    .map_err(|_| "a worn-muscle run panicked".to_string())?
            })
            .collect::<Result<Vec<_>, String>>()
    })?;
    println!();
    let worn = host_sim::wear::table(&comparisons);
    print!("{worn}");
    std::fs::write(out.join("worn.md"), &worn)?;
    std::fs::write(
        out.join("worn_trace.csv"),
        host_sim::wear::trace_csv(&comparisons),
    )?;
    report::plot_worn(&out.join("worn.svg"), &comparisons)?;
    println!();
    if end_to_end {
        println!(
            "[7/7] end to end: characterise each effect rig, pam-lab fit and diagnose, boot the firmware from each blob, track ..."
        );
        let rigs = host_sim::effect_rigs::effect_rigs();
        let scenario_list = scenarios(seed);
        let started = std::time::Instant::now();
        let outcomes = host_sim::end_to_end::run_all(&rigs, &scenario_list, &cfg);
        println!(
            "      {} rigs in {:.0} s",
            outcomes.len(),
            started.elapsed().as_secs_f64()
        );
        println!();
        let e2e = host_sim::end_to_end::table(&outcomes);
        print!("{e2e}");
        std::fs::write(out.join("end_to_end.md"), &e2e)?;
        report::plot_end_to_end(&out.join("end_to_end.svg"), &outcomes)?;
        for o in &outcomes {
            for r in &o.runs {
                let mut series = vec![
                    report::Series {
                        label: "PI only",
                        run: &r.pi,
                        colour: report::RUN_COLOURS[0],
                    },
                    report::Series {
                        label: "paper FF + PI",
                        run: &r.paper,
                        colour: report::RUN_COLOURS[1],
                    },
                ];
                if let Ok(d) = &r.diagnosed {
                    series.push(report::Series {
                        label: "diagnosed FF + PI",
                        run: d,
                        colour: report::RUN_COLOURS[2],
                    });
                }
                report::plot_scenario(
                    &out.join(format!("end_to_end_{}_{}.svg", o.rig.name, r.scenario)),
                    &format!("{} rig ({}): {}", o.rig.name, o.rig.effect, r.scenario),
                    &series,
                    cfg.warmup_s,
                )?;
            }
        }
    }
    println!();
    println!("Errors are the true contraction minus the reference (fraction of rest length; RMS and largest magnitude) after a {:.0} s warm-up, as the tracking-error panels plot them.", cfg.warmup_s);
    println!("Output written to {}/", out.display());
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::default_out;

    /// The report goes to the target directory the binary was built into,
    /// not to `./target` of whatever directory it is run from.
    #[test]
    fn the_default_report_folder_is_beside_the_build_not_the_working_directory() {
        let out = default_out();
        assert!(out.is_absolute(), "{}", out.display());
        assert!(out.ends_with("host-sim-report"), "{}", out.display());
        let exe = std::env::current_exe().unwrap();
        assert_eq!(out.parent(), exe.parent().and_then(|d| d.parent()));
    }
}
