//! A table of equivalence per kernel function, one column group per runtime (GL, wgpu, and in
//! headless Chromium WebGL2 and WebGPU) against the CPU: the largest ULP and absolute differences, invocations out of the stated tolerance,
//! and the time each runtime took (same run; the GPU runtimes include upload and readback).
//!
//! `cargo run --release --example equivalence_report [RAYS]` (RAYS: LittlestTokyo traversal
//! rays, default 100000). The pass/fail checks are in `tests/equivalence.rs`; this prints the
//! figures.

use std::path::Path;

use anyhow::{Context, Result};
use glam::{Vec2, Vec3};
use tracer::backend::harness::{Backend, Equivalence, GlHarness, Outcome, Tolerance, WgpuHarness};
use tracer::kernel::intersect::{self, MISS};
use tracer::kernel::RenderSettings;
use tracer::kernel::{rng, sampling, textures, traverse};
use tracer::pack::pack;

/// Test inputs: xorshift64*, independent of the kernel's RNG.
struct Inputs(u64);

impl Inputs {
    fn u32(&mut self) -> u32 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        (self.0.wrapping_mul(0x2545_f491_4f6c_dd1d) >> 32) as u32
    }

    fn unit(&mut self) -> f32 {
        (self.u32() >> 8) as f32 / 16_777_216.0
    }

    fn in_box(&mut self, lo: Vec3, hi: Vec3) -> Vec3 {
        lo + (hi - lo) * Vec3::new(self.unit(), self.unit(), self.unit())
    }
}

fn row<O>(outcome: &Outcome<O>) {
    let seconds = |b| outcome.seconds.iter().find(|(x, _)| *x == b).map_or(f64::NAN, |(_, s)| *s);
    let Some(first) = outcome.comparisons.first() else { return };
    let mut line = format!("| {:<25} | {:>9} | {:>7.3} |", outcome.function, first.invocations, seconds(Backend::Cpu));
    for backend in Backend::GPU {
        match outcome.comparison(backend) {
            Some(c) => line.push_str(&format!(
                " {:>6} | {:>8.1e} | {:>6} | {:>7.3} |",
                c.max_ulps,
                c.max_abs,
                c.mismatched.len(),
                seconds(backend)
            )),
            None => line.push_str(" - | - | - | - |"),
        }
    }
    println!("{line} {} |", first.tolerance);
}

