//! `lightport render BUNDLE.lpb`: an exported bundle renders natively, posed at `--time` when
//! its scene moves, as its scene file renders; a static one as its source, bit for bit; the
//! options that need the scene file are refused by name; a damaged bundle is an error, never
//! a panic.

use crate::common;

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

/// A directory removed on drop.
struct TempDir(PathBuf);

impl TempDir {
    fn new(tag: &str) -> TempDir {
        let nanos = std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH).unwrap().subsec_nanos();
        let dir = std::env::temp_dir().join(format!("lightport-render-bundle-{tag}-{}-{nanos}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        TempDir(dir)
    }
}

impl Drop for TempDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// `common::moving_parts_gltf` (a skinned and morphed mesh and three placements, all moving,
/// lit by a point light) seen by a camera of its own: without one, the camera is framed around
/// the pose the scene is loaded at, which a bundle keeps from its export.
fn moving_gltf_with_camera() -> Vec<u8> {
    let mut json: serde_json::Value = serde_json::from_slice(&common::moving_parts_gltf()).unwrap();
    json["cameras"] = serde_json::json!([{"type": "perspective", "perspective": {"yfov": 0.9, "znear": 0.01}}]);
    let nodes = json["nodes"].as_array_mut().unwrap();
    nodes.push(serde_json::json!({"camera": 0, "translation": [0.5, 1.0, 6.0]}));
    let camera = nodes.len() - 1;
    json["scenes"][0]["nodes"].as_array_mut().unwrap().push(camera.into());
    serde_json::to_vec(&json).unwrap()
}

/// `lightport export SCENE --out DIR/site` (with a stand-in page: only the bundles matter here):
/// each scene's name and bundle path, from scenes.json.
fn export(scene: &Path, dir: &Path, args: &[&str]) -> Vec<(String, PathBuf)> {
    let web = dir.join("web");
    std::fs::create_dir_all(web.join("www")).unwrap();
    std::fs::create_dir_all(web.join("pkg")).unwrap();
    std::fs::write(web.join("www/index.html"), "<!doctype html>").unwrap();
    std::fs::write(web.join("pkg/lightport_web_bg.wasm"), "").unwrap();
    std::fs::write(web.join("pkg/lightport_web.js"), "").unwrap();
    let site = dir.join("site");
    let o = Command::new(env!("CARGO_BIN_EXE_lightport"))
        .arg("export")
        .arg(scene)
        .arg("--out")
        .arg(&site)
        .arg("--web")
        .arg(&web)
        .args(args)
        .output()
        .expect("run lightport export");
    assert!(o.status.success(), "{}", stderr(&o));
    let list: serde_json::Value = serde_json::from_slice(&std::fs::read(site.join("scenes.json")).unwrap()).unwrap();
    list["scenes"]
        .as_array()
        .unwrap()
        .iter()
        .map(|s| (s["name"].as_str().unwrap().to_owned(), site.join(s["url"].as_str().unwrap())))
        .collect()
}

fn bundle_of<'a>(bundles: &'a [(String, PathBuf)], name: &str) -> &'a Path {
    &bundles.iter().find(|(n, _)| n == name).unwrap_or_else(|| panic!("no bundle {name}: {bundles:?}")).1
}

/// `lightport render SCENE ARGS` on the CPU at depth 4: `Err` with its error output.
fn run(scene: Option<&Path>, out: &Path, args: &[&str]) -> Result<(), String> {
    let o = Command::new(env!("CARGO_BIN_EXE_lightport"))
        .arg("render")
        .args(scene)
        .args(["--backend", "cpu", "--max-depth", "4", "--out"])
        .arg(out)
        .args(args)
        .output()
        .expect("run lightport render");
    let err = stderr(&o);
    assert!(!err.contains("panicked"), "{err}");
    match o.status.success() {
        true => Ok(()),
        false => Err(err),
    }
}

/// [`run`] at 24x24 (unless `args` size it) into the EXR `out`: its floats.
fn render(scene: Option<&Path>, out: &Path, args: &[&str]) -> Result<Vec<f32>, String> {
    let size: &[&str] = if args.contains(&"--width") { &[] } else { &["--width", "24", "--height", "24"] };
    run(scene, out, &[size, args].concat())?;
    Ok(image::open(out).expect("an EXR").into_rgb32f().into_raw())
}

