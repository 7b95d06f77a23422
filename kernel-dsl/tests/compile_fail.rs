//! The kernel DSL's boundary: every construct outside the supported subset is refused by
//! `#[kernel]` with a message that says what to write instead, at the offending span
//! (`tests/ui/fail/*.rs` with their expected `.stderr`), and a module using the whole subset
//! compiles, runs and exposes its IR (`tests/ui/pass/`).
//!
//! Regenerate the expected output with `TRYBUILD=overwrite cargo test -p kernel-dsl --test compile_fail`
//! and read every changed `.stderr` before committing it.

#[test]
fn compile_fail() {
    // One `TestCases` so that all cases share a single trybuild project and build.
    let t = trybuild::TestCases::new();
    t.pass("tests/ui/pass/*.rs");
    t.compile_fail("tests/ui/fail/*.rs");
}
