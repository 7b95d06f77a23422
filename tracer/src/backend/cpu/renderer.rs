use glam::{Vec3, Vec4, Vec4Swizzles};
use rayon::prelude::*;

use crate::backend::{exchange_scene, frame_seed, update_uniforms, GuideSums, RenderError, Renderer, RendererInfo};
use crate::kernel::integrator::{render_guided_sample, render_sample};
use crate::kernel::scene_data::Scene;
use crate::pack::Packed;

pub struct CpuRenderer {
    packed: Packed,
    seed: u32,
    frames: u32,
    /// Rows of the frame in progress already rendered ([`Renderer::render_band`]).
    band_row: u32,
    /// Sum of samples per pixel: rgb, and the number of accepted (finite) samples in w.
    accumulation: Vec<Vec4>,
    /// Sum of squared samples per pixel, for variance estimates.
    squares: Vec<Vec3>,
    /// With the denoiser's guide (`Features::denoise_guide`), its three sums per pixel
    /// (`integrator::GuidedSample`'s fields after the colour); empty without.
    guide: Vec<[Vec4; 3]>,
}

impl CpuRenderer {
    /// A renderer for `packed`; `seed` selects the random sequence (same seed, same image).
    pub fn new(packed: Packed, seed: u32) -> Self {
        let n = packed.scene.width as usize * packed.scene.height as usize;
        let guide = if packed.features.denoise_guide { vec![[Vec4::ZERO; 3]; n] } else { Vec::new() };
        CpuRenderer {
            packed,
            seed,
            frames: 0,
            band_row: 0,
            guide,
            accumulation: vec![Vec4::ZERO; n],
            squares: vec![Vec3::ZERO; n],
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

impl Renderer for CpuRenderer {
    fn describe(&self) -> RendererInfo {
        let threads = rayon::current_num_threads();
        RendererInfo { runtime: "cpu", device: format!("{threads} threads"), limits: Vec::new() }
    }

    fn packed(&self) -> &Packed {
        &self.packed
    }

    fn frames(&self) -> u32 {
        self.frames
    }

    fn rows_left(&self) -> u32 {
        self.packed.scene.height - self.band_row
    }

    /// Renders the band's rows in parallel, adding each pixel's sample in place: between the
    /// bands of a split frame, the rows rendered already hold the frame's sample (as on wgpu).
    fn render_band(&mut self, rows: u32) -> Result<bool, RenderError> {
        // At least one row, at most those left (none of an empty image).
        let rows = rows.max(1).min(self.rows_left());
        self.packed.scene.frame_seed = frame_seed(self.frames, self.seed);
        self.packed.scene.frame_index = self.frames;
        let scene = &self.packed.scene;
        let width = scene.width as usize;
        let (first, end) = (self.band_row as usize * width, (self.band_row + rows) as usize * width);
        let first_row = self.band_row;
        let rows_of_sums =
            self.accumulation[first..end].par_chunks_mut(width).zip(self.squares[first..end].par_chunks_mut(width));
        if self.guide.is_empty() {
            rows_of_sums
                .enumerate()
                .for_each(|(y, (row, squares))| render_row_fastest(scene, first_row + y as u32, row, squares));
        } else {
            rows_of_sums.zip(self.guide[first..end].par_chunks_mut(width)).enumerate().for_each(
                |(y, ((row, squares), guide))| render_guided_row(scene, first_row + y as u32, row, squares, guide),
            );
        }
        self.band_row += rows;
        if self.band_row < scene.height {
            return Ok(false);
        }
        self.band_row = 0;
        self.frames += 1;
        Ok(true)
    }

    fn finish(&self) -> Result<(), RenderError> {
        Ok(())
    }

    fn accumulation(&self) -> Result<Vec<Vec4>, RenderError> {
        Ok(self.accumulation.clone())
    }

    fn guide_sums(&self) -> Result<GuideSums, RenderError> {
        if self.guide.is_empty() {
            return Err(RenderError::NoGuide);
        }
        Ok(std::array::from_fn(|k| self.guide.iter().map(|g| g[k]).collect()))
    }

    fn set_uniforms(&mut self, update: &mut dyn FnMut(&mut Scene)) -> Result<(), RenderError> {
        update_uniforms(&mut self.packed.scene, update)?;
        self.restart()
    }

    fn take_geometry(&mut self, moved: Packed) -> Result<(), RenderError> {
        self.packed.take_geometry(moved)?;
        self.restart()
    }

    fn take_scene(&mut self, mut scene: Packed) -> Result<(), RenderError> {
        exchange_scene(&mut self.packed, &mut scene)?;
        self.restart()
    }

    fn restart(&mut self) -> Result<(), RenderError> {
        self.accumulation.fill(Vec4::ZERO);
        self.squares.fill(Vec3::ZERO);
        self.guide.fill([Vec4::ZERO; 3]);
        self.frames = 0;
        self.band_row = 0;
        Ok(())
    }
}

/// One sample for each pixel of row `y`, added to the row's sums.
#[inline(always)]
fn render_row(scene: &Scene, y: u32, row: &mut [Vec4], squares: &mut [Vec3]) {
    for (x, (acc, sq)) in row.iter_mut().zip(squares).enumerate() {
        let sample = render_sample(scene, x as u32, y);
        *acc += sample;
        *sq += sample.xyz() * sample.xyz();
    }
}

/// [`render_row`] with the denoiser's guide: each pixel's sample and its guide sums.
fn render_guided_row(scene: &Scene, y: u32, row: &mut [Vec4], squares: &mut [Vec3], guide: &mut [[Vec4; 3]]) {
    for (x, ((acc, sq), g)) in row.iter_mut().zip(squares).zip(guide).enumerate() {
        let sample = render_guided_sample(scene, x as u32, y);
        *acc += sample.color;
        *sq += sample.color.xyz() * sample.color.xyz();
        g[0] += sample.albedo;
        g[1] += sample.normal;
        g[2] += sample.emission;
    }
}

/// `render_row` compiled for the fastest instruction set this CPU has. The kernel's hot
/// functions are `#[inline(always)]`, so they are compiled again inside `render_row_avx2`:
/// the same code with VEX encodings (three-operand SSE, fewer register moves), about 9 % fewer
/// instructions. The samples are the same bit for bit: Rust never fuses a multiply and an add
/// on its own, and the other instructions round alike (a unit test compares the two).
fn render_row_fastest(scene: &Scene, y: u32, row: &mut [Vec4], squares: &mut [Vec3]) {
    #[cfg(target_arch = "x86_64")]
    if std::is_x86_feature_detected!("avx2") && std::is_x86_feature_detected!("fma") {
        // SAFETY: the CPU has the features `render_row_avx2` is compiled for (checked above;
        // the detection is cached, so the check costs a load per row).
        return unsafe { render_row_avx2(scene, y, row, squares) };
    }
    render_row(scene, y, row, squares)
}

/// `render_row` compiled for AVX2 and FMA. Safe to call only on a CPU that has them.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma,bmi1,bmi2,lzcnt,popcnt")]
unsafe fn render_row_avx2(scene: &Scene, y: u32, row: &mut [Vec4], squares: &mut [Vec3]) {
    render_row(scene, y, row, squares)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::kernel::features::RenderSettings;
    use crate::pack::pack;

    /// Every row the dispatched renderer gives equals the baseline build's, bit for bit: on the
    /// Cornell box (area lights) and the generated terrain (a sky, deep paths), two frames each.
    #[test]
    fn fastest_rows_equal_baseline_rows() {
        for scene in [crate::scene::cornell_box(), crate::scene::terrain_and_spheres()] {
            let bvh = crate::bvh::build(&scene.triangles).unwrap();
            let settings = RenderSettings { width: 48, height: 32, ..Default::default() };
            let mut packed = pack(&scene, &bvh, &settings).unwrap();
            for frame in 0..2 {
                packed.scene.frame_seed = frame_seed(frame, 7);
                packed.scene.frame_index = frame;
                for y in 0..settings.height {
                    let w = settings.width as usize;
                    let (mut base, mut base_sq) = (vec![Vec4::ZERO; w], vec![Vec3::ZERO; w]);
                    let (mut fast, mut fast_sq) = (vec![Vec4::ZERO; w], vec![Vec3::ZERO; w]);
                    render_row(&packed.scene, y, &mut base, &mut base_sq);
                    render_row_fastest(&packed.scene, y, &mut fast, &mut fast_sq);
                    let bits = |v: &[Vec4]| v.iter().flat_map(|p| p.to_array().map(f32::to_bits)).collect::<Vec<_>>();
                    assert_eq!(bits(&base), bits(&fast), "row {y}, frame {frame}");
                    assert!(base.iter().any(|p| p.x > 0.0), "row {y} is black: the test would prove nothing");
                }
            }
        }
    }
}
