//! [`GlRenderer`]: the kernel's fragment shader drawn into two ping-ponged RGBA32F framebuffers,
//! and the pipeline (program, data textures, framebuffers) it builds for a packed scene.

use std::marker::PhantomData;

use glam::Vec4;
use glow::HasContext;
use kernel_dsl::{Resource, Resources};
use lightport_codegen::Target;

use super::bindings::check_active_uniforms;
use super::targets::{read_image, render_targets, Objects};
#[cfg(feature = "gl")]
use super::HeadlessContext;
use super::{
    compile_program, gl_failed, upload_texels, GlError, GlFilter, GlInfo, GlOptions, ACCUMULATION_UNIFORM,
    SCENE_UNIFORM_PREFIX,
};
use crate::backend::{
    exchange_scene, frame_seed, ms_since, update_uniforms, BuildTimes, GuideSums, RenderError, Renderer, RendererInfo,
};
use crate::kernel::denoise::FilterImage;
use crate::kernel::scene_data::Scene;
use crate::pack::Packed;

/// Where a preview is drawn: RGBA32F images of its size (the kernel's outputs) and their
/// framebuffer, objects of the renderer's.
#[derive(Clone, Copy)]
struct PreviewTarget {
    width: u32,
    height: u32,
    texture: glow::Texture,
    framebuffer: glow::Framebuffer,
}

/// The state [`GlRenderer`] keeps besides its objects.
struct Pipeline {
    program: glow::Program,
    vertex_array: glow::VertexArray,
    /// (texture unit, texture) of every data texture the shader samples.
    data_textures: Vec<(u32, glow::Texture)>,
    /// The first of the texture units the accumulation textures are read on (one per output).
    accumulation_unit: u32,
    /// The running sums, ping-ponged: per side, the colour and, with the denoiser's guide, its
    /// three sums (the kernel's outputs 0..4, attachments of that side's framebuffer).
    accumulation: [Vec<glow::Texture>; 2],
    framebuffers: [glow::Framebuffer; 2],
    frame_seed_location: Option<glow::UniformLocation>,
    frame_index_location: Option<glow::UniformLocation>,
    info: GlInfo,
    /// What creating the pipeline took.
    times: BuildTimes,
}

impl Pipeline {
    /// Makes the kernel's program current with everything a draw of frame `frame` reads: the
    /// data textures, the running sums of side `current` and the frame's seed and index.
    ///
    /// # Safety
    /// The pipeline's objects must belong to `gl`, which must be current.
    unsafe fn bind_inputs(&self, gl: &glow::Context, current: usize, frame: u32, seed: u32) {
        gl.use_program(Some(self.program));
        for &(unit, texture) in &self.data_textures {
            gl.active_texture(glow::TEXTURE0 + unit);
            gl.bind_texture(glow::TEXTURE_2D, Some(texture));
        }
        for (k, &texture) in self.accumulation[current].iter().enumerate() {
            gl.active_texture(glow::TEXTURE0 + self.accumulation_unit + k as u32);
            gl.bind_texture(glow::TEXTURE_2D, Some(texture));
        }
        gl.uniform_1_u32(self.frame_seed_location.as_ref(), frame_seed(frame, seed));
        gl.uniform_1_u32(self.frame_index_location.as_ref(), frame);
        gl.disable(glow::BLEND);
        gl.disable(glow::DEPTH_TEST);
    }

    /// The kernel's full-screen triangle, into the bound framebuffer.
    ///
    /// # Safety
    /// As [`bind_inputs`](Self::bind_inputs), after it.
    unsafe fn draw(&self, gl: &glow::Context) {
        gl.bind_vertex_array(Some(self.vertex_array));
        gl.draw_arrays(glow::TRIANGLES, 0, 3);
        gl.bind_vertex_array(None);
    }
}

