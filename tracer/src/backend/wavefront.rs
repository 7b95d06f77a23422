//! The wavefront schedule as hosts run it (`kernel::wavefront` holds the stages): the order of
//! an iteration's dispatches, how each is sized, how big the pool of paths is, and the pool's
//! initial state. The CPU runtime (`cpu::WavefrontRenderer`) and the wgpu runtime
//! (`wgpu::WavefrontRenderer`) both follow [`ITERATION`].

use glam::{UVec4, Vec4};
use kernel_dsl::{Atomics, Storage};

use crate::kernel::wavefront::{
    Dispatch, Paths, ARGS_ACCUMULATE, ARGS_CONNECT, ARGS_EXTEND, ARGS_GENERATE, ARGS_WORDS, COUNTERS, FRAMES_DONE,
    FREE, SEGMENTS, SHADOW_RAYS, WORKGROUP,
};
use crate::kernel::Features;

/// One dispatch of an iteration: the kernel function it runs and how many invocations.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Stage {
    pub function: &'static str,
    /// `None`: one invocation (a `plan_*` stage, which reads the queue lengths and writes the
    /// next stages' sizes); `Some(at)`: the grid written at `at` in `Dispatch::args`.
    pub args: Option<u32>,
}

/// An iteration's dispatches, in order. Each path in the pool advances by at most one segment.
pub const ITERATION: [Stage; 8] = [
    Stage { function: "plan_generate", args: None },
    Stage { function: "generate", args: Some(ARGS_GENERATE) },
    Stage { function: "plan_extend", args: None },
    Stage { function: "extend", args: Some(ARGS_EXTEND) },
    Stage { function: "shade", args: Some(ARGS_EXTEND) },
    Stage { function: "plan_connect", args: None },
    Stage { function: "connect", args: Some(ARGS_CONNECT) },
    Stage { function: "accumulate", args: Some(ARGS_ACCUMULATE) },
];

/// Iterations a GPU runtime submits at once, between two read-backs of the counters: a
/// submission's work is at most this many path segments per slot of the pool, whatever the
/// paths' depth. Measured on lavapipe (`examples/bench_wavefront.rs`, 160x160, depth 8): 2, 4
/// and 8 per submission within noise of each other (4 the fastest), 10 (`max_depth + 2`) 5-30 %
/// slower on DamagedHelmet, whose paths mostly end early. At 640x480 (`--ips 4,8,16`, four
/// scenes, depths 8 and 32): 8 took 0.87-1.48x the time of 4, 16 took 0.97-1.82x: a frame ends
/// at a submission's end, so a longer one adds idle iterations (17-26 ms each on the textured
/// scenes), and waiting for the counters is not what costs.
pub const ITERATIONS_PER_SUBMISSION: u32 = 4;

