//! The wavefront schedule (`kernel::wavefront`, `backend::wavefront`) on the CPU: each path
//! computes what the megakernel's computes, so the two add the same samples and the same
//! denoiser's guide bit for bit; the queues lose and duplicate nothing; bad sizes are errors.

use glam::{Vec2, Vec3, Vec4};
use tracer::backend::cpu::{CpuRenderer, WavefrontRenderer};
use tracer::backend::wavefront::{pool_size, WavefrontError};
use tracer::backend::Renderer;
use tracer::denoise::Guide;
use tracer::kernel::wavefront::{FREE, WORKGROUP};
use tracer::kernel::{Features, Strategy};
use tracer::scene::{self, alpha_checker, Camera, Material, Scene, Triangle};

use crate::common::agreement::{damaged_helmet, packed, textured_box, STRATEGIES};

/// The Cornell box with a 4 x 4 alpha-checkered screen in front of its back wall.
fn masked_cornell() -> Scene {
    let mut scene = scene::cornell_box();
    let material = scene.materials.len() as u32;
    let mut screen = Material::diffuse("screen", Vec3::splat(0.7));
    screen.base_color_texture = Some(scene.textures.len() as u32);
    screen.alpha_cutoff = Some(0.5);
    scene.materials.push(screen);
    scene.textures.push(alpha_checker(4));
    let q = [Vec3::new(-0.5, 0.2, 0.0), Vec3::new(0.5, 0.2, 0.0), Vec3::new(0.5, 1.2, 0.0), Vec3::new(-0.5, 1.2, 0.0)];
    let uv = [Vec2::new(0.0, 1.0), Vec2::new(1.0, 1.0), Vec2::new(1.0, 0.0), Vec2::ZERO];
    for [a, b, c] in [[0, 1, 2], [0, 2, 3]] {
        scene.triangles.push(Triangle {
            positions: [q[a], q[b], q[c]],
            normals: [Vec3::Z; 3],
            uvs: [uv[a], uv[b], uv[c]],
            uvs1: Default::default(),
            tangents: Default::default(),
            material,
        });
    }
    scene
}

/// `frames` frames of `scene` on the megakernel and on the wavefront (a pool of `pool` slots),
/// their running sums.
fn both(scene: &Scene, strategy: Strategy, size: u32, frames: u32, pool: u32) -> (Vec<Vec4>, Vec<Vec4>) {
    let p = packed(scene, strategy, size, 8);
    let mut mega = CpuRenderer::new(p.clone(), 5);
    let mut wave = WavefrontRenderer::new(p, 5, pool).expect("a wavefront renderer");
    for _ in 0..frames {
        mega.render_frame().unwrap();
        wave.render_frame().unwrap();
    }
    assert_eq!(wave.frames(), frames);
    (mega.accumulation().unwrap(), wave.accumulation().unwrap())
}

#[test]
fn the_cpu_wavefront_adds_the_megakernels_samples_bit_for_bit() {
    // A pool smaller than the image: several waves per frame, frames drained and restarted.
    let (size, frames, pool) = (20, 3, 90);
    let mut scenes: Vec<(String, Scene, Strategy)> =
        STRATEGIES.iter().map(|s| (format!("Cornell box {s:?}"), scene::cornell_box(), *s)).collect();
    scenes.push(("glass Cornell box".into(), scene::glass_cornell(), Strategy::Mis));
    scenes.push(("metal-rough spheres".into(), scene::metal_rough_spheres(), Strategy::Mis));
    scenes.push(("BoxTextured under a sky".into(), textured_box(), Strategy::Mis));
    scenes.push(("DamagedHelmet under a sky".into(), damaged_helmet(), Strategy::Mis));
    scenes.push(("instanced shapes".into(), scene::instanced_shapes(2), Strategy::Mis));
    scenes.push(("alpha-masked screen".into(), masked_cornell(), Strategy::Nee));
    for (what, scene, strategy) in scenes {
        let (mega, wave) = both(&scene, strategy, size, frames, pool);
        let lit = mega.iter().filter(|a| a.x + a.y + a.z > 0.0).count();
        assert!(lit * 40 > mega.len(), "{what}: the test image must show something ({lit} lit pixels)");
        let differ = mega
            .iter()
            .zip(&wave)
            .filter(|(m, w)| m.to_array().map(f32::to_bits) != w.to_array().map(f32::to_bits))
            .count();
        assert_eq!(differ, 0, "{what}: pixels whose sums differ between the megakernel and the wavefront");
    }
}