/// The error of a render that must be refused.
fn refused(result: Result<Vec<f32>, String>, what: &str) -> String {
    result.err().unwrap_or_else(|| panic!("{what}: rendered instead of being refused"))
}

/// Means of the channels over the image's 4 x 4 blocks of 6 x 6 pixels, then over the whole
/// (24 x 24) image.
fn region_means(image: &[f32]) -> Vec<f64> {
    let pixel = |i: usize| glam::DVec3::new(image[3 * i] as f64, image[3 * i + 1] as f64, image[3 * i + 2] as f64);
    let regions = common::region_means(24, 4, pixel);
    regions.iter().flat_map(|r| r.to_array()).collect()
}

/// Per region and channel: the mean of the seeds' region means and its variance (of the mean).
fn over_seeds(runs: &[Vec<f64>]) -> Vec<(f64, f64)> {
    (0..runs[0].len())
        .map(|k| {
            let (mean, variance, n) = common::mean_variance(runs.iter().map(|r| r[k]));
            (mean, variance / n as f64)
        })
        .collect()
}

/// The animated scene's bundle, exported at 0 s, renders at `--time 0.7` as the scene file
/// does at `--time 0.7`: the same regions' means within 5 combined standard errors over four
/// seeds. Not bit for bit: the scene file at one time loads flattened into one BVH level, the
/// bundle keeps its moving parts placed by instances (two levels), so hits are computed in
/// instance space, to other roundings. With the same seed the two agree to the last bits in
/// nearly every pixel (counted and printed). `--frames` on the bundle renders each frame bit
/// for bit as `--frames` on the scene file (both pose a two-level scene with `pack::Posing`;
/// without a sky, the light list is the same at every pose).
#[test]
fn an_animated_bundle_renders_at_the_time_asked_as_its_scene_file() {
    let dir = TempDir::new("moving");
    let gltf = dir.0.join("moving.gltf");
    std::fs::write(&gltf, moving_gltf_with_camera()).unwrap();
    let bundles = export(&gltf, &dir.0, &[]);
    let bundle = bundle_of(&bundles, "moving");
    let out = |name: &str| dir.0.join(name);
    let (mut from_bundle, mut from_file, mut at_export) = (Vec::new(), Vec::new(), Vec::new());
    let mut differing = 0;
    for seed in ["1", "2", "3", "4"] {
        let args = ["--spp", "16", "--seed", seed, "--time", "0.7"];
        let b = render(Some(bundle), &out("b.exr"), &args).unwrap();
        let f = render(Some(&gltf), &out("f.exr"), &args).unwrap();
        let zero = render(Some(&gltf), &out("z.exr"), &["--spp", "16", "--seed", seed, "--time", "0"]).unwrap();
        differing += b.iter().zip(&f).filter(|(x, y)| x.to_bits() != y.to_bits()).count();
        from_bundle.push(region_means(&b));
        from_file.push(region_means(&f));
        at_export.push(region_means(&zero));
    }
    let (b, f, z) = (over_seeds(&from_bundle), over_seeds(&from_file), over_seeds(&at_export));
    let z_of = |a: &[(f64, f64)], c: &[(f64, f64)]| {
        // A region no sample varies in still differs by roundings (a relative 1e-5).
        let se = |x: (f64, f64), y: (f64, f64)| (x.1 + y.1).sqrt().max(1e-5 * x.0.abs().max(y.0.abs())).max(1e-9);
        a.iter().zip(c).map(|(&x, &y)| (x.0 - y.0).abs() / se(x, y)).fold(0.0, f64::max)
    };
    let (agree, apart) = (z_of(&b, &f), z_of(&b, &z));
    println!("bundle at 0.7 s against the file at 0.7 s: largest z {agree:.2}; {differing} of {} floats differ in bits; against the file at 0 s: largest z {apart:.1}", 4 * 24 * 24 * 3);
    assert!(agree < 5.0, "the bundle at 0.7 s renders unlike its scene file at 0.7 s (z {agree})");
    assert!(apart > 5.0, "the poses at 0 s and 0.7 s look alike (z {apart}): the test would prove nothing");

    // --frames on the bundle: each frame as the scene file's, bit for bit.
    let frames = ["--spp", "4", "--seed", "3", "--time", "0.2", "--frames", "3", "--until", "1", "--width", "20"];
    let frames = [&frames[..], &["--height", "12", "--strategy", "nee"]].concat();
    run(Some(bundle), &out("bf.exr"), &frames).unwrap();
    run(Some(&gltf), &out("ff.exr"), &frames).unwrap();
    let read = |name: &str| image::open(out(name)).expect("a frame").into_rgb32f().into_raw();
    let size = image::image_dimensions(out("bf-000.exr")).unwrap();
    assert_eq!(size, (20, 12), "the bundle's frames are rendered at the size asked");
    for k in 0..3 {
        let (b, f) = (read(&format!("bf-{k:03}.exr")), read(&format!("ff-{k:03}.exr")));
        assert!(b.iter().any(|v| *v > 0.0), "frame {k} is black");
        assert!(b == f, "frame {k}: the bundle's differs from the scene file's");
    }
    assert!(read("bf-000.exr") != read("bf-002.exr"), "the bundle's frames do not move");
}