/// The kernel on a GL context. Create it from a [`Packed`] scene; [`render_frame`](Self::render_frame)
/// adds one sample per pixel; [`image`](Self::image) reads the mean back, as
/// [`CpuRenderer`](super::cpu::CpuRenderer) does.
///
/// A GL context is current on one thread: the renderer is not `Send`.
pub struct GlRenderer {
    gl: glow::Context,
    packed: Packed,
    seed: u32,
    frames: u32,
    objects: Objects,
    pipeline: Pipeline,
    /// Which accumulation texture holds the running sum.
    current: usize,
    /// Rows of the frame in progress already drawn ([`render_band`](Self::render_band)).
    band_row: u32,
    /// The denoiser's pass, compiled when first asked for.
    filter: Option<GlFilter>,
    /// The preview's image and framebuffer ([`render_preview`](Self::render_preview)), created
    /// at the first preview.
    preview: Option<PreviewTarget>,
    /// The EGL context this renderer created ([`headless`](Self::headless)); dropped last.
    #[cfg(feature = "gl")]
    headless: Option<HeadlessContext>,
    _not_send: PhantomData<*const ()>,
}

impl GlRenderer {
    /// A renderer on `gl` (which must be current) for `packed`; `seed` selects the random
    /// sequence, as for the CPU backend.
    pub fn new(gl: glow::Context, packed: Packed, seed: u32) -> Result<Self, GlError> {
        Self::with_options(gl, packed, seed, &GlOptions::default())
    }

    pub fn with_options(gl: glow::Context, packed: Packed, seed: u32, options: &GlOptions) -> Result<Self, GlError> {
        let mut objects = Objects::default();
        match build(&gl, &packed, options, &mut objects) {
            Ok(pipeline) => Ok(GlRenderer {
                gl,
                packed,
                seed,
                frames: 0,
                objects,
                pipeline,
                current: 0,
                band_row: 0,
                filter: None,
                preview: None,
                #[cfg(feature = "gl")]
                headless: None,
                _not_send: PhantomData,
            }),
            Err(e) => {
                objects.delete(&gl);
                Err(e)
            }
        }
    }

    /// A renderer on its own headless EGL context (OpenGL ES 3.0, no surface).
    #[cfg(feature = "gl")]
    pub fn headless(packed: Packed, seed: u32) -> Result<Self, GlError> {
        Self::headless_with_options(packed, seed, &GlOptions::default())
    }

    #[cfg(feature = "gl")]
    pub fn headless_with_options(packed: Packed, seed: u32, options: &GlOptions) -> Result<Self, GlError> {
        let context = HeadlessContext::new()?;
        let gl = context.glow();
        let mut renderer = Self::with_options(gl, packed, seed, options)?;
        renderer.headless = Some(context);
        Ok(renderer)
    }

    /// Uploads the packed scene's geometry (just taken) as new data textures.
    fn upload_geometry(&mut self) -> Result<(), GlError> {
        self.upload_arrays(Some(&Packed::GEOMETRY_ARRAYS))
    }

