//! MetalRoughSpheres with the glTF metal-roughness BRDF and, for comparison, with every
//! material as the Lambert kernel renders it (metallic 0, roughness 1: what Lightport showed
//! before the BRDF existed). Writes both side by side as one PNG (PBR Neutral tone curve) and
//! prints the CPU render time of each (alternating, medians).
//!
//! With a glTF file (and a sky), that scene instead, and "before" is everything issue 15
//! changed turned off: Lambert, no normal maps, and the clamped display (no tone curve).
//!
//! ```sh
//! cargo run --release --example metal_rough_figure [-- OUT.png [SIZE [SPP [SCENE.gltf [SKY.hdr]]]]]
//! ```

use std::time::Instant;

use anyhow::{Context, Result};
use tracer::backend::cpu::CpuRenderer;
use tracer::backend::{Image, Renderer};
use tracer::kernel::{RenderSettings, Strategy};
use tracer::output::{write_image, Display, ToneMap};
use tracer::pack::build_and_pack;
use tracer::scene::{metal_rough_spheres, Scene};

fn lambert(mut scene: Scene) -> Scene {
    for m in &mut scene.materials {
        (m.metallic, m.roughness, m.metallic_roughness_texture) = (0.0, 1.0, None);
    }
    scene
}

/// What Lightport rendered before the glTF materials: Lambert, no normal maps.
fn before(scene: Scene) -> Scene {
    let mut scene = lambert(scene);
    for m in &mut scene.materials {
        m.normal_texture = None;
    }
    scene
}

/// The scene of the figure and the display of its "before" side.
fn figure_scene(path: Option<String>, sky: Option<String>) -> Result<(String, Scene, Scene, Display)> {
    let neutral = Display { tone_map: ToneMap::Neutral, exposure: 0.0 };
    let Some(path) = path else {
        return Ok(("MetalRoughSpheres".into(), lambert(metal_rough_spheres()), metal_rough_spheres(), neutral));
    };
    let mut scene = tracer::scene::load(path.as_ref()).with_context(|| format!("loading {path}"))?;
    if let Some(sky) = sky {
        scene.sky = Some(tracer::scene::load_sky(sky.as_ref(), 1.0, 0.0).with_context(|| format!("loading {sky}"))?);
    }
    let name = std::path::Path::new(&path).file_stem().map_or(path.clone(), |s| s.to_string_lossy().into_owned());
    Ok((name, before(scene.clone()), scene, Display::CLAMP))
}

/// Renders `spp` frames; returns the image and the seconds it took.
fn render(scene: &Scene, size: u32, spp: u32) -> Result<(Image, f64)> {
    let settings = RenderSettings { width: size, height: size, strategy: Strategy::Mis, max_depth: 8 };
    let (_, packed) = build_and_pack(scene, &settings).context("packing")?;
    let mut r = CpuRenderer::new(packed, 1);
    let t = Instant::now();
    for _ in 0..spp {
        r.render_frame()?;
    }
    Ok((r.image()?, t.elapsed().as_secs_f64()))
}

/// `image` as `display` shows it, in linear values that the clamped display writes unchanged.
fn display_as(image: &Image, display: &Display) -> Image {
    let linear = |c: f32| if c <= 0.04045 { c / 12.92 } else { ((c + 0.055) / 1.055).powf(2.4) };
    let pixels = image.pixels.iter().map(|p| display.srgb(*p).map(linear)).collect();
    Image { pixels, ..image.clone() }
}

fn main() -> Result<()> {
    let mut args = std::env::args().skip(1);
    let out = args.next().unwrap_or_else(|| "metal-rough-spheres.png".into());
    let size: u32 = args.next().map(|a| a.parse()).transpose().context("SIZE")?.unwrap_or(256);
    let spp: u32 = args.next().map(|a| a.parse()).transpose().context("SPP")?.unwrap_or(128);
    let (name, before_scene, after_scene, before_display) = figure_scene(args.next(), args.next())?;
    let scenes = [("Lambert (before)", before_scene), ("glTF metal-roughness", after_scene)];
    let mut times = [Vec::new(), Vec::new()];
    let mut images = Vec::new();
    // Three alternating rounds; the last round's images are kept.
    for round in 0..3 {
        images.clear();
        for (i, (_, scene)) in scenes.iter().enumerate() {
            let (image, seconds) = render(scene, size, spp)?;
            times[i].push(seconds);
            images.push(image);
        }
        eprintln!("round {round}: {:.2} s, {:.2} s", times[0][round], times[1][round]);
    }
    let median = |t: &mut Vec<f64>| {
        t.sort_by(f64::total_cmp);
        t[t.len() / 2]
    };
    let (lambert_s, gltf_s) = (median(&mut times[0]), median(&mut times[1]));
    println!("{name} {size}x{size}, {spp} spp, MIS, CPU, medians of 3:");
    println!("| kernel | seconds | Msamples/s | ÷ Lambert |\n|---|---|---|---|");
    for (name, s) in [(scenes[0].0, lambert_s), (scenes[1].0, gltf_s)] {
        let rate = (size * size * spp) as f64 / s / 1e6;
        println!("| {name} | {s:.2} | {rate:.2} | {:.2} |", s / lambert_s);
    }
    // Side by side, each through its display (PNG Neutral is the identity on [0, 0.76] only, so
    // the "before" side is displayed first and its sRGB values decoded back to linear for it).
    let shown = [display_as(&images[0], &before_display), display_as(&images[1], &Display::default())];
    let mut pixels = Vec::with_capacity((2 * size * size) as usize);
    for y in 0..size as usize {
        for image in &shown {
            pixels.extend_from_slice(&image.pixels[y * size as usize..(y + 1) * size as usize]);
        }
    }
    let both = Image { width: 2 * size, height: size, pixels };
    write_image(out.as_ref(), &both, &Display::CLAMP)?;
    println!("wrote {out}");
    Ok(())
}