/// A static bundle (the built-in Cornell box every export carries) renders as its source, bit
/// for bit: the same packed arrays; only the camera's aspect and the settings are uniforms set
/// again (the export packed it square). `--time` changes nothing, as on a scene file that does
/// not move; `--frames` is refused.
#[test]
fn a_static_bundle_renders_as_its_source() {
    let dir = TempDir::new("static");
    let gltf = dir.0.join("moving.gltf");
    std::fs::write(&gltf, moving_gltf_with_camera()).unwrap();
    let bundles = export(&gltf, &dir.0, &[]);
    let cornell = bundle_of(&bundles, "cornell-box");
    let args = ["--spp", "4", "--seed", "9", "--width", "20", "--height", "16"];
    let source = render(None, &dir.0.join("source.exr"), &args).unwrap();
    let bundle = render(Some(cornell), &dir.0.join("bundle.exr"), &args).unwrap();
    assert!(source.iter().any(|v| *v > 0.0), "a black image would prove nothing");
    assert!(source == bundle, "the Cornell box's bundle renders unlike the Cornell box");
    let later = render(Some(cornell), &dir.0.join("later.exr"), &[&args[..], &["--time", "3"]].concat()).unwrap();
    assert!(later == bundle, "--time moved a scene that does not move");
    let err = run(Some(cornell), &dir.0.join("frames.exr"), &["--frames", "2"]).unwrap_err();
    assert!(err.contains("--frames") && err.contains("does not move"), "{err}");
}

/// What needs the scene file is refused on a bundle, naming the option; a missing bundle is
/// an error too.
#[test]
fn options_that_need_the_scene_file_are_refused_on_a_bundle() {
    let dir = TempDir::new("options");
    let gltf = dir.0.join("moving.gltf");
    std::fs::write(&gltf, moving_gltf_with_camera()).unwrap();
    let bundles = export(&gltf, &dir.0, &[]);
    let (moving, cornell) = (bundle_of(&bundles, "moving"), bundle_of(&bundles, "cornell-box"));
    let sky = common::test_data("scenes/hdri/venice_sunset_1k.hdr");
    let sky = sky.to_str().unwrap();
    let out = dir.0.join("out.exr");
    for (bundle, args, says) in [
        (moving, vec!["--sky", sky], "--sky"),
        (cornell, vec!["--sky-intensity", "2"], "--sky-intensity"),
        (cornell, vec!["--sky-rotation", "90"], "--sky-rotation"),
        (moving, vec!["--flatten"], "--flatten"),
        (moving, vec!["--animation", "another"], "--animation another"),
        (cornell, vec!["--animation", "all"], "--animation all"),
        (moving, vec!["--time", "NaN"], "--time"),
    ] {
        let err = refused(render(Some(bundle), &out, &args), &format!("{args:?}"));
        assert!(err.starts_with("error: ") && err.contains(says), "{args:?}: {err}");
    }
    // The animation the bundle carries may be named.
    render(Some(moving), &out, &["--animation", "all", "--spp", "1"]).unwrap();
    let err = refused(render(Some(&dir.0.join("absent.lpb")), &out, &[]), "a missing bundle");
    assert!(err.contains("absent.lpb"), "{err}");
}

