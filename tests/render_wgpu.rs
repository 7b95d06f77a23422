//! The wgpu backend (Vulkan; Mesa lavapipe in CI) against the CPU backend: the generated WGSL
//! compute kernel over the same packed data must estimate the same image. Never skipped: a
//! machine without a Vulkan driver fails these tests with the reason (and the package to
//! install).
//!
//! Lean: lavapipe runs the kernel on the CPU, so the images are small and the frames few, yet
//! each comparison is the same 5-sigma test as the GL backend's (`render_gl.rs`).

mod common;

use common::agreement::{self, assert_agrees_with_cpu, packed};
use tracer::backend::wgpu::{WgpuDevice, WgpuError, WgpuOptions, WgpuRenderer};
use tracer::backend::{RenderError, Renderer, RendererKind};
use tracer::pack::{Packed, RenderSettings, Strategy};
use tracer::scene;

fn wgpu_renderer(packed: Packed, seed: u32) -> WgpuRenderer {
    WgpuRenderer::headless(packed, seed).unwrap_or_else(|e| panic!("the wgpu backend must run here: {e}"))
}

#[test]
fn wgpu_agrees_with_cpu_on_the_cornell_box() {
    assert_agrees_with_cpu(RendererKind::Wgpu, "Cornell box", &scene::cornell_box(), 32, 128, 6);
}

#[test]
fn wgpu_agrees_with_cpu_on_a_textured_scene() {
    assert_agrees_with_cpu(RendererKind::Wgpu, "BoxTextured", &agreement::textured_box(), 32, 96, 6);
}

#[test]
fn wgpu_agrees_with_cpu_under_an_hdr_sky() {
    assert_agrees_with_cpu(RendererKind::Wgpu, "plane under venice_sunset", &agreement::sky_lit_plane(), 32, 96, 4);
}

/// Glass: the smooth sphere's delta lobe and caustic, the rough absorbing block, each strategy.
#[test]
fn wgpu_agrees_with_cpu_on_glass() {
    let scene = scene::glass_cornell();
    let f = packed(&scene, Strategy::Mis, 4, 2).features;
    assert!(f.transmission && f.volume, "{f:?}");
    assert_agrees_with_cpu(RendererKind::Wgpu, "glass Cornell box", &scene, 32, 128, 6);
}

#[test]
fn the_random_sequence_matches_the_cpu() {
    agreement::assert_same_random_sequence(RendererKind::Wgpu);
}

#[test]
fn a_scene_beyond_the_storage_buffer_limit_is_a_clear_error() {
    let p = packed(&scene::cornell_box(), Strategy::Mis, 16, 4);
    let small = WgpuOptions { max_storage_buffer_binding_size: Some(256), ..Default::default() };
    let err = match WgpuRenderer::headless_with_options(p.clone(), 0, &small) {
        Err(e) => e,
        Ok(_) => panic!("a 256-byte binding limit cannot hold the Cornell box"),
    };
    let message = err.to_string();
    assert!(matches!(err, WgpuError::SceneTooLarge { max: 256, .. }), "{message}");
    assert!(
        message.contains("max_storage_buffer_binding_size is 256") && message.contains("lp_scene_vec4f (triangles + "),
        "{message}"
    );

    // The scene fits 64 KiB; a 128x128 image's accumulation (256 KiB) does not.
    let mut big = p;
    big.apply(&RenderSettings { width: 128, height: 128, strategy: Strategy::Mis, max_depth: 4 });
    let limit = WgpuOptions { max_storage_buffer_binding_size: Some(64 << 10), ..Default::default() };
    let err = match WgpuRenderer::headless_with_options(big, 0, &limit) {
        Err(e) => e,
        Ok(_) => panic!("a 128x128 accumulation cannot fit a 64 KiB binding"),
    };
    assert!(matches!(err, WgpuError::ImageTooLarge { needed: 262144, .. }), "{err}");
    assert!(
        err.to_string().contains("128x128") && err.to_string().contains("max_storage_buffer_binding_size"),
        "{err}"
    );
}

/// A shader error that wgpu reports names the generated line and the Rust source it came from.
#[test]
fn shader_errors_point_at_the_rust_source() {
    let device = WgpuDevice::native().unwrap_or_else(|e| panic!("the wgpu backend must run here: {e}"));
    let features = tracer::pack::Features { emissive_triangles: true, ..Default::default() };
    let mut generated = tracer::kernel::path_tracer_shader(&features, lightport_codegen::Target::Wgsl).unwrap();
    let mut lines: Vec<String> = generated.source.lines().map(String::from).collect();
    let at = lines.iter().position(|l| l.starts_with("fn power_heuristic(")).expect("power_heuristic") + 1;
    lines.insert(at, "    let broken: f32 = undeclared_thing;".into());
    generated.source = lines.join("\n");
    let err = device.compile(&generated).expect_err("the shader is broken");
    let message = err.to_string();
    eprintln!("{message}");
    assert!(matches!(err, WgpuError::Compile { .. }), "{message}");
    assert!(message.contains("undeclared_thing"), "wgpu's message: {message}");
    assert!(message.contains(&format!("generated line {}", at + 1)), "{message}");
    assert!(
        message.contains("tracer/src/kernel/lights.rs") && message.contains("lights::power_heuristic"),
        "{message}"
    );
}

#[test]
fn the_adapter_is_named_and_its_limits_are_used() {
    let r = wgpu_renderer(packed(&scene::cornell_box(), Strategy::Mis, 8, 2), 0);
    let info = r.info();
    eprintln!("{info:?}");
    assert!(!info.adapter.is_empty(), "{info:?}");
    assert!(info.max_storage_buffer_binding_size >= 128 << 20, "WebGPU's default at least: {info:?}");
}

/// Restarting drops every sample; changing the camera through `set_uniforms` changes the image.
#[test]
fn restart_and_uniform_updates_take_effect() {
    let mut r = wgpu_renderer(packed(&scene::cornell_box(), Strategy::Mis, 16, 3), 0);
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
    assert!(matches!(err, RenderError::SizeChanged { .. }), "{err}");
}

/// A frame rendered in bands of rows (the same dispatch over fewer rows, as the WebGPU page's
/// frame loop submits them) is the frame rendered whole, exactly (`common::bands`, as GL's in
/// `tests/web.rs`). Heights that are not multiples of the 8-row workgroup, so that a band's
/// last workgroup reaches into rows that belong to the next band.
#[test]
fn a_frame_split_into_bands_is_the_unsplit_frame() {
    let base = packed(&scene::cornell_box(), Strategy::Mis, 20, 4);
    assert_eq!((base.scene.width, base.scene.height), (20, 20));
    common::bands::assert_bands_make_the_whole_frame(
        &mut wgpu_renderer(base.clone(), 3),
        &mut wgpu_renderer(base, 3),
        20,
    );
}
