//! The inputs each target starts from: the test data (the Khronos glTF validator's corpus and
//! the test scenes vendored in `tests/data/`, or the larger `../shared` folder of the same
//! layout through `$LIGHTPORT_SHARED`), tiny inputs of every format made here, and the committed
//! regression inputs (`fuzz/regressions/<target>/`), each a crash the fuzzers found, minimised.

use std::io::Cursor;
use std::path::{Path, PathBuf};

use glam::Vec3;
use image::{DynamicImage, ImageFormat};
use serde_json::Value;
use tracer::kernel::RenderSettings;
use tracer::pack::build_and_pack;
use tracer::scene::{self, Sky};

use crate::targets::MTL_SEPARATOR;
use crate::Target;

/// A named input.
pub type Seed = (String, Vec<u8>);

/// The data folder (`scenes/`, `gltf-validator-tests/`): `$LIGHTPORT_SHARED` (e.g. the
/// larger `../shared` beside the repository, with the benchmark scenes), else the test data
/// vendored in the repository's `tests/data/`.
pub fn shared_dir() -> PathBuf {
    match std::env::var_os("LIGHTPORT_SHARED") {
        Some(dir) => PathBuf::from(dir),
        None => Path::new(env!("CARGO_MANIFEST_DIR")).join("../tests/data"),
    }
}

/// The folder of committed regression inputs for `target`.
pub fn regressions_dir(target: Target) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("regressions").join(target.name())
}

/// Every seed of `target` (data files that are missing are skipped: the generated seeds and
/// the regressions are always there), none longer than [`Target::max_len`].
pub fn seeds(target: Target) -> Vec<Seed> {
    let shared = shared_dir();
    let mut out = match target {
        Target::Gltf => gltf(&shared),
        Target::Obj => obj(&shared),
        Target::Texture => texture(&shared),
        Target::Sky => sky(&shared),
        Target::Bundle => bundle(),
        Target::Http => http(),
    };
    out.extend(regressions(target));
    out.retain(|(_, bytes)| bytes.len() <= target.max_len() && !bytes.is_empty());
    out
}

/// The committed regression inputs of `target`.
pub fn regressions(target: Target) -> Vec<Seed> {
    files_in(&regressions_dir(target), &|_| true)
}

fn files_in(dir: &Path, keep: &dyn Fn(&Path) -> bool) -> Vec<Seed> {
    let mut paths: Vec<PathBuf> = match std::fs::read_dir(dir) {
        Ok(entries) => entries.filter_map(|e| e.ok().map(|e| e.path())).filter(|p| p.is_file() && keep(p)).collect(),
        Err(_) => Vec::new(),
    };
    paths.sort();
    paths
        .into_iter()
        .filter_map(|p| Some((p.file_name()?.to_string_lossy().into_owned(), std::fs::read(&p).ok()?)))
        .collect()
}

/// Files under `dir` (recursively) with one of `extensions`, at most `max_bytes` each.
fn tree(dir: &Path, extensions: &[&str], max_bytes: u64) -> Vec<PathBuf> {
    let mut out = Vec::new();
    let mut stack = vec![dir.to_owned()];
    while let Some(d) = stack.pop() {
        let Ok(entries) = std::fs::read_dir(&d) else { continue };
        for e in entries.flatten() {
            let p = e.path();
            if p.is_dir() {
                stack.push(p);
            } else if extension_in(&p, extensions) && e.metadata().is_ok_and(|m| m.len() <= max_bytes) {
                out.push(p);
            }
        }
    }
    out.sort();
    out
}

fn extension_in(p: &Path, extensions: &[&str]) -> bool {
    p.extension().and_then(|e| e.to_str()).is_some_and(|e| extensions.contains(&e.to_ascii_lowercase().as_str()))
}

fn named(root: &Path, p: &Path, bytes: Vec<u8>) -> Seed {
    (p.strip_prefix(root).unwrap_or(p).to_string_lossy().replace('/', "_"), bytes)
}

/// A `.gltf` with its external buffers and images turned into data URIs (the target loads
/// from memory), when they exist; otherwise as it is (the loader's refusal is exercised too).
fn self_contained(path: &Path) -> Option<Vec<u8>> {
    let bytes = std::fs::read(path).ok()?;
    let Ok(mut root) = serde_json::from_slice::<Value>(&bytes) else { return Some(bytes) };
    let dir = path.parent()?;
    for list in ["buffers", "images"] {
        let Some(items) = root.get_mut(list).and_then(Value::as_array_mut) else { continue };
        for item in items {
            let Some(uri) = item.get("uri").and_then(Value::as_str) else { continue };
            if uri.starts_with("data:") {
                continue;
            }
            let Ok(data) = std::fs::read(dir.join(uri)) else { continue };
            if data.len() > 32 << 10 {
                return None; // too big a seed
            }
            item["uri"] = Value::String(format!("data:application/octet-stream;base64,{}", base64(&data)));
        }
    }
    serde_json::to_vec(&root).ok()
}

