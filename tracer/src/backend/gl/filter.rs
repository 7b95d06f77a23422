//! [`GlFilter`]: the denoiser's à-trous passes as fragment passes. The kernel's
//! `denoise::atrous_pixel`, generated as an image pass (`shaders-generated/denoise_pass.frag.glsl`),
//! is drawn once per pass into an RGBA32F framebuffer the size of the image; each pass's output
//! texture is the next pass's `filter_image_color`, so the image stays on the GPU until the last
//! pass is read back.
//!
//! The filter's texel arrays are bound as image-sized textures (width = the image's width):
//! the shader's `lp_fetch_vec4` divides the texel index `y * width + x` by the texture's width,
//! so texel (x, y) is pixel (x, y), and a framebuffer the pass wrote is read as an array.

use glam::Vec4;
use glow::HasContext;
use kernel_dsl::{Resource, Resources};
use lightport_codegen::Target;

use super::{compile_program, gl_failed, set_nearest, words_as_bytes, words_as_bytes_mut, GlError};
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
        let mut objects = PassObjects::default();
        let result = self.passes(gl, image, &mut objects);
        objects.delete(gl);
        result
    }

    fn passes(&self, gl: &glow::Context, image: &FilterImage, objects: &mut PassObjects) -> Result<Vec<Vec4>, GlError> {
        let (width, height) = (image.width as i32, image.height as i32);
        let guide = image_texture(gl, image.width, image.height, Some(image.guide.as_slice()), objects)?;
        let colors = [
            image_texture(gl, image.width, image.height, Some(image.color.as_slice()), objects)?,
            image_texture(gl, image.width, image.height, None, objects)?,
        ];
        let framebuffers = [framebuffer(gl, colors[0], objects)?, framebuffer(gl, colors[1], objects)?];
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
        read_image(gl, framebuffers[current], image.width, image.height)
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

/// The textures and framebuffers of one filter run, deleted together.
#[derive(Default)]
struct PassObjects {
    textures: Vec<glow::Texture>,
    framebuffers: Vec<glow::Framebuffer>,
}

impl PassObjects {
    fn delete(&mut self, gl: &glow::Context) {
        // SAFETY: each object was created on `gl` and is deleted once (the lists are drained).
        unsafe {
            for f in self.framebuffers.drain(..) {
                gl.delete_framebuffer(f);
            }
            for t in self.textures.drain(..) {
                gl.delete_texture(t);
            }
        }
    }
}

/// An RGBA32F texture of `width` x `height` texels, filled from `texels` (row-major) or left
/// undefined (a render target).
fn image_texture(
    gl: &glow::Context,
    width: u32,
    height: u32,
    texels: Option<&[Vec4]>,
    objects: &mut PassObjects,
) -> Result<glow::Texture, GlError> {
    let words: Option<Vec<u32>> =
        texels.map(|t| t.iter().flat_map(|texel| texel.to_array().map(f32::to_bits)).collect());
    // SAFETY: texture creation and upload on the current context; the slice holds width x
    // height RGBA floats.
    unsafe {
        let texture = gl.create_texture().map_err(gl_failed("glCreateTexture (filter image)"))?;
        objects.textures.push(texture);
        gl.bind_texture(glow::TEXTURE_2D, Some(texture));
        set_nearest(gl);
        gl.pixel_store_i32(glow::UNPACK_ALIGNMENT, 4);
        let data = glow::PixelUnpackData::Slice(words.as_deref().map(words_as_bytes));
        gl.tex_image_2d(
            glow::TEXTURE_2D,
            0,
            glow::RGBA32F as i32,
            width as i32,
            height as i32,
            0,
            glow::RGBA,
            glow::FLOAT,
            data,
        );
        let error = gl.get_error();
        gl.bind_texture(glow::TEXTURE_2D, None);
        if error != glow::NO_ERROR {
            let detail = format!("{width}x{height} RGBA32F: error {error:#06x}");
            return Err(GlError::Gl { what: "creating a filter texture", detail });
        }
        Ok(texture)
    }
}

/// A framebuffer rendering into `texture`.
fn framebuffer(
    gl: &glow::Context,
    texture: glow::Texture,
    objects: &mut PassObjects,
) -> Result<glow::Framebuffer, GlError> {
    // SAFETY: framebuffer creation on the current context, attaching one of its textures.
    unsafe {
        let framebuffer = gl.create_framebuffer().map_err(gl_failed("glCreateFramebuffer (filter)"))?;
        objects.framebuffers.push(framebuffer);
        gl.bind_framebuffer(glow::FRAMEBUFFER, Some(framebuffer));
        gl.framebuffer_texture_2d(glow::FRAMEBUFFER, glow::COLOR_ATTACHMENT0, glow::TEXTURE_2D, Some(texture), 0);
        let status = gl.check_framebuffer_status(glow::FRAMEBUFFER);
        gl.bind_framebuffer(glow::FRAMEBUFFER, None);
        if status != glow::FRAMEBUFFER_COMPLETE {
            let detail = format!("status {status:#06x}");
            return Err(GlError::Gl { what: "the filter framebuffer (RGBA32F)", detail });
        }
        Ok(framebuffer)
    }
}

/// The RGBA32F pixels of `framebuffer`, row-major.
fn read_image(
    gl: &glow::Context,
    framebuffer: glow::Framebuffer,
    width: u32,
    height: u32,
) -> Result<Vec<Vec4>, GlError> {
    let mut words = vec![0u32; width as usize * height as usize * 4];
    // SAFETY: the framebuffer belongs to the current context; the slice holds width x height
    // RGBA floats, the size glReadPixels writes with PACK_ALIGNMENT 4.
    let error = unsafe {
        gl.bind_framebuffer(glow::READ_FRAMEBUFFER, Some(framebuffer));
        gl.read_buffer(glow::COLOR_ATTACHMENT0);
        gl.pixel_store_i32(glow::PACK_ALIGNMENT, 4);
        let data = glow::PixelPackData::Slice(Some(words_as_bytes_mut(&mut words)));
        gl.read_pixels(0, 0, width as i32, height as i32, glow::RGBA, glow::FLOAT, data);
        gl.bind_framebuffer(glow::READ_FRAMEBUFFER, None);
        gl.get_error()
    };
    if error != glow::NO_ERROR {
        let detail = format!("error {error:#06x}");
        return Err(GlError::Gl { what: "glReadPixels (the filtered image)", detail });
    }
    Ok(words.chunks_exact(4).map(|t| Vec4::from_array([t[0], t[1], t[2], t[3]].map(f32::from_bits))).collect())
}
