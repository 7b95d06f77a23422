//! The denoiser (`tracer::denoise`): what it costs and what it buys. Prints
//! - what the guide costs (a frame of a renderer that accumulates it, `Features::denoise_guide`,
//!   against a plain frame, and reading it back) and the filter passes' time
//!   on each runtime (CPU, GL, wgpu: `Renderer::denoise_passes`, read-back included) at 640x480
//!   and 1920x1080 on the Cornell box, median of `--rounds`, as a ratio to rendering one sample
//!   per pixel of the same image on the same runtime in the same run; and the passes' time in
//!   headless Chromium on WebGL2 and WebGPU (the equivalence harness's page: `GlFilter` and
//!   `WgpuFilter` compiled to wasm, timed in the page, read-back included), where
//!   node, Chromium and `web/pkg` are there;
//! - the equal-quality speed-up on the Cornell box at 64x64: the relative MSE of the denoised
//!   16-spp image against a 4096-spp reference, and how many samples per pixel the noisy image
//!   needs to reach it (doubling until it does, interpolated in log-log).
//!
//! `cargo run --release --example bench_denoise [-- --rounds 5]`

use std::time::Instant;

use tracer::backend::cpu::CpuRenderer;
use tracer::backend::{Renderer, RendererKind};
use tracer::denoise::{denoise, filter_input, Guide};
use tracer::kernel::denoise::FilterImage;
use tracer::kernel::{RenderSettings, Strategy};
use tracer::output::Image;
use tracer::pack::{build_and_pack, Packed};

fn packed(size: (u32, u32)) -> Packed {
    let settings = RenderSettings { width: size.0, height: size.1, strategy: Strategy::Mis, max_depth: 6 };
    build_and_pack(&tracer::scene::cornell_box(), &settings).expect("pack").1
}

/// `spp` frames on the CPU, accumulating the guide: the image and its guide.
fn render(p: &Packed, spp: u32, seed: u32) -> (Image, Guide) {
    let mut guided = p.clone();
    guided.set_denoise_guide(true);
    let mut r = CpuRenderer::new(guided, seed);
    for _ in 0..spp {
        r.render_frame().expect("frame");
    }
    (r.image().expect("image"), Guide::read(&r).expect("guide"))
}

fn rel_mse(a: &Image, reference: &Image) -> f64 {
    tracer::stats::rel_mse(&a.pixels, &reference.pixels).expect("same size")
}