fn base64(data: &[u8]) -> String {
    const ALPHABET: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let mut out = String::with_capacity(data.len().div_ceil(3) * 4);
    for chunk in data.chunks(3) {
        let b = [chunk[0], *chunk.get(1).unwrap_or(&0), *chunk.get(2).unwrap_or(&0)];
        let n = u32::from(b[0]) << 16 | u32::from(b[1]) << 8 | u32::from(b[2]);
        for i in 0..4 {
            if i <= chunk.len() {
                out.push(ALPHABET[(n >> (18 - 6 * i) & 63) as usize] as char);
            } else {
                out.push('=');
            }
        }
    }
    out
}

fn gltf(shared: &Path) -> Vec<Seed> {
    let mut out = Vec::new();
    for root in [shared.join("gltf-validator-tests"), shared.join("scenes")] {
        for p in tree(&root, &["gltf", "glb"], 64 << 10) {
            let bytes = if extension_in(&p, &["gltf"]) { self_contained(&p) } else { std::fs::read(&p).ok() };
            if let Some(bytes) = bytes {
                out.push(named(shared, &p, bytes));
            }
        }
    }
    out.push(("generated_textured_quad.glb".into(), crate::glb::textured_quad(&crate::targets::tiny_images().0)));
    out.push(("generated_draco_grid.glb".into(), crate::glb::draco_grid()));
    out
}

fn obj(shared: &Path) -> Vec<Seed> {
    let mut out = Vec::new();
    let scenes = shared.join("scenes");
    for p in tree(&scenes, &["obj"], 16 << 10) {
        let Ok(mut bytes) = std::fs::read(&p) else { continue };
        // The MTL library it names, when it is next to it.
        let text = String::from_utf8_lossy(&bytes).into_owned();
        let mtl = text.lines().find_map(|l| l.strip_prefix("mtllib ")).map(|m| p.with_file_name(m.trim()));
        if let Some(Ok(mtl)) = mtl.map(std::fs::read) {
            bytes.extend_from_slice(MTL_SEPARATOR);
            bytes.extend_from_slice(&mtl);
        }
        out.push(named(shared, &p, bytes));
    }
    let textured = "mtllib t.mtl\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nvn 0 0 1\n\
        usemtl lamp\nf 1/1/1 2/2/1 3/3/1\nusemtl wall\nf 1/1/1 3/3/1 4/4/1\n#---mtl---\n\
        newmtl lamp\nKd 0.5 0.5 0.5\nKe 4 4 4\nmap_Ke -bm 1 glow.jpg\nnewmtl wall\nKd 0.8 0.2 0.2\nmap_Kd wall.png\nKs 1 1 1\nd 0.5\n";
    out.push(("generated_textured.obj".into(), textured.as_bytes().to_vec()));
    out
}

/// `image` encoded as `format`.
fn encode(image: DynamicImage, format: ImageFormat) -> Vec<u8> {
    let mut out = Cursor::new(Vec::new());
    image.write_to(&mut out, format).expect("encode a seed image");
    out.into_inner()
}

fn texture(shared: &Path) -> Vec<Seed> {
    let mut out = Vec::new();
    for p in tree(&shared.join("gltf-validator-tests"), &["png", "jpg", "jpeg", "webp"], 32 << 10) {
        if let Ok(bytes) = std::fs::read(&p) {
            out.push(named(shared, &p, bytes));
        }
    }
    for p in tree(&shared.join("scenes"), &["png", "jpg", "jpeg"], 8 << 10) {
        if let Ok(bytes) = std::fs::read(&p) {
            out.push(named(shared, &p, bytes));
        }
    }
    // Every layout the decoder takes: grey, grey + alpha, RGB, RGBA, 16-bit; PNG and JPEG.
    let rgba = image::RgbaImage::from_fn(5, 3, |x, y| image::Rgba([x as u8 * 50, y as u8 * 80, 128, 200]));
    let rgba = DynamicImage::ImageRgba8(rgba);
    let layouts = [
        ("l8", DynamicImage::ImageLuma8(rgba.to_luma8())),
        ("la8", DynamicImage::ImageLumaA8(rgba.to_luma_alpha8())),
        ("rgb8", DynamicImage::ImageRgb8(rgba.to_rgb8())),
        ("rgba8", rgba.clone()),
        ("rgba16", DynamicImage::ImageRgba16(rgba.to_rgba16())),
    ];
    for (name, image) in layouts {
        out.push((format!("generated_{name}.png"), encode(image.clone(), ImageFormat::Png)));
        if matches!(name, "l8" | "rgb8") {
            out.push((format!("generated_{name}.jpg"), encode(image, ImageFormat::Jpeg)));
        }
    }
    out
}

