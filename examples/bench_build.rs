//! BVH build benchmark: `cargo run --release --example bench_build [-- --quick]`
//!
//! Loads LittlestTokyo (141,802 triangles) and generates a scene of 1.23 M triangles
//! (`tracer::scene::terrain_and_spheres`), then
//! builds BVHs with a plain median-split builder (the baseline, written here) and obvhs'
//! presets, printing build time, size, SAH cost and a CPU ray-cast rate with the reference
//! traversal. Ratios are against the median-split baseline measured in the same run. The
//! default builder is also timed on one thread (the example re-runs itself with
//! `RAYON_NUM_THREADS=1`, since obvhs builds on rayon's global pool).
//!
//! Times are the minimum and the median of several builds after a warm-up, plus the CPU time
//! per build summed over all threads (Linux `/proc/self/task/*/schedstat`): on a busy machine
//! the minimum and the CPU time are the numbers to trust.

use std::path::Path;
use std::time::{Duration, Instant};

use anyhow::Context;
use glam::Vec3;
use tracer::bvh::{self, BuildOptions, BuildQuality, Bvh, BvhNode};
use tracer::scene::{self, Aabb, Camera, Triangle};

const CHILD_FLAG: &str = "--default-builder-only";

fn main() -> anyhow::Result<()> {
    let quick = std::env::args().any(|a| a == "--quick");
    let child = std::env::args().any(|a| a == CHILD_FLAG);
    let runs = if quick { 1 } else { 5 };

    let path = Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../shared/scenes/threejs/LittlestTokyo.glb"));
    let t0 = Instant::now();
    let tokyo = scene::load(path).with_context(|| format!("loading {}", path.display()))?;
    let tokyo_load = t0.elapsed();

    let t0 = Instant::now();
    let generated = scene::terrain_and_spheres();
    let (big, big_camera) = (generated.triangles, generated.camera);
    let big_gen = t0.elapsed();

    if child {
        // One line per scene: the default builder's minimum time in ms.
        for (tris, runs) in [(&tokyo.triangles, runs), (&big, runs.min(3))] {
            println!("{:.3}", ms(time_runs(runs, &|| bvh::build(tris).expect("build")).0.min));
        }
        return Ok(());
    }
    let single = single_thread_times(quick);
    let threads = std::thread::available_parallelism().map_or(1, |n| n.get());
    println!("# BVH build benchmark ({threads} hardware threads)");
    bench("LittlestTokyo", &tokyo.triangles, &tokyo.camera, tokyo_load, "load", runs, single.first().copied());
    bench("generated", &big, &big_camera, big_gen, "generate", runs.min(3), single.get(1).copied());
    Ok(())
}

/// Runs this example again on one rayon thread and reads the default builder's times.
fn single_thread_times(quick: bool) -> Vec<f64> {
    let Ok(exe) = std::env::current_exe() else { return Vec::new() };
    let mut cmd = std::process::Command::new(exe);
    cmd.arg(CHILD_FLAG).env("RAYON_NUM_THREADS", "1");
    if quick {
        cmd.arg("--quick");
    }
    match cmd.output() {
        Ok(out) if out.status.success() => {
            String::from_utf8_lossy(&out.stdout).lines().filter_map(|l| l.trim().parse().ok()).collect()
        }
        _ => Vec::new(),
    }
}

/// Wall and CPU time of some runs.
#[derive(Clone, Copy)]
struct Timing {
    min: Duration,
    median: Duration,
    /// CPU time per run, all threads together (None where /proc is unavailable).
    cpu: Option<Duration>,
}

/// Times `runs` calls after one warm-up call (allocator, page faults, rayon pool start);
/// returns the timing and the last result.
fn time_runs<T>(runs: usize, f: &dyn Fn() -> T) -> (Timing, T) {
    let mut last = f();
    let mut times = Vec::new();
    let cpu0 = process_cpu_ns();
    for _ in 0..runs.max(1) {
        let t0 = Instant::now();
        last = f();
        times.push(t0.elapsed());
    }
    let cpu = cpu0.zip(process_cpu_ns()).map(|(a, b)| Duration::from_nanos(b.saturating_sub(a) / times.len() as u64));
    times.sort();
    (Timing { min: times[0], median: times[times.len() / 2], cpu }, last)
}

/// CPU time of every thread of this process so far, in ns (Linux).
fn process_cpu_ns() -> Option<u64> {
    let mut total = 0;
    for task in std::fs::read_dir("/proc/self/task").ok()?.flatten() {
        let stat = std::fs::read_to_string(task.path().join("schedstat")).ok()?;
        total += stat.split_whitespace().next()?.parse::<u64>().ok()?;
    }
    Some(total)
}

struct Row {
    name: String,
    build: Timing,
    bvh: Bvh,
    mrays: f64,
}

