//! The GL runtime of the harness: codegen's GLSL harness shader reads each invocation's
//! arguments as raw words from an RGBA32UI texture and writes its results as raw words to
//! RGBA32UI colour attachments.

use std::collections::{BTreeMap, HashMap};
use std::marker::PhantomData;

use glow::HasContext;
use lightport_codegen::{Program, Target};

use crate::backend::gl::{
    compile_program, gl_failed, gl_type, upload_texels, words_as_bytes, words_as_bytes_mut, GlError,
    SCENE_UNIFORM_PREFIX,
};
use crate::backend::harness::{generated_layout, harness_selection, Backend, HarnessError, Runtime};
use crate::kernel::scene_data::Scene;
use crate::kernel::ShaderError;
use kernel_dsl::{Resource, Resources};

#[cfg(feature = "gl")]
use crate::backend::gl::HeadlessContext;

/// The sampler uniform of the generated GLSL harness holding the arguments.
pub const ARGS_UNIFORM: &str = "lp_args";

/// Options for [`GlHarness`].
#[derive(Clone, Debug)]
pub struct GlHarnessOptions {
    /// At most this many invocations per draw call: long draws can trip a GPU watchdog, and
    /// smaller batches bound the memory of input and output textures.
    pub max_invocations_per_draw: usize,
    /// Use at most this texture/viewport size even where the device allows more (to test
    /// chunking, or to stay within WebGL2's common limits).
    pub max_texture_size: Option<u32>,
}

impl Default for GlHarnessOptions {
    fn default() -> Self {
        GlHarnessOptions { max_invocations_per_draw: 1 << 18, max_texture_size: None }
    }
}

/// Device limits the harness respects.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct GlLimits {
    /// `GL_MAX_TEXTURE_SIZE` (or the smaller option).
    pub max_texture_size: u32,
    /// `GL_MAX_VIEWPORT_DIMS`.
    pub max_viewport: [u32; 2],
    /// min(`GL_MAX_DRAW_BUFFERS`, `GL_MAX_COLOR_ATTACHMENTS`).
    pub max_attachments: u32,
    pub max_texture_units: u32,
}

/// A compiled harness program.
struct HarnessProgram {
    program: glow::Program,
    layout: lightport_codegen::Harness,
    /// (uniform location, texture) of each scene data texture the program samples.
    scene_textures: Vec<(glow::UniformLocation, glow::Texture)>,
    args_location: Option<glow::UniformLocation>,
}

/// Kernel functions on a GL context through codegen's generated harness.
///
/// A GL context is current on one thread: the harness is not `Send`.
pub struct GlHarness {
    gl: glow::Context,
    program: Program,
    options: GlHarnessOptions,
    limits: GlLimits,
    programs: HashMap<String, HarnessProgram>,
    /// What the harness shaders are specialised to (`Selection::specialize`), e.g. a packed
    /// scene's `Features::specialization`, so that a function runs as that scene's kernel has it.
    specialize: BTreeMap<String, u32>,
    /// The scene's uniforms and data textures (every texel array, uploaded once).
    scene: Option<(Scene, HashMap<&'static str, glow::Texture>)>,
    vertex_array: glow::VertexArray,
    #[cfg(feature = "gl")]
    headless: Option<HeadlessContext>,
    _not_send: PhantomData<*const ()>,
}

impl GlHarness {
    /// A harness on `gl` (current) for the functions of `program`.
    pub fn new(gl: glow::Context, program: Program, options: GlHarnessOptions) -> Result<GlHarness, HarnessError> {
        if gl.version().major < 3 {
            return Err(
                GlError::Unsupported("the harness needs OpenGL ES 3.0, WebGL2 or desktop OpenGL 3.0+".into()).into()
            );
        }
        // SAFETY: plain queries and object creation on the current context.
        let (limits, vertex_array) = unsafe {
            let mut viewport = [0i32; 2];
            gl.get_parameter_i32_slice(glow::MAX_VIEWPORT_DIMS, &mut viewport);
            let device_max = gl.get_parameter_i32(glow::MAX_TEXTURE_SIZE).max(1) as u32;
            let attachments = gl
                .get_parameter_i32(glow::MAX_DRAW_BUFFERS)
                .min(gl.get_parameter_i32(glow::MAX_COLOR_ATTACHMENTS))
                .max(1) as u32;
            let limits = GlLimits {
                max_texture_size: options.max_texture_size.map_or(device_max, |m| m.clamp(1, device_max)),
                max_viewport: [viewport[0].max(1) as u32, viewport[1].max(1) as u32],
                max_attachments: attachments,
                max_texture_units: gl.get_parameter_i32(glow::MAX_TEXTURE_IMAGE_UNITS).max(0) as u32,
            };
            (limits, gl.create_vertex_array().map_err(gl_failed("glCreateVertexArray"))?)
        };
        Ok(GlHarness {
            gl,
            program,
            options,
            limits,
            programs: HashMap::new(),
            specialize: Default::default(),
            scene: None,
            vertex_array,
            #[cfg(feature = "gl")]
            headless: None,
            _not_send: PhantomData,
        })
    }

