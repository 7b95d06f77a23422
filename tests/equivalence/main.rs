//! Function-level equivalence: kernel functions run on the CPU (the kernel compiled as Rust),
//! on GL (the generated GLSL ES 3.00 through codegen's harness; Mesa llvmpipe in CI), on
//! wgpu (the generated WGSL as a compute shader; Mesa lavapipe in CI), and in headless
//! Chromium on WebGL2 and WebGPU (the same two harnesses compiled to wasm, on SwiftShader; one
//! browser for the whole binary) on the same inputs, compared word by word under the tolerance
//! each test states. Every check of a GPU answer runs for each GPU runtime (`Backend::GPU`).
//!
//! Never skipped: a machine without a usable GL or Vulkan driver, Chromium, node's
//! `tests/web/node_modules` or the wasm build `web/pkg/` fails every test here with the reason.
//! Run with `--nocapture` to see each function's comparison (invocations, max ULP, mismatches).

mod alpha_mask;
mod aov;
mod browser;
#[path = "../common/mod.rs"]
mod common;
mod dielectric;
mod filter_passes;
mod hazards;
mod intersection;
mod kernels;
mod normal_map;
mod path_segment;
mod texture_ref;

use common::{node_child_box, test_data, TestRng};
use glam::{IVec2, UVec3, UVec4, Vec2, Vec3};
use tracer::backend::harness::{Backend, Equivalence, Outcome, Tolerance, Values};
use tracer::kernel::intersect::{self, TriangleHit, MISS};
use tracer::kernel::scene_data::{self, Scene, NONE};
use tracer::kernel::traverse::{self, Hit};
use tracer::kernel::RenderSettings;
use tracer::kernel::{camera, integrator, metal_rough, rng, sampling, textures};
use tracer::pack::pack;

/// CPU, GL, wgpu, WebGL2 and WebGPU, with the hazards module linked in. Fails (never skips)
/// without a usable GL or Vulkan driver or browser.
fn equivalence() -> Equivalence {
    let backends = [Backend::Cpu, Backend::Gl, Backend::Wgpu, Backend::WebGl2, Backend::WebGpu];
    Equivalence::new(&backends, &[hazards::kernel::kernel_ir()]).unwrap_or_else(|e| {
        panic!(
            "every runtime must run here (install Mesa's EGL/GLES drivers and Vulkan: \
             libegl1 libegl-mesa0 libgles2 libgl1-mesa-dri mesa-vulkan-drivers libvulkan1; \
             the browser: apt-get install chromium nodejs npm, `npm ci` in tests/web, scripts/build-web.sh): {e}"
        )
    })
}

/// Runs `function` everywhere and asserts that every backend matches the CPU.
fn assert_equivalent<I, O>(
    eq: &mut Equivalence,
    function: &str,
    inputs: &[I],
    cpu: impl Fn(&Scene, &I) -> O + Sync,
    tolerance: Tolerance,
) -> Outcome<O>
where
    I: Values + Sync,
    O: Values + Send,
{
    let outcome = eq.run(function, inputs, cpu, tolerance).unwrap_or_else(|e| panic!("{function}: {e}"));
    report(&outcome);
    assert!(outcome.is_equivalent(), "{outcome}");
    outcome
}

fn report<O>(outcome: &Outcome<O>) {
    for c in &outcome.comparisons {
        let seconds = outcome.seconds.iter().find(|(b, _)| *b == c.backend).map_or(f64::NAN, |(_, s)| *s);
        println!(
            "{:<28} {:<6} {:>7.3} s {:>9} invocations  max {:>6} ULP  max abs {:>8.1e}  {:>7} inexact floats  {} mismatches ({})",
            outcome.function,
            c.backend,
            seconds,
            c.invocations,
            c.max_ulps,
            c.max_abs,
            c.inexact_floats,
            c.mismatched.len(),
            c.tolerance
        );
    }
}

/// A float with random bits (every exponent, NaNs and infinities included), not subnormal:
/// GPUs may flush subnormals, which `subnormals_flush_to_zero_or_are_kept` covers.
fn any_float(rng: &mut TestRng) -> f32 {
    loop {
        let x = f32::from_bits(rng.next_u32());
        if !x.is_subnormal() {
            return x;
        }
    }
}

/// Subnormals of both signs: the smallest, the largest, and random ones.
fn subnormals(n: usize, seed: u64) -> Vec<f32> {
    let mut r = TestRng::new(seed);
    let mut v =
        vec![f32::from_bits(1), f32::from_bits(0x8000_0001), f32::from_bits(0x007f_ffff), f32::from_bits(0x807f_ffff)];
    while v.len() < n {
        v.push(f32::from_bits((r.next_u32() & 0x807f_ffff) | 1));
    }
    v
}