fn bench(
    scene_name: &str,
    tris: &[Triangle],
    camera: &Camera,
    prep: Duration,
    prep_name: &str,
    runs: usize,
    single_thread_ms: Option<f64>,
) {
    println!(
        "\n## {scene_name}: {} triangles ({prep_name} {:.1} ms); builds timed {runs}x after a warm-up\n",
        tris.len(),
        ms(prep)
    );
    let mut rows: Vec<Row> = Vec::new();
    let mut measure = |name: &str, build: &dyn Fn() -> Bvh| {
        let (time, bvh) = time_runs(runs, build);
        if let Err(e) = bvh.validate(tris) {
            panic!("{name}: invalid BVH: {e}");
        }
        let mrays = trace_rate(&bvh, tris, camera);
        rows.push(Row { name: name.to_owned(), build: time, bvh, mrays });
    };
    measure("median split, leaf <= 4 (baseline)", &|| median_split(tris, 4));
    let presets = [
        ("obvhs fastest, leaf <= 4", BuildQuality::Fastest, 4, 1.5),
        ("obvhs fast, leaf <= 4 (default)", BuildQuality::Fast, 4, 1.5),
        ("obvhs fast, leaf <= 8, cost 3", BuildQuality::Fast, 8, 3.0),
        ("obvhs medium, leaf <= 4", BuildQuality::Medium, 4, 1.5),
        ("obvhs slow, leaf <= 4", BuildQuality::Slow, 4, 1.5),
    ];
    for (name, quality, max_leaf_size, traversal_cost) in presets {
        let options = BuildOptions { quality, max_leaf_size, traversal_cost };
        measure(name, &|| bvh::build_with(tris, &options).expect("build"));
    }

    let base = &rows[0];
    println!(
        "| builder | build ms min | median | CPU ms | Mtri/s | x baseline speed | nodes | tris/leaf | depth | SAH cost | x baseline SAH | Mrays/s (ref. CPU, 1 thread) |"
    );
    println!("|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|");
    for r in &rows {
        let leaves = r.bvh.leaf_count();
        println!(
            "| {} | {:.1} | {:.1} | {} | {:.2} | {:.2} | {} | {:.2} | {} | {:.1} | {:.2} | {:.2} |",
            r.name,
            ms(r.build.min),
            ms(r.build.median),
            r.build.cpu.map_or("-".to_owned(), |c| format!("{:.1}", ms(c))),
            tris.len() as f64 / r.build.min.as_secs_f64() / 1e6,
            base.build.min.as_secs_f64() / r.build.min.as_secs_f64(),
            r.bvh.nodes.len(),
            tris.len() as f64 / leaves as f64,
            r.bvh.depth(),
            r.bvh.sah_cost(),
            r.bvh.sah_cost() / base.bvh.sah_cost(),
            r.mrays
        );
    }
    if let (Some(one), Some(default)) = (single_thread_ms, rows.get(2)) {
        println!(
            "\ndefault builder on 1 thread: {one:.1} ms min ({:.2}x faster with all threads)",
            one / ms(default.build.min)
        );
    }
}

fn ms(d: Duration) -> f64 {
    d.as_secs_f64() * 1e3
}

/// Primary rays (256 x 192) through the camera, closest hit with the reference traversal, on
/// one thread. Millions of rays per second: a rough traversal-quality signal (the kernel's
/// traversal is another code).
fn trace_rate(bvh: &Bvh, tris: &[Triangle], camera: &Camera) -> f64 {
    let (w, h) = (256u32, 192u32);
    let forward = camera.forward();
    let right = forward.cross(camera.up).normalize();
    let up = right.cross(forward);
    let tan = (camera.yfov * 0.5).tan();
    let t0 = Instant::now();
    let hits: usize = (0..w * h)
        .filter(|&i| {
            let (x, y) = ((i % w) as f32 + 0.5, (i / w) as f32 + 0.5);
            let sx = (2.0 * x / w as f32 - 1.0) * tan * w as f32 / h as f32;
            let sy = (1.0 - 2.0 * y / h as f32) * tan;
            let dir = (forward + sx * right + sy * up).normalize();
            bvh.intersect_closest(tris, camera.position, dir, f32::INFINITY).is_some()
        })
        .count();
    let rate = f64::from(w * h) / t0.elapsed().as_secs_f64() / 1e6;
    std::hint::black_box(hits);
    rate
}

/// The baseline: top-down, split at the median centroid along the widest centroid axis.
fn median_split(tris: &[Triangle], max_leaf: usize) -> Bvh {
    let bounds = |t: &Triangle| {
        let mut b = Aabb::EMPTY;
        t.positions.iter().for_each(|p| b.extend(*p));
        b
    };
    let centroid = |t: &Triangle| (t.positions[0] + t.positions[1] + t.positions[2]) / 3.0;
    let mut order: Vec<u32> = (0..tris.len() as u32).collect();
    let leaf = BvhNode { min: Vec3::ZERO, max: Vec3::ZERO, first: 0, count: 0 };
    let mut nodes = vec![leaf];
    let mut stack = vec![(0usize, 0usize, tris.len())];
    while let Some((node, lo, hi)) = stack.pop() {
        let mut b = Aabb::EMPTY;
        let mut cb = Aabb::EMPTY;
        for &i in &order[lo..hi] {
            let t = &tris[i as usize];
            let tb = bounds(t);
            b.extend(tb.min);
            b.extend(tb.max);
            cb.extend(centroid(t));
        }
        if hi - lo <= max_leaf {
            nodes[node] = BvhNode { min: b.min, max: b.max, first: lo as u32, count: (hi - lo) as u32 };
            continue;
        }
        let axis = cb.diagonal().max_position();
        let mid = (lo + hi) / 2;
        order[lo..hi].select_nth_unstable_by(mid - lo, |&a, &b| {
            centroid(&tris[a as usize])[axis].total_cmp(&centroid(&tris[b as usize])[axis])
        });
        let child = nodes.len();
        nodes.push(leaf);
        nodes.push(leaf);
        nodes[node] = BvhNode { min: b.min, max: b.max, first: child as u32, count: 0 };
        stack.push((child + 1, mid, hi));
        stack.push((child, lo, mid));
    }
    Bvh { nodes, triangle_order: order }
}
