//! The GL backend (headless EGL; Mesa llvmpipe in CI) against the CPU backend: the same
//! kernel over the same packed data must estimate the same image. Never skipped: a machine
//! without a usable GL fails these tests with the reason.

mod common;

use std::time::Instant;

use common::agreement::{packed, BLOCKS};
use common::test_data;
use glam::{DVec3, Vec3, Vec4Swizzles};
use tracer::backend::cpu::CpuRenderer;
use tracer::backend::gl::{GlError, GlOptions, GlRenderer, HeadlessContext};
use tracer::backend::Renderer;
use tracer::pack::{Packed, RenderSettings, Strategy};
use tracer::scene::{self, Scene, Sky};
use tracer::stats::Estimate;

const STRATEGIES: [Strategy; 3] = [Strategy::Bsdf, Strategy::Nee, Strategy::Mis];

/// |CPU - GL| within 5 combined standard errors, per region and channel (a false alarm at
/// 5 sigma is ~1 in 10^6 per comparison; the runs use fixed seeds).
const Z_BOUND: f64 = 5.0;

fn gl_renderer(packed: Packed, seed: u32) -> GlRenderer {
    GlRenderer::headless(packed, seed).unwrap_or_else(|e| panic!("the GL backend must run here: {e}"))
}

/// Per-frame estimates of a render: for each frame, the mean of this frame's samples over each
/// 4 x 4 block and, last, the whole image.
struct Run {
    per_frame: Vec<Vec<DVec3>>,
    rejected: u64,
    seconds: f64,
}

fn run_cpu(packed: Packed, seed: u32, frames: u32) -> Run {
    let size = packed.scene.width;
    let mut r = CpuRenderer::new(packed, seed);
    let mut previous = vec![DVec3::ZERO; (size * size) as usize];
    let mut per_frame = Vec::new();
    let t = Instant::now();
    for _ in 0..frames {
        r.render_frame().expect("frame");
        let n = r.frames() as f64;
        let sums: Vec<DVec3> = r.image().expect("image").pixels.iter().map(|p| p.as_dvec3() * n).collect();
        per_frame.push(common::region_means(size, BLOCKS, |i| sums[i] - previous[i]));
        previous = sums;
    }
    Run { per_frame, rejected: r.rejected_samples().expect("accumulation"), seconds: t.elapsed().as_secs_f64() }
}

fn run_gl(packed: Packed, seed: u32, frames: u32) -> Run {
    let size = packed.scene.width;
    let mut r = gl_renderer(packed, seed);
    let mut previous = vec![DVec3::ZERO; (size * size) as usize];
    let mut per_frame = Vec::new();
    let t = Instant::now();
    for _ in 0..frames {
        r.render_frame().expect("GL frame");
        let sums: Vec<DVec3> = r.accumulation().expect("readback").iter().map(|a| a.xyz().as_dvec3()).collect();
        per_frame.push(common::region_means(size, BLOCKS, |i| sums[i] - previous[i]));
        previous = sums;
    }
    let rejected = r.rejected_samples().expect("readback");
    Run { per_frame, rejected, seconds: t.elapsed().as_secs_f64() }
}

fn estimate(run: &Run, region: usize, channel: usize) -> Estimate {
    let samples: Vec<f64> = run.per_frame.iter().map(|f| f[region][channel]).collect();
    Estimate::from_samples(&samples)
}

