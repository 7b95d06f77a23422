//! The denoised image on the canvas, through the kernel's display transform: the same
//! generated shaders as the runtimes' display passes (`tracer::backend::gl::display_fragment_shader`
//! on WebGL2, `tracer::backend::wgpu::display_shader` on WebGPU), fed the denoised linear image
//! (a mean, so `inverse_frames` is 1) instead of the accumulation. Tone curve, exposure and
//! sRGB encoding are therefore the raw image's, and the CLI's PNG output's.

use std::borrow::Cow;

use glam::Vec3;
use glow::HasContext;
use tracer::backend::Image;
use tracer::output::Display;
use wgpu::util::DeviceExt;

/// The image's pixels as RGBA32F bytes (alpha 1, so a row of texels is a row of the image).
fn rgba_bytes(pixels: &[Vec3]) -> Vec<u8> {
    pixels.iter().flat_map(|p| p.extend(1.0).to_array()).flat_map(f32::to_le_bytes).collect()
}

/// The WebGL2 pass: the display program over an RGBA32F texture holding the image (row y =
/// image row y from the top, as the accumulation texture the display shader was written for).
pub struct GlImageDisplay {
    program: glow::Program,
    vertex_array: glow::VertexArray,
    texture: glow::Texture,
    /// Which image the texture holds (see [`draw`](Self::draw)).
    uploaded: Option<u64>,
}

impl GlImageDisplay {
    pub fn new(gl: &glow::Context) -> Result<Self, String> {
        let fragment = tracer::backend::gl::display_fragment_shader().map_err(|e| e.to_string())?;
        let program = tracer::backend::gl::compile_program(gl, &fragment).map_err(|e| e.to_string())?;
        // SAFETY: object creation on the current context; the program is deleted on failure.
        unsafe {
            let objects = gl.create_vertex_array().and_then(|v| gl.create_texture().map(|t| (v, t)));
            match objects {
                Ok((vertex_array, texture)) => Ok(GlImageDisplay { program, vertex_array, texture, uploaded: None }),
                Err(e) => {
                    gl.delete_program(program);
                    Err(format!("creating the denoised image's GL objects failed: {e}"))
                }
            }
        }
    }

    /// Draws `image` (known to the caller as `id`: uploaded again only when it changes) through
    /// `display` to the canvas.
    pub fn draw(&mut self, gl: &glow::Context, image: &Image, id: u64, display: &Display) {
        let (w, h) = (image.width as i32, image.height as i32);
        let uniform = |name: &str| {
            // SAFETY: a query on the linked program.
            unsafe { gl.get_uniform_location(self.program, name) }
        };
        // SAFETY: objects of this context; the texture is RGBA32F of the image's size, filled
        // from a buffer of exactly width x height x 16 bytes; bindings are reset afterwards.
        unsafe {
            gl.active_texture(glow::TEXTURE0);
            gl.bind_texture(glow::TEXTURE_2D, Some(self.texture));
            if self.uploaded != Some(id) {
                gl.pixel_store_i32(glow::UNPACK_ALIGNMENT, 4);
                gl.tex_parameter_i32(glow::TEXTURE_2D, glow::TEXTURE_MIN_FILTER, glow::NEAREST as i32);
                gl.tex_parameter_i32(glow::TEXTURE_2D, glow::TEXTURE_MAG_FILTER, glow::NEAREST as i32);
                let bytes = rgba_bytes(&image.pixels);
                gl.tex_image_2d(
                    glow::TEXTURE_2D,
                    0,
                    glow::RGBA32F as i32,
                    w,
                    h,
                    0,
                    glow::RGBA,
                    glow::FLOAT,
                    glow::PixelUnpackData::Slice(Some(&bytes)),
                );
                self.uploaded = Some(id);
            }
            gl.bind_framebuffer(glow::FRAMEBUFFER, None);
            gl.viewport(0, 0, w, h);
            gl.disable(glow::BLEND);
            gl.disable(glow::SCISSOR_TEST);
            gl.use_program(Some(self.program));
            gl.uniform_1_i32(uniform("lp_display_accumulation").as_ref(), 0);
            gl.uniform_1_f32(uniform("lp_display_inverse_frames").as_ref(), 1.0);
            gl.uniform_1_u32(uniform("lp_display_operator").as_ref(), display.tone_map.kernel_id());
            gl.uniform_1_f32(uniform("lp_display_exposure_scale").as_ref(), display.exposure.exp2());
            gl.bind_vertex_array(Some(self.vertex_array));
            gl.draw_arrays(glow::TRIANGLES, 0, 3);
            gl.bind_vertex_array(None);
            gl.bind_texture(glow::TEXTURE_2D, None);
            gl.use_program(None);
        }
    }

