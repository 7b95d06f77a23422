//! The samplers' frames and distributions: orthonormal bases, cosine and triangle sampling
//! against their pdfs (chi-square and Monte Carlo estimates with fixed seeds).

use crate::common;

use common::{assert_chi_square, assert_within_sigmas, mean_variance, TestRng};
use glam::{Vec2, Vec3};
use tracer::kernel::sampling::{
    cos_sin_turns, cosine_hemisphere_pdf, cosine_sample_hemisphere, onb_from_normal, onb_to_world,
    sample_cosine_around, uniform_sample_triangle, INV_PI, PI,
};

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
