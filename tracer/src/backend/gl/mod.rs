//! The GL backend: the kernel's generated GLSL ES 3.00 fragment shader, drawn as a full-screen
//! triangle into an RGBA32F framebuffer once per frame, over the packed scene uploaded as data
//! textures.
//!
//! [`GlRenderer`] only needs a [`glow::Context`], so the same code drives native OpenGL ES /
//! desktop GL and (on wasm) WebGL2; only context creation and the frame loop around it differ.
//! Natively, [`GlRenderer::headless`] creates its own surfaceless EGL context (feature `gl`).
//!
//! Layout, as the generated shader expects it (see `shaders-generated/*.frag.glsl`):
//! - every `Texels<Vec4>` / `Texels<UVec4>` field `f` of the kernel's `Scene` is a 2D RGBA32F /
//!   RGBA32UI texture bound to the sampler uniform `scene_f`: the packed array exactly as
//!   packed, row-major, with the power-of-two width of [`texture_shape`] (the shader's
//!   `lp_fetch_*` takes the row as a shift and the column as a mask), NEAREST filtering;
//! - every scalar or vector field `f` is the uniform `scene_f`;
//! - `lp_accumulation` is the previous frame's running sum (rgb: sum of samples, w: number of
//!   finite samples); the entry point writes it plus this frame's sample. Two RGBA32F
//!   textures ping-pong.
//!
//! Fields and arrays that specialisation removed from the shader have no uniform location and
//! are skipped. The fields come from `Scene`'s one declaration (`kernel_dsl::Resources`, generated
//! by `#[kernel]`), and [`bindings::check_active_uniforms`] refuses a uniform bound as another type.
//!
//! One file per role: `renderer.rs` (the [`GlRenderer`] and the pipeline it builds),
//! `bindings.rs` (the `Scene` fields as uniforms and data textures), `texture.rs` (the data
//! textures' shape and upload), `compile.rs`, `display.rs`, `filter.rs` (the denoiser's passes), `targets.rs` (RGBA32F images,
//! their framebuffers and read-back, shared by the renderer and the filter).

mod bindings;
mod compile;
#[cfg(feature = "gl")]
mod context;
mod display;
mod filter;
pub mod harness;
mod pacing;
mod renderer;
mod targets;
mod texture;
pub use bindings::gl_type;
pub use compile::{annotate_log, compile_program, log_line_number};
pub use display::{display_fragment_shader, GlDisplay};
pub use filter::{GlFilter, QueuedFilter};
pub use pacing::{Pacer, QUAD_ROWS};
pub use renderer::GlRenderer;
pub(crate) use texture::{set_nearest, upload_texels, words_as_bytes, words_as_bytes_mut};
pub use texture::{texture_shape, ArrayStats};

use crate::kernel::ShaderError;
use crate::pack::PackError;

#[cfg(feature = "gl")]
pub use context::{EglError, HeadlessContext};

/// The sampler uniform holding the previous accumulation (written by codegen's entry point).
pub const ACCUMULATION_UNIFORM: &str = "lp_accumulation";
/// Prefix of every `Scene` field's uniform in the generated GLSL.
pub const SCENE_UNIFORM_PREFIX: &str = "scene_";

/// Why the GL backend cannot render.
#[derive(Debug, thiserror::Error)]
pub enum GlError {
    #[cfg(feature = "gl")]
    #[error(transparent)]
    Context(#[from] EglError),
    #[error("the GL context cannot run the kernel: {0}")]
    Unsupported(String),
    #[error("the scene does not fit this GL device (GL_MAX_TEXTURE_SIZE {max_texture_size}): {reason}")]
    SceneTooLarge { max_texture_size: u32, reason: PackError },
    #[error("the image is {width}x{height} but this GL device's {limit} is {max}")]
    ImageTooLarge { width: u32, height: u32, limit: &'static str, max: u32 },
    #[error(transparent)]
    Codegen(#[from] ShaderError),
    #[error("the {stage} shader does not compile (driver log, with the kernel's Rust locations):\n{log}")]
    Compile { stage: &'static str, log: String },
    #[error("the shader program does not link (driver log):\n{log}")]
    Link { log: String },
    #[error(
        "the shader declares uniform `{name}` (GL type {gl_type:#06x}), which the GL backend does not bind{expected}"
    )]
    UnboundUniform { name: String, gl_type: u32, expected: String },
    #[error("GL {what} failed: {detail}")]
    Gl { what: &'static str, detail: String },
}

pub(crate) fn gl_failed(what: &'static str) -> impl FnOnce(String) -> GlError {
    move |detail| GlError::Gl { what, detail }
}

/// Options for [`GlRenderer::with_options`].
#[derive(Clone, Debug, Default)]
pub struct GlOptions {
    /// Use at most this texture size even where the device allows more (e.g. to check that a
    /// scene fits WebGL2's common 4096, or to test the limit errors).
    pub max_texture_size: Option<u32>,
}

/// What the GL context reports about itself.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct GlInfo {
    /// `GL_VERSION`, e.g. "OpenGL ES 3.2 Mesa 25.0.7".
    pub version: String,
    /// `GL_RENDERER`, e.g. "llvmpipe (LLVM 19.1.7, 256 bits)".
    pub renderer: String,
    /// The texture size used (the device's `GL_MAX_TEXTURE_SIZE`, or the smaller option).
    pub max_texture_size: u32,
}
