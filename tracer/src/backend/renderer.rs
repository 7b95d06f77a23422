//! [`Renderer`]: the one interface of the CPU, GL and wgpu runtimes. A renderer is created from
//! a [`Packed`] scene and a seed; each frame adds one sample per pixel to a running sum, whole
//! ([`render_frame`](Renderer::render_frame)) or in bands of rows
//! ([`render_band`](Renderer::render_band), see [`frame_split`](super::frame_split)); the sum is
//! read back as [`accumulation`](Renderer::accumulation), and the image and the count of dropped
//! samples are derived from it once, here, for every runtime.

use std::future::Future;
use std::pin::Pin;

use glam::{Vec4, Vec4Swizzles};

use super::gl::GlError;
#[cfg(feature = "wgpu")]
use super::wgpu::WgpuError;
use super::Image;
use crate::kernel::denoise::FilterImage;
use crate::kernel::scene_data::Scene;
use crate::pack::Packed;

/// Why a renderer cannot be created or cannot render.
#[derive(Debug, thiserror::Error)]
pub enum RenderError {
    #[error(transparent)]
    Gl(#[from] GlError),
    #[cfg(feature = "wgpu")]
    #[error(transparent)]
    Wgpu(#[from] WgpuError),
    /// [`Renderer::set_uniforms`] changed the image size, which every runtime fixes at creation.
    #[error("the image size is fixed at {width}x{height} when the renderer is created; create one for {wanted}")]
    SizeChanged { width: u32, height: u32, wanted: String },
    /// [`Renderer::guide_sums`] of a renderer created without the denoiser's guide.
    #[error(
        "the renderer was created without the denoiser's guide (pack the scene with `Packed::set_denoise_guide(true)`)"
    )]
    NoGuide,
    /// [`Renderer::take_geometry`] of a pose the renderer's kernel cannot draw.
    #[error(transparent)]
    Pack(#[from] crate::pack::PackError),
    /// The wavefront schedule cannot render this scene or image here.
    #[error(transparent)]
    Wavefront(#[from] super::wavefront::WavefrontError),
    /// The runtime cannot do this here (not built in, or not on this platform).
    #[error("the {runtime} renderer {what}")]
    Unsupported { runtime: &'static str, what: &'static str },
}

/// A running sum read without blocking (see [`Renderer::read_accumulation`]).
pub type PendingAccumulation = Pin<Box<dyn Future<Output = Result<Vec<Vec4>, RenderError>>>>;

/// The running sums of the denoiser's guide per pixel, as a renderer created with
/// `Features::denoise_guide` accumulates them beside the colour: the fields of
/// `integrator::GuidedSample` after `color` (albedo and luminance, normal and depth, emission
/// and squared luminance). `tracer::denoise::Guide::from_sums` turns them into the filter's guide.
pub type GuideSums = [Vec<Vec4>; 3];

/// [`GuideSums`] read without blocking (see [`Renderer::read_guide_sums`]).
pub type PendingGuideSums = Pin<Box<dyn Future<Output = Result<GuideSums, RenderError>>>>;

/// What a renderer runs on, for read-outs and benchmark tables.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct RendererInfo {
    /// The runtime: "cpu", "gl" or "wgpu" (as `--backend` spells it).
    pub runtime: &'static str,
    /// The device as its API names it: the CPU's threads, `GL_RENDERER`, the wgpu adapter and
    /// its backend.
    pub device: String,
    /// The device limits the renderer checked the scene against, by name (empty on the CPU).
    pub limits: Vec<(&'static str, u64)>,
}

/// The kernel on one runtime, accumulating one sample per pixel per frame.
///
/// Frames may be split into bands of rows: [`render_band`](Self::render_band) renders the next
/// rows of the current frame with that frame's seed, so a frame rendered in bands is the frame
/// rendered whole, bit for bit; the sample count ([`frames`](Self::frames)) advances with a
/// frame's last band. [`restart`](Self::restart) abandons a split frame.
pub trait Renderer {
    /// The runtime and device, and the limits it works under.
    fn describe(&self) -> RendererInfo;

    /// The scene as the renderer holds it (its uniforms as [`set_uniforms`](Self::set_uniforms) left them).
    fn packed(&self) -> &Packed;

    /// Samples per pixel accumulated: frames completed since creation or the last restart.
    fn frames(&self) -> u32;

    /// Rows of the current frame not rendered yet (the image height between frames).
    fn rows_left(&self) -> u32;

    /// Renders the next `rows` rows (kernel rows from the top, clamped to `1..=rows_left()`) of
    /// the current frame. Returns whether this band completed the frame (and advanced the
    /// sample count). GPU runtimes queue the work; [`finish`](Self::finish) waits for it.
    fn render_band(&mut self, rows: u32) -> Result<bool, RenderError>;

    /// Adds one sample per pixel: the rest of the current frame, when it was begun in bands.
    fn render_frame(&mut self) -> Result<(), RenderError> {
        self.render_band(self.rows_left()).map(|_| ())
    }

    /// Waits until every queued frame has been rendered, e.g. around timings (nothing to wait
    /// for on the CPU; in the browser nothing blocks, so it only reports the device's errors).
    fn finish(&self) -> Result<(), RenderError>;

    /// The running sum per pixel, row y = kernel row y: rgb the sum of samples, w the number of
    /// finite samples. Blocks until it is read back (not available from WebGPU, which cannot
    /// block: use [`read_accumulation`](Self::read_accumulation)).
    fn accumulation(&self) -> Result<Vec<Vec4>, RenderError>;

    /// [`accumulation`](Self::accumulation) as a future: resolved at once where the read-back
    /// is synchronous; on wgpu the copy is queued now and the future resolves once the device
    /// has mapped it (in the browser a promise; natively someone must poll the device).
    fn read_accumulation(&self) -> PendingAccumulation {
        Box::pin(std::future::ready(self.accumulation()))
    }

    /// The denoiser's guide accumulated with the image (row y = kernel row y, as
    /// [`accumulation`](Self::accumulation)); [`RenderError::NoGuide`] unless the renderer was
    /// created from a scene packed with `Packed::set_denoise_guide(true)`. Blocks, as
    /// `accumulation` does (WebGPU: [`read_guide_sums`](Self::read_guide_sums)).
    fn guide_sums(&self) -> Result<GuideSums, RenderError>;

    /// [`guide_sums`](Self::guide_sums) as a future, as [`read_accumulation`](Self::read_accumulation).
    fn read_guide_sums(&self) -> PendingGuideSums {
        Box::pin(std::future::ready(self.guide_sums()))
    }

    /// Changes the scene's uniforms (camera, strategy, depth...) through `update` and restarts
    /// the accumulation, without recompiling or re-uploading anything: texel arrays changed by
    /// `update` are not re-uploaded. The image size cannot change: that is
    /// [`RenderError::SizeChanged`], and the size stays as it was.
    fn set_uniforms(&mut self, update: &mut dyn FnMut(&mut Scene)) -> Result<(), RenderError>;

    /// Takes the geometry of `moved`, the renderer's scene posed at another time
    /// (`Scene::pose`, packed again: [`Packed::take_geometry`]), uploads the scene's arrays
    /// again without recompiling the kernel, and restarts the accumulation. Uniforms set
    /// through [`set_uniforms`](Self::set_uniforms) stay. A pose that needs another kernel
    /// variant is [`PackError::KernelChanged`](crate::pack::PackError::KernelChanged) and
    /// changes nothing: create a renderer for it.
    fn take_geometry(&mut self, moved: Packed) -> Result<(), RenderError>;

    /// Takes `scene` whole in place of the renderer's (every array and uniform uploaded again),
    /// keeps the compiled kernel, and restarts the accumulation. `scene` must need the same
    /// kernel variant ([`PackError::KernelChanged`](crate::pack::PackError::KernelChanged)
    /// otherwise) at the same image size ([`RenderError::SizeChanged`]); then, as when an
    /// upload fails, nothing changes. For a renderer created from
    /// [`Packed::placeholder`](crate::pack::Packed::placeholder), which compiles the kernel
    /// while the scene is decoded (the page's viewer).
    fn take_scene(&mut self, scene: Packed) -> Result<(), RenderError>;

    /// Drops every accumulated sample: the next frame is sample 1 again (a split frame in
    /// progress is abandoned: the next band is its first row).
    fn restart(&mut self) -> Result<(), RenderError>;

    /// The mean of the accumulated samples (linear RGB).
    fn image(&self) -> Result<Image, RenderError> {
        let scene = &self.packed().scene;
        Ok(mean_image(scene.width, scene.height, self.frames(), &self.accumulation()?))
    }

    /// Samples that were not finite and were dropped, over the whole image.
    fn rejected_samples(&self) -> Result<u64, RenderError> {
        Ok(rejected_samples(self.frames(), &self.accumulation()?))
    }

    /// A wavefront renderer's ray counts since its last restart (read from the device: blocks
    /// natively); `None` for a megakernel.
    fn wavefront_counts(&self) -> Option<super::wavefront::WavefrontCounts> {
        None
    }

    /// The denoiser's à-trous passes over `image` on this runtime (the kernel's
    /// `denoise::atrous_pixel` at steps 1, 2, 4, ...): the last pass's output per pixel, as
    /// [`filter_on_cpu`](crate::denoise::filter_on_cpu) computes it. GL runs them as fragment
    /// passes and wgpu as compute passes on the renderer's own context or device; the CPU
    /// runtime (this default) in Rust.
    fn denoise_passes(&mut self, image: FilterImage) -> Result<Vec<Vec4>, RenderError> {
        Ok(crate::denoise::filter_on_cpu(image))
    }
}

/// The mean of `frames` accumulated samples per pixel (linear RGB) from a running sum.
pub fn mean_image(width: u32, height: u32, frames: u32, accumulation: &[Vec4]) -> Image {
    let n = frames.max(1) as f32;
    Image { width, height, pixels: accumulation.iter().map(|a| a.xyz() / n).collect() }
}

/// Samples dropped as not finite: `frames` per pixel, less the accepted ones counted in w.
pub fn rejected_samples(frames: u32, accumulation: &[Vec4]) -> u64 {
    let accepted: f64 = accumulation.iter().map(|a| a.w as f64).sum();
    (frames as u64 * accumulation.len() as u64).saturating_sub(accepted.round() as u64)
}

/// [`Packed::exchange_scene`] for [`Renderer::take_scene`]: refused, and nothing exchanged, for
/// another image size.
pub(crate) fn exchange_scene(current: &mut Packed, other: &mut Packed) -> Result<(), RenderError> {
    let (c, o) = (&current.scene, &other.scene);
    if (c.width, c.height) != (o.width, o.height) {
        let wanted = format!("{}x{}", o.width, o.height);
        return Err(RenderError::SizeChanged { width: c.width, height: c.height, wanted });
    }
    Ok(current.exchange_scene(other)?)
}

/// Applies `update` to `scene`, refusing (and undoing) a change of the image size.
pub(crate) fn update_uniforms(scene: &mut Scene, update: &mut dyn FnMut(&mut Scene)) -> Result<(), RenderError> {
    let (width, height) = (scene.width, scene.height);
    update(scene);
    if (scene.width, scene.height) != (width, height) {
        let wanted = format!("{}x{}", scene.width, scene.height);
        (scene.width, scene.height) = (width, height);
        return Err(RenderError::SizeChanged { width, height, wanted });
    }
    Ok(())
}

/// The runtimes a renderer can be created on in this process.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum RendererKind {
    Cpu,
    /// OpenGL ES 3.0 through a headless EGL context (feature `gl`).
    Gl,
    /// The WGSL kernel as a compute shader on a native wgpu device (feature `wgpu`).
    Wgpu,
}

impl RendererKind {
    pub const ALL: [RendererKind; 3] = [RendererKind::Cpu, RendererKind::Gl, RendererKind::Wgpu];

