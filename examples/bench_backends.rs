//! GL vs CPU backend throughput (samples per second), measured in the same run on the same
//! packed scenes, printed as a table with the ratio GL / CPU.
//!
//! ```sh
//! cargo run --release --example bench_backends [-- FRAMES] [--size N]
//! ```
//!
//! Each backend renders one untimed warm-up frame (the GL driver compiles its shader on the
//! first draw), then FRAMES frames (default 8) timed with `glFinish` before and after.
//! `--size N` renders both scenes at NxN (default: the Cornell box at 256x256, LittlestTokyo at
//! 128x128; a GPU wants more pixels per draw to be busy).
//!
//! The last column times the GL backend again with `leaf_stack_limit` 0: the same shader, but
//! `trace_closest` intersects every leaf as soon as its node is hit instead of pushing it (the
//! traversal order `tracer::pack` falls back to for trees whose leaves would not fit the stack).

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
    gl_leaves_at_once: f64,
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
    let args: Vec<String> = std::env::args().skip(1).collect();
    let size: Option<u32> = match args.iter().position(|a| a == "--size") {
        Some(i) => Some(args.get(i + 1).context("--size needs a value")?.parse().context("--size")?),
        None => None,
    };
    let frames: u32 =
        args.first().filter(|a| !a.starts_with("--")).map(|a| a.parse()).transpose().context("FRAMES")?.unwrap_or(8);
    let tokyo = Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/scenes/threejs/LittlestTokyo.glb");
    let scenes = [
        ("Cornell box".to_string(), tracer::scene::cornell_box(), size.unwrap_or(256)),
        (
            "LittlestTokyo".to_string(),
            tracer::scene::load(&tokyo).context("loading LittlestTokyo")?,
            size.unwrap_or(128),
        ),
    ];
    let mut rows = Vec::new();
    let mut renderer = String::new();
    for (name, scene, size) in scenes {
        let p = packed(&scene, size)?;
        let cpu = time_cpu(&p, frames);
        let (gl, r) = time_gl(&p, frames)?;
        renderer = r;
        let mut at_once = p.clone();
        at_once.scene.leaf_stack_limit = 0;
        let (gl_leaves_at_once, _) = time_gl(&at_once, frames)?;
        rows.push(Row { scene: name, size, triangles: p.triangle_count, cpu, gl, gl_leaves_at_once });
    }
    println!(
        "{frames} frames, MIS, max depth 8; CPU: {} threads; GL: {renderer}",
        std::thread::available_parallelism().map_or(1, |n| n.get())
    );
    println!("| scene | size | triangles | CPU Msamples/s | GL Msamples/s | GL / CPU | GL, leaves at once / pushed |");
    println!("|---|---|---|---|---|---|---|");
    for r in rows {
        println!(
            "| {} | {}x{} | {} | {:.3} | {:.3} | {:.2} | {:.2} |",
            r.scene,
            r.size,
            r.size,
            r.triangles,
            r.cpu / 1e6,
            r.gl / 1e6,
            r.gl / r.cpu,
            r.gl_leaves_at_once / r.gl
        );
    }
    Ok(())
}
