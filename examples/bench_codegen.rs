//! Kernel code generation benchmark: `cargo run --release --example bench_codegen [-- --runs N]`
//!
//! What a runtime pays to generate a scene's kernel before its driver sees it (the page pays it
//! in wasm, on the way to its first image: `BuildTimes::codegen_ms`): parsing the kernel
//! modules' IR, linking them (which type-checks every function) and emitting the specialised
//! megakernel (GLSL ES 3.00 and WGSL) and the wavefront (WGSL), for a plain scene (the Cornell
//! box's features) and one with every feature. Medians of `--runs` (default 15), ms; the
//! linked program is kept per process (`kernel::linked_kernel`), so a runtime pays the parse and
//! the link once, for its first shader.

use std::time::Instant;

use lightport_codegen::{Program, Selection, Target};
use tracer::kernel::{modules, Features};

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

fn ms(start: Instant) -> f64 {
    start.elapsed().as_secs_f64() * 1e3
}

fn main() -> anyhow::Result<()> {
    let args: Vec<String> = std::env::args().collect();
    let runs = match args.iter().position(|a| a == "--runs") {
        Some(i) => args
            .get(i + 1)
            .and_then(|r| r.parse().ok())
            .filter(|&r| r > 0)
            .ok_or_else(|| anyhow::anyhow!("--runs takes a positive integer"))?,
        None => 15,
    };
    let plain = Features { emissive_triangles: true, sky: true, traversal_stack: 11, ..Features::default() };
    let every = Features { traversal_stack: 64, ..Features::all() };

    let (mut parse, mut link) = (Vec::new(), Vec::new());
    let mut program = None;
    for _ in 0..runs {
        let t = Instant::now();
        let parsed = modules();
        parse.push(ms(t));
        let t = Instant::now();
        program = Some(Program::link(&parsed)?);
        link.push(ms(t));
    }
    let program = program.expect("at least one run");
    println!("kernel code generation, {runs} runs, medians (ms)\n");
    println!("| step | plain scene | every feature |\n|---|---|---|");
    println!("| parse the modules' IR | {:.1} | (same) |", median(parse));
    println!("| link (type-checks every function) | {:.1} | (same) |", median(link));
    let megakernel = |f: &Features| Selection::entry("render_sample", f.specialization());
    let wavefront =
        |f: &Features| Selection::compute(&tracer::backend::wavefront::stage_functions(), f.specialization());
    type Case<'a> = (&'a str, Target, &'a dyn Fn(&Features) -> Selection);
    let cases: [Case; 3] = [
        ("emit the megakernel, GLSL ES 3.00", Target::GlslEs300, &megakernel),
        ("emit the megakernel, WGSL", Target::Wgsl, &megakernel),
        ("emit the wavefront, WGSL", Target::Wgsl, &wavefront),
    ];
    for (what, target, selection) in cases {
        let mut row = Vec::new();
        for features in [&plain, &every] {
            let selection = selection(features);
            let mut times = Vec::new();
            for _ in 0..runs {
                let t = Instant::now();
                program.emit(target, &selection)?;
                times.push(ms(t));
            }
            row.push(median(times));
        }
        println!("| {what} | {:.1} | {:.1} |", row[0], row[1]);
    }
    Ok(())
}
