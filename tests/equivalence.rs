//! Function-level equivalence: kernel functions run on the CPU (the kernel compiled as Rust)
//! and on GL (the generated GLSL ES 3.00 through codegen's harness; Mesa llvmpipe in CI) on
//! the same inputs, compared word by word under the tolerance each test states.
//!
//! Never skipped: a machine without a usable GL fails every test here with the reason.
//! Run with `--nocapture` to see each function's comparison (invocations, max ULP, mismatches).

mod common;

use std::path::{Path, PathBuf};

use common::{node_child_box, TestRng};
use glam::{IVec2, UVec3, UVec4, Vec2, Vec3};
use tracer::backend::harness::{Backend, Equivalence, Outcome, Tolerance, Values};
use tracer::kernel::intersect::{self, TriangleHit, MISS};
use tracer::kernel::scene_data::{self, Scene, NONE};
use tracer::kernel::traverse::{self, Hit};
use tracer::kernel::{camera, metal_rough, rng, sampling};
use tracer::pack::{pack, RenderSettings};

/// Rust, GLSL ES 3.00 and WGSL differ on these operations (DESIGN.md principle 2, the table in
/// docs/dsl.md); the path-tracing kernel does not exercise all of them directly.
#[kernel_dsl::kernel]
mod hazards {
    use glam::{IVec2, UVec2, UVec4, Vec2, Vec4};

    pub fn float_to_u32(x: f32) -> u32 {
        x as u32
    }

    pub fn float_to_i32(x: f32) -> i32 {
        x as i32
    }

    pub fn u32_to_float(x: u32) -> f32 {
        x as f32
    }

    /// At most 24 significant bits: codegen may use a plain conversion here.
    pub fn u24_to_float(x: u32) -> f32 {
        (x >> 8) as f32
    }

    pub fn i32_to_float(x: i32) -> f32 {
        x as f32
    }

    pub fn div_rem_i32(a: i32, b: i32) -> IVec2 {
        IVec2::new(a / b, a % b)
    }

    pub fn div_rem_u32(a: u32, b: u32) -> UVec2 {
        UVec2::new(a / b, a % b)
    }

    /// Shift amounts are masked to 0..31 (`wrapping_shl/shr`); `>>` on i32 is arithmetic.
    pub fn shifts(x: u32, n: u32) -> UVec4 {
        let s = x as i32;
        UVec4::new(x.wrapping_shl(n), x.wrapping_shr(n), s.wrapping_shl(n) as u32, s.wrapping_shr(n) as u32)
    }

    /// Shifts by literals, the only form plain `<<`/`>>` take.
    pub fn literal_shifts(x: u32) -> UVec4 {
        let s = x as i32;
        UVec4::new(x << 31, x >> 31, (s >> 31) as u32, (s >> 1) as u32)
    }

    pub fn wrapping_ops(a: u32, b: u32) -> UVec4 {
        let s = a as i32;
        UVec4::new(a.wrapping_add(b), a.wrapping_sub(b), a.wrapping_mul(b), s.wrapping_neg() as u32)
    }

    pub fn fmod(a: f32, b: f32) -> f32 {
        a % b
    }

    pub fn rounding(x: f32) -> Vec4 {
        Vec4::new(x.round(), x.fract(), x.signum(), x.trunc())
    }

    pub fn floor_ceil_abs(x: f32) -> Vec4 {
        Vec4::new(x.floor(), x.ceil(), x.abs(), -x)
    }

    /// bit 0: NaN, bit 1: finite, bit 2: infinite.
    pub fn classify(x: f32) -> u32 {
        let mut c = 0;
        if x.is_nan() {
            c |= 1;
        }
        if x.is_finite() {
            c |= 2;
        }
        if x.is_infinite() {
            c |= 4;
        }
        c
    }

    /// The IEEE specials the DSL's literals stand for, and arithmetic producing them.
    pub fn specials(x: f32) -> Vec4 {
        Vec4::new(f32::NAN, f32::INFINITY, f32::NEG_INFINITY, x * f32::INFINITY)
    }

    pub fn min_max(a: f32, b: f32) -> Vec2 {
        Vec2::new(a.min(b), a.max(b))
    }

    pub fn to_bits(x: f32) -> u32 {
        x.to_bits()
    }
}

fn shared(path: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared").join(path)
}

