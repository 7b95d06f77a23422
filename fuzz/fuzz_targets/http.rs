//! libFuzzer target: raw requests to a running `lightport serve` over loopback; see
//! `lightport_fuzz::http` and docs/fuzzing.md (`scripts/fuzz.sh http`). The server is the
//! `lightport` binary at `$LIGHTPORT_BIN` (default: target/debug/lightport).
#![no_main]

use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Mutex, OnceLock};
use std::time::Duration;

use lightport_fuzz::http::{self, Server};
use lightport_fuzz::Target;

/// Each exchange must end within this (the server's own request timeout is 2 s).
const BOUND: Duration = Duration::from_secs(5);

fn server() -> &'static Mutex<Server> {
    static SERVER: OnceLock<Mutex<Server>> = OnceLock::new();
    SERVER.get_or_init(|| {
        let server = http::start_default_server(&http::default_binary()).unwrap_or_else(|e| panic!("{e}"));
        Mutex::new(server)
    })
}

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    static EXECUTIONS: AtomicU64 = AtomicU64::new(0);
    let mut server = server().lock().unwrap_or_else(|e| e.into_inner());
    if let Err(e) = http::exchange(server.addr, data, BOUND) {
        let alive = server.check_alive().err().unwrap_or_default();
        panic!("{e} {alive}");
    }
    if EXECUTIONS.fetch_add(1, Ordering::Relaxed) % 1000 == 0 {
        server.check_alive().unwrap_or_else(|e| panic!("{e}"));
    }
});

libfuzzer_sys::fuzz_mutator!(|data: &mut [u8], size: usize, max_size: usize, seed: u32| {
    lightport_fuzz::custom_mutate(Target::Http, data, size, max_size, seed, libfuzzer_sys::fuzzer_mutate)
});
