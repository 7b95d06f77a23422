//! Kernel DSL IR → GLSL ES 3.00 and WGSL.
//!
//! [`Program::link`] takes the IR of one or more `#[kernel]` modules, resolves names across
//! them and checks the program (no recursion, no unknown names, no duplicate items). The
//! program is then emitted for a [`Target`]: each function appears in dependency order,
//! preceded by a comment naming its Rust source, with Rust names kept (renamed only where
//! they clash with a target keyword or built-in). Output is deterministic.
//!
//! Where Rust, GLSL ES 3.00 and WGSL disagree, the emitted code keeps the DSL's (Rust's)
//! meaning; the rules are listed in `docs/dsl.md` and each has an equivalence test (`tests/equivalence.rs`).
//!
//! Layout: `lib.rs` (linking), `infer.rs` (types), `lower/` (the target-independent lowering),
//! `language.rs` (the trait a target language implements), one module per language
//! (`glsl/`, `wgsl/`, the same files in each), `validate.rs` (naga and glsl-lang), `build.rs`
//! (generating and validating shaders from a build script: [`build::write_shaders`]).

#[cfg(feature = "validate")]
pub mod build;
mod glsl;
mod infer;
mod language;
mod lower;
mod names;
pub mod types;
#[cfg(feature = "validate")]
pub mod validate;
mod wgsl;

use std::collections::{BTreeMap, BTreeSet};
use std::fmt;

pub use kernel_dsl_ir as ir;

/// The shading languages codegen writes.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Target {
    /// GLSL ES 3.00 (`#version 300 es`): WebGL2, OpenGL ES 3.0+, desktop GL with ES compatibility.
    GlslEs300,
    /// WGSL, as WebGPU and wgpu take it.
    Wgsl,
}

impl Target {
    /// Every target, in a fixed order.
    pub const ALL: [Target; 2] = [Target::GlslEs300, Target::Wgsl];

    /// The language module that writes this target.
    pub(crate) fn language(self) -> &'static dyn language::Language {
        match self {
            Target::GlslEs300 => &glsl::Glsl,
            Target::Wgsl => &wgsl::Wgsl,
        }
    }

    pub fn extension(self) -> &'static str {
        match self {
            Target::GlslEs300 => "glsl",
            Target::Wgsl => "wgsl",
        }
    }
}

/// An error located in the kernel's Rust source.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub struct CodegenError {
    pub file: String,
    pub span: ir::Span,
    /// The kernel function (`module::name`) the error is in, when there is one.
    pub function: Option<String>,
    pub message: String,
}

impl fmt::Display for CodegenError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}:{}:{}: ", self.file, self.span.line, self.span.column + 1)?;
        if let Some(func) = &self.function {
            write!(f, "in kernel fn `{func}`: ")?;
        }
        write!(f, "{}", self.message)
    }
}

/// A function, struct or const of the linked program, with where it came from.
#[derive(Clone, Debug)]
pub(crate) struct Located<T> {
    pub module: String,
    pub file: String,
    pub item: T,
}

/// Kernel modules linked into one namespace.
#[derive(Clone, Debug)]
pub struct Program {
    pub(crate) modules: Vec<ir::Module>,
    pub(crate) fns: BTreeMap<String, Located<ir::FnDef>>,
    pub(crate) structs: BTreeMap<String, Located<ir::StructDef>>,
    pub(crate) consts: BTreeMap<String, Located<ir::ConstDef>>,
    /// The globals the resource structs become (`Program::resource_globals`), found once.
    pub(crate) resource_global_names: BTreeSet<String>,
}

