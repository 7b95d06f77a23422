//! The function-level equivalence harness: any kernel function run on the CPU and on GL on the
//! same inputs, outputs compared word by word under a stated [`Tolerance`].
//!
//! A test states its inputs once ([`Equivalence::run`]): a slice of argument tuples and the
//! Rust call that is the reference. The CPU backend calls it; the GL backend runs codegen's
//! generated harness shader (`Selection::harness`) around the same kernel function, which
//! reads each invocation's arguments as raw 32-bit words from an RGBA32UI texture and writes
//! its results as raw words to RGBA32UI colour attachments (layout in
//! [`lightport_codegen::Harness`]). Values cross as their bits ([`Words`]), so NaN payloads,
//! -0.0 and integer bit patterns survive both ways.
//!
//! The Rust side's flattening is checked against the generated layout before anything runs:
//! same number of words, same scalar types, same struct field names in the IR's declaration
//! order. A mismatch is a [`HarnessError::Layout`], never a silent misread.
//!
//! [`GlHarness`] only needs a [`glow::Context`], so WebGL2 can reuse it (only context creation
//! differs); natively [`GlHarness::headless`] creates a surfaceless EGL context.

use std::collections::HashMap;
use std::fmt;
use std::marker::PhantomData;
use std::time::Instant;

use glam::{IVec2, IVec3, IVec4, UVec2, UVec3, UVec4, Vec2, Vec3, Vec4};
use glow::HasContext;
use lightport_codegen::types::Scalar;
use lightport_codegen::{Program, Selection, Target};
use rayon::prelude::*;

use super::gl::{compile_program, gl_failed, scene_bindings, upload_texels, words_as_bytes, words_as_bytes_mut};
use super::gl::{Binding, GlError, SCENE_UNIFORM_PREFIX};
use crate::kernel::scene_data::Scene;
use crate::kernel::ShaderError;

#[cfg(feature = "gl")]
use super::egl::HeadlessContext;

/// The sampler uniform of the generated GLSL harness holding the arguments.
pub const ARGS_UNIFORM: &str = "lp_args";

/// Where a kernel function can run.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Backend {
    /// The kernel compiled as Rust: the reference every other backend is compared with.
    Cpu,
    /// The generated GLSL ES 3.00 on a GL context (headless EGL natively).
    Gl,
}

impl fmt::Display for Backend {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Backend::Cpu => "CPU",
            Backend::Gl => "GL",
        })
    }
}

