#[kernel_dsl::kernel(compute)]
pub mod wavefront {
    //! The wavefront schedule of the path tracer (Laine, Karras & Aila 2013): the megakernel's
    //! three steps of a path segment ([`trace_closest`], [`shade_hit`], [`occluded`]) run as
    //! stages over a persistent pool of path slots, each stage one compute dispatch over a
    //! queue of slots, the queues' lengths kept in atomic counters on the device. A second
    //! schedule of the same path tracer, not a second path tracer: every path computes what the
    //! megakernel's would (bit for bit on the CPU).
    //!
    //! One iteration: [`plan_generate`] (one invocation) → [`generate`] → [`plan_extend`] →
    //! [`extend`] → [`shade`] → [`plan_connect`] → [`connect`] → [`accumulate`]. The `plan_*`
    //! stages turn queue lengths into the next stages' dispatch sizes (`Dispatch::args`, read by
    //! indirect dispatches), so a host never reads a queue back. A frame is one sample per pixel:
    //! pixels are handed out to free slots until every pixel of the frame has its path, and the
    //! frame is complete when every slot is free again (each pixel's sample is added to its sum
    //! by one path, so the sums need no float atomics).
    //!
    //! With the denoiser's guide (`Features::denoise_guide`, which specialises the stages as it
    //! does the megakernel), [`shade`] adds each path's first hit to its pixel's guide sums and
    //! [`accumulate`] the luminance moments of its sample: the sums the megakernel's entry point
    //! adds (`integrator::GuidedSample`). Without it the stages carry no guide code, and the
    //! guide's arrays are not bound.

    use glam::{UVec4, Vec3, Vec4, Vec4Swizzles};
    use kernel_dsl::{Atomics, Storage};

    use crate::kernel::integrator::{no_shadow_ray, shade_hit, start_path, FirstHit, PathState, SKY_DEPTH};
    use crate::kernel::intersect::MISS;
    use crate::kernel::lights::{finite_or_zero, luminance};
    use crate::kernel::rng::seed_of_frame;
    use crate::kernel::scene_data::Scene;
    use crate::kernel::traverse::{occluded, trace_closest, Hit};

    /// Invocations per workgroup of every stage (codegen's entry points).
    pub const WORKGROUP: u32 = 64;
    /// Workgroups per grid dimension (WebGPU's `maxComputeWorkgroupsPerDimension` default).
    pub const MAX_GROUPS: u32 = 65535;

    // `Paths::counters`, by index.
    /// Pixels of the current frame handed out to paths so far.
    pub const NEXT_PIXEL: u32 = 0;
    /// Frames completed since the pool was reset: every pixel's sample added to its sum.
    pub const FRAMES_DONE: u32 = 1;
    /// Free slots: the height of the `free` stack.
    pub const FREE: u32 = 2;
    /// Length of the current active queue (`active`, half `PARITY`): paths whose ray is traced
    /// and shaded this iteration.
    pub const ACTIVE: u32 = 3;
    /// Length of the next active queue (the other half): paths that go on after `shade`.
    pub const NEXT_ACTIVE: u32 = 4;
    /// Length of the shadow-ray queue.
    pub const SHADOW: u32 = 5;
    /// Length of the queue of paths that ended this iteration.
    pub const FINISHED: u32 = 6;
    /// The first pixel and the count [`generate`] starts this iteration.
    pub const GENERATE_BASE: u32 = 7;
    pub const GENERATE_COUNT: u32 = 8;
    /// Which half of `active` is the current queue (0 or 1).
    pub const PARITY: u32 = 9;
    /// Path segments traced since the pool was reset (extension rays), and shadow rays.
    pub const SEGMENTS: u32 = 10;
    pub const SHADOW_RAYS: u32 = 11;
    /// Counters in `Paths::counters`.
    pub const COUNTERS: u32 = 12;

    // `Dispatch::args`: three words (x, y, z workgroups) per indirect dispatch.
    pub const ARGS_GENERATE: u32 = 0;
    /// [`extend`] and [`shade`] (both over the current active queue).
    pub const ARGS_EXTEND: u32 = 3;
    pub const ARGS_CONNECT: u32 = 6;
    pub const ARGS_ACCUMULATE: u32 = 9;
    /// Words in `Dispatch::args`.
    pub const ARGS_WORDS: u32 = 12;

