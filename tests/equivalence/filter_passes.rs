//! The denoiser's filter passes in the browser: `kernel::denoise::atrous_pixel` generated as an
//! image pass runs on WebGL2 (fragment passes, `GlFilter`) and WebGPU (compute passes,
//! `WgpuFilter`) in the page and gives the CPU's output; natively on GL and wgpu:
//! `tests/rendering/denoise.rs`.

use super::*;
use common::agreement::{largest_difference, noisy_filter_input, textured_box};
use tracer::denoise::filter_on_cpu;

#[test]
fn the_filter_passes_agree_on_webgl2_and_webgpu() {
    let mut eq = equivalence();
    let inputs = [
        ("Cornell box 37x23, 4 spp", noisy_filter_input(&tracer::scene::cornell_box(), 37, 23, 4)),
        ("textured box 24x24, 2 spp", noisy_filter_input(&textured_box(), 24, 24, 2)),
        ("Cornell box 19x1, 4 spp", noisy_filter_input(&tracer::scene::cornell_box(), 19, 1, 4)),
    ];
    for backend in [Backend::WebGl2, Backend::WebGpu] {
        let runtime = eq.browser(backend).expect("a browser runtime");
        for (what, input) in &inputs {
            let expected = filter_on_cpu(input.clone());
            let (got, _) = runtime.run_filter(input).unwrap_or_else(|e| panic!("{backend}, {what}: {e}"));
            let difference = largest_difference(&got, &expected);
            eprintln!("{backend}, {what}: largest relative difference {difference:.2e}");
            // f32 exp/pow differ by a few ulp between drivers; four passes compound them.
            assert!(difference <= 1e-4, "{backend}, {what}: the filter differs from the CPU's by {difference:.2e}");
        }
    }
}