    /// A harness on its own headless EGL context (OpenGL ES 3.0, no surface).
    #[cfg(feature = "gl")]
    pub fn headless(program: Program, options: GlHarnessOptions) -> Result<GlHarness, HarnessError> {
        let context = HeadlessContext::new().map_err(GlError::from)?;
        let gl = context.glow();
        let mut harness = GlHarness::new(gl, program, options)?;
        harness.headless = Some(context);
        Ok(harness)
    }

    fn activate(&self) -> Result<(), HarnessError> {
        #[cfg(feature = "gl")]
        if let Some(context) = &self.headless {
            if !context.is_current() {
                context.make_current().map_err(GlError::from)?;
            }
        }
        Ok(())
    }

    pub fn limits(&self) -> GlLimits {
        self.limits
    }

    /// The linked kernel program the harness shaders are generated from.
    pub fn program(&self) -> &Program {
        &self.program
    }

    pub fn gl(&self) -> &glow::Context {
        &self.gl
    }

    /// Uploads `scene`'s data textures (replacing a previous scene's) for functions taking `&Scene`.
    pub fn set_scene(&mut self, scene: &Scene) -> Result<(), HarnessError> {
        self.activate()?;
        self.delete_scene();
        let mut textures = HashMap::new();
        for (name, binding) in scene.fields() {
            if binding.texels().is_none() {
                continue;
            }
            // SAFETY: uploads on the current context; the texture is deleted with the scene.
            match unsafe { upload_texels(&self.gl, &binding, self.limits.max_texture_size, name) } {
                Ok(t) => {
                    textures.insert(name, t);
                }
                Err(e) => {
                    // SAFETY: textures created above on this context, deleted once.
                    unsafe { textures.values().for_each(|t| self.gl.delete_texture(*t)) };
                    return Err(e.into());
                }
            }
        }
        self.scene = Some((scene.clone(), textures));
        // Programs bound the previous scene's textures and uniforms: rebuild them on next use.
        self.delete_programs();
        Ok(())
    }

    /// Specialises the harness shaders from now on as `Selection::specialize` does the kernel's
    /// (e.g. `packed.features.specialization()`: the scene's traversal stack size and flags).
    pub fn set_specialization(&mut self, specialize: BTreeMap<String, u32>) {
        if self.specialize != specialize {
            self.specialize = specialize;
            let _ = self.activate();
            self.delete_programs();
        }
    }

    fn delete_scene(&mut self) {
        if let Some((_, textures)) = self.scene.take() {
            // SAFETY: textures of this context, deleted once (the scene was taken).
            unsafe { textures.values().for_each(|t| self.gl.delete_texture(*t)) };
        }
    }

    fn delete_programs(&mut self) {
        for (_, p) in self.programs.drain() {
            // SAFETY: a program of this context, deleted once (drained).
            unsafe { self.gl.delete_program(p.program) };
        }
    }

    /// The generated harness layout of `function`, compiling its program on first use.
    pub fn layout(&mut self, function: &str) -> Result<lightport_codegen::Harness, HarnessError> {
        self.activate()?;
        Ok(self.program_for(function)?.layout.clone())
    }

    fn program_for(&mut self, function: &str) -> Result<&HarnessProgram, HarnessError> {
        if !self.programs.contains_key(function) {
            let compiled = self.compile(function)?;
            self.programs.insert(function.to_string(), compiled);
        }
        Ok(&self.programs[function])
    }