/// What a host's `profile_frame` measures over one frame: each stage's seconds (in
/// [`ITERATION`]'s order) and the paths each iteration extended (one entry per iteration).
pub type FrameProfile = (Vec<(&'static str, f64)>, Vec<u32>);

/// Every stage's function (the entry points of the wavefront's shader; each runs once per iteration).
pub fn stage_functions() -> Vec<&'static str> {
    ITERATION.iter().map(|s| s.function).collect()
}

/// Bytes of the pool's state per path slot: eight `Vec4` arrays, one `UVec4` array and five
/// `u32` queue entries (two active queues, shadow, finished, free).
pub const BYTES_PER_PATH: u64 = 8 * 16 + 16 + 5 * 4;

/// Bytes per path slot the denoiser's guide adds (`Features::denoise_guide`): the first hit's
/// emission (`Paths::first_emission`, one `Vec4`).
pub const GUIDE_BYTES_PER_PATH: u64 = 16;

/// Bytes per pixel: the image's running sum (one `Vec4`), and with the denoiser's guide its
/// three sums (`Paths::guide_albedo`, `guide_normal`, `guide_emission`).
pub const fn bytes_per_pixel(guide: bool) -> u64 {
    if guide {
        4 * 16
    } else {
        16
    }
}

/// At most this many path slots: a pool larger than the image has nothing to do (a frame is
/// one path per pixel), and beyond ~1 M paths a GPU is full while memory keeps growing.
pub const MAX_POOL: u32 = 1 << 20;

/// Why the wavefront cannot render a scene.
#[derive(Debug, thiserror::Error)]
pub enum WavefrontError {
    #[error(
        "the image ({pixels} pixels) does not fit the device: its running sums alone take {need} bytes, over the {limit_name} of {limit} bytes"
    )]
    ImageTooLarge { pixels: u64, need: u64, limit_name: &'static str, limit: u64 },
    #[error(
        "the {runtime} runtime has no wavefront schedule: GLSL ES 3.00 has no compute shaders or atomics (use `--schedule megakernel`, or the cpu or wgpu backend)"
    )]
    NoCompute { runtime: &'static str },
    /// A stage of [`ITERATION`] that a runtime has no function for (a new stage not added to it).
    #[error("the wavefront stage `{stage}` is not implemented by this runtime")]
    UnknownStage { stage: &'static str },
    #[error("the wavefront did not complete its frame in {iterations} iterations (a path outlived the scene's depth)")]
    Stalled { iterations: u32 },
}

/// The pool for an image of `pixels` pixels on a device whose largest storage binding is
/// `max_binding` bytes, for a scene with `features`: the per-slot `Vec4` arrays and the image's
/// sums (with the denoiser's guide, its sums and per-slot array too) share one binding
/// (`Storage<Vec4>` arrays are concatenated), so the slots are what is left of it after the
/// image, in whole workgroups, at most [`MAX_POOL`] and the image's pixel count.
pub fn pool_size(pixels: u32, max_binding: u64, features: &Features) -> Result<u32, WavefrontError> {
    let guide = features.denoise_guide;
    let image = pixels as u64 * bytes_per_pixel(guide);
    let per_slot = 8 * 16 + if guide { GUIDE_BYTES_PER_PATH } else { 0 };
    let room = max_binding.saturating_sub(image) / per_slot;
    let pool = room.min(pixels as u64).min(MAX_POOL as u64) as u32;
    let pool = if pool >= WORKGROUP { pool / WORKGROUP * WORKGROUP } else { pool };
    if pool == 0 && pixels > 0 {
        return Err(WavefrontError::ImageTooLarge {
            pixels: pixels as u64,
            need: image + per_slot,
            limit_name: "largest storage buffer binding",
            limit: max_binding,
        });
    }
    Ok(pool)
}

/// Elements of array `field` of [`Paths`] for a pool of `pool` slots and `pixels` pixels: one
/// per slot, two per slot for the two active queues, one per pixel for the image's sums and the
/// denoiser's guide sums, [`COUNTERS`] counters.
pub fn array_len(field: &str, pool: u32, pixels: u32) -> usize {
    match field {
        "active" => 2 * pool as usize,
        "image" | "guide_albedo" | "guide_normal" | "guide_emission" => pixels as usize,
        "counters" => COUNTERS as usize,
        _ => pool as usize,
    }
}

/// A fresh pool of `pool` slots for `pixels` pixels and render seed `seed`: every slot free,
/// no frame begun, the sums zero. With `guide` (`Features::denoise_guide`) the denoiser's
/// guide arrays are sized too (empty without: the stages do not reach them).
pub fn new_paths(pool: u32, pixels: u32, seed: u32, guide: bool) -> Paths {
    let slots = array_len("origin", pool, pixels);
    let guide_len = |field: &str| if guide { array_len(field, pool, pixels) } else { 0 };
    let paths = Paths {
        pool,
        pixels,
        frames_wanted: 0,
        seed,
        origin: Storage::new(slots),
        direction: Storage::new(slots),
        throughput: Storage::new(slots),
        radiance: Storage::new(slots),
        hit: Storage::new(slots),
        shadow_origin: Storage::new(slots),
        shadow_direction: Storage::new(slots),
        shadow_contribution: Storage::new(slots),
        words: Storage::<UVec4>::new(slots),
        active: Storage::new(array_len("active", pool, pixels)),
        shadow_queue: Storage::new(slots),
        finished: Storage::new(slots),
        free: Storage::new(slots),
        image: Storage::<Vec4>::new(array_len("image", pool, pixels)),
        guide_albedo: Storage::new(guide_len("guide_albedo")),
        guide_normal: Storage::new(guide_len("guide_normal")),
        guide_emission: Storage::new(guide_len("guide_emission")),
        first_emission: Storage::new(guide_len("first_emission")),
        counters: Atomics::new(array_len("counters", pool, pixels)),
    };
    reset(&paths);
    paths
}

/// Empties `paths`: every slot free (the stack holds slots 0..pool), every counter and sum zero.
pub fn reset(paths: &Paths) {
    for slot in 0..paths.pool {
        paths.free.store(slot, slot);
    }
    for k in 0..COUNTERS {
        paths.counters.atomic_store(k, 0);
    }
    paths.counters.atomic_store(FREE, paths.pool);
    for pixel in 0..paths.pixels {
        paths.image.store(pixel, Vec4::ZERO);
    }
    for sums in [&paths.guide_albedo, &paths.guide_normal, &paths.guide_emission] {
        for pixel in 0..sums.len() as u32 {
            sums.store(pixel, Vec4::ZERO);
        }
    }
}

/// The indirect dispatches' sizes, all zero.
pub fn new_dispatch() -> Dispatch {
    Dispatch { args: Storage::new(ARGS_WORDS as usize) }
}

/// Iterations after which a frame that has not completed is [`WavefrontError::Stalled`]:
/// each wave of paths (the pixels over the pool) takes at most `max_depth` segments, plus the
/// iteration that completes the frame.
pub fn iteration_bound(pixels: u32, pool: u32, max_depth: u32) -> u32 {
    let waves = pixels.div_ceil(pool.max(1));
    waves.saturating_mul(max_depth.max(1) + 2).saturating_add(4)
}

/// What a wavefront traced: extension rays (path segments) and shadow rays since the pool
/// was reset, and frames completed.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct WavefrontCounts {
    pub segments: u32,
    pub shadow_rays: u32,
    pub frames: u32,
}

