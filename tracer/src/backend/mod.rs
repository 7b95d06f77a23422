//! Backends run the same kernel over the same packed data, behind one interface, [`Renderer`]:
//! create from a [`Packed`](crate::pack::Packed) scene, `render_frame` (or `render_band`) adds
//! one sample per pixel, and the accumulated image is read back as linear RGB. [`create`] makes
//! one of any [`RendererKind`] natively.

pub mod cpu;
pub mod frame_split;
pub mod gl;
pub mod harness;
pub mod preview;
mod renderer;
pub mod wavefront;
#[cfg(feature = "wgpu")]
pub mod wgpu;

#[cfg(not(target_arch = "wasm32"))]
pub use renderer::{create, create_scheduled};
pub(crate) use renderer::{exchange_scene, update_uniforms};
// The image a renderer reads back lives with what writes and displays it (`output`).
pub use crate::output::Image;
pub use renderer::{
    mean_image, rejected_samples, GuideSums, PendingAccumulation, PendingGuideSums, RenderError, Renderer,
    RendererInfo, RendererKind, Schedule,
};

/// Where a GPU renderer's creation went, in milliseconds of the calling thread: generating the
/// kernel's shader for the scene's features (`codegen_ms`), handing it to the driver and, where
/// the driver answers synchronously, waiting for its verdict (`compile_ms`: GL's compile and
/// link; on wgpu only the pipeline creation calls, since WebGPU compiles asynchronously), and
/// creating and filling the scene's textures or buffers and the accumulation (`upload_ms`: the
/// data handed to the driver, which may still be copying it when creation returns).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct BuildTimes {
    pub codegen_ms: f64,
    pub compile_ms: f64,
    pub upload_ms: f64,
}

/// Milliseconds since `start` (on wasm too: `web_time` reads `performance.now()` there).
pub(crate) fn ms_since(start: web_time::Instant) -> f64 {
    start.elapsed().as_secs_f64() * 1e3
}

/// Seed of frame `frame` (the kernel's `rng::seed_of_frame`, which the wavefront's stages call
/// on the device).
pub fn frame_seed(frame: u32, seed: u32) -> u32 {
    crate::kernel::rng::seed_of_frame(frame, seed)
}
