//! The kernel functions (`tracer::kernel::*`) as ordinary Rust on the CPU: reference values
//! for the RNG, distributions of the samplers (chi-square / Monte Carlo estimates with fixed
//! seeds), and the ray intersection routines on hand-checked and adversarial inputs.
//!
//! These are the reference semantics: the shader backends are compared against the same
//! functions elsewhere.

use crate::common;

use common::{assert_chi_square, assert_within_sigmas, mean_variance, TestRng};
use glam::{Vec2, Vec3};
use tracer::kernel::intersect::{intersect_aabb, intersect_triangle, safe_inverse, TriangleHit, MISS};
use tracer::kernel::rng::{pixel_seed, random_float, random_u32, wang_hash};
use tracer::kernel::sampling::{
    cos_sin_turns, cosine_hemisphere_pdf, cosine_sample_hemisphere, onb_from_normal, onb_to_world,
    sample_cosine_around, uniform_sample_triangle, INV_PI, PI,
};

// ---------------------------------------------------------------------------------------------
// RNG
// ---------------------------------------------------------------------------------------------

/// Thomas Wang's hash written independently of the kernel: `* 9` as `+ (k << 3)`.
fn reference_wang_hash(key: u32) -> u32 {
    let mut k = key ^ 61 ^ (key >> 16);
    k = k.wrapping_add(k << 3);
    k ^= k >> 4;
    k = k.wrapping_mul(0x27d4_eb2d);
    k ^ (k >> 15)
}

/// Marsaglia's xorshift32 (13, 17, 5), written in 64-bit arithmetic with explicit masking.
fn reference_xorshift32(x: u32) -> u32 {
    let mut x = x as u64;
    x ^= (x << 13) & 0xffff_ffff;
    x ^= x >> 17;
    x ^= (x << 5) & 0xffff_ffff;
    x as u32
}

/// Inverse of `x ^= x >> k`.
fn unxorshift_right(y: u32, k: u32) -> u32 {
    let mut x = y;
    for _ in 0..32 / k + 1 {
        x = y ^ (x >> k);
    }
    x
}

/// Inverse of `x ^= x << k`.
fn unxorshift_left(y: u32, k: u32) -> u32 {
    let mut x = y;
    for _ in 0..32 / k + 1 {
        x = y ^ (x << k);
    }
    x
}

/// The multiplicative inverse of an odd number modulo 2^32 (Newton's iteration).
fn inverse_mod_2_32(a: u32) -> u32 {
    let mut x = a; // correct to 3 bits for odd a
    for _ in 0..5 {
        x = x.wrapping_mul(2u32.wrapping_sub(a.wrapping_mul(x)));
    }
    x
}

/// The state whose xorshift32 successor is `y`.
fn xorshift32_predecessor(y: u32) -> u32 {
    unxorshift_left(unxorshift_right(unxorshift_left(y, 5), 17), 13)
}

/// The key whose Wang hash is `h` (every step of the hash is a bijection).
fn inverse_wang_hash(h: u32) -> u32 {
    let mut k = unxorshift_right(h, 15);
    k = k.wrapping_mul(inverse_mod_2_32(0x27d4_eb2d));
    k = unxorshift_right(k, 4);
    k = k.wrapping_mul(inverse_mod_2_32(9));
    let y = k ^ 61; // = key ^ (key >> 16)
    y ^ (y >> 16)
}

#[test]
fn wang_hash_known_values() {
    // By hand: wang_hash(61): 61 ^ 61 ^ 0 = 0, and every later step keeps 0.
    assert_eq!(wang_hash(61), 0);
    // By hand: wang_hash(0): 0 ^ 61 = 61; * 9 = 549; 549 ^ (549 >> 4) = 549 ^ 34 = 519;
    // 519 * 0x27d4eb2d mod 2^32 = 3232286779; ^ (>> 15 = 98641) = 3232319850.
    assert_eq!(wang_hash(0), 3_232_319_850);
    // Computed with an independent (Python, arbitrary precision) implementation.
    assert_eq!(wang_hash(1), 663_891_101);
    assert_eq!(wang_hash(2), 3_329_832_309);
    assert_eq!(wang_hash(12345), 232_713_235);
    assert_eq!(wang_hash(0x8000_0000), 2_903_943_700);
    assert_eq!(wang_hash(u32::MAX), 1_895_078_355);
}

#[test]
fn wang_hash_matches_reference() {
    let mut rng = TestRng::new(1);
    let edge = [0, 1, 60, 61, 62, 0xffff, 0x1_0000, 0x7fff_ffff, 0x8000_0000, u32::MAX - 1, u32::MAX];
    for key in edge.into_iter().chain((0..100_000).map(|_| rng.next_u32())).chain(0..10_000) {
        assert_eq!(wang_hash(key), reference_wang_hash(key), "key {key:#x}");
    }
    // The inverse used below is right (so the hash is a bijection and 61 is the only zero).
    for _ in 0..10_000 {
        let key = rng.next_u32();
        assert_eq!(inverse_wang_hash(wang_hash(key)), key);
    }
    assert_eq!(inverse_wang_hash(0), 61);
}

#[test]
fn xorshift32_known_values() {
    // Marsaglia's xorshift32 (13, 17, 5) from state 1. By hand: 1 ^ (1 << 13) = 8193;
    // >> 17 is 0; 8193 ^ (8193 << 5 = 262176) = 270369.
    let mut state = 1;
    let expected = [270_369, 67_634_689, 2_647_435_461, 307_599_695, 2_398_689_233];
    for e in expected {
        let out = random_u32(&mut state);
        assert_eq!(out, e);
        assert_eq!(state, e, "the returned value is the new state");
    }
}

#[test]
fn xorshift32_matches_reference() {
    let mut rng = TestRng::new(2);
    for _ in 0..100_000 {
        let s = rng.next_u32() | 1;
        let mut state = s;
        let out = random_u32(&mut state);
        assert_eq!(out, reference_xorshift32(s), "state {s:#x}");
        assert_eq!(xorshift32_predecessor(out), s);
    }
    // A long stream never reaches zero and agrees step by step.
    let (mut state, mut reference) = (pixel_seed(7, 3), pixel_seed(7, 3));
    for i in 0..1_000_000 {
        reference = reference_xorshift32(reference);
        assert_eq!(random_u32(&mut state), reference, "step {i}");
        assert_ne!(state, 0);
    }
}

#[test]
fn pixel_seed_is_never_zero() {
    // wang_hash is a bijection with wang_hash(61) == 0: every (pixel, frame) pair summing to
    // 61 (mod 2^32) takes the replacement path.
    for (pixel, frame) in [(61, 0), (0, 61), (30, 31), (62, u32::MAX), (u32::MAX, 62), (61u32.wrapping_sub(1000), 1000)]
    {
        assert_eq!(wang_hash(pixel.wrapping_add(frame)), 0);
        let seed = pixel_seed(pixel, frame);
        assert_ne!(seed, 0, "pixel {pixel} frame {frame}");
        // The stream from it does not stick at zero either.
        let mut state = seed;
        assert_ne!(random_u32(&mut state), 0);
    }
    // Elsewhere it is the hash itself.
    let mut rng = TestRng::new(3);
    for _ in 0..100_000 {
        let (pixel, frame) = (rng.next_u32() % (4096 * 4096), rng.next_u32());
        let seed = pixel_seed(pixel, frame);
        assert_ne!(seed, 0);
        let h = reference_wang_hash(pixel.wrapping_add(frame));
        if h != 0 {
            assert_eq!(seed, h);
        }
    }
    // Neighbouring pixels of one frame get distinct seeds (the hash is a bijection).
    let seeds: std::collections::HashSet<u32> = (0..640 * 480).map(|p| pixel_seed(p, 12345)).collect();
    assert_eq!(seeds.len(), 640 * 480);
}