/// Renders `scene` on both backends with each strategy (independent seeds) and asserts that
/// every region mean agrees within the bound and no sample was rejected. Returns the
/// largest z-score.
fn assert_gl_agrees_with_cpu(what: &str, scene: &Scene, size: u32, frames: u32, max_depth: u32) -> f64 {
    let mut worst = 0.0f64;
    for strategy in STRATEGIES {
        let p = packed(scene, strategy, size, max_depth);
        let cpu = run_cpu(p.clone(), 1, frames);
        let gl = run_gl(p, 2, frames);
        assert_eq!(cpu.rejected, 0, "{what} {strategy:?}: the CPU dropped non-finite samples");
        assert_eq!(gl.rejected, 0, "{what} {strategy:?}: no NaN/Inf may reach the GL accumulation");
        let mut worst_here = 0.0f64;
        for region in 0..(BLOCKS * BLOCKS) as usize + 1 {
            for c in 0..3 {
                let (a, b) = (estimate(&cpu, region, c), estimate(&gl, region, c));
                let z = a.z_score(&b);
                assert!(
                    z < Z_BOUND,
                    "{what} {strategy:?} region {region} channel {c}: CPU {} ± {} vs GL {} ± {} (z = {z:.2})",
                    a.mean,
                    a.std_err,
                    b.mean,
                    b.std_err
                );
                worst_here = worst_here.max(z);
            }
        }
        let whole = estimate(&gl, (BLOCKS * BLOCKS) as usize, 1);
        eprintln!(
            "{what} {strategy:?} {size}x{size} x {frames} frames: max z {worst_here:.2}; whole-image green {:.4} ± {:.4}; CPU {:.2} s, GL {:.2} s",
            whole.mean, whole.std_err, cpu.seconds, gl.seconds
        );
        worst = worst.max(worst_here);
    }
    worst
}

#[test]
fn gl_agrees_with_cpu_on_the_cornell_box() {
    assert_gl_agrees_with_cpu("Cornell box", &scene::cornell_box(), 32, 256, 6);
}

#[test]
fn gl_agrees_with_cpu_on_a_textured_scene() {
    let mut scene = scene::load(&test_data("scenes/khronos/BoxTextured/glTF/BoxTextured.gltf")).expect("BoxTextured");
    scene.sky = Some(Sky::uniform(Vec3::ONE));
    assert_gl_agrees_with_cpu("BoxTextured", &scene, 32, 128, 6);
}

/// The metal-roughness kernel (`Features::metal_rough`): 25 spheres from smooth metal to rough
/// dielectric under an area light and a sky, each strategy.
#[test]
fn gl_agrees_with_cpu_on_metal_rough_spheres() {
    let scene = scene::metal_rough_spheres();
    assert!(packed(&scene, Strategy::Mis, 4, 2).features.metal_rough);
    assert_gl_agrees_with_cpu("MetalRoughSpheres", &scene, 32, 128, 4);
}

/// Glass (`Features::transmission` and `volume`): the glass Cornell box's smooth sphere (a
/// delta lobe, its caustic), rough absorbing block (light sampled through a rough lobe,
/// Beer–Lambert inside), each strategy.
#[test]
fn gl_agrees_with_cpu_on_glass() {
    let scene = scene::glass_cornell();
    let f = packed(&scene, Strategy::Mis, 4, 2).features;
    assert!(f.transmission && f.volume, "{f:?}");
    assert_gl_agrees_with_cpu("glass Cornell box", &scene, 32, 256, 6);
}

/// Normal maps (`Features::normal_map`): DamagedHelmet (MikkTSpace tangents, metal-roughness)
/// under a uniform sky, each strategy.
#[test]
fn gl_agrees_with_cpu_on_normal_maps() {
    let mut scene =
        scene::load(&test_data("scenes/khronos/DamagedHelmet/glTF-Binary/DamagedHelmet.glb")).expect("DamagedHelmet");
    scene.sky = Some(Sky::uniform(Vec3::ONE));
    assert!(packed(&scene, Strategy::Mis, 4, 2).features.normal_map);
    assert_gl_agrees_with_cpu("DamagedHelmet", &scene, 32, 64, 4);
}

fn sky_lit_plane() -> Scene {
    let mut scene = scene::diffuse_plane(Vec3::splat(0.6));
    scene.sky = Some(scene::load_sky(&test_data("scenes/hdri/venice_sunset_1k.hdr"), 1.0, 0.0).expect("sky"));
    scene
}

#[test]
fn gl_agrees_with_cpu_under_an_hdr_sky() {
    assert_gl_agrees_with_cpu("plane under venice_sunset", &sky_lit_plane(), 32, 128, 4);
}

