//! The wavefront schedule on the CPU: each stage of `kernel::wavefront` run over its grid with
//! rayon, the queues and counters the kernel's own `Storage` and `Atomics` (atomic words on the
//! CPU). The reference the wgpu wavefront is compared with, and, since every path computes what
//! the megakernel's would, equal to [`CpuRenderer`](super::CpuRenderer) bit for bit.

use glam::Vec4;
use rayon::prelude::*;

use crate::backend::wavefront::{
    iteration_bound, new_dispatch, new_paths, reset, FrameProfile, Stage, WavefrontCounts, WavefrontError, ITERATION,
    MAX_POOL,
};
use crate::backend::{exchange_scene, update_uniforms, GuideSums, RenderError, Renderer, RendererInfo};
use crate::kernel::scene_data::Scene;
use crate::kernel::wavefront::{self as stages, Dispatch, Paths, FRAMES_DONE, WORKGROUP};
use crate::pack::Packed;

/// Path slots on the CPU: one per pixel up to [`MAX_POOL`] (2^20; 164 bytes of state each,
/// 172 MB at a million pixels and more), so that a frame is one wave of paths. Measured
/// (`examples/bench_wavefront.rs --pools 65536,307200`, 640x480, median of 5 alternated rounds):
/// a slot per pixel took 0.79-0.96x the time of 2^16 slots on all eight rows (four scenes,
/// depths 8 and 32), 0.79x on the Cornell box.
pub const CPU_POOL: u32 = MAX_POOL;

/// A stage as the CPU calls it: the kernel function with every resource it may take.
type StageFn = fn(&Scene, &Paths, &Dispatch, u32);

/// Each stage of [`ITERATION`] by its kernel function's name.
const CPU_STAGES: [(&str, StageFn); 8] = [
    ("plan_generate", |_, p, d, i| stages::plan_generate(p, d, i)),
    ("generate", |s, p, _, i| stages::generate(s, p, i)),
    ("plan_extend", |_, p, d, i| stages::plan_extend(p, d, i)),
    ("extend", |s, p, _, i| stages::extend(s, p, i)),
    ("shade", |s, p, _, i| stages::shade(s, p, i)),
    ("plan_connect", |_, p, d, i| stages::plan_connect(p, d, i)),
    ("connect", |s, p, _, i| stages::connect(s, p, i)),
    ("accumulate", |s, p, _, i| stages::accumulate(s, p, i)),
];

pub struct WavefrontRenderer {
    packed: Packed,
    paths: Paths,
    dispatch: Dispatch,
    frames: u32,
}

impl WavefrontRenderer {
    /// A wavefront renderer for `packed` with `seed` (the megakernel's random sequence), over a
    /// pool of at most `pool` slots (at most one per pixel).
    pub fn new(packed: Packed, seed: u32, pool: u32) -> Result<Self, RenderError> {
        let pixels = packed.scene.width * packed.scene.height;
        let pool = pool.min(pixels).max(1);
        let paths = new_paths(pool, pixels, seed, packed.features.denoise_guide);
        Ok(WavefrontRenderer { packed, paths, dispatch: new_dispatch(), frames: 0 })
    }

    /// The pool: its slots, queues and counters as the stages left them.
    pub fn paths(&self) -> &Paths {
        &self.paths
    }

    /// What the pool has traced since the last restart.
    pub fn counts(&self) -> WavefrontCounts {
        WavefrontCounts::from_counters(&self.paths.counters.to_vec())
    }