#[test]
fn every_pixel_receives_exactly_the_samples_it_was_owed_and_no_slot_is_lost() {
    // A pool that divides nothing: 37 slots over 23 x 19 pixels.
    let mut p = packed(&scene::cornell_box(), Strategy::Mis, 23, 8);
    p.scene.height = 19;
    let mut wave = WavefrontRenderer::new(p, 9, 37).unwrap();
    for frame in 1..=4u32 {
        wave.render_frame().unwrap();
        let sums = wave.accumulation().unwrap();
        assert!(sums.iter().all(|a| a.w == frame as f32), "frame {frame}: every pixel has {frame} samples");
        let counts = wave.counts();
        assert_eq!(counts.frames, frame);
        // Every path of a frame traces its camera ray; bounces add more.
        assert!(counts.segments >= frame * 23 * 19, "{counts:?}");
        let paths = wave.paths();
        assert_eq!(paths.counters.atomic_load(FREE), 37, "every slot is free between frames");
        let mut free: Vec<u32> = (0..37).map(|i| paths.free.load(i)).collect();
        free.sort_unstable();
        assert_eq!(free, (0..37).collect::<Vec<u32>>(), "each slot once on the free stack");
    }
}

#[test]
fn pools_follow_the_device_limit_and_an_image_beyond_it_is_an_error() {
    // The image's sums and eight Vec4 arrays per slot share the largest binding.
    let plain = Features::default();
    assert_eq!(pool_size(640 * 480, 128 << 20, &plain).unwrap(), 640 * 480);
    let small = pool_size(1920 * 1080, 128 << 20, &plain).unwrap();
    assert!(small < 1920 * 1080 && small.is_multiple_of(WORKGROUP), "{small}");
    assert!(small as u64 * 8 * 16 + 1920 * 1080 * 16 <= 128 << 20);
    // With the denoiser's guide: three more sums per pixel and one more Vec4 per slot.
    let guided = Features { denoise_guide: true, ..Default::default() };
    let fewer = pool_size(1920 * 1080, 128 << 20, &guided).unwrap();
    assert!(fewer < small && fewer.is_multiple_of(WORKGROUP), "{fewer}");
    assert!(fewer as u64 * 9 * 16 + 1920 * 1080 * 4 * 16 <= 128 << 20);
    assert!((fewer as u64 + WORKGROUP as u64) * 9 * 16 + 1920 * 1080 * 4 * 16 > 128 << 20, "{fewer}");
    match pool_size(1 << 24, 1 << 20, &plain) {
        Err(e @ WavefrontError::ImageTooLarge { .. }) => {
            assert!(e.to_string().contains("largest storage buffer binding"), "{e}")
        }
        other => panic!("an image beyond the limit: {other:?}"),
    }
}