/// With the same seed, both backends draw the same random numbers: one frame's samples agree
/// pixel by pixel. With different seeds they would not: the scene's samples depend on every
/// random number drawn (jitter, light choice, directions) through a varied HDR sky.
///
/// Not every pixel: a direction sampled close to a sky texel's edge can land in the
/// neighbouring texel when `atan2`/`acos` differ by an ulp between the GL driver and Rust's libm
/// (on llvmpipe, 0.5% of the pixels with BSDF sampling, ~2% with NEE). The other pixels agree
/// within 1e-5 (relative; most exactly): the random sequences are the same.
#[test]
fn the_random_sequence_matches_the_cpu() {
    let (size, seed) = (32u32, 12345);
    let same = |a: &[Vec3], b: &[Vec3]| {
        let close =
            a.iter().zip(b).filter(|(x, y)| (**x - **y).abs().max_element() <= 1e-5 * x.max_element().max(1e-3));
        close.count() as f64 / a.len() as f64
    };
    for strategy in STRATEGIES {
        let p = packed(&sky_lit_plane(), strategy, size, 3);
        let mut cpu = CpuRenderer::new(p.clone(), seed);
        cpu.render_frame().expect("frame");
        let mut other = CpuRenderer::new(p.clone(), seed + 1);
        other.render_frame().expect("frame");
        let mut gl = gl_renderer(p, seed);
        gl.render_frame().expect("frame");
        let (cpu, other, gl) = (
            cpu.image().expect("image").pixels,
            other.image().expect("image").pixels,
            gl.image().expect("readback").pixels,
        );
        let agree = same(&cpu, &gl);
        let control = same(&cpu, &other);
        eprintln!(
            "{strategy:?}: same seed, CPU vs GL: {:.2}% of pixels agree; CPU seed vs seed + 1: {:.2}%",
            100.0 * agree,
            100.0 * control
        );
        assert!(control < 0.5, "{strategy:?}: the scene does not expose the random numbers ({control})");
        assert!(agree > 0.95, "{strategy:?}: only {:.2}% of the pixels match the CPU's", 100.0 * agree);
    }
}

#[test]
fn a_scene_beyond_the_texture_limit_is_a_clear_error() {
    let p = packed(&scene::cornell_box(), Strategy::Mis, 16, 4);
    let small = GlOptions { max_texture_size: Some(4) };
    let err = match GlRenderer::headless_with_options(p.clone(), 0, &small) {
        Err(e) => e,
        Ok(_) => panic!("a 4x4 texture limit cannot hold the Cornell box"),
    };
    let message = err.to_string();
    assert!(matches!(err, GlError::SceneTooLarge { max_texture_size: 4, .. }), "{message}");
    assert!(message.contains("GL_MAX_TEXTURE_SIZE 4") && message.contains("triangles needs"), "{message}");

    // The scene fits a 64x64 limit; a 128x128 image does not.
    let mut big = p;
    big.apply(&RenderSettings { width: 128, height: 128, strategy: Strategy::Mis, max_depth: 4 });
    let err = match GlRenderer::headless_with_options(big, 0, &GlOptions { max_texture_size: Some(64) }) {
        Err(e) => e,
        Ok(_) => panic!("a 128x128 image cannot fit a 64x64 limit"),
    };
    assert!(matches!(err, GlError::ImageTooLarge { max: 64, .. }), "{err}");
    assert!(err.to_string().contains("128x128") && err.to_string().contains("GL_MAX_TEXTURE_SIZE"), "{err}");
}

/// A driver error in the generated shader names the generated line and the Rust source it
/// came from.
#[test]
fn shader_compile_errors_point_at_the_rust_source() {
    let context = HeadlessContext::new().unwrap_or_else(|e| panic!("the GL backend must run here: {e}"));
    let gl = context.glow();
    let features = tracer::pack::Features { emissive_triangles: true, ..Default::default() };
    let mut generated = tracer::kernel::path_tracer_shader(&features, lightport_codegen::Target::GlslEs300).unwrap();
    let mut lines: Vec<String> = generated.source.lines().map(String::from).collect();
    let at = lines.iter().position(|l| l.starts_with("float power_heuristic(")).expect("power_heuristic") + 1;
    lines.insert(at, "    float broken = undeclared_thing;".into());
    generated.source = lines.join("\n");
    let err = tracer::backend::gl::compile_program(&gl, &generated).expect_err("the shader is broken");
    let message = err.to_string();
    eprintln!("{message}");
    assert!(matches!(err, GlError::Compile { stage: "fragment", .. }), "{message}");
    assert!(message.contains("undeclared_thing"), "the driver's log: {message}");
    assert!(message.contains(&format!("generated line {}", at + 1)), "{message}");
    assert!(
        message.contains("tracer/src/kernel/lights.rs") && message.contains("lights::power_heuristic"),
        "{message}"
    );
}