/// Why a harness run could not happen.
#[derive(Debug, thiserror::Error)]
pub enum HarnessError {
    #[error(transparent)]
    Gl(#[from] GlError),
    #[error(transparent)]
    Shader(#[from] ShaderError),
    #[error("the Rust values given for `{function}` do not follow the generated harness layout: {detail}")]
    Layout { function: String, detail: String },
    #[error("`{function}` writes {attachments} colour attachments but this GL device allows {max} ({limit})")]
    TooManyOutputs { function: String, attachments: u32, max: u32, limit: &'static str },
    #[error("`{function}` reads the scene (`{uniform}`) but no scene was set: call `set_scene` first")]
    NoScene { function: String, uniform: String },
}

// ---------------------------------------------------------------------------------------------
// Values as words.

/// A DSL value type as harness words: its layout (path and scalar type of each word, in the
/// order codegen flattens it) and its bits.
pub trait Words: Sized {
    /// Appends one [`HarnessWord`] per word, paths starting with `path`.
    fn layout(path: &str, out: &mut Vec<HarnessWord>);
    fn push_words(&self, out: &mut Vec<u32>);
    /// Reads the value from the front of `words`, advancing it. Callers check lengths against
    /// the layout first; a short slice reads zeros rather than panicking.
    fn take_words(words: &mut &[u32]) -> Self;
}

/// `path.segment` (or `segment` at the top).
#[doc(hidden)]
pub fn join(path: &str, segment: &str) -> String {
    if path.is_empty() {
        segment.to_string()
    } else {
        format!("{path}.{segment}")
    }
}

fn take_word(words: &mut &[u32]) -> u32 {
    match words.split_first() {
        Some((first, rest)) => {
            *words = rest;
            *first
        }
        None => 0,
    }
}

macro_rules! scalar_words {
    ($($ty:ty: $scalar:ident, $to:expr, $from:expr;)*) => {$(
        impl Words for $ty {
            fn layout(path: &str, out: &mut Vec<HarnessWord>) {
                out.push(HarnessWord { path: path.to_string(), scalar: Scalar::$scalar });
            }
            fn push_words(&self, out: &mut Vec<u32>) {
                let to: fn($ty) -> u32 = $to;
                out.push(to(*self));
            }
            fn take_words(words: &mut &[u32]) -> Self {
                let from: fn(u32) -> $ty = $from;
                from(take_word(words))
            }
        }
    )*};
}

scalar_words! {
    u32: U32, |x| x, |w| w;
    i32: I32, |x| x as u32, |w| w as i32;
    f32: F32, f32::to_bits, f32::from_bits;
    bool: Bool, u32::from, |w| w != 0;
}

macro_rules! vector_words {
    ($($ty:ty: $elem:ty, [$($c:ident),*];)*) => {$(
        impl Words for $ty {
            fn layout(path: &str, out: &mut Vec<HarnessWord>) {
                $(<$elem>::layout(&join(path, stringify!($c)), out);)*
            }
            fn push_words(&self, out: &mut Vec<u32>) {
                $(self.$c.push_words(out);)*
            }
            fn take_words(words: &mut &[u32]) -> Self {
                $(let $c = <$elem>::take_words(words);)*
                <$ty>::new($($c),*)
            }
        }
    )*};
}

vector_words! {
    Vec2: f32, [x, y];
    Vec3: f32, [x, y, z];
    Vec4: f32, [x, y, z, w];
    UVec2: u32, [x, y];
    UVec3: u32, [x, y, z];
    UVec4: u32, [x, y, z, w];
    IVec2: i32, [x, y];
    IVec3: i32, [x, y, z];
    IVec4: i32, [x, y, z, w];
}

impl<T: Words + Copy + Default, const N: usize> Words for [T; N] {
    fn layout(path: &str, out: &mut Vec<HarnessWord>) {
        for i in 0..N {
            T::layout(&format!("{path}[{i}]"), out);
        }
    }
    fn push_words(&self, out: &mut Vec<u32>) {
        self.iter().for_each(|x| x.push_words(out));
    }
    fn take_words(words: &mut &[u32]) -> Self {
        let mut array = [T::default(); N];
        array.iter_mut().for_each(|x| *x = T::take_words(words));
        array
    }
}

/// The layout of field `name` of a struct, its type taken from `_field` (an accessor).
#[doc(hidden)]
pub fn field_layout<S, T: Words>(_field: fn(&S) -> &T, path: &str, out: &mut Vec<HarnessWord>) {
    T::layout(path, out);
}

/// Implements [`Words`] for kernel structs, fields in the IR's declaration order. The struct
/// pattern names every field (no `..`): a new field does not compile until it is listed, and
/// a wrong order is caught by the layout check against codegen (paths carry the field names).
#[macro_export]
macro_rules! harness_struct_words {
    ($($ty:path { $($field:ident),* $(,)? })*) => {$(
        impl $crate::backend::harness::Words for $ty {
            fn layout(path: &str, out: &mut Vec<$crate::backend::harness::HarnessWord>) {
                $($crate::backend::harness::field_layout(
                    |s: &$ty| &s.$field,
                    &$crate::backend::harness::join(path, stringify!($field)),
                    out,
                );)*
            }
            fn push_words(&self, out: &mut Vec<u32>) {
                let $ty { $($field),* } = self;
                $($crate::backend::harness::Words::push_words($field, out);)*
            }
            fn take_words(words: &mut &[u32]) -> Self {
                $ty { $($field: $crate::backend::harness::Words::take_words(words)),* }
            }
        }
    )*};
}

pub use lightport_codegen::HarnessWord;

mod kernel_structs {
    use crate::kernel::camera::Ray;
    use crate::kernel::integrator::Bounce;
    use crate::kernel::intersect::TriangleHit;
    use crate::kernel::lights::LightSample;
    use crate::kernel::metal_rough::{BrdfSample, Surface};
    use crate::kernel::normal_map::NormalMapData;
    use crate::kernel::sampling::Onb;
    use crate::kernel::scene_data::{MaterialData, MetalRoughData, TriangleData};
    use crate::kernel::traverse::{Hit, NodeHits};

    harness_struct_words! {
        Ray { origin, dir }
        TriangleHit { t, u, v }
        Hit { triangle, t, u, v }
        NodeHits { t, entries }
        TriangleData { v0, v1, v2, material, light }
        MaterialData { base_color, base_texture, emission, emissive_texture }
        Onb { tangent, bitangent, normal }
        LightSample { dir, dist, radiance, pdf, delta }
        Surface { diffuse, f0, alpha, specular }
        BrdfSample { dir, pdf, weight }
        MetalRoughData { metallic, roughness, texture, specular }
        Bounce { direct, dir, pdf, weight }
        NormalMapData { texture, scale }
    }
}

/// A function's arguments or results: a tuple of [`Words`] values, element `i` being the
/// `i`-th non-resource parameter (inputs) or, for outputs, the return value followed by the
/// final value of each `&mut` parameter.
pub trait Values: Sized {
    /// One [`HarnessWord`] per word; paths start with `#i` for tuple element `i`.
    fn layout() -> Vec<HarnessWord>;
    fn push_words(&self, out: &mut Vec<u32>);
    fn take_words(words: &mut &[u32]) -> Self;
}

macro_rules! tuple_values {
    ($(($($t:ident $i:tt),*))*) => {$(
        impl<$($t: Words),*> Values for ($($t,)*) {
            fn layout() -> Vec<HarnessWord> {
                let mut out = Vec::new();
                $($t::layout(concat!("#", stringify!($i)), &mut out);)*
                out
            }
            fn push_words(&self, out: &mut Vec<u32>) {
                $(self.$i.push_words(out);)*
            }
            fn take_words(words: &mut &[u32]) -> Self {
                ($($t::take_words(words),)*)
            }
        }
    )*};
}

tuple_values! {
    (A 0)
    (A 0, B 1)
    (A 0, B 1, C 2)
    (A 0, B 1, C 2, D 3)
    (A 0, B 1, C 2, D 3, E 4)
    (A 0, B 1, C 2, D 3, E 4, F 5)
}

/// The top-level segment of a path (`origin` of `origin.x`, `#0` of `#0.x`) and the rest.
fn split_top(path: &str) -> (&str, &str) {
    match path.find(['.', '[']) {
        Some(i) => (&path[..i], &path[i..]),
        None => (path, ""),
    }
}

fn same_scalar(a: Scalar, b: Scalar) -> bool {
    let word = |s| if s == Scalar::USize { Scalar::U32 } else { s };
    word(a) == word(b)
}

/// Checks that `rust` (from [`Values::layout`]) matches `generated` (codegen's): same words,
/// same scalar types, same paths below the top level, and the same grouping into top-level
/// values (parameters / results).
pub fn check_layout(what: &str, rust: &[HarnessWord], generated: &[HarnessWord]) -> Result<(), String> {
    let describe = |l: &[HarnessWord]| l.iter().map(|w| format!("{} {:?}", w.path, w.scalar)).collect::<Vec<_>>();
    if rust.len() != generated.len() {
        return Err(format!(
            "{what}: the Rust values have {} words, the shader {} (Rust {:?}; shader {:?})",
            rust.len(),
            generated.len(),
            describe(rust),
            describe(generated)
        ));
    }
    for (i, (r, g)) in rust.iter().zip(generated).enumerate() {
        let (r_top, r_rest) = split_top(&r.path);
        let (g_top, g_rest) = split_top(&g.path);
        let same_group = i == 0 || {
            let (pr, _) = split_top(&rust[i - 1].path);
            let (pg, _) = split_top(&generated[i - 1].path);
            (pr == r_top) == (pg == g_top)
        };
        if !same_scalar(r.scalar, g.scalar) || r_rest != g_rest || !same_group {
            return Err(format!(
                "{what} word {i}: Rust `{}` ({:?}) vs shader `{}` ({:?})",
                r.path, r.scalar, g.path, g.scalar
            ));
        }
    }
    Ok(())
}

// ---------------------------------------------------------------------------------------------
// Comparison.

/// How far a float output may be from the reference. Integer and bool words must be equal.
///
/// Two floats match when their bits are equal, when both are NaN (any payload: NaN matches NaN
/// by class), or — both finite — when they are at most `ulps` representable values apart (+0
/// and -0 count as one apart), or `|a - b| <= relative * max(|a|, |b|)`, or
/// `|a - b| <= absolute`. Infinities match only themselves. With `flush_subnormals`, a
/// subnormal reference also matches a zero of either sign: GPUs may flush subnormals to zero
/// (GLSL ES 3.00 leaves their support optional; llvmpipe flushes them).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Tolerance {
    pub ulps: u32,
    pub relative: f32,
    pub absolute: f32,
    pub flush_subnormals: bool,
}

impl Tolerance {
    /// Bit-exact floats (NaN still matches NaN).
    pub const EXACT: Tolerance = Tolerance { ulps: 0, relative: 0.0, absolute: 0.0, flush_subnormals: false };

    pub const fn ulps(ulps: u32) -> Tolerance {
        Tolerance { ulps, ..Tolerance::EXACT }
    }

    /// Also accept zero where the reference is subnormal.
    pub const fn flushing_subnormals(self) -> Tolerance {
        Tolerance { flush_subnormals: true, ..self }
    }

    pub const fn with_absolute(self, absolute: f32) -> Tolerance {
        Tolerance { absolute, ..self }
    }

    pub const fn with_relative(self, relative: f32) -> Tolerance {
        Tolerance { relative, ..self }
    }

    /// Whether `got` matches the reference `want`.
    pub fn floats_match(&self, want: f32, got: f32) -> bool {
        if want.to_bits() == got.to_bits() || (want.is_nan() && got.is_nan()) {
            return true;
        }
        if !want.is_finite() || !got.is_finite() {
            return false;
        }
        if self.flush_subnormals && want.is_subnormal() && got == 0.0 {
            return true;
        }
        let diff = (want - got).abs();
        // The bounds are inclusive but a zero bound allows nothing: +0 and -0 differ by 0.0.
        ulp_distance(want, got) <= u64::from(self.ulps)
            || (self.relative > 0.0 && diff <= self.relative * want.abs().max(got.abs()))
            || (self.absolute > 0.0 && diff <= self.absolute)
    }
}

impl fmt::Display for Tolerance {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if (self.ulps, self.relative, self.absolute) == (0, 0.0, 0.0) {
            f.write_str("bit-exact")?;
        } else {
            write!(f, "{} ULP", self.ulps)?;
        }
        if self.relative > 0.0 {
            write!(f, " or relative {:e}", self.relative)?;
        }
        if self.absolute > 0.0 {
            write!(f, " or absolute {:e}", self.absolute)?;
        }
        if self.flush_subnormals {
            f.write_str(", subnormals may flush to 0")?;
        }
        Ok(())
    }
}

/// Representable f32 values between `a` and `b` (not NaN): the distance between their
/// positions on the ordered line of floats, where -0.0 and +0.0 are neighbours.
pub fn ulp_distance(a: f32, b: f32) -> u64 {
    fn position(x: f32) -> i64 {
        let bits = x.to_bits();
        let magnitude = i64::from(bits & 0x7fff_ffff);
        if bits >> 31 == 1 {
            -magnitude - 1
        } else {
            magnitude
        }
    }
    position(a).abs_diff(position(b))
}

/// One output word of one invocation that did not match.
#[derive(Clone, Debug, PartialEq)]
pub struct Mismatch {
    pub invocation: usize,
    /// The word's path in the generated layout, e.g. `return.t`.
    pub path: String,
    pub scalar: Scalar,
    pub reference: u32,
    pub got: u32,
}

impl fmt::Display for Mismatch {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let show = |w: u32| match self.scalar {
            Scalar::F32 => format!("{:e} ({w:#010x})", f32::from_bits(w)),
            Scalar::I32 => format!("{}", w as i32),
            _ => format!("{w} ({w:#x})"),
        };
        write!(f, "invocation {} `{}`: CPU {} vs {}", self.invocation, self.path, show(self.reference), show(self.got))
    }
}

