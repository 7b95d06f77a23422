//! CPU, GL and wgpu backend throughput (samples per second), measured in the same run on the same
//! packed scenes, printed as a table of medians and ratios; the CPU and wgpu each under both
//! schedules (the megakernel and the wavefront, `docs/wavefront.md`).
//!
//! ```sh
//! cargo run --release --example bench_backends [-- FRAMES] [--size N] [--rounds R]
//! ```
//!
//! Every renderer is created once and renders one untimed warm-up frame (drivers compile their
//! shaders on the first draw). Then R rounds (default 5) time FRAMES frames (default 8) on each
//! renderer of each scene, waiting for the device before and after; the order of the renderers
//! rotates from round to round, so that a noisy neighbour on a shared machine hits every column
//! and every row alike. The table gives each renderer's median and the ratios of medians. Each
//! runtime's wavefront renderer is created right after its megakernel, so every round measures
//! the two back to back (A/B, the order alternating with the rotation).
//!
//! `--size N` renders both scenes at NxN (default: the Cornell box at 256x256, LittlestTokyo at
//! 128x128; a GPU wants more pixels per dispatch to be busy, e.g. `--size 1024`).
//!
//! Rows: the Cornell box, LittlestTokyo under a uniform white sky as shipped (alpha-masked
//! materials) and the same made opaque (every `alphaMode` MASK and BLEND dropped: the same
//! geometry and BVH), so that the second table, the cost of masks per runtime (opaque / masked
//! samples per second), is measured in one run. Two more rows split that cost: masks without
//! holes (cutoff 0: the opaque scene's light paths, every hole test run) and the same with no
//! triangle flagged as masked (the hole test compiled into traversal but never run).
//!
//! Columns beyond the backends:
//! - **CPU wavefront, wgpu wavefront** (`Schedule::Wavefront`) and **wavefront / megakernel**:
//!   the ratio of the wavefront's samples per second to its runtime's megakernel's (above 1: the
//!   wavefront is faster). GL has no wavefront (no compute).
//! - **sized / 64**: the kernel with its traversal stack sized to the scene (`Features::
//!   traversal_stack`, a specialisation constant) against the same kernel with 64 entries, on
//!   GL and on wgpu.
//! - **GL, leaves at once / pushed**: `leaf_stack_limit` 0, i.e. `trace_closest` intersects every
//!   leaf as soon as its node is hit instead of pushing it (the traversal order `tracer::pack`
//!   falls back to for trees whose leaves would not fit the stack).

use std::path::Path;
use std::time::Instant;

use anyhow::{Context, Result};
use tracer::backend::{create_scheduled, Renderer, RendererKind, Schedule};
use tracer::kernel::{RenderSettings, Strategy};
use tracer::pack::{pack, Packed};

/// Renders `frames` frames and returns samples per second; waits for the device first.
fn samples_per_second(r: &mut dyn Renderer, frames: u32) -> Result<f64> {
    r.finish()?;
    let t = Instant::now();
    for _ in 0..frames {
        r.render_frame()?;
    }
    r.finish()?;
    let seconds = t.elapsed().as_secs_f64();
    let p = r.packed();
    Ok(frames as f64 * p.scene.width as f64 * p.scene.height as f64 / seconds)
}

/// A renderer that dropped non-finite samples measured something else than the kernel.
fn check(r: &dyn Renderer) -> Result<()> {
    let rejected = r.rejected_samples()?;
    anyhow::ensure!(rejected == 0, "the {} backend dropped {rejected} non-finite samples", r.describe().runtime);
    Ok(())
}

/// The columns, in the order renderers are created (a wavefront right after its megakernel).
const COLUMNS: [&str; 8] = [
    "CPU",
    "CPU, wavefront",
    "GL",
    "GL, 64-entry stack",
    "GL, leaves at once",
    "wgpu",
    "wgpu, wavefront",
    "wgpu, 64-entry stack",
];

