//! The browser runtimes' own checks: a wrong word in the page's reply is reported as that
//! invocation, bad driver replies are errors (not panics), and a hung page gives up after the
//! deadline instead of hanging the test.

use std::time::{Duration, Instant};

use super::*;
use tracer::backend::harness::{BrowserOptions, BrowserRuntime, BrowserSession, Corruption, Runtime};

const BROWSERS: [Backend; 2] = [Backend::WebGl2, Backend::WebGpu];

/// The page flips one bit of one output word: exactly that invocation is out of tolerance on
/// that runtime, and every other runtime still matches.
#[test]
fn a_wrong_word_in_the_pages_reply_is_reported() {
    let mut eq = equivalence();
    let seeds: Vec<(u32,)> = (0..5000u32).map(|s| (s,)).collect();
    // random_float gives 2 words per invocation: word 2 * 321 + 1 is invocation 321's state.
    for (backend, word) in BROWSERS.into_iter().zip([2 * 321 + 1, 2 * 4321]) {
        eq.browser(backend).expect("a browser runtime").corrupt_next_run(Corruption::FlipWord(word));
    }
    let random = |_: &Scene, &(s,): &(u32,)| {
        let mut state = s;
        (rng::random_float(&mut state), state)
    };
    let outcome = eq.run("random_float", &seeds, random, Tolerance::EXACT).expect("runs");
    for (backend, wrong) in BROWSERS.into_iter().zip([321, 4321]) {
        let c = outcome.comparison(backend).expect("ran");
        assert_eq!(c.mismatched, vec![wrong], "{backend}: {outcome}");
    }
    for backend in [Backend::Gl, Backend::Wgpu] {
        assert!(outcome.comparison(backend).expect("ran").is_equivalent(), "{outcome}");
    }
    // The corruption was for one run only.
    assert!(eq.run("random_float", &seeds, random, Tolerance::EXACT).expect("runs").is_equivalent());
}

/// Replies with a wrong word count or that are not JSON are typed errors, and the session
/// goes on answering.
#[test]
fn bad_driver_replies_are_errors() {
    let mut eq = equivalence();
    let seeds: Vec<(u32,)> = (0..100u32).map(|s| (s,)).collect();
    for (corruption, expected) in [(Corruption::DropLastWord, "returned 99 words"), (Corruption::NotJson, "not JSON")] {
        for backend in BROWSERS {
            eq.browser(backend).expect("a browser runtime").corrupt_next_run(corruption);
            let e = eq.run("wang_hash", &seeds, |_, &(s,)| (rng::wang_hash(s),), Tolerance::EXACT).unwrap_err();
            assert!(e.to_string().contains(expected), "{corruption:?} on {backend}: {e}");
            assert!(e.to_string().contains(&backend.to_string()), "{e}");
        }
    }
    let outcome = eq.run("wang_hash", &seeds, |_, &(s,)| (rng::wang_hash(s),), Tolerance::EXACT).expect("runs");
    assert!(outcome.is_equivalent(), "{outcome}");
    // An error from the page itself (a function it does not know) is one too.
    let runtime = eq.browser(Backend::WebGpu).expect("a browser runtime");
    let e = runtime.run_words("no_such_function", 1, &[0]).unwrap_err();
    assert!(e.to_string().contains("no_such_function"), "{e}");
}

/// A page that never answers: the request gives up after the session's deadline, the driver
/// and its browser end, and later requests are errors at once. A session of its own (the
/// shared one must survive).
#[test]
fn a_hung_page_gives_up_after_the_deadline() {
    let deadline = Duration::from_secs(5);
    let options = BrowserOptions { deadline, ..BrowserOptions::default() };
    let session = std::sync::Arc::new(BrowserSession::start(&options).unwrap_or_else(|e| panic!("{e}")));
    let modules = [tracer::kernel::modules(), vec![hazards::kernel::kernel_ir()]].concat();
    let program = lightport_codegen::Program::link(&modules).expect("links");
    let mut runtime = BrowserRuntime::new(session, Backend::WebGl2, program, &modules).expect("a runtime");
    assert_eq!(runtime.run_words("wang_hash", 2, &[1, 2]).expect("runs").len(), 2);
    runtime.corrupt_next_run(Corruption::Hang);
    let started = Instant::now();
    let e = runtime.run_words("wang_hash", 2, &[1, 2]).unwrap_err();
    let waited = started.elapsed();
    assert!(e.to_string().contains("gave up"), "{e}");
    assert!(waited >= deadline && waited < deadline + Duration::from_secs(30), "waited {waited:?}");
    let started = Instant::now();
    let e = runtime.run_words("wang_hash", 2, &[1, 2]).unwrap_err();
    assert!(e.to_string().contains("session ended earlier"), "{e}");
    assert!(started.elapsed() < Duration::from_secs(1));
}