    fn compile(&self, function: &str) -> Result<HarnessProgram, HarnessError> {
        let generated = self
            .program
            .emit(Target::GlslEs300, &harness_selection(function, &self.specialize))
            .map_err(ShaderError::from)?;
        #[cfg(feature = "validate")]
        lightport_codegen::validate::validate(&generated).map_err(ShaderError::from)?;
        let layout = generated_layout(function, &generated)?;
        if layout.output_attachments() > self.limits.max_attachments {
            return Err(HarnessError::TooManyOutputs {
                function: function.to_string(),
                attachments: layout.output_attachments(),
                max: self.limits.max_attachments,
                limit: "GL_MAX_DRAW_BUFFERS / GL_MAX_COLOR_ATTACHMENTS",
            });
        }
        let gl = &self.gl;
        let program = compile_program(gl, &generated)?;
        let delete = |e: HarnessError| {
            // SAFETY: the program was just created on this context and is not kept.
            unsafe { gl.delete_program(program) };
            e
        };
        // Every active uniform must be the argument texture or a scene field bound here.
        let no_scene = Scene::default();
        let (scene, textures) = match &self.scene {
            Some((s, t)) => (s, Some(t)),
            None => (&no_scene, None),
        };
        let bindings = scene.fields();
        let mut scene_textures = Vec::new();
        // SAFETY: queries and uniform updates on a linked program of the current context.
        unsafe {
            gl.use_program(Some(program));
            let active: Vec<glow::ActiveUniform> =
                (0..gl.get_active_uniforms(program)).filter_map(|i| gl.get_active_uniform(program, i)).collect();
            for u in active {
                if u.name == ARGS_UNIFORM && u.utype == glow::UNSIGNED_INT_SAMPLER_2D {
                    continue;
                }
                let field = u.name.strip_prefix(SCENE_UNIFORM_PREFIX);
                let Some((name, binding)) = field.and_then(|f| bindings.iter().find(|(n, _)| *n == f)) else {
                    return Err(delete(
                        GlError::UnboundUniform { name: u.name, gl_type: u.utype, expected: String::new() }.into(),
                    ));
                };
                if gl_type(binding) != u.utype {
                    return Err(delete(
                        GlError::UnboundUniform {
                            name: u.name,
                            gl_type: u.utype,
                            expected: format!(" as that type (the Scene field is {})", binding.dsl_type()),
                        }
                        .into(),
                    ));
                }
                let Some(textures) = textures else {
                    return Err(delete(HarnessError::NoScene { function: function.to_string(), uniform: u.name }));
                };
                let location = gl.get_uniform_location(program, &u.name);
                match binding {
                    Resource::Vec4s(_) | Resource::UVec4s(_) => {
                        if let (Some(location), Some(texture)) = (location, textures.get(name)) {
                            scene_textures.push((location, *texture));
                        }
                    }
                    Resource::F32(x) => gl.uniform_1_f32(location.as_ref(), **x),
                    Resource::U32(x) => gl.uniform_1_u32(location.as_ref(), **x),
                    Resource::Vec3(v) => gl.uniform_3_f32(location.as_ref(), v.x, v.y, v.z),
                    // Not reached: `gl_type` of a compute field matches no uniform (checked
                    // above), and GLSL ES 3.00 has no storage or atomics to bind.
                    Resource::Vec4Storage(_)
                    | Resource::UVec4Storage(_)
                    | Resource::U32Storage(_)
                    | Resource::F32Storage(_)
                    | Resource::Atomics(_) => {}
                }
            }
            gl.use_program(None);
        }
        if scene_textures.len() as u32 + 1 > self.limits.max_texture_units {
            return Err(delete(
                GlError::Unsupported(format!(
                    "`{function}` samples {} textures but GL_MAX_TEXTURE_IMAGE_UNITS is {}",
                    scene_textures.len() + 1,
                    self.limits.max_texture_units
                ))
                .into(),
            ));
        }
        // SAFETY: as above.
        let args_location = unsafe { gl.get_uniform_location(program, ARGS_UNIFORM) };
        Ok(HarnessProgram { program, layout, scene_textures, args_location })
    }