/// The filter passes in the page (WebGL2 and WebGPU on SwiftShader here): medians of the
/// page's own timings; a missing browser piece is a row saying so.
fn page_rows(size: (u32, u32), input: &FilterImage, rounds: usize) {
    use tracer::backend::harness::{Backend, BrowserOptions, BrowserRuntime, BrowserSession};
    let modules = tracer::kernel::modules();
    let session = match BrowserSession::start(&BrowserOptions::default()) {
        Ok(s) => std::sync::Arc::new(s),
        Err(e) => return println!("| {}x{} | page | unavailable: {e} | | | | | |", size.0, size.1),
    };
    for backend in [Backend::WebGl2, Backend::WebGpu] {
        let program = lightport_codegen::Program::link(&modules).expect("the kernel links");
        let mut runtime = match BrowserRuntime::new(session.clone(), backend, program, &modules) {
            Ok(r) => r,
            Err(e) => {
                println!("| {}x{} | {backend} | unavailable: {e} | | | | | |", size.0, size.1);
                continue;
            }
        };
        let times: Vec<f64> = (0..rounds).map(|_| runtime.run_filter(input).expect("the page's passes").1).collect();
        println!("| {}x{} | {backend} (page) | | | | | {:.1} | |", size.0, size.1, median(times));
    }
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let rounds: usize =
        args.iter().position(|a| a == "--rounds").and_then(|i| args.get(i + 1)?.parse().ok()).unwrap_or(5);
    println!("threads: {}", rayon::current_num_threads());
    println!(
        "\n| image | runtime | 1 spp frame (ms) | with the guide (ms) | guided / plain | guide read-back (ms) | filter passes (ms) | filter / frame |"
    );
    println!("|---|---|---|---|---|---|---|---|");
    for size in [(640, 480), (1920, 1080)] {
        let p = packed(size);
        let (image, guide) = render(&p, 2, 1);
        let input = filter_input(&image, &guide).expect("filter input");
        let mut guided = p.clone();
        guided.set_denoise_guide(true);
        // Per runtime, a plain renderer and one that accumulates the guide.
        let mut runtimes: Vec<(Box<dyn Renderer>, Box<dyn Renderer>)> = RendererKind::ALL
            .iter()
            .filter_map(|kind| {
                let create = |packed: &Packed| {
                    tracer::backend::create(*kind, packed.clone(), 3)
                        .map_err(|e| {
                            println!("| {}x{} | {} | unavailable: {e} | | | | | |", size.0, size.1, kind.name())
                        })
                        .ok()
                };
                Some((create(&p)?, create(&guided)?))
            })
            .collect();
        let timed = |f: &mut dyn FnMut()| {
            let t = Instant::now();
            f();
            t.elapsed().as_secs_f64() * 1e3
        };
        let mut times = vec![[Vec::new(), Vec::new(), Vec::new(), Vec::new()]; runtimes.len()];
        // Alternate the runtimes and the measurements, round after round.
        for _ in 0..rounds {
            for ((plain, with_guide), [frame, guided_frame, read, filter]) in runtimes.iter_mut().zip(&mut times) {
                for (r, column) in [(&mut *plain, &mut *frame), (&mut *with_guide, &mut *guided_frame)] {
                    column.push(timed(&mut || {
                        r.render_frame().expect("frame");
                        r.finish().expect("finish");
                    }));
                }
                read.push(timed(&mut || drop(Guide::read(with_guide.as_ref()).expect("guide"))));
                filter.push(timed(&mut || {
                    let out = plain.denoise_passes(input.clone()).expect("filter passes");
                    assert!(out.iter().all(|p| p.is_finite()));
                }));
            }
        }
        for ((r, _), columns) in runtimes.iter().zip(times) {
            let [frame, guided_frame, read, filter] = columns.map(median);
            let name = r.describe().runtime;
            println!(
                "| {}x{} | {name} | {frame:.1} | {guided_frame:.1} | {:.2}x | {read:.1} | {filter:.1} | {:.2}x |",
                size.0,
                size.1,
                guided_frame / frame,
                filter / frame
            );
        }
        page_rows(size, &input, rounds);
    }

    let p = packed((64, 64));
    let (reference, _) = render(&p, 4096, 99);
    let (noisy, guide) = render(&p, 16, 7);
    let denoised = denoise(&noisy, &guide).expect("denoise").image;
    let target = rel_mse(&denoised, &reference);
    println!("\nCornell box 64x64: relMSE 16 spp noisy {:.5}, denoised {target:.5}", rel_mse(&noisy, &reference));
    let mut previous = (16.0f64, rel_mse(&noisy, &reference));
    let mut spp = 32;
    while spp <= 4096 {
        let e = rel_mse(&render(&p, spp, 7).0, &reference);
        println!("  noisy at {spp:>4} spp: relMSE {e:.5}");
        if e <= target {
            // Log-log interpolation between the last two sample counts.
            let (s0, e0) = previous;
            let f = (target.ln() - e0.ln()) / (e.ln() - e0.ln());
            let needed = (s0.ln() + f * ((spp as f64).ln() - s0.ln())).exp();
            println!("equal quality: {needed:.0} spp without the filter = {:.1}x the samples", needed / 16.0);
            return;
        }
        previous = (spp as f64, e);
        spp *= 2;
    }
    println!("equal quality: beyond 4096 spp");
}