fn renderers(p: &Packed) -> Result<Vec<Box<dyn Renderer>>> {
    let mut stack_64 = p.clone();
    stack_64.features.traversal_stack = 0; // no specialisation: the kernel's own 64 entries
    let mut at_once = p.clone();
    at_once.scene.leaf_stack_limit = 0;
    let (mega, wave) = (Schedule::Megakernel, Schedule::Wavefront);
    [
        (RendererKind::Cpu, mega, p.clone()),
        (RendererKind::Cpu, wave, p.clone()),
        (RendererKind::Gl, mega, p.clone()),
        (RendererKind::Gl, mega, stack_64.clone()),
        (RendererKind::Gl, mega, at_once),
        (RendererKind::Wgpu, mega, p.clone()),
        (RendererKind::Wgpu, wave, p.clone()),
        (RendererKind::Wgpu, mega, stack_64),
    ]
    .into_iter()
    .map(|(kind, schedule, packed)| {
        create_scheduled(kind, schedule, packed, 0).with_context(|| format!("{} {}", kind.name(), schedule.name()))
    })
    .collect()
}

/// One scene's medians, by column.
struct Medians {
    cpu: f64,
    cpu_wave: f64,
    gl: f64,
    gl_64: f64,
    gl_at_once: f64,
    wgpu: f64,
    wgpu_wave: f64,
    wgpu_64: f64,
}

impl Medians {
    fn of(m: &[f64]) -> Medians {
        let [cpu, cpu_wave, gl, gl_64, gl_at_once, wgpu, wgpu_wave, wgpu_64] = m[..] else {
            unreachable!("one median per column")
        };
        Medians { cpu, cpu_wave, gl, gl_64, gl_at_once, wgpu, wgpu_wave, wgpu_64 }
    }
}