    /// Uploads the packed scene's arrays named in `only` (every array: `None`) as new data
    /// textures, keeps the others' textures, and sets every uniform.
    fn upload_arrays(&mut self, only: Option<&[&'static str]>) -> Result<(), GlError> {
        let packed = &self.packed;
        let max_texture_size = self.pipeline.info.max_texture_size;
        packed.arrays(max_texture_size).map_err(|reason| GlError::SceneTooLarge { max_texture_size, reason })?;
        let gl = &self.gl;
        let program = self.pipeline.program;
        let mut fresh = Objects::default();
        // SAFETY: the program was linked on this context, which is current.
        unsafe { gl.use_program(Some(program)) };
        let reuse = only.map(|upload| Reuse { textures: &self.pipeline.data_textures, upload });
        let bound = bind_scene(gl, program, &packed.scene.fields(), max_texture_size, &mut fresh, reuse);
        // SAFETY: as above.
        unsafe { gl.use_program(None) };
        let bound = match bound {
            Ok(bound) if bound.data_textures.len() == self.pipeline.data_textures.len() => bound,
            other => {
                fresh.delete(gl);
                let detail = "its arrays do not bind to the kernel's data textures".to_string();
                return Err(other.err().unwrap_or(GlError::Gl { what: "uploading a moved scene", detail }));
            }
        };
        let kept: Vec<glow::Texture> = bound.data_textures.iter().map(|&(_, t)| t).collect();
        let old: Vec<glow::Texture> =
            self.pipeline.data_textures.iter().map(|&(_, t)| t).filter(|t| !kept.contains(t)).collect();
        self.objects.textures.retain(|t| !old.contains(t));
        // SAFETY: the old data textures belong to this context and no longer to the pipeline.
        unsafe { old.iter().for_each(|&t| gl.delete_texture(t)) };
        self.objects.textures.append(&mut fresh.textures);
        self.pipeline.data_textures = bound.data_textures;
        self.pipeline.frame_seed_location = bound.frame_seed_location;
        self.pipeline.frame_index_location = bound.frame_index_location;
        Ok(())
    }

    /// Makes the renderer's own EGL context current if another one is.
    fn activate(&self) -> Result<(), GlError> {
        #[cfg(feature = "gl")]
        if let Some(context) = &self.headless {
            if !context.is_current() {
                context.make_current()?;
            }
        }
        Ok(())
    }

    pub fn gl(&self) -> &glow::Context {
        &self.gl
    }

    /// What creating the renderer took: generating the shader, compiling and linking it (GL
    /// answers the link status synchronously), uploading the data textures and creating the
    /// accumulation (the driver may still be copying the textures when this returns).
    pub fn build_times(&self) -> BuildTimes {
        self.pipeline.times
    }

    pub fn info(&self) -> &GlInfo {
        &self.pipeline.info
    }

    /// The texture holding the running sum (what [`accumulation`](Self::accumulation) reads),
    /// for a display pass that draws the converging image (the web viewer).
    pub fn accumulation_texture(&self) -> glow::Texture {
        self.pipeline.accumulation[self.current][0]
    }

    /// During the first frame after a (re)start, split into bands: the texture its bands are
    /// drawn into (the rows drawn hold one sample, the others zero), for a display pass that
    /// shows the new view band by band instead of the old one for a whole slow frame.
    pub fn first_frame_in_progress(&self) -> Option<glow::Texture> {
        (self.frames == 0 && self.band_row > 0).then_some(self.pipeline.accumulation[1 - self.current][0])
    }
}

impl GlRenderer {
    /// A preview (see [`preview`](crate::backend::preview)): one sample per pixel of the current
    /// view at `width` x `height` (at most the image's size), drawn by the same program into an
    /// image of its own, which is returned (row y = image row y from the top, as the
    /// accumulation; one sample, so its mean). Only before the accumulation's first frame
    /// (nothing of it drawn since the last restart): the pass reads the accumulation, zero
    /// then, as the running sum it adds to, and writes only the preview's image, so the
    /// accumulation is untouched. For that one draw the scene's `width` and `height` uniforms
    /// are the preview's; they are set back after it. One submission.
    pub fn render_preview(&mut self, width: u32, height: u32) -> Result<glow::Texture, RenderError> {
        let texture = self.draw_preview(width, height)?;
        // SAFETY: a plain query on this renderer's context, current since the draw.
        let error = unsafe { self.gl.get_error() };
        if error != glow::NO_ERROR {
            let detail = format!("{width}x{height}: error {error:#06x}");
            return Err(GlError::Gl { what: "drawing a preview", detail }.into());
        }
        Ok(texture)
    }

    /// A 1x1 preview handed to the driver without waiting for anything (no error query: in a
    /// browser each is a round trip to the GPU process, which would wait for the draw): a
    /// driver that compiles a program at its first draw (SwiftShader) compiles the kernel then,
    /// while the caller goes on. For a renderer of `Packed::placeholder` before it takes its
    /// scene (`Renderer::take_scene`). Before the accumulation's first frame only, as
    /// [`render_preview`](Self::render_preview).
    pub fn warm_up(&mut self) -> Result<(), RenderError> {
        self.draw_preview(1, 1)?;
        // A fence makes ANGLE submit the draw to its Vulkan driver, where SwiftShader compiles
        // the program (a flush alone did not: the compile then waited for the next
        // synchronising call, after the decode). Nothing waits for it.
        // SAFETY: plain calls on this renderer's context, current since the draw; the fence is
        // deleted once made.
        unsafe {
            let fence = self.gl.fence_sync(glow::SYNC_GPU_COMMANDS_COMPLETE, 0);
            self.gl.flush();
            if let Ok(fence) = fence {
                self.gl.delete_sync(fence);
            }
        }
        Ok(())
    }

