//! CI's smoke run of every file fuzz target: its seeds (the corpora of `tests/data/`, the generated
//! inputs and the committed regression inputs in `fuzz/regressions/`) and a few thousand
//! structure-aware and byte-level mutations, each input under the driver's time bound. Seconds
//! per target; the long coverage-guided runs are `scripts/fuzz.sh` (docs/fuzzing.md).
//!
//! One test runs the targets one after another: the driver's panic hook counts panics on any
//! thread, so nothing else may run in this binary at the same time.

use std::time::Duration;

use lightport_fuzz::driver::{self, Options};
use lightport_fuzz::{seeds, Target};

/// Mutations per target (about a second each in the dev profile).
const MUTATIONS: u64 = 2000;

#[test]
fn every_file_target_survives_its_seeds_and_mutations() {
    let failures = std::env::temp_dir().join(format!("lightport-fuzz-smoke-{}", std::process::id()));
    let mut problems = Vec::new();
    for target in Target::FILES {
        let seeds = seeds::seeds(target);
        // The corpora must be there: a smoke run of generated seeds alone proves little.
        let minimum = match target {
            Target::Gltf => 300,
            Target::Texture => 10,
            Target::Obj | Target::Sky => 4,
            Target::Bundle | Target::Http => 3,
        };
        assert!(
            seeds.len() >= minimum,
            "{}: {} seeds, expected at least {minimum} (is tests/data there, or $LIGHTPORT_SHARED right? see docs/fuzzing.md)",
            target.name(),
            seeds.len()
        );
        if target == Target::Bundle {
            // The motion section (`tracer/src/bundle/motion.rs`) must be among what is mutated.
            let moving = |bytes: &[u8]| tracer::bundle::Bundle::decode(bytes).is_ok_and(|b| b.moving.is_some());
            assert!(seeds.iter().any(|(_, bytes)| moving(bytes)), "no bundle seed has a motion section");
        }
        let options = Options {
            mutations: MUTATIONS,
            max_time: Duration::from_secs(120),
            time_bound: Duration::from_secs(30),
            failures: failures.clone(),
            seed: 0x5eed,
            progress_every: 0,
        };
        let report = driver::run(target, &seeds, &options, &mut |input| target.run(input));
        eprintln!(
            "{:8} {:4} seeds, {:6} executions, {:7.0} execs/s, slowest {:6.1} ms, {} panics",
            target.name(),
            seeds.len(),
            report.executions,
            report.execs_per_second(),
            report.slowest.as_secs_f64() * 1e3,
            report.panics.len()
        );
        assert_eq!(report.executions, seeds.len() as u64 + MUTATIONS, "{}: every input ran", target.name());
        for (path, message) in report.panics {
            problems.push(format!("{}: {message} (input saved at {})", target.name(), path.display()));
        }
    }
    assert!(problems.is_empty(), "panics:\n{}", problems.join("\n"));
    let _ = std::fs::remove_dir_all(&failures);
}