/// One backend's outputs against the CPU reference.
#[derive(Clone, Debug)]
pub struct Comparison {
    pub backend: Backend,
    pub tolerance: Tolerance,
    pub invocations: usize,
    /// Invocations with at least one word out of tolerance, in order.
    pub mismatched: Vec<usize>,
    /// The first mismatching words (at most [`Comparison::EXAMPLES`]).
    pub examples: Vec<Mismatch>,
    /// The largest ULP distance among float words where both sides are finite (including
    /// those within tolerance, excluding subnormals flushed to zero where the tolerance allows
    /// it): how close the backends really are.
    pub max_ulps: u64,
    /// The largest absolute difference among the same words.
    pub max_abs: f64,
    /// Float words that are not bit-identical (but may be within tolerance).
    pub inexact_floats: usize,
}

impl Comparison {
    pub const EXAMPLES: usize = 8;

    pub fn is_equivalent(&self) -> bool {
        self.mismatched.is_empty()
    }
}

impl fmt::Display for Comparison {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "{} vs CPU: {} of {} invocations out of tolerance ({}); max {} ULP / {:e} absolute, {} float words not bit-identical",
            self.backend,
            self.mismatched.len(),
            self.invocations,
            self.tolerance,
            self.max_ulps,
            self.max_abs,
            self.inexact_floats
        )?;
        for m in &self.examples {
            write!(f, "\n  {m}")?;
        }
        Ok(())
    }
}