#[test]
fn the_context_is_opengl_es_3_with_float_render_targets() {
    let r = gl_renderer(packed(&scene::cornell_box(), Strategy::Mis, 8, 2), 0);
    let info = r.info();
    eprintln!("{info:?}");
    assert!(info.version.contains("OpenGL ES 3"), "{info:?}");
    assert!(info.max_texture_size >= 2048, "{info:?}");
}

/// The display pass (the page's, `GlDisplay`) draws what the CLI's PNG output stores with the
/// same tone curve and exposure: every pixel within one 8-bit step (GPU and CPU round the same
/// float differently at most by that), for every curve, and the curves do differ on this image.
#[test]
fn the_display_pass_shows_what_the_png_stores() {
    use glow::HasContext;
    use tracer::backend::gl::GlDisplay;
    use tracer::output::{to_display_srgb8, Display, ToneMap};

    const SIZE: i32 = 24;
    let mut renderer = gl_renderer(packed(&scene::cornell_box(), Strategy::Mis, SIZE as u32, 4), 3);
    for _ in 0..4 {
        renderer.render_frame().expect("frame");
    }
    let image = renderer.image().expect("image");
    let display = GlDisplay::new(renderer.gl()).expect("the display pass compiles");
    let gl = renderer.gl();
    // SAFETY: objects of the renderer's current context, deleted at the end of the test.
    let (texture, framebuffer) = unsafe {
        let texture = gl.create_texture().expect("texture");
        gl.bind_texture(glow::TEXTURE_2D, Some(texture));
        gl.tex_storage_2d(glow::TEXTURE_2D, 1, glow::RGBA8, SIZE, SIZE);
        let framebuffer = gl.create_framebuffer().expect("framebuffer");
        gl.bind_framebuffer(glow::FRAMEBUFFER, Some(framebuffer));
        gl.framebuffer_texture_2d(glow::FRAMEBUFFER, glow::COLOR_ATTACHMENT0, glow::TEXTURE_2D, Some(texture), 0);
        (texture, framebuffer)
    };
    let mut shown = Vec::new();
    for (tone_map, exposure) in
        [(ToneMap::Neutral, 0.0), (ToneMap::Aces, 1.5), (ToneMap::Agx, -1.0), (ToneMap::None, 0.0)]
    {
        let settings = Display { tone_map, exposure };
        display.draw(&renderer, Some(framebuffer), [SIZE, SIZE], &settings);
        let mut rgba = vec![0u8; (SIZE * SIZE * 4) as usize];
        // SAFETY: reads the framebuffer just drawn into a buffer of its exact size.
        unsafe {
            gl.bind_framebuffer(glow::FRAMEBUFFER, Some(framebuffer));
            let pixels = glow::PixelPackData::Slice(Some(&mut rgba));
            gl.read_pixels(0, 0, SIZE, SIZE, glow::RGBA, glow::UNSIGNED_BYTE, pixels);
        }
        let png = to_display_srgb8(&image, &settings);
        let mut worst = 0;
        for y in 0..SIZE as usize {
            // Framebuffer row 0 is the bottom; image row 0 the top.
            let row = SIZE as usize - 1 - y;
            for x in 0..SIZE as usize {
                for c in 0..3 {
                    let gpu = rgba[(row * SIZE as usize + x) * 4 + c];
                    let cpu = png[(y * SIZE as usize + x) * 3 + c];
                    worst = worst.max(gpu.abs_diff(cpu));
                }
            }
        }
        assert!(worst <= 1, "{}: the display pass is {worst} 8-bit steps from the PNG", tone_map.name());
        shown.push(png);
    }
    for (i, a) in shown.iter().enumerate() {
        for b in &shown[i + 1..] {
            assert_ne!(a, b, "two display settings gave the same image: the test cannot tell them apart");
        }
    }
    // SAFETY: created above on this context.
    unsafe {
        gl.bind_framebuffer(glow::FRAMEBUFFER, None);
        gl.delete_framebuffer(framebuffer);
        gl.delete_texture(texture);
    }
    display.delete(renderer.gl());
}