    /// "cpu", "gl" or "wgpu" ([`RendererInfo::runtime`]).
    pub fn name(self) -> &'static str {
        match self {
            RendererKind::Cpu => "cpu",
            RendererKind::Gl => "gl",
            RendererKind::Wgpu => "wgpu",
        }
    }
}

/// How a renderer organises a frame's work: the same path tracer either way.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum Schedule {
    /// One invocation per pixel follows its path to the end (`integrator::trace_path`): every
    /// runtime.
    #[default]
    Megakernel,
    /// Stages over a pool of paths with queues on the device (`kernel::wavefront`): the CPU and
    /// wgpu (GLSL ES 3.00 has no compute shaders or atomics).
    Wavefront,
}

impl Schedule {
    pub const ALL: [Schedule; 2] = [Schedule::Megakernel, Schedule::Wavefront];

    /// What `--schedule auto` runs natively: the megakernel, faster on every native row
    /// measured (`examples/bench_wavefront.rs`, 640x480, four scenes at depths 8 and 32, median
    /// of 5 alternated rounds: the wavefront took 1.22-2.01x the megakernel's time on the CPU
    /// and 1.00-1.39x on lavapipe, so `auto` is never more than 5 % slower than the faster
    /// schedule there; see `docs/wavefront.md`, "Measurements").
    ///
    /// The page's `?schedule=auto` on WebGPU starts with this and then measures: the wavefront
    /// measured 0.40-0.80x the megakernel's frame time on some scenes and 1.25-2.33x on others
    /// on SwiftShader, and real GPUs differ again, so no fixed rule fits the browser. Once a
    /// scene's first frame has shown, the page times both schedules on the device and scene at
    /// hand (alternated turns, medians) and keeps the wavefront only if it is more than 5 %
    /// faster (`web/src/schedule_choice.rs`; `docs/wavefront.md`, "auto in the page").
    pub fn auto() -> Schedule {
        Schedule::Megakernel
    }