fn main() -> Result<()> {
    let rays: usize =
        std::env::args().nth(1).map(|a| a.parse()).transpose().context("RAYS must be a number")?.unwrap_or(100_000);
    let backends = [Backend::Cpu, Backend::Gl, Backend::Wgpu, Backend::WebGl2, Backend::WebGpu];
    let mut eq = Equivalence::new(&backends, &[]).context(
        "creating the CPU, GL, wgpu, WebGL2 and WebGPU runtimes (the browser ones need Chromium, \
         `npm ci` in tests/web and scripts/build-web.sh)",
    )?;
    let info = eq.runtime::<GlHarness>().map(|g| g.limits()).context("the GL runtime")?;
    println!("GL limits: {info:?}");
    let adapter = eq.runtime::<WgpuHarness>().map(|w| w.device().info.clone()).context("the wgpu runtime")?;
    println!("wgpu: {} ({}, {})", adapter.adapter, adapter.driver, adapter.backend);
    for backend in [Backend::WebGl2, Backend::WebGpu] {
        println!("{backend}: {}", eq.browser(backend).map(|b| b.info().to_string()).context("a browser runtime")?);
    }
    let mut header = "| function | invocations | CPU s |".to_string();
    for backend in Backend::GPU {
        header.push_str(&format!(" {backend} max ULP | {backend} max abs | {backend} beyond | {backend} s |"));
    }
    println!("{header} tolerance |");
    println!("|---|---:|---:|{}---|", "---:|".repeat(4 * Backend::GPU.len()));
    let mut r = Inputs(0x1234_5678_9abc_def1);

    let seeds: Vec<(u32,)> = (0..1u32 << 20).map(|_| (r.u32(),)).collect();
    row(&eq.run("wang_hash", &seeds, |_, &(s,)| (rng::wang_hash(s),), Tolerance::EXACT)?);
    let random = |_: &_, &(s,): &(u32,)| {
        let mut state = s;
        (rng::random_float(&mut state), state)
    };
    row(&eq.run("random_float", &seeds, random, Tolerance::EXACT)?);

    let uniforms: Vec<(f32, f32)> = (0..1 << 16).map(|_| (r.unit(), r.unit())).collect();
    let sampling_tolerance = Tolerance::ulps(16).with_absolute(2e-6).flushing_subnormals();
    row(&eq.run(
        "cosine_sample_hemisphere",
        &uniforms,
        |_, &(a, b)| (sampling::cosine_sample_hemisphere(a, b),),
        sampling_tolerance,
    )?);
    let normals: Vec<(Vec3, f32, f32)> =
        uniforms.iter().map(|&(a, b)| (r.in_box(Vec3::splat(-1.0), Vec3::ONE).normalize(), a, b)).collect();
    row(&eq.run(
        "sample_cosine_around",
        &normals,
        |_, &(n, a, b)| (sampling::sample_cosine_around(n, a, b),),
        sampling_tolerance,
    )?);

    let triangles: Vec<(Vec3, Vec3, Vec3, Vec3, Vec3)> = (0..1 << 17)
        .map(|_| {
            let v0 = r.in_box(Vec3::splat(-1.0), Vec3::ONE);
            let o = r.in_box(Vec3::splat(-2.0), Vec3::splat(2.0));
            let d = (r.in_box(Vec3::splat(-1.0), Vec3::ONE) - o).normalize();
            (
                o,
                d,
                v0,
                v0 + r.in_box(Vec3::splat(-0.5), Vec3::splat(0.5)),
                v0 + r.in_box(Vec3::splat(-0.5), Vec3::splat(0.5)),
            )
        })
        .collect();
    let triangle_tolerance = Tolerance::ulps(16).flushing_subnormals();
    row(&eq.run(
        "intersect_triangle",
        &triangles,
        |_, &(o, d, a, b, c)| (intersect::intersect_triangle(o, d, a, b, c),),
        triangle_tolerance,
    )?);
    let boxes: Vec<(Vec3, Vec3, Vec3, Vec3, f32)> =
        triangles.iter().map(|&(o, d, a, b, _)| (o, intersect::safe_inverse(d), a.min(b), a.max(b), MISS)).collect();
    row(&eq.run(
        "intersect_aabb",
        &boxes,
        |_, &(o, i, lo, hi, t)| (intersect::intersect_aabb(o, i, lo, hi, t),),
        Tolerance::ulps(4).flushing_subnormals(),
    )?);

    let tokyo = Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/scenes/threejs/LittlestTokyo.glb");
    let scene = tracer::scene::load(&tokyo).with_context(|| format!("loading {}", tokyo.display()))?;
    let bvh = tracer::bvh::build(&scene.triangles)?;
    let packed = pack(&scene, &bvh, &RenderSettings::default())?;
    eq.set_scene(&packed.scene)?;
    let b = scene.bounds();
    let (lo, hi) = (b.min - b.diagonal() * 0.1, b.max + b.diagonal() * 0.1);
    let rays: Vec<(Vec3, Vec3, f32)> = (0..rays)
        .map(|_| {
            let o = r.in_box(lo, hi);
            (o, (r.in_box(b.min, b.max) - o).normalize(), MISS)
        })
        .collect();
    let closest =
        eq.run("trace_closest", &rays, |s, &(o, d, t)| (traverse::trace_closest(s, o, d, t),), triangle_tolerance)?;
    row(&closest);
    let cpu = closest.output(Backend::Cpu).unwrap_or(&[]);
    let other_triangle = Backend::GPU.map(|b| {
        let gpu = closest.output(b).unwrap_or(&[]);
        (b, cpu.iter().zip(gpu).filter(|((a,), (b,))| a.triangle != b.triangle).count())
    });
    row(&eq.run("occluded", &rays, |s, &(o, d, t)| (traverse::occluded(s, o, d, t),), Tolerance::EXACT)?);

    let duck = Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/scenes/khronos/Duck/glTF-Binary/Duck.glb");
    let scene = tracer::scene::load(&duck).with_context(|| format!("loading {}", duck.display()))?;
    let packed = pack(&scene, &tracer::bvh::build(&scene.triangles)?, &RenderSettings::default())?;
    eq.set_scene(&packed.scene)?;
    let lookups: Vec<(u32, Vec2)> =
        (0..1 << 16).map(|_| (0, Vec2::new(r.unit() * 3.0 - 1.0, r.unit() * 3.0 - 1.0))).collect();
    row(&eq.run(
        "sample_texture",
        &lookups,
        |s, &(i, uv)| (textures::sample_texture(s, i, uv),),
        Tolerance::ulps(16).flushing_subnormals(),
    )?);

    for (backend, n) in other_triangle {
        println!("\ntrace_closest: {n} of {} rays hit a different triangle on {backend}", rays.len());
    }
    println!("(timings: one run on a shared machine; compare backends within this run only)");
    Ok(())
}
