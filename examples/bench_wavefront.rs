//! The wavefront schedule against the megakernel, per runtime (CPU and wgpu; GL has no
//! compute), at two path depths, alternated round by round in one run: milliseconds per frame
//! (median of the rounds), the wavefront / megakernel ratio, the rays per second split into
//! primary (camera paths generated: one per pixel and frame), extension (the other closest-hit
//! rays) and shadow rays (from the wavefront's counters; the megakernel traces the same paths,
//! on the CPU bit for bit, so its column divides the same count by its own time), and the time
//! to the first frame (creation, compile and one frame). Scenes: the built-in Cornell box and
//! any glTF files given (under a white sky).
//!
//! Investigations (same run, same alternation):
//! - `--ips 4,8,16`: the wgpu wavefront with that many iterations per submission (one counters
//!   read-back each), as extra columns; the first is the main table's.
//! - `--pools 65536,307200`: the CPU wavefront over pools of that many slots; the first is the
//!   main table's.
//! - `--profile`: one more frame per wavefront with each stage timed on its own (wgpu: each
//!   stage its own submission, waited for), the iterations the frame took and how many of them
//!   extended fewer than 1 % of the pool's slots (the frame's tail), and on wgpu the cost of an
//!   idle iteration (8 dispatches with nothing to do).
//!
//! ```sh
//! cargo run --release --example bench_wavefront [-- SCENE.glb ...] [--size WxH|N] [--frames F]
//!     [--rounds R] [--depths 8,32] [--runtimes cpu,wgpu] [--ips 4,8] [--pools 65536] [--profile]
//! ```

use std::path::PathBuf;
use std::time::Instant;

use anyhow::{bail, Context, Result};
use glam::Vec3;
use tracer::backend::wavefront::{FrameProfile, WavefrontCounts, ITERATIONS_PER_SUBMISSION};
use tracer::backend::{cpu, create_scheduled, wgpu, Renderer, RendererKind, Schedule};
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

fn list<T: std::str::FromStr>(args: &[String], name: &str, default: &str) -> Result<Vec<T>> {
    flag::<String>(args, name)?
        .unwrap_or_else(|| default.into())
        .split(',')
        .map(|d| d.trim().parse().ok().with_context(|| format!("{name}: {d}")))
        .collect()
}

/// `WxH` or `N` (a square).
fn size(s: &str) -> Result<(u32, u32)> {
    let (w, h) = s.split_once('x').unwrap_or((s, s));
    Ok((w.parse().context("--size")?, h.parse().context("--size")?))
}

/// Seconds per frame over `frames` frames after a restart.
fn seconds_per_frame(r: &mut dyn Renderer, frames: u32) -> Result<f64> {
    r.restart()?;
    r.finish()?;
    let t = Instant::now();
    for _ in 0..frames {
        r.render_frame()?;
    }
    r.finish()?;
    Ok(t.elapsed().as_secs_f64() / frames as f64)
}

/// A wavefront renderer as a concrete type (for its measurement hooks).
enum Wave {
    Cpu(Box<cpu::WavefrontRenderer>),
    Wgpu(Box<wgpu::WavefrontRenderer>),
}

impl Wave {
    fn renderer(&mut self) -> &mut dyn Renderer {
        match self {
            Wave::Cpu(r) => r.as_mut(),
            Wave::Wgpu(r) => r.as_mut(),
        }
    }

    fn counts(&self) -> WavefrontCounts {
        match self {
            Wave::Cpu(r) => r.counts(),
            Wave::Wgpu(r) => r.counts(),
        }
    }

    fn profile(&mut self) -> Result<FrameProfile> {
        Ok(match self {
            Wave::Cpu(r) => r.profile_frame()?,
            Wave::Wgpu(r) => r.profile_frame()?,
        })
    }
}