/// `random_float` from the state whose next xorshift output is `output`.
fn float_for_output(output: u32) -> f32 {
    let mut state = xorshift32_predecessor(output);
    let f = random_float(&mut state);
    assert_eq!(state, output);
    f
}

#[test]
fn random_float_edge_cases_stay_below_one() {
    let largest = 1.0 - 2f32.powi(-24);
    let cases = [
        (u32::MAX, largest),
        (u32::MAX - 1, largest),
        (0xffff_ff80, largest),
        (0xffff_ff00, largest),
        (0xffff_feff, 1.0 - 2f32.powi(-23)),
        (0xffff_fe00, 1.0 - 2f32.powi(-23)),
        (0x8000_0000, 0.5),
        (0x7fff_ffff, 0.5 - 2f32.powi(-24)),
        (0x0000_01ff, 2f32.powi(-24)),
        (0x0000_0100, 2f32.powi(-24)),
        (0x0000_00ff, 0.0),
        (0x0000_0001, 0.0),
    ];
    for (output, expected) in cases {
        let f = float_for_output(output);
        assert_eq!(f, expected, "output {output:#x}");
        assert!((0.0..1.0).contains(&f));
    }
    // Outputs just below 2^32: the float is the top 24 bits, never rounded up to 1.0.
    for output in (u32::MAX - 100_000)..=u32::MAX {
        assert!(float_for_output(output) < 1.0, "output {output:#x}");
    }
}

#[test]
fn random_float_covers_all_24_bit_values_in_order() {
    // For each of the 2^24 top-bit patterns (low byte all ones, the worst case for rounding),
    // the float is exactly pattern * 2^-24: in [0, 1), distinct and increasing.
    let mut previous = -1.0f32;
    for top in 0..(1u32 << 24) {
        let f = float_for_output((top << 8) | 0xff);
        assert!(f > previous && f < 1.0, "pattern {top:#x}: {f} after {previous}");
        assert_eq!(f, top as f32 / 16_777_216.0);
        previous = f;
    }
}

#[test]
fn random_float_mean_and_variance() {
    const N: usize = 1_000_000;
    let mut state = pixel_seed(1234, 99);
    let draws: Vec<f64> = (0..N).map(|_| random_float(&mut state) as f64).collect();
    assert!(draws.iter().all(|x| (0.0..1.0).contains(x)));
    let (mean, variance, n) = mean_variance(draws.iter().copied());
    // Uniform [0, 1): mean 1/2 (variance of one draw 1/12); variance 1/12, and the variance
    // of one draw's squared deviation is E[(X - 1/2)^4] - (1/12)^2 = 1/80 - 1/144 = 1/180.
    let z_mean = assert_within_sigmas("mean", mean, 0.5, 1.0 / 12.0, n, 5.0);
    let z_var = assert_within_sigmas("variance", variance, 1.0 / 12.0, 1.0 / 180.0, n, 5.0);
    // And the histogram is flat (64 bins).
    let mut bins = [0u64; 64];
    for x in &draws {
        bins[(x * 64.0) as usize] += 1;
    }
    let chi2 = assert_chi_square("random_float histogram", &bins, &[N as f64 / 64.0; 64]);
    // Successive pairs are not correlated.
    let pairs = draws.windows(2).map(|w| (w[0] - 0.5) * (w[1] - 0.5));
    let (cov, _, n) = mean_variance(pairs);
    let z_cov = assert_within_sigmas("lag-1 covariance", cov, 0.0, 1.0 / 144.0, n, 5.0);
    eprintln!(
        "random_float: mean {mean:.5} ({z_mean:+.2} se), variance {variance:.5} ({z_var:+.2} se), \
         chi2 {chi2:.1} (63 dof), lag-1 covariance {z_cov:+.2} se"
    );
}

// ---------------------------------------------------------------------------------------------
// Sampling
// ---------------------------------------------------------------------------------------------

fn assert_frame(n: Vec3, tol: f32) {
    let onb = onb_from_normal(n);
    let (t, b) = (onb.tangent, onb.bitangent);
    assert_eq!(onb.normal, n);
    for (what, v) in [("|t|", t.length()), ("|b|", b.length())] {
        assert!((v - 1.0).abs() <= tol, "n {n}: {what} = {v}");
    }
    for (what, v) in [("t.b", t.dot(b)), ("t.n", t.dot(n)), ("b.n", b.dot(n))] {
        assert!(v.abs() <= tol, "n {n}: {what} = {v}");
    }
    // Right-handed: t x b = n.
    let c = t.cross(b);
    assert!((c - n).abs().max_element() <= tol, "n {n}: t x b = {c}");
    assert!(t.is_finite() && b.is_finite());
}

#[test]
fn onb_from_normal_is_orthonormal_and_right_handed() {
    let fixed = [
        Vec3::Z,
        Vec3::NEG_Z,
        Vec3::X,
        Vec3::NEG_X,
        Vec3::Y,
        Vec3::NEG_Y,
        Vec3::new(0.0, 0.0, -1.0),
        Vec3::new(1e-4, 0.0, -1.0).normalize(),
        Vec3::new(0.0, 1e-7, -1.0).normalize(),
        Vec3::new(1e-3, -1e-3, -1.0).normalize(),
        Vec3::new(-1e-6, 1e-6, -1.0).normalize(),
        Vec3::new(1.0, 0.0, -1e-8).normalize(),
        Vec3::new(1.0, 0.0, 1e-8).normalize(),
        Vec3::new(0.6, 0.8, 0.0),
        Vec3::new(1.0, 1.0, 1.0).normalize(),
        Vec3::new(-1.0, 2.0, -3.0).normalize(),
    ];
    for n in fixed {
        assert_frame(n, 2e-6);
    }
    let mut rng = TestRng::new(10);
    for _ in 0..200_000 {
        assert_frame(rng.unit_vector(), 2e-6);
    }
}

#[test]
fn onb_to_world_maps_local_axes() {
    let mut rng = TestRng::new(11);
    for _ in 0..1000 {
        let n = rng.unit_vector();
        let onb = onb_from_normal(n);
        assert_eq!(onb_to_world(onb, Vec3::Z), n);
        assert_eq!(onb_to_world(onb, Vec3::X), onb.tangent);
        assert_eq!(onb_to_world(onb, Vec3::Y), onb.bitangent);
        let v = rng.vec3(2.0);
        let w = onb_to_world(onb, v);
        assert!((w.length() - v.length()).abs() <= 1e-5 * v.length().max(1.0), "lengths are kept");
    }
}

/// The largest value `random_float` returns.
const BELOW_ONE: f32 = 1.0 - 1.0 / 16_777_216.0;

#[test]
fn cos_sin_turns_is_within_2e7_of_cos_and_sin() {
    // Every quarter-turn boundary, the ends, and 2^20 + 1 evenly spaced points of [0, 1].
    let n = 1 << 20;
    let points = (0..=n).map(|i| i as f32 / n as f32).chain([0.125, 0.375, 0.625, 0.875, BELOW_ONE]);
    let mut worst = 0.0f64;
    for t in points {
        let cs = cos_sin_turns(t);
        let angle = std::f64::consts::TAU * t as f64;
        let error = (cs.x as f64 - angle.cos()).abs().max((cs.y as f64 - angle.sin()).abs());
        worst = worst.max(error);
        assert!(error <= 2e-7, "t = {t}: ({}, {}), error {error:e}", cs.x, cs.y);
    }
    // Dropping the last term of either polynomial breaks the bound: 3e-7 (sine) and 4e-6
    // (cosine) at an eighth of a turn.
    println!("worst error {worst:e}");
}