/// A damaged bundle (truncated, bytes flipped) is refused with a message, never a panic; a
/// bundle is known by its magic bytes under any name.
#[test]
fn a_damaged_bundle_is_an_error_not_a_panic() {
    let dir = TempDir::new("damaged");
    let gltf = dir.0.join("moving.gltf");
    std::fs::write(&gltf, moving_gltf_with_camera()).unwrap();
    let bundles = export(&gltf, &dir.0, &[]);
    let good = std::fs::read(bundle_of(&bundles, "moving")).unwrap();
    let out = dir.0.join("out.exr");
    let args = ["--spp", "1", "--time", "0.5"];
    // Under another name, known by its first bytes.
    let renamed = dir.0.join("scene.bin");
    std::fs::write(&renamed, &good).unwrap();
    render(Some(&renamed), &out, &args).unwrap();

    let damaged = dir.0.join("damaged.lpb");
    for len in [0, 7, 100, good.len() / 2, good.len() - 1] {
        std::fs::write(&damaged, &good[..len]).unwrap();
        let err = refused(render(Some(&damaged), &out, &args), &format!("{len} bytes"));
        assert!(err.starts_with("error: ") && err.contains("truncated"), "{len} bytes: {err}");
    }
    // Flips in the header and in the first entry's name and type are refused; a flip anywhere
    // is refused or renders (a float of the data may take another value), never a panic.
    for at in [0, 9, 25, 26, 28] {
        let mut bad = good.clone();
        bad[at] ^= 0x5a;
        std::fs::write(&damaged, &bad).unwrap();
        let err = refused(render(Some(&damaged), &out, &args), &format!("byte {at} flipped"));
        assert!(err.starts_with("error: ") && err.contains("bundle"), "byte {at}: {err}");
    }
    let (mut refused, mut rendered) = (0, 0);
    for at in (0..good.len()).step_by(53) {
        let mut bad = good.clone();
        bad[at] ^= 0xff;
        std::fs::write(&damaged, &bad).unwrap();
        match render(Some(&damaged), &out, &args) {
            Ok(_) => rendered += 1,
            Err(e) => {
                assert!(e.starts_with("error: "), "byte {at}: {e}");
                refused += 1;
            }
        }
    }
    println!("bytes flipped one at a time: {refused} refused, {rendered} rendered");
    assert!(refused > 0);
}