/// Compares `got` with `reference` (both `invocations * layout.len()` words).
pub fn compare_words(
    backend: Backend,
    layout: &[HarnessWord],
    reference: &[u32],
    got: &[u32],
    tolerance: Tolerance,
) -> Comparison {
    let per = layout.len().max(1);
    let invocations = reference.len() / per;
    let mut c = Comparison {
        backend,
        tolerance,
        invocations,
        mismatched: Vec::new(),
        examples: Vec::new(),
        max_ulps: 0,
        max_abs: 0.0,
        inexact_floats: 0,
    };
    for (i, (want, have)) in reference.chunks(per).zip(got.chunks(per)).enumerate() {
        let mut bad = false;
        for ((word, &w), &g) in layout.iter().zip(want).zip(have) {
            let ok = if word.scalar == Scalar::F32 {
                let (a, b) = (f32::from_bits(w), f32::from_bits(g));
                if w != g && !(a.is_nan() && b.is_nan()) {
                    c.inexact_floats += 1;
                    let flushed = tolerance.flush_subnormals && a.is_subnormal() && b == 0.0;
                    if a.is_finite() && b.is_finite() && !flushed {
                        c.max_ulps = c.max_ulps.max(ulp_distance(a, b));
                        c.max_abs = c.max_abs.max((f64::from(a) - f64::from(b)).abs());
                    }
                }
                tolerance.floats_match(a, b)
            } else {
                w == g
            };
            if !ok {
                bad = true;
                if c.examples.len() < Comparison::EXAMPLES {
                    c.examples.push(Mismatch {
                        invocation: i,
                        path: word.path.clone(),
                        scalar: word.scalar,
                        reference: w,
                        got: g,
                    });
                }
            }
        }
        if bad {
            c.mismatched.push(i);
        }
    }
    c
}

