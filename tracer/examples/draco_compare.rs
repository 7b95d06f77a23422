//! Compares a Draco-compressed glTF with its uncompressed original: triangle counts, bounds,
//! the largest distance from each compressed triangle to the nearest matching original one
//! (corners in order, any rotation), and load times (median of runs alternating the two files).
//!
//! ```sh
//! cargo run --release -p lightport-tracer --example draco_compare -- ORIGINAL.glb DRACO.glb [RUNS]
//! ```
//! e.g. `../shared/scenes/threejs/LittlestTokyo.glb ../shared/scenes/extra/LittlestTokyo.draco.glb`.

use std::collections::HashMap;
use std::path::Path;
use std::time::{Duration, Instant};

use glam::IVec3;
use tracer::scene::{self, Scene, Triangle};

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let (Some(original), Some(draco)) = (args.first(), args.get(1)) else {
        eprintln!("usage: draco_compare ORIGINAL.glb DRACO.glb [RUNS]");
        std::process::exit(2);
    };
    let runs: usize = args.get(2).and_then(|r| r.parse().ok()).unwrap_or(3);
    let mut times = [Vec::new(), Vec::new()];
    let mut scenes: [Option<Scene>; 2] = [None, None];
    for _ in 0..runs {
        for (i, path) in [original, draco].iter().enumerate() {
            let start = Instant::now();
            let s = scene::load(Path::new(path)).unwrap_or_else(|e| panic!("{path}: {e}"));
            times[i].push(start.elapsed());
            scenes[i] = Some(s);
        }
    }
    let [Some(a), Some(b)] = scenes else { unreachable!() };
    times.iter_mut().for_each(|t| t.sort());
    for (name, s, t) in [("original", &a, &times[0]), ("draco", &b, &times[1])] {
        let bounds = s.bounds();
        println!(
            "{name:9} {:>8} triangles, bounds {:?} .. {:?}, load median {:.3} s (of {:?}), {} warnings",
            s.triangles.len(),
            bounds.min.to_array(),
            bounds.max.to_array(),
            t[t.len() / 2].as_secs_f64(),
            t.iter().map(Duration::as_secs_f64).collect::<Vec<_>>(),
            s.warnings.len()
        );
        for w in &s.warnings {
            println!("          warning: {w}");
        }
    }
    let (worst, unmatched) = max_difference(&a, &b);
    let extent = a.bounds().max - a.bounds().min;
    println!(
        "largest corner difference {worst:.6} ({:.2e} of the largest extent {:.3}); {unmatched} Draco triangles with no original within the search cells",
        worst / extent.max_element(),
        extent.max_element()
    );
}

/// For each triangle of `b`, the nearest triangle of `a` (largest corner distance, corners in
/// order with any rotation) among those whose centroid lies in the neighbouring grid cells;
/// the largest of these distances, and how many found none.
fn max_difference(a: &Scene, b: &Scene) -> (f32, usize) {
    let bounds = a.bounds();
    let cell = (bounds.max - bounds.min).max_element() / 4096.0;
    let key = |t: &Triangle| {
        let c = (t.positions[0] + t.positions[1] + t.positions[2]) / 3.0;
        ((c - bounds.min) / cell).floor().as_ivec3()
    };
    let mut grid: HashMap<IVec3, Vec<usize>> = HashMap::new();
    for (i, t) in a.triangles.iter().enumerate() {
        grid.entry(key(t)).or_default().push(i);
    }
    let mut worst = 0.0f32;
    let mut unmatched = 0;
    for t in &b.triangles {
        let k = key(t);
        let mut best = f32::INFINITY;
        for dz in -1..=1 {
            for dy in -1..=1 {
                for dx in -1..=1 {
                    for &i in grid.get(&(k + IVec3::new(dx, dy, dz))).into_iter().flatten() {
                        best = best.min(distance(&a.triangles[i], t));
                    }
                }
            }
        }
        if best.is_finite() {
            worst = worst.max(best);
        } else {
            unmatched += 1;
        }
    }
    (worst, unmatched)
}

fn distance(a: &Triangle, b: &Triangle) -> f32 {
    (0..3)
        .map(|s| (0..3).map(|k| (a.positions[(k + s) % 3] - b.positions[k]).abs().max_element()).fold(0.0, f32::max))
        .fold(f32::INFINITY, f32::min)
}
