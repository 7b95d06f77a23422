//! CI's smoke run of the HTTP fuzz target (`fuzz/src/http.rs`): its seed requests and a
//! thousand request-aware mutations of them, sent over loopback to the real `lightport serve`
//! (the Cornell box, a 2 s request timeout). Every exchange must end within 5 s with a status
//! below 500 or a closed connection, and the server must stay up without a panic. The long
//! runs are `scripts/fuzz.sh http` (docs/fuzzing.md).

use std::path::Path;
use std::time::Duration;

use lightport_fuzz::driver::{self, Options};
use lightport_fuzz::{http, seeds, Target};

#[test]
fn the_server_survives_mutated_requests() {
    let mut server = http::start_default_server(Path::new(env!("CARGO_BIN_EXE_lightport")))
        .unwrap_or_else(|e| panic!("lightport serve: {e}"));
    let seeds = seeds::seeds(Target::Http);
    let options = Options {
        mutations: 1000,
        max_time: Duration::from_secs(120),
        time_bound: Duration::from_secs(20),
        failures: std::env::temp_dir().join(format!("lightport-fuzz-http-{}", std::process::id())),
        seed: 0x5eed,
        progress_every: 0,
    };
    let addr = server.addr;
    let mut answers = std::collections::BTreeMap::new();
    let report = driver::run(Target::Http, &seeds, &options, &mut |input| match http::exchange(
        addr,
        input,
        Duration::from_secs(5),
    ) {
        Ok(answer) => *answers.entry(format!("{answer:?}")).or_insert(0u32) += 1,
        Err(e) => panic!("{e}"),
    });
    eprintln!(
        "http: {} exchanges, {:.0}/s, slowest {:.1} ms; answers {answers:?}",
        report.executions,
        report.execs_per_second(),
        report.slowest.as_secs_f64() * 1e3
    );
    let failures: Vec<String> =
        report.panics.iter().map(|(p, m)| format!("{m} (request saved at {})", p.display())).collect();
    assert!(failures.is_empty(), "{}", failures.join("\n"));
    server.check_alive().unwrap_or_else(|e| panic!("{e}"));
    assert!(answers.contains_key("Status(200)"), "the seeds' valid requests are answered: {answers:?}");
    assert!(answers.len() >= 3, "the mutations reach several outcomes: {answers:?}");
}