// ---------------------------------------------------------------------------------------------
// The GL backend.

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
    specialize: std::collections::BTreeMap<String, u32>,
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

    pub fn gl(&self) -> &glow::Context {
        &self.gl
    }

    /// Uploads `scene`'s data textures (replacing a previous scene's) for functions taking `&Scene`.
    pub fn set_scene(&mut self, scene: &Scene) -> Result<(), HarnessError> {
        self.activate()?;
        self.delete_scene();
        let mut textures = HashMap::new();
        for (name, binding) in scene_bindings(scene) {
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
    pub fn set_specialization(&mut self, specialize: std::collections::BTreeMap<String, u32>) {
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

    fn selection(&self, function: &str) -> Selection {
        Selection { specialize: self.specialize.clone(), ..Selection::harness(function) }
    }

    fn compile(&self, function: &str) -> Result<HarnessProgram, HarnessError> {
        let generated = self.program.emit(Target::GlslEs300, &self.selection(function)).map_err(ShaderError::from)?;
        #[cfg(feature = "validate")]
        lightport_codegen::validate::validate(&generated).map_err(ShaderError::from)?;
        let layout = generated.harness.clone().ok_or_else(|| HarnessError::Layout {
            function: function.to_string(),
            detail: "codegen returned no harness layout".into(),
        })?;
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
        let bindings = scene_bindings(scene);
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
                if binding.gl_type() != u.utype {
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
                    Binding::Vec4s(_) | Binding::UVec4s(_) => {
                        if let (Some(location), Some(texture)) = (location, textures.get(name)) {
                            scene_textures.push((location, *texture));
                        }
                    }
                    Binding::F32(x) => gl.uniform_1_f32(location.as_ref(), **x),
                    Binding::U32(x) => gl.uniform_1_u32(location.as_ref(), **x),
                    Binding::Vec3(v) => gl.uniform_3_f32(location.as_ref(), v.x, v.y, v.z),
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
                let mut outputs = Vec::new();
                for _ in 0..attachments {
                    let t = gl.create_texture().map_err(gl_failed("glCreateTexture (harness results)"))?;
                    textures.push(t);
                    upload_uint_texture(gl, t, columns as i32, rows as i32, None);
                    outputs.push(t);
                }
                let fb = gl.create_framebuffer().map_err(gl_failed("glCreateFramebuffer (harness)"))?;
                framebuffer = Some(fb);
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
                let mut results = Vec::new();
                gl.pixel_store_i32(glow::PACK_ALIGNMENT, 4);
                for buffer in &buffers {
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
    super::gl::set_nearest(gl);
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

// ---------------------------------------------------------------------------------------------
// Every backend at once.

/// A function's outputs on every backend and each backend's comparison with the CPU.
#[derive(Clone, Debug)]
pub struct Outcome<O> {
    pub function: String,
    /// The generated harness layout (word paths and types of inputs and outputs).
    pub layout: lightport_codegen::Harness,
    /// Outputs per backend, CPU first, one per input.
    pub outputs: Vec<(Backend, Vec<O>)>,
    /// Every non-CPU backend against the CPU.
    pub comparisons: Vec<Comparison>,
    /// Wall-clock seconds per backend (including the GL upload and readback).
    pub seconds: Vec<(Backend, f64)>,
}

impl<O> Outcome<O> {
    pub fn output(&self, backend: Backend) -> Option<&[O]> {
        self.outputs.iter().find(|(b, _)| *b == backend).map(|(_, o)| o.as_slice())
    }

    pub fn comparison(&self, backend: Backend) -> Option<&Comparison> {
        self.comparisons.iter().find(|c| c.backend == backend)
    }

    /// Whether every backend matched the CPU within the tolerance.
    pub fn is_equivalent(&self) -> bool {
        self.comparisons.iter().all(Comparison::is_equivalent)
    }
}

impl<O> fmt::Display for Outcome<O> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}:", self.function)?;
        for c in &self.comparisons {
            write!(f, "\n {c}")?;
        }
        Ok(())
    }
}

/// Runs kernel functions on every backend it was created with, comparing each with the CPU.
pub struct Equivalence {
    program: Program,
    scene: Scene,
    gl: Option<GlHarness>,
    /// Harness layouts by function, for the CPU-only case.
    layouts: HashMap<String, lightport_codegen::Harness>,
}

impl Equivalence {
    /// The tracer's kernel modules plus `extra` (e.g. a test's own `#[kernel]` module), on the
    /// CPU and each of `backends` (GL: a headless EGL context, or its error).
    pub fn new(backends: &[Backend], extra: &[kernel_dsl::ir::Module]) -> Result<Equivalence, HarnessError> {
        let mut modules = crate::kernel::modules();
        modules.extend_from_slice(extra);
        let program = Program::link(&modules).map_err(ShaderError::from)?;
        #[cfg_attr(not(feature = "gl"), allow(unused_mut))] // only the `gl` feature assigns it
        let mut gl = None;
        for backend in backends {
            match backend {
                Backend::Cpu => {}
                #[cfg(feature = "gl")]
                Backend::Gl => gl = Some(GlHarness::headless(program.clone(), GlHarnessOptions::default())?),
                #[cfg(not(feature = "gl"))]
                Backend::Gl => {
                    return Err(GlError::Unsupported(
                        "built without the `gl` feature: create the GL harness with `Equivalence::with_gl`".into(),
                    )
                    .into())
                }
            }
        }
        Ok(Equivalence { program, scene: Scene::default(), gl, layouts: HashMap::new() })
    }

    /// The CPU and an existing GL harness (e.g. on a WebGL2 context).
    pub fn with_gl(gl: GlHarness) -> Equivalence {
        Equivalence { program: gl.program.clone(), scene: Scene::default(), gl: Some(gl), layouts: HashMap::new() }
    }

    pub fn backends(&self) -> Vec<Backend> {
        let mut b = vec![Backend::Cpu];
        if self.gl.is_some() {
            b.push(Backend::Gl);
        }
        b
    }

    pub fn gl(&mut self) -> Option<&mut GlHarness> {
        self.gl.as_mut()
    }

    /// The scene that functions taking `&Scene` read, on every backend.
    pub fn set_scene(&mut self, scene: &Scene) -> Result<(), HarnessError> {
        if let Some(gl) = &mut self.gl {
            gl.set_scene(scene)?;
        }
        self.scene = scene.clone();
        Ok(())
    }

    pub fn scene(&self) -> &Scene {
        &self.scene
    }

    /// Specialises the GPU side's shaders (see [`GlHarness::set_specialization`]); the CPU runs
    /// the Rust source, which is never specialised.
    pub fn set_specialization(&mut self, specialize: std::collections::BTreeMap<String, u32>) {
        if let Some(gl) = &mut self.gl {
            gl.set_specialization(specialize);
        }
    }

    fn layout(&mut self, function: &str) -> Result<lightport_codegen::Harness, HarnessError> {
        if let Some(gl) = &mut self.gl {
            return gl.layout(function);
        }
        if let Some(l) = self.layouts.get(function) {
            return Ok(l.clone());
        }
        let generated =
            self.program.emit(Target::GlslEs300, &Selection::harness(function)).map_err(ShaderError::from)?;
        let layout = generated.harness.ok_or_else(|| HarnessError::Layout {
            function: function.to_string(),
            detail: "codegen returned no harness layout".into(),
        })?;
        self.layouts.insert(function.to_string(), layout.clone());
        Ok(layout)
    }

    /// Runs kernel function `function` on every input, on every backend: `cpu` is the Rust call
    /// (the reference; it gets the scene set with [`set_scene`](Self::set_scene)) and returns
    /// the outputs in the harness order (return value, then each `&mut` parameter's final value).
    pub fn run<I, O>(
        &mut self,
        function: &str,
        inputs: &[I],
        cpu: impl Fn(&Scene, &I) -> O + Sync,
        tolerance: Tolerance,
    ) -> Result<Outcome<O>, HarnessError>
    where
        I: Values + Sync,
        O: Values + Send,
    {
        let layout = self.layout(function)?;
        let layout_error = |detail| HarnessError::Layout { function: function.to_string(), detail };
        check_layout("inputs", &I::layout(), &layout.inputs).map_err(layout_error)?;
        check_layout("outputs", &O::layout(), &layout.outputs).map_err(layout_error)?;

        let started = Instant::now();
        let scene = &self.scene;
        let reference: Vec<O> = inputs.par_iter().map(|i| cpu(scene, i)).collect();
        let mut seconds = vec![(Backend::Cpu, started.elapsed().as_secs_f64())];
        let mut reference_words = Vec::with_capacity(inputs.len() * layout.outputs.len());
        reference.iter().for_each(|o| o.push_words(&mut reference_words));
        let mut outputs = vec![(Backend::Cpu, reference)];
        let mut comparisons = Vec::new();

        if let Some(gl) = &mut self.gl {
            let started = Instant::now();
            let mut input_words = Vec::with_capacity(inputs.len() * layout.inputs.len());
            inputs.iter().for_each(|i| i.push_words(&mut input_words));
            let words = gl.run_words(function, inputs.len(), &input_words)?;
            seconds.push((Backend::Gl, started.elapsed().as_secs_f64()));
            comparisons.push(compare_words(Backend::Gl, &layout.outputs, &reference_words, &words, tolerance));
            let mut rest = words.as_slice();
            let values = (0..inputs.len()).map(|_| O::take_words(&mut rest)).collect();
            outputs.push((Backend::Gl, values));
        }
        Ok(Outcome { function: function.to_string(), layout, outputs, comparisons, seconds })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::kernel::traverse::Hit;

    #[test]
    fn ulp_distance_counts_representable_values() {
        assert_eq!(ulp_distance(1.0, 1.0), 0);
        assert_eq!(ulp_distance(1.0, f32::from_bits(1.0f32.to_bits() + 3)), 3);
        assert_eq!(ulp_distance(0.0, -0.0), 1);
        assert_eq!(ulp_distance(f32::from_bits(1), -f32::from_bits(1)), 3);
        assert_eq!(ulp_distance(-1.0, -f32::from_bits(1.0f32.to_bits() + 2)), 2);
    }

    #[test]
    fn tolerance_rules() {
        let exact = Tolerance::EXACT;
        assert!(exact.floats_match(f32::NAN, f32::from_bits(0x7fc0_0001)), "NaN matches NaN by class");
        assert!(!exact.floats_match(0.0, -0.0), "bit-exact tells the zeros apart");
        assert!(!exact.floats_match(1.0, f32::from_bits(1.0f32.to_bits() + 1)));
        assert!(!exact.floats_match(f32::INFINITY, f32::MAX));
        assert!(!exact.floats_match(f32::NAN, 1.0));
        let two = Tolerance::ulps(2);
        assert!(two.floats_match(1.0, f32::from_bits(1.0f32.to_bits() + 2)));
        assert!(!two.floats_match(1.0, f32::from_bits(1.0f32.to_bits() + 3)));
        assert!(Tolerance::EXACT.with_absolute(1e-6).floats_match(1e-30, -1e-30));
        assert!(Tolerance::EXACT.with_relative(1e-3).floats_match(1000.0, 1000.5));
        assert!(!Tolerance::EXACT.with_relative(1e-3).floats_match(1000.0, 1002.0));
        let subnormal = f32::from_bits(5);
        assert!(!exact.floats_match(subnormal, 0.0));
        assert!(exact.flushing_subnormals().floats_match(subnormal, -0.0));
        assert!(exact.flushing_subnormals().floats_match(-subnormal, 0.0));
        assert!(!exact.flushing_subnormals().floats_match(f32::MIN_POSITIVE, 0.0), "normal numbers do not flush");
    }

    #[test]
    fn values_round_trip_through_words() {
        let v = (Hit { triangle: 7, t: -0.0, u: f32::NAN, v: 1.5 }, Vec3::new(1.0, -2.0, 3.0), -5i32, true);
        let mut words = Vec::new();
        v.push_words(&mut words);
        assert_eq!(words.len(), <(Hit, Vec3, i32, bool)>::layout().len());
        let mut rest = words.as_slice();
        let back = <(Hit, Vec3, i32, bool)>::take_words(&mut rest);
        assert!(rest.is_empty());
        assert_eq!(back.0.t.to_bits(), (-0.0f32).to_bits());
        assert!(back.0.u.is_nan());
        assert_eq!((back.0.triangle, back.0.v, back.1, back.2, back.3), (7, 1.5, v.1, -5, true));
    }

    #[test]
    fn layouts_follow_the_generated_harness() {
        let mut eq = Equivalence::new(&[Backend::Cpu], &[]).expect("links");
        let layout = eq.layout("trace_closest").expect("layout");
        check_layout("inputs", &<(Vec3, Vec3, f32)>::layout(), &layout.inputs).expect("inputs");
        check_layout("outputs", &<(Hit,)>::layout(), &layout.outputs).expect("outputs");
        // Wrong field order, type or grouping are refused with the word that differs.
        let e = check_layout("inputs", &<(Vec3, Vec3, u32)>::layout(), &layout.inputs).unwrap_err();
        assert!(e.contains("word 6"), "{e}");
        let e = check_layout("inputs", &<(Vec4, Vec2, f32)>::layout(), &layout.inputs).unwrap_err();
        assert!(e.contains("word 3"), "{e}");
        let e = check_layout("outputs", &<(u32, f32, f32, f32)>::layout(), &layout.outputs).unwrap_err();
        assert!(e.contains("word 0"), "{e}");
        let e = check_layout("outputs", &<(crate::kernel::intersect::TriangleHit,)>::layout(), &layout.outputs);
        assert!(e.unwrap_err().contains("3 words"));
        // random_float(&mut u32) -> f32: the result, then the state.
        let layout = eq.layout("random_float").expect("layout");
        check_layout("outputs", &<(f32, u32)>::layout(), &layout.outputs).expect("outputs");
        assert!(check_layout("outputs", &<(u32, f32)>::layout(), &layout.outputs).is_err());
    }

    /// Every kernel struct with a `Words` impl lists its fields as the IR declares them.
    #[test]
    fn kernel_struct_words_follow_the_ir() {
        use crate::kernel::{camera::Ray, intersect::TriangleHit, lights::LightSample, sampling::Onb};
        use crate::kernel::{scene_data::MaterialData, scene_data::TriangleData, traverse::NodeHits};
        fn top_fields<T: Words>() -> Vec<String> {
            let mut out = Vec::new();
            T::layout("", &mut out);
            let mut names: Vec<String> = out.iter().map(|w| split_top(&w.path).0.to_string()).collect();
            names.dedup();
            names
        }
        let checks: Vec<(&str, Vec<String>)> = vec![
            ("Ray", top_fields::<Ray>()),
            ("TriangleHit", top_fields::<TriangleHit>()),
            ("Hit", top_fields::<Hit>()),
            ("NodeHits", top_fields::<NodeHits>()),
            ("TriangleData", top_fields::<TriangleData>()),
            ("MaterialData", top_fields::<MaterialData>()),
            ("Onb", top_fields::<Onb>()),
            ("LightSample", top_fields::<LightSample>()),
            ("Surface", top_fields::<crate::kernel::metal_rough::Surface>()),
            ("BrdfSample", top_fields::<crate::kernel::metal_rough::BrdfSample>()),
            ("MetalRoughData", top_fields::<crate::kernel::scene_data::MetalRoughData>()),
            ("Bounce", top_fields::<crate::kernel::integrator::Bounce>()),
            ("NormalMapData", top_fields::<crate::kernel::normal_map::NormalMapData>()),
        ];
        let structs: Vec<kernel_dsl::ir::StructDef> = crate::kernel::modules()
            .into_iter()
            .flat_map(|m| m.items)
            .filter_map(|i| match i {
                kernel_dsl::ir::Item::Struct(s) if !s.resources => Some(s),
                _ => None,
            })
            .collect();
        for (name, fields) in checks {
            let s = structs.iter().find(|s| s.name == name).unwrap_or_else(|| panic!("{name} is a kernel struct"));
            let ir: Vec<String> = s.fields.iter().map(|f| f.name.clone()).collect();
            assert_eq!(fields, ir, "{name}");
        }
        assert_eq!(
            structs.len(),
            13,
            "a new kernel struct needs a Words impl here: {:?}",
            structs.iter().map(|s| &s.name).collect::<Vec<_>>()
        );
    }

    #[test]
    fn comparison_reports_mismatching_words() {
        let layout = <(Hit,)>::layout();
        let a = [3u32, 1.0f32.to_bits(), 0, 0, 4, 2.0f32.to_bits(), 0, 0];
        let mut b = a;
        b[1] = f32::from_bits(b[1]).next_up().to_bits();
        b[4] = 5;
        let c = compare_words(Backend::Gl, &layout, &a, &b, Tolerance::ulps(1));
        assert_eq!(c.mismatched, vec![1]);
        assert_eq!(c.max_ulps, 1);
        assert_eq!(c.examples[0].path, "#0.triangle");
        let c = compare_words(Backend::Gl, &layout, &a, &b, Tolerance::EXACT);
        assert_eq!(c.mismatched, vec![0, 1]);
    }
}