/// Floats that break conversions and rounding: zeros, halves, integer edges, limits, specials.
fn special_floats() -> Vec<f32> {
    let mut v = vec![
        0.0,
        -0.0,
        0.5,
        -0.5,
        1.5,
        -1.5,
        2.5,
        -2.5,
        0.49999997,
        -0.49999997,
        1.0,
        -1.0,
        -0.99999994,
        8388607.5,
        -8388607.5,
        16777216.0,
        2147483520.0,
        2147483648.0,
        -2147483648.0,
        -2147483904.0,
        4294967040.0,
        4294967296.0,
        1e10,
        -1e10,
        f32::MAX,
        f32::MIN,
        f32::MIN_POSITIVE,
        -f32::MIN_POSITIVE,
        f32::EPSILON,
        f32::INFINITY,
        f32::NEG_INFINITY,
        f32::NAN,
        -f32::NAN,
        f32::from_bits(0x7f80_0001),
        f32::from_bits(0xffc1_2345),
    ];
    for k in 0..40 {
        let x = (k as f32 - 20.0) * 0.25;
        v.push(x);
        v.push(x.next_up());
        v.push(x.next_down());
    }
    v
}

fn floats_with_specials(n: usize, seed: u64, mut random: impl FnMut(&mut TestRng) -> f32) -> Vec<f32> {
    let mut rng = TestRng::new(seed);
    let mut v: Vec<f32> = special_floats().into_iter().filter(|x| !x.is_subnormal()).collect();
    while v.len() < n {
        v.push(random(&mut rng));
    }
    v
}

// ---------------------------------------------------------------------------------------------
// The harness itself.

/// The comparison is not vacuous: a reference that differs in one invocation is reported as
/// exactly that invocation, and a float one ULP off is out of a bit-exact tolerance.
#[test]
fn the_harness_reports_a_wrong_reference() {
    let mut eq = equivalence();
    let seeds: Vec<(u32,)> = (0..5000u32).map(|s| (s,)).collect();
    let outcome = eq
        .run("wang_hash", &seeds, |_, &(s,)| (rng::wang_hash(s) ^ u32::from(s == 1234),), Tolerance::EXACT)
        .expect("runs");
    for backend in Backend::GPU {
        assert_eq!(outcome.comparison(backend).expect("ran").mismatched, vec![1234], "{backend}: {outcome}");
    }
    let outcome = eq
        .run(
            "random_float",
            &seeds,
            |_, &(s,)| {
                let mut state = s;
                let x = rng::random_float(&mut state);
                (if s == 77 { x.next_up() } else { x }, state)
            },
            Tolerance::EXACT,
        )
        .expect("runs");
    for backend in Backend::GPU {
        let gpu = outcome.comparison(backend).expect("ran");
        assert_eq!((gpu.mismatched.as_slice(), gpu.max_ulps), ([77usize].as_slice(), 1), "{backend}: {outcome}");
    }
}

/// Rust values that do not follow the generated layout are a typed error before anything runs.
#[test]
fn values_not_matching_the_layout_are_refused() {
    let mut eq = equivalence();
    let e = eq.run("wang_hash", &[(1.0f32,)], |_, &(x,)| (x.to_bits(),), Tolerance::EXACT).unwrap_err();
    assert!(e.to_string().contains("do not follow the generated harness layout"), "{e}");
    let e = eq.run("no_such_function", &[(1u32,)], |_, &(x,)| (x,), Tolerance::EXACT).unwrap_err();
    assert!(e.to_string().contains("no_such_function"), "{e}");
    let e = eq
        .run("fetch_triangle", &[(0u32,)], |s, &(i,)| (scene_data::fetch_triangle(s, i),), Tolerance::EXACT)
        .unwrap_err();
    assert!(e.to_string().contains("no scene was set"), "{e}");
}

/// Chunking: more invocations than one draw (or one texture row) holds give the same words.
#[test]
fn large_batches_are_chunked() {
    use tracer::backend::harness::{GlHarness, GlHarnessOptions};
    let program = lightport_codegen::Program::link(&tracer::kernel::modules()).expect("links");
    let options = GlHarnessOptions { max_invocations_per_draw: 1000, max_texture_size: Some(64) };
    let mut gl = GlHarness::headless(program, options).unwrap_or_else(|e| panic!("GL: {e}"));
    // intersect_triangle: 15 input words = 4 texels per invocation, so 16 per 64-texel row.
    let mut r = TestRng::new(5);
    let n = 10_007;
    let inputs: Vec<f32> = (0..n * 15).map(|_| r.range(-1.0, 1.0)).collect();
    let words: Vec<u32> = inputs.iter().map(|x| x.to_bits()).collect();
    let out = gl.run_words("intersect_triangle", n, &words).expect("runs");
    assert_eq!(out.len(), n * 3);
    let mut hits = 0;
    for (i, args) in inputs.chunks(15).enumerate() {
        let v = |k: usize| Vec3::new(args[k], args[k + 1], args[k + 2]);
        let want = intersect::intersect_triangle(v(0), v(3), v(6), v(9), v(12));
        let got = f32::from_bits(out[i * 3]);
        assert_eq!(want.t == MISS, got == MISS, "invocation {i}: {want:?} vs t {got}");
        hits += usize::from(want.t < MISS);
    }
    assert!(hits > n / 50, "{hits} hits: too few to check the layout");
}
