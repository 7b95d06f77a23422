//! `lightport-fuzz`: the seeds and the mutational driver from the command line.
//!
//! ```text
//! lightport-fuzz seeds TARGET DIR          write TARGET's seeds into DIR (libFuzzer's corpus)
//! lightport-fuzz max-len TARGET            the largest input the fuzzers make for TARGET
//! lightport-fuzz run TARGET [MUTATIONS] [SECONDS]
//!                                          the mutational driver (no instrumentation needed);
//!                                          prints executions, execs/s, panics, slowest, peak RSS
//! lightport-fuzz replay TARGET FROM TO     runs inputs FROM..TO of `run`'s sequence, naming each
//!                                          on stderr before it runs (which one killed a run?)
//! lightport-fuzz input TARGET K FILE       writes input K of `run`'s sequence to FILE
//! lightport-fuzz exec TARGET FILE...       runs a file target on each FILE (a saved finding),
//!                                          printing how long each took
//! lightport-fuzz regressions               rewrites the generated regression inputs (the bundles
//!                                          in fuzz/regressions/bundle/, after a format or kernel
//!                                          change; see lightport_fuzz::regressions)
//! ```
//! Targets: gltf obj texture sky bundle http. `scripts/fuzz.sh` runs the coverage-guided
//! libFuzzer binaries; see docs/fuzzing.md.

use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Duration;

use lightport_fuzz::driver::{self, Options};
use lightport_fuzz::{http, regressions, seeds, Target};

/// The mutation seed of `run` (and so of `replay` and `input`).
const RUN_SEED: u64 = 1;

fn main() -> ExitCode {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let target = args.get(1).and_then(|t| Target::from_name(t));
    match (args.first().map(String::as_str), target) {
        (Some("seeds"), Some(target)) if args.len() == 3 => write_seeds(target, &PathBuf::from(&args[2])),
        (Some("max-len"), Some(target)) => {
            println!("{}", target.max_len());
            ExitCode::SUCCESS
        }
        (Some("run"), Some(target)) => {
            let mutations = args.get(2).and_then(|n| n.parse().ok()).unwrap_or(100_000);
            let seconds = args.get(3).and_then(|n| n.parse().ok()).unwrap_or(3600.0);
            run(target, mutations, Duration::from_secs_f64(seconds))
        }
        (Some("replay"), Some(target)) if target != Target::Http && args.len() == 4 => {
            match (args[2].parse::<usize>(), args[3].parse::<usize>()) {
                (Ok(from), Ok(to)) => replay(target, from, to),
                _ => usage(),
            }
        }
        (Some("input"), Some(target)) if args.len() == 4 => match args[2].parse::<usize>() {
            Ok(k) => write_input(target, k, &PathBuf::from(&args[3])),
            Err(_) => usage(),
        },
        (Some("exec"), Some(target)) if target != Target::Http && args.len() >= 3 => exec(target, &args[2..]),
        (Some("regressions"), _) => match regressions::write_generated() {
            Ok(paths) => {
                for p in paths {
                    println!("wrote {}", p.display());
                }
                ExitCode::SUCCESS
            }
            Err(e) => {
                eprintln!("cannot write the regression inputs: {e}");
                ExitCode::FAILURE
            }
        },
        _ => usage(),
    }
}

fn usage() -> ExitCode {
    eprintln!(
        "usage: lightport-fuzz seeds TARGET DIR | max-len TARGET | run TARGET [MUTATIONS] [SECONDS] \
         | replay TARGET FROM TO | input TARGET K FILE | exec TARGET FILE... | regressions"
    );
    eprintln!("targets: {}", Target::ALL.map(Target::name).join(" "));
    ExitCode::from(2)
}

/// Runs inputs `from..to` of the driver's sequence, each named (and flushed) before it runs.
fn replay(target: Target, from: usize, to: usize) -> ExitCode {
    use std::io::Write;
    let seeds = seeds::seeds(target);
    for (k, input) in driver::inputs(target, &seeds, RUN_SEED).enumerate().take(to).skip(from) {
        let _ = writeln!(std::io::stderr(), "input {k}: {} bytes", input.len());
        target.run(&input);
    }
    eprintln!("inputs {from}..{to} ran");
    ExitCode::SUCCESS
}

fn exec(target: Target, files: &[String]) -> ExitCode {
    for file in files {
        let Ok(input) = std::fs::read(file) else {
            eprintln!("cannot read {file}");
            return ExitCode::FAILURE;
        };
        let t0 = std::time::Instant::now();
        target.run(&input);
        println!(
            "{file}: {} bytes, {:.1} ms, peak RSS {} MiB",
            input.len(),
            t0.elapsed().as_secs_f64() * 1e3,
            driver::peak_rss_kib() / 1024
        );
    }
    ExitCode::SUCCESS
}

fn write_input(target: Target, k: usize, file: &PathBuf) -> ExitCode {
    let seeds = seeds::seeds(target);
    let Some(input) = driver::inputs(target, &seeds, RUN_SEED).nth(k) else { return usage() };
    match std::fs::write(file, &input) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("cannot write {}: {e}", file.display());
            ExitCode::FAILURE
        }
    }
}

fn write_seeds(target: Target, dir: &PathBuf) -> ExitCode {
    if let Err(e) = std::fs::create_dir_all(dir) {
        eprintln!("cannot create {}: {e}", dir.display());
        return ExitCode::FAILURE;
    }
    let seeds = seeds::seeds(target);
    for (name, bytes) in &seeds {
        if let Err(e) = std::fs::write(dir.join(name), bytes) {
            eprintln!("cannot write {name}: {e}");
            return ExitCode::FAILURE;
        }
    }
    println!("{}: {} seeds in {}", target.name(), seeds.len(), dir.display());
    ExitCode::SUCCESS
}

fn run(target: Target, mutations: u64, max_time: Duration) -> ExitCode {
    let options = Options {
        mutations,
        max_time,
        time_bound: Duration::from_secs(10),
        failures: PathBuf::from("fuzz-failures"),
        seed: RUN_SEED,
        progress_every: 100_000,
    };
    let seeds = seeds::seeds(target);
    let report = if target == Target::Http {
        let mut server = match http::start_default_server(&http::default_binary()) {
            Ok(s) => s,
            Err(e) => {
                eprintln!("{e}");
                return ExitCode::FAILURE;
            }
        };
        let addr = server.addr;
        let mut report = driver::run(target, &seeds, &options, &mut |input| {
            if let Err(e) = http::exchange(addr, input, Duration::from_secs(5)) {
                panic!("{e}");
            }
        });
        if let Err(e) = server.check_alive() {
            report.panics.push((PathBuf::new(), e));
        }
        report
    } else {
        driver::run(target, &seeds, &options, &mut |input| target.run(input))
    };
    println!("| target | seeds | executions | execs/s | panics | slowest | peak RSS |");
    println!(
        "| {} | {} | {} | {:.0} | {} | {:.1} ms | {} MiB |",
        target.name(),
        seeds.len(),
        report.executions,
        report.execs_per_second(),
        report.panics.len(),
        report.slowest.as_secs_f64() * 1e3,
        report.peak_rss_kib / 1024
    );
    for (path, message) in &report.panics {
        eprintln!("PANIC {}: {message}", path.display());
    }
    if report.panics.is_empty() {
        ExitCode::SUCCESS
    } else {
        ExitCode::FAILURE
    }
}
