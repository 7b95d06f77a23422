//! [`GlFilter`]: the denoiser's à-trous passes as fragment passes. The kernel's
//! `denoise::atrous_pixel`, generated as an image pass (`shaders-generated/denoise_pass.frag.glsl`),
//! is drawn once per pass into an RGBA32F framebuffer the size of the image; each pass's output
//! texture is the next pass's `filter_image_color`, so the image stays on the GPU until the last
//! pass is read back.
//!
//! The filter's texel arrays are bound as image-sized textures (width = the image's width):
//! the shader's `lp_fetch_vec4` takes the texel index `y * width + x` back to row y and column
//! x by the texture's width, so texel (x, y) is pixel (x, y), and a framebuffer the pass wrote
//! is read as an array.
//!
//! [`GlFilter::run`] waits for the output; [`GlFilter::queue`] only queues the passes behind a
//! fence ([`QueuedFilter`]), for a caller that must not block (the browser page polls the fence
//! from its frame loop and reads the output once it is signalled).

use glam::Vec4;
use glow::HasContext;
use kernel_dsl::{Resource, Resources};
use lightport_codegen::Target;

use super::targets::{image_texture, read_image, render_target, Objects};
use super::{compile_program, gl_failed, GlError};
use crate::kernel::denoise::{FilterImage, ATROUS_ITERATIONS};

/// Prefix of every `FilterImage` field's uniform in the generated GLSL.
const FILTER_UNIFORM_PREFIX: &str = "filter_image_";

/// The filter pass's program on a context.
pub struct GlFilter {
    program: glow::Program,
    vertex_array: glow::VertexArray,
}

impl GlFilter {
    /// Compiles the filter pass on `gl` (current). Every uniform the shader declares must be a
    /// `FilterImage` field of the type the field has.
    pub fn new(gl: &glow::Context) -> Result<Self, GlError> {
        let fragment = crate::kernel::denoise_pass_shader(Target::GlslEs300)?;
        let program = compile_program(gl, &fragment)?;
        // SAFETY: queries on the linked program of the current context; it is deleted on error.
        unsafe {
            let image = FilterImage::default();
            let fields = image.fields();
            for i in 0..gl.get_active_uniforms(program) {
                let Some(u) = gl.get_active_uniform(program, i) else { continue };
                let field = u.name.strip_prefix(FILTER_UNIFORM_PREFIX);
                let known = field.and_then(|f| fields.iter().find(|(n, _)| *n == f));
                if known.is_none_or(|(_, r)| super::gl_type(r) != u.utype) {
                    gl.delete_program(program);
                    let expected = " (not a FilterImage field of that type)".to_string();
                    return Err(GlError::UnboundUniform { name: u.name, gl_type: u.utype, expected });
                }
            }
            let vertex_array = match gl.create_vertex_array() {
                Ok(v) => v,
                Err(e) => {
                    gl.delete_program(program);
                    return Err(gl_failed("glCreateVertexArray")(e));
                }
            };
            Ok(GlFilter { program, vertex_array })
        }
    }

    /// `ATROUS_ITERATIONS` passes over `image` at steps 1, 2, 4, ...; the last pass's output.
    /// The image must fit the context's texture and viewport limits.
    pub fn run(&self, gl: &glow::Context, image: &FilterImage) -> Result<Vec<Vec4>, GlError> {
        self.queue(gl, image)?.read(gl)
    }

    /// [`run`](Self::run)'s passes queued and flushed behind a fence, without waiting for them.
    pub fn queue(&self, gl: &glow::Context, image: &FilterImage) -> Result<QueuedFilter, GlError> {
        let (width, height) = (image.width, image.height);
        let pixels = width as usize * height as usize;
        if image.color.len() != pixels || image.guide.len() != pixels || pixels == 0 {
            return Err(GlError::Unsupported(format!(
                "the filter image is {width}x{height} but holds {} colours and {} guides",
                image.color.len(),
                image.guide.len()
            )));
        }
        // SAFETY: plain queries on the current context.
        let (max_texture, max_viewport) = unsafe {
            let mut viewport = [0i32; 2];
            gl.get_parameter_i32_slice(glow::MAX_VIEWPORT_DIMS, &mut viewport);
            (gl.get_parameter_i32(glow::MAX_TEXTURE_SIZE).max(0) as u32, viewport[0].min(viewport[1]).max(0) as u32)
        };
        for (limit, max) in [("GL_MAX_TEXTURE_SIZE", max_texture), ("GL_MAX_VIEWPORT_DIMS", max_viewport)] {
            if width > max || height > max {
                return Err(GlError::ImageTooLarge { width, height, limit, max });
            }
        }
        let mut objects = Objects::default();
        let framebuffer = match self.passes(gl, image, &mut objects) {
            Ok(f) => f,
            Err(e) => {
                objects.delete(gl);
                return Err(e);
            }
        };
        // SAFETY: a fence and a flush on the current context. Without sync objects, no fence:
        // the read then simply waits.
        let fence = unsafe {
            let fence = gl.fence_sync(glow::SYNC_GPU_COMMANDS_COMPLETE, 0).ok();
            gl.flush();
            fence
        };
        Ok(QueuedFilter { objects, framebuffer, width, height, fence })
    }