    /// `name` as `--schedule` and the page's `?schedule=` spell it: "megakernel",
    /// "wavefront", or "auto" ([`auto`](Self::auto)'s choice).
    pub fn parse(name: &str) -> Result<Schedule, String> {
        match name.to_ascii_lowercase().as_str() {
            "" | "auto" => Ok(Schedule::auto()),
            "megakernel" => Ok(Schedule::Megakernel),
            "wavefront" => Ok(Schedule::Wavefront),
            other => Err(format!("unknown schedule {other:?}: use auto, megakernel or wavefront")),
        }
    }

    /// "megakernel" or "wavefront" (as `--schedule` spells it).
    pub fn name(self) -> &'static str {
        match self {
            Schedule::Megakernel => "megakernel",
            Schedule::Wavefront => "wavefront",
        }
    }
}

/// A renderer of `kind` for `packed` with `seed` (the same seed gives the same random sequence
/// on every runtime), on its own context or device where it needs one. In the browser the
/// canvas's context or device is the page's: create [`GlRenderer`](super::gl::GlRenderer) or
/// [`WgpuRenderer`](super::wgpu::WgpuRenderer) on it.
#[cfg(not(target_arch = "wasm32"))]
pub fn create(kind: RendererKind, packed: Packed, seed: u32) -> Result<Box<dyn Renderer>, RenderError> {
    create_scheduled(kind, Schedule::Megakernel, packed, seed)
}

