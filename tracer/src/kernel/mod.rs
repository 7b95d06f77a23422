//! The path-tracing kernel, written in the kernel DSL. Each file holds one `#[kernel]` module;
//! the same code runs on the CPU and is generated into GLSL ES 3.00 and WGSL
//! (`shaders-generated/`, regenerated with `cargo run -- shaders`).

// Kernels write `!(x > 0.0)` on purpose: it is true for NaN, which is how they reject NaN on
// every target. `RangeInclusive::contains` and `u32::is_multiple_of` are not part of the DSL.
#![allow(clippy::neg_cmp_op_on_partial_ord, clippy::manual_range_contains, clippy::manual_is_multiple_of)]

#[path = "alpha_mask.rs"]
mod alpha_mask_src;
#[path = "bsdf.rs"]
mod bsdf_src;
#[path = "camera.rs"]
mod camera_src;
#[path = "denoise.rs"]
mod denoise_src;
#[path = "dielectric.rs"]
mod dielectric_src;
#[path = "instances.rs"]
mod instances_src;
#[path = "integrator.rs"]
// Conditions that specialisation decides are written `if (if scene.has_x != 0 { a } else { b })`:
// the folded kernel keeps the text it had without the feature.
#[allow(unused_parens)]
mod integrator_src;
#[path = "intersect.rs"]
mod intersect_src;
#[path = "lights.rs"]
mod lights_src;
#[path = "metal_rough.rs"]
mod metal_rough_src;
#[path = "normal_map.rs"]
mod normal_map_src;
#[path = "rng.rs"]
mod rng_src;
#[path = "sampling.rs"]
mod sampling_src;
#[path = "scene_data.rs"]
mod scene_data_src;
#[path = "texture_ref.rs"]
mod texture_ref_src;
#[path = "textures.rs"]
mod textures_src;
#[path = "tonemap.rs"]
// The tone curves' coefficients are written as their sources print them (AgX, ACES fit),
// digits beyond f32 included, so they can be checked against those sources by eye.
#[allow(clippy::excessive_precision)]
mod tonemap_src;
#[path = "traverse_masked.rs"]
mod traverse_masked_src;
#[path = "traverse.rs"]
mod traverse_src;
#[path = "wavefront.rs"]
mod wavefront_src;

pub mod features;

pub use alpha_mask_src::alpha_mask;
pub use bsdf_src::bsdf;
pub use camera_src::camera;
pub use denoise_src::denoise;
pub use dielectric_src::dielectric;
pub use instances_src::instances;
pub use integrator_src::integrator;
pub use intersect_src::intersect;
pub use lights_src::lights;
pub use metal_rough_src::metal_rough;
pub use normal_map_src::normal_map;
pub use rng_src::rng;
pub use sampling_src::sampling;
pub use scene_data_src::scene_data;
pub use texture_ref_src::texture_ref;
pub use textures_src::textures;
pub use tonemap_src::tonemap;
pub use traverse_masked_src::traverse_masked;
pub use traverse_src::traverse;
pub use wavefront_src::wavefront;

pub use features::{Features, RenderSettings, Strategy};

/// Every kernel module's IR, in link order (parsed from [`ir_json`], the one list of them).
pub fn modules() -> Vec<kernel_dsl::ir::Module> {
    ir_json().into_iter().map(kernel_dsl::ir::Module::from_json).collect()
}

/// Every kernel module's captured description, as the macro serialised it (what
/// [`modules`] parses): a stable text to fingerprint the kernel with.
pub fn ir_json() -> [&'static str; 20] {
    [
        rng::KERNEL_IR_JSON,
        sampling::KERNEL_IR_JSON,
        intersect::KERNEL_IR_JSON,
        scene_data::KERNEL_IR_JSON,
        instances::KERNEL_IR_JSON,
        texture_ref::KERNEL_IR_JSON,
        textures::KERNEL_IR_JSON,
        alpha_mask::KERNEL_IR_JSON,
        traverse::KERNEL_IR_JSON,
        traverse_masked::KERNEL_IR_JSON,
        camera::KERNEL_IR_JSON,
        lights::KERNEL_IR_JSON,
        metal_rough::KERNEL_IR_JSON,
        dielectric::KERNEL_IR_JSON,
        normal_map::KERNEL_IR_JSON,
        bsdf::KERNEL_IR_JSON,
        integrator::KERNEL_IR_JSON,
        tonemap::KERNEL_IR_JSON,
        denoise::KERNEL_IR_JSON,
        wavefront::KERNEL_IR_JSON,
    ]
}