#[test]
fn cosine_samples_are_unit_and_in_the_hemisphere() {
    let edges = [0.0, 1e-7, 0.25, 0.5, 0.999, BELOW_ONE];
    for u1 in edges {
        for u2 in edges {
            let d = cosine_sample_hemisphere(u1, u2);
            assert!((d.length() - 1.0).abs() <= 1e-6, "({u1}, {u2}) -> {d}");
            assert!(d.z > 0.0, "({u1}, {u2}) -> {d}");
        }
    }
    assert_eq!(cosine_sample_hemisphere(0.0, 0.3), Vec3::Z);
    let mut rng = TestRng::new(20);
    let normals = [Vec3::Z, Vec3::NEG_Z, Vec3::X, Vec3::NEG_Y, Vec3::new(1e-4, 0.0, -1.0).normalize()];
    for i in 0..500_000 {
        let n = if i < normals.len() * 1000 { normals[i % normals.len()] } else { rng.unit_vector() };
        let (u1, u2) = if i % 7 == 0 { (BELOW_ONE, rng.f32()) } else { (rng.f32(), rng.f32()) };
        let d = sample_cosine_around(n, u1, u2);
        assert!((d.length() - 1.0).abs() <= 2e-6, "n {n}, ({u1}, {u2}) -> {d}");
        assert!(d.dot(n) >= 0.0, "n {n}, ({u1}, {u2}) -> {d}: below the surface");
    }
}

#[test]
fn cosine_sampling_has_the_stated_pdf() {
    const N: usize = 1_000_000;
    const BINS: usize = 20;
    let mut rng = TestRng::new(21);
    // cos(theta) of a cosine-weighted direction has density 2c on [0, 1]: a bin [a, b]
    // holds b^2 - a^2 of the samples. Azimuth is uniform. Checked in world space around
    // random normals (through the frame) and in local space.
    let mut cos_bins = [0u64; BINS];
    let mut phi_bins = [0u64; BINS];
    let mut estimates = Vec::with_capacity(N);
    let mut estimates_cos3 = Vec::with_capacity(N);
    for _ in 0..N {
        let n = rng.unit_vector();
        let (u1, u2) = (rng.f32(), rng.f32());
        let d = sample_cosine_around(n, u1, u2);
        let cos_theta = d.dot(n).clamp(0.0, 1.0);
        cos_bins[((cos_theta * BINS as f32) as usize).min(BINS - 1)] += 1;
        let local = cosine_sample_hemisphere(u1, u2);
        let phi = local.y.atan2(local.x).rem_euclid(2.0 * std::f32::consts::PI);
        phi_bins[((phi / (2.0 * std::f32::consts::PI) * BINS as f32) as usize).min(BINS - 1)] += 1;
        // Monte Carlo estimates of the integrals of cos^2 and cos^3 over the hemisphere,
        // f / pdf with the kernel's pdf.
        let pdf = cosine_hemisphere_pdf(cos_theta) as f64;
        let c = cos_theta as f64;
        estimates.push(c * c / pdf);
        estimates_cos3.push(c * c * c / pdf);
    }
    let expected_cos: Vec<f64> = (0..BINS)
        .map(|i| {
            let (a, b) = (i as f64 / BINS as f64, (i + 1) as f64 / BINS as f64);
            N as f64 * (b * b - a * a)
        })
        .collect();
    let chi_cos = assert_chi_square("cos theta histogram", &cos_bins, &expected_cos);
    let chi_phi = assert_chi_square("azimuth histogram", &phi_bins, &[N as f64 / BINS as f64; BINS]);
    // Integral of cos^2 over the hemisphere = 2 pi / 3; the estimator is pi cos with variance
    // pi^2 (1/2 - 4/9) = pi^2 / 18 under the cosine density.
    let pi = std::f64::consts::PI;
    let (mean, _, n) = mean_variance(estimates);
    let z2 = assert_within_sigmas("integral of cos^2", mean, 2.0 * pi / 3.0, pi * pi / 18.0, n, 5.0);
    // Integral of cos^3 = pi / 2; the estimator pi cos^2 has variance pi^2 (1/3 - 1/4).
    let (mean3, _, n) = mean_variance(estimates_cos3);
    let z3 = assert_within_sigmas("integral of cos^3", mean3, pi / 2.0, pi * pi / 12.0, n, 5.0);
    eprintln!(
        "cosine sampling: chi2(cos) {chi_cos:.1}, chi2(phi) {chi_phi:.1} (19 dof), \
         integral of cos^2 {mean:.5} ({z2:+.2} se), of cos^3 {mean3:.5} ({z3:+.2} se)"
    );
}

#[test]
fn cosine_pdf_values() {
    assert_eq!(cosine_hemisphere_pdf(1.0), INV_PI);
    assert_eq!(cosine_hemisphere_pdf(0.0), 0.0);
    assert_eq!(cosine_hemisphere_pdf(-0.5), 0.0, "below the surface");
    assert!((cosine_hemisphere_pdf(0.5) - 0.5 / std::f32::consts::PI).abs() < 1e-8);
    assert_eq!(PI, std::f32::consts::PI);
    // The pdf integrates to one over the hemisphere: 2 pi * integral of c / pi dc on [0, 1],
    // by the midpoint rule in cos theta.
    let steps = 100_000;
    let integral: f64 = (0..steps)
        .map(|i| {
            let c = (i as f64 + 0.5) / steps as f64;
            2.0 * std::f64::consts::PI * cosine_hemisphere_pdf(c as f32) as f64 / steps as f64
        })
        .sum();
    assert!((integral - 1.0).abs() < 1e-5, "{integral}");
}

#[test]
fn uniform_sample_triangle_is_inside_and_uniform() {
    let edges = [0.0, 1e-7, 0.5, BELOW_ONE];
    for u1 in edges {
        for u2 in edges {
            let b = uniform_sample_triangle(u1, u2);
            assert!(b.x >= 0.0 && b.y >= 0.0 && b.x + b.y <= 1.0, "({u1}, {u2}) -> {b}");
        }
    }
    // Split the triangle u, v >= 0, u + v <= 1 into K^2 congruent triangles (K per side),
    // each with probability 1 / K^2 under a uniform density.
    const K: usize = 8;
    const N: usize = 1_000_000;
    let mut cells = [[0u64; 2 * K]; K]; // [row by u][2 * column + inverted]
    let mut rng = TestRng::new(30);
    let mut sum = Vec2::ZERO.as_dvec2();
    for _ in 0..N {
        let b = uniform_sample_triangle(rng.f32(), rng.f32());
        assert!(b.x >= 0.0 && b.y >= 0.0 && b.x + b.y <= 1.0 + 1e-7, "{b}");
        sum += b.as_dvec2();
        let (x, y) = (b.x as f64 * K as f64, b.y as f64 * K as f64);
        let (i, j) = ((x as usize).min(K - 1), (y as usize).min(K - 1));
        let inverted = x - i as f64 + (y - j as f64) >= 1.0;
        if i + j < K && (!inverted || i + j < K - 1) {
            cells[i][2 * j + inverted as usize] += 1;
        } else {
            // On the hypotenuse (rounding): count it in the upright cell it borders.
            cells[i][2 * (K - 1 - i)] += 1;
        }
    }
    let observed: Vec<u64> = (0..K)
        .flat_map(|i| {
            let row = cells[i];
            (0..K - i).flat_map(move |j| {
                let upright = std::iter::once(row[2 * j]);
                let inverted = (i + j < K - 1).then_some(row[2 * j + 1]);
                upright.chain(inverted)
            })
        })
        .collect();
    assert_eq!(observed.len(), K * K);
    assert_eq!(observed.iter().sum::<u64>(), N as u64);
    let chi2 = assert_chi_square("triangle cells", &observed, &vec![N as f64 / (K * K) as f64; K * K]);
    // The centroid: mean barycentrics 1/3 each (variance of one coordinate 1/18).
    let mean = sum / N as f64;
    assert_within_sigmas("mean u", mean.x, 1.0 / 3.0, 1.0 / 18.0, N, 5.0);
    assert_within_sigmas("mean v", mean.y, 1.0 / 3.0, 1.0 / 18.0, N, 5.0);
    eprintln!("uniform_sample_triangle: chi2 {chi2:.1} ({} dof)", K * K - 1);
}

