//! Fuzzing Lightport: one target per input a user or a network can hand it, the seeds each
//! starts from, structure-aware mutations, and a driver that runs them under a time bound.
//!
//! * [`targets`]: the targets. Each takes bytes and must return (Ok or a typed error) without
//!   panicking, hanging or allocating what the input does not back. The file targets go as far
//!   as a loaded input goes in the program (a scene that loads is also packed; a bundle that
//!   decodes is also rendered).
//! * [`http`]: the server target, over loopback against a running `lightport serve`.
//! * [`seeds`]: the starting inputs (the glTF validator corpus, the test scenes, tiny images
//!   of every format made here, and the committed regression inputs under `fuzz/regressions/`).
//! * [`mutate`]: byte-level and structure-aware mutations (glTF JSON fields, GLB chunks, bundle
//!   entries, HTTP request lines and headers), used by libFuzzer's custom mutator hook and by
//!   the [`driver`].
//! * [`regressions`]: the regression inputs made in code (bundles, which a format or kernel
//!   change makes stale), rewritten by `lightport-fuzz regressions`.
//! * [`driver`]: runs a target over its seeds and N mutations, each input under a time bound,
//!   every panic (also one a loader catches) a failure with the input saved. It is what CI's
//!   smoke test runs; the coverage-guided runs use libFuzzer (`fuzz_targets/`, `scripts/fuzz.sh`).
//!
//! See `docs/fuzzing.md`.

pub mod driver;
pub mod glb;
pub mod http;
pub mod mutate;
pub mod regressions;
pub mod rng;
pub mod seeds;
pub mod targets;

pub use targets::Target;

/// libFuzzer's custom mutator hook (`fuzz_mutator!` in `fuzz_targets/`): half of the time a
/// structure-aware mutation of the input (when it parses and fits), otherwise libFuzzer's own
/// byte-level mutation (`fallback`, i.e. `libfuzzer_sys::fuzzer_mutate`).
pub fn custom_mutate(
    target: Target,
    data: &mut [u8],
    size: usize,
    max_size: usize,
    seed: u32,
    fallback: fn(&mut [u8], usize, usize) -> usize,
) -> usize {
    let mut rng = rng::Rng::new(u64::from(seed));
    if rng.one_in(2) {
        if let Some(m) = mutate::structured(target, &data[..size], &mut rng) {
            if m.len() <= max_size && m.len() <= data.len() {
                data[..m.len()].copy_from_slice(&m);
                return m.len();
            }
        }
    }
    fallback(data, size, max_size)
}