    /// [`render_preview`](Self::render_preview) without its error check.
    fn draw_preview(&mut self, width: u32, height: u32) -> Result<glow::Texture, RenderError> {
        if self.frames != 0 || self.band_row != 0 {
            return Err(RenderError::Unsupported {
                runtime: "gl",
                what: "renders a preview only before the accumulation's first frame (after a restart)",
            });
        }
        self.activate()?;
        let (full_width, full_height) = (self.packed.scene.width, self.packed.scene.height);
        let (width, height) = (width.clamp(1, full_width), height.clamp(1, full_height));
        let target = match self.preview {
            Some(t) if (t.width, t.height) == (width, height) => t,
            _ => {
                let outputs = self.pipeline.accumulation[0].len();
                let (textures, framebuffer) = render_targets(&self.gl, width, height, outputs, &mut self.objects)?;
                let target = PreviewTarget { width, height, texture: textures[0], framebuffer };
                self.preview = Some(target);
                target
            }
        };
        let gl = &self.gl;
        let p = &self.pipeline;
        // SAFETY: every object belongs to this context, which is current; the draw reads the
        // accumulation textures (zero: no frame since the restart) and writes the preview's.
        unsafe {
            p.bind_inputs(gl, self.current, 0, self.seed);
            let size_locations = ["width", "height"]
                .map(|name| gl.get_uniform_location(p.program, &format!("{SCENE_UNIFORM_PREFIX}{name}")));
            let [Some(width_location), Some(height_location)] = &size_locations else {
                gl.use_program(None);
                return Err(RenderError::Unsupported {
                    runtime: "gl",
                    what: "has no image size uniforms to preview with",
                });
            };
            gl.uniform_1_u32(Some(width_location), width);
            gl.uniform_1_u32(Some(height_location), height);
            gl.bind_framebuffer(glow::FRAMEBUFFER, Some(target.framebuffer));
            gl.viewport(0, 0, width as i32, height as i32);
            gl.disable(glow::SCISSOR_TEST);
            p.draw(gl);
            gl.bind_framebuffer(glow::FRAMEBUFFER, None);
            gl.uniform_1_u32(Some(width_location), full_width);
            gl.uniform_1_u32(Some(height_location), full_height);
            gl.use_program(None);
        }
        Ok(target.texture)
    }

    /// The last preview's pixels (one sample each, row-major from the top).
    pub fn read_preview(&self) -> Result<Vec<Vec4>, RenderError> {
        let Some(target) = self.preview else {
            return Err(RenderError::Unsupported { runtime: "gl", what: "has rendered no preview" });
        };
        self.activate()?;
        Ok(read_image(&self.gl, target.framebuffer, 0, target.width, target.height)?)
    }
}

impl Renderer for GlRenderer {
    fn describe(&self) -> RendererInfo {
        let info = &self.pipeline.info;
        RendererInfo {
            runtime: "gl",
            device: format!("{} ({})", info.renderer, info.version),
            limits: vec![("GL_MAX_TEXTURE_SIZE", info.max_texture_size as u64)],
        }
    }

    fn frames(&self) -> u32 {
        self.frames
    }

    fn packed(&self) -> &Packed {
        &self.packed
    }

    fn rows_left(&self) -> u32 {
        self.packed.scene.height - self.band_row
    }