// ---------------------------------------------------------------------------------------------
// Ray / triangle
// ---------------------------------------------------------------------------------------------

const V0: Vec3 = Vec3::new(0.0, 0.0, 0.0);
const V1: Vec3 = Vec3::new(1.0, 0.0, 0.0);
const V2: Vec3 = Vec3::new(0.0, 1.0, 0.0);

fn hit(t: f32, u: f32, v: f32) -> TriangleHit {
    TriangleHit { t, u, v }
}

fn assert_miss(h: TriangleHit, what: &str) {
    assert_eq!(h.t, MISS, "{what}: expected a miss, got {h:?}");
}

/// From above the unit right triangle in z = 0, straight down onto (x, y).
fn down_at(x: f32, y: f32) -> TriangleHit {
    intersect_triangle(Vec3::new(x, y, 1.0), Vec3::NEG_Z, V0, V1, V2)
}

#[test]
fn triangle_hand_checked_hits() {
    // e1 = X, e2 = Y, p = dir x e2 = X, det = 1, s = (0.25, 0.5, 1), u = s.p = 0.25,
    // q = s x e1 = (0, 1, -0.5), v = dir.q = 0.5, t = e2.q = 1.
    assert_eq!(down_at(0.25, 0.5), hit(1.0, 0.25, 0.5));
    // Two-sided: from below the same point.
    assert_eq!(intersect_triangle(Vec3::new(0.25, 0.5, -2.0), Vec3::Z, V0, V1, V2), hit(2.0, 0.25, 0.5));
    // A non-unit direction: t is in units of `dir`.
    let (a, b, c) = (Vec3::new(0.0, 0.0, 1.0), Vec3::new(4.0, 0.0, 1.0), Vec3::new(0.0, 4.0, 1.0));
    assert_eq!(intersect_triangle(Vec3::new(1.0, 1.0, 5.0), Vec3::new(0.0, 0.0, -2.0), a, b, c), hit(2.0, 0.25, 0.25));
    // Reversed winding swaps the barycentrics, not the hit.
    assert_eq!(intersect_triangle(Vec3::new(1.0, 2.0, 5.0), Vec3::new(0.0, 0.0, -2.0), a, c, b), hit(2.0, 0.5, 0.25));
    // An oblique ray from (2, 2, 2) with dir (-1, -1, -2) reaches (1, 1, 0) at t = 1
    // on the triangle (0,0,0), (4,0,0), (0,4,0): u = v = 1/4.
    let h = intersect_triangle(Vec3::splat(2.0), Vec3::new(-1.0, -1.0, -2.0), V0, V1 * 4.0, V2 * 4.0);
    assert!((h.t - 1.0).abs() < 1e-6 && (h.u - 0.25).abs() < 1e-6 && (h.v - 0.25).abs() < 1e-6, "{h:?}");
    // A triangle in x = 3, hit along +X.
    let h = intersect_triangle(
        Vec3::new(0.0, 0.5, 0.25),
        Vec3::X,
        Vec3::new(3.0, 0.0, 0.0),
        Vec3::new(3.0, 1.0, 0.0),
        Vec3::new(3.0, 0.0, 1.0),
    );
    assert_eq!(h, hit(3.0, 0.5, 0.25));
}

#[test]
fn triangle_edges_and_vertices_are_inside() {
    for (x, y, u, v) in [
        (0.0, 0.0, 0.0, 0.0), // v0
        (1.0, 0.0, 1.0, 0.0), // v1
        (0.0, 1.0, 0.0, 1.0), // v2
        (0.5, 0.0, 0.5, 0.0), // edge v0-v1
        (0.0, 0.5, 0.0, 0.5), // edge v0-v2
        (0.5, 0.5, 0.5, 0.5), // edge v1-v2 (u + v = 1)
        (0.25, 0.75, 0.25, 0.75),
        (0.75, 0.25, 0.75, 0.25),
    ] {
        assert_eq!(down_at(x, y), hit(1.0, u, v), "at ({x}, {y})");
    }
    // Just outside each edge.
    let eps = 1e-6;
    for (x, y) in [(0.5, -eps), (-eps, 0.5), (0.5 + eps, 0.5), (0.5, 0.5 + eps), (1.0 + eps, 0.0), (0.0, 1.0 + eps)] {
        assert_miss(down_at(x, y), &format!("({x}, {y})"));
    }
    // Shared edge of two triangles: a ray through it hits both (no crack).
    let v3 = Vec3::new(1.0, 1.0, 0.0);
    let o = Vec3::new(0.5, 0.5, 1.0);
    assert_ne!(intersect_triangle(o, Vec3::NEG_Z, V0, V1, V2).t, MISS);
    assert_ne!(intersect_triangle(o, Vec3::NEG_Z, V1, v3, V2).t, MISS);
}

#[test]
fn triangle_edge_on_and_parallel_rays_miss() {
    // In the triangle's plane, through its interior, along an edge, and towards a vertex.
    for (origin, dir) in [
        (Vec3::new(-1.0, 0.25, 0.0), Vec3::X),
        (Vec3::new(-1.0, 0.0, 0.0), Vec3::X),
        (Vec3::new(0.25, -1.0, 0.0), Vec3::new(0.0, 2.0, 0.0)),
        (Vec3::new(-1.0, -1.0, 0.0), Vec3::new(1.0, 1.0, 0.0)),
        (Vec3::new(0.1, 0.1, 0.0), Vec3::new(1.0, 3.0, 0.0)), // origin inside the triangle
    ] {
        assert_miss(intersect_triangle(origin, dir, V0, V1, V2), &format!("edge-on {origin} {dir}"));
    }
    // A tilted triangle in the plane x + y + z = 1 and rays in that plane (exact arithmetic).
    let (a, b, c) = (Vec3::X, Vec3::Y, Vec3::Z);
    for (origin, dir) in [
        (Vec3::new(1.0, 1.0, -1.0), Vec3::new(-1.0, -1.0, 2.0)),
        (Vec3::new(2.0, 0.0, -1.0), Vec3::new(-1.0, 0.0, 1.0)),
    ] {
        assert_miss(intersect_triangle(origin, dir, a, b, c), &format!("edge-on tilted {origin} {dir}"));
    }
    // Parallel to the plane, above it.
    for dir in [Vec3::X, Vec3::Y, Vec3::new(1.0, -1.0, 0.0)] {
        assert_miss(intersect_triangle(Vec3::new(0.25, 0.25, 1.0), dir, V0, V1, V2), &format!("parallel {dir}"));
    }
}

#[test]
fn triangle_degenerate_triangles_miss() {
    let o = Vec3::new(0.5, 0.0, 1.0);
    let cases = [
        ("all vertices equal", V1, V1, V1),
        ("two vertices equal", V0, V1, V1),
        ("v0 = v2", V0, V1, V0),
        ("collinear on x", V0, V1, Vec3::new(2.0, 0.0, 0.0)),
        ("collinear, middle vertex last", V0, Vec3::new(2.0, 0.0, 0.0), V1),
        ("collinear along (1, 2, 3)", V0, Vec3::new(1.0, 2.0, 3.0), Vec3::new(2.0, 4.0, 6.0)),
    ];
    for (what, a, b, c) in cases {
        // Rays aimed at a point of the degenerate triangle (the segment), from several sides.
        let target = (a + b + c) / 3.0;
        for origin in [o, Vec3::new(0.5, 1.0, 1.0), Vec3::new(-1.0, 3.0, 2.0), Vec3::new(3.0, -2.0, 0.5)] {
            let h = intersect_triangle(origin, target - origin, a, b, c);
            assert_miss(h, &format!("{what}, from {origin}"));
        }
    }
}

