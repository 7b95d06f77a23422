//! Image-level agreement of a GPU runtime with the CPU runtime, through the `Renderer` trait:
//! the same scenes, the same per-frame region statistics, the same bound; and
//! [`agreement_suite!`], the tests every GPU runtime runs.

use std::time::Instant;

use glam::{DVec3, Vec3, Vec4, Vec4Swizzles};
use tracer::backend::cpu::CpuRenderer;
use tracer::backend::{create_scheduled, Renderer, RendererKind, Schedule};
use tracer::denoise::{filter_input, Guide};
use tracer::kernel::denoise::FilterImage;
use tracer::kernel::{RenderSettings, Strategy};
use tracer::pack::{pack, Packed};
use tracer::scene::{self, Scene, Sky};
use tracer::stats::Estimate;

pub const STRATEGIES: [Strategy; 3] = [Strategy::Bsdf, Strategy::Nee, Strategy::Mis];

/// |CPU - GPU| within 5 combined standard errors, per region and channel (a false alarm at
/// 5 sigma is ~1 in 10^6 per comparison; the runs use fixed seeds).
pub const Z_BOUND: f64 = 5.0;

/// Regions per side: the image's 4 x 4 blocks, plus the whole image.
pub const BLOCKS: u32 = 4;

pub fn packed(scene: &Scene, strategy: Strategy, size: u32, max_depth: u32) -> Packed {
    let bvh = tracer::bvh::build(&scene.triangles).expect("BVH");
    let settings = RenderSettings { width: size, height: size, strategy, max_depth };
    pack(scene, &bvh, &settings).expect("pack")
}

/// The demodulated image `denoise` hands to the filter passes for `scene` at `spp`.
pub fn noisy_filter_input(scene: &Scene, width: u32, height: u32, spp: u32) -> FilterImage {
    let mut p = packed(scene, Strategy::Mis, width.max(height), 6);
    p.scene.width = width;
    p.scene.height = height;
    p.set_denoise_guide(true);
    let mut r = CpuRenderer::new(p, 3);
    for _ in 0..spp {
        r.render_frame().expect("frame");
    }
    let guide = Guide::read(&r).expect("the guide");
    filter_input(&r.image().expect("image"), &guide).expect("filter input")
}

/// The largest difference between two filtered images (colour and variance), relative to the
/// larger value (absolute below 1).
pub fn largest_difference(a: &[Vec4], b: &[Vec4]) -> f32 {
    a.iter()
        .zip(b)
        .map(|(x, y)| ((*x - *y).abs() / x.abs().max(y.abs()).max(Vec4::ONE)).max_element())
        .fold(0.0, f32::max)
}

/// BoxTextured under a uniform white sky.
pub fn textured_box() -> Scene {
    let mut scene =
        scene::load(&super::test_data("scenes/khronos/BoxTextured/glTF/BoxTextured.gltf")).expect("BoxTextured");
    scene.sky = Some(Sky::uniform(Vec3::ONE));
    scene
}

/// A diffuse plane under the venice_sunset HDR sky.
pub fn sky_lit_plane() -> Scene {
    let mut scene = scene::diffuse_plane(Vec3::splat(0.6));
    scene.sky = Some(scene::load_sky(&super::test_data("scenes/hdri/venice_sunset_1k.hdr"), 1.0, 0.0).expect("sky"));
    scene
}

/// DamagedHelmet under a uniform white sky.
pub fn damaged_helmet() -> Scene {
    let path = super::test_data("scenes/khronos/DamagedHelmet/glTF-Binary/DamagedHelmet.glb");
    let mut scene = scene::load(&path).expect("DamagedHelmet");
    scene.sky = Some(Sky::uniform(Vec3::ONE));
    scene
}

/// Per-frame estimates of a render: for each frame, the mean of this frame's samples over each
/// 4 x 4 block and, last, the whole image.
pub struct Run {
    pub per_frame: Vec<Vec<DVec3>>,
    pub rejected: u64,
    pub seconds: f64,
}

/// A runtime and the schedule it runs the path tracer with: what the agreement suite tests
/// (a bare [`RendererKind`] is its megakernel).
#[derive(Clone, Copy, Debug)]
pub struct Runtime {
    pub kind: RendererKind,
    pub schedule: Schedule,
}