    /// Queues the passes; the framebuffer holding the last pass's output.
    fn passes(
        &self,
        gl: &glow::Context,
        image: &FilterImage,
        objects: &mut Objects,
    ) -> Result<glow::Framebuffer, GlError> {
        let (width, height) = (image.width as i32, image.height as i32);
        let guide = image_texture(gl, image.width, image.height, image.guide.as_slice(), objects)?;
        let blank = vec![Vec4::ZERO; image.color.len()];
        let targets = [
            render_target(gl, image.width, image.height, image.color.as_slice(), objects)?,
            render_target(gl, image.width, image.height, &blank, objects)?,
        ];
        let (colors, framebuffers) = ([targets[0].0, targets[1].0], [targets[0].1, targets[1].1]);
        let location = |name: &str| {
            // SAFETY: a query on the linked program.
            unsafe { gl.get_uniform_location(self.program, &format!("{FILTER_UNIFORM_PREFIX}{name}")) }
        };
        let mut current = 0;
        // SAFETY: every object belongs to the current context; each pass reads one colour
        // texture and writes the other (no feedback loop).
        unsafe {
            gl.use_program(Some(self.program));
            // Texel arrays take texture units 0, 1, ... in declaration order.
            let mut units = Vec::new();
            for (name, field) in image.fields() {
                let at = location(name);
                match field {
                    Resource::U32(x) if name != "step" => gl.uniform_1_u32(at.as_ref(), *x),
                    Resource::Vec4s(_) => {
                        gl.uniform_1_i32(at.as_ref(), units.len() as i32);
                        units.push(name);
                    }
                    _ => {}
                }
            }
            let unit = |field: &str| units.iter().position(|n| *n == field).unwrap_or(0) as u32;
            let (color_unit, guide_unit) = (unit("color"), unit("guide"));
            gl.active_texture(glow::TEXTURE0 + guide_unit);
            gl.bind_texture(glow::TEXTURE_2D, Some(guide));
            gl.disable(glow::BLEND);
            gl.disable(glow::DEPTH_TEST);
            gl.disable(glow::SCISSOR_TEST);
            gl.viewport(0, 0, width, height);
            gl.bind_vertex_array(Some(self.vertex_array));
            let step = location("step");
            for pass in 0..ATROUS_ITERATIONS {
                gl.uniform_1_u32(step.as_ref(), 1 << pass);
                gl.active_texture(glow::TEXTURE0 + color_unit);
                gl.bind_texture(glow::TEXTURE_2D, Some(colors[current]));
                gl.bind_framebuffer(glow::FRAMEBUFFER, Some(framebuffers[1 - current]));
                gl.draw_arrays(glow::TRIANGLES, 0, 3);
                current = 1 - current;
            }
            gl.bind_vertex_array(None);
            gl.bind_framebuffer(glow::FRAMEBUFFER, None);
            gl.use_program(None);
        }
        Ok(framebuffers[current])
    }

    /// Deletes the program on `gl` (the context it was created on, current).
    pub fn delete(self, gl: &glow::Context) {
        // SAFETY: both objects were created on `gl` and are deleted once.
        unsafe {
            gl.delete_program(self.program);
            gl.delete_vertex_array(self.vertex_array);
        }
    }
}

/// Filter passes queued on a context ([`GlFilter::queue`]): their images and the fence behind
/// them. [`read`](Self::read) or [`delete`](Self::delete) it on the same context.
pub struct QueuedFilter {
    objects: Objects,
    framebuffer: glow::Framebuffer,
    width: u32,
    height: u32,
    fence: Option<glow::Fence>,
}

impl QueuedFilter {
    /// Whether the passes are done, without blocking (no fence, or a lost context: true, and
    /// [`read`](Self::read) then waits or fails).
    pub fn done(&self, gl: &glow::Context) -> bool {
        let Some(fence) = self.fence else { return true };
        // SAFETY: a zero-timeout poll of a fence of this context.
        let status = unsafe { gl.client_wait_sync(fence, 0, 0) };
        status != glow::TIMEOUT_EXPIRED
    }

    /// The last pass's output per pixel (waiting for the passes if they are not done); the
    /// objects are deleted.
    pub fn read(mut self, gl: &glow::Context) -> Result<Vec<Vec4>, GlError> {
        let output = read_image(gl, self.framebuffer, 0, self.width, self.height);
        self.release(gl);
        output
    }

    /// Deletes the objects without reading (the output is no longer wanted).
    pub fn delete(mut self, gl: &glow::Context) {
        self.release(gl);
    }

    fn release(&mut self, gl: &glow::Context) {
        if let Some(fence) = self.fence.take() {
            // SAFETY: the fence belongs to this context and is deleted once.
            unsafe { gl.delete_sync(fence) };
        }
        self.objects.delete(gl);
    }
}