#[test]
fn triangle_behind_the_origin_misses() {
    assert_miss(intersect_triangle(Vec3::new(0.25, 0.25, 1.0), Vec3::Z, V0, V1, V2), "pointing away");
    assert_miss(intersect_triangle(Vec3::new(0.25, 0.25, -1.0), Vec3::NEG_Z, V0, V1, V2), "pointing away, below");
    // Starting on the triangle (t = 0) is not a hit: t must be > 0.
    assert_miss(intersect_triangle(Vec3::new(0.25, 0.25, 0.0), Vec3::Z, V0, V1, V2), "t = 0");
    assert_miss(intersect_triangle(Vec3::new(0.25, 0.25, 0.0), Vec3::NEG_Z, V0, V1, V2), "t = 0, down");
    // Zero direction.
    assert_miss(intersect_triangle(Vec3::new(0.25, 0.25, 1.0), Vec3::ZERO, V0, V1, V2), "zero direction");
}

#[test]
fn triangle_nan_and_infinite_inputs_never_hit_with_nan() {
    let good = [Vec3::new(0.25, 0.25, 1.0), Vec3::NEG_Z, V0, V1, V2];
    assert_ne!(intersect_triangle(good[0], good[1], good[2], good[3], good[4]).t, MISS);
    let specials = [f32::NAN, f32::INFINITY, f32::NEG_INFINITY, f32::MAX, -f32::MAX, f32::MIN_POSITIVE];
    for arg in 0..5 {
        for axis in 0..3 {
            for &value in &specials {
                let mut args = good;
                args[arg][axis] = value;
                let h = intersect_triangle(args[0], args[1], args[2], args[3], args[4]);
                let what = format!("argument {arg} axis {axis} = {value}: {h:?}");
                assert!(!h.t.is_nan() && !h.u.is_nan() && !h.v.is_nan(), "{what}");
                assert!(h.t == MISS || (h.t > 0.0 && h.t.is_finite()), "{what}");
                if value.is_nan() {
                    assert_eq!(h.t, MISS, "{what}");
                }
            }
        }
    }
    // Random combinations of special values anywhere.
    let mut rng = TestRng::new(40);
    for _ in 0..100_000 {
        let mut args = [rng.vec3(2.0), rng.vec3(1.0), rng.vec3(2.0), rng.vec3(2.0), rng.vec3(2.0)];
        for _ in 0..1 + rng.next_u32() % 3 {
            let (arg, axis) = ((rng.next_u32() % 5) as usize, (rng.next_u32() % 3) as usize);
            args[arg][axis] = specials[(rng.next_u32() % specials.len() as u32) as usize];
        }
        let h = intersect_triangle(args[0], args[1], args[2], args[3], args[4]);
        assert!(!h.t.is_nan() && !h.u.is_nan() && !h.v.is_nan(), "{args:?}: {h:?}");
        assert!(h.t == MISS || (h.t > 0.0 && h.t.is_finite()), "{args:?}: {h:?}");
        let has_nan = args.iter().any(|a| a.is_nan());
        assert!(!has_nan || h.t == MISS, "NaN input hit: {args:?}: {h:?}");
    }
}

#[test]
fn triangle_random_rays_agree_with_barycentrics() {
    // Aim at a known barycentric point of a random triangle: the hit must report it.
    let mut rng = TestRng::new(41);
    let mut checked = 0;
    for _ in 0..100_000 {
        let (a, b, c) = (rng.vec3(3.0), rng.vec3(3.0), rng.vec3(3.0));
        let normal = (b - a).cross(c - a);
        if normal.length() < 0.1 {
            continue; // thin triangles make the expected barycentrics ill-conditioned
        }
        let (mut u, mut v) = (rng.f32(), rng.f32());
        if u + v > 1.0 {
            (u, v) = (1.0 - u, 1.0 - v);
        }
        let p = a * (1.0 - u - v) + b * u + c * v;
        let origin = rng.vec3(10.0);
        let dir = p - origin;
        let cos = dir.normalize().dot(normal.normalize()).abs();
        if cos < 0.05 || dir.length() < 0.1 {
            continue; // grazing: the point is ill-conditioned
        }
        let h = intersect_triangle(origin, dir, a, b, c);
        let inside_margin = u.min(v).min(1.0 - u - v);
        if inside_margin < 1e-3 {
            continue;
        }
        assert!((h.t - 1.0).abs() < 1e-3, "{origin} {dir} onto ({a}, {b}, {c}) at ({u}, {v}): {h:?}");
        assert!((h.u - u).abs() < 1e-3 && (h.v - v).abs() < 1e-3, "({u}, {v}) vs {h:?}");
        // The same ray reversed (from the far side of the origin) misses.
        assert_miss(intersect_triangle(origin, -dir, a, b, c), "reversed");
        // And a ray aimed outside (past an edge) misses.
        let outside = a * (1.0 + 0.2) + b * -0.1 + c * -0.1;
        assert_miss(intersect_triangle(origin, outside - origin, a, b, c), "outside");
        checked += 1;
    }
    assert!(checked > 50_000, "only {checked} rays checked");
}

// ---------------------------------------------------------------------------------------------
// Ray / box
// ---------------------------------------------------------------------------------------------

const BMIN: Vec3 = Vec3::new(0.0, 0.0, 0.0);
const BMAX: Vec3 = Vec3::new(1.0, 2.0, 3.0);

fn aabb(origin: Vec3, dir: Vec3, t_max: f32) -> f32 {
    let t = intersect_aabb(origin, safe_inverse(dir), BMIN, BMAX, t_max);
    assert!(!t.is_nan(), "{origin} {dir} {t_max}: NaN");
    t
}

#[test]
fn safe_inverse_values() {
    assert_eq!(safe_inverse(Vec3::new(2.0, -4.0, 0.5)), Vec3::new(0.5, -0.25, 2.0));
    let small = 2f32.powi(-64); // 5.4e-20: above the 1e-20 threshold, kept
    assert_eq!(safe_inverse(Vec3::new(small, -small, 1.0)), Vec3::new(2f32.powi(64), -(2f32.powi(64)), 1.0));
    let tiny_inverse = 1.0 / 1.0e-20f32;
    for (d, expected) in [
        (0.0, tiny_inverse),
        (1e-21, tiny_inverse),
        (-1e-21, -tiny_inverse),
        (f32::MIN_POSITIVE, tiny_inverse),
        (-f32::MIN_POSITIVE, -tiny_inverse),
        (1e-45, tiny_inverse), // subnormal
        (-1e-45, -tiny_inverse),
    ] {
        let inv = safe_inverse(Vec3::new(d, d, d));
        assert_eq!(inv, Vec3::splat(expected), "dir component {d:e}");
    }
    // -0.0 gives a finite inverse of either sign (never -inf).
    let inv = safe_inverse(Vec3::new(-0.0, 1.0, 1.0));
    assert!(inv.x.is_finite() && inv.x.abs() == tiny_inverse, "{inv}");
    // Never infinite or NaN for finite input.
    let mut rng = TestRng::new(50);
    for _ in 0..100_000 {
        let d = rng.vec3(1.0) * 10f32.powi((rng.next_u32() % 60) as i32 - 40);
        let inv = safe_inverse(d);
        assert!(inv.is_finite(), "{d} -> {inv}");
        for axis in 0..3 {
            // (-0.0 becomes +1e20: the sign of a zero does not matter to the slab test.)
            if d[axis] != 0.0 {
                assert_eq!(inv[axis].signum(), d[axis].signum(), "{d} -> {inv}: sign kept");
            }
        }
    }
}

