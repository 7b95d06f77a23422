//! Two levels against one (issue 28): memory, render speed and top-level build time, measured
//! in the same run and printed as tables of medians and ratios.
//!
//! ```sh
//! cargo run --release --example bench_instancing [-- --size N] [--frames F] [--rounds R]
//! ```
//!
//! Rows: `tracer::scene::instanced_shapes(g)` (one ~1,000-triangle mesh placed g x g times,
//! rotated, scaled non-uniformly, a third mirrored, over a static floor and light) for several
//! g, and the same placements pushed together until their boxes overlap. Each row is packed
//! twice from the same triangles: two levels (as loaded) and flattened (`Scene::bake_instances`).
//! Columns: packed geometry bytes (triangles, shading, nodes), and samples per second on the
//! CPU, GL and wgpu of each, the order alternating from round to round; the ratio two levels /
//! flattened says what the second level costs per sample.
//!
//! Last table: the top level's build (PLOC over the placements' boxes, widened), what a frame
//! in which something moves has to redo, for 1,000, 10,000 and 100,000 placements.

use std::time::Instant;

use anyhow::{Context, Result};
use glam::Vec3;
use tracer::backend::{create, Renderer, RendererKind};
use tracer::kernel::{RenderSettings, Strategy};
use tracer::pack::{build_and_pack, top_level, Packed};
use tracer::scene::{instanced_shapes, Scene};

fn samples_per_second(r: &mut dyn Renderer, frames: u32) -> Result<f64> {
    r.finish()?;
    let t = Instant::now();
    for _ in 0..frames {
        r.render_frame()?;
    }
    r.finish()?;
    let p = r.packed();
    Ok(frames as f64 * p.scene.width as f64 * p.scene.height as f64 / t.elapsed().as_secs_f64())
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

/// Bytes of the packed geometry (`Packed::arrays`): triangles, shading data, nodes (and
/// placements), children.
fn geometry_bytes(p: &Packed) -> usize {
    let geometry = ["triangles", "shading", "nodes", "node_children"];
    let arrays = p.arrays(16384).unwrap_or_default();
    arrays.iter().filter(|a| geometry.contains(&a.name)).map(|a| a.texels * a.texel_bytes).sum()
}

fn arg(args: &[String], flag: &str, default: u32) -> Result<u32> {
    match args.iter().position(|a| a == flag) {
        Some(i) => args.get(i + 1).with_context(|| format!("{flag} needs a value"))?.parse().context(flag.to_string()),
        None => Ok(default),
    }
}

const KINDS: [(RendererKind, &str); 3] =
    [(RendererKind::Cpu, "CPU"), (RendererKind::Gl, "GL"), (RendererKind::Wgpu, "wgpu")];

fn main() -> Result<()> {
    let args: Vec<String> = std::env::args().collect();
    let size = arg(&args, "--size", 128)?;
    let frames = arg(&args, "--frames", 4)?;
    let rounds = arg(&args, "--rounds", 5)? as usize;
    let settings = RenderSettings { width: size, height: size, strategy: Strategy::Mis, max_depth: 8 };

    let mut rows: Vec<(String, Scene)> = Vec::new();
    for g in [4, 8, 16] {
        rows.push((format!("{g}x{g} apart"), instanced_shapes(g)));
    }
    let mut overlapping = instanced_shapes(8);
    for i in &mut overlapping.instances {
        i.transform.w_axis = (i.transform.w_axis.truncate() * 0.3).extend(1.0);
    }
    rows.push(("8x8 overlapping".into(), overlapping));

    println!("{size}x{size}, {frames} frames per measurement, median of {rounds} alternating rounds\n");
    println!(
        "| scene | placements | triangles stored / placed | geometry bytes, 2 levels / flat | {} |",
        KINDS.map(|(_, k)| format!("{k} Msamples/s 2 levels / flat (ratio)")).join(" | ")
    );
    println!("|---|---|---|---|{}", "---|".repeat(KINDS.len()));
    for (name, scene) in &rows {
        let two = build_and_pack(scene, &settings)?.1;
        let mut flat_scene = scene.clone();
        flat_scene.bake_instances()?;
        let flat = build_and_pack(&flat_scene, &settings)?.1;
        anyhow::ensure!(two.features.instances && !flat.features.instances, "{name}: levels as expected");
        let mut cells = Vec::new();
        for (kind, _) in KINDS {
            let mut renderers = [create(kind, two.clone(), 1)?, create(kind, flat.clone(), 1)?];
            for r in renderers.iter_mut() {
                samples_per_second(r.as_mut(), 1)?;
            }
            let mut samples = [Vec::new(), Vec::new()];
            for round in 0..rounds {
                for k in 0..2 {
                    let i = (round + k) % 2;
                    samples[i].push(samples_per_second(renderers[i].as_mut(), frames)?);
                }
            }
            let [a, b] = samples.map(median);
            cells.push(format!("{:.2} / {:.2} ({:.2})", a / 1e6, b / 1e6, a / b));
        }
        println!(
            "| {name} | {} | {} / {} | {:.2} / {:.2} MB ({:.2}) | {} |",
            scene.instances.len(),
            two.triangle_count,
            flat.triangle_count,
            geometry_bytes(&two) as f64 / 1e6,
            geometry_bytes(&flat) as f64 / 1e6,
            geometry_bytes(&two) as f64 / geometry_bytes(&flat) as f64,
            cells.join(" | ")
        );
    }

    println!("\n| placements | top-level build, ms (median of 5) |");
    println!("|---|---|");
    // The stress field's placements (`instanced_field`), as the page times them in wasm.
    for side in [32usize, 100, 317] {
        let n = side * side;
        let boxes: Vec<(Vec3, Vec3)> =
            tracer::scene::instanced_field(side).placement_boxes().iter().map(|b| (b.min, b.max)).collect();
        let times: Vec<f64> = (0..5)
            .map(|_| -> Result<f64> {
                let t = Instant::now();
                std::hint::black_box(top_level(&boxes)?);
                Ok(t.elapsed().as_secs_f64() * 1e3)
            })
            .collect::<Result<_>>()?;
        println!("| {n} | {:.2} |", median(times));
    }
    Ok(())
}
