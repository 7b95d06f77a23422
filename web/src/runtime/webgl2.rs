//! The WebGL2 runtime: the native GL backend's [`GlRenderer`] on the canvas's WebGL2 context,
//! a display pass drawing the accumulation's mean to the canvas, and the fenced band pacer
//! (`tracer::backend::frame_split`) that submits each frame in bands within the time budget.

use glow::HasContext;
use tracer::backend::frame_split::{Pacer, Step};
use tracer::backend::gl::{GlOptions, GlRenderer};
use tracer::pack::Packed;
use wasm_bindgen::JsCast;
use web_sys::{HtmlCanvasElement, WebGl2RenderingContext, WebGlContextAttributes};

/// The display pass: the accumulation's mean, clamped to [0, 1] and sRGB-encoded, as
/// `tracer::output::to_srgb8` does for PNG (non-finite values show black). Accumulation row y is
/// image row y from the top; the canvas's gl_FragCoord.y counts from the bottom.
const DISPLAY_FRAGMENT_SHADER: &str = r#"#version 300 es
precision highp float;
precision highp int;
uniform highp sampler2D lp_display_accumulation;
uniform float lp_display_inverse_frames;
out vec4 lp_display_color;
void main() {
    ivec2 size = textureSize(lp_display_accumulation, 0);
    ivec2 p = ivec2(gl_FragCoord.xy);
    vec3 c = texelFetch(lp_display_accumulation, ivec2(p.x, size.y - 1 - p.y), 0).rgb * lp_display_inverse_frames;
    bvec3 finite = lessThanEqual(abs(c), vec3(3.0e38));
    c = clamp(mix(vec3(0.0), c, vec3(finite)), 0.0, 1.0);
    vec3 srgb = mix(12.92 * c, 1.055 * pow(c, vec3(1.0 / 2.4)) - 0.055, vec3(greaterThan(c, vec3(0.0031308))));
    lp_display_color = vec4(srgb, 1.0);
}
"#;

/// The display program and its uniforms, on the renderer's context.
struct DisplayPass {
    program: glow::Program,
    vertex_array: glow::VertexArray,
    accumulation: Option<glow::UniformLocation>,
    inverse_frames: Option<glow::UniformLocation>,
}

impl DisplayPass {
    fn new(gl: &glow::Context) -> Result<Self, String> {
        // SAFETY: shader and program creation on the current WebGL2 context; shaders are
        // deleted after linking, the program on failure.
        unsafe {
            let program = gl.create_program()?;
            let mut shaders = Vec::new();
            for (stage, source) in [
                (glow::VERTEX_SHADER, lightport_codegen::fullscreen_vertex_shader()),
                (glow::FRAGMENT_SHADER, DISPLAY_FRAGMENT_SHADER),
            ] {
                let shader = gl.create_shader(stage)?;
                gl.shader_source(shader, source);
                gl.compile_shader(shader);
                if !gl.get_shader_compile_status(shader) {
                    let log = gl.get_shader_info_log(shader);
                    gl.delete_shader(shader);
                    gl.delete_program(program);
                    return Err(format!("the display shader does not compile: {log}"));
                }
                gl.attach_shader(program, shader);
                shaders.push(shader);
            }
            gl.link_program(program);
            for shader in shaders {
                gl.detach_shader(program, shader);
                gl.delete_shader(shader);
            }
            if !gl.get_program_link_status(program) {
                let log = gl.get_program_info_log(program);
                gl.delete_program(program);
                return Err(format!("the display program does not link: {log}"));
            }
            let vertex_array = gl.create_vertex_array()?;
            Ok(DisplayPass {
                accumulation: gl.get_uniform_location(program, "lp_display_accumulation"),
                inverse_frames: gl.get_uniform_location(program, "lp_display_inverse_frames"),
                program,
                vertex_array,
            })
        }
    }

    fn draw(&self, renderer: &GlRenderer, width: i32, height: i32) {
        let gl = renderer.gl();
        // SAFETY: draws with objects of this context into the default framebuffer (the canvas);
        // the accumulation texture is only read.
        unsafe {
            gl.bind_framebuffer(glow::FRAMEBUFFER, None);
            gl.viewport(0, 0, width, height);
            gl.use_program(Some(self.program));
            gl.active_texture(glow::TEXTURE0);
            // The first frame after a restart, band by band; then the running mean.
            let texture = renderer.first_frame_in_progress().unwrap_or(renderer.accumulation_texture());
            gl.bind_texture(glow::TEXTURE_2D, Some(texture));
            gl.uniform_1_i32(self.accumulation.as_ref(), 0);
            gl.uniform_1_f32(self.inverse_frames.as_ref(), 1.0 / renderer.frames().max(1) as f32);
            gl.bind_vertex_array(Some(self.vertex_array));
            gl.draw_arrays(glow::TRIANGLES, 0, 3);
            gl.bind_vertex_array(None);
            gl.bind_texture(glow::TEXTURE_2D, None);
            gl.use_program(None);
        }
    }

