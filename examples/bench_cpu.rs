//! CPU backend benchmark: samples/s and rays/s on the Cornell box and LittlestTokyo, plus
//! BVH build + packing time. Every figure is also given as a ratio to a baseline measured in
//! the same run (the same work on one thread), so numbers from different machines compare.
//!
//! `cargo run --release --example bench_cpu [-- --quick]`

use std::time::Instant;

use glam::{Vec2, Vec3};
use rayon::prelude::*;
use tracer::backend::cpu::CpuRenderer;
use tracer::kernel::camera::camera_ray;
use tracer::kernel::intersect::MISS;
use tracer::kernel::traverse::{occluded, trace_closest};
use tracer::pack::{pack, Packed, RenderSettings};

fn samples_per_second(packed: &Packed, frames: u32, threads: usize) -> f64 {
    let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().expect("thread pool");
    pool.install(|| {
        let mut r = CpuRenderer::new(packed.clone(), 1);
        r.render_frame(); // warm-up
        let t = Instant::now();
        for _ in 0..frames {
            r.render_frame();
        }
        let s = packed.scene.width as f64 * packed.scene.height as f64 * frames as f64;
        s / t.elapsed().as_secs_f64()
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

fn main() {
    let quick = std::env::args().any(|a| a == "--quick");
    let threads = rayon::current_num_threads();
    let settings = RenderSettings { width: 256, height: 256, ..Default::default() };
    let tokyo_path = concat!(env!("CARGO_MANIFEST_DIR"), "/../shared/scenes/threejs/LittlestTokyo.glb");

    let mut scenes = vec![("Cornell box", tracer::scene::cornell_box())];
    let t = Instant::now();
    match tracer::scene::load(std::path::Path::new(tokyo_path)) {
        Ok(s) => {
            println!("LittlestTokyo: loaded in {:.0} ms", t.elapsed().as_secs_f64() * 1e3);
            scenes.push(("LittlestTokyo", s));
        }
        Err(e) => println!("LittlestTokyo skipped: {e}"),
    }

    println!("\n| scene | triangles | BVH build | pack | samples/s ({threads} threads) | samples/s (1 thread) | ratio | closest rays/s | shadow rays/s |");
    println!("|---|---|---|---|---|---|---|---|---|");
    for (name, scene) in &scenes {
        let t = Instant::now();
        let bvh = tracer::bvh::build(&scene.triangles).expect("BVH");
        let build = t.elapsed().as_secs_f64() * 1e3;
        let t = Instant::now();
        let packed = pack(scene, &bvh, &settings).expect("pack");
        let pack_ms = t.elapsed().as_secs_f64() * 1e3;
        let frames = if quick {
            2
        } else if *name == "Cornell box" {
            32
        } else {
            8
        };
        let multi = samples_per_second(&packed, frames, threads);
        let single = samples_per_second(&packed, frames.div_ceil(2), 1);
        let (closest, shadow) = rays_per_second(&packed, if quick { 20_000 } else { 200_000 }, threads);
        println!(
            "| {name} | {} | {build:.1} ms | {pack_ms:.1} ms | {:.2} M | {:.2} M | {:.2}x | {:.2} M | {:.2} M |",
            scene.triangles.len(),
            multi / 1e6,
            single / 1e6,
            multi / single,
            closest / 1e6,
            shadow / 1e6
        );
        std::hint::black_box(Vec3::ZERO);
    }
}