#[test]
fn aabb_hits_from_outside() {
    // Along each axis, both directions: the entry distance.
    assert_eq!(aabb(Vec3::new(-2.0, 1.0, 1.5), Vec3::X, 100.0), 2.0);
    assert_eq!(aabb(Vec3::new(3.0, 1.0, 1.5), Vec3::NEG_X, 100.0), 2.0);
    assert_eq!(aabb(Vec3::new(0.5, -1.0, 1.5), Vec3::Y, 100.0), 1.0);
    assert_eq!(aabb(Vec3::new(0.5, 6.0, 1.5), Vec3::NEG_Y, 100.0), 4.0);
    assert_eq!(aabb(Vec3::new(0.5, 1.0, -0.5), Vec3::Z, 100.0), 0.5);
    assert_eq!(aabb(Vec3::new(0.5, 1.0, 4.0), Vec3::NEG_Z, 100.0), 1.0);
    // A non-unit direction: t in units of dir.
    assert_eq!(aabb(Vec3::new(-2.0, 1.0, 1.5), Vec3::new(4.0, 0.0, 0.0), 100.0), 0.5);
    // Diagonal: from (-1, -1, -1) along (1, 1, 1) the box is entered at t = 1 (x, y, z all 0).
    assert_eq!(aabb(Vec3::splat(-1.0), Vec3::ONE, 100.0), 1.0);
    // Entering through the corner (1, 2, 3) from beyond it.
    assert_eq!(aabb(Vec3::new(2.0, 3.0, 4.0), Vec3::NEG_ONE, 100.0), 1.0);
    // Entering exactly through a box edge (x = 0, y = 0 at z = 1).
    assert_eq!(aabb(Vec3::new(-1.0, -1.0, 1.0), Vec3::new(1.0, 1.0, 0.0), 100.0), 1.0);
}

#[test]
fn aabb_origin_inside_gives_zero() {
    for dir in [Vec3::X, Vec3::NEG_X, Vec3::Y, Vec3::NEG_Z, Vec3::new(0.3, -0.2, 0.9), Vec3::ZERO] {
        assert_eq!(aabb(Vec3::new(0.5, 1.0, 1.5), dir, 100.0), 0.0, "dir {dir}");
    }
    // On the surface, pointing in or out: inside the closed box at t = 0.
    assert_eq!(aabb(Vec3::new(0.0, 1.0, 1.5), Vec3::X, 100.0), 0.0);
    assert_eq!(aabb(Vec3::new(1.0, 1.0, 1.5), Vec3::X, 100.0), 0.0);
}

#[test]
fn aabb_axis_parallel_rays() {
    // Zero components with the origin inside those slabs: hit; outside: miss.
    for zero in [0.0, -0.0] {
        let dir = Vec3::new(1.0, zero, zero);
        assert_eq!(aabb(Vec3::new(-1.0, 1.0, 1.5), dir, 100.0), 1.0, "inside y and z slabs, dir {dir}");
        assert_eq!(aabb(Vec3::new(-1.0, 2.5, 1.5), dir, 100.0), MISS, "above the y slab");
        assert_eq!(aabb(Vec3::new(-1.0, -0.5, 1.5), dir, 100.0), MISS, "below the y slab");
        assert_eq!(aabb(Vec3::new(-1.0, 1.0, 3.5), dir, 100.0), MISS, "beyond the z slab");
        let dir = Vec3::new(zero, zero, -1.0);
        assert_eq!(aabb(Vec3::new(0.5, 1.0, 5.0), dir, 100.0), 2.0);
        assert_eq!(aabb(Vec3::new(1.5, 1.0, 5.0), dir, 100.0), MISS);
        assert_eq!(aabb(Vec3::new(-0.5, 1.0, 5.0), dir, 100.0), MISS);
    }
    // Tiny (non-zero) components behave like zero.
    assert_eq!(aabb(Vec3::new(-1.0, 1.0, 1.5), Vec3::new(1.0, 1e-30, -1e-30), 100.0), 1.0);
    assert_eq!(aabb(Vec3::new(-1.0, 2.5, 1.5), Vec3::new(1.0, 1e-30, -1e-30), 100.0), MISS);
}

/// A ray that lies exactly in the plane of one of the box's faces, travelling parallel to it
/// and entering the face's extent at t = 1: it touches the closed box.
fn face_plane_rays() -> Vec<(&'static str, Vec3, Vec3)> {
    let mut rays = Vec::new();
    for zero in [0.0f32, -0.0] {
        rays.push(("x = min", Vec3::new(0.0, -1.0, 1.5), Vec3::new(zero, 1.0, zero)));
        rays.push(("x = max", Vec3::new(1.0, -1.0, 1.5), Vec3::new(zero, 1.0, zero)));
        rays.push(("y = min", Vec3::new(-1.0, 0.0, 1.5), Vec3::new(1.0, zero, zero)));
        rays.push(("y = max", Vec3::new(-1.0, 2.0, 1.5), Vec3::new(1.0, zero, zero)));
        rays.push(("z = min", Vec3::new(-1.0, 1.0, 0.0), Vec3::new(1.0, zero, zero)));
        rays.push(("z = max", Vec3::new(-1.0, 1.0, 3.0), Vec3::new(1.0, zero, zero)));
    }
    rays
}

#[test]
fn aabb_ray_in_a_face_plane_lower_faces() {
    for (what, origin, dir) in face_plane_rays().into_iter().filter(|(what, _, _)| what.ends_with("min")) {
        assert_eq!(aabb(origin, dir, 100.0), 1.0, "{what}: {origin} {dir}");
    }
}

#[test]
fn aabb_ray_in_a_face_plane_touches_the_closed_box() {
    // Edges and faces of triangles count as inside (see `triangle_edges_and_vertices_are_inside`),
    // so a box must not cull a ray that runs along its face: a triangle with an edge in that
    // face is hit by the triangle test.
    let mut failures = Vec::new();
    for (what, origin, dir) in face_plane_rays() {
        let t = aabb(origin, dir, 100.0);
        if t != 1.0 {
            failures.push(format!("{what}: origin {origin} dir {dir:?} -> {t}"));
        }
    }
    assert!(failures.is_empty(), "rays in a face plane missed the closed box:\n{}", failures.join("\n"));
}

#[test]
fn aabb_does_not_cull_a_triangle_hit_on_its_max_face() {
    // A triangle in x = 0.5 with its edge a-b in the plane z = 3, the top of its bounding box.
    let (a, b, c) = (Vec3::new(0.5, 0.0, 3.0), Vec3::new(0.5, 2.0, 3.0), Vec3::new(0.5, 1.0, 0.0));
    let (bmin, bmax) = (a.min(b).min(c), a.max(b).max(c));
    let (origin, dir) = (Vec3::new(-1.0, 1.0, 3.0), Vec3::X);
    // By hand: e1 = (0, 2, 0), e2 = (0, 1, -3), p = (0, 3, 1), det = 6, s = (-1.5, 1, 0),
    // u = 3/6, q = (0, 0, -3), v = 0 (on the edge a-b), t = 9/6.
    assert_eq!(intersect_triangle(origin, dir, a, b, c), TriangleHit { t: 1.5, u: 0.5, v: 0.0 });
    let t = intersect_aabb(origin, safe_inverse(dir), bmin, bmax, MISS);
    assert!(t <= 1.5, "the triangle's own box culls its hit: {t}");
}

#[test]
fn aabb_misses_and_t_max_clipping() {
    // Pointing away.
    assert_eq!(aabb(Vec3::new(-2.0, 1.0, 1.5), Vec3::NEG_X, 100.0), MISS);
    // Passing beside.
    assert_eq!(aabb(Vec3::new(-2.0, 1.0, 1.5), Vec3::new(1.0, 2.0, 0.0), 100.0), MISS);
    // Box behind the origin along the ray's line.
    assert_eq!(aabb(Vec3::new(5.0, 1.0, 1.5), Vec3::X, 100.0), MISS);
    // t_max clips: the box spans t in [2, 3] along this ray.
    let o = Vec3::new(-2.0, 1.0, 1.5);
    assert_eq!(aabb(o, Vec3::X, 1.999), MISS);
    assert_eq!(aabb(o, Vec3::X, 2.0), 2.0, "t_max at the entry: inclusive");
    assert_eq!(aabb(o, Vec3::X, 2.5), 2.0);
    assert_eq!(aabb(o, Vec3::X, MISS), 2.0);
    // Inside the box, t_max = 0 still reports 0.
    assert_eq!(aabb(Vec3::new(0.5, 1.0, 1.5), Vec3::X, 0.0), 0.0);
    // A negative t_max (no valid interval) misses.
    assert_eq!(aabb(Vec3::new(0.5, 1.0, 1.5), Vec3::X, -1.0), MISS);
}

