//! The denoiser's quality, and variants of it, against the project's own high-sample
//! references (issue #30): per scene, PSNR of the displayed image (clamped to [0, 1]) and
//! relative MSE, noisy and denoised, at 1, 4, 16, 64 and 256 spp. The variants run on the
//! host (`filter.rs`: a parametric copy of `atrous_pixel`, the same demodulation) so that
//! ideas can be measured before they go into the DSL:
//! - `shipped`: `tracer::denoise::denoise` as it is;
//! - `per-sample`: each sample's reflected light divided by its own first hit's albedo, summed
//!   (the illumination the filter sees), remodulated by the mean albedo;
//! - `remodulated xK`: the same filtered illumination remodulated by the albedo and emission of
//!   K first hits per sample from a second renderer at max_depth 2 (what any runtime can do
//!   today), and what those frames cost;
//! - with `DQ_DENSE=1,3,15`, oracles: remodulated (`remod dK`) or demodulated and remodulated
//!   (`both dK`) by the image's guide plus K first hits per sample, and only the emission dense
//!   (`e dK`, `e+cov dK`); with `DQ_PER_SAMPLE=1`, each sample demodulated by its own first hit;
//! - parameter sweeps (σn, σl, σz, iterations); `σn128 (before)` is the filter before σn 1024.
//!
//! Found (2026-12-05, DamagedHelmet under a sky, 16 spp): the filter's own parameters move
//! nothing at 16 spp (±0.3 dB): the error left is coverage within pixels. Remodulating by 3
//! first hits per sample gains +2.7 dB PSNR at 48x48 (+2.5 at 128x128), but a max_depth-2
//! frame costs 0.6-1.1x a path-traced frame here, and 64 spp of plain path tracing (R2
//! stratified: coverage converges faster than 1/N) is 9 dB better than 16: at equal time it
//! loses. Demodulating by the denser guide too (`both`) gains only +0.1-0.8 dB; per-sample
//! demodulation loses 1.2-1.7 dB.
//!
//! `cargo run --release --example denoise_quality [-- helmet|helmet-venice|cornell|box [size]]`
//! References are cached under the system's temporary directory.

use std::path::PathBuf;

use glam::{DVec3, Vec3, Vec4, Vec4Swizzles};
use tracer::backend::cpu::CpuRenderer;
use tracer::backend::Renderer;
use tracer::denoise::{denoise, Aov, Guide};
use tracer::kernel::denoise::MIN_ALBEDO;
use tracer::kernel::lights::luminance;
use tracer::kernel::{RenderSettings, Strategy};
use tracer::output::Image;
use tracer::pack::build_and_pack;
use tracer::scene::{self, Scene};

mod filter;

use filter::{demodulation, filter, input_mean, input_per_sample, Params, BEFORE, SHIPPED};

fn data(path: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/data").join(path)
}

fn scene_named(name: &str) -> Scene {
    match name {
        "helmet" | "helmet-venice" => {
            let mut s =
                scene::load(&data("scenes/khronos/DamagedHelmet/glTF-Binary/DamagedHelmet.glb")).expect("helmet");
            s.sky = Some(if name == "helmet" {
                scene::Sky::uniform(Vec3::splat(0.8))
            } else {
                scene::load_sky(&data("scenes/hdri/venice_sunset_1k.hdr"), 1.0, 0.0).expect("sky")
            });
            s
        }
        "cornell" => scene::cornell_box(),
        "box" => {
            let mut s = scene::load(&data("scenes/khronos/BoxTextured/glTF/BoxTextured.gltf")).expect("box");
            s.sky = Some(scene::Sky::uniform(Vec3::ONE));
            s
        }
        _ => panic!("unknown scene {name}"),
    }
}

/// Per pixel, what the variants need beyond the renderer's sums: each sample's demodulated
/// reflected light (surface samples only) and its luminance moments.
#[derive(Clone, Default)]
struct PerSample {
    illumination: Vec<DVec3>,
    surface: Vec<f64>,
    moments: Vec<(f64, f64)>,
}

struct Rendered {
    sums: [Vec<Vec4>; 3],
    image: Image,
    guide: Guide,
    per_sample: PerSample,
}

fn renderer(scene: &Scene, size: u32, seed: u32) -> CpuRenderer {
    renderer_to_depth(scene, size, seed, 6)
}

