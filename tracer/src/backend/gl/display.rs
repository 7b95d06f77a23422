//! The display pass: a [`GlRenderer`]'s accumulation drawn to a framebuffer (the canvas, on
//! the web) as sRGB display values, through the kernel's own display transform
//! (`tonemap::display_srgb`, generated from the DSL), so the screen shows exactly what a PNG
//! written by the CLI with the same [`Display`] stores.

use glow::HasContext;
use lightport_codegen::{Generated, Target};

use super::{compile_program, gl_failed, GlError, GlRenderer};
use crate::backend::Renderer;
use crate::kernel::{self, ShaderError};
use crate::output::Display;

/// The display pass's entry point, appended to the generated display transform. Accumulation
/// row y is image row y from the top; `gl_FragCoord.y` counts from the framebuffer's bottom.
/// The image is stretched over the viewport (`lp_display_viewport`): a smaller image (a preview)
/// shows upscaled, each of its pixels a block; one of the viewport's size maps pixel to pixel
/// exactly ((x + 0.5) * n / n is exact in floats).
const DISPLAY_MAIN: &str = r#"
uniform highp sampler2D lp_display_accumulation;
uniform float lp_display_inverse_frames;
uniform uint lp_display_operator;
uniform float lp_display_exposure_scale;
uniform vec2 lp_display_viewport;
out vec4 lp_display_color;
void main() {
    ivec2 size = textureSize(lp_display_accumulation, 0);
    ivec2 p = min(ivec2(gl_FragCoord.xy * vec2(size) / lp_display_viewport), size - 1);
    vec3 c = texelFetch(lp_display_accumulation, ivec2(p.x, size.y - 1 - p.y), 0).rgb * lp_display_inverse_frames;
    lp_display_color = vec4(display_srgb(c, lp_display_operator, lp_display_exposure_scale), 1.0);
}
"#;

/// The display pass's GLSL ES 3.00 fragment shader (line map kept for driver logs).
pub fn display_fragment_shader() -> Result<Generated, ShaderError> {
    let mut generated = kernel::display_transform(Target::GlslEs300)?;
    generated.source.push_str(DISPLAY_MAIN);
    Ok(generated)
}

/// The display program and its uniforms, on a renderer's context.
pub struct GlDisplay {
    program: glow::Program,
    vertex_array: glow::VertexArray,
    accumulation: Option<glow::UniformLocation>,
    inverse_frames: Option<glow::UniformLocation>,
    operator: Option<glow::UniformLocation>,
    exposure_scale: Option<glow::UniformLocation>,
    viewport: Option<glow::UniformLocation>,
}

impl GlDisplay {
    /// The display program on `gl` (the renderer's context, current).
    pub fn new(gl: &glow::Context) -> Result<Self, GlError> {
        let fragment = display_fragment_shader()?;
        let program = compile_program(gl, &fragment)?;
        // SAFETY: queries on the program just linked on `gl`; it is deleted if the vertex
        // array cannot be created.
        unsafe {
            let vertex_array = match gl.create_vertex_array() {
                Ok(v) => v,
                Err(e) => {
                    gl.delete_program(program);
                    return Err(gl_failed("glGenVertexArrays")(e));
                }
            };
            Ok(GlDisplay {
                accumulation: gl.get_uniform_location(program, "lp_display_accumulation"),
                inverse_frames: gl.get_uniform_location(program, "lp_display_inverse_frames"),
                operator: gl.get_uniform_location(program, "lp_display_operator"),
                exposure_scale: gl.get_uniform_location(program, "lp_display_exposure_scale"),
                viewport: gl.get_uniform_location(program, "lp_display_viewport"),
                program,
                vertex_array,
            })
        }
    }

    /// Draws `renderer`'s image through `display` into `framebuffer` (None: the default one,
    /// the canvas on the web) over a `width` x `height` viewport. The first frame after a
    /// restart shows band by band; after it, the running mean.
    pub fn draw(
        &self,
        renderer: &GlRenderer,
        framebuffer: Option<glow::Framebuffer>,
        size: [i32; 2],
        display: &Display,
    ) {
        let texture = renderer.first_frame_in_progress().unwrap_or(renderer.accumulation_texture());
        let inverse_frames = 1.0 / renderer.frames().max(1) as f32;
        self.draw_texture(renderer.gl(), texture, framebuffer, size, inverse_frames, display);
    }

    /// Draws the RGBA32F `texture` (a running sum, or an image with `inverse_frames` 1, row y
    /// = image row y from the top) through `display` into `framebuffer` over a `width` x
    /// `height` viewport, on `gl` (the context the pass was created on). A texture smaller than
    /// the viewport (a preview) is stretched over it.
    pub fn draw_texture(
        &self,
        gl: &glow::Context,
        texture: glow::Texture,
        framebuffer: Option<glow::Framebuffer>,
        [width, height]: [i32; 2],
        inverse_frames: f32,
        display: &Display,
    ) {
        // SAFETY: draws with objects of this context into `framebuffer`; the texture is only
        // read, and every binding is reset afterwards.
        unsafe {
            gl.bind_framebuffer(glow::FRAMEBUFFER, framebuffer);
            gl.viewport(0, 0, width, height);
            gl.use_program(Some(self.program));
            gl.active_texture(glow::TEXTURE0);
            gl.bind_texture(glow::TEXTURE_2D, Some(texture));
            gl.uniform_1_i32(self.accumulation.as_ref(), 0);
            gl.uniform_1_f32(self.inverse_frames.as_ref(), inverse_frames);
            gl.uniform_1_u32(self.operator.as_ref(), display.tone_map.kernel_id());
            gl.uniform_1_f32(self.exposure_scale.as_ref(), display.exposure.exp2());
            gl.uniform_2_f32(self.viewport.as_ref(), width as f32, height as f32);
            gl.bind_vertex_array(Some(self.vertex_array));
            gl.draw_arrays(glow::TRIANGLES, 0, 3);
            gl.bind_vertex_array(None);
            gl.bind_texture(glow::TEXTURE_2D, None);
            gl.use_program(None);
            gl.bind_framebuffer(glow::FRAMEBUFFER, None);
        }
    }

    /// Deletes the program; `gl` must be the context it was created on.
    pub fn delete(self, gl: &glow::Context) {
        // SAFETY: both objects were created on `gl` and are deleted once (self is consumed).
        unsafe {
            gl.delete_program(self.program);
            gl.delete_vertex_array(self.vertex_array);
        }
    }
}