    /// The pool of paths and its queues, a structure of arrays: slot `s`'s state is element `s`
    /// of each per-slot array (see `docs/wavefront.md` for the bytes per path).
    #[resources(group = 1)]
    pub struct Paths {
        /// Slots in the pool.
        pub pool: u32,
        /// Pixels per frame (the image's width times height).
        pub pixels: u32,
        /// Frames to render: no path is started for a later frame.
        pub frames_wanted: u32,
        /// The render's seed, as `rng::seed_of_frame` takes it.
        pub seed: u32,
        /// Per slot: the ray's origin and the pdf of the BSDF sample that chose it.
        pub origin: Storage<Vec4>,
        /// Per slot: the ray's direction.
        pub direction: Storage<Vec4>,
        pub throughput: Storage<Vec4>,
        pub radiance: Storage<Vec4>,
        /// Per slot: what the ray hit (t, u, v, the instance's bits).
        pub hit: Storage<Vec4>,
        /// Per slot: the shadow ray's origin and length, direction, and what it adds.
        pub shadow_origin: Storage<Vec4>,
        pub shadow_direction: Storage<Vec4>,
        pub shadow_contribution: Storage<Vec4>,
        /// Per slot: pixel, random stream, depth, the hit triangle.
        pub words: Storage<UVec4>,
        /// Two active queues of `pool` slots each (current and next, by `PARITY`).
        pub active: Storage<u32>,
        pub shadow_queue: Storage<u32>,
        pub finished: Storage<u32>,
        /// The free slots, a stack.
        pub free: Storage<u32>,
        /// Per pixel: the running sum (rgb) and the count of finite samples (w).
        pub image: Storage<Vec4>,
        /// Per pixel, with the denoiser's guide only: the running sums of
        /// `integrator::GuidedSample`'s fields after the colour (albedo and luminance, normal
        /// and depth, emission and squared luminance), as the megakernel's entry point adds them.
        pub guide_albedo: Storage<Vec4>,
        pub guide_normal: Storage<Vec4>,
        pub guide_emission: Storage<Vec4>,
        /// Per slot, with the denoiser's guide only: the emission the path's first hit sends to
        /// the camera, which [`accumulate`] takes from the sample for the luminance moments.
        pub first_emission: Storage<Vec4>,
        pub counters: Atomics,
    }

    /// The indirect dispatches' sizes, written by the `plan_*` stages. A group of its own: a
    /// buffer read by an indirect dispatch may not be bound to the stage it dispatches.
    #[resources(group = 2)]
    pub struct Dispatch {
        pub args: Storage<u32>,
    }

    /// Writes, at `at` in `args`, a grid of `WORKGROUP`-wide workgroups covering `invocations`:
    /// at most `MAX_GROUPS` along x, the rest along y (a stage numbers its invocations
    /// `x + y * groups_x * WORKGROUP` and checks its own bound).
    pub fn write_grid(dispatch: &Dispatch, at: u32, invocations: u32) {
        let groups = invocations / WORKGROUP + if invocations % WORKGROUP != 0 { 1 } else { 0 };
        let mut x = groups;
        let mut y = 1u32;
        if groups > MAX_GROUPS {
            x = MAX_GROUPS;
            y = groups / MAX_GROUPS + if groups % MAX_GROUPS != 0 { 1 } else { 0 };
        }
        dispatch.args.store(at, x);
        dispatch.args.store(at + 1, y);
        dispatch.args.store(at + 2, 1);
    }

    /// One invocation: completes the frame whose paths have all ended, swaps the active
    /// queues (what `shade` appended becomes current) and hands free slots the next pixels.
    pub fn plan_generate(paths: &Paths, dispatch: &Dispatch, invocation: u32) {
        if invocation != 0 {
            return;
        }
        let mut next_pixel = paths.counters.atomic_load(NEXT_PIXEL);
        let mut frames = paths.counters.atomic_load(FRAMES_DONE);
        let free = paths.counters.atomic_load(FREE);
        if next_pixel >= paths.pixels && free == paths.pool {
            frames += 1;
            next_pixel = 0;
            paths.counters.atomic_store(FRAMES_DONE, frames);
        }
        paths.counters.atomic_store(PARITY, paths.counters.atomic_load(PARITY) ^ 1);
        paths.counters.atomic_store(ACTIVE, paths.counters.atomic_load(NEXT_ACTIVE));
        paths.counters.atomic_store(NEXT_ACTIVE, 0);
        let mut count = 0u32;
        if frames < paths.frames_wanted {
            count = paths.pixels - next_pixel;
            if free < count {
                count = free;
            }
        }
        paths.counters.atomic_store(GENERATE_BASE, next_pixel);
        paths.counters.atomic_store(GENERATE_COUNT, count);
        paths.counters.atomic_store(NEXT_PIXEL, next_pixel + count);
        paths.counters.atomic_store(FREE, free - count);
        write_grid(dispatch, ARGS_GENERATE, count);
    }