fn renderer_to_depth(scene: &Scene, size: u32, seed: u32, max_depth: u32) -> CpuRenderer {
    let settings = RenderSettings { width: size, height: size, strategy: Strategy::Mis, max_depth };
    let mut p = build_and_pack(scene, &settings).expect("pack").1;
    p.set_denoise_guide(true);
    CpuRenderer::new(p, seed)
}

/// Renders `scene` frame by frame to each count in `counts`, reading back after every frame
/// (the per-sample values are the differences of the sums).
fn render_steps(scene: &Scene, size: u32, seed: u32, counts: &[u32]) -> Vec<Rendered> {
    let mut r = renderer(scene, size, seed);
    let n = (size * size) as usize;
    let mut ps = PerSample { illumination: vec![DVec3::ZERO; n], surface: vec![0.0; n], moments: vec![(0.0, 0.0); n] };
    let mut prev_acc = vec![Vec4::ZERO; n];
    let mut prev_guide: [Vec<Vec4>; 3] = std::array::from_fn(|_| vec![Vec4::ZERO; n]);
    let mut out = Vec::new();
    let last = *counts.iter().max().unwrap();
    for frame in 1..=last {
        r.render_frame().expect("frame");
        let acc = r.accumulation().unwrap();
        let g = r.guide_sums().unwrap();
        for i in 0..n {
            let c = (acc[i] - prev_acc[i]).xyz();
            let a = (g[0][i] - prev_guide[0][i]).xyz();
            let e = (g[2][i] - prev_guide[2][i]).xyz();
            if a.max_element() > 0.0 {
                let ill = (c - e) / demodulation(a);
                ps.illumination[i] += ill.as_dvec3();
                ps.surface[i] += 1.0;
                let l = luminance(ill) as f64;
                ps.moments[i].0 += l;
                ps.moments[i].1 += l * l;
            }
        }
        prev_acc = acc;
        prev_guide = g;
        if counts.contains(&frame) {
            out.push(Rendered {
                sums: r.guide_sums().unwrap(),
                image: r.image().unwrap(),
                guide: Guide::read(&r).unwrap(),
                per_sample: ps.clone(),
            });
        }
    }
    out
}

fn reference(name: &str, scene: &Scene, size: u32, spp: u32) -> Image {
    let path = std::env::temp_dir().join(format!("lightport-dq-{name}-{size}-{spp}.bin"));
    if let Ok(bytes) = std::fs::read(&path) {
        let pixels: Vec<Vec3> = bytes
            .chunks_exact(12)
            .map(|c| {
                let f = |k: usize| f32::from_le_bytes(c[k * 4..k * 4 + 4].try_into().unwrap());
                Vec3::new(f(0), f(1), f(2))
            })
            .collect();
        if pixels.len() == (size * size) as usize {
            return Image { width: size, height: size, pixels };
        }
    }
    let mut r = renderer(scene, size, 99);
    for _ in 0..spp {
        r.render_frame().expect("frame");
    }
    let image = r.image().unwrap();
    let bytes: Vec<u8> = image.pixels.iter().flat_map(|p| p.to_array()).flat_map(f32::to_le_bytes).collect();
    std::fs::write(&path, bytes).expect("cache");
    image
}

fn remodulate(image: &Image, filtered: &[Vec4], modulation: &[(Vec3, Vec3)]) -> Image {
    remodulate_keeping(image, filtered, modulation, modulation)
}

/// The filtered illumination times `modulation`'s albedo plus its emission, the reflected light
/// scaled to the noisy image's total less `own`'s emission (the image's own first hits).
fn remodulate_keeping(image: &Image, filtered: &[Vec4], modulation: &[(Vec3, Vec3)], own: &[(Vec3, Vec3)]) -> Image {
    let reflected: DVec3 = image.pixels.iter().zip(own).map(|(c, (_, e))| (*c - *e).as_dvec3()).sum();
    let rem: Vec<Vec3> = filtered.iter().zip(modulation).map(|(f, (d, _))| f.xyz() * *d).collect();
    let total: DVec3 = rem.iter().map(|r| r.as_dvec3()).sum();
    let scale = DVec3::select(total.cmpgt(DVec3::ZERO), reflected / total, DVec3::ONE).as_vec3();
    Image {
        width: image.width,
        height: image.height,
        pixels: rem.iter().zip(modulation).map(|(r, (_, e))| *r * scale + *e).collect(),
    }
}