/// What to emit: the functions asked for and everything they reach.
#[derive(Clone, Debug, Default)]
pub struct Selection {
    /// Kernel functions to emit (with their transitive callees). Empty: every function.
    pub roots: Vec<String>,
    /// Resource fields fixed at code-generation time, as `"Struct.field"` → value (u32
    /// fields). Each use becomes a literal, branches it decides are removed, and functions
    /// and resources only those branches used are not emitted: the kernel variant carries only
    /// the code a scene needs. A key without a `.` fixes an integer const (`"STACK_SIZE"`),
    /// array lengths included: the CPU keeps the Rust value, a GPU variant gets the scene's.
    pub specialize: BTreeMap<String, u32>,
    /// Also emit an entry point (`main`) around a kernel function.
    pub entry: Option<EntryPoint>,
    /// Also emit an equivalence-test harness around a kernel function (see [`Harness`]).
    pub harness: Option<String>,
    /// How the file is regenerated, for its header (`Do not edit: {regenerate}.`), e.g.
    /// "regenerate with `cargo run -- shaders`". None: the header only says not to edit it.
    pub regenerate: Option<String>,
    /// Compute entry points (WGSL only): one `main_{stage}` per stage function
    /// `fn stage(<&resources..>, invocation: u32)`, see [`Selection::compute`].
    pub compute: Vec<String>,
    /// How the runtime lays texel arrays out as GLSL data textures (WGSL reads storage
    /// buffers and ignores it).
    pub texel_rows: TexelRows,
}

/// The width of the 2D data texture a GLSL kernel reads a texel array from (texel `i` at
/// column `i mod width`, row `i / width`): what the generated `lp_fetch_*` may assume.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum TexelRows {
    /// A power of two (the renderers' scene arrays): the row is a shift and the column a mask.
    /// A JIT that inlines every call (SwiftShader, llvmpipe) copies the fetch to each of its call
    /// sites (53 in the Cornell box's variant, 128 in LittlestTokyo's), so its size is a good
    /// part of the kernel's compile time.
    #[default]
    PowerOfTwoWidth,
    /// Any width (an image pass's image-wide arrays, texel `y * width + x` at pixel (x, y)):
    /// an f32 quotient corrected once (no integer division, which SIMD drivers run lane by lane).
    AnyWidth,
}

/// Invocations per workgroup of a compute entry point ([`Selection::compute`]).
pub const COMPUTE_WORKGROUP_SIZE: u32 = 64;

/// The most workgroups a dispatch may have along one dimension (WebGPU's default
/// `maxComputeWorkgroupsPerDimension`).
pub const MAX_WORKGROUPS_PER_DIMENSION: u32 = 65_535;

/// The workgroup grid of a compute entry point's dispatch covering `invocations` invocations:
/// `[x, y, 1]` with x, y at most 65,535 and `x * y * 64 >= invocations` (invocation
/// `id.x + id.y * x * 64`; those at or beyond `invocations` run too, and the stage's own bound
/// check skips them).
pub fn dispatch_grid(invocations: u32) -> [u32; 3] {
    let groups = invocations.div_ceil(COMPUTE_WORKGROUP_SIZE);
    if groups <= MAX_WORKGROUPS_PER_DIMENSION {
        [groups, 1, 1]
    } else {
        [MAX_WORKGROUPS_PER_DIMENSION, groups.div_ceil(MAX_WORKGROUPS_PER_DIMENSION), 1]
    }
}

/// One `#[resources]` struct's bindings in generated WGSL ([`Generated::bindings`]), in
/// binding order: what a host creates buffers and bind groups from. The rule (see `docs/dsl.md`,
/// "Compute kernels"): group `#[resources(group = N)]`, bindings numbered within each group in
/// struct order; per struct its uniform block, then one read-only buffer per texel element
/// type (`vec4<f32>`, `vec4<u32>`), then one read-write buffer per storage element type
/// (`vec4<f32>`, `vec4<u32>`, `u32`, `f32`), then one read-write buffer of `atomic<u32>` for
/// all its `Atomics`. Only what the emitted code uses is bound.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ResourceBindings {
    /// The Rust struct name.
    pub resources: String,
    pub group: u32,
    pub bindings: Vec<ResourceBinding>,
}