impl From<RendererKind> for Runtime {
    fn from(kind: RendererKind) -> Runtime {
        Runtime { kind, schedule: Schedule::Megakernel }
    }
}

impl Runtime {
    /// "wgpu", or "wgpu wavefront".
    pub fn name(&self) -> String {
        match self.schedule {
            Schedule::Megakernel => self.kind.name().to_string(),
            other => format!("{} {}", self.kind.name(), other.name()),
        }
    }
}

/// A renderer of `runtime` (the GPU ones on their own headless context or device); a runtime
/// that cannot start fails the test with the reason.
pub fn renderer(runtime: impl Into<Runtime>, packed: Packed, seed: u32) -> Box<dyn Renderer> {
    let r = runtime.into();
    create_scheduled(r.kind, r.schedule, packed, seed)
        .unwrap_or_else(|e| panic!("the {} backend must run here: {e}", r.name()))
}

/// The running sums of an accumulation (rgb: sum of samples, w: finite samples).
pub fn accumulated_sums(accumulation: &[Vec4]) -> Vec<DVec3> {
    accumulation.iter().map(|a| a.xyz().as_dvec3()).collect()
}

/// Renders `frames` frames, recording each frame's region means.
pub fn run(renderer: &mut dyn Renderer, size: u32, frames: u32) -> Run {
    let mut previous = vec![DVec3::ZERO; (size * size) as usize];
    let mut per_frame = Vec::new();
    let t = Instant::now();
    for _ in 0..frames {
        renderer.render_frame().expect("frame");
        let sums = accumulated_sums(&renderer.accumulation().expect("readback"));
        per_frame.push(super::region_means(size, BLOCKS, |i| sums[i] - previous[i]));
        previous = sums;
    }
    let rejected = renderer.rejected_samples().expect("readback");
    Run { per_frame, rejected, seconds: t.elapsed().as_secs_f64() }
}

fn estimate(run: &Run, region: usize, channel: usize) -> Estimate {
    let samples: Vec<f64> = run.per_frame.iter().map(|f| f[region][channel]).collect();
    Estimate::from_samples(&samples)
}

/// Renders `scene` on the CPU and on `kind` with each strategy (independent seeds) and asserts
/// that every region mean agrees within the bound and no sample was rejected. Returns the
/// largest z-score.
pub fn assert_agrees_with_cpu(
    kind: impl Into<Runtime>,
    what: &str,
    scene: &Scene,
    size: u32,
    frames: u32,
    max_depth: u32,
) -> f64 {
    let kind = kind.into();
    let name = kind.name();
    let name = name.as_str();
    let mut worst = 0.0f64;
    for strategy in STRATEGIES {
        let p = packed(scene, strategy, size, max_depth);
        let cpu = run(&mut CpuRenderer::new(p.clone(), 1), size, frames);
        let gpu = run(renderer(kind, p, 2).as_mut(), size, frames);
        let worst_here = assert_runs_agree(&format!("{what} {strategy:?}"), ["CPU", name], &cpu, &gpu);
        let whole = estimate(&gpu, (BLOCKS * BLOCKS) as usize, 1);
        eprintln!(
            "{what} {strategy:?} {size}x{size} x {frames} frames: max z {worst_here:.2}; whole-image green {:.4} ± {:.4}; CPU {:.2} s, {name} {:.2} s",
            whole.mean, whole.std_err, cpu.seconds, gpu.seconds
        );
        worst = worst.max(worst_here);
    }
    worst
}

/// Asserts that two runs (`names`) rendered the same image: every region mean agrees within
/// the bound and neither rejected a sample. Returns the largest z-score.
pub fn assert_runs_agree(what: &str, names: [&str; 2], a_run: &Run, b_run: &Run) -> f64 {
    for (name, r) in names.iter().zip([a_run, b_run]) {
        assert_eq!(r.rejected, 0, "{what}: no NaN/Inf may reach the {name} accumulation");
    }
    let mut worst = 0.0f64;
    for region in 0..(BLOCKS * BLOCKS) as usize + 1 {
        for c in 0..3 {
            let (a, b) = (estimate(a_run, region, c), estimate(b_run, region, c));
            let z = a.z_score(&b);
            assert!(
                z < Z_BOUND,
                "{what} region {region} channel {c}: {} {} ± {} vs {} {} ± {} (z = {z:.2})",
                names[0],
                a.mean,
                a.std_err,
                names[1],
                b.mean,
                b.std_err
            );
            worst = worst.max(z);
        }
    }
    worst
}

