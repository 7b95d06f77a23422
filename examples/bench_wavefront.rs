//! The wavefront schedule against the megakernel, per runtime (CPU and wgpu; GL has no
//! compute), at two path depths, alternated round by round in one run: milliseconds per frame
//! (median of the rounds), the wavefront's extension and shadow rays per second, and its
//! time to the first frame (creation, compile and one frame). Scenes: the built-in Cornell box
//! and any glTF files given (under a white sky).
//!
//! ```sh
//! cargo run --release --example bench_wavefront [-- SCENE.glb ...] [--size N] [--frames F] [--rounds R] [--depths 8,32]
//! ```

use std::path::PathBuf;
use std::time::Instant;

use anyhow::{Context, Result};
use glam::Vec3;
use tracer::backend::wavefront::WavefrontCounts;
use tracer::backend::{create_scheduled, Renderer, RendererKind, Schedule};
use tracer::kernel::{RenderSettings, Strategy};
use tracer::pack::{pack, Packed};
use tracer::scene::{self, Sky};

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    let m = v.len() / 2;
    if v.is_empty() {
        f64::NAN
    } else if v.len() % 2 == 1 {
        v[m]
    } else {
        (v[m - 1] + v[m]) / 2.0
    }
}

fn flag<T: std::str::FromStr>(args: &[String], name: &str) -> Result<Option<T>>
where
    T::Err: std::error::Error + Send + Sync + 'static,
{
    match args.iter().position(|a| a == name) {
        Some(i) => Ok(Some(args.get(i + 1).with_context(|| format!("{name} needs a value"))?.parse()?)),
        None => Ok(None),
    }
}

/// Seconds per frame over `frames` frames (after one warm-up frame).
fn seconds_per_frame(r: &mut dyn Renderer, frames: u32) -> Result<f64> {
    r.restart()?;
    r.render_frame()?;
    r.finish()?;
    let t = Instant::now();
    for _ in 0..frames {
        r.render_frame()?;
    }
    r.finish()?;
    Ok(t.elapsed().as_secs_f64() / frames as f64)
}

fn main() -> Result<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let size: u32 = flag(&args, "--size")?.unwrap_or(160);
    let frames: u32 = flag(&args, "--frames")?.unwrap_or(4);
    let rounds: u32 = flag(&args, "--rounds")?.unwrap_or(3);
    let depths: Vec<u32> = flag::<String>(&args, "--depths")?
        .unwrap_or_else(|| "8,32".into())
        .split(',')
        .map(|d| d.parse().context("--depths"))
        .collect::<Result<_>>()?;
    let values = ["--size", "--frames", "--rounds", "--depths"];
    let files: Vec<PathBuf> = args
        .iter()
        .enumerate()
        .filter(|(i, a)| !a.starts_with("--") && (*i == 0 || !values.contains(&args[i - 1].as_str())))
        .map(|(_, a)| PathBuf::from(a))
        .collect();
    let mut scenes = vec![("Cornell box".to_string(), scene::cornell_box())];
    for f in files {
        let mut s = scene::load(&f).with_context(|| format!("loading {}", f.display()))?;
        s.sky = Some(Sky::uniform(Vec3::ONE));
        scenes.push((f.file_stem().unwrap_or_default().to_string_lossy().into_owned(), s));
    }
    println!("{size}x{size}, {frames} frames per measurement, median of {rounds} rounds (megakernel and wavefront alternated)");
    println!(
        "| scene | depth | runtime | megakernel ms/frame | wavefront ms/frame | wavefront / megakernel | wavefront Mrays/s (extension + shadow) | first frame, wavefront | first frame, megakernel |"
    );
    println!("|---|---|---|---|---|---|---|---|---|");
    for (name, scene) in &scenes {
        let bvh = tracer::bvh::build(&scene.triangles).context("BVH")?;
        for &max_depth in &depths {
            let settings = RenderSettings { width: size, height: size, strategy: Strategy::Mis, max_depth };
            let packed: Packed = pack(scene, &bvh, &settings).context("pack")?;
            for kind in [RendererKind::Cpu, RendererKind::Wgpu] {
                let mut renderers = Vec::new();
                let mut first = Vec::new();
                for schedule in Schedule::ALL {
                    let t = Instant::now();
                    let mut r = create_scheduled(kind, schedule, packed.clone(), 1)
                        .with_context(|| format!("{} {}", kind.name(), schedule.name()))?;
                    r.render_frame()?;
                    r.finish()?;
                    first.push(t.elapsed().as_secs_f64());
                    renderers.push(r);
                }
                let mut times = [Vec::new(), Vec::new()];
                for _ in 0..rounds {
                    for (k, r) in renderers.iter_mut().enumerate() {
                        times[k].push(seconds_per_frame(r.as_mut(), frames)?);
                    }
                }
                let [mega, wave] = times.map(median);
                // Rays of the wavefront's last measurement (frames + the warm-up frame).
                let counts = wavefront_counts(renderers[1].as_ref());
                let rays =
                    counts.map_or(f64::NAN, |c| (c.segments as f64 + c.shadow_rays as f64) / (frames + 1) as f64);
                println!(
                    "| {name} | {max_depth} | {} | {:.1} | {:.1} | {:.2} | {:.2} | {:.2} s | {:.2} s |",
                    kind.name(),
                    mega * 1e3,
                    wave * 1e3,
                    wave / mega,
                    rays / wave / 1e6,
                    first[1],
                    first[0]
                );
            }
        }
    }
    Ok(())
}

/// The wavefront's ray counts, from its pool's counters (the CPU's and wgpu's renderers).
fn wavefront_counts(r: &dyn Renderer) -> Option<WavefrontCounts> {
    r.wavefront_counts()
}
