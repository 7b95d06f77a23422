//! The function-level equivalence harness: any kernel function run on the CPU and on every GPU
//! runtime (GL, wgpu, and in headless Chromium WebGL2 and WebGPU) on the same inputs, outputs compared word by word under a stated
//! [`Tolerance`].
//!
//! A test states its inputs once ([`Equivalence::run`]): a slice of argument tuples and the
//! Rust call that is the reference. The CPU backend calls it; each GPU runtime runs codegen's
//! generated harness shader (`Selection::harness`) around the same kernel function, which
//! reads each invocation's arguments as raw 32-bit words and writes its results as raw words
//! (layout in [`lightport_codegen::Harness`]): GL (`backend/gl/harness.rs`) through an RGBA32UI texture and
//! RGBA32UI colour attachments, wgpu (`backend/wgpu/harness.rs`) through storage buffers of a compute shader.
//! Values cross as their bits ([`Words`]), so NaN payloads, -0.0 and integer bit patterns
//! survive both ways.
//!
//! The Rust side's flattening is checked against the generated layout before anything runs:
//! same number of words, same scalar types, same struct field names in the IR's declaration
//! order. A mismatch is a [`HarnessError::Layout`], never a silent misread.
//!
//! The runtimes stand side by side with one shape ([`Runtime`]): `set_scene`,
//! `set_specialization`, `layout`, `run_words`. [`GlHarness`] only needs a [`glow::Context`]
//! and [`WgpuHarness`] a device and queue, so WebGL2 and WebGPU reuse them: the browser
//! runtimes ([`browser`], native only) are the same two harnesses compiled to wasm and run in a
//! page of headless Chromium (`web/src/harness.rs`), driven over a pipe.

#[cfg(all(feature = "wgpu", not(target_arch = "wasm32")))]
pub mod browser;
mod compare;
mod scene_words;
mod words;

use std::collections::{BTreeMap, HashMap};
use std::fmt;
use std::time::Instant;

use lightport_codegen::{Program, Selection, Target};
use rayon::prelude::*;

pub use super::gl::harness::{GlHarness, GlHarnessOptions, GlLimits, ARGS_UNIFORM};
#[cfg(feature = "wgpu")]
pub use super::wgpu::harness::WgpuHarness;
#[cfg(all(feature = "wgpu", not(target_arch = "wasm32")))]
pub use browser::{BrowserOptions, BrowserRuntime, BrowserSession, Corruption};
pub use compare::{compare_words, ulp_distance, Comparison, Mismatch, Tolerance};
pub use scene_words::{decode_resources, decode_scene, encode_resources, encode_scene};
pub use words::{check_layout, field_layout, join, HarnessWord, Values, Words};

use super::gl::GlError;
use crate::kernel::scene_data::Scene;
use crate::kernel::ShaderError;

/// Where a kernel function can run.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Backend {
    /// The kernel compiled as Rust: the reference every other backend is compared with.
    Cpu,
    /// The generated GLSL ES 3.00 on a GL context (headless EGL natively).
    Gl,
    /// The generated WGSL as a compute shader on a wgpu device (Vulkan natively).
    Wgpu,
    /// The GL harness compiled to wasm, on WebGL2 in headless Chromium (ANGLE on SwiftShader).
    WebGl2,
    /// The wgpu harness compiled to wasm, on WebGPU in headless Chromium (SwiftShader).
    WebGpu,
}

impl Backend {
    /// Every GPU runtime, in the order [`Equivalence`] runs them.
    pub const GPU: [Backend; 4] = [Backend::Gl, Backend::Wgpu, Backend::WebGl2, Backend::WebGpu];

    /// Whether this runtime runs in the browser ([`browser`]).
    pub fn is_browser(self) -> bool {
        matches!(self, Backend::WebGl2 | Backend::WebGpu)
    }
}

impl fmt::Display for Backend {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Backend::Cpu => "CPU",
            Backend::Gl => "GL",
            Backend::Wgpu => "wgpu",
            Backend::WebGl2 => "WebGL2",
            Backend::WebGpu => "WebGPU",
        })
    }
}