fn sky(shared: &Path) -> Vec<Seed> {
    let mut out = Vec::new();
    for p in tree(&shared.join("scenes"), &["hdr", "exr"], 48 << 10) {
        if let Ok(bytes) = std::fs::read(&p) {
            out.push(named(shared, &p, bytes));
        }
    }
    let sky = image::Rgb32FImage::from_fn(8, 4, |x, y| image::Rgb([x as f32 * 0.5, y as f32, 2.0]));
    out.push(("generated.hdr".into(), encode(DynamicImage::ImageRgb32F(sky.clone()), ImageFormat::Hdr)));
    out.push(("generated.exr".into(), encode(DynamicImage::ImageRgb32F(sky.clone()), ImageFormat::OpenExr)));
    let rgba = DynamicImage::ImageRgb32F(sky).to_rgba32f();
    out.push(("generated_rgba.exr".into(), encode(DynamicImage::ImageRgba32F(rgba), ImageFormat::OpenExr)));
    out
}

/// Bundles of the generated scenes at a small image size: diffuse only, emissive triangles and
/// point lights, a sky made in code (its texels travel) and one from a file (the file
/// travels: `tracer/src/bundle/sky.rs`), textures.
fn bundle() -> Vec<Seed> {
    let settings = RenderSettings { width: 8, height: 6, ..RenderSettings::default() };
    let mut with_sky = scene::diffuse_plane(Vec3::splat(0.5));
    with_sky.sky = Some(Sky {
        width: 4,
        height: 2,
        texels: (0..8).map(|i| Vec3::splat(i as f32)).collect(),
        intensity: 1.0,
        rotation: 0.0,
        file: None,
    });
    let mut with_sky_file = scene::diffuse_plane(Vec3::splat(0.5));
    let hdr = image::Rgb32FImage::from_fn(8, 4, |x, y| image::Rgb([x as f32 * 0.5, y as f32, 2.0]));
    let hdr = encode(DynamicImage::ImageRgb32F(hdr), ImageFormat::Hdr);
    with_sky_file.sky = scene::load_sky_slice(&hdr, scene::SkyFormat::Hdr, "generated.hdr", 1.0, 0.0).ok();
    let textured =
        scene::load_gltf_slice(&crate::glb::textured_quad(&crate::targets::tiny_images().0), None, &Default::default());
    // Two levels: placements the decoder's checks must bound (roots, transforms, flags).
    let mut scenes =
        vec![("cornell_box", scene::cornell_box()), ("sky", with_sky), ("instanced", scene::instanced_shapes(2))];
    if with_sky_file.sky.is_some() {
        scenes.push(("sky_file", with_sky_file));
    }
    if let Ok(t) = textured {
        scenes.push(("textured", t));
    }
    let mut out: Vec<Seed> = scenes
        .into_iter()
        .filter_map(|(name, scene)| {
            let (_, packed) = build_and_pack(&scene, &settings).ok()?;
            Some((format!("generated_{name}.lpb"), tracer::bundle::encode_named(name, &packed)))
        })
        .collect();
    out.extend(moving_bundle(&settings).map(|bytes| ("generated_moving.lpb".to_string(), bytes)));
    out
}

/// The bundle of a scene that moves, with its motion section (`tracer/src/bundle/motion.rs`):
/// the vendored moving-scene glTF (a skinned, morphed mesh, instances under a moving node, every
/// interpolation), loaded with its motion kept.
pub fn moving_bundle(settings: &RenderSettings) -> Option<Vec<u8>> {
    let path =
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../tests/data/scenes/generated/animated-skinned-instanced.gltf");
    let options = scene::LoadOptions { keep_motion: true, ..Default::default() };
    let scene = scene::load_gltf_slice(&std::fs::read(path).ok()?, None, &options).ok()?;
    let (moving, packed) = tracer::pack::MovingScene::new(scene, settings).ok()?;
    Some(tracer::bundle::encode_scene("moving", &packed, moving.scene()))
}

fn http() -> Vec<Seed> {
    let requests = [
        "GET / HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n",
        "GET /scenes.json HTTP/1.1\r\nHost: 127.0.0.1\r\nAccept-Encoding: gzip\r\n\r\n",
        "HEAD /index.html HTTP/1.1\r\nHost: 127.0.0.1\r\nIf-None-Match: \"abc\"\r\n\r\n",
        "GET /main.js HTTP/1.1\r\nHost: x\r\nConnection: keep-alive\r\n\r\nGET /style.css HTTP/1.1\r\nHost: x\r\n\r\n",
        "POST /scenes.json HTTP/1.1\r\nHost: x\r\nContent-Length: 4\r\n\r\nabcd",
        "GET /bundles/x.lpb HTTP/1.0\r\n\r\n",
        "GET /../../etc/passwd HTTP/1.1\r\nHost: x\r\n\r\n",
        "OPTIONS * HTTP/1.1\r\nHost: x\r\n\r\n",
    ];
    requests.iter().enumerate().map(|(i, r)| (format!("request_{i}"), r.as_bytes().to_vec())).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn base64_matches_the_standard() {
        assert_eq!(base64(b"hello"), "aGVsbG8=");
        assert_eq!(base64(b"ab"), "YWI=");
        assert_eq!(base64(b"abc"), "YWJj");
    }
}
