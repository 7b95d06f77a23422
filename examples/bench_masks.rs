//! What alpha masks cost per sample, per runtime: LittlestTokyo under a white sky as shipped
//! against the same scene made opaque (every `alphaMode` dropped), on the CPU, GL and wgpu,
//! alternated round by round in one run. A narrower, longer `bench_backends` table for a shared
//! machine: each measurement also reads the process's CPU time (`/proc/self/stat`, every thread:
//! the CPU backend's workers and llvmpipe's/lavapipe's), which a busy neighbour disturbs far less
//! than the wall clock.
//!
//! ```sh
//! cargo run --release --example bench_masks [-- FRAMES] [--size N] [--rounds R]
//! ```

use std::path::Path;
use std::time::Instant;

use anyhow::{Context, Result};
use tracer::backend::{create, Renderer, RendererKind};
use tracer::kernel::{RenderSettings, Strategy};
use tracer::pack::pack;

/// The process's user + system CPU time in seconds (clock ticks of 10 ms).
fn cpu_seconds() -> Result<f64> {
    let stat = std::fs::read_to_string("/proc/self/stat")?;
    // Fields after the command name, which is in parentheses.
    let rest = &stat[stat.rfind(')').context("/proc/self/stat")? + 2..];
    let fields: Vec<&str> = rest.split(' ').collect();
    let utime: f64 = fields[11].parse()?;
    let stime: f64 = fields[12].parse()?;
    Ok((utime + stime) / 100.0)
}

/// Wall and CPU seconds per frame.
fn time_frames(r: &mut dyn Renderer, frames: u32) -> Result<(f64, f64)> {
    r.finish()?;
    let (t, c) = (Instant::now(), cpu_seconds()?);
    for _ in 0..frames {
        r.render_frame()?;
    }
    r.finish()?;
    Ok((t.elapsed().as_secs_f64() / frames as f64, (cpu_seconds()? - c) / frames as f64))
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    let m = v.len() / 2;
    if v.len() % 2 == 1 {
        v[m]
    } else {
        (v[m - 1] + v[m]) / 2.0
    }
}

fn value_of(args: &[String], flag: &str) -> Result<Option<u32>> {
    match args.iter().position(|a| a == flag) {
        Some(i) => Ok(Some(
            args.get(i + 1).with_context(|| format!("{flag} needs a value"))?.parse().context(flag.to_string())?,
        )),
        None => Ok(None),
    }
}

fn main() -> Result<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let size = value_of(&args, "--size")?.unwrap_or(128);
    let rounds = value_of(&args, "--rounds")?.unwrap_or(7).max(1) as usize;
    let frames: u32 =
        args.first().filter(|a| !a.starts_with("--")).map(|a| a.parse()).transpose().context("FRAMES")?.unwrap_or(4);
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/scenes/threejs/LittlestTokyo.glb");
    let mut masked = tracer::scene::load(&path).context("loading LittlestTokyo")?;
    masked.sky = Some(tracer::scene::Sky::uniform(glam::Vec3::ONE));
    let mut opaque = masked.clone();
    for m in &mut opaque.materials {
        m.alpha_cutoff = None;
    }
    let settings = RenderSettings { width: size, height: size, strategy: Strategy::Mis, max_depth: 8 };
    let kinds = [("CPU", RendererKind::Cpu), ("GL", RendererKind::Gl), ("wgpu", RendererKind::Wgpu)];
    // Per runtime: the masked renderer, then the opaque one.
    let mut renderers: Vec<Box<dyn Renderer>> = Vec::new();
    for scene in [&masked, &opaque] {
        let bvh = tracer::bvh::build(&scene.triangles).context("BVH")?;
        let p = pack(scene, &bvh, &settings)?;
        for (_, kind) in kinds {
            renderers.push(create(kind, p.clone(), 0)?);
        }
    }
    for r in renderers.iter_mut() {
        time_frames(r.as_mut(), 1)?; // warm-up: shader compilation, first uploads
    }
    let n = renderers.len();
    let mut wall = vec![Vec::new(); n];
    let mut cpu = vec![Vec::new(); n];
    for round in 0..rounds {
        for k in 0..n {
            // Each runtime's masked and opaque renderers back to back, the order alternating.
            let i = (k / 2 + round) % kinds.len() + kinds.len() * ((k + round) % 2);
            let (w, c) = time_frames(renderers[i].as_mut(), frames)?;
            wall[i].push(w);
            cpu[i].push(c);
        }
    }
    println!("LittlestTokyo {size}x{size}, white sky, MIS, depth 8; {frames} frames x {rounds} rounds, medians");
    println!("| runtime | masked ms/frame | opaque ms/frame | masked / opaque (wall) | masked / opaque (CPU time) |");
    println!("|---|---|---|---|---|");
    for (j, (name, _)) in kinds.iter().enumerate() {
        let (mw, ow) = (median(wall[j].clone()), median(wall[j + kinds.len()].clone()));
        let (mc, oc) = (median(cpu[j].clone()), median(cpu[j + kinds.len()].clone()));
        println!("| {name} | {:.1} | {:.1} | {:.2} | {:.2} |", mw * 1e3, ow * 1e3, mw / ow, mc / oc);
    }
    Ok(())
}