/// An independent slab test in f64 with true infinities: (entry, exit) or `None`.
fn reference_slab(origin: Vec3, dir: Vec3, bmin: Vec3, bmax: Vec3, t_max: f64) -> Option<(f64, f64)> {
    let (mut enter, mut exit) = (0.0f64, t_max);
    for axis in 0..3 {
        let (o, d) = (origin[axis] as f64, dir[axis] as f64);
        let (lo, hi) = (bmin[axis] as f64, bmax[axis] as f64);
        if d == 0.0 {
            if o < lo || o > hi {
                return None;
            }
            continue;
        }
        let (a, b) = ((lo - o) / d, (hi - o) / d);
        enter = enter.max(a.min(b));
        exit = exit.min(a.max(b));
    }
    (enter <= exit).then_some((enter, exit))
}

#[test]
fn aabb_random_rays_agree_with_a_reference() {
    let mut rng = TestRng::new(51);
    let (mut hits, mut misses) = (0, 0);
    for i in 0..200_000 {
        let c = rng.vec3(2.0);
        let half = Vec3::new(rng.range(0.0, 1.0), rng.range(0.0, 1.0), rng.range(0.0, 1.0));
        let (bmin, bmax) = (c - half, c + half);
        let origin = rng.vec3(4.0);
        let mut dir = if i % 2 == 0 {
            // Towards a random point of the box (grown a little, so some rays pass beside it).
            let target = c + half * rng.vec3(1.2);
            (target - origin).normalize()
        } else {
            rng.unit_vector()
        };
        if i % 4 == 0 {
            dir[(rng.next_u32() % 3) as usize] = 0.0; // axis-parallel to one slab
        }
        let t_max = if i % 3 == 0 { rng.range(0.0, 6.0) } else { MISS };
        let t = intersect_aabb(origin, safe_inverse(dir), bmin, bmax, t_max);
        assert!(!t.is_nan());
        let reference = reference_slab(origin, dir, bmin, bmax, t_max as f64);
        match reference {
            // Skip rays within rounding of touching the box or of t_max.
            Some((enter, exit)) if exit - enter > 1e-4 => {
                assert!(
                    (t as f64 - enter).abs() <= 1e-4 * enter.max(1.0),
                    "{origin} {dir} {bmin} {bmax}: {t} vs {enter}"
                );
                hits += 1;
            }
            None => {
                let grown = reference_slab(origin, dir, bmin - 1e-4, bmax + 1e-4, t_max as f64 + 1e-4);
                if grown.is_none() {
                    assert_eq!(t, MISS, "{origin} {dir} {bmin} {bmax} {t_max}");
                    misses += 1;
                }
            }
            Some(_) => {}
        }
    }
    assert!(hits > 10_000 && misses > 10_000, "{hits} hits, {misses} misses checked");
}

#[test]
fn aabb_nan_inputs_never_give_nan() {
    // NaN or infinite inputs may give a (conservative) hit or a miss, but never a NaN
    // distance, nor one before the origin or past t_max.
    let specials = [f32::NAN, f32::INFINITY, f32::NEG_INFINITY, 0.0, -0.0];
    let mut rng = TestRng::new(52);
    for _ in 0..100_000 {
        let mut args = [rng.vec3(3.0), rng.unit_vector(), rng.vec3(1.0) - 1.0, rng.vec3(1.0) + 1.0];
        for _ in 0..1 + rng.next_u32() % 3 {
            let (arg, axis) = ((rng.next_u32() % 4) as usize, (rng.next_u32() % 3) as usize);
            args[arg][axis] = specials[(rng.next_u32() % specials.len() as u32) as usize];
        }
        let t_max = if rng.next_u32().is_multiple_of(5) { f32::NAN } else { 100.0 };
        let t = intersect_aabb(args[0], safe_inverse(args[1]), args[2], args[3], t_max);
        assert!(!t.is_nan(), "{args:?} t_max {t_max}: NaN");
        // A hit is at or after the origin and not beyond t_max (a NaN t_max clips nothing).
        assert!(t == MISS || (t >= 0.0 && (t_max.is_nan() || t <= t_max)), "{args:?} t_max {t_max}: {t}");
    }
}

// ---------------------------------------------------------------------------------------------
// Texture texels: 8-bit sRGBA packed four to a `UVec4`, decoded in the kernel
// ---------------------------------------------------------------------------------------------

#[test]
fn decode_srgba8_matches_the_sampled_decoding_for_every_byte() {
    use tracer::kernel::textures::decode_srgba8;
    let linear = |v: u32| tracer::scene::srgb_to_linear(v as f32 / 255.0);
    for v in 0..=255u32 {
        // A different byte in every channel, so a swapped channel or shift shows.
        let (r, g, b, a) = (v, 255 - v, v ^ 0x5a, (v * 7) & 255);
        let decoded = decode_srgba8(r | g << 8 | b << 16 | a << 24);
        // The same f32 operations as the loader's conversion: bit-exact on the CPU.
        assert_eq!(decoded, glam::Vec4::new(linear(r), linear(g), linear(b), a as f32 / 255.0), "byte {v}");
    }
}

#[test]
fn texel_reads_its_lane_of_the_packed_element() {
    use glam::UVec4;
    use tracer::kernel::scene_data::{Scene, WRAP_CLAMP};
    use tracer::kernel::textures::texel;
    // A 3x2 texture starting at atlas texel 4 (element 1), after another texture's element.
    let words: Vec<u32> = (0..6u32).map(|i| u32::from_le_bytes([40 * i as u8, 255 - 40 * i as u8, 9, 255])).collect();
    let scene = Scene {
        texture_texels: kernel_dsl::Texels::new(vec![
            UVec4::splat(0xffff_ffff),
            UVec4::new(words[0], words[1], words[2], words[3]),
            UVec4::new(words[4], words[5], 0, 0),
        ]),
        ..Default::default()
    };
    let info = UVec4::new(4, 3, 2, WRAP_CLAMP | WRAP_CLAMP << 8);
    for y in 0..2 {
        for x in 0..3 {
            let expected = tracer::scene::srgba8_to_linear(words[(y * 3 + x) as usize]);
            assert_eq!(texel(&scene, info, x, y), expected, "texel ({x}, {y})");
        }
    }
}

// ---------------------------------------------------------------------------------------------
// Tone mapping: the kernel's curves against the reference formulas, written again here in f64
// with each matrix in its source's layout (GLSL's column-major `mat3(...)` for AgX, HLSL rows
// for ACES), so that a transposed or mistyped matrix in the kernel fails.
// ---------------------------------------------------------------------------------------------

mod tone_reference {
    pub type V = [f64; 3];

    /// `M * v` for a GLSL `mat3(c0, c1, c2)` given as its columns.
    pub fn mul_columns(m: [V; 3], v: V) -> V {
        std::array::from_fn(|i| m[0][i] * v[0] + m[1][i] * v[1] + m[2][i] * v[2])
    }

    /// `mul(M, v)` for an HLSL `float3x3` given as its rows.
    pub fn mul_rows(m: [V; 3], v: V) -> V {
        std::array::from_fn(|i| m[i][0] * v[0] + m[i][1] * v[1] + m[i][2] * v[2])
    }

    /// Khronos PBR Neutral, as the Khronos reference GLSL writes it.
    pub fn neutral(c: V) -> V {
        let start = 0.8 - 0.04;
        let desaturation = 0.15;
        let x = c[0].min(c[1]).min(c[2]);
        let offset = if x < 0.08 { x - 6.25 * x * x } else { 0.04 };
        let c = c.map(|v| v - offset);
        let peak = c[0].max(c[1]).max(c[2]);
        if peak < start {
            return c;
        }
        let d = 1.0 - start;
        let new_peak = 1.0 - d * d / (peak + d - start);
        let c = c.map(|v| v * new_peak / peak);
        let g = 1.0 - 1.0 / (desaturation * (peak - new_peak) + 1.0);
        c.map(|v| v * (1.0 - g) + new_peak * g)
    }

