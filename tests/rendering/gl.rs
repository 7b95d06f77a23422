//! The GL runtime (headless EGL; Mesa llvmpipe in CI): the agreement suite against the CPU
//! (`agreement_suite!`: the same kernel over the same packed data must estimate the same image)
//! and what is GL's own: texture limits, driver errors at the Rust source, the context, and the
//! display pass. Never skipped: a machine without a usable GL fails these tests with the reason.

use tracer::backend::gl::{GlError, GlOptions, GlRenderer, HeadlessContext};
use tracer::backend::{Renderer, RendererKind};
use tracer::kernel::{RenderSettings, Strategy};
use tracer::pack::Packed;
use tracer::scene;

use crate::common::agreement::packed;

crate::agreement_suite!(RendererKind::Gl, frames / 1);

fn gl_renderer(packed: Packed, seed: u32) -> GlRenderer {
    GlRenderer::headless(packed, seed).unwrap_or_else(|e| panic!("the GL backend must run here: {e}"))
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
    let features = tracer::kernel::Features { emissive_triangles: true, ..Default::default() };
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
