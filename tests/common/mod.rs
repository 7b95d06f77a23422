//! Helpers shared by the integration tests: the path of the vendored test data, a small
//! deterministic random number generator (independent of the kernel's own RNG, so kernel tests
//! do not test the RNG with itself) and the statistics used by the sampling tests.
//!
//! Each test binary (`tests/<binary>/main.rs`) includes it with `#[path = "../common/mod.rs"] mod common;`.

// Each test file uses a different part of this module.
#![allow(dead_code)]

pub mod agreement;
pub mod bands;
pub mod browser;
pub mod sphere_grid;
pub mod texture_quads;

use std::path::{Path, PathBuf};

use glam::{DVec3, Vec3};

/// A file of the test data vendored in `tests/data/` (see its README.md), named relative to
/// that folder: `test_data("scenes/khronos/Duck/glTF-Binary/Duck.glb")`. Every test reads its
/// scenes through this, so that a plain clone runs them with nothing beside it.
pub fn test_data(rel: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data").join(rel)
}

/// `tests/data/scenes/generated/animated-skinned-instanced.gltf` (a skinned, morphed triangle
/// whose joints and weights are animated, and a triangle placed three times by
/// `EXT_mesh_gpu_instancing`) with its instanced node turned by the animation's rotation
/// sampler too: every kind of moving part at once (`LoadOptions::keep_motion`); a point light
/// lights them.
pub fn moving_parts_gltf() -> Vec<u8> {
    let path = test_data("scenes/generated/animated-skinned-instanced.gltf");
    let mut json: serde_json::Value = serde_json::from_slice(&std::fs::read(path).expect("the seed")).expect("JSON");
    let channel = serde_json::json!({"sampler": 1, "target": {"node": 3, "path": "rotation"}});
    json["animations"][0]["channels"].as_array_mut().expect("channels").push(channel);
    // A point light in front of them, so that the page (which has no sky) sees them lit.
    json["extensionsUsed"] = serde_json::json!(["EXT_mesh_gpu_instancing", "KHR_lights_punctual"]);
    json["extensions"] = serde_json::json!({"KHR_lights_punctual": {"lights": [{"type": "point", "intensity": 40}]}});
    let nodes = json["nodes"].as_array_mut().expect("nodes");
    nodes.push(serde_json::json!({"translation": [0.5, 1.5, 3], "extensions": {"KHR_lights_punctual": {"light": 0}}}));
    let light = nodes.len() - 1;
    json["scenes"][0]["nodes"].as_array_mut().expect("scene nodes").push(light.into());
    serde_json::to_vec(&json).expect("JSON")
}

/// xorshift64* (Vigna 2016): a fast, good-enough generator for test inputs. Deterministic,
/// so a failing statistical test fails the same way every run.
#[derive(Clone, Debug)]
pub struct TestRng(u64);

impl TestRng {
    pub fn new(seed: u64) -> Self {
        // splitmix64 of the seed: any seed (including 0) gives a good non-zero state.
        let mut z = seed.wrapping_add(0x9e37_79b9_7f4a_7c15);
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^= z >> 31;
        TestRng(if z == 0 { 1 } else { z })
    }

    pub fn next_u64(&mut self) -> u64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        self.0.wrapping_mul(0x2545_f491_4f6c_dd1d)
    }

    pub fn next_u32(&mut self) -> u32 {
        (self.next_u64() >> 32) as u32
    }

    /// Uniform in [0, 1) with 24 random bits (every value exact in f32).
    pub fn f32(&mut self) -> f32 {
        (self.next_u64() >> 40) as f32 * (1.0 / 16_777_216.0)
    }

    /// Uniform in [0, 1) with 53 random bits.
    pub fn f64(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 * (1.0 / 9_007_199_254_740_992.0)
    }

    /// Uniform in [lo, hi).
    pub fn range(&mut self, lo: f32, hi: f32) -> f32 {
        lo + (hi - lo) * self.f32()
    }

    /// A point uniform in the cube [-scale, scale)^3.
    pub fn vec3(&mut self, scale: f32) -> Vec3 {
        Vec3::new(self.range(-scale, scale), self.range(-scale, scale), self.range(-scale, scale))
    }

    /// A direction uniform on the unit sphere (computed in f64, then rounded).
    pub fn unit_vector(&mut self) -> Vec3 {
        let z = 1.0 - 2.0 * self.f64();
        let phi = 2.0 * std::f64::consts::PI * self.f64();
        let r = (1.0 - z * z).max(0.0).sqrt();
        DVec3::new(r * phi.cos(), r * phi.sin(), z).normalize().as_vec3()
    }
}