    fn delete(self, gl: &glow::Context) {
        // SAFETY: both objects were created on `gl` and are deleted once (self is consumed).
        unsafe {
            gl.delete_program(self.program);
            gl.delete_vertex_array(self.vertex_array);
        }
    }
}

/// The WebGL2 context of `canvas` (which must not hold another kind of context).
pub fn context(canvas: &HtmlCanvasElement) -> Result<WebGl2RenderingContext, String> {
    let attributes = WebGlContextAttributes::new();
    attributes.set_antialias(false);
    attributes.set_depth(false);
    attributes.set_stencil(false);
    attributes.set_alpha(false);
    attributes.set_power_preference(web_sys::WebGlPowerPreference::HighPerformance);
    canvas
        .get_context_with_context_options("webgl2", &attributes)
        .map_err(|e| format!("creating a WebGL2 context failed: {e:?}"))?
        .ok_or_else(|| {
            "this browser or device has no WebGL2: the path tracer needs WebGL2 or WebGPU (enable hardware \
             acceleration, or try a current Chrome, Firefox or Safari)"
                .to_string()
        })?
        .dyn_into::<WebGl2RenderingContext>()
        .map_err(|_| "the canvas returned a context that is not WebGL2".to_string())
}

/// The renderer and its display pass, on one context.
pub struct GlRuntime {
    context: WebGl2RenderingContext,
    renderer: GlRenderer,
    /// Always `Some` until dropped (taken to delete it before the renderer's context goes).
    display: Option<DisplayPass>,
    /// Bands of the frame loop (`step`), one on the GPU at a time.
    pacer: Pacer,
}

impl GlRuntime {
    pub fn new(
        context: &WebGl2RenderingContext,
        packed: &Packed,
        seed: u32,
        options: &GlOptions,
        band_budget_ms: Option<f64>,
    ) -> Result<Self, String> {
        let gl = glow::Context::from_webgl2_context(context.clone());
        let renderer = GlRenderer::with_options(gl, packed.clone(), seed, options).map_err(|e| e.to_string())?;
        let display = DisplayPass::new(renderer.gl())?;
        let pacer = Pacer::new(packed.scene.height, band_budget_ms);
        Ok(GlRuntime { context: context.clone(), renderer, display: Some(display), pacer })
    }

    pub fn renderer(&self) -> &GlRenderer {
        &self.renderer
    }

    pub fn renderer_mut(&mut self) -> &mut GlRenderer {
        &mut self.renderer
    }

    pub fn pacer(&self) -> &Pacer {
        &self.pacer
    }

    pub fn context_lost(&self) -> bool {
        self.context.is_context_lost()
    }

    fn size(&self) -> (i32, i32) {
        let s = &self.renderer.packed().scene;
        (s.width as i32, s.height as i32)
    }

    /// One whole frame in one submission, then the display pass.
    pub fn frame(&mut self) -> Result<(), String> {
        // The band in flight would be timed with this whole frame.
        self.pacer.forget(self.renderer.gl());
        self.renderer.render_frame().map_err(|e| e.to_string())?;
        let (w, h) = self.size();
        if let Some(display) = &self.display {
            display.draw(&self.renderer, w, h);
        }
        Ok(())
    }

    /// The frame loop's step (see `Viewer::step`).
    pub fn step(&mut self, now_ms: f64) -> Result<Step, String> {
        let (w, h) = self.size();
        let display = self.display.as_ref();
        self.pacer
            .step(&mut self.renderer, now_ms, |renderer, frame_done| {
                // Each band of the first frame after a restart shows; later, each whole frame.
                if let (true, Some(display)) = (frame_done || renderer.frames() == 0, display) {
                    display.draw(renderer, w, h);
                }
            })
            .map_err(|e| e.to_string())
    }

    pub fn set_band_budget(&mut self, budget_ms: Option<f64>) {
        self.pacer.forget(self.renderer.gl());
        self.pacer = Pacer::new(self.renderer.packed().scene.height, budget_ms);
    }

    /// Waits for the GPU: reads one pixel of the canvas back.
    pub fn sync(&self) {
        let gl = self.renderer.gl();
        let mut pixel = [0u8; 4];
        // SAFETY: reads one RGBA8 pixel of the default framebuffer into a 4-byte buffer.
        unsafe {
            gl.bind_framebuffer(glow::FRAMEBUFFER, None);
            gl.read_pixels(0, 0, 1, 1, glow::RGBA, glow::UNSIGNED_BYTE, glow::PixelPackData::Slice(Some(&mut pixel)));
        }
    }
}

impl Drop for GlRuntime {
    fn drop(&mut self) {
        self.pacer.forget(self.renderer.gl());
        if let Some(display) = self.display.take() {
            display.delete(self.renderer.gl());
        }
    }
}
