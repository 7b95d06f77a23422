//! CPU backend benchmark: samples/s and rays/s on the Cornell box, LittlestTokyo and a generated
//! scene of 1.23 M triangles (`tracer::scene::terrain_and_spheres`), plus BVH build + packing
//! time. Every figure is also given as a ratio to a baseline measured in
//! the same run (the same work on one thread), so numbers from different machines compare.
//!
//! Build + pack is reported per part (BVH, textures, geometry), sequentially and with the
//! textures packed in parallel with the BVH build (`pack::build_and_pack`), the minimum of
//! several runs. "pack geometry" is also the cost of repacking after a geometry change.
//!
//! `cargo run --release --example bench_cpu [-- --quick] [--scene cornell|tokyo|generated]`

use std::time::Instant;

use glam::Vec2;
use rayon::prelude::*;
use tracer::backend::cpu::CpuRenderer;
use tracer::backend::Renderer;
use tracer::kernel::camera::camera_ray;
use tracer::kernel::intersect::MISS;
use tracer::kernel::traverse::{occluded, trace_closest};
use tracer::kernel::RenderSettings;
use tracer::pack::{build_and_pack, pack, pack_textures, pack_with_textures, Packed};

/// CPU time of every thread of this process so far, in ns (Linux `/proc/self/task/*/schedstat`).
/// On a busy machine wall times stretch with the load; CPU time much less so.
fn process_cpu_ns() -> Option<u64> {
    let mut total = 0;
    for task in std::fs::read_dir("/proc/self/task").ok()?.flatten() {
        let stat = std::fs::read_to_string(task.path().join("schedstat")).ok()?;
        total += stat.split_whitespace().next()?.parse::<u64>().ok()?;
    }
    Some(total)
}

/// Samples per wall second, and per CPU second (all threads together; `None` without /proc).
fn samples_per_second(packed: &Packed, frames: u32, threads: usize) -> (f64, Option<f64>) {
    let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().expect("thread pool");
    pool.install(|| {
        let mut r = CpuRenderer::new(packed.clone(), 1);
        r.render_frame().expect("frame"); // warm-up
        let cpu = process_cpu_ns();
        let t = Instant::now();
        for _ in 0..frames {
            r.render_frame().expect("frame");
        }
        let wall = t.elapsed().as_secs_f64();
        let cpu = cpu.zip(process_cpu_ns()).map(|(a, b)| b.saturating_sub(a) as f64 * 1e-9);
        let s = packed.scene.width as f64 * packed.scene.height as f64 * frames as f64;
        (s / wall, cpu.map(|c| s / c))
    })
}

/// Closest-hit rays/s for camera rays, and shadow (any-hit) rays/s towards the scene centre.
fn rays_per_second(packed: &Packed, n: u32, threads: usize) -> (f64, f64) {
    let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().expect("thread pool");
    let s = &packed.scene;
    let (w, h) = (s.width, s.height);
    pool.install(|| {
        let t = Instant::now();
        let hits: u32 = (0..n)
            .into_par_iter()
            .map(|i| {
                let film = Vec2::new((i % w) as f32 + 0.5, ((i / w) % h) as f32 + 0.5);
                let ray = camera_ray(s, film, Vec2::ZERO);
                (trace_closest(s, ray.origin, ray.dir, MISS).t < MISS) as u32
            })
            .sum();
        let closest = n as f64 / t.elapsed().as_secs_f64();
        let t = Instant::now();
        let blocked: u32 = (0..n)
            .into_par_iter()
            .map(|i| {
                let film = Vec2::new((i % w) as f32 + 0.5, ((i / w) % h) as f32 + 0.5);
                let ray = camera_ray(s, film, Vec2::ZERO);
                occluded(s, ray.origin, ray.dir, 1e3) as u32
            })
            .sum();
        let shadow = n as f64 / t.elapsed().as_secs_f64();
        std::hint::black_box((hits, blocked));
        (closest, shadow)
    })
}