impl WavefrontCounts {
    /// The counts in `counters` (`Paths::counters` as read back).
    pub fn from_counters(counters: &[u32]) -> WavefrontCounts {
        let at = |k: u32| counters.get(k as usize).copied().unwrap_or(0);
        WavefrontCounts { segments: at(SEGMENTS), shadow_rays: at(SHADOW_RAYS), frames: at(FRAMES_DONE) }
    }
}

#[cfg(test)]
mod tests {
    use lightport_codegen::BindingKind;

    use super::*;

    /// The denoiser's guide in the stages only when asked for: without `denoise_guide` the
    /// stages carry no guide code and bind no guide array; with it the guide's arrays share the
    /// pool's one `Vec4` buffer (the stages stay within WebGPU's 8 storage buffers), and
    /// [`array_len`] sizes the sums per pixel and the first hit's emission per slot.
    #[test]
    fn the_guide_is_in_the_stages_only_with_the_flag() {
        let guide_arrays = ["guide_albedo", "guide_normal", "guide_emission", "first_emission"];
        for guide in [false, true] {
            let features = Features { emissive_triangles: true, denoise_guide: guide, ..Default::default() };
            let generated = crate::kernel::wavefront_shader(&features).expect("the wavefront's shader");
            let storage: Vec<_> = generated
                .bindings
                .iter()
                .flat_map(|r| &r.bindings)
                .filter(|b| !matches!(b.kind, BindingKind::Uniform))
                .collect();
            assert!(storage.len() <= 8, "guide {guide}: {} storage buffers", storage.len());
            let vec4f: Vec<&str> = storage
                .iter()
                .filter(|b| b.variable == "lp_paths_storage_vec4f")
                .flat_map(|b| b.fields.iter().map(|f| f.field.as_str()))
                .collect();
            assert!(vec4f.contains(&"image"), "{vec4f:?}");
            for array in guide_arrays {
                assert_eq!(vec4f.contains(&array), guide, "guide {guide}: {array} in {vec4f:?}");
                assert_eq!(generated.source.contains(array), guide, "guide {guide}: {array} in the source");
            }
        }
        assert_eq!(array_len("guide_normal", 64, 1000), 1000);
        assert_eq!(array_len("first_emission", 64, 1000), 64);
        let paths = new_paths(64, 1000, 1, false);
        assert!(paths.guide_albedo.is_empty() && paths.first_emission.is_empty());
        let paths = new_paths(64, 1000, 1, true);
        assert_eq!((paths.guide_emission.len(), paths.first_emission.len()), (1000, 64));
    }
}