    /// Deletes the objects; `gl` must be the context they were created on.
    pub fn delete(self, gl: &glow::Context) {
        // SAFETY: created on `gl`, deleted once (self is consumed).
        unsafe {
            gl.delete_program(self.program);
            gl.delete_vertex_array(self.vertex_array);
            gl.delete_texture(self.texture);
        }
    }
}

/// The WebGPU pass: the display shader's pipeline over a storage buffer holding the image
/// (row 0 at the top, as the accumulation buffer it was written for).
pub struct GpuImageDisplay {
    pipeline: wgpu::RenderPipeline,
    layout: wgpu::BindGroupLayout,
    uniform: wgpu::Buffer,
    /// The image's pixels and which image they are.
    pixels: Option<(wgpu::Buffer, u64)>,
}

impl GpuImageDisplay {
    pub fn new(device: &wgpu::Device, format: wgpu::TextureFormat) -> Result<Self, String> {
        let source = tracer::backend::wgpu::display_shader().map_err(|e| e.to_string())?;
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("lightport denoised display"),
            source: wgpu::ShaderSource::Wgsl(Cow::Owned(source)),
        });
        let entry = |binding, ty| wgpu::BindGroupLayoutEntry {
            binding,
            visibility: wgpu::ShaderStages::FRAGMENT,
            ty: wgpu::BindingType::Buffer { ty, has_dynamic_offset: false, min_binding_size: None },
            count: None,
        };
        let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("lightport denoised display"),
            entries: &[
                entry(0, wgpu::BufferBindingType::Storage { read_only: true }),
                entry(1, wgpu::BufferBindingType::Uniform),
            ],
        });
        let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("lightport denoised display"),
            bind_group_layouts: &[Some(&layout)],
            immediate_size: 0,
        });
        let pipeline = device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
            label: Some("lightport denoised display"),
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
        let uniform = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("lightport denoised display uniforms"),
            size: 16,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        Ok(GpuImageDisplay { pipeline, layout, uniform, pixels: None })
    }

    /// Draws `image` (known to the caller as `id`: uploaded again only when it changes) through
    /// `display` into `target`.
    pub fn draw(
        &mut self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        target: &wgpu::TextureView,
        image: &Image,
        id: u64,
        display: &Display,
    ) {
        if self.pixels.as_ref().is_none_or(|(_, uploaded)| *uploaded != id) {
            let buffer = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some("lightport denoised image"),
                contents: &rgba_bytes(&image.pixels),
                usage: wgpu::BufferUsages::STORAGE,
            });
            self.pixels = Some((buffer, id));
        }
        let Some((pixels, _)) = &self.pixels else { return };
        let words: [u32; 4] =
            [image.width, 1.0f32.to_bits(), display.tone_map.kernel_id(), display.exposure.exp2().to_bits()];
        let bytes: Vec<u8> = words.iter().flat_map(|w| w.to_le_bytes()).collect();
        queue.write_buffer(&self.uniform, 0, &bytes);
        let group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("lightport denoised display"),
            layout: &self.layout,
            entries: &[
                wgpu::BindGroupEntry { binding: 0, resource: pixels.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 1, resource: self.uniform.as_entire_binding() },
            ],
        });
        let mut encoder = device.create_command_encoder(&Default::default());
        {
            let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
                label: Some("lightport denoised display"),
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