    /// Runs `function` on `invocations` argument sets given as words (`input_words` per
    /// invocation, in the generated layout) and returns `output_words` per invocation.
    pub fn run_words(&mut self, function: &str, invocations: usize, input: &[u32]) -> Result<Vec<u32>, HarnessError> {
        self.activate()?;
        let limits = self.limits;
        let per_draw_option = self.options.max_invocations_per_draw.max(1);
        self.program_for(function)?;
        let p = &self.programs[function];
        let (in_words, out_words) = (p.layout.input_words as usize, p.layout.output_words as usize);
        if input.len() != invocations * in_words {
            return Err(HarnessError::Layout {
                function: function.to_string(),
                detail: format!("{} input words for {invocations} invocations of {in_words} words", input.len()),
            });
        }
        let texels = p.layout.input_texels() as usize;
        let attachments = p.layout.output_attachments() as usize;
        if texels > limits.max_texture_size as usize {
            return Err(GlError::Unsupported(format!(
                "`{function}` takes {in_words} argument words, more than one row of GL_MAX_TEXTURE_SIZE {} RGBA32UI texels holds",
                limits.max_texture_size
            ))
            .into());
        }
        // The grid: `columns` invocations per row, each `texels` wide in the input texture.
        let columns_max = (limits.max_texture_size as usize / texels).min(limits.max_viewport[0] as usize).max(1);
        let rows_max = (limits.max_texture_size.min(limits.max_viewport[1]) as usize).max(1);
        let per_draw = per_draw_option.min(columns_max * rows_max).max(1);
        let columns = per_draw.min(columns_max).min(invocations.max(1));
        let mut output = vec![0u32; invocations * out_words];
        let mut start = 0;
        while start < invocations {
            let count = per_draw.min(invocations - start);
            let rows = count.div_ceil(columns);
            let mut words = vec![0u32; columns * rows * texels * 4];
            for k in 0..count {
                let src = &input[(start + k) * in_words..(start + k + 1) * in_words];
                let dst = k * texels * 4; // (x * texels + row * columns * texels) texels of 4 words
                words[dst..dst + in_words].copy_from_slice(src);
            }
            let results = self.draw(function, columns, rows, texels, attachments, &words)?;
            for k in 0..count {
                for w in 0..out_words {
                    let (j, c) = (w / 4, w % 4);
                    output[(start + k) * out_words + w] = results[j][k * 4 + c];
                }
            }
            start += count;
        }
        Ok(output)
    }

    /// One draw over a `columns` x `rows` grid; returns each attachment's RGBA words, row-major.
    fn draw(
        &self,
        function: &str,
        columns: usize,
        rows: usize,
        texels: usize,
        attachments: usize,
        input: &[u32],
    ) -> Result<Vec<Vec<u32>>, HarnessError> {
        let gl = &self.gl;
        let p = &self.programs[function];
        let mut textures = Vec::new();
        let mut framebuffer = None;
        // SAFETY: object creation, uploads of exactly width x height RGBA32UI texels, a draw and
        // readbacks into buffers of exactly the framebuffer's size, on the current context.
        // Every object created here is deleted before returning.
        let result = unsafe {
            (|| -> Result<Vec<Vec<u32>>, HarnessError> {
                let args = gl.create_texture().map_err(gl_failed("glCreateTexture (harness arguments)"))?;
                textures.push(args);
                upload_uint_texture(gl, args, (columns * texels) as i32, rows as i32, Some(input));
                let buffers = attach_results(gl, columns, rows, attachments, &mut textures, &mut framebuffer)?;
                gl.use_program(Some(p.program));
                for (unit, (location, texture)) in p.scene_textures.iter().enumerate() {
                    gl.active_texture(glow::TEXTURE0 + unit as u32);
                    gl.bind_texture(glow::TEXTURE_2D, Some(*texture));
                    gl.uniform_1_i32(Some(location), unit as i32);
                }
                let args_unit = p.scene_textures.len() as u32;
                gl.active_texture(glow::TEXTURE0 + args_unit);
                gl.bind_texture(glow::TEXTURE_2D, Some(args));
                gl.uniform_1_i32(p.args_location.as_ref(), args_unit as i32);
                gl.viewport(0, 0, columns as i32, rows as i32);
                gl.disable(glow::BLEND);
                gl.disable(glow::DEPTH_TEST);
                gl.disable(glow::SCISSOR_TEST);
                gl.bind_vertex_array(Some(self.vertex_array));
                gl.draw_arrays(glow::TRIANGLES, 0, 3);
                gl.bind_vertex_array(None);
                gl.use_program(None);
                let results = read_results(gl, &buffers, columns, rows);
                let error = gl.get_error();
                if error != glow::NO_ERROR {
                    return Err(GlError::Gl {
                        what: "running the harness",
                        detail: format!("`{function}` on {columns}x{rows}: error {error:#06x}"),
                    }
                    .into());
                }
                Ok(results)
            })()
        };
        // SAFETY: the objects above, created on this context, deleted once.
        unsafe {
            gl.bind_framebuffer(glow::FRAMEBUFFER, None);
            if let Some(fb) = framebuffer {
                gl.delete_framebuffer(fb);
            }
            for t in textures {
                gl.delete_texture(t);
            }
        }
        result
    }
}

/// Allocates the bound-to-nothing texture `texture` as RGBA32UI `width` x `height` (NEAREST),
/// filled with `words` when given.
unsafe fn upload_uint_texture(
    gl: &glow::Context,
    texture: glow::Texture,
    width: i32,
    height: i32,
    words: Option<&[u32]>,
) {
    gl.bind_texture(glow::TEXTURE_2D, Some(texture));
    crate::backend::gl::set_nearest(gl);
    gl.pixel_store_i32(glow::UNPACK_ALIGNMENT, 4);
    gl.tex_image_2d(
        glow::TEXTURE_2D,
        0,
        glow::RGBA32UI as i32,
        width,
        height,
        0,
        glow::RGBA_INTEGER,
        glow::UNSIGNED_INT,
        glow::PixelUnpackData::Slice(words.map(words_as_bytes)),
    );
    gl.bind_texture(glow::TEXTURE_2D, None);
}

impl Drop for GlHarness {
    fn drop(&mut self) {
        if self.activate().is_ok() {
            self.delete_programs();
            self.delete_scene();
            // SAFETY: created in `new` on this context, deleted once.
            unsafe { self.gl.delete_vertex_array(self.vertex_array) };
        }
        // `headless` (declared after `gl`) is dropped after this, destroying the context.
    }
}

impl Runtime for GlHarness {
    fn as_any_mut(&mut self) -> &mut dyn std::any::Any {
        self
    }

