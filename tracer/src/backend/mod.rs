//! Backends run the same kernel over the same packed data, behind one interface, [`Renderer`]:
//! create from a [`Packed`](crate::pack::Packed) scene, `render_frame` (or `render_band`) adds
//! one sample per pixel, and the accumulated image is read back as linear RGB. [`create`] makes
//! one of any [`RendererKind`] natively.

pub mod cpu;
#[cfg(feature = "gl")]
pub mod egl;
pub mod frame_split;
pub mod gl;
pub mod harness;
mod renderer;
#[cfg(feature = "wgpu")]
pub mod wgpu;

#[cfg(not(target_arch = "wasm32"))]
pub use renderer::create;
pub(crate) use renderer::update_uniforms;
// The image a renderer reads back lives with what writes and displays it (`output`).
pub use crate::output::Image;
pub use renderer::{
    mean_image, rejected_samples, PendingAccumulation, RenderError, Renderer, RendererInfo, RendererKind,
};

/// Seed of frame `frame`: spreads consecutive frames over the hash's input space.
pub fn frame_seed(frame: u32, seed: u32) -> u32 {
    frame.wrapping_mul(0x9e37_79b9) ^ seed.wrapping_mul(0x85eb_ca6b)
}
