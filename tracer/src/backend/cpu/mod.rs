//! The CPU runtime: the DSL kernel compiled as ordinary Rust, run per pixel with rayon; the
//! reference every GPU runtime is compared with. Its equivalence-harness side is the kernel
//! function itself, called by `harness::Equivalence`.
//!
//! Every runtime folder has the same files for the same roles: `renderer.rs` (its
//! [`Renderer`](super::Renderer)), and where the runtime has them `context.rs`/`device.rs`,
//! `compile.rs`, `display.rs` and `harness.rs`.

mod renderer;
mod wavefront;

pub use renderer::CpuRenderer;
pub use wavefront::{WavefrontRenderer, CPU_POOL};
