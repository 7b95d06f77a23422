//! What scene bundles weigh against the files they were made from: per scene the source's size
//! (the glTF with its buffers and images, or the GLB), the bundle raw and gzip-compressed as
//! `lightport serve` sends it, and the ratio gzip / source; with `--entries`, what each entry
//! of the bundle weighs, raw and gzip-compressed on its own.
//!
//! ```sh
//! cargo run --release --example bundle_sizes -- [--entries] [--write DIR] SCENE...
//! ```
//!
//! `--write DIR` also writes each bundle to `DIR/<scene>.lpb`; `--sky FILE` (`.hdr` or `.exr`)
//! adds that sky to every scene, as `lightport serve --sky` does, and counts its file in the
//! source.

use std::io::Write;
use std::path::{Path, PathBuf};

use tracer::pack::build_and_pack;

use tracer::kernel::RenderSettings;

fn gzip(bytes: &[u8]) -> usize {
    let mut encoder = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::default());
    encoder.write_all(bytes).expect("writing to memory");
    encoder.finish().expect("writing to memory").len()
}

/// The scene file and, for a `.gltf`, the files next to it that it names (buffers, images).
fn source_bytes(path: &Path) -> u64 {
    let size = |p: &Path| std::fs::metadata(p).map_or(0, |m| m.len());
    let mut total = size(path);
    if path.extension().is_some_and(|e| e.eq_ignore_ascii_case("gltf")) {
        let json: serde_json::Value =
            std::fs::read(path).ok().and_then(|b| serde_json::from_slice(&b).ok()).unwrap_or_default();
        let dir = path.parent().unwrap_or(Path::new("."));
        for list in ["buffers", "images"] {
            for item in json[list].as_array().into_iter().flatten() {
                if let Some(uri) = item["uri"].as_str().filter(|u| !u.starts_with("data:")) {
                    total += size(&dir.join(uri));
                }
            }
        }
    }
    total
}

fn mb(bytes: u64) -> String {
    format!("{:.2} MB", bytes as f64 / 1e6)
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let (mut entries, mut write, mut sky, mut paths) = (false, None, None, Vec::new());
    let mut args = std::env::args().skip(1);
    while let Some(arg) = args.next() {
        match arg.as_str() {
            "--entries" => entries = true,
            "--write" => write = Some(PathBuf::from(args.next().ok_or("--write takes a directory")?)),
            "--sky" => sky = Some(PathBuf::from(args.next().ok_or("--sky takes a .hdr or .exr file")?)),
            _ => paths.push(PathBuf::from(arg)),
        }
    }
    if paths.is_empty() {
        return Err("usage: bundle_sizes [--entries] [--write DIR] [--sky FILE] SCENE...".into());
    }
    println!("| scene | triangles | source | bundle raw | bundle gzip | gzip / source | encode | decode |");
    println!("|---|---|---|---|---|---|---|---|");
    let mut details = Vec::new();
    for path in &paths {
        let mut scene = tracer::scene::load(path)?;
        if let Some(sky) = &sky {
            scene.sky = Some(tracer::scene::load_sky(sky, 1.0, 0.0)?);
        }
        let (_, packed) = build_and_pack(&scene, &RenderSettings::default())?;
        let name = path.file_stem().unwrap_or_default().to_string_lossy().into_owned();
        let start = std::time::Instant::now();
        let bytes = tracer::bundle::encode_named(&name, &packed);
        let encode = start.elapsed().as_secs_f64() * 1e3;
        let start = std::time::Instant::now();
        tracer::bundle::decode(&bytes)?;
        let decode = start.elapsed().as_secs_f64() * 1e3;
        if let Some(dir) = &write {
            std::fs::write(dir.join(format!("{name}.lpb")), &bytes)?;
        }
        let sky_file = sky.as_deref().map_or(0, source_bytes);
        let (source, zipped) = (source_bytes(path) + sky_file, gzip(&bytes) as u64);
        println!(
            "| {name} | {} | {} | {} | {} | {:.2} | {encode:.0} ms | {decode:.0} ms |",
            packed.triangle_count,
            mb(source),
            mb(bytes.len() as u64),
            mb(zipped),
            zipped as f64 / source as f64
        );
        if entries {
            details.push((name, bytes));
        }
    }
    for (name, bytes) in details {
        println!("\n{name}: entries over 1 kB\n\n| entry | raw | gzip |\n|---|---|---|");
        for (entry, data) in tracer::bundle::entries(&bytes)?.into_iter().filter(|(_, data)| data.len() > 1000) {
            println!("| {entry} | {} | {} |", mb(data.len() as u64), mb(gzip(data) as u64));
        }
    }
    Ok(())
}