/// Minimum wall time of `runs` calls of `f` after a warm-up call, in ms, and the last result.
/// Also the minimum CPU time of a run (all threads), in ms, as text ("-" without /proc).
fn min_ms<T>(runs: usize, mut f: impl FnMut() -> T) -> (f64, String, T) {
    let mut last = f();
    let mut best = f64::INFINITY;
    let mut best_cpu: Option<f64> = None;
    for _ in 0..runs {
        let cpu = process_cpu_ns();
        let t = Instant::now();
        last = f();
        best = best.min(t.elapsed().as_secs_f64() * 1e3);
        if let Some(used) = cpu.zip(process_cpu_ns()).map(|(a, b)| b.saturating_sub(a) as f64 * 1e-6) {
            best_cpu = Some(best_cpu.map_or(used, |b| b.min(used)));
        }
    }
    (best, best_cpu.map_or("-".into(), |c| format!("{c:.1}")), last)
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let quick = args.iter().any(|a| a == "--quick");
    // `--scene cornell`, `--scene tokyo` or `--scene generated`: only that scene (e.g. for profiling).
    let only = args.iter().position(|a| a == "--scene").and_then(|i| args.get(i + 1)).map(|s| s.to_lowercase());
    let wanted = |name: &str| only.as_ref().is_none_or(|o| name.to_lowercase().contains(o.as_str()));
    let threads = rayon::current_num_threads();
    let settings = RenderSettings { width: 256, height: 256, ..Default::default() };
    let tokyo_path = concat!(env!("CARGO_MANIFEST_DIR"), "/../shared/scenes/threejs/LittlestTokyo.glb");

    let mut scenes = Vec::new();
    if wanted("Cornell box") {
        scenes.push(("Cornell box", tracer::scene::cornell_box()));
    }
    if wanted("LittlestTokyo") {
        let t = Instant::now();
        match tracer::scene::load(std::path::Path::new(tokyo_path)) {
            Ok(s) => {
                println!("LittlestTokyo: loaded in {:.0} ms", t.elapsed().as_secs_f64() * 1e3);
                scenes.push(("LittlestTokyo", s));
            }
            Err(e) => println!("LittlestTokyo skipped: {e}"),
        }
    }
    if wanted("generated") {
        let t = Instant::now();
        let s = tracer::scene::terrain_and_spheres();
        println!("generated (terrain and spheres): made in {:.0} ms", t.elapsed().as_secs_f64() * 1e3);
        scenes.push(("generated", s));
    }

    // Build + pack: minimum of several runs after a warm-up. "sequential" is the BVH build
    // followed by a full `pack` (textures included); "parallel" is `build_and_pack` (textures
    // packed while the BVH builds); "geometry only" repacks with textures packed before.
    let runs = if quick { 2 } else { 7 };
    println!("\nwall ms (minimum of {runs} runs after a warm-up) / CPU ms of all threads (minimum)\n");
    println!("| scene | triangles | BVH build | pack textures | pack geometry | sequential build + pack | parallel build + pack | first sequential build + pack (cold) |");
    println!("|---|---|---|---|---|---|---|---|");
    for (name, scene) in &scenes {
        // The first build + pack of the scene in this process (cold caches and fresh pages).
        let t = Instant::now();
        let bvh = tracer::bvh::build(&scene.triangles).expect("BVH");
        std::hint::black_box(pack(scene, &bvh, &settings).expect("pack"));
        let cold = t.elapsed().as_secs_f64() * 1e3;
        let (build, build_cpu, bvh) = min_ms(runs, || tracer::bvh::build(&scene.triangles).expect("BVH"));
        let (textures_ms, textures_cpu, textures) = min_ms(runs, || pack_textures(scene));
        let (geometry, geometry_cpu, _) =
            min_ms(runs, || pack_with_textures(scene, &bvh, &textures, &settings).expect("pack"));
        let (sequential, sequential_cpu, _) = min_ms(runs, || {
            let bvh = tracer::bvh::build(&scene.triangles).expect("BVH");
            pack(scene, &bvh, &settings).expect("pack")
        });
        let (parallel, parallel_cpu, _) = min_ms(runs, || build_and_pack(scene, &settings).expect("build and pack"));
        println!(
            "| {name} | {} | {build:.1} / {build_cpu} | {textures_ms:.1} / {textures_cpu} | {geometry:.1} / {geometry_cpu} | {sequential:.1} / {sequential_cpu} | {parallel:.1} / {parallel_cpu} | {cold:.1} |",
            scene.triangles.len(),
        );
    }

    println!("\n| scene | samples/s ({threads} threads) | samples per CPU-second | samples/s (1 thread) | ratio | closest rays/s | shadow rays/s |");
    println!("|---|---|---|---|---|---|---|");
    for (name, scene) in &scenes {
        let (_, packed) = build_and_pack(scene, &settings).expect("build and pack");
        let frames = if quick {
            2
        } else if *name == "Cornell box" {
            32
        } else {
            8
        };
        let (multi, per_cpu_second) = samples_per_second(&packed, frames, threads);
        let (single, _) = samples_per_second(&packed, frames.div_ceil(2), 1);
        let (closest, shadow) = rays_per_second(&packed, if quick { 20_000 } else { 200_000 }, threads);
        println!(
            "| {name} | {:.2} M | {} | {:.2} M | {:.2}x | {:.2} M | {:.2} M |",
            multi / 1e6,
            per_cpu_second.map_or("-".into(), |s| format!("{:.2} M", s / 1e6)),
            single / 1e6,
            multi / single,
            closest / 1e6,
            shadow / 1e6
        );
    }
}