    /// Draws the next `rows` rows (kernel rows from the top, clamped to those left) of the
    /// current frame: the same fragment pass as a whole frame, over a scissor rectangle, so the
    /// pixels and their random sequence are the unsplit frame's. The sample count advances, and
    /// [`accumulation`](Self::accumulation) and [`image`](Self::image) show the new sample,
    /// when the last row is drawn: returns whether this band completed the frame. See
    /// [`frame_split`](super::frame_split).
    fn render_band(&mut self, rows: u32) -> Result<bool, RenderError> {
        self.activate()?;
        let gl = &self.gl;
        let p = &self.pipeline;
        let (width, height) = (self.packed.scene.width as i32, self.packed.scene.height as i32);
        let rows = rows.clamp(1, self.rows_left()) as i32;
        // SAFETY: every object belongs to this context, which is current; the draw reads the
        // textures bound here and writes the other accumulation texture (no feedback loop).
        unsafe {
            p.bind_inputs(gl, self.current, self.frames, self.seed);
            gl.bind_framebuffer(glow::FRAMEBUFFER, Some(p.framebuffers[1 - self.current]));
            gl.viewport(0, 0, width, height);
            // Framebuffer row y is kernel row y (gl_FragCoord is unchanged by the scissor).
            gl.enable(glow::SCISSOR_TEST);
            gl.scissor(0, self.band_row as i32, width, rows);
            p.draw(gl);
            gl.disable(glow::SCISSOR_TEST);
            gl.bind_framebuffer(glow::FRAMEBUFFER, None);
        }
        self.band_row += rows as u32;
        if self.band_row < height as u32 {
            return Ok(false);
        }
        self.band_row = 0;
        self.current = 1 - self.current;
        self.frames += 1;
        Ok(true)
    }

    /// `glFinish`.
    fn finish(&self) -> Result<(), RenderError> {
        self.activate()?;
        // SAFETY: a plain synchronisation call on the current context.
        unsafe { self.gl.finish() };
        Ok(())
    }

    fn accumulation(&self) -> Result<Vec<Vec4>, RenderError> {
        self.activate()?;
        let scene = &self.packed.scene;
        Ok(read_image(&self.gl, self.pipeline.framebuffers[self.current], 0, scene.width, scene.height)?)
    }

    fn guide_sums(&self) -> Result<GuideSums, RenderError> {
        if self.pipeline.accumulation[0].len() < 4 {
            return Err(RenderError::NoGuide);
        }
        self.activate()?;
        let scene = &self.packed.scene;
        let framebuffer = self.pipeline.framebuffers[self.current];
        let read = |k| read_image(&self.gl, framebuffer, k, scene.width, scene.height);
        Ok([read(1)?, read(2)?, read(3)?])
    }

    /// Changes the scene's uniforms (camera, strategy, depth...) and restarts the accumulation,
    /// without recompiling the shader or re-uploading the data textures: an interactive camera
    /// costs nothing. Texel arrays changed by `update` are not re-uploaded; the image size
    /// cannot change (its textures are allocated at creation): that is an error.
    fn set_uniforms(&mut self, update: &mut dyn FnMut(&mut Scene)) -> Result<(), RenderError> {
        self.activate()?;
        update_uniforms(&mut self.packed.scene, update)?;
        let gl = &self.gl;
        let program = self.pipeline.program;
        // SAFETY: uniform updates on this context's linked program, which is current.
        unsafe {
            gl.use_program(Some(program));
            for (name, binding) in self.packed.scene.fields() {
                let location = gl.get_uniform_location(program, &format!("{SCENE_UNIFORM_PREFIX}{name}"));
                match binding {
                    Resource::F32(x) => gl.uniform_1_f32(location.as_ref(), *x),
                    Resource::U32(x) => gl.uniform_1_u32(location.as_ref(), *x),
                    Resource::Vec3(v) => gl.uniform_3_f32(location.as_ref(), v.x, v.y, v.z),
                    Resource::Vec4s(_) | Resource::UVec4s(_) => {}
                    // `Scene` has no storage or atomics (compute modules only, never GLSL).
                    Resource::Vec4Storage(_)
                    | Resource::UVec4Storage(_)
                    | Resource::U32Storage(_)
                    | Resource::F32Storage(_)
                    | Resource::Atomics(_) => {}
                }
            }
            gl.use_program(None);
        }
        self.restart()
    }