    /// Starts the camera paths of the pixels `plan_generate` handed out, one per free slot
    /// (taken from the top of the stack), and queues them to be traced.
    pub fn generate(scene: &Scene, paths: &Paths, invocation: u32) {
        if invocation >= paths.counters.atomic_load(GENERATE_COUNT) {
            return;
        }
        let slot = paths.free.load(paths.counters.atomic_load(FREE) + invocation);
        let pixel = paths.counters.atomic_load(GENERATE_BASE) + invocation;
        let frame = paths.counters.atomic_load(FRAMES_DONE);
        let path = start_path(scene, pixel % scene.width, pixel / scene.width, seed_of_frame(frame, paths.seed), frame);
        store_path(paths, slot, path, pixel);
        let at = paths.counters.atomic_add(ACTIVE, 1);
        paths.active.store(paths.counters.atomic_load(PARITY) * paths.pool + at, slot);
    }

    /// One invocation: the extension and shading stages' size (the current active queue);
    /// empties the shadow and finished queues for `shade` to fill.
    pub fn plan_extend(paths: &Paths, dispatch: &Dispatch, invocation: u32) {
        if invocation != 0 {
            return;
        }
        paths.counters.atomic_store(SHADOW, 0);
        paths.counters.atomic_store(FINISHED, 0);
        let active = paths.counters.atomic_load(ACTIVE);
        // The statistics are counted here, once per stage, not by an atomic per ray.
        paths.counters.atomic_add(SEGMENTS, active);
        write_grid(dispatch, ARGS_EXTEND, active);
    }

    /// The closest hit of each active path's ray.
    pub fn extend(scene: &Scene, paths: &Paths, invocation: u32) {
        if invocation >= paths.counters.atomic_load(ACTIVE) {
            return;
        }
        let slot = paths.active.load(paths.counters.atomic_load(PARITY) * paths.pool + invocation);
        let origin = paths.origin.load(slot).xyz();
        let dir = paths.direction.load(slot).xyz();
        let hit = trace_closest(scene, origin, dir, MISS);
        paths.hit.store(slot, Vec4::new(hit.t, hit.u, hit.v, f32::from_bits(hit.instance)));
        let w = paths.words.load(slot);
        paths.words.store(slot, UVec4::new(w.x, w.y, w.z, hit.triangle));
    }

    /// Each active path at its hit (`integrator::shade_hit`): its shadow ray queued for
    /// `connect`, the path queued to go on or to be accumulated.
    pub fn shade(scene: &Scene, paths: &Paths, invocation: u32) {
        if invocation >= paths.counters.atomic_load(ACTIVE) {
            return;
        }
        let parity = paths.counters.atomic_load(PARITY);
        let slot = paths.active.load(parity * paths.pool + invocation);
        let mut path = load_path(paths, slot);
        let h = paths.hit.load(slot);
        let w = paths.words.load(slot);
        let hit = Hit { triangle: w.w, t: h.x, u: h.y, v: h.z, instance: h.w.to_bits() };
        // The denoiser's guide is the megakernel's (`Features::denoise_guide` selects it).
        let mut first = FirstHit { albedo: Vec3::ZERO, normal: Vec3::Z, depth: SKY_DEPTH, emission: Vec3::ZERO };
        let mut shadow = no_shadow_ray();
        let go_on = shade_hit(scene, &mut path, hit, &mut first, &mut shadow);
        // `w.z`: the path's depth before this segment (0 at its first hit).
        if scene.has_denoise_guide != 0 && w.z == 0 {
            add_first_hit(paths, w.x, slot, first);
        }
        store_path(paths, slot, path, w.x);
        if shadow.t_max > 0.0 {
            paths.shadow_origin.store(slot, shadow.origin.extend(shadow.t_max));
            paths.shadow_direction.store(slot, shadow.dir.extend(0.0));
            paths.shadow_contribution.store(slot, shadow.contribution.extend(0.0));
            paths.shadow_queue.store(paths.counters.atomic_add(SHADOW, 1), slot);
        }
        if go_on {
            paths.active.store((parity ^ 1) * paths.pool + paths.counters.atomic_add(NEXT_ACTIVE, 1), slot);
        } else {
            paths.finished.store(paths.counters.atomic_add(FINISHED, 1), slot);
        }
    }

    /// One invocation: the sizes of the shadow-ray and accumulation stages.
    pub fn plan_connect(paths: &Paths, dispatch: &Dispatch, invocation: u32) {
        if invocation != 0 {
            return;
        }
        let shadow = paths.counters.atomic_load(SHADOW);
        paths.counters.atomic_add(SHADOW_RAYS, shadow);
        write_grid(dispatch, ARGS_CONNECT, shadow);
        write_grid(dispatch, ARGS_ACCUMULATE, paths.counters.atomic_load(FINISHED));
    }

