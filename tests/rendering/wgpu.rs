//! The wgpu runtime (Vulkan; Mesa lavapipe in CI): the agreement suite against the CPU
//! (`agreement_suite!`: the generated WGSL compute kernel over the same packed data must
//! estimate the same image) and what is wgpu's own: storage-buffer limits, shader errors at the
//! Rust source, the adapter. Never skipped: a machine without a Vulkan driver fails these tests
//! with the reason (and the package to install).

use tracer::backend::wgpu::{WgpuDevice, WgpuError, WgpuOptions, WgpuRenderer};
use tracer::backend::RendererKind;
use tracer::kernel::{RenderSettings, Strategy};
use tracer::pack::Packed;
use tracer::scene;

use crate::common::agreement::packed;

// Lean: lavapipe runs the kernel on the CPU, so half GL's frames (each comparison is the same
// 5-sigma test, with wider errors).
crate::agreement_suite!(RendererKind::Wgpu, frames / 2);

fn wgpu_renderer(packed: Packed, seed: u32) -> WgpuRenderer {
    WgpuRenderer::headless(packed, seed).unwrap_or_else(|e| panic!("the wgpu backend must run here: {e}"))
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
        message.contains("max_storage_buffer_binding_size is 256")
            && message.contains("lp_scene_vec4f (materials + triangles + "),
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
    let features = tracer::kernel::Features { emissive_triangles: true, ..Default::default() };
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
