//! A moving scene through a bundle: per scene (loaded with its motion kept), the bundle's size
//! with and without its motion section, the section's size, the encode and decode times, and
//! whether the moving parts read back pose to the same meshes and instances, bit for bit, as
//! the loaded scene at several times.
//!
//! ```sh
//! cargo run --release --example bundle_motion -- SCENE...   # e.g. ../shared/scenes/threejs/LittlestTokyo.glb
//! ```

use std::time::Instant;

use tracer::kernel::RenderSettings;
use tracer::scene::{AnimationChoice, LoadOptions};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let paths: Vec<String> = std::env::args().skip(1).collect();
    if paths.is_empty() {
        return Err("usage: bundle_motion SCENE...".into());
    }
    println!(
        "| scene | moves | bundle without motion | motion section | encode | decode | poses equal (bit for bit) |"
    );
    println!("|---|---|---|---|---|---|---|");
    for path in paths {
        let options = LoadOptions { keep_motion: true, animation: AnimationChoice::First, ..Default::default() };
        let scene = tracer::scene::load_with(std::path::Path::new(&path), &options)?;
        let Some(motion) = scene.motion.as_ref() else {
            println!("| {path} | nothing | | | | | |");
            continue;
        };
        let (describe, duration) = (motion.describe(), motion.duration());
        let (moving, packed) = tracer::pack::MovingScene::new(scene, &RenderSettings::default())?;
        let mut scene = moving.scene().clone();
        let without = tracer::bundle::encode_named("scene", &packed).len();
        let t0 = Instant::now();
        let bytes = tracer::bundle::encode_scene("scene", &packed, &scene);
        let encode = t0.elapsed();
        let t1 = Instant::now();
        let bundle = tracer::bundle::Bundle::decode(&bytes)?;
        let decode = t1.elapsed();
        let mut back = bundle.moving.ok_or("no motion section read back")?;
        let times: Vec<f32> = (0..8).map(|k| duration * k as f32 / 7.0 + 0.01).collect();
        let mut equal = 0;
        for &t in &times {
            scene.pose(t)?;
            back.pose(t)?;
            equal += (scene.meshes == back.meshes && scene.instances == back.instances) as usize;
        }
        println!(
            "| {} | {describe} | {:.2} MB | {:.2} MB | {:.0} ms | {:.0} ms | {equal} of {} |",
            std::path::Path::new(&path).file_name().map_or(path.clone(), |n| n.to_string_lossy().into_owned()),
            without as f64 / 1e6,
            (bytes.len() - without) as f64 / 1e6,
            encode.as_secs_f64() * 1e3,
            decode.as_secs_f64() * 1e3,
            times.len()
        );
    }
    Ok(())
}