/// The path tracer's complete shader for `target`, specialised to `features`: a GLSL ES 3.00
/// fragment shader or a WGSL compute shader around `integrator::render_sample` (with the
/// denoiser's guide, `render_guided_sample`: four outputs), validated.
pub fn path_tracer_shader(
    features: &Features,
    target: lightport_codegen::Target,
) -> Result<lightport_codegen::Generated, ShaderError> {
    path_tracer_shader_for(features, target, None)
}

/// [`path_tracer_shader`], with `regenerate` (how the file is regenerated) in its header.
fn path_tracer_shader_for(
    features: &Features,
    target: lightport_codegen::Target,
    regenerate: Option<&str>,
) -> Result<lightport_codegen::Generated, ShaderError> {
    let entry = if features.denoise_guide { "render_guided_sample" } else { "render_sample" };
    let selection = lightport_codegen::Selection::entry(entry, features.specialization());
    emit_validated(target, selection, regenerate)
}

/// The wavefront schedule's shader (WGSL only: GLSL ES 3.00 has no compute), specialised to
/// `features` as the megakernel is: one module with an entry point `main_<stage>` per stage of
/// `kernel::wavefront` ([`backend::wavefront::ITERATION`](crate::backend::wavefront::ITERATION)), validated.
pub fn wavefront_shader(features: &Features) -> Result<lightport_codegen::Generated, ShaderError> {
    wavefront_shader_for(features, None)
}

fn wavefront_shader_for(
    features: &Features,
    regenerate: Option<&str>,
) -> Result<lightport_codegen::Generated, ShaderError> {
    let stages = crate::backend::wavefront::stage_functions();
    let selection = lightport_codegen::Selection::compute(&stages, features.specialization());
    emit_validated(lightport_codegen::Target::Wgsl, selection, regenerate)
}

/// One pass of the denoiser's à-trous filter for `target`: a GLSL ES 3.00 fragment shader or a
/// WGSL compute shader storing `denoise::atrous_pixel` as each pixel (over the `FilterImage`
/// resources), validated.
pub fn denoise_pass_shader(target: lightport_codegen::Target) -> Result<lightport_codegen::Generated, ShaderError> {
    denoise_pass_shader_for(target, None)
}

fn denoise_pass_shader_for(
    target: lightport_codegen::Target,
    regenerate: Option<&str>,
) -> Result<lightport_codegen::Generated, ShaderError> {
    emit_validated(target, lightport_codegen::Selection::image_pass("atrous_pixel", Default::default()), regenerate)
}

/// The kernel's modules, parsed and linked once per process: every shader a runtime generates
/// (each scene's megakernel and wavefront, the display and denoiser passes) is emitted from it.
/// In the page this is a third of what generating the first scene's kernel took.
pub fn linked_kernel() -> Result<&'static lightport_codegen::Program, ShaderError> {
    static PROGRAM: std::sync::OnceLock<Result<lightport_codegen::Program, lightport_codegen::CodegenError>> =
        std::sync::OnceLock::new();
    let linked = PROGRAM.get_or_init(|| lightport_codegen::Program::link(&modules()));
    linked.as_ref().map_err(|e| ShaderError::from(e.clone()))
}

/// `selection` of the linked kernel for `target`, with `regenerate` in its header, validated
/// (with the `validate` feature).
fn emit_validated(
    target: lightport_codegen::Target,
    selection: lightport_codegen::Selection,
    regenerate: Option<&str>,
) -> Result<lightport_codegen::Generated, ShaderError> {
    let program = linked_kernel()?;
    let selection = lightport_codegen::Selection { regenerate: regenerate.map(str::to_string), ..selection };
    let generated = program.emit(target, &selection)?;
    #[cfg(feature = "validate")]
    lightport_codegen::validate::validate(&generated)?;
    Ok(generated)
}