/// `lightport chart SCENE --reference-dir DIR`, CPU MIS only, 16x16: its reference image (EXR
/// floats) and the reference's own mean squared error per pixel and channel.
fn chart_reference(scene: &Path, dir: &Path, args: &[&str]) -> (Vec<f32>, f64) {
    let o = Command::new(env!("CARGO_BIN_EXE_lightport"))
        .arg("chart")
        .arg(scene)
        .args(["--backends", "cpu", "--strategies", "mis", "--schedules", "megakernel", "--size", "16"])
        .args(["--spp", "2", "--reference-spp", "64", "--out-dir"])
        .arg(dir.join("chart"))
        .arg("--reference-dir")
        .arg(dir.join("reference"))
        .args(args)
        .output()
        .expect("run lightport chart");
    assert!(o.status.success(), "{}", stderr(&o));
    let exr = std::fs::read_dir(dir.join("reference"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .find(|p| p.extension().is_some_and(|e| e == "exr"))
        .expect("a reference image");
    let key = std::fs::read_to_string(exr.with_extension("txt")).unwrap();
    let noise: f64 = key.rsplit("noise_mse: ").next().unwrap().trim().parse().unwrap();
    (image::open(&exr).unwrap().into_rgb32f().into_raw(), noise)
}

/// `chart` takes a bundle as `render` does: posed at `--time`, its reference (a long CPU MIS
/// render) is the scene file's at that time, within the references' own noise (the RMS of
/// their difference under 3 x what two independent references would differ by); the pose at
/// 0 s is far from it. `--sky` is refused.
#[test]
fn chart_takes_a_bundle_posed_at_the_time_asked() {
    let dir = TempDir::new("chart");
    let gltf = dir.0.join("moving.gltf");
    std::fs::write(&gltf, moving_gltf_with_camera()).unwrap();
    let bundles = export(&gltf, &dir.0, &[]);
    let bundle = bundle_of(&bundles, "moving");
    let (b, noise_b) = chart_reference(bundle, &dir.0.join("bundle"), &["--time", "0.7"]);
    let (f, noise_f) = chart_reference(&gltf, &dir.0.join("file"), &["--time", "0.7"]);
    let (z, _) = chart_reference(&gltf, &dir.0.join("zero"), &["--time", "0"]);
    let rms = |a: &[f32], c: &[f32]| {
        (a.iter().zip(c).map(|(x, y)| ((x - y) as f64).powi(2)).sum::<f64>() / a.len() as f64).sqrt()
    };
    let bound = 3.0 * (noise_b + noise_f).sqrt();
    let (agree, apart) = (rms(&b, &f), rms(&b, &z));
    println!(
        "chart references: bundle vs file at 0.7 s RMS {agree:.2e}, vs the file at 0 s {apart:.2e}; bound {bound:.2e}"
    );
    assert!(b.iter().any(|v| *v > 0.0), "a black reference would prove nothing");
    assert!(agree < bound, "the bundle's chart at 0.7 s is not the scene file's (RMS {agree:e}, bound {bound:e})");
    assert!(apart > bound, "the poses at 0 s and 0.7 s look alike (RMS {apart:e}): the test would prove nothing");
    let sky = common::test_data("scenes/hdri/venice_sunset_1k.hdr");
    let o = Command::new(env!("CARGO_BIN_EXE_lightport"))
        .arg("chart")
        .arg(bundle)
        .arg("--sky")
        .arg(&sky)
        .args(["--backends", "cpu", "--out-dir"])
        .arg(dir.0.join("sky"))
        .output()
        .expect("run lightport chart");
    assert!(!o.status.success() && stderr(&o).contains("--sky"), "{}", stderr(&o));
}

/// `bytes` as a glTF buffer's data URI.
fn data_uri(bytes: &[u8]) -> String {
    use base64::Engine;
    format!("data:application/octet-stream;base64,{}", base64::engine::general_purpose::STANDARD.encode(bytes))
}

/// Appends `bytes` to the glTF `json`'s buffers, as a data URI.
fn push_buffer(json: &mut serde_json::Value, bytes: &[u8]) {
    let buffer = serde_json::json!({"byteLength": bytes.len(), "uri": data_uri(bytes)});
    json["buffers"].as_array_mut().unwrap().push(buffer);
}

/// A floor, a point light, a camera and a triangle (node 1) whose animation scales it from 1
/// at 0 s to `scale_at_1` at 1 s (LINEAR), under a node of scale `parent_scale`. The camera
/// sees the triangle (at rest) against nothing: no sky, and the floor ends before the rays
/// that pass it could reach it.
fn scaled_gltf(scale_at_1: f32, parent_scale: f32) -> Vec<u8> {
    let floor =
        [[-2.0, 0.0, -2.0], [2.0, 0.0, -2.0], [2.0, 0.0, 2.0], [-2.0, 0.0, -2.0], [2.0, 0.0, 2.0], [-2.0, 0.0, 2.0]];
    let triangle = [[0.0, 0.5, 0.0], [1.0, 0.5, 0.0], [0.0, 1.5, 0.0f32]];
    let mut bytes: Vec<u8> = floor.iter().chain(&triangle).flatten().flat_map(|v: &f32| v.to_le_bytes()).collect();
    let keys = [0.0f32, 1.0, 1.0, 1.0, 1.0, scale_at_1, scale_at_1, scale_at_1];
    bytes.extend(keys.iter().flat_map(|v| v.to_le_bytes()));
    let uri = data_uri(&bytes);
    let json = serde_json::json!({
        "asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": [0, 4, 2, 3]}],
        "nodes": [
            {"mesh": 0},
            {"mesh": 1, "name": "shrinking"},
            {"translation": [0.5, 3, 3], "extensions": {"KHR_lights_punctual": {"light": 0}}},
            {"camera": 0, "translation": [0.4, 1, 2.5]},
            {"children": [1], "scale": [parent_scale, parent_scale, parent_scale]}
        ],
        "extensionsUsed": ["KHR_lights_punctual"],
        "extensions": {"KHR_lights_punctual": {"lights": [{"type": "point", "intensity": 60}]}},
        "cameras": [{"type": "perspective", "perspective": {"yfov": 0.8, "znear": 0.01}}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0}}]}, {"primitives": [{"attributes": {"POSITION": 1}}]}],
        "animations": [{"name": "scale", "channels": [{"sampler": 0, "target": {"node": 1, "path": "scale"}}],
                        "samplers": [{"input": 2, "output": 3}]}],
        "buffers": [{"byteLength": bytes.len(), "uri": uri}],
        "bufferViews": [
            {"buffer": 0, "byteOffset": 0, "byteLength": 72}, {"buffer": 0, "byteOffset": 72, "byteLength": 36},
            {"buffer": 0, "byteOffset": 108, "byteLength": 8}, {"buffer": 0, "byteOffset": 116, "byteLength": 24}
        ],
        "accessors": [
            {"bufferView": 0, "componentType": 5126, "count": 6, "type": "VEC3", "min": [-2, 0, -2], "max": [2, 0, 2]},
            {"bufferView": 1, "componentType": 5126, "count": 3, "type": "VEC3", "min": [0, 0.5, 0], "max": [1, 1.5, 0]},
            {"bufferView": 2, "componentType": 5126, "count": 2, "type": "SCALAR", "min": [0], "max": [1]},
            {"bufferView": 3, "componentType": 5126, "count": 2, "type": "VEC3"}
        ]
    });
    serde_json::to_vec(&json).unwrap()
}