/// CPU and GL, with the hazards module linked in. Fails (never skips) without a usable GL.
fn equivalence() -> Equivalence {
    Equivalence::new(&[Backend::Cpu, Backend::Gl], &[hazards::kernel_ir()])
        .unwrap_or_else(|e| panic!("the GL backend must run here (install Mesa's EGL/GLES drivers): {e}"))
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
        println!(
            "{:<28} {:>9} invocations  max {:>6} ULP  max abs {:>8.1e}  {:>7} inexact floats  {} mismatches ({})",
            outcome.function,
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
    assert_eq!(outcome.comparison(Backend::Gl).expect("GL ran").mismatched, vec![1234], "{outcome}");
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
    let gl = outcome.comparison(Backend::Gl).expect("GL ran");
    assert_eq!((gl.mismatched.as_slice(), gl.max_ulps), ([77usize].as_slice(), 1), "{outcome}");
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

// ---------------------------------------------------------------------------------------------
// RNG: bit-exact.

#[test]
fn rng_is_bit_exact() {
    let mut eq = equivalence();
    let mut r = TestRng::new(1);
    let mut seeds: Vec<(u32,)> = (0..1u32 << 19).map(|s| (s,)).collect();
    seeds.extend([0, 1, 61, 0x7fff_ffff, 0x8000_0000, u32::MAX, 0x9e37_79b9].map(|s| (s,)));
    while seeds.len() < 1 << 20 {
        seeds.push((r.next_u32(),));
    }
    assert_equivalent(&mut eq, "wang_hash", &seeds, |_, &(s,)| (rng::wang_hash(s),), Tolerance::EXACT);
    assert_equivalent(
        &mut eq,
        "random_u32",
        &seeds,
        |_, &(s,)| {
            let mut state = s;
            (rng::random_u32(&mut state), state)
        },
        Tolerance::EXACT,
    );
    let outcome = assert_equivalent(
        &mut eq,
        "random_float",
        &seeds,
        |_, &(s,)| {
            let mut state = s;
            (rng::random_float(&mut state), state)
        },
        Tolerance::EXACT,
    );
    let gl = outcome.output(Backend::Gl).expect("GL ran");
    assert!(gl.iter().all(|(x, _)| (0.0..1.0).contains(x)), "random floats stay in [0, 1) on GL");
    let pairs: Vec<(u32, u32)> = (0..1 << 18).map(|i| (r.next_u32() >> (i % 24), r.next_u32())).collect();
    assert_equivalent(&mut eq, "pixel_seed", &pairs, |_, &(p, f)| (rng::pixel_seed(p, f),), Tolerance::EXACT);
}

// ---------------------------------------------------------------------------------------------
// Sampling.

/// Uniforms in [0, 1): 24-bit values, both ends included.
fn uniforms(n: usize, seed: u64) -> Vec<(f32, f32)> {
    let mut r = TestRng::new(seed);
    let top = 1.0 - f32::EPSILON / 2.0;
    let mut v = vec![(0.0, 0.0), (top, top), (0.0, top), (top, 0.0), (0.5, 0.5), (0.25, 0.75)];
    while v.len() < n {
        v.push((r.f32(), r.f32()));
    }
    v
}

fn unit_normals(n: usize, seed: u64) -> Vec<Vec3> {
    let mut r = TestRng::new(seed);
    let mut v = vec![Vec3::X, Vec3::Y, Vec3::Z, -Vec3::X, -Vec3::Y, -Vec3::Z, Vec3::new(1.0, 0.0, -0.0)];
    v.push(Vec3::new(0.0, 0.6, -0.8));
    v.push(Vec3::new(1e-4, 0.0, -1.0).normalize());
    while v.len() < n {
        v.push(r.unit_vector());
    }
    v
}

/// Trigonometry and square roots are not correctly rounded on GPUs (GLSL ES states no bound
/// for sin/cos): directions within 16 ULP or 2e-6 absolute (components are in [-1, 1]).
const SAMPLING: Tolerance = Tolerance::ulps(16).with_absolute(2e-6).flushing_subnormals();

#[test]
fn sampling_functions_agree() {
    let mut eq = equivalence();
    let u = uniforms(1 << 16, 2);
    assert_equivalent(
        &mut eq,
        "cosine_sample_hemisphere",
        &u,
        |_, &(a, b)| (sampling::cosine_sample_hemisphere(a, b),),
        SAMPLING,
    );
    assert_equivalent(&mut eq, "sample_disk", &u, |_, &(a, b)| (camera::sample_disk(a, b),), SAMPLING);
    assert_equivalent(
        &mut eq,
        "uniform_sample_triangle",
        &u,
        |_, &(a, b)| (sampling::uniform_sample_triangle(a, b),),
        SAMPLING,
    );
    let cos: Vec<(f32,)> = floats_with_specials(1 << 14, 3, |r| r.range(-1.0, 1.0)).into_iter().map(|x| (x,)).collect();
    assert_equivalent(
        &mut eq,
        "cosine_hemisphere_pdf",
        &cos,
        |_, &(c,)| (sampling::cosine_hemisphere_pdf(c),),
        Tolerance::ulps(1).flushing_subnormals(),
    );
    let normals: Vec<(Vec3,)> = unit_normals(1 << 16, 4).into_iter().map(|n| (n,)).collect();
    assert_equivalent(&mut eq, "onb_from_normal", &normals, |_, &(n,)| (sampling::onb_from_normal(n),), SAMPLING);
    let around: Vec<(Vec3, f32, f32)> = normals.iter().zip(&u).map(|(&(n,), &(a, b))| (n, a, b)).collect();
    assert_equivalent(
        &mut eq,
        "sample_cosine_around",
        &around,
        |_, &(n, a, b)| (sampling::sample_cosine_around(n, a, b),),
        SAMPLING,
    );
}

// ---------------------------------------------------------------------------------------------
// The metal-roughness BRDF.

/// Random BRDF inputs: surfaces over the whole parameter range (roughness 0, i.e. the clamp,
/// included), directions above the surface down to 1e-4 from the horizon, and uniforms.
fn brdf_cases(n: usize, seed: u64) -> Vec<(metal_rough::Surface, Vec3, Vec3, Vec3)> {
    let mut r = TestRng::new(seed);
    let upper = |r: &mut TestRng| {
        let v = r.unit_vector();
        Vec3::new(v.x, v.y, v.z.abs().max(1e-4)).normalize()
    };
    (0..n)
        .map(|i| {
            let base = Vec3::new(r.f32(), r.f32(), r.f32());
            let roughness = if i % 5 == 0 { 0.0 } else { r.f32() };
            let s = metal_rough::metal_rough_surface(base, r.f32(), roughness, if i % 11 == 0 { 0.0 } else { 1.0 });
            (s, upper(&mut r), upper(&mut r), Vec3::new(r.f32(), r.f32(), r.f32()))
        })
        .collect()
}

/// The BRDF's peak grows as 1 / α² (10^5 at the roughness clamp) and its half vector is
/// normalised from a sum: GPU `sqrt`/`inversesqrt` and division differ from the CPU's by a
/// few ULP, which the peak magnifies. Measured on llvmpipe, with a margin (see the printout).
const BRDF: Tolerance = Tolerance::ulps(256).with_absolute(1e-6).flushing_subnormals();

/// A sampled direction is reflected about a half vector drawn within a lobe ~2e-3 wide at
/// the roughness clamp: GPU rounding of `sqrt` and the turn's sine moves it by up to 4.6e-5
/// relative (456 ULP measured on llvmpipe). Its pdf, D ∝ 1 / t² with t ∝ |h.xy|² / α², takes
/// about four times that relative error (1288 ULP measured).
const BRDF_SAMPLE: Tolerance = Tolerance::ulps(4096).with_absolute(1e-6).flushing_subnormals();

/// Visible-normal sampling: the cap point's `sqrt(1 − z²)` near the cap's rim and the
/// normalisations magnify GPU rounding: half-vector components within 1e-5 absolute (5.2e-6
/// measured on llvmpipe; they lie in [-1, 1]).
const VNDF: Tolerance = Tolerance::ulps(16).with_absolute(1e-5).flushing_subnormals();

#[test]
fn metal_rough_functions_agree() {
    let mut eq = equivalence();
    let cases = brdf_cases(1 << 14, 31);
    let pairs: Vec<(metal_rough::Surface, Vec3, Vec3)> = cases.iter().map(|&(s, a, b, _)| (s, a, b)).collect();
    assert_equivalent(
        &mut eq,
        "metal_rough_eval",
        &pairs,
        |_, &(s, a, b)| (metal_rough::metal_rough_eval(s, a, b),),
        BRDF,
    );
    assert_equivalent(
        &mut eq,
        "metal_rough_pdf",
        &pairs,
        |_, &(s, a, b)| (metal_rough::metal_rough_pdf(s, a, b),),
        BRDF,
    );
    // Sampling decides twice: the lobe (u.z against the lobe probability) and whether the
    // direction is above the horizon. Cases within 1e-5 of either decision may go either way.
    let sampled: Vec<(metal_rough::Surface, Vec3, Vec3)> = cases
        .iter()
        .map(|&(s, a, _, u)| (s, a, u))
        .filter(|&(s, a, u)| {
            let near_lobe = (u.z - metal_rough::specular_probability(s, a.z)).abs() < 1e-5;
            let dir = metal_rough::metal_rough_sample(s, a, u).dir;
            !near_lobe && (dir.z - metal_rough::MIN_COSINE).abs() > 1e-5
        })
        .collect();
    assert!(sampled.len() > cases.len() * 9 / 10, "{} cases left", sampled.len());
    assert_equivalent(
        &mut eq,
        "metal_rough_sample",
        &sampled,
        |_, &(s, a, u)| (metal_rough::metal_rough_sample(s, a, u),),
        BRDF_SAMPLE,
    );
    let vndf: Vec<(f32, Vec3, f32, f32)> = cases.iter().map(|&(s, a, _, u)| (s.alpha, a, u.x, u.y)).collect();
    assert_equivalent(
        &mut eq,
        "sample_ggx_vndf",
        &vndf,
        |_, &(alpha, a, u1, u2)| (metal_rough::sample_ggx_vndf(alpha, a, u1, u2),),
        VNDF,
    );
}

// ---------------------------------------------------------------------------------------------
// Ray/triangle and ray/box.

/// Hit or miss may differ only where the exact answer is on the boundary: the hit side's
/// barycentrics within `EDGE` of an edge. Measured on llvmpipe; see the printed counts.
const EDGE: f32 = 1e-5;

/// Möller–Trumbore where both sides hit: most results are within a few ULP, but GPUs may fuse
/// the cross and dot products' multiply-adds (docs/dsl.md: contraction is not guaranteed either
/// way), which changes the cancellation error. Hits outside `TRIANGLE` must then be within
/// `CONDITIONED` units of [`hit_error_scale`], the forward error bound of the computation.
const TRIANGLE: Tolerance = Tolerance::ulps(16).flushing_subnormals();
const CONDITIONED: f64 = 16.0;

/// The forward error scale of Möller–Trumbore's t, u and v (per unit roundoff): each is a
/// quotient of a triple product by `det`, so its error is about eps * (the products' magnitudes
/// plus the quotient times det's magnitude) / |det|. Large for grazing rays and slivers.
fn hit_error_scale(o: Vec3, d: Vec3, v0: Vec3, v1: Vec3, v2: Vec3, hit: &TriangleHit) -> [f64; 3] {
    let (o, d, v0, v1, v2) = (o.as_dvec3(), d.as_dvec3(), v0.as_dvec3(), v1.as_dvec3(), v2.as_dvec3());
    let (e1, e2, s) = (v1 - v0, v2 - v0, o - v0);
    let det = e1.dot(d.cross(e2)).abs();
    let det_magnitude = e1.length() * d.length() * e2.length();
    let eps = f64::from(f32::EPSILON);
    let scale = |triple: f64, value: f32| eps * (triple + det_magnitude * f64::from(value).abs()) / det;
    [
        scale(e2.length() * s.length() * e1.length(), hit.t),
        scale(s.length() * d.length() * e2.length(), hit.u),
        scale(d.length() * s.length() * e1.length(), hit.v),
    ]
}

/// How many error scales apart two hits on the same triangle are (the largest of t, u, v).
fn hit_difference(args: (Vec3, Vec3, Vec3, Vec3, Vec3), a: &TriangleHit, b: &TriangleHit) -> f64 {
    let (o, d, v0, v1, v2) = args;
    let scale = hit_error_scale(o, d, v0, v1, v2, a);
    let diffs = [a.t - b.t, a.u - b.u, a.v - b.v].map(|x| f64::from(x).abs());
    diffs.iter().zip(scale).map(|(d, s)| d / s.max(1e-30)).fold(0.0, f64::max)
}

type TriangleArgs = (Vec3, Vec3, Vec3, Vec3, Vec3);

fn triangle_cases(n: usize) -> Vec<TriangleArgs> {
    let mut r = TestRng::new(6);
    let (a, b, c) = (Vec3::new(0.0, 0.0, 0.0), Vec3::new(1.0, 0.0, 0.0), Vec3::new(0.0, 1.0, 0.0));
    let above = Vec3::new(0.25, 0.25, 1.0);
    let down = -Vec3::Z;
    let nan = Vec3::new(f32::NAN, 0.0, 0.0);
    let inf = Vec3::new(f32::INFINITY, 0.0, 0.0);
    let mut v = vec![
        (above, down, a, b, c),                         // plain hit
        (Vec3::new(0.5, 0.5, 1.0), down, a, b, c),      // on the hypotenuse
        (Vec3::new(0.0, 0.0, 1.0), down, a, b, c),      // on a vertex
        (Vec3::new(-0.5, 0.25, 0.0), Vec3::X, a, b, c), // edge-on: in the plane
        (above, Vec3::X, a, b, c),                      // parallel above
        (above, down, a, a, c),                         // zero-area (two equal vertices)
        (above, down, a, b, Vec3::new(2.0, 0.0, 0.0)),  // collinear
        (above, Vec3::ZERO, a, b, c),                   // zero direction
        (above, -down, a, b, c),                        // behind the origin
        (Vec3::new(0.25, 0.25, 0.0), down, a, b, c),    // origin on the triangle (t = 0)
        (nan, down, a, b, c),
        (above, nan, a, b, c),
        (above, down, nan, b, c),
        (inf, down, a, b, c),
        (above, Vec3::new(0.0, 0.0, f32::NEG_INFINITY), a, b, c),
        (above * 1e30, down, a * 1e30, b * 1e30, c * 1e30),     // huge
        (above * 1e-30, down, a * 1e-30, b * 1e-30, c * 1e-30), // tiny (denormal products)
    ];
    while v.len() < n {
        let v0 = r.vec3(1.0);
        let v1 = v0 + r.vec3(0.5);
        let v2 = v0 + r.vec3(0.5);
        let origin = r.vec3(2.0);
        // Half of the rays aim at a point of the triangle's plane near it (many near edges).
        let target = if r.f32() < 0.5 {
            let (s, t) = (r.range(-0.05, 1.05), r.range(-0.05, 1.05));
            v0 + (v1 - v0) * s * (1.0 - t) + (v2 - v0) * s * t
        } else {
            r.vec3(1.0)
        };
        v.push((origin, (target - origin).normalize(), v0, v1, v2));
    }
    v
}

#[test]
fn ray_triangle_agrees() {
    let mut eq = equivalence();
    let cases = triangle_cases(1 << 17);
    let outcome = eq
        .run(
            "intersect_triangle",
            &cases,
            |_, &(o, d, a, b, c)| (intersect::intersect_triangle(o, d, a, b, c),),
            TRIANGLE,
        )
        .expect("runs");
    report(&outcome);
    let cpu = outcome.output(Backend::Cpu).unwrap();
    let gl = outcome.output(Backend::Gl).unwrap();
    let comparison = outcome.comparison(Backend::Gl).unwrap();
    let near_edge = |h: &TriangleHit| h.u.min(h.v).min(1.0 - h.u - h.v) <= EDGE;
    let (mut flips, mut conditioned, mut worst) = (0, 0, 0.0f64);
    for &i in &comparison.mismatched {
        let ((want,), (got,)) = (cpu[i], gl[i]);
        if want.t < MISS && got.t < MISS {
            let scales = hit_difference(cases[i], &want, &got);
            assert!(
                scales <= CONDITIONED,
                "case {i} {:?}: CPU {want:?} vs GL {got:?}: {scales:.1} error scales",
                cases[i]
            );
            worst = worst.max(scales);
            conditioned += 1;
            continue;
        }
        let hit = if want.t == MISS { got } else { want };
        assert!(near_edge(&hit), "case {i} {:?}: CPU {want:?} vs GL {got:?}", cases[i]);
        flips += 1;
    }
    println!(
        "intersect_triangle: {flips} hit/miss flips, all within {EDGE} of an edge; {conditioned} common hits beyond \
         {TRIANGLE}, all within {worst:.2} (<= {CONDITIONED}) forward error scales"
    );
    assert!(flips * 1000 <= cases.len(), "{flips} flips of {}", cases.len());
    // The special cases (the first ones) agree exactly on hit or miss.
    for i in 0..17 {
        assert_eq!(cpu[i].0.t == MISS, gl[i].0.t == MISS, "special case {i} {:?}", cases[i]);
    }
    let hits = cpu.iter().filter(|(h,)| h.t < MISS).count();
    assert!(hits > cases.len() / 10, "{hits} hits: too few to compare");
}

type BoxArgs = (Vec3, Vec3, Vec3, Vec3, f32);

fn box_cases(n: usize) -> Vec<BoxArgs> {
    let mut r = TestRng::new(7);
    let (lo, hi) = (Vec3::splat(-1.0), Vec3::splat(1.0));
    let inv = |d: Vec3| intersect::safe_inverse(d);
    let mut v = vec![
        (Vec3::new(-2.0, 0.0, 0.0), inv(Vec3::X), lo, hi, MISS), // straight in
        (Vec3::new(-2.0, 1.0, 0.0), inv(Vec3::X), lo, hi, MISS), // along a face (y = max)
        (Vec3::new(-2.0, -1.0, -1.0), inv(Vec3::X), lo, hi, MISS), // along an edge
        (Vec3::new(-2.0, 1.0, 0.0), inv(Vec3::new(1.0, -0.0, 0.0)), lo, hi, MISS), // -0.0 component
        (Vec3::ZERO, inv(Vec3::Y), lo, hi, MISS),                // inside
        (Vec3::new(1.0, 0.0, 0.0), inv(Vec3::X), lo, hi, MISS),  // on the exit face
        (Vec3::new(-2.0, 0.0, 0.0), inv(Vec3::X), lo, hi, 0.5),  // t_max before the box
        (Vec3::new(-2.0, 0.0, 0.0), inv(-Vec3::X), lo, hi, MISS), // pointing away
        (Vec3::new(-2.0, 0.0, 0.0), inv(Vec3::X), Vec3::ZERO, Vec3::ZERO, MISS), // point box
        (Vec3::new(f32::NAN, 0.0, 0.0), inv(Vec3::X), lo, hi, MISS),
        (Vec3::new(-2.0, 0.0, 0.0), inv(Vec3::new(f32::NAN, 0.0, 0.0)), lo, hi, MISS),
        (Vec3::new(-2.0, 0.0, 0.0), inv(Vec3::ZERO), lo, hi, MISS), // zero direction
    ];
    let specials = v.len();
    while v.len() < n {
        let c = r.vec3(1.0);
        let e = Vec3::new(r.range(0.0, 0.5), r.range(0.0, 0.5), r.range(0.0, 0.5));
        let origin = r.vec3(2.0);
        let mut dir = r.unit_vector();
        // A quarter of the rays are axis-parallel, some starting on a face plane.
        if r.f32() < 0.25 {
            let axis = (r.next_u32() % 3) as usize;
            let mut d = Vec3::ZERO;
            d[axis] = if r.f32() < 0.5 { 1.0 } else { -1.0 };
            dir = d;
        }
        let mut o = origin;
        if r.f32() < 0.1 {
            let axis = (r.next_u32() % 3) as usize;
            o[axis] = if r.f32() < 0.5 { c[axis] - e[axis] } else { c[axis] + e[axis] };
        }
        let t_max = if r.f32() < 0.2 { r.range(0.0, 3.0) } else { MISS };
        v.push((o, inv(dir), c - e, c + e, t_max));
    }
    assert!(specials < n);
    v
}

#[test]
fn ray_box_agrees() {
    let mut eq = equivalence();
    let dirs: Vec<(Vec3,)> = floats_with_specials(1 << 15, 8, any_float)
        .chunks(3)
        .filter(|c| c.len() == 3)
        .map(|c| (Vec3::new(c[0], c[1], c[2]),))
        .collect();
    // 1 / x: GLSL ES only requires 2.5 ULP for division.
    assert_equivalent(
        &mut eq,
        "safe_inverse",
        &dirs,
        |_, &(d,)| (intersect::safe_inverse(d),),
        Tolerance::ulps(3).flushing_subnormals(),
    );

    let pairs: Vec<(f32, f32)> = floats_with_specials(1 << 14, 21, any_float)
        .chunks(2)
        .filter(|p| p.len() == 2 && !p[0].is_nan() && !p[1].is_nan())
        .map(|p| (p[0], p[1]))
        .collect();
    // Compare-and-select: exact, except that drivers may turn it into min/max, which do not
    // order +0 and -0 (measured: llvmpipe returns +0 for min_no_nan(0, -0), Rust -0).
    for function in ["min_no_nan", "max_no_nan"] {
        let select = |a: f32, b: f32| {
            if function == "min_no_nan" {
                intersect::min_no_nan(a, b)
            } else {
                intersect::max_no_nan(a, b)
            }
        };
        let outcome = eq.run(function, &pairs, |_, &(a, b)| (select(a, b),), Tolerance::EXACT).expect("runs");
        report(&outcome);
        let gl = outcome.output(Backend::Gl).unwrap();
        let mismatched = &outcome.comparison(Backend::Gl).unwrap().mismatched;
        for &i in mismatched {
            let (a, b) = pairs[i];
            assert!(a == 0.0 && b == 0.0 && gl[i].0 == 0.0, "{function}({a:e}, {b:e}) on GL: {}", gl[i].0);
        }
        println!("{function}: {} signed-zero pairs where GL picks the other zero", mismatched.len());
    }

    let cases = box_cases(1 << 17);
    let outcome = eq
        .run(
            "intersect_aabb",
            &cases,
            |_, &(o, inv, lo, hi, t)| (intersect::intersect_aabb(o, inv, lo, hi, t),),
            Tolerance::ulps(4).flushing_subnormals(),
        )
        .expect("runs");
    report(&outcome);
    let (cpu, gl) = (outcome.output(Backend::Cpu).unwrap(), outcome.output(Backend::Gl).unwrap());
    let mut flips = Vec::new();
    for &i in &outcome.comparison(Backend::Gl).unwrap().mismatched {
        let ((want,), (got,)) = (cpu[i], gl[i]);
        // Only hit/miss flips may differ, and only where the ray grazes the box: the entry
        // distance equals the exit distance up to rounding.
        let (o, inv, lo, hi, t_max) = cases[i];
        let (t0, t1) = ((lo - o) * inv, (hi - o) * inv);
        let enter = t0.min(t1).max_element().max(0.0);
        let exit = t0.max(t1).min_element().min(t_max);
        let grazing = (enter - exit).abs() <= 1e-5 * enter.abs().max(exit.abs()).max(1.0);
        assert!((want == MISS) != (got == MISS) && grazing, "case {i} {:?}: CPU {want} vs GL {got}", cases[i]);
        flips.push(i);
    }
    println!("intersect_aabb: {} hit/miss flips, all grazing", flips.len());
    assert!(flips.len() * 1000 <= cases.len(), "{} flips", flips.len());
    for i in 0..12 {
        assert_eq!(cpu[i].0.to_bits(), gl[i].0.to_bits(), "special case {i} {:?}", cases[i]);
    }
}

// ---------------------------------------------------------------------------------------------
// Full BVH traversal on LittlestTokyo.

type NodeArgs = (u32, Vec3, Vec3, UVec3, f32);

/// `per_node` rays at each node of `k`'s BVH, aimed through one of its children, a quarter of
/// them axis-parallel from that child's face plane (the slab test's rare "exit == 0" path),
/// some with a short `t_max`.
fn node_rays(k: &Scene, per_node: usize, seed: u64) -> Vec<NodeArgs> {
    let mut r = TestRng::new(seed);
    let nodes = k.nodes.len() as u32 / scene_data::NODE_TEXELS;
    let mut out = Vec::new();
    for node in 0..nodes {
        let used = (0..4).filter(|&c| node_child_box(k, node, c).0.x <= node_child_box(k, node, c).1.x).count();
        for _ in 0..per_node {
            let c = (r.next_u32() as usize) % used.max(1);
            let (lo, hi) = node_child_box(k, node, c);
            let target = lo + (hi - lo) * Vec3::new(r.f32(), r.f32(), r.f32());
            let mut origin = target + r.unit_vector() * (hi - lo).length().max(1e-3) * 2.0;
            let mut dir = (target - origin).normalize_or(Vec3::X);
            if r.f32() < 0.25 {
                let axis = (r.next_u32() % 3) as usize;
                dir = Vec3::ZERO;
                dir[axis] = if r.f32() < 0.5 { 1.0 } else { -1.0 };
                let face = (r.next_u32() % 3) as usize;
                origin = target - dir * (hi - lo).length();
                if face != axis {
                    origin[face] = if r.f32() < 0.5 { lo[face] } else { hi[face] };
                }
            }
            let inv_dir = intersect::safe_inverse(dir);
            let t_max = if r.f32() < 0.2 { r.range(0.0, 2.0 * (target - origin).length()) } else { MISS };
            out.push((node, origin, inv_dir, traverse::near_planes(inv_dir), t_max));
        }
    }
    out
}

#[test]
fn bvh_traversal_on_littlest_tokyo() {
    let scene = tracer::scene::load(&shared("scenes/threejs/LittlestTokyo.glb")).expect("LittlestTokyo loads");
    let bvh = tracer::bvh::build(&scene.triangles).expect("BVH");
    let packed = pack(&scene, &bvh, &RenderSettings::default()).expect("pack");
    let mut eq = equivalence();
    eq.set_scene(&packed.scene).expect("scene uploads");
    // GL traverses with the stack sized to this scene (fewer than 64 entries), as its kernel does;
    // the CPU keeps 64: a stack one entry short would drop subtrees and miss hits.
    assert!(packed.features.traversal_stack < traverse::STACK_SIZE as u32, "{:?}", packed.features);
    eq.set_specialization(packed.features.specialization());

    // Rays from around and inside the model towards points inside it.
    let b = scene.bounds();
    let (lo, hi) = (b.min - b.diagonal() * 0.1, b.max + b.diagonal() * 0.1);
    let mut r = TestRng::new(9);
    let point = |r: &mut TestRng, lo: Vec3, hi: Vec3| lo + (hi - lo) * Vec3::new(r.f32(), r.f32(), r.f32());
    let rays: Vec<(Vec3, Vec3, f32)> = (0..100_000)
        .map(|_| {
            let o = point(&mut r, lo, hi);
            (o, (point(&mut r, b.min, b.max) - o).normalize(), MISS)
        })
        .collect();
    let closest =
        eq.run("trace_closest", &rays, |s, &(o, d, t)| (traverse::trace_closest(s, o, d, t),), TRIANGLE).expect("runs");
    report(&closest);
    let cpu = closest.output(Backend::Cpu).unwrap();
    let gl = closest.output(Backend::Gl).unwrap();
    let k = eq.scene().clone();
    // The distance from ray i to triangle `tri`, on the CPU.
    let t_of = |i: usize, tri: u32| {
        let (o, d, _) = rays[i];
        let t = scene_data::fetch_triangle(&k, tri);
        intersect::intersect_triangle(o, d, t.v0, t.v1, t.v2).t
    };
    let mut different_triangle = Vec::new();
    let (mut same_triangle_beyond, mut same_triangle_worst) = (0, 0.0f64);
    for &i in &closest.comparison(Backend::Gl).unwrap().mismatched {
        let ((want,), (got,)): ((Hit,), (Hit,)) = (cpu[i], gl[i]);
        if want.triangle == got.triangle {
            let (o, d, _) = rays[i];
            let t = scene_data::fetch_triangle(&k, want.triangle);
            let as_hit = |h: &Hit| TriangleHit { t: h.t, u: h.u, v: h.v };
            let scales = hit_difference((o, d, t.v0, t.v1, t.v2), &as_hit(&want), &as_hit(&got));
            assert!(
                scales <= CONDITIONED,
                "ray {i}: same triangle, CPU {want:?} vs GL {got:?}: {scales:.1} error scales"
            );
            same_triangle_worst = same_triangle_worst.max(scales);
            same_triangle_beyond += 1;
            continue;
        }
        // A different triangle: both must be hits at (nearly) the same distance. The gap is
        // measured between the two backends' distances, and between the CPU's distances to
        // both triangles (MISS where the CPU misses GL's triangle, e.g. across a shared edge).
        assert!(want.triangle != NONE && got.triangle != NONE, "ray {i}: hit vs miss: CPU {want:?} vs GL {got:?}");
        let gap = (got.t - want.t).abs() / want.t;
        let cpu_gap = (t_of(i, got.triangle) - want.t).abs() / want.t;
        different_triangle.push((i, gap, cpu_gap));
    }
    let hits = cpu.iter().filter(|(h,)| h.triangle != NONE).count();
    println!(
        "trace_closest: {hits} of {} rays hit; {same_triangle_beyond} same-triangle hits beyond {TRIANGLE}, all within \
         {same_triangle_worst:.2} forward error scales; {} hit a different triangle on GL, relative t-gaps \
         (GL vs CPU t; CPU t of both triangles): {:?}",
        rays.len(),
        different_triangle.len(),
        different_triangle.iter().map(|(i, g, c)| format!("ray {i}: {g:.2e}; {c:.2e}")).collect::<Vec<_>>()
    );
    assert!(hits > rays.len() / 2, "{hits} hits: the rays should mostly hit");
    for &(i, gap, _) in &different_triangle {
        assert!(gap <= 1e-5, "ray {i}: GL's triangle is {gap:e} (relative) farther than the CPU's: not a near-tie");
    }
    assert!(different_triangle.len() * 1000 <= rays.len(), "{} near-ties", different_triangle.len());

    // Any-hit: nothing before the closest hit, something just after it, and the same as the
    // closest-hit answer without a bound.
    let shadow: Vec<(Vec3, Vec3, f32)> = rays
        .iter()
        .zip(cpu)
        .flat_map(|(&(o, d, _), (h,))| {
            let t = if h.triangle == NONE { 1.0 } else { h.t };
            [(o, d, MISS), (o, d, t * 0.999), (o, d, t * 1.001)]
        })
        .collect();
    let any =
        eq.run("occluded", &shadow, |s, &(o, d, t)| (traverse::occluded(s, o, d, t),), Tolerance::EXACT).expect("runs");
    report(&any);
    let (cpu_any, gl_any) = (any.output(Backend::Cpu).unwrap(), any.output(Backend::Gl).unwrap());
    let near_tie = |ray: usize| different_triangle.iter().any(|&(i, _, _)| i == ray);
    let mut disagreements = 0;
    for (ray, hit) in cpu.iter().enumerate() {
        let hit = hit.0.triangle != NONE;
        let gl_hit = gl[ray].0.triangle != NONE;
        let [unbounded, before, after] = [0, 1, 2].map(|j| gl_any[ray * 3 + j].0);
        assert_eq!(unbounded, gl_hit, "ray {ray}: GL's any-hit disagrees with its closest hit");
        assert_eq!(cpu_any[ray * 3].0, hit, "ray {ray}: CPU's any-hit disagrees with its closest hit");
        if hit && !(before == cpu_any[ray * 3 + 1].0 && after == cpu_any[ray * 3 + 2].0) {
            disagreements += 1;
            assert!(near_tie(ray) || !before, "ray {ray}: GL finds an occluder before the CPU's closest hit");
        }
    }
    println!("occluded: {disagreements} rays where GL and CPU bounded any-hit answers differ");
    assert!(disagreements * 1000 <= rays.len(), "{disagreements} bounded any-hit disagreements");

    // Closest hits with every leaf intersected as soon as its node is visited (the path the
    // kernel takes beyond `leaf_stack_limit`, for trees too deep to push every leaf): GL still
    // agrees with the CPU, and both with the hits above.
    assert_eq!(packed.scene.leaf_stack_limit, packed.features.traversal_stack, "Tokyo fits with every leaf pushed");
    let mut at_once = packed.scene.clone();
    at_once.leaf_stack_limit = 0;
    eq.set_scene(&at_once).expect("scene uploads");
    let some = &rays[..20_000];
    let closest_at_once =
        eq.run("trace_closest", some, |s, &(o, d, t)| (traverse::trace_closest(s, o, d, t),), TRIANGLE).expect("runs");
    report(&closest_at_once);
    let gl_at_once = closest_at_once.output(Backend::Gl).unwrap();
    let near = |a: &Hit, b: &Hit| {
        a.triangle == b.triangle || (a.triangle != NONE && b.triangle != NONE && (a.t - b.t).abs() <= 1e-5 * b.t)
    };
    let differ = (0..some.len()).filter(|&i| !near(&gl_at_once[i].0, &cpu[i].0)).count();
    assert_eq!(differ, 0, "leaves intersected at once: {differ} GL hits are neither the same triangle nor a near-tie");
}

// ---------------------------------------------------------------------------------------------
// Scene data: fetches and texture lookups on a textured scene packed by `pack()`.

#[test]
fn texture_and_scene_fetches_agree() {
    let scene = tracer::scene::load(&shared("scenes/khronos/Duck/glTF-Binary/Duck.glb")).expect("Duck loads");
    let bvh = tracer::bvh::build(&scene.triangles).expect("BVH");
    let packed = pack(&scene, &bvh, &RenderSettings::default()).expect("pack");
    assert!(packed.features.textures, "the Duck is textured");
    let mut eq = equivalence();
    eq.set_scene(&packed.scene).expect("scene uploads");
    let k = eq.scene().clone();
    let triangles = packed.triangle_count as u32;
    let mut r = TestRng::new(10);

    let indices: Vec<(u32,)> = (0..triangles).map(|i| (i,)).collect();
    assert_equivalent(
        &mut eq,
        "fetch_triangle",
        &indices,
        |s, &(i,)| (scene_data::fetch_triangle(s, i),),
        Tolerance::EXACT,
    );
    let node_rays = node_rays(&k, 16, 11);
    assert_equivalent(
        &mut eq,
        "intersect_node",
        &node_rays,
        |s, &(node, origin, inv_dir, near, t_max)| (traverse::intersect_node(s, node, origin, inv_dir, near, t_max),),
        Tolerance::EXACT,
    );
    let materials: Vec<(u32,)> = (0..k.materials.len() as u32 / scene_data::MATERIAL_TEXELS).map(|i| (i,)).collect();
    assert_equivalent(
        &mut eq,
        "fetch_material",
        &materials,
        |s, &(i,)| (scene_data::fetch_material(s, i),),
        Tolerance::EXACT,
    );
    let barycentric: Vec<(u32, f32, f32)> = (0..1 << 15)
        .map(|_| {
            let (u, v) = (r.f32(), r.f32());
            let (u, v) = if u + v > 1.0 { (1.0 - u, 1.0 - v) } else { (u, v) };
            (r.next_u32() % triangles, u, v)
        })
        .collect();
    assert_equivalent(
        &mut eq,
        "texcoord",
        &barycentric,
        |s, &(i, u, v)| (scene_data::texcoord(s, i, u, v),),
        Tolerance::ulps(4),
    );
    assert_equivalent(
        &mut eq,
        "shading_normal",
        &barycentric,
        |s, &(i, u, v)| (scene_data::shading_normal(s, i, u, v),),
        Tolerance::ulps(4),
    );

    // Wrap modes on every axis, coordinates far outside the texture included.
    let textures = k.texture_info.len() as u32;
    assert!(textures > 0);
    let wraps: Vec<(i32, i32, u32)> = (0..1 << 15)
        .map(|j| {
            let size = 1 + (r.next_u32() % 700) as i32;
            let i = match j % 4 {
                0 => r.next_u32() as i32,
                _ => (r.next_u32() % 4000) as i32 - 2000,
            };
            (i, size, r.next_u32() % 3)
        })
        .chain([(i32::MIN, 7, 0), (i32::MIN, 7, 2), (i32::MAX, 7, 2), (i32::MIN, 1, 1), (-1, 1, 2)])
        .collect();
    assert_equivalent(
        &mut eq,
        "wrap_coordinate",
        &wraps,
        |_, &(i, n, m)| (scene_data::wrap_coordinate(i, n, m),),
        Tolerance::EXACT,
    );
    let texels: Vec<(UVec4, i32, i32)> = (0..1 << 15)
        .map(|_| {
            let mut info = k.texture_info.fetch(r.next_u32() % textures);
            info.w = (r.next_u32() % 3) | ((r.next_u32() % 3) << 8);
            let (w, h) = (info.y as i32, info.z as i32);
            (info, (r.next_u32() % (6 * w as u32)) as i32 - 3 * w, (r.next_u32() % (6 * h as u32)) as i32 - 3 * h)
        })
        .collect();
    // Texels are 8-bit sRGB decoded in the kernel: `powf` is not correctly rounded on GPUs.
    assert_equivalent(&mut eq, "texel", &texels, |s, &(info, x, y)| (scene_data::texel(s, info, x, y),), SRGB);
    let lookups: Vec<(u32, Vec2)> = (0..1 << 16)
        .map(|j| {
            let uv = match j % 64 {
                0 => Vec2::new(f32::NAN, 0.5),
                1 => Vec2::new(1e6, -1e6),
                2 => Vec2::new(0.0, 1.0),
                _ => Vec2::new(r.range(-2.0, 3.0), r.range(-2.0, 3.0)),
            };
            (r.next_u32() % textures, uv)
        })
        .collect();
    // Bilinear weights: a few ULP (products and sums may be fused or reordered on GPUs).
    assert_equivalent(
        &mut eq,
        "sample_texture",
        &lookups,
        |s, &(i, uv)| (scene_data::sample_texture(s, i, uv),),
        SRGB.with_absolute(1e-6),
    );
}

/// The sRGB decode (`powf(2.4)`): GLSL ES computes `pow` as `exp2(y * log2(x))`, not correctly
/// rounded. Measured on llvmpipe; see the printed maxima.
const SRGB: Tolerance = Tolerance::ulps(16).flushing_subnormals();

#[test]
fn srgb_decoding_agrees() {
    let mut eq = equivalence();
    let mut r = TestRng::new(20);
    // Every byte value in every lane, then random words.
    let mut words: Vec<(u32,)> =
        (0..256u32).flat_map(|b| [(b,), (b << 8,), (b << 16,), (b << 24,), (b * 0x0101_0101,)]).collect();
    while words.len() < 1 << 16 {
        words.push((r.next_u32(),));
    }
    assert_equivalent(&mut eq, "decode_srgba8", &words, |_, &(w,)| (scene_data::decode_srgba8(w),), SRGB);
    let channels: Vec<(f32,)> = (0..=255u32)
        .map(|b| (b as f32 / 255.0,))
        .chain([(0.04045,), (0.04045f32.next_up(),), (0.0,), (1.0,)])
        .chain((0..1 << 14).map(|_| (r.f32(),)))
        .collect();
    assert_equivalent(&mut eq, "srgb_to_linear", &channels, |_, &(c,)| (scene_data::srgb_to_linear(c),), SRGB);
}

/// Radiance for the tone curves: log-uniform over 2^-20..2^16 per channel (greys and saturated
/// colours alike), and zeros, negatives, NaN and infinities, which display as black.
fn radiance_samples(n: usize, seed: u64) -> Vec<Vec3> {
    let mut r = TestRng::new(seed);
    let mut v = vec![
        Vec3::ZERO,
        Vec3::ONE,
        Vec3::splat(0.18),
        Vec3::splat(0.76),
        Vec3::new(1e6, 0.0, 0.0),
        Vec3::new(-1.0, 0.5, 2.0),
        Vec3::new(f32::NAN, 1.0, f32::INFINITY),
        Vec3::new(f32::NEG_INFINITY, f32::MAX, f32::MIN_POSITIVE),
    ];
    while v.len() < n {
        let channel = |r: &mut TestRng| r.range(-20.0, 16.0).exp2();
        v.push(if r.f32() < 0.25 {
            Vec3::splat(channel(&mut r))
        } else {
            Vec3::new(channel(&mut r), channel(&mut r), channel(&mut r))
        });
    }
    v
}

/// The tone curves end in values in [0, 1]: 2e-6 absolute (about 1/2000 of an 8-bit step), or
/// 64 ULP where GPUs' `pow`/`log2` (exp2(y log2 x), not correctly rounded) meet small values.
const TONE: Tolerance = Tolerance::ulps(64).with_absolute(2e-6).flushing_subnormals();
/// AgX takes `log2`, a 6th-degree polynomial and `pow(2.2)` of it: the GPU's log2/pow errors
/// grow to 1.35e-5 absolute on llvmpipe (1/290 of an 8-bit display step); 3e-5 is allowed.
/// `tone_map` and `display_srgb` include AgX.
const TONE_AGX: Tolerance = Tolerance::ulps(64).with_absolute(3e-5).flushing_subnormals();

#[test]
fn tone_mapping_agrees() {
    use tracer::kernel::tonemap;
    let mut eq = equivalence();
    let radiance = radiance_samples(1 << 14, 21);
    let finite: Vec<(Vec3,)> =
        radiance.iter().filter(|c| c.is_finite() && c.min_element() >= 0.0).map(|&c| (c,)).collect();
    assert_equivalent(&mut eq, "pbr_neutral", &finite, |_, &(c,)| (tonemap::pbr_neutral(c),), TONE);
    assert_equivalent(&mut eq, "aces_fitted", &finite, |_, &(c,)| (tonemap::aces_fitted(c),), TONE);
    assert_equivalent(&mut eq, "agx", &finite, |_, &(c,)| (tonemap::agx(c),), TONE_AGX);
    let mut r = TestRng::new(22);
    let calls: Vec<(Vec3, u32, f32)> = radiance
        .iter()
        .enumerate()
        .map(|(i, &c)| (c, i as u32 % 5, if i % 3 == 0 { 1.0 } else { r.range(-8.0, 8.0).exp2() }))
        .collect();
    assert_equivalent(&mut eq, "tone_map", &calls, |_, &(c, op, e)| (tonemap::tone_map(c, op, e),), TONE_AGX);
    assert_equivalent(&mut eq, "display_srgb", &calls, |_, &(c, op, e)| (tonemap::display_srgb(c, op, e),), TONE_AGX);
    let channels: Vec<(f32,)> =
        (0..=1 << 12).map(|i| (i as f32 / 4096.0,)).chain([(0.0031308,), (0.0031308f32.next_up(),)]).collect();
    assert_equivalent(&mut eq, "linear_to_srgb", &channels, |_, &(c,)| (tonemap::linear_to_srgb(c),), SRGB);
}

// ---------------------------------------------------------------------------------------------
// Divergence hazards: the DSL's rule (Rust's meaning) on every target.

#[test]
fn float_to_int_conversions_saturate_like_rust() {
    let mut eq = equivalence();
    let xs: Vec<(f32,)> = floats_with_specials(1 << 16, 11, any_float).into_iter().map(|x| (x,)).collect();
    assert_equivalent(&mut eq, "float_to_u32", &xs, |_, &(x,)| (hazards::float_to_u32(x),), Tolerance::EXACT);
    assert_equivalent(&mut eq, "float_to_i32", &xs, |_, &(x,)| (hazards::float_to_i32(x),), Tolerance::EXACT);
}

#[test]
fn int_to_float_rounds_to_nearest_even() {
    let mut eq = equivalence();
    let mut r = TestRng::new(12);
    let mut xs: Vec<u32> = vec![0, 1, u32::MAX, u32::MAX - 127, u32::MAX - 128, 0x8000_0000, 0x7fff_ffff];
    for k in 23..32 {
        let base = 1u32 << k;
        for d in 0..=64 {
            xs.push(base.wrapping_add(d));
            xs.push(base.wrapping_sub(d));
            // Exact halfway points between neighbouring floats (ties go to even).
            let step = 1u32 << (k - 23).max(0);
            xs.push(base.wrapping_add(step * d).wrapping_add(step / 2));
        }
    }
    while xs.len() < 1 << 17 {
        xs.push(r.next_u32() >> (r.next_u32() % 32));
    }
    let u: Vec<(u32,)> = xs.iter().map(|&x| (x,)).collect();
    assert_equivalent(&mut eq, "u32_to_float", &u, |_, &(x,)| (hazards::u32_to_float(x),), Tolerance::EXACT);
    assert_equivalent(&mut eq, "u24_to_float", &u, |_, &(x,)| (hazards::u24_to_float(x),), Tolerance::EXACT);
    let i: Vec<(i32,)> = xs.iter().flat_map(|&x| [(x as i32,), ((x as i32).wrapping_neg(),)]).collect();
    assert_equivalent(&mut eq, "i32_to_float", &i, |_, &(x,)| (hazards::i32_to_float(x),), Tolerance::EXACT);
}

#[test]
fn integer_division_truncates_toward_zero() {
    let mut eq = equivalence();
    let mut r = TestRng::new(13);
    let mut pairs: Vec<(i32, i32)> = Vec::new();
    for a in [-7, 7, -1, 1, 0, 6, -6, i32::MIN, i32::MAX, i32::MIN + 1] {
        for b in [-7, 7, -2, 2, -1, 1, 3, -3, i32::MIN, i32::MAX] {
            pairs.push((a, b));
        }
    }
    while pairs.len() < 1 << 16 {
        let a = r.next_u32() as i32 >> (r.next_u32() % 32);
        let b = r.next_u32() as i32 >> (r.next_u32() % 32);
        if b != 0 {
            pairs.push((a, b));
        }
    }
    // i32::MIN / -1 overflows: Rust panics (a kernel must not do it); GLSL's lp_div_i32 and WGSL
    // both give the wrapping result (MIN, remainder 0), which is what this reference states.
    assert_equivalent(
        &mut eq,
        "div_rem_i32",
        &pairs,
        |_, &(a, b)| {
            if (a, b) == (i32::MIN, -1) {
                (IVec2::new(a.wrapping_div(b), a.wrapping_rem(b)),)
            } else {
                (hazards::div_rem_i32(a, b),)
            }
        },
        Tolerance::EXACT,
    );
    let unsigned: Vec<(u32, u32)> = pairs.iter().map(|&(a, b)| (a as u32, b as u32)).collect();
    assert_equivalent(&mut eq, "div_rem_u32", &unsigned, |_, &(a, b)| (hazards::div_rem_u32(a, b),), Tolerance::EXACT);
}

#[test]
fn shifts_and_wrapping_arithmetic() {
    let mut eq = equivalence();
    let mut r = TestRng::new(14);
    let mut args: Vec<(u32, u32)> = Vec::new();
    for x in [0, 1, 0x8000_0000, u32::MAX, 0x1234_5678, 0xdead_beef] {
        for n in (0..=70).chain([u32::MAX, 0x8000_0000, 0x8000_001f]) {
            args.push((x, n));
        }
    }
    while args.len() < 1 << 16 {
        args.push((r.next_u32(), r.next_u32() >> (r.next_u32() % 32)));
    }
    assert_equivalent(&mut eq, "shifts", &args, |_, &(x, n)| (hazards::shifts(x, n),), Tolerance::EXACT);
    let xs: Vec<(u32,)> = args.iter().map(|&(x, n)| (x ^ n,)).collect();
    assert_equivalent(&mut eq, "literal_shifts", &xs, |_, &(x,)| (hazards::literal_shifts(x),), Tolerance::EXACT);
    assert_equivalent(&mut eq, "wrapping_ops", &args, |_, &(a, b)| (hazards::wrapping_ops(a, b),), Tolerance::EXACT);
}

#[test]
fn float_rounding_and_classification() {
    let mut eq = equivalence();
    let xs: Vec<(f32,)> = floats_with_specials(1 << 16, 15, any_float)
        .into_iter()
        .chain(floats_with_specials(1 << 14, 16, |r| r.range(-8.0, 8.0)))
        .map(|x| (x,))
        .collect();
    assert_equivalent(&mut eq, "rounding", &xs, |_, &(x,)| (hazards::rounding(x),), Tolerance::EXACT);
    assert_equivalent(&mut eq, "floor_ceil_abs", &xs, |_, &(x,)| (hazards::floor_ceil_abs(x),), Tolerance::EXACT);
    assert_equivalent(&mut eq, "classify", &xs, |_, &(x,)| (hazards::classify(x),), Tolerance::EXACT);
    assert_equivalent(&mut eq, "to_bits", &xs, |_, &(x,)| (hazards::to_bits(x),), Tolerance::EXACT);
    assert_equivalent(&mut eq, "specials", &xs, |_, &(x,)| (hazards::specials(x),), Tolerance::EXACT);
}

#[test]
fn float_remainder_truncates() {
    let mut eq = equivalence();
    let mut r = TestRng::new(17);
    let mut pairs: Vec<(f32, f32)> = vec![(5.5, 2.0), (-5.5, 2.0), (5.5, -2.0), (-5.5, -2.0), (-0.0, 1.0), (1.0, 0.5)];
    while pairs.len() < 1 << 16 {
        let a = r.range(-1000.0, 1000.0);
        let b = r.range(0.01, 10.0) * if r.f32() < 0.5 { -1.0 } else { 1.0 };
        pairs.push((a, b));
    }
    // GLSL's a - b * trunc(a / b) rounds the quotient; Rust's % is exact. Quotients here stay
    // below 2^17, so the difference is a few ULP of b * quotient (measured and printed).
    let outcome = assert_equivalent(
        &mut eq,
        "fmod",
        &pairs,
        |_, &(a, b)| (hazards::fmod(a, b),),
        Tolerance::EXACT.with_absolute(2e-4),
    );
    // The sign of the result is the dividend's (truncation, not GLSL mod's floor).
    let gl = outcome.output(Backend::Gl).unwrap();
    for (&(a, b), &(m,)) in pairs.iter().zip(gl) {
        assert!(m == 0.0 || m.is_sign_negative() == a.is_sign_negative(), "{a} % {b} = {m} on GL");
    }
}

/// Runs `function` on subnormal inputs and asserts that GL either keeps them (the CPU's answer)
/// or flushes them to zero: its answer is then the CPU's for +0 or -0 (outputs may flush too).
/// Returns how many inputs GL flushed.
fn assert_flushed_or_kept<I, O>(
    eq: &mut Equivalence,
    function: &str,
    inputs: &[f32],
    make: impl Fn(f32) -> I + Sync,
    f: impl Fn(&I) -> O + Sync,
    tolerance: Tolerance,
) -> usize
where
    I: Values + Sync,
    O: Values + Send,
{
    let tolerance = tolerance.flushing_subnormals();
    let args: Vec<I> = inputs.iter().map(|&x| make(x)).collect();
    let outcome = eq.run(function, &args, |_, i| f(i), tolerance).unwrap_or_else(|e| panic!("{function}: {e}"));
    report(&outcome);
    let gl = outcome.output(Backend::Gl).unwrap();
    let words = |o: &O| {
        let mut w = Vec::new();
        o.push_words(&mut w);
        w
    };
    let layout = O::layout();
    let mismatched = &outcome.comparison(Backend::Gl).unwrap().mismatched;
    for &i in mismatched {
        let got = words(&gl[i]);
        // Flushing is per operation (llvmpipe's `ceil` flushes its input, `abs` and negation
        // keep the bits): each output word is the CPU's for the input or for a zero.
        let references = [inputs[i], 0.0, -0.0].map(|x| words(&f(&make(x))));
        for (k, word) in layout.iter().enumerate() {
            let matches = references.iter().any(|want| {
                let one = std::slice::from_ref(word);
                tracer::backend::harness::compare_words(Backend::Gl, one, &want[k..=k], &got[k..=k], tolerance)
                    .is_equivalent()
            });
            assert!(
                matches,
                "{function}({:e}) word `{}`: GL's {:#x} is neither the CPU's for the input nor for a zero ({:x?})",
                inputs[i], word.path, got[k], references
            );
        }
    }
    mismatched.len()
}

#[test]
fn subnormals_flush_to_zero_or_are_kept() {
    let mut eq = equivalence();
    let xs = subnormals(1 << 12, 22);
    let exact = Tolerance::EXACT;
    let flushed = [
        assert_flushed_or_kept(&mut eq, "to_bits", &xs, |x| (x,), |&(x,)| (hazards::to_bits(x),), exact),
        assert_flushed_or_kept(&mut eq, "classify", &xs, |x| (x,), |&(x,)| (hazards::classify(x),), exact),
        assert_flushed_or_kept(&mut eq, "rounding", &xs, |x| (x,), |&(x,)| (hazards::rounding(x),), exact),
        assert_flushed_or_kept(&mut eq, "floor_ceil_abs", &xs, |x| (x,), |&(x,)| (hazards::floor_ceil_abs(x),), exact),
        assert_flushed_or_kept(&mut eq, "float_to_i32", &xs, |x| (x,), |&(x,)| (hazards::float_to_i32(x),), exact),
        assert_flushed_or_kept(&mut eq, "specials", &xs, |x| (x,), |&(x,)| (hazards::specials(x),), exact),
        assert_flushed_or_kept(
            &mut eq,
            "safe_inverse",
            &xs,
            |x| (Vec3::new(x, 1.0, -x),),
            |&(d,)| (intersect::safe_inverse(d),),
            Tolerance::ulps(3),
        ),
    ];
    println!("subnormal inputs flushed by GL, per function: {flushed:?} of {}", xs.len());
}

/// `min`/`max` with NaN are not defined by the DSL (kernels avoid them): without NaN they are
/// exact; with NaN, GL may return either operand or NaN, but nothing else.
#[test]
fn min_max_with_and_without_nan() {
    let mut eq = equivalence();
    let mut r = TestRng::new(18);
    let xs = floats_with_specials(1 << 12, 19, any_float);
    let mut pairs: Vec<(f32, f32)> = xs.iter().flat_map(|&a| [(a, f32::NAN), (f32::NAN, a)]).collect();
    while pairs.len() < 1 << 15 {
        pairs.push((any_float(&mut r), any_float(&mut r)));
    }
    let outcome = eq.run("min_max", &pairs, |_, &(a, b)| (hazards::min_max(a, b),), Tolerance::EXACT).expect("runs");
    report(&outcome);
    let gl = outcome.output(Backend::Gl).unwrap();
    let mut nan_cases_differing = 0;
    for &i in &outcome.comparison(Backend::Gl).unwrap().mismatched {
        let (a, b) = pairs[i];
        let is_either = |m: f32| m.to_bits() == a.to_bits() || m.to_bits() == b.to_bits() || m.is_nan();
        let (got,) = gl[i];
        assert!(a.is_nan() || b.is_nan() || (a == 0.0 && b == 0.0), "min/max({a}, {b}) without NaN differs: GL {got}");
        // +0 and -0 compare equal, so min/max may return either zero.
        assert!(is_either(got.x) && is_either(got.y), "min/max({a}, {b}) on GL = {got}: neither operand nor NaN");
        nan_cases_differing += 1;
    }
    let zeros = pairs.iter().filter(|(a, b)| *a == 0.0 && *b == 0.0).count();
    println!("min_max: {nan_cases_differing} NaN cases where GL differs from Rust (allowed); {zeros} zero pairs");
}

// ---------------------------------------------------------------------------------------------
// Normal maps (`kernel::normal_map`), on DamagedHelmet's packed normal-mapped data.

/// Normalisations (`sqrt`, division) and a cross product: GPU rounding of a few ULP in each,
/// compounded; components lie in [-1, 1]. Measured on llvmpipe; see the printout.
const NORMAL_MAP: Tolerance = Tolerance::ulps(64).with_absolute(2e-6).flushing_subnormals();

/// Whether `bend_normal(n, ng, wo)` is within `margin` of its decision (left alone or bent),
/// where GPU rounding may take the other branch.
fn near_bend_decision(n: Vec3, ng: Vec3, wo: Vec3, margin: f32) -> bool {
    let cos_n = n.dot(wo);
    let r = n * (2.0 * cos_n) - wo;
    cos_n.abs() < margin || (ng.dot(r) - tracer::kernel::normal_map::MIN_REFLECTION_COSINE).abs() < margin
}

#[test]
fn normal_map_functions_agree() {
    use tracer::kernel::normal_map;
    let mut eq = equivalence();
    let mut r = TestRng::new(41);
    // Pure functions: texel decoding, the tangent frame, the bend, adversarial inputs included.
    let texels: Vec<(Vec3, f32)> =
        (0..1 << 14).map(|_| (Vec3::new(r.f32(), r.f32(), r.f32()), r.range(-3.0, 3.0))).collect();
    assert_equivalent(
        &mut eq,
        "tangent_space_normal",
        &texels,
        |_, &(rgb, scale)| (normal_map::tangent_space_normal(rgb, scale),),
        NORMAL_MAP,
    );
    let frames: Vec<(Vec3, glam::Vec4, Vec3)> = (0..1 << 14)
        .map(|i| {
            let n = r.unit_vector();
            let t = match i % 16 {
                0 => glam::Vec4::ZERO,
                1 => (n * 2.0).extend(1.0),
                _ => r.vec3(1.0).extend(r.range(-1.0, 1.0)),
            };
            (n, t, r.vec3(1.0))
        })
        .filter(|&(n, t, m)| {
            // Away from the degenerate-tangent and zero-normal cut-offs: a tangent nearly along
            // the normal magnifies rounding by 1 / |tangent - normal part| (1.2e-5 absolute
            // measured at 1e-3).
            let tt = t.truncate() - n * n.dot(t.truncate());
            (tt.length() > 0.05 || t == glam::Vec4::ZERO || tt.length() < 1e-7) && m.length() > 0.05
        })
        .collect();
    assert_equivalent(
        &mut eq,
        "perturb_normal",
        &frames,
        |_, &(n, t, m)| (normal_map::perturb_normal(n, t, m),),
        NORMAL_MAP,
    );
    let bends: Vec<(Vec3, Vec3, Vec3)> = (0..1 << 15)
        .map(|i| {
            let ng = r.unit_vector();
            let v = r.unit_vector();
            let height = if i % 4 == 0 { 10f32.powf(-r.range(0.0, 5.0)) } else { r.f32() };
            let wo = ((v - ng * v.dot(ng)).normalize_or(ng.any_orthonormal_vector()) + ng * height).normalize();
            let n = if i % 7 == 0 { -ng } else { r.unit_vector() };
            (n, ng, wo)
        })
        .filter(|&(n, ng, wo)| !near_bend_decision(n, ng, wo, 1e-4))
        .collect();
    // Bent normals normalise a component that can be short (the reflection nearly along the
    // geometric normal) and sums of nearly opposite grazing vectors: 1.2e-5 absolute measured.
    assert_equivalent(
        &mut eq,
        "bend_normal",
        &bends,
        |_, &(n, ng, wo)| (normal_map::bend_normal(n, ng, wo),),
        NORMAL_MAP.with_absolute(3e-5),
    );

    // Scene functions on DamagedHelmet, which has a normal map.
    let scene = tracer::scene::load(&shared("scenes/khronos/DamagedHelmet/glTF/DamagedHelmet.gltf")).expect("loads");
    let bvh = tracer::bvh::build(&scene.triangles).expect("BVH");
    let packed = pack(&scene, &bvh, &RenderSettings::default()).expect("pack");
    assert!(packed.features.normal_map, "{:?}", packed.features);
    eq.set_scene(&packed.scene).expect("scene uploads");
    eq.set_specialization(packed.features.specialization());
    let k = eq.scene().clone();
    let triangles = packed.triangle_count as u32;
    let materials = (k.materials.len() as u32 - k.normal_map_first).min(k.normal_map_first / 2);
    let indices: Vec<(u32,)> = (0..materials).map(|i| (i,)).collect();
    assert_equivalent(
        &mut eq,
        "fetch_normal_map",
        &indices,
        |s, &(i,)| (normal_map::fetch_normal_map(s, i),),
        Tolerance::EXACT,
    );
    let barycentric: Vec<(u32, f32, f32)> = (0..1 << 15)
        .map(|_| {
            let (u, v) = (r.f32(), r.f32());
            let (u, v) = if u + v > 1.0 { (1.0 - u, 1.0 - v) } else { (u, v) };
            (r.next_u32() % triangles, u, v)
        })
        .collect();
    assert_equivalent(
        &mut eq,
        "interpolated_tangent",
        &barycentric,
        |s, &(i, u, v)| (normal_map::interpolated_tangent(s, i, u, v),),
        Tolerance::ulps(4).with_absolute(1e-7),
    );
    // Whole shading normals at random points, views down to grazing, both faces.
    let hits: Vec<(Hit, u32, Vec3, f32, Vec3, Vec3)> = barycentric
        .iter()
        .enumerate()
        .filter_map(|(j, &(i, u, v))| {
            let tri = scene_data::fetch_triangle(&k, i);
            let face = (tri.v1 - tri.v0).cross(tri.v2 - tri.v0).normalize_or_zero();
            let flip = if j % 2 == 0 { 1.0 } else { -1.0 };
            let ng = face * flip;
            let n = scene_data::shading_normal(&k, i, u, v).normalize_or_zero() * flip;
            let side = r.unit_vector();
            let wo = ((side - ng * side.dot(ng)).normalize_or_zero() + ng * 10f32.powf(-r.range(0.0, 4.0)))
                .normalize_or_zero();
            let ns = if n.dot(ng) > 0.0 { n } else { ng };
            let hit = Hit { triangle: i, t: 1.0, u, v };
            // Skip cases near the bend's decision for the mapped normal as the CPU computes it.
            let mapped = {
                let map = normal_map::fetch_normal_map(&k, tri.material);
                let uv = scene_data::texcoord(&k, i, u, v);
                let rgb = scene_data::sample_data_texture(&k, map.texture, uv);
                let t = normal_map::interpolated_tangent(&k, i, u, v);
                normal_map::perturb_normal(ns * flip, t, normal_map::tangent_space_normal(rgb.truncate(), map.scale))
                    * flip
            };
            (face != Vec3::ZERO && wo != Vec3::ZERO && !near_bend_decision(mapped, ng, wo, 1e-3)).then_some((
                hit,
                tri.material,
                ns,
                flip,
                ng,
                wo,
            ))
        })
        .collect();
    assert!(hits.len() > barycentric.len() / 2, "{} cases", hits.len());
    assert_equivalent(
        &mut eq,
        "normal_mapped",
        &hits,
        |s, &(hit, m, ns, flip, ng, wo)| (normal_map::normal_mapped(s, hit, m, ns, flip, ng, wo),),
        // The bilinear weights add their own few ULP before the frame and the bend.
        NORMAL_MAP.with_absolute(3e-5),
    );
}
