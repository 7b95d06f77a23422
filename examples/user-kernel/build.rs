//! Generates and validates this crate's shaders at every `cargo build` (into `OUT_DIR`, where
//! `src/main.rs` embeds them), so they can never be stale against the kernels.

use lightport_codegen::build::{BuildError, Shaders};
use lightport_example_kernels::julia;

fn main() -> Result<(), BuildError> {
    // The kernels are a build-dependency, so Cargo reruns this script when they change.
    println!("cargo:rerun-if-changed=build.rs");
    let out_dir = std::env::var("OUT_DIR").expect("Cargo sets OUT_DIR for build scripts");
    Shaders::new(&[julia::kernel_ir()]).module("julia").write(out_dir)?;
    Ok(())
}
