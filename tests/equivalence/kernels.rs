//! The kernel's building blocks: RNG (bit-exact), sampling, the metal-roughness BRDF, scene
//! data fetches, texture lookups, sRGB decoding and tone mapping.

use super::*;
use crate::intersection::node_rays;

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
    for backend in Backend::GPU {
        let gpu = outcome.output(backend).expect("ran");
        assert!(gpu.iter().all(|(x, _)| (0.0..1.0).contains(x)), "random floats stay in [0, 1) on {backend}");
    }
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
// Scene data: fetches and texture lookups on a textured scene packed by `pack()`.

#[test]
fn texture_and_scene_fetches_agree() {
    let scene = tracer::scene::load(&test_data("scenes/khronos/Duck/glTF-Binary/Duck.glb")).expect("Duck loads");
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
        // A divisor of 1, the largest axis and mirror period, negative multiples.
        .chain([(i32::MAX, 1, 0), (i32::MIN, 1, 0), (i32::MAX, 1, 2), (i32::MIN, 2, 0), (i32::MAX, 16384, 2)])
        .chain([(i32::MIN + 1, 16384, 0), (-16385, 16384, 0), (32767, 16384, 2), (-1, 16384, 2)])
        .collect();
    assert_equivalent(
        &mut eq,
        "wrap_coordinate",
        &wraps,
        |_, &(i, n, m)| (textures::wrap_coordinate(i, n, m),),
        Tolerance::EXACT,
    );
    assert_equivalent(&mut eq, "wrap_pair", &wraps, |_, &(i, n, m)| (textures::wrap_pair(i, n, m),), Tolerance::EXACT);
    let texels: Vec<(UVec4, i32, i32)> = (0..1 << 15)
        .map(|_| {
            let mut info = k.texture_info.fetch(r.next_u32() % textures);
            info.w = (r.next_u32() % 3) | ((r.next_u32() % 3) << 8);
            let (w, h) = (info.y as i32, info.z as i32);
            (info, (r.next_u32() % (6 * w as u32)) as i32 - 3 * w, (r.next_u32() % (6 * h as u32)) as i32 - 3 * h)
        })
        .collect();
    // Texels are 8-bit sRGB decoded in the kernel: `powf` is not correctly rounded on GPUs.
    assert_equivalent(&mut eq, "texel", &texels, |s, &(info, x, y)| (textures::texel(s, info, x, y),), SRGB);
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
        |s, &(i, uv)| (textures::sample_texture(s, i, uv),),
        SRGB.with_absolute(1e-6),
    );
    // The alpha-mask test's lookup: alpha alone (linear, no sRGB decode).
    assert_equivalent(
        &mut eq,
        "bilinear_alpha",
        &lookups,
        |s, &(i, uv)| (textures::bilinear_alpha(s, i, uv),),
        Tolerance::ulps(4).with_absolute(1e-6),
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
    assert_equivalent(&mut eq, "decode_srgba8", &words, |_, &(w,)| (textures::decode_srgba8(w),), SRGB);
    let channels: Vec<(f32,)> = (0..=255u32)
        .map(|b| (b as f32 / 255.0,))
        .chain([(0.04045,), (0.04045f32.next_up(),), (0.0,), (1.0,)])
        .chain((0..1 << 14).map(|_| (r.f32(),)))
        .collect();
    assert_equivalent(&mut eq, "srgb_to_linear", &channels, |_, &(c,)| (textures::srgb_to_linear(c),), SRGB);
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