/// The display transform (`tonemap::display_srgb` and what it calls) in `target`'s language:
/// what each runtime's display pass wraps its own entry point around, so that the screen shows
/// what the CLI's PNG output stores.
pub fn display_transform(target: lightport_codegen::Target) -> Result<lightport_codegen::Generated, ShaderError> {
    use lightport_codegen::Selection;
    let program = linked_kernel()?;
    let selection = Selection { roots: vec!["display_srgb".into()], ..Selection::default() };
    Ok(program.emit(target, &selection)?)
}

/// One generated shader file.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct GeneratedFile {
    /// File name inside `shaders-generated/`, e.g. `rng.wgsl`.
    pub name: String,
    pub source: String,
}

/// The contents of `shaders-generated/`: for every kernel module, a GLSL ES 3.00 and a WGSL
/// file holding its functions and everything they use from other modules, each validated
/// (WGSL by naga, GLSL parsed by glsl-lang) before it is returned.
#[cfg(feature = "validate")]
pub fn generated_shaders() -> Result<Vec<GeneratedFile>, ShaderError> {
    use lightport_codegen::{Selection, Target};
    let program = linked_kernel()?;
    let mut files = Vec::new();
    for module in program.module_names() {
        let compute = program.is_compute_module(&module);
        for target in [Target::GlslEs300, Target::Wgsl] {
            if compute && target == Target::GlslEs300 {
                // A compute module has no GLSL ES 3.00 (no storage buffers, atomics or compute).
                continue;
            }
            let selection = Selection { regenerate: Some(REGENERATE.into()), ..Selection::module(program, &module) };
            let generated = program.emit(target, &selection)?;
            lightport_codegen::validate::validate(&generated)?;
            files.push(GeneratedFile { name: format!("{module}.{}", target.extension()), source: generated.source });
        }
    }
    // The complete path tracer: every feature on, and the variant a Cornell box needs.
    let variants = [("path_tracer", Features::all()), ("path_tracer_cornell", cornell_features())];
    for (name, features) in variants {
        for target in [Target::GlslEs300, Target::Wgsl] {
            let generated = path_tracer_shader_for(&features, target, Some(REGENERATE))?;
            let ext = if target == Target::GlslEs300 { "frag.glsl" } else { "wgsl" };
            files.push(GeneratedFile { name: format!("{name}.{ext}"), source: generated.source });
        }
    }
    // The wavefront schedule's stages, with every feature and for the Cornell box.
    for (name, features) in
        [("path_tracer_wavefront", Features::all()), ("path_tracer_wavefront_cornell", cornell_features())]
    {
        let generated = wavefront_shader_for(&features, Some(REGENERATE))?;
        files.push(GeneratedFile { name: format!("{name}.wgsl"), source: generated.source });
    }
    // The denoiser's filter pass.
    for target in [Target::GlslEs300, Target::Wgsl] {
        let generated = denoise_pass_shader_for(target, Some(REGENERATE))?;
        let ext = if target == Target::GlslEs300 { "frag.glsl" } else { "wgsl" };
        files.push(GeneratedFile { name: format!("denoise_pass.{ext}"), source: generated.source });
    }
    Ok(files)
}

/// How `shaders-generated/` is regenerated, for the header of its files.
#[cfg(feature = "validate")]
const REGENERATE: &str = "regenerate with `cargo run -- shaders`";

/// What the built-in Cornell box uses: emissive triangles only, and a traversal stack of
/// `CORNELL_STACK` entries (`tests/kernel/codegen.rs` checks this against the packed scene).
#[cfg(feature = "validate")]
fn cornell_features() -> Features {
    Features { emissive_triangles: true, traversal_stack: CORNELL_STACK, ..Default::default() }
}

/// The traversal stack the built-in Cornell box's BVH needs with every leaf pushed.
#[cfg(feature = "validate")]
const CORNELL_STACK: u32 = 11;

/// Code generation or validation of the kernel failed (reported against its Rust source).
#[derive(Debug, thiserror::Error)]
pub enum ShaderError {
    #[error(transparent)]
    Codegen(#[from] lightport_codegen::CodegenError),
    #[cfg(feature = "validate")]
    #[error(transparent)]
    Validation(#[from] lightport_codegen::validate::ValidationError),
}