    /// Uploads the moved arrays (`Packed::GEOMETRY_ARRAYS`) as new data textures on the same
    /// units (the kernel variant is the same), keeps the others (textures, materials, sky) and
    /// sets every uniform; the program is kept, and nothing is copied on the host. A pose the
    /// context refuses leaves the renderer as it was.
    fn take_geometry(&mut self, mut moved: Packed) -> Result<(), RenderError> {
        self.activate()?;
        self.packed.exchange_geometry(&mut moved)?;
        if let Err(e) = self.upload_geometry() {
            // Back to the geometry the textures hold (the exchange was just checked).
            let _ = self.packed.exchange_geometry(&mut moved);
            return Err(e.into());
        }
        self.restart()
    }

    /// Every array uploaded as new data textures (the old ones deleted) and every uniform set;
    /// the program is kept.
    fn take_scene(&mut self, mut scene: Packed) -> Result<(), RenderError> {
        self.activate()?;
        exchange_scene(&mut self.packed, &mut scene)?;
        if let Err(e) = self.upload_arrays(None) {
            // Back to the scene the textures hold (the exchange was just checked).
            let _ = self.packed.exchange_scene(&mut scene);
            return Err(e.into());
        }
        self.restart()
    }

    /// Fragment passes of the kernel's `atrous_pixel` on this renderer's context ([`GlFilter`]).
    fn denoise_passes(&mut self, image: FilterImage) -> Result<Vec<Vec4>, RenderError> {
        self.activate()?;
        if self.filter.is_none() {
            self.filter = Some(GlFilter::new(&self.gl)?);
        }
        let filter = self.filter.as_ref().expect("created above");
        Ok(filter.run(&self.gl, &image)?)
    }