/// The share of pixels whose values agree within 1e-5 (relative).
pub fn share_equal(a: &[Vec3], b: &[Vec3]) -> f64 {
    let close = a.iter().zip(b).filter(|(x, y)| (**x - **y).abs().max_element() <= 1e-5 * x.max_element().max(1e-3));
    close.count() as f64 / a.len() as f64
}

/// With the same seed, the CPU and `kind` draw the same random numbers: one frame's samples
/// agree pixel by pixel; with different seeds they would not (the control: the scene's samples
/// depend on every random number drawn, through a varied HDR sky).
///
/// Not every pixel: a direction sampled close to a sky texel's edge can land in the
/// neighbouring texel when `atan2`/`acos` differ by an ulp between the driver and Rust's libm
/// (on llvmpipe, 0.5% of the pixels with BSDF sampling, ~2% with NEE). The other pixels agree
/// within 1e-5 (relative; most exactly).
pub fn assert_same_random_sequence(kind: impl Into<Runtime>) {
    let kind = kind.into();
    let (size, seed, name) = (32u32, 12345, kind.name());
    let first_frame = |r: &mut dyn Renderer| {
        r.render_frame().expect("frame");
        r.image().expect("readback").pixels
    };
    for strategy in STRATEGIES {
        let p = packed(&sky_lit_plane(), strategy, size, 3);
        let cpu = first_frame(&mut CpuRenderer::new(p.clone(), seed));
        let other = first_frame(&mut CpuRenderer::new(p.clone(), seed + 1));
        let gpu = first_frame(renderer(kind, p, seed).as_mut());
        let agree = share_equal(&cpu, &gpu);
        let control = share_equal(&cpu, &other);
        eprintln!(
            "{strategy:?}: same seed, CPU vs {name}: {:.2}% of pixels agree; CPU seed vs seed + 1: {:.2}%",
            100.0 * agree,
            100.0 * control
        );
        assert!(control < 0.5, "{strategy:?}: the scene does not expose the random numbers ({control})");
        assert!(agree > 0.95, "{strategy:?}: only {:.2}% of the pixels match the CPU's", 100.0 * agree);
    }
}