    fn backend(&self) -> Backend {
        Backend::Gl
    }
    fn set_scene(&mut self, scene: &Scene) -> Result<(), HarnessError> {
        GlHarness::set_scene(self, scene)
    }
    fn set_specialization(&mut self, specialize: BTreeMap<String, u32>) {
        GlHarness::set_specialization(self, specialize)
    }
    fn layout(&mut self, function: &str) -> Result<lightport_codegen::Harness, HarnessError> {
        GlHarness::layout(self, function)
    }
    fn run_words(&mut self, function: &str, invocations: usize, input: &[u32]) -> Result<Vec<u32>, HarnessError> {
        GlHarness::run_words(self, function, invocations, input)
    }
}

/// `attachments` RGBA32UI result textures of `columns` x `rows` on a new framebuffer (bound),
/// recorded in `textures` and `framebuffer` for the caller to delete; their draw buffers.
///
/// # Safety
/// `gl`'s context is current.
unsafe fn attach_results(
    gl: &glow::Context,
    columns: usize,
    rows: usize,
    attachments: usize,
    textures: &mut Vec<glow::Texture>,
    framebuffer: &mut Option<glow::Framebuffer>,
) -> Result<Vec<u32>, HarnessError> {
    let mut outputs = Vec::new();
    for _ in 0..attachments {
        let t = gl.create_texture().map_err(gl_failed("glCreateTexture (harness results)"))?;
        textures.push(t);
        upload_uint_texture(gl, t, columns as i32, rows as i32, None);
        outputs.push(t);
    }
    let fb = gl.create_framebuffer().map_err(gl_failed("glCreateFramebuffer (harness)"))?;
    *framebuffer = Some(fb);
    gl.bind_framebuffer(glow::FRAMEBUFFER, Some(fb));
    let buffers: Vec<u32> = (0..attachments as u32).map(|j| glow::COLOR_ATTACHMENT0 + j).collect();
    for (j, t) in outputs.iter().enumerate() {
        gl.framebuffer_texture_2d(glow::FRAMEBUFFER, buffers[j], glow::TEXTURE_2D, Some(*t), 0);
    }
    gl.draw_buffers(&buffers);
    let status = gl.check_framebuffer_status(glow::FRAMEBUFFER);
    if status != glow::FRAMEBUFFER_COMPLETE {
        return Err(GlError::Unsupported(format!(
            "{attachments} RGBA32UI attachments of {columns}x{rows} are incomplete (status {status:#06x})"
        ))
        .into());
    }
    Ok(buffers)
}

/// The words of each draw buffer of the bound framebuffer (`columns` x `rows` RGBA32UI).
///
/// # Safety
/// `gl`'s context is current, with the framebuffer [`attach_results`] made bound.
unsafe fn read_results(gl: &glow::Context, buffers: &[u32], columns: usize, rows: usize) -> Vec<Vec<u32>> {
    let mut results = Vec::new();
    gl.pixel_store_i32(glow::PACK_ALIGNMENT, 4);
    for buffer in buffers {
        let mut words = vec![0u32; columns * rows * 4];
        gl.read_buffer(*buffer);
        gl.read_pixels(
            0,
            0,
            columns as i32,
            rows as i32,
            glow::RGBA_INTEGER,
            glow::UNSIGNED_INT,
            glow::PixelPackData::Slice(Some(words_as_bytes_mut(&mut words))),
        );
        results.push(words);
    }
    results
}