#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ResourceBinding {
    pub binding: u32,
    /// The variable's name in WGSL (`scene`, `lp_scene_vec4f`, `lp_pool_storage_u32`,
    /// `lp_pool_atomics`).
    pub variable: String,
    pub kind: BindingKind,
    /// A uniform block: its members in order (uniform fields, then the start members of the
    /// struct's texel, storage and atomic arrays). A buffer: the arrays concatenated in it, in
    /// order; array `field` starts at element `{uniform}.lp_start_{field}`.
    pub fields: Vec<BoundField>,
}

/// What a [`ResourceBinding`] holds.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum BindingKind {
    /// `var<uniform>`: the struct's scalars and vectors and where each array starts.
    Uniform,
    /// `var<storage, read>`: the same, for the struct in bind group 0 of a module with compute
    /// stages (the wavefront's `scene`, which every stage reads). lavapipe (Mesa's Vulkan on the
    /// CPU: CI, and wgpu on machines without a GPU) specialises a shader for the values of the
    /// uniforms its branches test, and Mesa 22.3 (Debian 12) does it again each time a pipeline
    /// is bound. A megakernel binds one pipeline per pass and gains from it; a wavefront binds
    /// one per stage, 8 per iteration, and on a textured scene paid 6 ms per iteration for it
    /// (`docs/backends.md`). Storage loads are not specialised. The structs of groups 1 and up
    /// stay uniforms: WebGPU's 8 storage buffers per stage leave the wavefront no room.
    Scalars,
    /// `var<storage, read>`: `Texels<..>` arrays.
    Texels,
    /// `var<storage, read_write>`: `Storage<..>` arrays of one element type.
    Storage,
    /// `var<storage, read_write>` of `atomic<u32>`: `Atomics` arrays.
    Atomics,
}

/// A field of a resources struct in a [`ResourceBinding`].
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct BoundField {
    /// The Rust field.
    pub field: String,
    /// The DSL type: of the uniform member (`f32`, `Vec3`; `u32` for a start member), or of
    /// the array's elements in a buffer (`Vec4`, `UVec4`, `u32`, `f32`; `u32` for atomics).
    pub ty: String,
    /// In a uniform block, the member's name: the field's ([`identifier`]), or
    /// `lp_start_{field}` for where array `field` starts in its buffer (in elements). None in a
    /// buffer.
    pub member: Option<String>,
}

/// The layout of a generated equivalence-test harness: a `main` that calls one kernel
/// function per invocation on arguments read from an input buffer and writes its results.
///
/// Every value travels as 32-bit words (f32 as its bits, so NaN and -0.0 survive; i32 as its
/// two's complement; bool as 0/1), flattened field by field and component by component.
/// Inputs: the non-resource parameters in order (`&mut` parameters give their initial value).
/// Outputs: the return value, then the final value of each `&mut` parameter.
///
/// GLSL (fragment shader): invocation (x, y) of a W x H grid reads texels
/// `(x * input_texels + k, y)` of the RGBA32UI texture `lp_args` and writes output word `4j + c`
/// to component `c` of the RGBA32UI colour attachment `j` (`lp_out0`, `lp_out1`, ...).
/// WGSL (compute shader, 64 invocations per workgroup along x): invocation `i` reads
/// `lp_args[i * input_words + k]` and writes `lp_results[i * output_words + k]`, for
/// `i < lp_count.n`.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Harness {
    pub function: String,
    pub input_words: u32,
    pub output_words: u32,
    /// Every input word in order (`input_words` of them), so that a host can check that the
    /// values it flattens follow the same layout.
    pub inputs: Vec<HarnessWord>,
    /// Every output word in order (`output_words` of them).
    pub outputs: Vec<HarnessWord>,
}

/// One 32-bit word of a harness's inputs or outputs.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct HarnessWord {
    /// Where the word comes from, in Rust terms: the parameter name (or `return`), then struct
    /// fields, vector components and array indices, e.g. `origin.x`, `return.t`, `state`.
    pub path: String,
    /// How the word encodes its value (`usize` travels as a `u32`).
    pub scalar: types::Scalar,
}

