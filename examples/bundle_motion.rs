//! A moving scene through a bundle: per scene (loaded with its motion kept), the source's size,
//! the bundle with its motion section (raw and gzip-compressed, as `lightport serve` sends it)
//! and without, the encode and decode times, and what a pose costs: packing the posed scene
//! whole (what `MovingScene` did before `pack::Posing`) against the pose step over the packed
//! arrays, for the loaded scene and for the bundle's (`MovingScene::from_bundle`), with
//! whether the three agree bit for bit (lights aside: a pose keeps the first pose's) at 8 times.
//!
//! ```sh
//! cargo run --release --example bundle_motion -- [--shapes N] SCENE...   # e.g. ../shared/scenes/threejs/LittlestTokyo.glb
//! ```
//!
//! `--shapes N` puts each scene inside `instanced_shapes(N)` (its static floor and light, its
//! sphere placed N x N times): a generated scene with a larger static part.

use std::io::Write;
use std::time::Instant;

use tracer::kernel::RenderSettings;
use tracer::pack::{pack_textures, pack_with_textures, static_bvh, MovingScene, Packed};
use tracer::scene::{AnimationChoice, LoadOptions, Scene};

fn gzip(bytes: &[u8]) -> usize {
    let mut encoder = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::default());
    encoder.write_all(bytes).expect("writing to memory");
    encoder.finish().expect("writing to memory").len()
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

/// `scene` inside `instanced_shapes(n)`.
fn with_shapes(mut scene: Scene, n: usize) -> Scene {
    let more = tracer::scene::instanced_shapes(n);
    let (materials, meshes) = (scene.materials.len() as u32, scene.meshes.len() as u32);
    let offset = |t: &tracer::scene::Triangle| tracer::scene::Triangle { material: t.material + materials, ..*t };
    scene.triangles.extend(more.triangles.iter().map(offset));
    scene.meshes.extend(
        more.meshes.iter().map(|m| tracer::scene::Mesh { triangles: m.triangles.iter().map(offset).collect() }),
    );
    scene.instances.extend(more.instances.iter().map(|i| tracer::scene::Instance { mesh: i.mesh + meshes, ..*i }));
    scene.materials.extend(more.materials);
    scene
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let (mut shapes, mut paths) = (None, Vec::new());
    let mut args = std::env::args().skip(1);
    while let Some(arg) = args.next() {
        match arg.as_str() {
            "--shapes" => shapes = Some(args.next().ok_or("--shapes takes a number")?.parse::<usize>()?),
            _ => paths.push(arg),
        }
    }
    if paths.is_empty() {
        return Err("usage: bundle_motion [--shapes N] SCENE...".into());
    }
    println!(
        "| scene | moves | source | bundle raw / gzip (gzip / source) | without motion raw / gzip | encode | decode | \
         pose: whole repack | pose step (loaded / bundle) | bundle setup | equal (of 8) |"
    );
    println!("|---|---|---|---|---|---|---|---|---|---|---|");
    for path in paths {
        let options = LoadOptions { keep_motion: true, animation: AnimationChoice::First, ..Default::default() };
        let mut scene = tracer::scene::load_with(std::path::Path::new(&path), &options)?;
        if let Some(n) = shapes {
            scene = with_shapes(scene, n);
        }
        let source = std::fs::metadata(&path)?.len();
        let name = std::path::Path::new(&path).file_name().map_or(path.clone(), |n| n.to_string_lossy().into_owned());
        let Some(motion) = scene.motion.as_ref() else {
            println!("| {name} | nothing | | | | | | | | | |");
            continue;
        };
        let (describe, duration) = (motion.describe(), motion.duration());
        let settings = RenderSettings::default();
        let (bvh, textures) = (static_bvh(&scene)?, pack_textures(&scene));
        let (mut loaded, packed) = MovingScene::new(scene.clone(), &settings)?;
        let without = tracer::bundle::encode_named("scene", &packed);
        let t0 = Instant::now();
        let bytes = tracer::bundle::encode_scene("scene", &packed, loaded.scene());
        let encode = t0.elapsed();
        let t1 = Instant::now();
        let bundle = tracer::bundle::Bundle::decode(&bytes)?;
        let decode = t1.elapsed();
        let t2 = Instant::now();
        let mut served = MovingScene::from_bundle(&bundle.packed, bundle.moving.ok_or("no motion section")?)?;
        let setup = t2.elapsed();
        let (mut whole_ms, mut step_ms, mut served_ms, mut equal) = (Vec::new(), Vec::new(), Vec::new(), 0);
        let mut whole = scene;
        for k in 0..8 {
            let t = duration * k as f32 / 7.0 + 0.01;
            whole.pose(t)?;
            loaded.pose(t)?;
            served.pose(t)?;
            let t3 = Instant::now();
            let mut reference: Packed = pack_with_textures(&whole, &bvh, &textures, &settings)?;
            whole_ms.push(t3.elapsed().as_secs_f64() * 1e3);
            let t4 = Instant::now();
            let a = loaded.pack()?;
            step_ms.push(t4.elapsed().as_secs_f64() * 1e3);
            let t5 = Instant::now();
            let b = served.pack()?;
            served_ms.push(t5.elapsed().as_secs_f64() * 1e3);
            reference.scene.lights = packed.scene.lights.clone();
            let encoded = tracer::bundle::encode(&a);
            equal += (encoded == tracer::bundle::encode(&b) && encoded == tracer::bundle::encode(&reference)) as usize;
        }
        println!(
            "| {name} | {describe} | {:.2} MB | {:.2} / {:.2} MB ({:.2}x) | {:.2} / {:.2} MB | {:.0} ms | {:.0} ms | \
             {:.1} ms | {:.1} / {:.1} ms | {:.1} ms | {equal} |",
            source as f64 / 1e6,
            bytes.len() as f64 / 1e6,
            gzip(&bytes) as f64 / 1e6,
            gzip(&bytes) as f64 / source as f64,
            without.len() as f64 / 1e6,
            gzip(&without) as f64 / 1e6,
            encode.as_secs_f64() * 1e3,
            decode.as_secs_f64() * 1e3,
            median(whole_ms),
            median(step_ms),
            median(served_ms),
            setup.as_secs_f64() * 1e3,
        );
    }
    Ok(())
}