fn main() -> Result<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let (width, height) = size(&flag::<String>(&args, "--size")?.unwrap_or_else(|| "160".into()))?;
    let frames: u32 = flag(&args, "--frames")?.unwrap_or(2);
    let rounds: u32 = flag(&args, "--rounds")?.unwrap_or(3);
    let depths: Vec<u32> = list(&args, "--depths", "8,32")?;
    let ips: Vec<u32> = list(&args, "--ips", &ITERATIONS_PER_SUBMISSION.to_string())?;
    let pools: Vec<u32> = list(&args, "--pools", &cpu::CPU_POOL.to_string())?;
    let profile = args.iter().any(|a| a == "--profile");
    let kinds: Vec<RendererKind> = flag::<String>(&args, "--runtimes")?
        .unwrap_or_else(|| "cpu,wgpu".into())
        .split(',')
        .map(|k| match k {
            "cpu" => Ok(RendererKind::Cpu),
            "wgpu" => Ok(RendererKind::Wgpu),
            other => bail!("--runtimes: {other} (cpu or wgpu; GL has no wavefront)"),
        })
        .collect::<Result<_>>()?;
    let values = ["--size", "--frames", "--rounds", "--depths", "--ips", "--pools", "--runtimes"];
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
    let pixels = (width * height) as f64;
    println!(
        "{width}x{height}, MIS, {frames} frames per measurement, median of {rounds} rounds (megakernel and each wavefront variant alternated)"
    );
    let mut main_rows = Vec::new();
    let mut variant_rows = Vec::new();
    let mut profile_rows = Vec::new();
    for (name, scene) in &scenes {
        let bvh = tracer::bvh::build(&scene.triangles).context("BVH")?;
        for &max_depth in &depths {
            let settings = RenderSettings { width, height, strategy: Strategy::Mis, max_depth };
            let packed: Packed = pack(scene, &bvh, &settings).context("pack")?;
            for &kind in &kinds {
                let t = Instant::now();
                let mut mega = create_scheduled(kind, Schedule::Megakernel, packed.clone(), 1)
                    .with_context(|| format!("{} megakernel", kind.name()))?;
                mega.render_frame()?;
                mega.finish()?;
                let first_mega = t.elapsed().as_secs_f64();
                // The wavefront renderers and, per variant, (label, renderer, iterations per submission).
                let mut waves = Vec::new();
                let mut variants = Vec::new();
                let mut first_wave = f64::NAN;
                match kind {
                    RendererKind::Cpu => {
                        for &pool in &pools {
                            variants.push((format!("pool {pool}"), waves.len(), 0));
                            waves.push(Wave::Cpu(Box::new(cpu::WavefrontRenderer::new(packed.clone(), 1, pool)?)));
                        }
                    }
                    _ => {
                        let t = Instant::now();
                        waves.push(Wave::Wgpu(Box::new(wgpu::WavefrontRenderer::headless(packed.clone(), 1)?)));
                        waves[0].renderer().render_frame()?;
                        waves[0].renderer().finish()?;
                        first_wave = t.elapsed().as_secs_f64();
                        for &n in &ips {
                            variants.push((format!("{n} iterations/submission"), 0, n));
                        }
                    }
                }
                if kind == RendererKind::Cpu {
                    let t = Instant::now();
                    waves[0].renderer().render_frame()?;
                    first_wave = t.elapsed().as_secs_f64();
                }
                let mut times = vec![Vec::new(); variants.len() + 1];
                let mut counts = None;
                for _ in 0..rounds {
                    times[0].push(seconds_per_frame(mega.as_mut(), frames)?);
                    for (k, (_, w, n)) in variants.iter().enumerate() {
                        if let Wave::Wgpu(r) = &mut waves[*w] {
                            r.set_iterations_per_submission(*n);
                        }
                        times[k + 1].push(seconds_per_frame(waves[*w].renderer(), frames)?);
                        if k == 0 {
                            counts = Some(waves[*w].counts());
                        }
                    }
                }
                let medians: Vec<f64> = times.into_iter().map(median).collect();
                let (m, w) = (medians[0], medians[1]);
                let c = counts.context("no wavefront variant")?;
                let f = frames as f64;
                let primary = pixels;
                let extension = c.segments as f64 / f - primary;
                let shadow = c.shadow_rays as f64 / f;
                let total = primary + extension + shadow;
                main_rows.push(format!(
                    "| {name} | {max_depth} | {} | {:.1} | {:.1} | {:.2} | {:.2} | {:.2} | {:.2} | {:.2} | {:.2} | {:.2} | {:.1} s | {:.1} s |",
                    kind.name(),
                    m * 1e3,
                    w * 1e3,
                    w / m,
                    primary / w / 1e6,
                    extension / w / 1e6,
                    shadow / w / 1e6,
                    total / w / 1e6,
                    total / m / 1e6,
                    total / pixels,
                    first_wave,
                    first_mega,
                ));
                for (k, (label, _, _)) in variants.iter().enumerate() {
                    variant_rows.push(format!(
                        "| {name} | {max_depth} | {} | {label} | {:.1} | {:.2} | {:.2} |",
                        kind.name(),
                        medians[k + 1] * 1e3,
                        medians[k + 1] / m,
                        medians[k + 1] / w
                    ));
                }
                if profile {
                    // Default variant settings back, a frame to settle, then the profiled one.
                    if let Wave::Wgpu(r) = &mut waves[0] {
                        r.set_iterations_per_submission(ips[0]);
                    }
                    waves[0].renderer().restart()?;
                    waves[0].renderer().render_frame()?;
                    let iterations = match &waves[0] {
                        Wave::Wgpu(r) => r.last_frame_iterations().to_string(),
                        Wave::Cpu(_) => "-".into(),
                    };
                    let (stages, extended) = waves[0].profile()?;
                    let pool = match &waves[0] {
                        Wave::Cpu(r) => r.paths().pool,
                        Wave::Wgpu(r) => r.pool(),
                    };
                    let tail = extended.iter().filter(|&&e| (e as f64) < pool as f64 * 0.01).count();
                    let idle = match &mut waves[0] {
                        Wave::Wgpu(r) => format!("{:.2}", r.time_idle_iterations(32)? / 32.0 * 1e3),
                        Wave::Cpu(_) => "-".into(),
                    };
                    let sum: f64 = stages.iter().map(|s| s.1).sum();
                    let cells: Vec<String> =
                        stages.iter().map(|(_, s)| format!("{:.1} ({:.0} %)", s * 1e3, s / sum * 100.0)).collect();
                    profile_rows.push(format!(
                        "| {name} | {max_depth} | {} | {pool} | {} | {iterations} | {tail} | {} | {:.1} | {:.1} | {idle} |",
                        kind.name(),
                        extended.len(),
                        cells.join(" | "),
                        sum * 1e3,
                        w * 1e3,
                    ));
                }
                // Keep the progress visible on long runs.
                eprintln!("{name} depth {max_depth} {}: done", kind.name());
            }
        }
    }
    println!(
        "\n| scene | depth | runtime | megakernel ms/frame | wavefront ms/frame | wavefront / megakernel | wavefront Mrays/s primary | extension | shadow | total | megakernel Mrays/s total (same paths) | rays per pixel | first frame, wavefront | first frame, megakernel |"
    );
    println!("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|");
    for r in &main_rows {
        println!("{r}");
    }
    println!("\n| scene | depth | runtime | wavefront variant | ms/frame | / megakernel | / first variant |");
    println!("|---|---|---|---|---|---|---|");
    for r in &variant_rows {
        println!("{r}");
    }
    if profile {
        println!(
            "\nOne frame with each stage timed on its own (wgpu: one submission per stage, waited for), ms over the frame (share):"
        );
        println!(
            "\n| scene | depth | runtime | pool | iterations (profiled) | iterations (normal frame, whole submissions) | iterations extending < 1 % of the pool | plan_generate | generate | plan_extend | extend | shade | plan_connect | connect | accumulate | sum | normal frame ms | idle iteration ms |"
        );
        println!("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|");
        for r in &profile_rows {
            println!("{r}");
        }
    }
    Ok(())
}