impl Harness {
    /// RGBA32UI texels per invocation in the GLSL input texture.
    pub fn input_texels(&self) -> u32 {
        self.input_words.div_ceil(4).max(1)
    }

    /// Colour attachments the GLSL harness writes.
    pub fn output_attachments(&self) -> u32 {
        self.output_words.div_ceil(4).max(1)
    }
}

/// A shader entry point wrapped around a kernel function `fn(&Resources, x: u32, y: u32) -> Vec4`
/// that computes pixel (x, y)'s value: one sample added to a running sum
/// ([`PixelOutput::Accumulate`]), or the pixel of an image pass ([`PixelOutput::Write`]). An
/// accumulating function may return a struct of `Vec4` fields instead: field k is summed into
/// output k (`lp_out{k}`/`lp_accumulation{k}` in GLSL, the buffer `lp_accumulation{k}` at
/// binding k + 1 in WGSL; the first field keeps the plain names).
///
/// GLSL: a fragment shader; pixel = `gl_FragCoord.xy` (row 0 is the framebuffer's first row),
/// the output `lp_out` = the value, plus the texel of `lp_accumulation` when accumulating (w
/// counting accepted samples). A matching vertex shader is [`fullscreen_vertex_shader`].
/// WGSL: a compute shader (8 x 8 workgroups) over the rows `[lp_target.first_row,
/// lp_target.end_row)`, adding the value to the storage buffer `lp_accumulation` or storing it
/// in `lp_output` (row-major, `lp_target.width` wide; group 1, binding 0; `lp_target` binding 1).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct EntryPoint {
    pub function: String,
    pub output: PixelOutput,
}

/// What an [`EntryPoint`] does with the value its function returns for a pixel.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum PixelOutput {
    /// Add it to the pixel's running sum (a path tracer's sample).
    #[default]
    Accumulate,
    /// Store it as the pixel (an image pass, e.g. one of the denoiser's filter passes).
    Write,
}

impl Selection {
    /// Every function of the named module (and what it calls in other modules).
    pub fn module(program: &Program, module: &str) -> Selection {
        Selection {
            roots: program.fns.values().filter(|f| f.module == module).map(|f| f.item.name.clone()).collect(),
            ..Selection::default()
        }
    }

    /// A complete shader: `entry` and everything it reaches, specialised, adding each pixel's
    /// value to a running sum.
    pub fn entry(function: &str, specialize: BTreeMap<String, u32>) -> Selection {
        Selection::entry_with(function, specialize, PixelOutput::Accumulate)
    }

    /// A complete shader of one image pass: `function`'s value stored as each pixel. Its texel
    /// arrays are image-wide ([`TexelRows::AnyWidth`]).
    pub fn image_pass(function: &str, specialize: BTreeMap<String, u32>) -> Selection {
        Selection { texel_rows: TexelRows::AnyWidth, ..Selection::entry_with(function, specialize, PixelOutput::Write) }
    }

    fn entry_with(function: &str, specialize: BTreeMap<String, u32>, output: PixelOutput) -> Selection {
        Selection {
            roots: vec![function.to_string()],
            specialize,
            entry: Some(EntryPoint { function: function.to_string(), output }),
            ..Selection::default()
        }
    }

    /// Compute stages (WGSL only): each `stage` (a kernel function `fn stage(<&resources..>,
    /// invocation: u32)` without a return value) and everything it reaches, specialised, with
    /// an entry point `main_{stage}` per stage sharing one set of resource declarations. Entry
    /// `main_{stage}` runs 64-invocation workgroups ([`COMPUTE_WORKGROUP_SIZE`]) over a 2-D grid
    /// ([`dispatch_grid`]) and calls `stage(id.x + id.y * groups.x * 64)`; the stage checks its
    /// own bound (CUDA style). GLSL ES 3.00 refuses it.
    pub fn compute(stages: &[&str], specialize: BTreeMap<String, u32>) -> Selection {
        let stages: Vec<String> = stages.iter().map(|s| s.to_string()).collect();
        Selection { roots: stages.clone(), specialize, compute: stages, ..Selection::default() }
    }