/// [`scaled_gltf`] (`parent_scale` 1) with its triangle (node 1) skinned instead of scaled:
/// one joint (node 5, at (0, 3, 0), its inverse bind matrix undoing that, so that at rest the
/// triangle is where it is unskinned) that the animation scales from 1 at 0 s to `scale_at_1`
/// at 1 s. The joint's matrix has (0, 3, 0) + scale x (0, -3, 0) in translation: from a scale
/// of about 1.1e38 on, it is not finite.
fn skinned_gltf(scale_at_1: f32) -> Vec<u8> {
    let mut json: serde_json::Value = serde_json::from_slice(&scaled_gltf(scale_at_1, 1.0)).unwrap();
    let mut bytes = vec![0u8; 12]; // JOINTS_0: joint 0 for every vertex (unsigned bytes)
    let weights = [1.0f32, 0.0, 0.0, 0.0].repeat(3);
    let inverse_bind = glam::Mat4::from_translation(glam::Vec3::new(0.0, -3.0, 0.0)).to_cols_array();
    bytes.extend(weights.iter().chain(&inverse_bind).flat_map(|v| v.to_le_bytes()));
    push_buffer(&mut json, &bytes);
    json["bufferViews"].as_array_mut().unwrap().extend([
        serde_json::json!({"buffer": 1, "byteOffset": 0, "byteLength": 12}),
        serde_json::json!({"buffer": 1, "byteOffset": 12, "byteLength": 48}),
        serde_json::json!({"buffer": 1, "byteOffset": 60, "byteLength": 64}),
    ]);
    json["accessors"].as_array_mut().unwrap().extend([
        serde_json::json!({"bufferView": 4, "componentType": 5121, "count": 3, "type": "VEC4"}),
        serde_json::json!({"bufferView": 5, "componentType": 5126, "count": 3, "type": "VEC4"}),
        serde_json::json!({"bufferView": 6, "componentType": 5126, "count": 1, "type": "MAT4"}),
    ]);
    let attributes = &mut json["meshes"][1]["primitives"][0]["attributes"];
    (attributes["JOINTS_0"], attributes["WEIGHTS_0"]) = (4.into(), 5.into());
    json["nodes"][1]["skin"] = 0.into();
    json["nodes"].as_array_mut().unwrap().push(serde_json::json!({"name": "joint", "translation": [0, 3, 0]}));
    json["skins"] = serde_json::json!([{"joints": [5], "inverseBindMatrices": 6}]);
    json["animations"][0]["channels"][0]["target"]["node"] = 5.into();
    serde_json::to_vec(&json).unwrap()
}