    /// Stephen Hill's fitted ACES (BakingLab's ACES.hlsl).
    pub fn aces(c: V) -> V {
        let input = [[0.59719, 0.35458, 0.04823], [0.07600, 0.90834, 0.01566], [0.02840, 0.13383, 0.83777]];
        let output = [[1.60475, -0.53108, -0.07367], [-0.10208, 1.10813, -0.00605], [-0.00327, -0.07276, 1.07602]];
        let v = mul_rows(input, c)
            .map(|v| (v * (v + 0.0245786) - 0.000090537) / (v * (0.983729 * v + 0.4329510) + 0.238081));
        mul_rows(output, v).map(|v| v.clamp(0.0, 1.0))
    }

    /// Minimal AgX (Benjamin Wrensch), default look, with its 2.2 display EOTF.
    pub fn agx(c: V) -> V {
        let agx_mat = [
            [0.842479062253094, 0.0423282422610123, 0.0423756549057051],
            [0.0784335999999992, 0.878468636469772, 0.0784336],
            [0.0792237451477643, 0.0791661274605434, 0.879142973793104],
        ];
        let agx_mat_inv = [
            [1.19687900512017, -0.0528968517574562, -0.0529716355144438],
            [-0.0980208811401368, 1.15190312990417, -0.0980434501171241],
            [-0.0990297440797205, -0.0989611768448433, 1.15107367264116],
        ];
        let (min_ev, max_ev) = (-12.47393, 4.026069);
        let v =
            mul_columns(agx_mat, c).map(|v| (v.max(1e-10).log2().clamp(min_ev, max_ev) - min_ev) / (max_ev - min_ev));
        let v = v.map(|x| {
            let (x2, x4) = (x * x, x * x * x * x);
            15.5 * x4 * x2 - 40.14 * x4 * x + 31.96 * x4 - 6.868 * x2 * x + 0.4298 * x2 + 0.1191 * x - 0.00232
        });
        mul_columns(agx_mat_inv, v).map(|v| v.clamp(0.0, 1.0).powf(2.2))
    }
}

#[test]
fn tone_curves_match_the_reference_formulas() {
    use tracer::kernel::tonemap::{self, TONEMAP_ACES, TONEMAP_AGX, TONEMAP_NEUTRAL, TONEMAP_NONE};
    let mut r = TestRng::new(31);
    let mut worst = [0.0f64; 3];
    for i in 0..20_000 {
        let c = if i % 4 == 0 {
            Vec3::splat(r.range(-12.0, 12.0).exp2())
        } else {
            Vec3::new(r.range(-12.0, 12.0).exp2(), r.range(-12.0, 12.0).exp2(), r.range(-12.0, 12.0).exp2())
        };
        let v = c.as_dvec3().to_array();
        let cases = [
            (tonemap::tone_map(c, TONEMAP_NEUTRAL, 1.0), tone_reference::neutral(v).map(|x| x.clamp(0.0, 1.0))),
            (tonemap::tone_map(c, TONEMAP_ACES, 1.0), tone_reference::aces(v)),
            (tonemap::tone_map(c, TONEMAP_AGX, 1.0), tone_reference::agx(v)),
        ];
        for (k, (got, want)) in cases.iter().enumerate() {
            for (g, w) in got.to_array().iter().zip(want) {
                assert!((0.0..=1.0).contains(g), "{c}: operator {k} gave {got}");
                worst[k] = worst[k].max((*g as f64 - w).abs());
            }
        }
    }
    println!("largest difference from the f64 references (neutral, ACES, AgX): {worst:?}");
    assert!(worst.iter().all(|&w| w < 2e-5), "{worst:?}");

    // Hand-checked values. Neutral: grey below the knee only loses the 0.04 toe offset; a
    // 10 x brighter grey rolls off to 1 - 0.24² / 9.44.
    let neutral = |c: f32| tonemap::tone_map(Vec3::splat(c), TONEMAP_NEUTRAL, 1.0).x;
    assert!((neutral(0.5) - 0.46).abs() < 1e-6 && (neutral(0.05) - 0.015625).abs() < 1e-6);
    assert!((neutral(10.0) - (1.0 - 0.0576 / 9.44)).abs() < 1e-6, "{}", neutral(10.0));
    // ACES: black stays (nearly) black, very bright saturates to white.
    let aces = |c: f32| tonemap::tone_map(Vec3::splat(c), TONEMAP_ACES, 1.0);
    assert!(aces(0.0).max_element() < 1e-3 && aces(1e4).min_element() > 0.99, "{} {}", aces(0.0), aces(1e4));
    // AgX maps middle grey 0.18 near the middle of the display range, white-balanced.
    let agx_grey = tonemap::tone_map(Vec3::splat(0.18), TONEMAP_AGX, 1.0);
    assert!((agx_grey.x - agx_grey.z).abs() < 1e-3 && agx_grey.x > 0.1 && agx_grey.x < 0.3, "{agx_grey}");
    // None clamps; exposure scales before the curve (+1 EV: twice the radiance).
    assert_eq!(tonemap::tone_map(Vec3::new(0.25, 2.0, -1.0), TONEMAP_NONE, 1.0), Vec3::new(0.25, 1.0, 0.0));
    assert_eq!(tonemap::tone_map(Vec3::splat(0.2), TONEMAP_NONE, 2.0), Vec3::splat(0.4));
    assert_eq!(
        tonemap::tone_map(Vec3::splat(0.3), TONEMAP_NEUTRAL, 2.0),
        tonemap::tone_map(Vec3::splat(0.6), TONEMAP_NEUTRAL, 1.0)
    );
    // Non-finite and negative radiance displays black with every operator.
    for op in [TONEMAP_NONE, TONEMAP_NEUTRAL, TONEMAP_ACES, TONEMAP_AGX] {
        let v = tonemap::display_srgb(Vec3::new(f32::NAN, f32::INFINITY, -3.0), op, 1.0);
        assert!(v.is_finite() && v.max_element() < 0.02, "operator {op}: {v}");
    }
    // sRGB encoding: the two pieces meet at 0.0031308; 1 stays 1.
    assert!((tonemap::linear_to_srgb(1.0) - 1.0).abs() < 1e-6);
    assert!((tonemap::linear_to_srgb(0.0031308) - 0.0031308 * 12.92).abs() < 1e-6);
    assert!((tonemap::linear_to_srgb(0.18) - 0.4614).abs() < 1e-3);
}

#[test]
fn png_output_keeps_the_old_clamp_as_none_and_tone_maps_by_default() {
    use tracer::backend::Image;
    use tracer::output::{to_display_srgb8, to_srgb8, Display, ToneMap};
    let image =
        Image { width: 3, height: 1, pixels: vec![Vec3::splat(0.5), Vec3::splat(4.0), Vec3::new(f32::NAN, 0.0, 1.0)] };
    let clamped = to_srgb8(&image);
    assert_eq!(clamped, [188, 188, 188, 255, 255, 255, 0, 0, 255]);
    assert_eq!(to_display_srgb8(&image, &Display::CLAMP), clamped);
    let neutral = to_display_srgb8(&image, &Display::default());
    assert_eq!(Display::default().tone_map, ToneMap::Neutral);
    // Neutral keeps a 4.0 highlight below white and darkens 0.5 only by its toe offset.
    assert!(neutral[3] < 255 && neutral[3] > 240 && neutral[0] < 188 && neutral[0] > 175, "{neutral:?}");
    let brighter = to_display_srgb8(&image, &Display { tone_map: ToneMap::Neutral, exposure: 1.0 });
    assert!(brighter[0] > neutral[0], "{brighter:?}");
}