/// The denoiser's guide (`Features::denoise_guide`): the CPU wavefront adds the megakernel's
/// guide sums bit for bit (first hits written by `shade`, luminance moments by `accumulate`),
/// through several waves per frame, on scenes whose first hits see lights, the sky, glossy
/// metal-roughness surfaces (their directional albedo), glass and alpha-masked holes; a restart
/// empties them, and the frames after it add them again.
#[test]
fn the_cpu_wavefront_adds_the_megakernels_denoiser_guide_bit_for_bit() {
    let (size, frames, pool) = (20, 3, 90);
    let scenes: Vec<(&str, Scene, Strategy)> = vec![
        ("Cornell box", scene::cornell_box(), Strategy::Mis),
        ("BoxTextured under a sky", textured_box(), Strategy::Mis),
        ("metal-rough spheres", scene::metal_rough_spheres(), Strategy::Mis),
        ("glass Cornell box", scene::glass_cornell(), Strategy::Nee),
        ("alpha-masked screen", masked_cornell(), Strategy::Bsdf),
    ];
    let bits = |sums: &[Vec<Vec4>; 3]| -> Vec<u32> {
        sums.iter().flat_map(|s| s.iter().flat_map(|v| v.to_array().map(f32::to_bits))).collect()
    };
    for (what, scene, strategy) in scenes {
        let mut p = packed(&scene, strategy, size, 8);
        p.set_denoise_guide(true);
        let mut mega = CpuRenderer::new(p.clone(), 5);
        let mut wave = WavefrontRenderer::new(p, 5, pool).expect("a wavefront renderer");
        for round in 0..2 {
            for _ in 0..frames {
                mega.render_frame().unwrap();
                wave.render_frame().unwrap();
            }
            let (m, w) = (mega.guide_sums().unwrap(), wave.guide_sums().unwrap());
            // The guide shows the scene: first hits on surfaces, and luminance moments.
            assert!(m[0].iter().any(|a| a.x > 0.0) && m[1].iter().any(|n| n.w > 0.0), "{what}: no first hits");
            assert!(m[2].iter().any(|e| e.w > 0.0), "{what}: no luminance moments");
            let (mb, wb) = (bits(&m), bits(&w));
            assert_eq!(mb.len(), wb.len(), "{what}: the guide's size");
            let differ = mb.iter().zip(&wb).filter(|(a, b)| a != b).count();
            assert_eq!(differ, 0, "{what}, round {round}: guide words that differ from the megakernel's");
            assert_eq!(bits_of(&mega.accumulation().unwrap()), bits_of(&wave.accumulation().unwrap()), "{what}");
            mega.restart().unwrap();
            wave.restart().unwrap();
            let zero = wave.guide_sums().unwrap();
            assert!(zero.iter().all(|s| s.iter().all(|v| *v == Vec4::ZERO)), "{what}: a restart empties the guide");
        }
    }
    // Without the guide there is none to read.
    let wave = WavefrontRenderer::new(packed(&scene::cornell_box(), Strategy::Mis, 8, 4), 1, 64).unwrap();
    assert!(matches!(wave.guide_sums(), Err(tracer::backend::RenderError::NoGuide)));
}

fn bits_of(sums: &[Vec4]) -> Vec<u32> {
    sums.iter().flat_map(|v| v.to_array().map(f32::to_bits)).collect()
}

#[test]
fn a_camera_inside_a_closed_box_still_completes_every_frame() {
    // Paths that never escape end by depth and roulette: the frame completes within the bound.
    let mut scene = scene::cornell_box();
    scene.camera = Camera::look_at(Vec3::new(0.0, 1.0, 0.0), Vec3::new(0.0, 1.0, -1.0), Vec3::Y, 1.0);
    let p = packed(&scene, Strategy::Bsdf, 12, 32);
    let mut wave = WavefrontRenderer::new(p, 2, 64).unwrap();
    wave.render_frame().unwrap();
    assert_eq!(wave.frames(), 1);
}

/// On wgpu, a pool far smaller than the image (a storage binding limit that leaves room for
/// 192 slots beside a 48 x 48 image's sums): twelve waves per frame, and still every pixel gets
/// exactly its samples, however the device's atomics interleave the queues.
#[test]
fn the_wgpu_wavefront_gives_every_pixel_its_samples_through_a_small_pool() {
    use tracer::backend::wgpu::{WavefrontRenderer as WgpuWavefront, WgpuDevice, WgpuOptions};
    let p = packed(&scene::cornell_box(), Strategy::Mis, 48, 8);
    let limit = 48 * 48 * 16 + 192 * 8 * 16;
    let options = WgpuOptions { max_storage_buffer_binding_size: Some(limit), ..Default::default() };
    let device = WgpuDevice::native().unwrap_or_else(|e| panic!("the wgpu backend must run here: {e}"));
    let mut wave = pollster::block_on(WgpuWavefront::new(device, p, 4, &options)).expect("a wgpu wavefront");
    assert_eq!(wave.pool(), 192, "the pool follows the binding limit");
    for frame in 1..=3u32 {
        wave.render_frame().unwrap();
        let sums = wave.accumulation().unwrap();
        let wrong = sums.iter().filter(|a| a.w != frame as f32).count();
        assert_eq!(wrong, 0, "frame {frame}: pixels without exactly {frame} samples");
        let counts = wave.wavefront_counts().expect("a wavefront");
        assert_eq!(counts.frames, frame);
        assert!(counts.segments >= frame * 48 * 48, "{counts:?}");
    }
    assert!(sums_lit(&wave.accumulation().unwrap()) > 48 * 48 / 2, "the box is lit");
}

