//! Refit against rebuild for a deformed mesh's bottom level (issue 28; `pack::posing`'s
//! `REFIT_MIN_TRIANGLES` and `REFIT_BOUND`), measured in one run and printed as a table.
//!
//! ```sh
//! cargo run --release --example bench_refit [-- --size N] [--rays R] [--rounds K]
//! ```
//!
//! A grid of N x N quads (2N² triangles; default N = 224, ~100k) bulged by a morph-like
//! displacement of growing amount and twisted, then torn (strips slid apart). Per amount: the time to build its hierarchy
//! and to refit the rest pose's to it (medians of K), the SAH cost of each (the refitted one's
//! also as a ratio to the rest pose's, which is what the pose step can know without building,
//! and to the rebuilt one's), and closest-hit rays per second through each (the same R rays
//! from in front of the grid; `Bvh::intersect_closest` on the CPU, one thread), rounds
//! alternating which goes first. Where the refitted hierarchy traces more slowly than the
//! rebuilt one by more than its build costs over a few frames, a pose should rebuild: the
//! table shows at what SAH ratio that happens.

use std::time::Instant;

use glam::{Vec2, Vec3};
use tracer::bvh::{self, Bvh};
use tracer::scene::Triangle;

fn arg(name: &str, default: usize) -> usize {
    let args: Vec<String> = std::env::args().collect();
    args.iter().position(|a| a == name).and_then(|i| args.get(i + 1)).and_then(|v| v.parse().ok()).unwrap_or(default)
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

/// The grid deformed by `amount`: `tear` false, bulged towards +Z and twisted about Y by
/// `amount` radians per unit of height (a smooth deformation, as skins and morphs give); `tear`
/// true, its columns slid apart along Y in alternate strips of 1/16 of its width, by up to
/// `amount` (what a refit handles worst: neighbours in the hierarchy fly apart).
fn grid(n: usize, amount: f32, tear: bool) -> Vec<Triangle> {
    let at = |i: usize, j: usize| {
        let (x, y) = (i as f32 / n as f32 * 2.0 - 1.0, j as f32 / n as f32 * 2.0 - 1.0);
        if tear {
            let strip = (i * 16 / (n + 1)) as f32;
            return Vec3::new(x, y + amount * if strip % 2.0 == 0.0 { strip / 16.0 } else { -strip / 16.0 }, 0.0);
        }
        let z = amount * (x * 3.0).sin() * (y * 2.0).cos();
        let (s, c) = (y * amount).sin_cos();
        Vec3::new(x * c - z * s, y, x * s + z * c)
    };
    let tri = |a: Vec3, b: Vec3, c: Vec3| Triangle {
        positions: [a, b, c],
        normals: [Vec3::Z; 3],
        uvs: [Vec2::ZERO; 3],
        uvs1: Default::default(),
        tangents: Default::default(),
        material: 0,
    };
    let mut out = Vec::with_capacity(2 * n * n);
    for j in 0..n {
        for i in 0..n {
            out.push(tri(at(i, j), at(i + 1, j), at(i + 1, j + 1)));
            out.push(tri(at(i, j), at(i + 1, j + 1), at(i, j + 1)));
        }
    }
    out
}

/// Rays from a plane in front of the grid towards it, jittered (a deterministic sequence).
fn rays(count: usize) -> Vec<(Vec3, Vec3)> {
    let mut state = 0x9E37_79B9u32;
    let mut next = move || {
        state ^= state << 13;
        state ^= state >> 17;
        state ^= state << 5;
        state as f32 / u32::MAX as f32
    };
    (0..count)
        .map(|_| {
            let origin = Vec3::new(next() * 2.4 - 1.2, next() * 2.4 - 1.2, 3.0);
            let dir = Vec3::new(next() * 0.6 - 0.3, next() * 0.6 - 0.3, -1.0).normalize();
            (origin, dir)
        })
        .collect()
}

fn rays_per_second(bvh: &Bvh, triangles: &[Triangle], rays: &[(Vec3, Vec3)]) -> f64 {
    let t = Instant::now();
    let hits = rays.iter().filter(|(o, d)| bvh.intersect_closest(triangles, *o, *d, f32::INFINITY).is_some()).count();
    std::hint::black_box(hits);
    rays.len() as f64 / t.elapsed().as_secs_f64()
}

fn main() -> anyhow::Result<()> {
    let (n, ray_count, rounds) = (arg("--size", 224), arg("--rays", 50_000), arg("--rounds", 3).max(1));
    let rest = grid(n, 0.0, false);
    let first = bvh::build(&rest)?;
    let first_cost = first.sah_cost();
    let rays = rays(ray_count);
    println!(
        "Refit against rebuild: a {n} x {n} grid ({} triangles) bulged and twisted; {ray_count} rays, \
         medians of {rounds} alternated rounds (one thread; a shared 2-core machine: compare within a row).\n",
        rest.len()
    );
    println!(
        "| amount | build (ms) | refit (ms) | SAH rebuilt | SAH refitted | refitted / first pose | refitted / rebuilt | \
         rays/s rebuilt | rays/s refitted | refitted / rebuilt speed |"
    );
    println!("|---|---|---|---|---|---|---|---|---|---|");
    let cases =
        [0.05f32, 0.1, 0.2, 0.3, 0.5, 0.8].map(|a| (a, false)).into_iter().chain([0.5f32, 1.0, 2.0].map(|a| (a, true)));
    for (amount, tear) in cases {
        let moved = grid(n, amount, tear);
        let (mut build_ms, mut refit_ms, mut built_speed, mut refit_speed) = (vec![], vec![], vec![], vec![]);
        let (mut built, mut refitted) = (first.clone(), first.clone());
        for round in 0..rounds {
            let build = |built: &mut Bvh, ms: &mut Vec<f64>| -> anyhow::Result<()> {
                let t = Instant::now();
                *built = bvh::build(&moved)?;
                ms.push(t.elapsed().as_secs_f64() * 1e3);
                Ok(())
            };
            let refit = |refitted: &mut Bvh, ms: &mut Vec<f64>| -> anyhow::Result<()> {
                *refitted = first.clone();
                let t = Instant::now();
                refitted.refit(&moved)?;
                ms.push(t.elapsed().as_secs_f64() * 1e3);
                Ok(())
            };
            if round % 2 == 0 {
                build(&mut built, &mut build_ms)?;
                refit(&mut refitted, &mut refit_ms)?;
                built_speed.push(rays_per_second(&built, &moved, &rays));
                refit_speed.push(rays_per_second(&refitted, &moved, &rays));
            } else {
                refit(&mut refitted, &mut refit_ms)?;
                build(&mut built, &mut build_ms)?;
                refit_speed.push(rays_per_second(&refitted, &moved, &rays));
                built_speed.push(rays_per_second(&built, &moved, &rays));
            }
        }
        let (sah_built, sah_refit) = (built.sah_cost(), refitted.sah_cost());
        let (bs, rs) = (median(built_speed), median(refit_speed));
        println!(
            "| {}{amount} | {:.1} | {:.2} | {sah_built:.1} | {sah_refit:.1} | {:.2} | {:.2} | {:.0} | {:.0} | {:.2} |",
            if tear { "torn " } else { "" },
            median(build_ms),
            median(refit_ms),
            sah_refit / first_cost,
            sah_refit / sah_built,
            bs,
            rs,
            rs / bs
        );
    }
    Ok(())
}