/// Why a harness run could not happen.
#[derive(Debug, thiserror::Error)]
pub enum HarnessError {
    #[error(transparent)]
    Gl(#[from] GlError),
    #[cfg(feature = "wgpu")]
    #[error(transparent)]
    Wgpu(#[from] crate::backend::wgpu::WgpuError),
    #[error(transparent)]
    Shader(#[from] ShaderError),
    #[error("the Rust values given for `{function}` do not follow the generated harness layout: {detail}")]
    Layout { function: String, detail: String },
    #[error("`{function}` writes {attachments} colour attachments but this GL device allows {max} ({limit})")]
    TooManyOutputs { function: String, attachments: u32, max: u32, limit: &'static str },
    #[error("`{function}` reads the scene (`{uniform}`) but no scene was set: call `set_scene` first")]
    NoScene { function: String, uniform: String },
    #[error("the {backend} runtime is not built in: {detail}")]
    NotBuilt { backend: Backend, detail: &'static str },
    #[error("the {backend} runtime (headless Chromium): {detail}")]
    Browser { backend: Backend, detail: String },
}

/// A GPU runtime of the harness: what [`Equivalence`] asks of GL and of wgpu alike.
pub trait Runtime: std::any::Any {
    fn backend(&self) -> Backend;
    /// This runtime as its own type (e.g. to inject a fault into the browser's pipe).
    fn as_any_mut(&mut self) -> &mut dyn std::any::Any;
    /// Uploads `scene`'s data (replacing a previous scene's) for functions taking `&Scene`.
    fn set_scene(&mut self, scene: &Scene) -> Result<(), HarnessError>;
    /// Specialises the harness shaders from now on as `Selection::specialize` does the
    /// kernel's (e.g. `packed.features.specialization()`).
    fn set_specialization(&mut self, specialize: BTreeMap<String, u32>);
    /// The generated harness layout of `function`, compiling its shader on first use.
    fn layout(&mut self, function: &str) -> Result<lightport_codegen::Harness, HarnessError>;
    /// Runs `function` on `invocations` argument sets given as words (`input_words` per
    /// invocation, in the generated layout) and returns `output_words` per invocation.
    fn run_words(&mut self, function: &str, invocations: usize, input: &[u32]) -> Result<Vec<u32>, HarnessError>;
}

/// The selection that emits `function`'s harness specialised by `specialize`.
pub(crate) fn harness_selection(function: &str, specialize: &BTreeMap<String, u32>) -> Selection {
    Selection { specialize: specialize.clone(), ..Selection::harness(function) }
}

/// The harness layout from a generated shader, or the error that codegen gave none.
pub(crate) fn generated_layout(
    function: &str,
    generated: &lightport_codegen::Generated,
) -> Result<lightport_codegen::Harness, HarnessError> {
    generated.harness.clone().ok_or_else(|| HarnessError::Layout {
        function: function.to_string(),
        detail: "codegen returned no harness layout".into(),
    })
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
    /// The GPU runtimes, in [`Backend::GPU`] order: each behind the one [`Runtime`] interface.
    runtimes: Vec<Box<dyn Runtime>>,
    /// Harness layouts by function, for the CPU-only case.
    layouts: HashMap<String, lightport_codegen::Harness>,
}

impl Equivalence {
    /// The tracer's kernel modules plus `extra` (e.g. a test's own `#[kernel]` module), on the
    /// CPU and each of `backends` (GL: a headless EGL context; wgpu: a native device; WebGL2
    /// and WebGPU: the page of the shared headless Chromium, [`BrowserSession::shared`]; or the
    /// error that it could not be created).
    pub fn new(backends: &[Backend], extra: &[kernel_dsl::ir::Module]) -> Result<Equivalence, HarnessError> {
        let mut modules = crate::kernel::modules();
        modules.extend_from_slice(extra);
        let program = Program::link(&modules).map_err(ShaderError::from)?;
        // Only the GPU runtimes built in (features `gl`, `wgpu`) assign to it.
        #[cfg_attr(not(any(feature = "gl", all(feature = "wgpu", not(target_arch = "wasm32")))), allow(unused_mut))]
        let mut e = Equivalence::cpu_only(program);
        for backend in backends {
            match backend {
                Backend::Cpu => {}
                #[cfg(feature = "gl")]
                Backend::Gl => {
                    e.runtimes.push(Box::new(GlHarness::headless(e.program.clone(), GlHarnessOptions::default())?))
                }
                #[cfg(not(feature = "gl"))]
                Backend::Gl => {
                    return Err(HarnessError::NotBuilt {
                        backend: Backend::Gl,
                        detail: "built without the `gl` feature: create the GL harness with `Equivalence::with_gl`",
                    })
                }
                #[cfg(all(feature = "wgpu", not(target_arch = "wasm32")))]
                Backend::Wgpu => e.runtimes.push(Box::new(WgpuHarness::headless(e.program.clone())?)),
                #[cfg(not(all(feature = "wgpu", not(target_arch = "wasm32"))))]
                Backend::Wgpu => {
                    return Err(HarnessError::NotBuilt {
                        backend: Backend::Wgpu,
                        detail: "built without the `wgpu` feature (or on wasm, where the device comes from the page)",
                    })
                }
                #[cfg(all(feature = "wgpu", not(target_arch = "wasm32")))]
                Backend::WebGl2 | Backend::WebGpu => {
                    let session = BrowserSession::shared()?;
                    e.runtimes.push(Box::new(BrowserRuntime::new(session, *backend, e.program.clone(), &modules)?));
                }
                #[cfg(not(all(feature = "wgpu", not(target_arch = "wasm32"))))]
                Backend::WebGl2 | Backend::WebGpu => {
                    return Err(HarnessError::NotBuilt {
                        backend: *backend,
                        detail: "the browser runtimes are driven from a native build with the `wgpu` feature",
                    })
                }
            }
        }
        e.runtimes.sort_by_key(|r| Backend::GPU.iter().position(|&b| b == r.backend()));
        Ok(e)
    }

    fn cpu_only(program: Program) -> Equivalence {
        Equivalence { program, scene: Scene::default(), runtimes: Vec::new(), layouts: HashMap::new() }
    }

    pub fn backends(&self) -> Vec<Backend> {
        let mut b = vec![Backend::Cpu];
        b.extend(self.runtimes.iter().map(|r| r.backend()));
        b
    }

    /// The first runtime of type `R` this was created with (e.g. `GlHarness`, for its limits).
    pub fn runtime<R: Runtime>(&mut self) -> Option<&mut R> {
        self.runtimes.iter_mut().find_map(|r| r.as_any_mut().downcast_mut::<R>())
    }

    /// A browser runtime (WebGL2 or WebGPU) this was created with.
    #[cfg(all(feature = "wgpu", not(target_arch = "wasm32")))]
    pub fn browser(&mut self, backend: Backend) -> Option<&mut BrowserRuntime> {
        let runtime = self.runtimes.iter_mut().find(|r| r.backend() == backend)?;
        runtime.as_any_mut().downcast_mut::<BrowserRuntime>()
    }

    /// Every GPU runtime this was created with, in [`Backend::GPU`] order.
    fn runtimes(&mut self) -> impl Iterator<Item = &mut dyn Runtime> {
        self.runtimes.iter_mut().map(|r| r.as_mut() as &mut dyn Runtime)
    }

    /// The scene that functions taking `&Scene` read, on every backend.
    pub fn set_scene(&mut self, scene: &Scene) -> Result<(), HarnessError> {
        for r in self.runtimes() {
            r.set_scene(scene)?;
        }
        self.scene = scene.clone();
        Ok(())
    }

    pub fn scene(&self) -> &Scene {
        &self.scene
    }

    /// Specialises the GPU runtimes' shaders (see [`Runtime::set_specialization`]); the CPU
    /// runs the Rust source, which is never specialised.
    pub fn set_specialization(&mut self, specialize: BTreeMap<String, u32>) {
        for r in self.runtimes() {
            r.set_specialization(specialize.clone());
        }
    }

    fn layout(&mut self, function: &str) -> Result<lightport_codegen::Harness, HarnessError> {
        // Every runtime's layout is the same IR's; the first one's is the one checked.
        if let Some(r) = self.runtimes().next() {
            return r.layout(function);
        }
        if let Some(l) = self.layouts.get(function) {
            return Ok(l.clone());
        }
        let generated =
            self.program.emit(Target::GlslEs300, &Selection::harness(function)).map_err(ShaderError::from)?;
        let layout = generated_layout(function, &generated)?;
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

        let mut input_words = Vec::with_capacity(inputs.len() * layout.inputs.len());
        inputs.iter().for_each(|i| i.push_words(&mut input_words));
        for runtime in self.runtimes() {
            let backend = runtime.backend();
            let started = Instant::now();
            let words = runtime.run_words(function, inputs.len(), &input_words)?;
            seconds.push((backend, started.elapsed().as_secs_f64()));
            comparisons.push(compare_words(backend, &layout.outputs, &reference_words, &words, tolerance));
            let mut rest = words.as_slice();
            let values = (0..inputs.len()).map(|_| O::take_words(&mut rest)).collect();
            outputs.push((backend, values));
        }
        Ok(Outcome { function: function.to_string(), layout, outputs, comparisons, seconds })
    }
}

#[cfg(test)]
mod tests {
    use super::words::split_top;
    use super::*;
    use crate::kernel::traverse::Hit;
    use glam::{Vec2, Vec3, Vec4};

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
        let v =
            (Hit { triangle: 7, t: -0.0, u: f32::NAN, v: 1.5, instance: 3 }, Vec3::new(1.0, -2.0, 3.0), -5i32, true);
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
        let e = check_layout("outputs", &<(u32, f32, f32, f32, f32)>::layout(), &layout.outputs).unwrap_err();
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
            ("Bsdf", top_fields::<crate::kernel::bsdf::Bsdf>()),
            ("Shading", top_fields::<crate::kernel::integrator::Shading>()),
            ("NormalMapData", top_fields::<crate::kernel::normal_map::NormalMapData>()),
            ("AlphaMaskData", top_fields::<crate::kernel::alpha_mask::AlphaMaskData>()),
            ("Footprint", top_fields::<crate::kernel::textures::Footprint>()),
            ("GlassData", top_fields::<crate::kernel::scene_data::GlassData>()),
            ("GuidedSample", top_fields::<crate::kernel::integrator::GuidedSample>()),
            ("FirstHit", top_fields::<crate::kernel::integrator::FirstHit>()),
            ("InstanceRay", top_fields::<crate::kernel::instances::InstanceRay>()),
            ("SurfaceNormals", top_fields::<crate::kernel::integrator::SurfaceNormals>()),
            ("PathState", top_fields::<crate::kernel::integrator::PathState>()),
            ("ShadowRay", top_fields::<crate::kernel::integrator::ShadowRay>()),
        ];
        let structs: Vec<kernel_dsl::ir::StructDef> = crate::kernel::modules()
            .into_iter()
            .flat_map(|m| m.items)
            .filter_map(|i| match i {
                kernel_dsl::ir::Item::Struct(s) if !s.resources => Some(s),
                _ => None,
            })
            .collect();
        for (name, fields) in &checks {
            let s = structs.iter().find(|s| s.name == *name).unwrap_or_else(|| panic!("{name} is a kernel struct"));
            let ir: Vec<String> = s.fields.iter().map(|f| f.name.clone()).collect();
            assert_eq!(fields, &ir, "{name}");
        }
        assert_eq!(
            structs.len(),
            checks.len(),
            "a new kernel struct needs a Words impl here: {:?}",
            structs.iter().map(|s| &s.name).collect::<Vec<_>>()
        );
    }

    #[test]
    fn comparison_reports_mismatching_words() {
        let layout = <(Hit,)>::layout();
        let a = [3u32, 1.0f32.to_bits(), 0, 0, 0, 4, 2.0f32.to_bits(), 0, 0, 0];
        let mut b = a;
        b[1] = f32::from_bits(b[1]).next_up().to_bits();
        b[5] = 5;
        let c = compare_words(Backend::Gl, &layout, &a, &b, Tolerance::ulps(1));
        assert_eq!(c.mismatched, vec![1]);
        assert_eq!(c.max_ulps, 1);
        assert_eq!(c.examples[0].path, "#0.triangle");
        let c = compare_words(Backend::Gl, &layout, &a, &b, Tolerance::EXACT);
        assert_eq!(c.mismatched, vec![0, 1]);
    }
}