/// [`scaled_gltf`] (`parent_scale` 1) with its triangle (node 1) morphed instead of scaled: a
/// morph target moving its top vertex by (0, 2, 0), whose weight the animation holds at 0
/// until 1 s and sets to `weight_at_1` from then on (STEP): from a weight of 1.7e38 on, the
/// morphed vertex is not finite.
fn morphed_gltf(weight_at_1: f32) -> Vec<u8> {
    let mut json: serde_json::Value = serde_json::from_slice(&scaled_gltf(1.0, 1.0)).unwrap();
    let values = [0.0f32, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 2.0, 0.0, 0.0, weight_at_1];
    let bytes: Vec<u8> = values.iter().flat_map(|v| v.to_le_bytes()).collect();
    push_buffer(&mut json, &bytes);
    json["bufferViews"].as_array_mut().unwrap().extend([
        serde_json::json!({"buffer": 1, "byteOffset": 0, "byteLength": 36}),
        serde_json::json!({"buffer": 1, "byteOffset": 36, "byteLength": 8}),
    ]);
    json["accessors"].as_array_mut().unwrap().extend([
        serde_json::json!({"bufferView": 4, "componentType": 5126, "count": 3, "type": "VEC3", "min": [0, 0, 0], "max": [0, 2, 0]}),
        serde_json::json!({"bufferView": 5, "componentType": 5126, "count": 2, "type": "SCALAR"}),
    ]);
    json["meshes"][1]["primitives"][0]["targets"] = serde_json::json!([{"POSITION": 4}]);
    json["animations"][0]["channels"][0]["target"]["path"] = "weights".into();
    json["animations"][0]["samplers"][0] = serde_json::json!({"input": 2, "output": 5, "interpolation": "STEP"});
    serde_json::to_vec(&json).unwrap()
}