/// Median samples per second of each renderer over `rounds` rotated rounds.
fn measure(renderers: &mut [Box<dyn Renderer>], frames: u32, rounds: usize) -> Result<Vec<f64>> {
    for r in renderers.iter_mut() {
        samples_per_second(r.as_mut(), 1)?; // warm-up: shader compilation, first uploads
    }
    let n = renderers.len();
    let mut samples = vec![Vec::with_capacity(rounds); n];
    for round in 0..rounds {
        for k in 0..n {
            let i = (round + k) % n;
            samples[i].push(samples_per_second(renderers[i].as_mut(), frames)?);
        }
    }
    for r in renderers.iter() {
        check(r.as_ref())?;
    }
    Ok(samples.into_iter().map(median).collect())
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

fn packed(scene: &tracer::scene::Scene, size: u32) -> Result<Packed> {
    let bvh = tracer::bvh::build(&scene.triangles).context("BVH")?;
    let settings = RenderSettings { width: size, height: size, strategy: Strategy::Mis, max_depth: 8 };
    Ok(pack(scene, &bvh, &settings)?)
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
    let size = value_of(&args, "--size")?;
    let rounds = value_of(&args, "--rounds")?.unwrap_or(5).max(1) as usize;
    let frames: u32 =
        args.first().filter(|a| !a.starts_with("--")).map(|a| a.parse()).transpose().context("FRAMES")?.unwrap_or(8);
    let tokyo = Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/scenes/threejs/LittlestTokyo.glb");
    let mut tokyo = tracer::scene::load(&tokyo).context("loading LittlestTokyo")?;
    // Under a white sky, as a user first renders it (`--sky white.hdr`): the scene has few lights.
    tokyo.sky = Some(tracer::scene::Sky::uniform(glam::Vec3::ONE));
    let mut opaque = tokyo.clone();
    for m in &mut opaque.materials {
        m.alpha_cutoff = None;
    }
    // The masked kernel and data, but a cutoff of 0 leaves no holes: the same light paths as
    // the opaque scene, so that the mask cost splits into the test itself and the longer paths.
    let mut no_holes = tokyo.clone();
    for m in &mut no_holes.materials {
        m.alpha_cutoff = m.alpha_cutoff.map(|_| 0.0);
    }
    let tokyo_size = size.unwrap_or(128);
    let scenes = [
        ("Cornell box", tracer::scene::cornell_box(), size.unwrap_or(256), false),
        ("LittlestTokyo", tokyo, tokyo_size, false),
        ("LittlestTokyo, opaque", opaque, tokyo_size, false),
        ("LittlestTokyo, masked without holes", no_holes.clone(), tokyo_size, false),
        ("LittlestTokyo, masked, no triangle flagged", no_holes, tokyo_size, true),
    ];
    // Every renderer of every scene in one rotation, so that noise on a shared machine hits
    // the scenes alike (the mask cost below compares two of them).
    let mut rows = Vec::new();
    let mut all: Vec<Box<dyn Renderer>> = Vec::new();
    for (name, scene, size, unflag) in scenes {
        let mut p = packed(&scene, size)?;
        if unflag {
            // The masked kernel and data, but no triangle says it is masked: the hole test is
            // compiled into traversal and never runs.
            let t = p.scene.triangles.as_slice().to_vec();
            p.scene.triangles = kernel_dsl::Texels::from_fn(t.len(), |i| {
                let mut texel = t[i];
                if i % tracer::kernel::scene_data::TRIANGLE_TEXELS as usize == 2 {
                    texel.w = 0.0;
                }
                texel
            });
        }
        all.extend(renderers(&p)?);
        rows.push((name, size, p.triangle_count, p.features.traversal_stack));
    }
    // Each runtime's device, once: "cpu: 2 threads; gl: llvmpipe (...); wgpu: llvmpipe (...) (Vulkan)".
    let mut described: Vec<String> = Vec::new();
    for r in &all {
        let info = r.describe();
        let line = format!("{}: {}", info.runtime, info.device);
        if !described.contains(&line) {
            described.push(line);
        }
    }
    let devices = described.join("; ");
    let medians = measure(&mut all, frames, rounds)?;
    let table: Vec<_> = rows
        .into_iter()
        .zip(medians.chunks(COLUMNS.len()))
        .map(|((name, size, triangles, stack), m)| (name, size, triangles, stack, Medians::of(m)))
        .collect();
    println!("{frames} frames x {rounds} rounds (medians), MIS, max depth 8; {devices}");
    println!("columns: {}", COLUMNS.join(", "));
    println!(
        "| scene | size | triangles | stack | CPU Ms/s | CPU wavefront Ms/s | GL Ms/s | wgpu Ms/s | wgpu wavefront Ms/s \
         | CPU wavefront / megakernel | wgpu wavefront / megakernel | GL / CPU | wgpu / CPU | wgpu / GL \
         | GL sized / 64 | wgpu sized / 64 | GL leaves at once / pushed |"
    );
    println!("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|");
    for (name, size, triangles, stack, m) in &table {
        let (size, triangles, stack) = (*size, *triangles, *stack);
        println!(
            "| {name} | {size}x{size} | {triangles} | {stack} | {:.3} | {:.3} | {:.3} | {:.3} | {:.3} | {:.2} | {:.2} \
             | {:.2} | {:.2} | {:.2} | {:.2} | {:.2} | {:.2} |",
            m.cpu / 1e6,
            m.cpu_wave / 1e6,
            m.gl / 1e6,
            m.wgpu / 1e6,
            m.wgpu_wave / 1e6,
            m.cpu_wave / m.cpu,
            m.wgpu_wave / m.wgpu,
            m.gl / m.cpu,
            m.wgpu / m.cpu,
            m.wgpu / m.gl,
            m.gl / m.gl_64,
            m.wgpu / m.wgpu_64,
            m.gl_at_once / m.gl,
        );
    }
    // The cost of alpha masks per runtime, and where it goes.
    let [masked, opaque, no_holes, unflagged] = [&table[1].4, &table[2].4, &table[3].4, &table[4].4];
    let row = |what: &str, a: &Medians, b: &Medians| {
        println!(
            "| {what} | {:.2} | {:.2} | {:.2} | {:.2} | {:.2} |",
            a.cpu / b.cpu,
            a.cpu_wave / b.cpu_wave,
            a.gl / b.gl,
            a.wgpu / b.wgpu,
            a.wgpu_wave / b.wgpu_wave
        );
    };
    println!(
        "\n| LittlestTokyo, cost of masks (ratio of samples per second) | CPU | CPU wavefront | GL | wgpu | wgpu wavefront |"
    );
    println!("|---|---|---|---|---|---|");
    row("as shipped: opaque / masked", opaque, masked);
    row("the paths through holes: masked without holes / masked", no_holes, masked);
    row("the hole tests run: no triangle flagged / masked without holes", unflagged, no_holes);
    row("the masked code present: opaque / no triangle flagged", opaque, unflagged);
    Ok(())
}