    /// An equivalence-test harness around `function` and everything it reaches.
    pub fn harness(function: &str) -> Selection {
        Selection { roots: vec![function.to_string()], harness: Some(function.to_string()), ..Selection::default() }
    }
}

/// A kernel (Rust) identifier as it appears in generated code: unchanged unless some target
/// reserves it (then `_` is appended, e.g. `step` → `step_`): what a host looks up, e.g. a
/// resources struct's uniform members in WGSL.
pub fn identifier(name: &str) -> String {
    names::safe(name)
}

/// The GLSL ES 3.00 vertex shader that pairs with a fragment entry point: one triangle
/// covering the viewport, no vertex buffers.
pub fn fullscreen_vertex_shader() -> &'static str {
    glsl::fullscreen_vertex_shader()
}

/// Generated shader text with a map from its lines back to the Rust source.
#[derive(Clone, Debug)]
pub struct Generated {
    pub target: Target,
    pub source: String,
    /// The harness layout, when one was asked for.
    pub harness: Option<Harness>,
    /// (1-based output line, Rust file, Rust span, kernel fn), in output order.
    pub source_map: Vec<SourceMapEntry>,
    /// WGSL: each resources struct's bind group and bindings, in declaration order (empty for
    /// GLSL, whose resources are uniforms and samplers by name). The bindings of a pixel entry
    /// point or a harness (`lp_accumulation`, `lp_target`, `lp_args`, ..., group 1) are theirs,
    /// documented with [`EntryPoint`] and [`Harness`], and not listed here.
    pub bindings: Vec<ResourceBindings>,
}

#[derive(Clone, Debug, PartialEq, Eq)]
pub struct SourceMapEntry {
    pub line: u32,
    pub file: String,
    pub span: ir::Span,
    pub function: String,
}

impl Generated {
    /// The Rust location of generated line `line` (1-based): the closest mapped line at or
    /// before it.
    pub fn rust_location(&self, line: u32) -> Option<&SourceMapEntry> {
        self.source_map.iter().take_while(|e| e.line <= line).last()
    }
}

impl Program {
    /// Links kernel modules into one program.
    pub fn link(modules: &[ir::Module]) -> Result<Program, CodegenError> {
        let mut program = Program {
            modules: modules.to_vec(),
            fns: BTreeMap::new(),
            structs: BTreeMap::new(),
            consts: BTreeMap::new(),
            resource_global_names: BTreeSet::new(),
        };
        let mut seen: BTreeMap<String, (String, String)> = BTreeMap::new();
        for m in modules {
            for item in &m.items {
                let name = item.name().to_string();
                let span = match item {
                    ir::Item::Struct(s) => s.span,
                    ir::Item::Const(c) => c.span,
                    ir::Item::Fn(f) => f.span,
                };
                if let Some((other_mod, other_file)) = seen.get(&name) {
                    return Err(CodegenError {
                        file: m.file.clone(),
                        span,
                        function: None,
                        message: format!(
                            "`{name}` is also defined in kernel module `{other_mod}` ({other_file}): shaders have one namespace, so kernel item names must be unique across linked modules"
                        ),
                    });
                }
                seen.insert(name.clone(), (m.name.clone(), m.file.clone()));
                let (module, file) = (m.name.clone(), m.file.clone());
                match item {
                    ir::Item::Struct(s) => {
                        program.structs.insert(name, Located { module, file, item: s.clone() });
                    }
                    ir::Item::Const(c) => {
                        program.consts.insert(name, Located { module, file, item: c.clone() });
                    }
                    ir::Item::Fn(f) => {
                        program.fns.insert(name, Located { module, file, item: f.clone() });
                    }
                }
            }
        }
        for m in modules {
            for import in &m.imports {
                let module_name = import.path.last().cloned().unwrap_or_default();
                let known_module = modules.iter().any(|k| k.name == module_name);
                match &import.names {
                    None if !known_module => {
                        return Err(CodegenError {
                            file: m.file.clone(),
                            span: import.span,
                            function: None,
                            message: format!(
                                "`{}` is not a kernel module linked into this program (link it, or import only kernel modules)",
                                import.path.join("::")
                            ),
                        })
                    }
                    Some(names) => {
                        for n in names {
                            if !seen.contains_key(n) && !known_module {
                                return Err(CodegenError {
                                    file: m.file.clone(),
                                    span: import.span,
                                    function: None,
                                    message: format!(
                                        "`{}::{n}` is not a kernel item: kernels can only call kernel functions",
                                        import.path.join("::")
                                    ),
                                });
                            }
                        }
                    }
                    None => {}
                }
            }
        }
        program.resource_global_names = program.resource_globals();
        // Type-check every function now, so that errors surface at link time.
        for f in program.fns.values() {
            infer::infer_fn(&program, f)?;
        }
        program.check_no_recursion()?;
        Ok(program)
    }

