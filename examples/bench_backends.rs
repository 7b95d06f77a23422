//! GL vs CPU backend throughput (samples per second), measured in the same run on the same
//! packed scenes, printed as a table with the ratio GL / CPU.
//!
//! ```sh
//! cargo run --release --example bench_backends [-- FRAMES]
//! ```
//!
//! Each backend renders one untimed warm-up frame (the GL driver compiles its shader on the
//! first draw), then FRAMES frames (default 8) timed with `glFinish` before and after.

use std::path::Path;
use std::time::Instant;

use anyhow::{Context, Result};
use tracer::backend::cpu::CpuRenderer;
use tracer::backend::gl::GlRenderer;
use tracer::pack::{pack, Packed, RenderSettings, Strategy};

struct Row {
    scene: String,
    size: u32,
    triangles: usize,
    cpu: f64,
    gl: f64,
}

fn packed(scene: &tracer::scene::Scene, size: u32) -> Result<Packed> {
    let bvh = tracer::bvh::build(&scene.triangles).context("BVH")?;
    let settings = RenderSettings { width: size, height: size, strategy: Strategy::Mis, max_depth: 8 };
    Ok(pack(scene, &bvh, &settings)?)
}

/// Samples per second of the CPU backend.
fn time_cpu(p: &Packed, frames: u32) -> f64 {
    let mut r = CpuRenderer::new(p.clone(), 0);
    r.render_frame();
    let t = Instant::now();
    for _ in 0..frames {
        r.render_frame();
    }
    let pixels = p.scene.width as f64 * p.scene.height as f64;
    frames as f64 * pixels / t.elapsed().as_secs_f64()
}

/// Samples per second of the GL backend.
fn time_gl(p: &Packed, frames: u32) -> Result<(f64, String)> {
    let mut r = GlRenderer::headless(p.clone(), 0)?;
    r.render_frame()?;
    r.finish()?;
    let t = Instant::now();
    for _ in 0..frames {
        r.render_frame()?;
    }
    r.finish()?;
    let seconds = t.elapsed().as_secs_f64();
    anyhow::ensure!(r.rejected_samples()? == 0, "the GL backend dropped non-finite samples");
    let pixels = p.scene.width as f64 * p.scene.height as f64;
    Ok((frames as f64 * pixels / seconds, r.info().renderer.clone()))
}

fn main() -> Result<()> {
    let frames: u32 = std::env::args().nth(1).map(|a| a.parse()).transpose().context("FRAMES")?.unwrap_or(8);
    let tokyo = Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/scenes/threejs/LittlestTokyo.glb");
    let scenes = [
        ("Cornell box".to_string(), tracer::scene::cornell_box(), 256),
        ("LittlestTokyo".to_string(), tracer::scene::load(&tokyo).context("loading LittlestTokyo")?, 128),
    ];
    let mut rows = Vec::new();
    let mut renderer = String::new();
    for (name, scene, size) in scenes {
        let p = packed(&scene, size)?;
        let cpu = time_cpu(&p, frames);
        let (gl, r) = time_gl(&p, frames)?;
        renderer = r;
        rows.push(Row { scene: name, size, triangles: p.triangle_count, cpu, gl });
    }
    println!(
        "{frames} frames, MIS, max depth 8; CPU: {} threads; GL: {renderer}",
        std::thread::available_parallelism().map_or(1, |n| n.get())
    );
    println!("| scene | size | triangles | CPU Msamples/s | GL Msamples/s | GL / CPU |");
    println!("|---|---|---|---|---|---|");
    for r in rows {
        println!(
            "| {} | {}x{} | {} | {:.3} | {:.3} | {:.2} |",
            r.scene,
            r.size,
            r.size,
            r.triangles,
            r.cpu / 1e6,
            r.gl / 1e6,
            r.gl / r.cpu
        );
    }
    Ok(())
}