/// The image-level suite every GPU runtime passes, written once and instantiated in the
/// runtime's test module (`tests/rendering/gl.rs`, `wgpu.rs`), as CubeCL's `testgen_all!`:
/// `agreement_suite!(RendererKind::Gl, frames / 1);` (a [`Runtime`] for another schedule; `whole frames` for one that does not split frames into bands). Each scene is rendered on the CPU and
/// on the runtime with every strategy and compared region by region
/// ([`assert_agrees_with_cpu`]); the frame counts are GL's, divided by the second argument
/// for slower runtimes (lavapipe). Then the random sequence, bands and restarts.
#[macro_export]
macro_rules! agreement_suite {
    ($kind:expr, frames / $fewer:expr) => {
        $crate::agreement_suite!($kind, frames / $fewer, whole frames);

        /// A frame rendered in bands of rows is the frame rendered whole (`common::bands`).
        /// Heights that are not multiples of a GPU's 8-row workgroup, so that a band's last
        /// workgroup reaches into rows that belong to the next band.
        #[test]
        fn a_frame_split_into_bands_is_the_unsplit_frame() {
            let base = suite::packed(&tracer::scene::cornell_box(), tracer::kernel::Strategy::Mis, 20, 4);
            assert_eq!((base.scene.width, base.scene.height), (20, 20));
            $crate::common::bands::assert_bands_make_the_whole_frame(
                suite::renderer($kind, base.clone(), 3).as_mut(),
                suite::renderer($kind, base, 3).as_mut(),
                20,
            );
        }
    };
    // A schedule whose frames are not split into rows (the wavefront bounds its work per
    // submission instead): every test but the bands'.
    ($kind:expr, frames / $fewer:expr, whole frames) => {
        use $crate::common::agreement as suite;

        #[test]
        fn agrees_with_cpu_on_the_cornell_box() {
            let scene = tracer::scene::cornell_box();
            suite::assert_agrees_with_cpu($kind, "Cornell box", &scene, 32, 256 / $fewer, 6);
        }

        #[test]
        fn agrees_with_cpu_on_a_textured_scene() {
            suite::assert_agrees_with_cpu($kind, "BoxTextured", &suite::textured_box(), 32, 128 / $fewer, 6);
        }

        #[test]
        fn agrees_with_cpu_under_an_hdr_sky() {
            let scene = suite::sky_lit_plane();
            suite::assert_agrees_with_cpu($kind, "plane under venice_sunset", &scene, 32, 128 / $fewer, 4);
        }

        /// The metal-roughness kernel (`Features::metal_rough`): 25 spheres from smooth metal to
        /// rough dielectric under an area light and a sky.
        #[test]
        fn agrees_with_cpu_on_metal_rough_spheres() {
            let scene = tracer::scene::metal_rough_spheres();
            assert!(suite::packed(&scene, tracer::kernel::Strategy::Mis, 4, 2).features.metal_rough);
            suite::assert_agrees_with_cpu($kind, "MetalRoughSpheres", &scene, 32, 128 / $fewer, 4);
        }

        /// Glass (`Features::transmission` and `volume`): the glass Cornell box's smooth sphere
        /// (a delta lobe, its caustic) and rough absorbing block (light sampled through a rough
        /// lobe, Beer–Lambert inside).
        #[test]
        fn agrees_with_cpu_on_glass() {
            let scene = tracer::scene::glass_cornell();
            let f = suite::packed(&scene, tracer::kernel::Strategy::Mis, 4, 2).features;
            assert!(f.transmission && f.volume, "{f:?}");
            suite::assert_agrees_with_cpu($kind, "glass Cornell box", &scene, 32, 256 / $fewer, 6);
        }

        /// Normal maps (`Features::normal_map`): DamagedHelmet (MikkTSpace tangents,
        /// metal-roughness) under a uniform sky.
        #[test]
        fn agrees_with_cpu_on_normal_maps() {
            let scene = suite::damaged_helmet();
            assert!(suite::packed(&scene, tracer::kernel::Strategy::Mis, 4, 2).features.normal_map);
            suite::assert_agrees_with_cpu($kind, "DamagedHelmet", &scene, 32, 64 / $fewer, 4);
        }

        /// Two levels (`Features::instances`): one mesh placed 4 x 4 times, rotated, scaled
        /// non-uniformly and mirrored, over static triangles.
        #[test]
        fn agrees_with_cpu_on_instanced_shapes() {
            let scene = tracer::scene::instanced_shapes(4);
            assert!(suite::packed(&scene, tracer::kernel::Strategy::Mis, 4, 2).features.instances);
            suite::assert_agrees_with_cpu($kind, "instanced shapes", &scene, 32, 128 / $fewer, 4);
        }

        #[test]
        fn the_random_sequence_matches_the_cpu() {
            suite::assert_same_random_sequence($kind);
        }

        /// Restarting drops every sample; moving the camera through `set_uniforms` changes the
        /// image; the image size cannot change.
        #[test]
        fn restart_and_uniform_updates_take_effect() {
            let p = suite::packed(&tracer::scene::cornell_box(), tracer::kernel::Strategy::Mis, 16, 3);
            let mut r = suite::renderer($kind, p, 0);
            r.render_frame().unwrap();
            r.render_frame().unwrap();
            let before = r.image().unwrap();
            r.restart().unwrap();
            assert_eq!(r.frames(), 0);
            assert!(r.accumulation().unwrap().iter().all(|a| *a == glam::Vec4::ZERO), "restart clears the sums");
            r.set_uniforms(&mut |s| s.camera_position += s.camera_forward * 10.0).unwrap();
            r.render_frame().unwrap();
            let moved = r.image().unwrap();
            assert_ne!(before.mean(), moved.mean(), "the camera moved behind the back wall");
            let err = r.set_uniforms(&mut |s| s.width = 17).expect_err("the size is fixed");
            assert!(matches!(err, tracer::backend::RenderError::SizeChanged { .. }), "{err}");
        }
    };
}
