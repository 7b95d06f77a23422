//! The CPU backend: the DSL kernel compiled as ordinary Rust, run per pixel with rayon. It is
//! the reference the GPU backends are compared with.

use glam::{Vec3, Vec4, Vec4Swizzles};
use rayon::prelude::*;

use super::{frame_seed, Image};
use crate::kernel::integrator::render_sample;
use crate::pack::Packed;

pub struct CpuRenderer {
    packed: Packed,
    seed: u32,
    frames: u32,
    /// Sum of samples per pixel: rgb, and the number of accepted (finite) samples in w.
    accumulation: Vec<Vec4>,
    /// Sum of squared samples per pixel, for variance estimates.
    squares: Vec<Vec3>,
}

impl CpuRenderer {
    /// A renderer for `packed`; `seed` selects the random sequence (same seed, same image).
    pub fn new(packed: Packed, seed: u32) -> Self {
        let n = packed.scene.width as usize * packed.scene.height as usize;
        CpuRenderer { packed, seed, frames: 0, accumulation: vec![Vec4::ZERO; n], squares: vec![Vec3::ZERO; n] }
    }

    pub fn frames(&self) -> u32 {
        self.frames
    }

    pub fn packed(&self) -> &Packed {
        &self.packed
    }

    /// Adds one sample per pixel.
    pub fn render_frame(&mut self) {
        self.packed.scene.frame_seed = frame_seed(self.frames, self.seed);
        let scene = &self.packed.scene;
        let width = scene.width as usize;
        self.accumulation.par_chunks_mut(width).zip(self.squares.par_chunks_mut(width)).enumerate().for_each(
            |(y, (row, squares))| {
                for (x, (acc, sq)) in row.iter_mut().zip(squares).enumerate() {
                    let sample = render_sample(scene, x as u32, y as u32);
                    *acc += sample;
                    *sq += sample.xyz() * sample.xyz();
                }
            },
        );
        self.frames += 1;
    }

    /// Samples that were not finite and were dropped, over the whole image.
    pub fn rejected_samples(&self) -> u64 {
        let accepted: f64 = self.accumulation.iter().map(|a| a.w as f64).sum();
        (self.frames as u64 * self.accumulation.len() as u64).saturating_sub(accepted.round() as u64)
    }

    /// The mean of the accumulated samples (linear RGB).
    pub fn image(&self) -> Image {
        let n = self.frames.max(1) as f32;
        Image {
            width: self.packed.scene.width,
            height: self.packed.scene.height,
            pixels: self.accumulation.iter().map(|a| a.xyz() / n).collect(),
        }
    }

    /// Per-pixel sample variance (unbiased, per channel).
    pub fn variance(&self) -> Vec<Vec3> {
        let n = self.frames as f32;
        if n < 2.0 {
            return vec![Vec3::ZERO; self.squares.len()];
        }
        self.accumulation
            .iter()
            .zip(&self.squares)
            .map(|(s, q)| {
                let mean = s.xyz() / n;
                ((*q / n - mean * mean) * (n / (n - 1.0))).max(Vec3::ZERO)
            })
            .collect()
    }
}
