//! libFuzzer target: see `lightport_fuzz::targets` and docs/fuzzing.md (`scripts/fuzz.sh sky`).
#![no_main]

use lightport_fuzz::Target;

libfuzzer_sys::fuzz_target!(|data: &[u8]| Target::Sky.run(data));

libfuzzer_sys::fuzz_mutator!(|data: &mut [u8], size: usize, max_size: usize, seed: u32| {
    lightport_fuzz::custom_mutate(Target::Sky, data, size, max_size, seed, libfuzzer_sys::fuzzer_mutate)
});