    /// Whether `name` is taken program-wide: a function, struct, const or resource global, which
    /// a local binding must not shadow in the generated code.
    pub(crate) fn is_global_name(&self, name: &str) -> bool {
        self.fns.contains_key(name)
            || self.structs.contains_key(name)
            || self.consts.contains_key(name)
            || self.resource_global_names.contains(name)
    }

    /// Whether the linked module `name` is a `#[kernel(compute)]` module (storage, atomics: WGSL
    /// and the CPU only).
    pub fn is_compute_module(&self, name: &str) -> bool {
        self.modules.iter().any(|m| m.name == name && m.compute)
    }

    /// Names of the linked modules, in link order.
    pub fn module_names(&self) -> Vec<String> {
        self.modules.iter().map(|m| m.name.clone()).collect()
    }

    /// The kernel function a call path names (`foo`, `super::rng::foo`), if any: paths through
    /// a built-in type (`Vec3::new`, `f32::max`) are not kernel functions.
    pub(crate) fn kernel_fn_of_path<'p>(&self, path: &'p [String]) -> Option<&'p str> {
        if path.len() > 1 && ir::BUILTIN_TYPES.contains(&path[0].as_str()) {
            return None;
        }
        path.last().map(String::as_str).filter(|n| self.fns.contains_key(*n))
    }

    /// The kernel functions `name` calls directly, with the call's span.
    pub(crate) fn callees(&self, name: &str) -> Vec<(String, ir::Span)> {
        let mut out = Vec::new();
        if let Some(f) = self.fns.get(name) {
            collect_calls_block(&f.item.body, &|p: &[String]| self.kernel_fn_of_path(p).map(str::to_string), &mut out);
        }
        out
    }

    fn check_no_recursion(&self) -> Result<(), CodegenError> {
        fn visit(
            p: &Program,
            name: &str,
            stack: &mut Vec<String>,
            done: &mut BTreeSet<String>,
        ) -> Result<(), CodegenError> {
            if done.contains(name) {
                return Ok(());
            }
            stack.push(name.to_string());
            for (callee, span) in p.callees(name) {
                if stack.contains(&callee) {
                    let f = &p.fns[name];
                    return Err(CodegenError {
                        file: f.file.clone(),
                        span,
                        function: Some(format!("{}::{}", f.module, name)),
                        message: format!(
                            "recursion is not supported on GPUs (`{callee}` is reached again through this call): use a loop with an explicit stack"
                        ),
                    });
                }
                visit(p, &callee, stack, done)?;
            }
            stack.pop();
            done.insert(name.to_string());
            Ok(())
        }
        let mut done = BTreeSet::new();
        for name in self.fns.keys() {
            visit(self, name, &mut Vec::new(), &mut done)?;
        }
        Ok(())
    }

    /// Emits the selected functions (and everything they use) for `target`.
    pub fn emit(&self, target: Target, selection: &Selection) -> Result<Generated, CodegenError> {
        lower::emit(self, target, selection)
    }
}