/// The shipped filter's illumination (demodulated by the image's own guide: its samples'
/// colour and first hits agree) remodulated by `first_hits`' albedo (where the image's own was
/// divided out) and emission.
fn remodulated(image: &Image, guide: &Guide, first_hits: &[Aov]) -> Image {
    let inp = input_mean(image, guide);
    let modulation: Vec<(Vec3, Vec3)> = inp
        .modulation
        .iter()
        .zip(first_hits)
        .zip(&guide.aovs)
        .map(|((&(d, _), dense), own)| {
            let divided = own.albedo.cmpge(Vec3::splat(MIN_ALBEDO));
            (Vec3::select(divided, dense.albedo.max(Vec3::ZERO), d), dense.emission)
        })
        .collect();
    let f = filter(inp.img, SHIPPED);
    remodulate_keeping(image, &f, &modulation, &inp.modulation)
}

fn error(image: &Image, reference: &Image) -> (f64, f64) {
    let rel = tracer::stats::rel_mse(&image.pixels, &reference.pixels).unwrap();
    let clamp = |p: &[Vec3]| p.iter().map(|p| p.clamp(Vec3::ZERO, Vec3::ONE)).collect::<Vec<_>>();
    let d = tracer::stats::mse(&clamp(&image.pixels), &clamp(&reference.pixels)).unwrap();
    (rel, -10.0 * d.log10())
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let name = args.first().map(String::as_str).unwrap_or("helmet");
    let size: u32 = args.get(1).and_then(|s| s.parse().ok()).unwrap_or(128);
    let ref_spp: u32 = args.get(2).and_then(|s| s.parse().ok()).unwrap_or(2048);
    let mut only: Vec<u32> = args
        .get(3)
        .map(|s| s.split(',').map(|x| x.parse().expect("sample counts, e.g. 1,4,16")).collect())
        .unwrap_or(vec![1, 4, 16, 64, 256]);
    // Rows follow the renders, which come in ascending order, once each.
    only.sort_unstable();
    only.dedup();
    let scene = scene_named(name);
    let t = std::time::Instant::now();
    let reference = reference(name, &scene, size, ref_spp);
    eprintln!("reference {:.1} s", t.elapsed().as_secs_f64());
    let counts = only.clone();
    let t = std::time::Instant::now();
    let steps = render_steps(&scene, size, 7, &counts);
    eprintln!("renders {:.1} s", t.elapsed().as_secs_f64());
    // A denser guide (what extra first-hit rays would give): K more first hits per sample,
    // from another seed, summed with the path's own.
    let ks: Vec<u32> = std::env::var("DQ_DENSE")
        .map(|v| v.split(',').map(|k| k.parse().expect("DQ_DENSE: first hits per sample, e.g. 1,3,15")).collect())
        .unwrap_or_default();
    let mut dense_counts: Vec<u32> = counts.iter().flat_map(|c| ks.iter().map(move |k| c * k)).collect();
    dense_counts.retain(|c| *c <= 1024);
    dense_counts.sort();
    dense_counts.dedup();
    let dense = if dense_counts.is_empty() { Vec::new() } else { render_steps(&scene, size, 11, &dense_counts) };
    let combined = |r: &Rendered, spp: u32, k: u32| -> Option<Guide> {
        let d = &dense[dense_counts.iter().position(|c| *c == spp * k)?];
        let sums: [Vec<Vec4>; 3] =
            std::array::from_fn(|f| r.sums[f].iter().zip(&d.sums[f]).map(|(a, b)| *a + *b).collect());
        let mut g = Guide::from_sums(spp * (k + 1), &sums);
        g.variance = r.guide.variance.clone();
        Some(g)
    };
    // Remodulation by denser first hits, as it could run on any runtime today: K first hits per
    // sample from a second renderer at max_depth 2 (another seed; at depth 1 the guide has no
    // metal-roughness albedo), and what its frames cost against the image's.
    let max = *counts.iter().max().expect("a sample count");
    let fk: u32 = std::env::var("DQ_FIRST_HITS").ok().and_then(|v| v.parse().ok()).unwrap_or(3);
    let mut first_hits = Vec::new();
    let mut fr = renderer_to_depth(&scene, size, 11, 2);
    let t = std::time::Instant::now();
    for frame in 1..=fk * max {
        fr.render_frame().expect("frame");
        if counts.contains(&(frame / fk)) && frame % fk == 0 {
            first_hits.push(Guide::read(&fr).unwrap().aovs);
        }
    }
    let first_hit_frame = t.elapsed().as_secs_f64() / (fk * max) as f64;
    let mut pr = renderer(&scene, size, 5);
    let t = std::time::Instant::now();
    for _ in 0..8 {
        pr.render_frame().expect("frame");
    }
    let path_frame = t.elapsed().as_secs_f64() / 8.0;
    println!(
        "{name}: a max_depth-2 frame with the guide costs {:.2}x a max_depth-6 frame with the guide ({fk} per sample: {:.2}x)",
        first_hit_frame / path_frame,
        fk as f64 * first_hit_frame / path_frame
    );
    println!("{name} {size}x{size}, reference {ref_spp} spp; each cell: PSNR dB (displayed) / relMSE gain dB vs noisy");
    for (spp, r) in counts.iter().zip(&steps) {
        let (rel_n, psnr_n) = error(&r.image, &reference);
        let mut row = format!("{spp:>4} spp noisy {psnr_n:6.2} dB relMSE {rel_n:.5}");
        let mut cell = |label: &str, img: &Image| {
            let (rel, psnr) = error(img, &reference);
            row += &format!(" | {label} {:+.2}/{:+.2}", psnr - psnr_n, 10.0 * (rel_n / rel).log10());
        };
        cell("shipped", &denoise(&r.image, &r.guide).unwrap().image);
        let k = counts.iter().position(|c| c == spp).unwrap();
        cell(&format!("remodulated x{fk}"), &remodulated(&r.image, &r.guide, &first_hits[k]));
        let inp = input_mean(&r.image, &r.guide);
        let f = filter(inp.img, SHIPPED);
        cell("copy", &remodulate(&r.image, &f, &inp.modulation));
        for &k in &ks {
            let Some(dg) = combined(r, *spp, k) else { continue };
            let dmod: Vec<(Vec3, Vec3)> = dg.aovs.iter().map(|a| (demodulation(a.albedo), a.emission)).collect();
            cell(&format!("remod d{k}"), &remodulate(&r.image, &f, &dmod));
            cell(&format!("both d{k}"), &denoise(&r.image, &dg).unwrap().image);
            // Only the emission dense (the albedo the path's own); then also the albedo scaled
            // by the surface coverage the dense guide sees over the path's own (from the depth
            // sums: the sky's depth dominates them).
            let sky = |g: &Guide, i: usize| (g.aovs[i].depth as f64 / 1.0e20).clamp(0.0, 1.0) as f32;
            let emod: Vec<(Vec3, Vec3)> =
                r.guide.aovs.iter().zip(&dg.aovs).map(|(c, d)| (demodulation(c.albedo), d.emission)).collect();
            cell(&format!("e d{k}"), &remodulate(&r.image, &f, &emod));
            let cmod: Vec<(Vec3, Vec3)> = (0..emod.len())
                .map(|i| {
                    let (sc, sd) = (sky(&r.guide, i), sky(&dg, i));
                    let s = if sc < 1.0 { (1.0 - sd) / (1.0 - sc) } else { 1.0 };
                    (demodulation(r.guide.aovs[i].albedo) * s, dg.aovs[i].emission)
                })
                .collect();
            cell(&format!("e+cov d{k}"), &remodulate(&r.image, &f, &cmod));
        }
        if std::env::var("DQ_PER_SAMPLE").is_ok() {
            let inp = input_per_sample(&r.image, &r.guide, &r.per_sample);
            let f2 = filter(inp.img, SHIPPED);
            cell("per-sample", &remodulate(&r.image, &f2, &inp.modulation));
        }
        for (label, p) in [
            ("σn128 (before)", BEFORE),
            ("σn512", Params { sigma_normal: 512.0, ..SHIPPED }),
            ("σn2048", Params { sigma_normal: 2048.0, ..SHIPPED }),
            ("σl3", Params { sigma_luminance: 3.0, ..SHIPPED }),
            ("σz.5", Params { sigma_depth: 0.5, ..SHIPPED }),
            ("it5", Params { iterations: 5, ..SHIPPED }),
        ] {
            let inp = input_mean(&r.image, &r.guide);
            let f = filter(inp.img, p);
            cell(label, &remodulate(&r.image, &f, &inp.modulation));
        }
        println!("{row}");
    }
}
