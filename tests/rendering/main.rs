//! Rendered images: the path tracer on the CPU (analytic scenes, strategies, stability cases,
//! each material feature) and every GPU runtime against it (`gl`, `wgpu`: one agreement suite,
//! `common::agreement::agreement_suite!`, instantiated per runtime). GPU tests are never
//! skipped: a machine without a GL or Vulkan driver fails them with the reason.

mod alpha_mask;
#[path = "../common/mod.rs"]
mod common;
mod cpu;
mod denoise;
mod gl;
mod glass;
mod instancing;
mod metal_rough;
mod moving;
mod normal_maps;
mod preview;
mod stability;
mod take_scene;
mod texture_transform;
mod wavefront;
mod wgpu;
