//! The wgpu backend: the kernel's generated WGSL compute shader, dispatched once per frame over
//! the packed scene uploaded as storage buffers, adding one sample per pixel to an accumulation
//! buffer.
//!
//! [`WgpuRenderer`] only needs a [`wgpu::Device`] and its queue, so the same code drives native
//! Vulkan/Metal/DX12 and (on wasm) the browser's WebGPU; only device creation differs.
//! Natively, [`WgpuRenderer::headless`] creates its own device (Vulkan; Mesa lavapipe without a
//! GPU).
//!
//! Layout, as the generated shader expects it (see `shaders-generated/*.wgsl`), read back from
//! the shader itself (naga's reflection) rather than assumed, because specialisation removes
//! arrays and renumbers the bindings:
//! - the `Texels<Vec4>` fields of the kernel's `Scene` that the variant keeps are concatenated
//!   into one read-only storage buffer, `lp_scene_vec4f`, and the `Texels<UVec4>` fields into
//!   `lp_scene_vec4u`: each packed array exactly as packed (no 2D shape: a storage buffer is
//!   indexed directly), starting where the uniform member `lp_start_{field}` says. Two storage
//!   buffers whatever the scene (the all-features kernel reads 11 arrays; WebGPU guarantees 8
//!   storage buffers per stage, SwiftShader offers 10);
//! - the scalar and vector fields are the members of the uniform struct `scene`, at the offsets
//!   WGSL's layout rules give them, followed by the arrays' starts;
//! - `lp_accumulation` is the running sum (rgb: sum of samples, w: number of finite samples),
//!   one read-write storage buffer updated in place (a compute invocation owns its pixel, so no
//!   ping-pong is needed), and `lp_target` the image size.
//!
//! A resource the shader declares and this backend does not know is an error, as is a `Scene`
//! member it has no value for. The compute path is one dispatch of one entry point over the
//! image; see `docs/backends.md` for how stages over ray queues would extend it.

mod compile;
mod device;
mod display;
mod filter;
pub mod harness;
mod oneshot;
mod renderer;
mod resources;
mod wavefront;
mod wavefront_pool;

pub use compile::{compile_pipeline, start_pipeline, start_pipelines, PipelineCheck};
pub use device::{WgpuDevice, WgpuInfo};
pub use display::{display_shader, DisplayPass};
pub use filter::WgpuFilter;
pub use renderer::WgpuRenderer;
pub(crate) use resources::{
    bind_group_layouts, check_scene_limits, map_readback, most_buffer_bytes, pipeline_bind_groups, place_arrays,
    reflect, scene_room, scene_uniform_bytes, storage_limit, u32_uniform_bytes, upload_scene, upload_scene_with_room,
    Bindings, BufferEntry, OwnResource, ShaderLayout, UncapturedErrors, UniformLayout,
};
pub use wavefront::WavefrontRenderer;

use crate::backend::{BuildTimes, RenderError, Renderer};
use crate::kernel::ShaderError;

/// `read` (queues a read-back on the device) waited for: natively by polling the device until
/// it arrives; in the browser nothing may block, so an error (await the `read_*` future instead).
pub(crate) fn wait_for_read<T, F>(renderer: &dyn Renderer, read: impl FnOnce() -> F) -> Result<T, RenderError>
where
    F: std::future::Future<Output = Result<T, RenderError>>,
{
    #[cfg(not(target_arch = "wasm32"))]
    {
        let read = read();
        renderer.finish()?;
        pollster::block_on(read)
    }
    #[cfg(target_arch = "wasm32")]
    {
        let _ = (renderer, read);
        Err(RenderError::Unsupported { runtime: "wgpu", what: "cannot block for a read-back in the browser" })
    }
}

/// A renderer on a wgpu device, whichever schedule runs it (the megakernel's [`WgpuRenderer`],
/// the [`WavefrontRenderer`]): what a host that draws its image (the display pass, the page's
/// WebGPU runtime and denoiser) needs beyond [`Renderer`].
pub trait DeviceRenderer: Renderer {
    fn device(&self) -> &WgpuDevice;
    /// The storage buffer whose first `width × height` texels are the running sums (rgb: sum,
    /// w: finite samples; row-major, row 0 at the top).
    fn sums(&self) -> &wgpu::Buffer;
    /// The first error wgpu reported outside an error scope since the renderer was created.
    fn check_uncaptured(&self) -> Result<(), WgpuError>;
    /// Watches the device's uncaptured errors for this renderer again, from now on: a device
    /// keeps one handler, so creating another renderer on it (the page's `auto` measuring the
    /// wavefront beside the megakernel) took them over.
    fn watch_uncaptured(&mut self);
    /// What creating the renderer took on this thread.
    fn build_times(&self) -> BuildTimes;
    /// "megakernel" or "wavefront".
    fn schedule(&self) -> crate::backend::Schedule;
    /// A preview of the current view at `width` x `height` (see
    /// [`preview`](crate::backend::preview)), queued: the storage buffer holding it (one
    /// sample per pixel, `width` per row, row 0 at the top), which the accumulation never sees.
    /// `None`: this renderer renders no preview (the wavefront's).
    fn render_preview(&mut self, width: u32, height: u32) -> Result<Option<wgpu::Buffer>, RenderError> {
        let _ = (width, height);
        Ok(None)
    }
}