/// [`create`] with the frame's work organised by `schedule`. A wavefront on GL is
/// [`WavefrontError::NoCompute`](super::wavefront::WavefrontError::NoCompute).
#[cfg(not(target_arch = "wasm32"))]
pub fn create_scheduled(
    kind: RendererKind,
    schedule: Schedule,
    packed: Packed,
    seed: u32,
) -> Result<Box<dyn Renderer>, RenderError> {
    use super::wavefront::WavefrontError;
    Ok(match (kind, schedule) {
        (RendererKind::Cpu, Schedule::Megakernel) => Box::new(super::cpu::CpuRenderer::new(packed, seed)),
        (RendererKind::Cpu, Schedule::Wavefront) => {
            Box::new(super::cpu::WavefrontRenderer::new(packed, seed, super::cpu::CPU_POOL)?)
        }
        #[cfg(feature = "gl")]
        (RendererKind::Gl, Schedule::Megakernel) => Box::new(super::gl::GlRenderer::headless(packed, seed)?),
        (RendererKind::Gl, Schedule::Wavefront) => return Err(WavefrontError::NoCompute { runtime: "gl" }.into()),
        #[cfg(feature = "wgpu")]
        (RendererKind::Wgpu, Schedule::Megakernel) => Box::new(super::wgpu::WgpuRenderer::headless(packed, seed)?),
        #[cfg(feature = "wgpu")]
        (RendererKind::Wgpu, Schedule::Wavefront) => Box::new(super::wgpu::WavefrontRenderer::headless(packed, seed)?),
        #[allow(unreachable_patterns)]
        (other, _) => {
            return Err(RenderError::Unsupported { runtime: other.name(), what: "is not built in (cargo feature)" })
        }
    })
}
