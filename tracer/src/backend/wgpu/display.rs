//! The display pass on wgpu: the accumulation's mean drawn to a colour target (in the browser,
//! the canvas's WebGPU surface) through the kernel's display transform
//! (`tonemap::display_srgb`, generated as WGSL by codegen, the same functions the CPU's PNG
//! output runs), as [`GlDisplay`](crate::backend::gl::GlDisplay) does with its GLSL. A full-screen triangle; each fragment
//! reads its pixel from the accumulation storage buffer (row 0 at the top, as WebGPU's
//! framebuffer coordinates count).

use std::borrow::Cow;

use lightport_codegen::Target;
use wgpu::util::DeviceExt;

use super::{DeviceRenderer, WgpuError};
use crate::output::Display;

/// The entry points and resources the pass adds to the generated tone-map module.
const DISPLAY_ENTRY: &str = r#"
// Display pass (tracer/src/backend/wgpu/display.rs): the mean of the accumulation, tone-mapped
// and sRGB-encoded by display_srgb above.
struct LpDisplay {
    width: u32,
    inverse_frames: f32,
    operator_: u32,
    exposure_scale: f32,
    // The image's size over the target's: 1 where they match; a smaller image (a preview)
    // is stretched over the target, each of its pixels a block.
    scale: vec2<f32>,
}
@group(0) @binding(0) var<storage, read> lp_display_accumulation: array<vec4<f32>>;
@group(0) @binding(1) var<uniform> lp_display: LpDisplay;

@vertex
fn lp_display_vertex(@builtin(vertex_index) i: u32) -> @builtin(position) vec4<f32> {
    let corner = vec2<f32>(f32((i << 1u) & 2u), f32(i & 2u));
    return vec4<f32>(corner * 2.0 - 1.0, 0.0, 1.0);
}

@fragment
fn lp_display_fragment(@builtin(position) position: vec4<f32>) -> @location(0) vec4<f32> {
    let p = vec2<u32>(position.xy * lp_display.scale);
    let sum = lp_display_accumulation[p.y * lp_display.width + p.x];
    let c = display_srgb(sum.xyz * lp_display.inverse_frames, lp_display.operator_, lp_display.exposure_scale);
    return vec4<f32>(c, 1.0);
}
"#;

/// The display shader's WGSL: the kernel's display transform (`tonemap::display_srgb`, as
/// the GL display pass takes it in GLSL) and the pass's entry points.
pub fn display_shader() -> Result<String, WgpuError> {
    let generated = crate::kernel::display_transform(Target::Wgsl)?;
    Ok(format!("{}\n{DISPLAY_ENTRY}", generated.source))
}

/// The display pipeline for one colour-target format.
pub struct DisplayPass {
    pipeline: wgpu::RenderPipeline,
    layout: wgpu::BindGroupLayout,
    uniform: wgpu::Buffer,
}