/// The read-write storage buffer holding the running sum (written by codegen's entry point).
pub const ACCUMULATION_BUFFER: &str = "lp_accumulation";
/// The uniform holding the image size (written by codegen's entry point).
pub const TARGET_UNIFORM: &str = "lp_target";
/// The uniform struct holding the `Scene`'s scalar and vector fields.
pub const SCENE_UNIFORM: &str = "scene";
/// The compute entry point codegen writes.
pub const ENTRY_POINT: &str = "main";
/// Workgroup size of the generated entry point (`@workgroup_size(8, 8)`).
pub const WORKGROUP_SIZE: [u32; 2] = [8, 8];

/// The Debian packages that provide a Vulkan driver without a GPU (Mesa lavapipe).
pub const VULKAN_PACKAGES: &str = "mesa-vulkan-drivers libvulkan1";

/// Why the wgpu backend cannot render.
#[derive(Debug, thiserror::Error)]
pub enum WgpuError {
    #[error(
        "no wgpu adapter ({backends}): {detail}. Install a Vulkan driver; on Debian or Ubuntu, \
         `apt-get install {VULKAN_PACKAGES}` (Mesa lavapipe runs on the CPU)"
    )]
    NoAdapter { backends: String, detail: String },
    #[error("the wgpu device could not be created on {adapter}: {detail}")]
    Device { adapter: String, detail: String },
    #[error("the scene does not fit this device: `{array}` needs {bytes} bytes but {limit} is {max}")]
    SceneTooLarge { array: String, bytes: u64, limit: &'static str, max: u64 },
    #[error("the image is {width}x{height}: {what} needs {needed} but this device's {limit} is {max}")]
    ImageTooLarge { width: u32, height: u32, what: &'static str, needed: u64, limit: &'static str, max: u64 },
    #[error("the shader needs {needed} for {limit} but this device allows {max}")]
    Unsupported { limit: &'static str, needed: u64, max: u64 },
    #[error(transparent)]
    Codegen(#[from] ShaderError),
    #[error("the WGSL compute shader was rejected (wgpu's messages, with the kernel's Rust locations):\n{log}")]
    Compile { log: String },
    #[error("the shader declares `{name}`, which the wgpu backend does not bind{detail}")]
    UnboundResource { name: String, detail: String },
    #[error("wgpu {what} failed: {detail}")]
    Wgpu { what: &'static str, detail: String },
}

/// Options for [`WgpuRenderer::with_options`].
#[derive(Clone, Debug, Default)]
pub struct WgpuOptions {
    /// Use at most this storage-buffer binding size even where the device allows more (e.g. to
    /// check that a scene fits WebGPU's default 128 MiB, or to test the limit errors).
    pub max_storage_buffer_binding_size: Option<u64>,
    /// Use at most this many storage buffers per shader stage (every kernel binds 3: two texel
    /// buffers and the accumulation; WebGPU's default is 8): to test the limit errors and the
    /// browser's fallback.
    pub max_storage_buffers_per_shader_stage: Option<u32>,
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::kernel::features::Features;
    use crate::kernel::scene_data::Scene;
    use lightport_codegen::Target;

    /// Every resource of every kernel variant is one the backend binds (reflection only: no
    /// device needed).
    #[test]
    fn every_variant_reflects_into_known_resources() {
        let scene = Scene::default();
        for features in [Features::all(), Features { emissive_triangles: true, ..Default::default() }] {
            let generated = crate::kernel::path_tracer_shader(&features, Target::Wgsl).expect("kernel");
            let layout = reflect(&generated, SCENE_UNIFORM, &[ACCUMULATION_BUFFER, TARGET_UNIFORM]).expect("reflect");
            let uniform = layout.scene_uniform.as_ref().expect("scene uniform");
            scene_uniform_bytes(uniform, SCENE_UNIFORM, &scene).expect("every uniform member has a value");
            assert!(uniform.members.iter().any(|(n, _)| n == "frame_seed"));
        }
        let all = reflect(
            &crate::kernel::path_tracer_shader(&Features::all(), Target::Wgsl).unwrap(),
            SCENE_UNIFORM,
            &[ACCUMULATION_BUFFER, TARGET_UNIFORM],
        )
        .unwrap();
        assert_eq!(all.texel_buffers.len(), 2, "{:?}", all.texel_buffers);
        let starts = all.scene_uniform.unwrap().members.iter().filter(|(n, _)| n.starts_with("lp_start_")).count();
        assert_eq!(starts, 11, "every array of the all-features kernel has its start");
    }

    /// The uniform offsets follow WGSL's rules: a vec3 is 16-byte aligned and a scalar may
    /// follow it in its last 4 bytes.
    #[test]
    fn uniform_members_sit_at_wgsl_offsets() {
        let generated = crate::kernel::path_tracer_shader(&Features::all(), Target::Wgsl).unwrap();
        let layout = reflect(&generated, SCENE_UNIFORM, &[ACCUMULATION_BUFFER, TARGET_UNIFORM]).unwrap();
        let u = layout.scene_uniform.unwrap();
        let offset = |name: &str| u.members.iter().find(|(n, _)| n == name).map(|(_, o)| *o).expect(name);
        // Five u32s (the normal-map, alpha-mask and texture-reference offsets) before the camera:
        // the first vec3 rounds up to 32.
        assert_eq!(offset("normal_map_first") + 4, 8);
        assert_eq!(offset("camera_position"), 32);
        assert_eq!(offset("camera_right"), offset("camera_position") + 16);
        assert_eq!(offset("camera_forward"), offset("camera_position") + 48);
        assert_eq!(offset("lens_radius"), offset("camera_forward") + 12);
    }
}
