//! Lights: emissive triangles, point lights, then the sky (the kernel expects it last), each with
//! its share of the light samples, chosen through an alias table (`kernel::lights::choose_light`).

use glam::{Vec3, Vec4};
use kernel_dsl::Texels;
use rayon::prelude::*;

use super::PackedTextures;
use crate::bvh::Bvh;
use crate::kernel::lights::luminance;
use crate::kernel::scene_data::{LIGHT_POINT, LIGHT_SKY, LIGHT_TEXELS, LIGHT_TRIANGLE};
use crate::scene::{Aabb, Scene, Triangle};

/// Which materials and triangles emit.
pub(super) struct Emissive {
    material: Vec<bool>,
    /// Emissive triangles' indices in BVH order, ascending.
    pub triangles: Vec<u32>,
}

impl Emissive {
    pub fn new(scene: &Scene, bvh: &Bvh) -> Self {
        let material: Vec<bool> = scene.materials.iter().map(|m| m.is_emissive()).collect();
        // Which triangles emit is read in scene order (a stream through memory, not a gather),
        // then permuted.
        let triangles: Vec<u32> = if material.contains(&true) {
            let emits: Vec<bool> = scene.triangles.par_iter().map(|t| emits(&material, t)).collect();
            (bvh.triangle_order.par_iter().with_min_len(1 << 12).enumerate())
                .filter(|(_, &t)| emits[t as usize])
                .map(|(i, _)| i as u32)
                .collect()
        } else {
            Vec::new()
        };
        Emissive { material, triangles }
    }

    /// The light of triangle `t`, the `i`th in BVH order: emissive triangle `i`'s light is its
    /// position in `triangles` (they come first).
    pub fn light_of(&self, i: usize, t: &Triangle) -> Option<u32> {
        if emits(&self.material, t) {
            self.triangles.binary_search(&(i as u32)).ok().map(|l| l as u32)
        } else {
            None
        }
    }
}

/// Whether `t`'s material emits.
fn emits(material: &[bool], t: &Triangle) -> bool {
    material.get(t.material as usize).copied().unwrap_or(false)
}

/// The kernel's light array.
pub(super) struct PackedLights {
    pub lights: Texels<Vec4>,
    pub count: usize,
}

/// The light list: per light its power estimate (the weight light selection samples by) and its
/// kind with two texels of data. `sky_mean_radiance` is [`super::sky::PackedSky::mean_radiance`].
pub(super) fn pack_lights(
    scene: &Scene,
    ordered: &[&Triangle],
    emissive: &Emissive,
    textures: &PackedTextures,
    bounds: Aabb,
    sky_mean_radiance: f32,
) -> PackedLights {
    let radius = (0.5 * bounds.diagonal().length()).max(1e-6);
    let mut light_weights = Vec::new();
    let mut light_data: Vec<(u32, Vec4, Vec4)> = Vec::new();
    let texture_mean = &textures.emissive_mean_luminance;
    for &ti in &emissive.triangles {
        let t = ordered[ti as usize];
        let m = &scene.materials[t.material as usize];
        let texture_mean =
            m.emissive_texture.and_then(|i| texture_mean.get(i as usize).copied().flatten()).unwrap_or(1.0);
        // The same arithmetic as the kernel's for a hit triangle (`integrator`), so that both
        // MIS pdfs of a light use the same area.
        let face = (t.positions[1] - t.positions[0]).cross(t.positions[2] - t.positions[0]);
        let area2 = face.length();
        let area = 0.5 * area2;
        let normal = if area2 > 0.0 { face / area2 } else { Vec3::ZERO };
        light_weights.push(luminance(m.emission) as f64 * texture_mean as f64 * area as f64 * std::f64::consts::PI);
        light_data.push((
            LIGHT_TRIANGLE,
            Vec4::new(ti as f32, normal.x, normal.y, normal.z),
            Vec4::new(area, 0.0, 0.0, 0.0),
        ));
    }
    for p in &scene.point_lights {
        light_weights.push(luminance(p.intensity) as f64 * 4.0 * std::f64::consts::PI);
        light_data.push((LIGHT_POINT, p.position.extend(0.0), p.intensity.extend(0.0)));
    }
    if scene.sky.is_some() {
        light_weights
            .push(sky_mean_radiance as f64 * std::f64::consts::PI * (radius as f64).powi(2) * std::f64::consts::PI);
        light_data.push((LIGHT_SKY, Vec4::ZERO, Vec4::ZERO));
    }
    let light_weights = shares(&light_weights);
    let total_weight: f32 = light_weights.iter().sum();
    let alias = alias_table(&light_weights);
    let mut lights = Vec::with_capacity(light_data.len() * LIGHT_TEXELS as usize);
    for (i, (kind, a, b)) in light_data.iter().enumerate() {
        let (threshold, alias_index) = alias[i];
        lights.push(Vec4::new(threshold, alias_index as f32, light_weights[i] / total_weight, *kind as f32));
        lights.push(*a);
        lights.push(*b);
    }
    PackedLights { lights: Texels::new(lights), count: light_data.len() }
}

/// Each light's share of the samples, relative to the mean weight. Every light keeps a share:
/// with next event estimation only, a light that is never chosen would be missing from the
/// image. Weights are powers in f64: f32 radiances up to the loaders' limit times areas cannot
/// overflow it, so one huge light cannot turn the mean (and every pmf) into inf/NaN.
fn shares(light_weights: &[f64]) -> Vec<f32> {
    let mean_weight = light_weights.iter().sum::<f64>() / light_weights.len().max(1) as f64;
    let floor = if mean_weight > 0.0 && mean_weight.is_finite() { mean_weight * 1e-3 } else { 1.0 };
    light_weights
        .iter()
        .map(|w| {
            let w = if w.is_finite() { w.max(floor) } else { floor };
            // The shares are what the kernel reads; normalise in f64 before narrowing.
            w / mean_weight.max(floor)
        })
        .map(|w| w as f32)
        .collect()
}

/// Vose's alias method: (threshold, alias) per entry for sampling proportionally to `weights`.
fn alias_table(weights: &[f32]) -> Vec<(f32, u32)> {
    let n = weights.len();
    let total: f64 = weights.iter().map(|w| *w as f64).sum();
    let mut scaled: Vec<f64> = weights.iter().map(|w| *w as f64 * n as f64 / total).collect();
    let mut table = vec![(1.0f32, 0u32); n];
    for (i, t) in table.iter_mut().enumerate() {
        t.1 = i as u32;
    }
    let (mut small, mut large): (Vec<usize>, Vec<usize>) = (0..n).partition(|&i| scaled[i] < 1.0);
    while let (Some(s), Some(&l)) = (small.pop(), large.last()) {
        table[s] = (scaled[s] as f32, l as u32);
        scaled[l] -= 1.0 - scaled[s];
        if scaled[l] < 1.0 {
            large.pop();
            small.push(l);
        }
    }
    table
}