impl DisplayPass {
    /// A display pipeline drawing into targets of `format` (not an sRGB format: the shader
    /// encodes sRGB itself, as the WebGL2 pass does). Shader errors are wgpu's uncaptured errors.
    pub fn new(device: &wgpu::Device, format: wgpu::TextureFormat) -> Result<Self, WgpuError> {
        let source = display_shader()?;
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("lightport display"),
            source: wgpu::ShaderSource::Wgsl(Cow::Owned(source)),
        });
        let entry = |binding, ty| wgpu::BindGroupLayoutEntry {
            binding,
            visibility: wgpu::ShaderStages::FRAGMENT,
            ty: wgpu::BindingType::Buffer { ty, has_dynamic_offset: false, min_binding_size: None },
            count: None,
        };
        let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("lightport display"),
            entries: &[
                entry(0, wgpu::BufferBindingType::Storage { read_only: true }),
                entry(1, wgpu::BufferBindingType::Uniform),
            ],
        });
        let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("lightport display"),
            bind_group_layouts: &[Some(&layout)],
            immediate_size: 0,
        });
        let pipeline = device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
            label: Some("lightport display"),
            layout: Some(&pipeline_layout),
            vertex: wgpu::VertexState {
                module: &module,
                entry_point: Some("lp_display_vertex"),
                compilation_options: Default::default(),
                buffers: &[],
            },
            primitive: wgpu::PrimitiveState::default(),
            depth_stencil: None,
            multisample: wgpu::MultisampleState::default(),
            fragment: Some(wgpu::FragmentState {
                module: &module,
                entry_point: Some("lp_display_fragment"),
                compilation_options: Default::default(),
                targets: &[Some(wgpu::ColorTargetState { format, blend: None, write_mask: wgpu::ColorWrites::ALL })],
            }),
            multiview_mask: None,
            cache: None,
        });
        let uniform = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("lightport display uniforms"),
            contents: &[0u8; 32],
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
        });
        Ok(DisplayPass { pipeline, layout, uniform })
    }

    /// Draws `renderer`'s current mean through `settings` into `target` (the renderer's image
    /// size).
    pub fn draw(&self, renderer: &dyn DeviceRenderer, target: &wgpu::TextureView, settings: &Display) {
        let device = renderer.device();
        let width = renderer.packed().scene.width;
        let inverse_frames = 1.0 / renderer.frames().max(1) as f32;
        let sums = renderer.sums();
        self.draw_buffer(&device.device, &device.queue, target, sums, width, inverse_frames, settings);
    }

    /// Draws `pixels` (a storage buffer of `vec4<f32>`, `width` per row, row 0 at the top: a
    /// running sum, or an image with `inverse_frames` 1) through `settings` into `target`, of
    /// the image's size.
    #[allow(clippy::too_many_arguments)]
    pub fn draw_buffer(
        &self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        target: &wgpu::TextureView,
        pixels: &wgpu::Buffer,
        width: u32,
        inverse_frames: f32,
        settings: &Display,
    ) {
        self.draw_stretched(device, queue, target, pixels, width, [1.0, 1.0], inverse_frames, settings);
    }

    /// [`draw_buffer`](Self::draw_buffer) of an image of `size` stretched over a `target` of
    /// `target_size` (a preview, upscaled: each of its pixels a block).
    #[allow(clippy::too_many_arguments)]
    pub fn draw_upscaled(
        &self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        target: &wgpu::TextureView,
        pixels: &wgpu::Buffer,
        size: [u32; 2],
        target_size: [u32; 2],
        inverse_frames: f32,
        settings: &Display,
    ) {
        let scale = [0, 1].map(|i| size[i] as f32 / target_size[i].max(1) as f32);
        self.draw_stretched(device, queue, target, pixels, size[0], scale, inverse_frames, settings);
    }

    #[allow(clippy::too_many_arguments)]
    fn draw_stretched(
        &self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        target: &wgpu::TextureView,
        pixels: &wgpu::Buffer,
        width: u32,
        scale: [f32; 2],
        inverse_frames: f32,
        settings: &Display,
    ) {
        let words: [u32; 8] = [
            width,
            inverse_frames.to_bits(),
            settings.tone_map.kernel_id(),
            settings.exposure.exp2().to_bits(),
            scale[0].to_bits(),
            scale[1].to_bits(),
            0,
            0,
        ];
        queue.write_buffer(&self.uniform, 0, bytemuck::cast_slice(&words));
        let group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("lightport display"),
            layout: &self.layout,
            entries: &[
                wgpu::BindGroupEntry { binding: 0, resource: pixels.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 1, resource: self.uniform.as_entire_binding() },
            ],
        });
        let mut encoder = device.create_command_encoder(&Default::default());
        {
            let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
                label: Some("lightport display"),
                color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                    view: target,
                    depth_slice: None,
                    resolve_target: None,
                    ops: wgpu::Operations {
                        load: wgpu::LoadOp::Clear(wgpu::Color::BLACK),
                        store: wgpu::StoreOp::Store,
                    },
                })],
                depth_stencil_attachment: None,
                timestamp_writes: None,
                occlusion_query_set: None,
                multiview_mask: None,
            });
            pass.set_pipeline(&self.pipeline);
            pass.set_bind_group(0, &group, &[]);
            pass.draw(0..3, 0..1);
        }
        queue.submit([encoder.finish()]);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The display shader (generated tone map + entry points) is valid WGSL with both stages.
    #[test]
    fn the_display_shader_validates() {
        let source = display_shader().expect("display shader");
        let module = naga::front::wgsl::parse_str(&source).unwrap_or_else(|e| panic!("{}", e.emit_to_string(&source)));
        naga::valid::Validator::new(naga::valid::ValidationFlags::all(), naga::valid::Capabilities::default())
            .validate(&module)
            .expect("valid");
        let stages: Vec<_> = module.entry_points.iter().map(|e| e.stage).collect();
        assert_eq!(stages, [naga::ShaderStage::Vertex, naga::ShaderStage::Fragment]);
    }
}