/// Pearson's chi-square statistic of observed counts against expected counts.
pub fn chi_square(observed: &[u64], expected: &[f64]) -> f64 {
    assert_eq!(observed.len(), expected.len());
    observed
        .iter()
        .zip(expected)
        .map(|(&o, &e)| {
            assert!(e >= 5.0, "expected count {e} too small for a chi-square test");
            let d = o as f64 - e;
            d * d / e
        })
        .sum()
}

/// The chi-square value exceeded with probability 1e-6 for `dof` degrees of freedom
/// (Wilson–Hilferty approximation, within about 1% for dof >= 10). A correct sampler fails
/// a test at this bound once in a million seeds; the tests use fixed seeds.
pub fn chi_square_critical_1e6(dof: usize) -> f64 {
    const Z: f64 = 4.753_424; // standard normal upper quantile for p = 1e-6
    let k = dof as f64;
    let c = 2.0 / (9.0 * k);
    k * (1.0 - c + Z * c.sqrt()).powi(3)
}

/// Asserts that `observed` fits `expected` (counts per bin) and returns the statistic.
pub fn assert_chi_square(what: &str, observed: &[u64], expected: &[f64]) -> f64 {
    let chi2 = chi_square(observed, expected);
    let dof = observed.len() - 1;
    let critical = chi_square_critical_1e6(dof);
    assert!(chi2 < critical, "{what}: chi-square {chi2:.1} >= {critical:.1} ({dof} dof); counts {observed:?}");
    chi2
}

/// Mean and unbiased variance of a sample.
pub fn mean_variance(values: impl IntoIterator<Item = f64>) -> (f64, f64, usize) {
    // Welford, in f64.
    let (mut n, mut mean, mut m2) = (0usize, 0.0f64, 0.0f64);
    for x in values {
        n += 1;
        let d = x - mean;
        mean += d / n as f64;
        m2 += d * (x - mean);
    }
    (mean, if n > 1 { m2 / (n - 1) as f64 } else { 0.0 }, n)
}

/// Asserts `|estimate - expected| <= sigmas * standard error`, where the standard error is
/// that of the mean of `n` samples with the given variance.
/// Returns how many standard errors off the estimate is.
pub fn assert_within_sigmas(what: &str, estimate: f64, expected: f64, variance: f64, n: usize, sigmas: f64) -> f64 {
    let se = (variance / n as f64).sqrt();
    let z = (estimate - expected) / se;
    assert!(z.abs() <= sigmas, "{what}: {estimate} vs {expected}: {z:.2} standard errors ({se:e}) off");
    z
}

/// Means over the regions the statistical agreement tests compare: each block of a
/// `blocks x blocks` grid over a `size x size` image, then (last) the whole image, of
/// `pixel(i)` for pixel `i = y * size + x`.
pub fn region_means(size: u32, blocks: u32, pixel: impl Fn(usize) -> DVec3) -> Vec<DVec3> {
    let bs = size / blocks;
    let mut out = vec![DVec3::ZERO; (blocks * blocks) as usize + 1];
    for y in 0..size {
        for x in 0..size {
            let value = pixel((y * size + x) as usize);
            out[((y / bs) * blocks + x / bs) as usize] += value / (bs * bs) as f64;
            out[(blocks * blocks) as usize] += value / (size * size) as f64;
        }
    }
    out
}

/// The box of child `child` (0..4) of packed BVH node `node`, decoded from the node's plane
/// texels (layout: `tracer::kernel::scene_data::NODE_TEXELS`). Unused slots give an empty box
/// (min > max).
pub fn node_child_box(scene: &tracer::kernel::scene_data::Scene, node: u32, child: usize) -> (Vec3, Vec3) {
    use tracer::kernel::scene_data::NODE_TEXELS;
    let plane = |t: u32| scene.nodes.as_slice()[(node * NODE_TEXELS + t) as usize][child];
    (Vec3::new(plane(0), plane(2), plane(4)), Vec3::new(plane(1), plane(3), plane(5)))
}