/// The wgpu wavefront's stages bind the scene's scalars as a storage buffer (not a uniform:
/// lavapipe re-specialised every stage at every pipeline bind, `docs/backends.md`), so they
/// bind 8 storage buffers, WebGPU's guaranteed number: a device allowing 8 gets the wavefront,
/// one allowing 7 refuses it with the limit named, before anything is compiled.
#[test]
fn the_wgpu_wavefronts_stages_fit_webgpus_eight_storage_buffers_with_the_scene_scalars_counted() {
    use tracer::backend::wgpu::{WavefrontRenderer as WgpuWavefront, WgpuDevice, WgpuOptions};
    let p = packed(&scene::cornell_box(), Strategy::Mis, 16, 4);
    let device = WgpuDevice::native().unwrap_or_else(|e| panic!("the wgpu backend must run here: {e}"));
    let eight = WgpuOptions { max_storage_buffers_per_shader_stage: Some(8), ..Default::default() };
    let mut wave = pollster::block_on(WgpuWavefront::new(device.clone(), p.clone(), 4, &eight)).expect("8 fit");
    wave.render_frame().unwrap();
    assert_eq!(wave.accumulation().unwrap().iter().filter(|a| a.w != 1.0).count(), 0, "one sample each");
    let seven = WgpuOptions { max_storage_buffers_per_shader_stage: Some(7), ..Default::default() };
    let refused = pollster::block_on(WgpuWavefront::new(device, p, 4, &seven)).err().expect("7 are too few");
    let message = refused.to_string();
    assert!(message.contains("max_storage_buffers_per_shader_stage") && message.contains('8'), "{message}");
}

/// On wgpu the wavefront accumulates the CPU megakernel's denoiser guide (through a pool of
/// 192 slots under a 48 x 48 image: twelve waves per frame, with the guide's arrays in the
/// binding limit): the same seed gives the same paths, so the first hits' albedo, normal,
/// depth and emission and the luminance variance agree pixel by pixel up to the GPU's rounding
/// (a ray grazing an edge may take the other triangle: at most 2 % of the pixels differ, as
/// `denoise.rs` allows the megakernels); a restart empties the guide.
#[test]
fn the_wgpu_wavefront_accumulates_the_cpus_denoiser_guide() {
    use tracer::backend::wgpu::{WavefrontRenderer as WgpuWavefront, WgpuDevice, WgpuOptions};
    let size = 48;
    let mut p = packed(&scene::cornell_box(), Strategy::Mis, size, 4);
    p.set_denoise_guide(true);
    let limit = 48 * 48 * 4 * 16 + 192 * 9 * 16;
    let options = WgpuOptions { max_storage_buffer_binding_size: Some(limit), ..Default::default() };
    let device = WgpuDevice::native().unwrap_or_else(|e| panic!("the wgpu backend must run here: {e}"));
    let mut wave = pollster::block_on(WgpuWavefront::new(device, p.clone(), 5, &options)).expect("a wgpu wavefront");
    assert_eq!(wave.pool(), 192, "the pool follows the binding limit, the guide's arrays counted");
    let mut cpu = CpuRenderer::new(p, 5);
    for _ in 0..8 {
        cpu.render_frame().unwrap();
        wave.render_frame().unwrap();
    }
    let (cpu, gpu) = (Guide::read(&cpu).unwrap(), Guide::read(&wave).unwrap());
    assert!(cpu.aovs.iter().any(|a| a.emission.max_element() > 1.0), "no pixel sees the light");
    let mismatched = crate::denoise::guide_pixels_differing(&cpu, &gpu);
    eprintln!("wgpu wavefront: {mismatched} of {} guide pixels differ from the CPU's", cpu.aovs.len());
    assert!(mismatched * 50 <= cpu.aovs.len(), "{mismatched} of {} guide pixels differ", cpu.aovs.len());
    wave.restart().unwrap();
    let zero = wave.guide_sums().unwrap();
    assert!(zero.iter().all(|s| s.iter().all(|v| *v == Vec4::ZERO)), "a restart empties the guide");
}

fn sums_lit(sums: &[Vec4]) -> usize {
    sums.iter().filter(|a| a.x + a.y + a.z > 0.0).count()
}

/// The wavefront on wgpu (lavapipe in CI) against the CPU's megakernel: the agreement suite's
/// scenes and strategies, the random sequence, restarts and uniform updates.
mod wgpu_wavefront {
    use tracer::backend::{RendererKind, Schedule};

    use crate::common::agreement::Runtime;

    const WAVEFRONT: Runtime = Runtime { kind: RendererKind::Wgpu, schedule: Schedule::Wavefront };

    crate::agreement_suite!(WAVEFRONT, frames / 2, whole frames);
}