    /// Each queued shadow ray: its contribution added to its path unless occluded.
    pub fn connect(scene: &Scene, paths: &Paths, invocation: u32) {
        if invocation >= paths.counters.atomic_load(SHADOW) {
            return;
        }
        let slot = paths.shadow_queue.load(invocation);
        let o = paths.shadow_origin.load(slot);
        if !occluded(scene, o.xyz(), paths.shadow_direction.load(slot).xyz(), o.w) {
            let r = paths.radiance.load(slot);
            paths.radiance.store(slot, (r.xyz() + paths.shadow_contribution.load(slot).xyz()).extend(0.0));
        }
    }

    /// Each path that ended: its sample added to its pixel's sum (as the megakernel's entry
    /// point adds `render_sample`), with the denoiser's guide the sample's luminance moments to
    /// the pixel's guide sums (as it adds `render_guided_sample`'s), its slot freed.
    pub fn accumulate(scene: &Scene, paths: &Paths, invocation: u32) {
        if invocation >= paths.counters.atomic_load(FINISHED) {
            return;
        }
        let slot = paths.finished.load(invocation);
        let pixel = paths.words.load(slot).x;
        let sample = finite_or_zero(paths.radiance.load(slot).xyz());
        paths.image.store(pixel, paths.image.load(pixel) + sample);
        if scene.has_denoise_guide != 0 {
            // `integrator::render_guided_sample`'s moments: the light reflected, without the
            // emission the camera sees directly. Race-free as in `add_first_hit`.
            let l = luminance(sample.xyz() - paths.first_emission.load(slot).xyz());
            let a = paths.guide_albedo.load(pixel);
            paths.guide_albedo.store(pixel, Vec4::new(a.x, a.y, a.z, a.w + l));
            let e = paths.guide_emission.load(pixel);
            paths.guide_emission.store(pixel, Vec4::new(e.x, e.y, e.z, e.w + l * l));
        }
        paths.free.store(paths.counters.atomic_add(FREE, 1), slot);
    }

    /// With the denoiser's guide: the first hit of pixel `pixel`'s path (in slot `slot`) added
    /// to the pixel's guide sums, as the megakernel's entry point adds `render_guided_sample`'s
    /// fields (the luminance moments, in w, once the sample is known: [`accumulate`]); its
    /// emission kept in the slot for `accumulate`.
    ///
    /// Plain adds, no atomics: one path per pixel is in flight. `plan_generate` hands each pixel
    /// of a frame to one path (`NEXT_PIXEL` only grows within the frame) and starts the next
    /// frame only when every slot is free again (`FREE == pool`, after the frame's last
    /// `accumulate`), so no two invocations of a dispatch (`shade` or `accumulate`) touch one
    /// pixel's sums, and a pixel's frames add in order. Each component of a sum gets the
    /// megakernel's addends in its order (rgb here, w in `accumulate`; a component not added
    /// to is stored back as loaded), so splitting the adds between two stages changes no bit.
    pub fn add_first_hit(paths: &Paths, pixel: u32, slot: u32, first: FirstHit) {
        let a = paths.guide_albedo.load(pixel);
        paths.guide_albedo.store(pixel, (a.xyz() + first.albedo).extend(a.w));
        paths.guide_normal.store(pixel, paths.guide_normal.load(pixel) + first.normal.extend(first.depth));
        let e = paths.guide_emission.load(pixel);
        paths.guide_emission.store(pixel, (e.xyz() + first.emission).extend(e.w));
        paths.first_emission.store(slot, first.emission.extend(0.0));
    }

    /// Slot `slot`'s path (as `store_path` left it).
    pub fn load_path(paths: &Paths, slot: u32) -> PathState {
        let o = paths.origin.load(slot);
        let w = paths.words.load(slot);
        PathState {
            origin: o.xyz(),
            dir: paths.direction.load(slot).xyz(),
            throughput: paths.throughput.load(slot).xyz(),
            radiance: paths.radiance.load(slot).xyz(),
            scatter_pdf: o.w,
            depth: w.z,
            rng: w.y,
        }
    }

    /// Stores `path` (of pixel `pixel`) in slot `slot`.
    pub fn store_path(paths: &Paths, slot: u32, path: PathState, pixel: u32) {
        paths.origin.store(slot, path.origin.extend(path.scatter_pdf));
        paths.direction.store(slot, path.dir.extend(0.0));
        paths.throughput.store(slot, path.throughput.extend(0.0));
        paths.radiance.store(slot, path.radiance.extend(0.0));
        let w = paths.words.load(slot);
        paths.words.store(slot, UVec4::new(pixel, path.rng, path.depth, w.w));
    }
}