    fn restart(&mut self) -> Result<(), RenderError> {
        self.activate()?;
        let gl = &self.gl;
        // SAFETY: clears this context's RGBA32F accumulation attachments with a float clear,
        // valid for float colour buffers: the one the next frame reads, and the one it writes
        // (rows a split first frame has not reached yet show zero, not an old sum).
        let error = unsafe {
            gl.disable(glow::SCISSOR_TEST);
            for framebuffer in self.pipeline.framebuffers {
                gl.bind_framebuffer(glow::FRAMEBUFFER, Some(framebuffer));
                for k in 0..self.pipeline.accumulation[0].len() as u32 {
                    gl.clear_buffer_f32_slice(glow::COLOR, k, &[0.0; 4]);
                }
            }
            gl.bind_framebuffer(glow::FRAMEBUFFER, None);
            gl.get_error()
        };
        if error != glow::NO_ERROR {
            let detail = format!("error {error:#06x}");
            return Err(GlError::Gl { what: "clearing the accumulation", detail }.into());
        }
        self.frames = 0;
        self.band_row = 0;
        Ok(())
    }
}

impl Drop for GlRenderer {
    fn drop(&mut self) {
        if self.activate().is_ok() {
            self.objects.delete(&self.gl);
            if let Some(filter) = self.filter.take() {
                filter.delete(&self.gl);
            }
        }
        // `headless` (declared after `gl`) is dropped after this, destroying the context.
    }
}

/// Whether the context can render to an RGBA32F framebuffer: desktop GL 3.0+, OpenGL ES 3.2,
/// or `EXT_color_buffer_float` (OpenGL ES 3.0/3.1, WebGL2).
fn float_render_targets(gl: &glow::Context) -> bool {
    let v = gl.version();
    let extensions = gl.supported_extensions();
    (!v.is_embedded && v.major >= 3)
        || (v.is_embedded && (v.major, v.minor) >= (3, 2))
        || extensions.contains("GL_EXT_color_buffer_float")
        || extensions.contains("EXT_color_buffer_float")
}

/// The context's version, renderer and texture limit (the smaller option's, if given), or why
/// the kernel cannot run on it; also its largest viewport side.
fn context_info(gl: &glow::Context, options: &GlOptions) -> Result<(GlInfo, u32), GlError> {
    // SAFETY: plain queries on the current context.
    let (version, renderer, device_max, viewport) = unsafe {
        let mut viewport = [0i32; 2];
        gl.get_parameter_i32_slice(glow::MAX_VIEWPORT_DIMS, &mut viewport);
        (
            gl.get_parameter_string(glow::VERSION),
            gl.get_parameter_string(glow::RENDERER),
            gl.get_parameter_i32(glow::MAX_TEXTURE_SIZE).max(0) as u32,
            viewport,
        )
    };
    let v = gl.version();
    if v.major < 3 {
        return Err(GlError::Unsupported(format!(
            "it is {version}; the kernel needs OpenGL ES 3.0, WebGL2 or desktop OpenGL 3.0+"
        )));
    }
    if !float_render_targets(gl) {
        return Err(GlError::Unsupported(format!(
            "{version} ({renderer}) cannot render to RGBA32F (no EXT_color_buffer_float), which the accumulation needs"
        )));
    }
    let max_texture_size = options.max_texture_size.map_or(device_max, |m| m.min(device_max));
    let max_viewport = viewport[0].min(viewport[1]).max(0) as u32;
    Ok((GlInfo { version, renderer, max_texture_size }, max_viewport))
}

/// Creates the program, textures and framebuffers for `packed`, recording each object in
/// `objects` (deleted by the caller on error).
fn build(gl: &glow::Context, packed: &Packed, options: &GlOptions, objects: &mut Objects) -> Result<Pipeline, GlError> {
    let (info, max_viewport) = context_info(gl, options)?;
    let max_texture_size = info.max_texture_size;
    // Limits: every packed array and the image must fit.
    packed.arrays(max_texture_size).map_err(|reason| GlError::SceneTooLarge { max_texture_size, reason })?;
    let scene = &packed.scene;
    let (width, height) = (scene.width, scene.height);
    for (limit, max) in [("GL_MAX_TEXTURE_SIZE", max_texture_size), ("GL_MAX_VIEWPORT_DIMS", max_viewport)] {
        if width > max || height > max {
            return Err(GlError::ImageTooLarge { width, height, limit, max });
        }
    }

    let started = web_time::Instant::now();
    let fragment = crate::kernel::path_tracer_shader(&packed.features, Target::GlslEs300)?;
    let codegen_ms = ms_since(started);
    let compiling = web_time::Instant::now();
    let program = compile_program(gl, &fragment)?;
    objects.programs.push(program);
    let bindings = scene.fields();
    check_active_uniforms(gl, program, &bindings)?;
    let compile_ms = ms_since(compiling);

    let uploading = web_time::Instant::now();
    // SAFETY: the program was linked on the current context.
    unsafe { gl.use_program(Some(program)) };
    let SceneBindings { data_textures, frame_seed_location, frame_index_location } =
        bind_scene(gl, program, &bindings, max_texture_size, objects, None)?;
    let accumulation_unit = data_textures.len() as u32;
    // The kernel's outputs: the colour, and with the denoiser's guide its three sums.
    let outputs = if packed.features.denoise_guide { 4 } else { 1 };
    // SAFETY: plain queries and uniform setting on the program in use.
    unsafe {
        let units = gl.get_parameter_i32(glow::MAX_TEXTURE_IMAGE_UNITS).max(0) as u32;
        if accumulation_unit + outputs > units {
            return Err(GlError::Unsupported(format!(
                "the shader samples {} textures but GL_MAX_TEXTURE_IMAGE_UNITS is {units}",
                accumulation_unit + outputs
            )));
        }
        for k in 0..outputs {
            let name = if k == 0 { ACCUMULATION_UNIFORM.to_string() } else { format!("{ACCUMULATION_UNIFORM}{k}") };
            let location = gl
                .get_uniform_location(program, &name)
                .ok_or_else(|| GlError::Unsupported(format!("the generated entry point has no `{name}` sampler")))?;
            gl.uniform_1_i32(Some(&location), (accumulation_unit + k) as i32);
        }
    }
    let (side_a, framebuffer_a) = render_targets(gl, width, height, outputs as usize, objects)?;
    let (side_b, framebuffer_b) = render_targets(gl, width, height, outputs as usize, objects)?;
    let (accumulation, framebuffers) = ([side_a, side_b], [framebuffer_a, framebuffer_b]);
    // SAFETY: object creation and queries on the current context.
    unsafe {
        let vertex_array = gl.create_vertex_array().map_err(gl_failed("glCreateVertexArray"))?;
        objects.vertex_arrays.push(vertex_array);
        gl.use_program(None);
        let error = gl.get_error();
        if error != glow::NO_ERROR {
            return Err(GlError::Gl { what: "setting up the renderer", detail: format!("error {error:#06x}") });
        }
        Ok(Pipeline {
            program,
            vertex_array,
            data_textures,
            accumulation_unit,
            accumulation,
            framebuffers,
            frame_seed_location,
            frame_index_location,
            info,
            times: BuildTimes { codegen_ms, compile_ms, upload_ms: ms_since(uploading) },
        })
    }
}

/// Uploads the `Scene` fields the program (in use) reads: each texel array as a data texture on
/// the next texture unit, each scalar as its uniform. With `reuse` (a previous binding's data
/// textures, and the arrays to upload anyway), the other arrays keep their texture.
fn bind_scene(
    gl: &glow::Context,
    program: glow::Program,
    bindings: &[(&'static str, Resource<'_>)],
    max_texture_size: u32,
    objects: &mut Objects,
    reuse: Option<Reuse<'_>>,
) -> Result<SceneBindings, GlError> {
    let mut data_textures = Vec::new();
    let (mut frame_seed_location, mut frame_index_location) = (None, None);
    for (name, binding) in bindings {
        // SAFETY: queries and uniform setting on the program in use; uploads pass slices of
        // exactly the texture's texels.
        unsafe {
            let Some(location) = gl.get_uniform_location(program, &format!("{SCENE_UNIFORM_PREFIX}{name}")) else {
                continue; // removed by specialisation
            };
            let location = Some(&location);
            match binding {
                Resource::Vec4s(_) | Resource::UVec4s(_) => {
                    let unit = data_textures.len() as u32;
                    let kept = reuse.filter(|r| !r.upload.contains(name)).map(|r| r.textures.get(unit as usize));
                    let texture = match kept {
                        Some(Some(&(_, texture))) => texture,
                        Some(None) => {
                            let detail = format!("no data texture on unit {unit} to keep for `{name}`");
                            return Err(GlError::Gl { what: "binding a moved scene", detail });
                        }
                        None => {
                            let texture = upload_texels(gl, binding, max_texture_size, name)?;
                            objects.textures.push(texture);
                            texture
                        }
                    };
                    gl.uniform_1_i32(location, unit as i32);
                    data_textures.push((unit, texture));
                }
                Resource::F32(x) => gl.uniform_1_f32(location, **x),
                Resource::U32(x) => gl.uniform_1_u32(location, **x),
                Resource::Vec3(v) => gl.uniform_3_f32(location, v.x, v.y, v.z),
                // `Scene` has no storage or atomics (compute modules only, never GLSL): a
                // uniform of that name would not be one the program declares.
                Resource::Vec4Storage(_)
                | Resource::UVec4Storage(_)
                | Resource::U32Storage(_)
                | Resource::F32Storage(_)
                | Resource::Atomics(_) => {}
            }
            match *name {
                "frame_seed" => frame_seed_location = location.cloned(),
                "frame_index" => frame_index_location = location.cloned(),
                _ => {}
            }
        }
    }
    Ok(SceneBindings { data_textures, frame_seed_location, frame_index_location })
}

/// A previous binding's data textures (by unit), kept by [`bind_scene`] except for the arrays
/// named in `upload`.
#[derive(Clone, Copy)]
struct Reuse<'a> {
    textures: &'a [(u32, glow::Texture)],
    upload: &'a [&'a str],
}

/// What [`bind_scene`] bound: the data textures by unit, and where `frame_seed` is set.
struct SceneBindings {
    data_textures: Vec<(u32, glow::Texture)>,
    frame_seed_location: Option<glow::UniformLocation>,
    frame_index_location: Option<glow::UniformLocation>,
}