    /// A measurement: renders the next frame as [`render_band`](Renderer::render_band) does,
    /// timing each stage, and returns each stage's seconds over the frame (in [`ITERATION`]'s
    /// order) and the paths each iteration extended (its length is the
    /// iterations the frame took).
    pub fn profile_frame(&mut self) -> Result<FrameProfile, RenderError> {
        let wanted = self.frames + 1;
        self.paths.frames_wanted = wanted;
        let bound = iteration_bound(self.paths.pixels, self.paths.pool, self.packed.scene.max_depth);
        let mut seconds = [0.0; ITERATION.len()];
        let mut iterations = 0;
        let mut extended = Vec::new();
        let mut segments = self.counts().segments;
        while self.paths.counters.atomic_load(FRAMES_DONE) < wanted {
            if iterations == bound {
                return Err(WavefrontError::Stalled { iterations }.into());
            }
            for (stage, s) in ITERATION.into_iter().zip(&mut seconds) {
                let t = std::time::Instant::now();
                self.run(stage)?;
                *s += t.elapsed().as_secs_f64();
            }
            iterations += 1;
            let now = self.counts().segments;
            extended.push(now.wrapping_sub(segments));
            segments = now;
        }
        self.frames = wanted;
        Ok((ITERATION.iter().map(|s| s.function).zip(seconds).collect(), extended))
    }

    /// Runs `stage` over its grid: one invocation for a `plan_*` stage, else the grid its plan
    /// wrote, numbered as a GPU numbers it (`x + y * groups_x * WORKGROUP`).
    fn run(&self, stage: Stage) -> Result<(), WavefrontError> {
        let (scene, paths, dispatch) = (&self.packed.scene, &self.paths, &self.dispatch);
        let invocations = match stage.args {
            None => 1,
            Some(at) => dispatch.args.load(at) * dispatch.args.load(at + 1) * dispatch.args.load(at + 2) * WORKGROUP,
        };
        let Some(&(_, run)) = CPU_STAGES.iter().find(|(name, _)| *name == stage.function) else {
            return Err(WavefrontError::UnknownStage { stage: stage.function });
        };
        let call = |i: u32| run(scene, paths, dispatch, i);
        if invocations <= WORKGROUP {
            (0..invocations).for_each(call);
        } else {
            (0..invocations).into_par_iter().with_min_len(WORKGROUP as usize).for_each(call);
        }
        Ok(())
    }
}

impl Renderer for WavefrontRenderer {
    fn describe(&self) -> RendererInfo {
        let threads = rayon::current_num_threads();
        RendererInfo {
            runtime: "cpu",
            device: format!("{threads} threads, wavefront"),
            limits: vec![("path slots", self.paths.pool as u64)],
        }
    }

    fn packed(&self) -> &Packed {
        &self.packed
    }

    fn frames(&self) -> u32 {
        self.frames
    }

    /// A wavefront frame is not split into rows (its work per iteration is bounded by the pool).
    fn rows_left(&self) -> u32 {
        self.packed.scene.height
    }

    /// Renders a whole frame, whatever `rows`: iterations until every pixel has its sample.
    fn render_band(&mut self, _rows: u32) -> Result<bool, RenderError> {
        let wanted = self.frames + 1;
        self.paths.frames_wanted = wanted;
        let scene = &self.packed.scene;
        let bound = iteration_bound(self.paths.pixels, self.paths.pool, scene.max_depth);
        let mut iterations = 0;
        while self.paths.counters.atomic_load(FRAMES_DONE) < wanted {
            if iterations == bound {
                return Err(WavefrontError::Stalled { iterations }.into());
            }
            for stage in ITERATION {
                self.run(stage)?;
            }
            iterations += 1;
        }
        self.frames = wanted;
        Ok(true)
    }

    fn finish(&self) -> Result<(), RenderError> {
        Ok(())
    }

    fn accumulation(&self) -> Result<Vec<Vec4>, RenderError> {
        Ok(self.paths.image.to_vec())
    }

    fn guide_sums(&self) -> Result<GuideSums, RenderError> {
        if !self.packed.features.denoise_guide {
            return Err(RenderError::NoGuide);
        }
        let p = &self.paths;
        Ok([p.guide_albedo.to_vec(), p.guide_normal.to_vec(), p.guide_emission.to_vec()])
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

    fn wavefront_counts(&self) -> Option<WavefrontCounts> {
        Some(self.counts())
    }

    fn restart(&mut self) -> Result<(), RenderError> {
        reset(&self.paths);
        self.paths.frames_wanted = 0;
        self.frames = 0;
        Ok(())
    }
}