/// A pose whose transform for a placement cannot be inverted (the animation scales the node
/// to zero at 1 s) or is not finite (scaled by 1e30 under a parent of scale 1e10: the product
/// overflows), or that makes a skinned mesh's joint matrix non-finite (its joint scaled by
/// 3e38: from 0.5 s on) or a morphed vertex non-finite (a weight of 3e38 from 1 s on), drops
/// that placement or mesh with one warning, and `--strict`
/// refuses it, whichever path poses it: the scene file at `--time 1` (flattened at load),
/// `--frames` on it (a kept motion posed frame by frame) and its bundle at `--time 1` (posed
/// from the motion section). Never a panic or a non-finite pixel; where the pose places it
/// nothing is said. Dropped means gone from the image: the pixels where the triangle shows at
/// rest, against nothing (black without it), are black at 1 s.
#[test]
fn a_placement_a_pose_cannot_place_is_dropped_with_one_warning() {
    let dir = TempDir::new("dropped");
    let small = ["--width", "12", "--height", "12", "--spp", "2"];
    let render_small = |scene: &Path, args: &[&str], out: &Path| {
        Command::new(env!("CARGO_BIN_EXE_lightport"))
            .arg("render")
            .arg(scene)
            .args(small)
            .args(args)
            .arg("--out")
            .arg(out)
            .output()
            .unwrap()
    };
    let read = |path: &Path| image::open(path).unwrap().into_rgb32f().into_raw();
    // Where the triangle shows at rest against nothing: lit with it, black without it.
    let rest = dir.0.join("rest.gltf");
    std::fs::write(&rest, scaled_gltf(1.0, 1.0)).unwrap();
    let mut json: serde_json::Value = serde_json::from_slice(&scaled_gltf(1.0, 1.0)).unwrap();
    json["nodes"][1].as_object_mut().unwrap().remove("mesh");
    let without = dir.0.join("without.gltf");
    std::fs::write(&without, serde_json::to_vec(&json).unwrap()).unwrap();
    let images: Vec<Vec<f32>> = [&rest, &without]
        .iter()
        .map(|scene| {
            let out = dir.0.join("reference.exr");
            let o = render_small(scene, &[], &out);
            assert!(o.status.success(), "{}", stderr(&o));
            read(&out)
        })
        .collect();
    let pixel = |image: &[f32], i: usize| image[3 * i] + image[3 * i + 1] + image[3 * i + 2];
    let region: Vec<usize> =
        (0..12 * 12).filter(|&i| pixel(&images[0], i) > 0.0 && pixel(&images[1], i) == 0.0).collect();
    println!("the triangle shows against nothing in {} of 144 pixels", region.len());
    assert!(region.len() >= 8, "the triangle covers too few pixels to tell: {region:?}");
    for (name, gltf, why, placed_at) in [
        ("zero", scaled_gltf(0.0, 1.0), "cannot be inverted", "0.5"),
        ("overflow", scaled_gltf(1e30, 1e10), "is not finite", "0"),
        ("skin", skinned_gltf(3e38), "is not finite (a joint's matrix", "0"),
        ("morph", morphed_gltf(3e38), "is not finite (its morph weights", "0.5"),
        // Finite, but carried beyond the world (scene::WORLD_LIMIT): at 1e20 the load's camera
        // framing overflowed ("invalid camera") before.
        ("beyond", scaled_gltf(1e20, 1.0), "places it beyond 1e12 units", "0"),
        ("skin-beyond", skinned_gltf(1e20), "is not finite (a joint's matrix", "0"),
        ("morph-beyond", morphed_gltf(1e20), "is not finite (its morph weights", "0"),
    ] {
        let sub = dir.0.join(name);
        std::fs::create_dir_all(&sub).unwrap();
        let file = sub.join(format!("{name}.gltf"));
        std::fs::write(&file, gltf).unwrap();
        let bundles = export(&file, &sub, &["--time", "0"]);
        let bundle = bundle_of(&bundles, name).to_owned();
        let ways: [(&str, &Path, Vec<&str>); 4] = [
            ("the file", &file, vec!["--time", "1"]),
            ("--frames", &file, vec!["--frames", "3", "--until", "1"]),
            // Loaded at a time the pose drops it (the kept motion's load-time pose).
            ("--frames from 1 s", &file, vec!["--frames", "3", "--time", "1", "--until", "1"]),
            ("the bundle", &bundle, vec!["--time", "1"]),
        ];
        for (way, scene, args) in ways {
            let out = sub.join("out.exr");
            let o = render_small(scene, &args, &out);
            let err = stderr(&o);
            assert!(o.status.success(), "{name}, {way}: {err}");
            let warnings: Vec<&str> = err.lines().filter(|l| l.starts_with("warning: ")).collect();
            assert!(
                warnings.len() == 1 && warnings[0].contains("node 1") && warnings[0].contains(why),
                "{name}, {way}: one warning: {err}"
            );
            let stdout = String::from_utf8_lossy(&o.stdout);
            assert!(!stdout.contains("non-finite"), "{name}, {way}: {stdout}");
            let last = if way.starts_with("--frames") { sub.join("out-002.exr") } else { out };
            let image = read(&last);
            assert!(image.iter().all(|v| v.is_finite()) && image.iter().any(|v| *v > 0.0), "{name}, {way}");
            let seen: Vec<usize> = region.iter().copied().filter(|&i| pixel(&image, i) != 0.0).collect();
            assert!(seen.is_empty(), "{name}, {way}: at 1 s the dropped triangle still shows in pixels {seen:?}");
            let strict = render_small(scene, &[&args[..], &["--strict"]].concat(), &sub.join("strict.exr"));
            let err = stderr(&strict);
            assert!(!strict.status.success() && err.contains("--strict") && err.contains(why), "{name}, {way}: {err}");
            assert!(!err.contains("panicked"), "{err}");
        }
        let before =
            run(Some(&bundle), &sub.join("before.exr"), &[&small[..], &["--time", placed_at, "--strict"]].concat());
        assert!(before.is_ok(), "{name}: at {placed_at} s nothing is dropped: {before:?}");
        let at_rest = render_small(&file, &["--time", "0", "--strict"], &sub.join("at-rest.exr"));
        assert!(at_rest.status.success(), "{name}: {}", stderr(&at_rest));
        if name != "overflow" {
            // At rest (scale 1 under a parent of 1) the triangle shows where it does in rest.gltf.
            let image = read(&sub.join("at-rest.exr"));
            let missing: Vec<usize> = region.iter().copied().filter(|&i| pixel(&image, i) == 0.0).collect();
            assert!(missing.len() < region.len() / 4, "{name}: at 0 s the triangle does not show: {missing:?}");
        }
    }
}