fn collect_calls_block(
    b: &ir::Block,
    resolve: &dyn Fn(&[String]) -> Option<String>,
    out: &mut Vec<(String, ir::Span)>,
) {
    for s in &b.stmts {
        match s {
            ir::Stmt::Let { init: Some(e), .. } | ir::Stmt::Expr(e) => collect_calls(e, resolve, out),
            ir::Stmt::Let { init: None, .. } => {}
        }
    }
    if let Some(t) = &b.tail {
        collect_calls(t, resolve, out);
    }
}

/// Visits every expression below `e` (including `e`), depth first.
pub(crate) fn walk_expr<'a>(e: &'a ir::Expr, f: &mut dyn FnMut(&'a ir::Expr)) {
    use ir::ExprKind as K;
    f(e);
    let block = |b: &'a ir::Block, f: &mut dyn FnMut(&'a ir::Expr)| {
        for s in &b.stmts {
            match s {
                ir::Stmt::Let { init: Some(e), .. } | ir::Stmt::Expr(e) => walk_expr(e, f),
                ir::Stmt::Let { init: None, .. } => {}
            }
        }
        if let Some(t) = &b.tail {
            walk_expr(t, f);
        }
    };
    match &e.kind {
        K::Lit(_) | K::Path(_) | K::Break | K::Continue => {}
        K::Unary { expr, .. } | K::Cast { expr, .. } | K::AddrOfMut(expr) | K::AddrOf(expr) | K::Paren(expr) => {
            walk_expr(expr, f)
        }
        K::Binary { lhs, rhs, .. } => {
            walk_expr(lhs, f);
            walk_expr(rhs, f);
        }
        K::Assign { place, value, .. } => {
            walk_expr(place, f);
            walk_expr(value, f);
        }
        K::Call { args, .. } | K::Array(args) => args.iter().for_each(|a| walk_expr(a, f)),
        K::MethodCall { receiver, args, .. } => {
            walk_expr(receiver, f);
            args.iter().for_each(|a| walk_expr(a, f));
        }
        K::Field { base, .. } => walk_expr(base, f),
        K::Index { base, index } => {
            walk_expr(base, f);
            walk_expr(index, f);
        }
        K::StructLit { fields, .. } => fields.iter().for_each(|(_, v)| walk_expr(v, f)),
        K::ArrayRepeat { value, .. } => walk_expr(value, f),
        K::If { cond, then, otherwise } => {
            walk_expr(cond, f);
            block(then, f);
            if let Some(o) = otherwise {
                walk_expr(o, f);
            }
        }
        K::Match { scrutinee, arms } => {
            walk_expr(scrutinee, f);
            for a in arms {
                a.patterns.iter().for_each(|p| walk_expr(p, f));
                walk_expr(&a.body, f);
            }
        }
        K::Block(b) | K::Loop { body: b } => block(b, f),
        K::While { cond, body } => {
            walk_expr(cond, f);
            block(body, f);
        }
        K::ForRange { start, end, body, .. } => {
            walk_expr(start, f);
            walk_expr(end, f);
            block(body, f);
        }
        K::Return(v) => {
            if let Some(v) = v {
                walk_expr(v, f)
            }
        }
    }
}

fn collect_calls(e: &ir::Expr, resolve: &dyn Fn(&[String]) -> Option<String>, out: &mut Vec<(String, ir::Span)>) {
    walk_expr(e, &mut |e| {
        if let ir::ExprKind::Call { path, .. } = &e.kind {
            if let Some(name) = resolve(path) {
                out.push((name, e.span));
            }
        }
    });
}
