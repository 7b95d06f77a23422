//! `lightport-fuzz`: the seeds and the mutational driver from the command line.
//!
//! ```text
//! lightport-fuzz seeds TARGET DIR          write TARGET's seeds into DIR (libFuzzer's corpus)
//! lightport-fuzz max-len TARGET            the largest input the fuzzers make for TARGET
//! lightport-fuzz run TARGET [MUTATIONS] [SECONDS]
//!                                          the mutational driver (no instrumentation needed);
//!                                          prints executions, execs/s, panics, slowest, peak RSS
//! ```
//! Targets: gltf obj texture sky bundle http. `scripts/fuzz.sh` runs the coverage-guided
//! libFuzzer binaries; see docs/fuzzing.md.

use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Duration;

use lightport_fuzz::driver::{self, Options};
use lightport_fuzz::{http, seeds, Target};

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
        _ => {
            eprintln!("usage: lightport-fuzz seeds TARGET DIR | run TARGET [MUTATIONS] [SECONDS]");
            eprintln!("targets: {}", Target::ALL.map(Target::name).join(" "));
            ExitCode::from(2)
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
        seed: 1,
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
