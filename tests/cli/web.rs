//! The web path tracer end to end: `lightport serve`, the page and its wasm build (`web/`,
//! built by `scripts/build-web.sh`) in headless Chromium (Debian's `chromium`, driven by
//! `tests/web/run.mjs` through npm `playwright-core`). The node script only drives the page and
//! reports what it saw; the statistics and assertions are here.
//!
//! Never skipped: without `web/pkg/`, `node`, `tests/web/node_modules` or `/usr/bin/chromium`
//! these tests fail and say which command installs the missing piece (`scripts/test.sh` runs
//! them all).

mod animation;
mod api;
mod denoise;
mod fallback;
mod layout;
mod preview;
mod wavefront;

use crate::common;
use crate::common::browser;
use lightport::serve_child;

use std::path::Path;
use std::time::Duration;

use api::api_report;
use browser::{browse, no_page_error};
use glam::{DVec3, Vec3};
use serde_json::Value;
use tracer::backend::cpu::CpuRenderer;
use tracer::backend::Renderer;
use tracer::kernel::{RenderSettings, Strategy};
use tracer::pack::{pack, Packed};
use tracer::scene::{self, Scene};
use tracer::stats::Estimate;

/// |CPU - browser| within 5 combined standard errors per region and channel, as for the native
/// GL backend (tests/rendering/gl.rs).
const Z_BOUND: f64 = 5.0;
/// Regions per side: the image's 4 x 4 blocks, plus the whole image.
const BLOCKS: u32 = 4;
/// The render size of the browser tests (SwiftShader is slow; the statistics need many frames).
const SIZE: u32 = 32;
/// `lightport serve` packs bundles with the default settings; the page keeps their depth.
const SERVED_MAX_DEPTH: u32 = 8;

fn root() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

/// `lightport serve` on a free port, killed when dropped.
struct Server {
    _process: serve_child::Killed,
    url: String,
}

impl Server {
    fn start(args: &[&str]) -> Server {
        assert!(
            root().join("web/pkg/lightport_web_bg.wasm").is_file(),
            "web/pkg/ is missing: run scripts/build-web.sh (it builds the wasm module the page loads)"
        );
        let exe = Path::new(env!("CARGO_BIN_EXE_lightport"));
        let (process, url) = serve_child::start_serve(exe, args, Duration::from_secs(120), true)
            .unwrap_or_else(|e| panic!("lightport serve {args:?}: {e}"));
        Server { _process: process, url }
    }
}

/// Batch means per region and channel: for each batch, the mean of the samples it added over
/// each 4 x 4 block and (last) the whole image. `sums` are running sums after each batch.
fn batch_regions(sums: &[Vec<DVec3>], frames_per_batch: f64) -> Vec<Vec<DVec3>> {
    let mut previous = vec![DVec3::ZERO; (SIZE * SIZE) as usize];
    let mut out = Vec::new();
    for batch in sums {
        out.push(common::region_means(SIZE, BLOCKS, |i| (batch[i] - previous[i]) / frames_per_batch));
        previous.clone_from(batch);
    }
    out
}

fn estimate(batches: &[Vec<DVec3>], region: usize, channel: usize) -> Estimate {
    Estimate::from_samples(&batches.iter().map(|b| b[region][channel]).collect::<Vec<_>>())
}

fn packed(scene: &Scene, strategy: Strategy) -> Packed {
    let bvh = tracer::bvh::build(&scene.triangles).expect("BVH");
    let settings = RenderSettings { width: SIZE, height: SIZE, strategy, max_depth: SERVED_MAX_DEPTH };
    pack(scene, &bvh, &settings).expect("pack")
}

/// Renders `scene_name` in the browser (on `api`: "webgl2" or "webgpu") and `scene` on the CPU
/// in `batches` x `frames` frames and asserts that every region agrees within the bound.
fn assert_browser_agrees_with_cpu(server: &Server, scene_name: &str, scene: &Scene, strategy: Strategy, api: &str) {
    assert_page_agrees_with_cpu(server, scene_name, scene, strategy, api, "auto");
}

/// [`assert_browser_agrees_with_cpu`] with the page's `schedule` ("auto", "megakernel" or
/// "wavefront"; auto runs the megakernel).
fn assert_page_agrees_with_cpu(
    server: &Server,
    scene_name: &str,
    scene: &Scene,
    strategy: Strategy,
    api: &str,
    schedule: &str,
) {
    let runs = if schedule == "wavefront" { "wavefront" } else { "megakernel" };
    assert_page_runs_and_agrees_with_cpu(server, scene_name, scene, strategy, api, schedule, &[], runs);
}

/// [`assert_page_agrees_with_cpu`] with more of the `accumulate` scenario's options (`extra`),
/// the page running schedule `runs` once it has started; returns the scenario's report.
#[allow(clippy::too_many_arguments)]
fn assert_page_runs_and_agrees_with_cpu(
    server: &Server,
    scene_name: &str,
    scene: &Scene,
    strategy: Strategy,
    api: &str,
    schedule: &str,
    extra: &[(&str, &str)],
    runs: &str,
) -> Value {
    let (batches, frames) = (16usize, 16u32);
    let size = format!("{SIZE}x{SIZE}");
    let (batch_text, frame_text) = (batches.to_string(), frames.to_string());
    let mut options = vec![
        ("scene", scene_name),
        ("size", &size),
        ("strategy", strategy.name()),
        ("batches", &batch_text),
        ("frames", &frame_text),
        ("api", api),
        ("schedule", schedule),
    ];
    options.extend_from_slice(extra);
    let report = browse(&server.url, "accumulate", &options);
    no_page_error(&report);
    let info = &report["info"];
    eprintln!("{scene_name}: {} on {}, {} ({})", info["name"], info["api"], info["schedule"], info["adapter"]);
    assert_eq!(info["strategy"], strategy.name());
    let shown = if api == "webgpu" { "WebGPU" } else { "WebGL2" };
    assert_eq!(info["api"], shown, "the page runs the API asked for: {info}");
    assert_eq!(info["schedule"], runs, "the page runs the schedule asked for: {info}");
    // The read-out names a two-level scene's placements (the static triangles' one included).
    let placements = info["placements"].as_u64().expect("placements");
    let want = if scene.instances.is_empty() { 0 } else { scene.instances.len() as u64 + 1 };
    assert_eq!(placements, want, "{scene_name}: placements in the read-out: {info}");
    let mut browser_sums = Vec::new();
    for (b, batch) in report["batches"].as_array().expect("batches").iter().enumerate() {
        let spp = batch["spp"].as_u64().expect("spp");
        assert_eq!(spp, (b as u64 + 1) * frames as u64, "frames rendered by batch {b}");
        assert_eq!((batch["width"].as_u64(), batch["height"].as_u64()), (Some(SIZE as u64), Some(SIZE as u64)));
        let data: Vec<f64> =
            batch["data"].as_array().expect("data").iter().map(|v| v.as_f64().unwrap_or(f64::NAN)).collect();
        assert_eq!(data.len(), (SIZE * SIZE * 4) as usize);
        // w counts the finite samples: none may have been dropped.
        let rejected = data.chunks_exact(4).filter(|t| t[3] != spp as f64).count();
        assert_eq!(rejected, 0, "{scene_name}: pixels with non-finite samples in the browser");
        browser_sums.push(data.chunks_exact(4).map(|t| DVec3::new(t[0], t[1], t[2])).collect::<Vec<_>>());
    }
    assert_eq!(browser_sums.len(), batches);

    let mut cpu = CpuRenderer::new(packed(scene, strategy), 7);
    let mut cpu_sums = Vec::new();
    for _ in 0..batches {
        for _ in 0..frames {
            cpu.render_frame().expect("frame");
        }
        let n = cpu.frames() as f64;
        cpu_sums.push(cpu.image().expect("image").pixels.iter().map(|p| p.as_dvec3() * n).collect::<Vec<_>>());
    }
    assert_eq!(cpu.rejected_samples().expect("accumulation"), 0);

    let browser = batch_regions(&browser_sums, frames as f64);
    let cpu = batch_regions(&cpu_sums, frames as f64);
    let mut worst = 0.0f64;
    for region in 0..(BLOCKS * BLOCKS) as usize + 1 {
        for c in 0..3 {
            let (a, b) = (estimate(&cpu, region, c), estimate(&browser, region, c));
            let z = a.z_score(&b);
            assert!(
                z < Z_BOUND,
                "{scene_name} region {region} channel {c}: CPU {} ± {} vs browser {} ± {} (z = {z:.2})",
                a.mean,
                a.std_err,
                b.mean,
                b.std_err
            );
            worst = worst.max(z);
        }
    }
    let whole = estimate(&browser, (BLOCKS * BLOCKS) as usize, 1);
    assert!(whole.mean > 0.0, "{scene_name}: the browser's image is black");
    eprintln!(
        "{scene_name} {strategy:?} {SIZE}x{SIZE} x {} frames: max z {worst:.2}; whole-image green {:.4} ± {:.4}",
        batches as u32 * frames,
        whole.mean,
        whole.std_err
    );
    report
}

const STRATEGIES: [Strategy; 3] = [Strategy::Bsdf, Strategy::Nee, Strategy::Mis];

#[test]
fn the_browser_agrees_with_the_cpu_on_the_cornell_box() {
    let server = Server::start(&[]);
    assert_browser_agrees_with_cpu(&server, "cornell-box", &scene::cornell_box(), Strategy::Mis, "webgl2");
}

/// The same statistics on the page's WebGPU runtime (the wgpu backend's WGSL compute kernel on
/// Chromium's WebGPU, SwiftShader), for each strategy.
#[test]
fn the_browser_agrees_with_the_cpu_on_the_cornell_box_on_webgpu() {
    let server = Server::start(&[]);
    for strategy in STRATEGIES {
        assert_browser_agrees_with_cpu(&server, "cornell-box", &scene::cornell_box(), strategy, "webgpu");
    }
}

/// BoxTextured under venice_sunset, served as the page gets it, and loaded here for the CPU.
fn textured_scene() -> (Server, Scene) {
    let gltf = common::test_data("scenes/khronos/BoxTextured/glTF/BoxTextured.gltf");
    let sky = common::test_data("scenes/hdri/venice_sunset_1k.hdr");
    let server = Server::start(&[gltf.to_str().unwrap(), "--sky", sky.to_str().unwrap()]);
    let mut scene = scene::load(&gltf).expect("BoxTextured");
    scene.sky = Some(scene::load_sky(&sky, 1.0, 0.0).expect("sky"));
    (server, scene)
}

/// A served scene that nothing lights (Khronos' Box) is lit by the default white sky: the page
/// renders what the CPU renders of the scene lit so (it was a black canvas, with the warning
/// printed only by `serve`), and shows the warning.
#[test]
fn a_served_unlit_scene_is_lit_by_the_default_sky_as_on_the_cpu() {
    let path = common::test_data("scenes/khronos/Box/glTF-Binary/Box.glb");
    let server = Server::start(&[path.to_str().unwrap()]);
    let mut scene = scene::load(&path).expect("Box");
    assert!(scene.light_if_unlit().is_some(), "nothing lights Box");
    let report = assert_page_runs_and_agrees_with_cpu(
        &server,
        "Box",
        &scene,
        Strategy::Mis,
        "webgl2",
        "auto",
        &[],
        "megakernel",
    );
    let warnings = report["warnings"].as_str().unwrap_or_default();
    assert!(warnings.contains("lit by a uniform white sky"), "the page shows the warning: {report:.300}");
}

#[test]
fn the_browser_agrees_with_the_cpu_on_a_textured_scene() {
    let (server, scene) = textured_scene();
    assert_browser_agrees_with_cpu(&server, "BoxTextured", &scene, Strategy::Mis, "webgl2");
}

#[test]
fn the_browser_agrees_with_the_cpu_on_a_textured_scene_on_webgpu() {
    let (server, scene) = textured_scene();
    for strategy in STRATEGIES {
        assert_browser_agrees_with_cpu(&server, "BoxTextured", &scene, strategy, "webgpu");
    }
}

/// Glass (the glass Cornell box, served by its built-in name): the delta and rough lobes,
/// refraction in and out of volumes and absorption, on WebGL2 and WebGPU, each strategy.
#[test]
fn the_browser_agrees_with_the_cpu_on_glass() {
    let server = Server::start(&["glass-cornell"]);
    let scene = scene::glass_cornell();
    for api in ["webgl2", "webgpu"] {
        for strategy in STRATEGIES {
            assert_browser_agrees_with_cpu(&server, "glass-cornell", &scene, strategy, api);
        }
    }
}

/// Two levels (`Features::instances`; generated scenes served by their built-in names): the
/// page's WebGL2 and WebGPU kernels traverse both levels as the CPU does, on the field of
/// mirrored and non-uniformly scaled placements and on the stress field (10,000 placements of
/// a 10,240-triangle sphere: 102 million triangles placed, within the page's memory).
#[test]
fn the_browser_agrees_with_the_cpu_on_instanced_scenes() {
    let server = Server::start(&["instanced-shapes", "instanced-field"]);
    for name in ["instanced-shapes", "instanced-field"] {
        let scene = scene::builtin(name).expect("built in");
        assert!(!scene.instances.is_empty());
        for api in ["webgl2", "webgpu"] {
            assert_browser_agrees_with_cpu(&server, name, &scene, Strategy::Mis, api);
        }
    }
}

/// A grey plane (an OBJ written here: the page loads files) under venice_sunset: only the sky
/// lights it, so NEE and MIS sample the sky's importance table.
fn sky_lit_plane() -> (Server, Scene) {
    let dir = std::env::temp_dir().join(format!("lightport-web-plane-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("temp dir");
    std::fs::write(dir.join("plane.mtl"), "newmtl grey\nKd 0.6 0.6 0.6\n").expect("mtl");
    let obj = "mtllib plane.mtl\nv -10 0 10\nv 10 0 10\nv 10 0 -10\nv -10 0 -10\nusemtl grey\nf 1 2 3\nf 1 3 4\n";
    let path = dir.join("plane.obj");
    std::fs::write(&path, obj).expect("obj");
    let sky = common::test_data("scenes/hdri/venice_sunset_1k.hdr");
    let server = Server::start(&[path.to_str().unwrap(), "--sky", sky.to_str().unwrap()]);
    let mut scene = scene::load(&path).expect("plane");
    scene.sky = Some(scene::load_sky(&sky, 1.0, 0.0).expect("sky"));
    (server, scene)
}

#[test]
fn the_browser_agrees_with_the_cpu_under_an_hdr_sky() {
    let (server, scene) = sky_lit_plane();
    for (strategy, api) in [(Strategy::Mis, "webgl2")].into_iter().chain(STRATEGIES.map(|s| (s, "webgpu"))) {
        assert_browser_agrees_with_cpu(&server, "plane", &scene, strategy, api);
    }
}

/// A bundle's textures travel as the files they were loaded from (DamagedHelmet: JPEGs) and the
/// page decodes them in wasm: to the very texels the native loader made, or the browser and
/// the CPU reference would render different scenes.
#[test]
fn the_page_decodes_a_bundles_images_to_the_native_texels() {
    let helmet = common::test_data("scenes/khronos/DamagedHelmet/glTF-Binary/DamagedHelmet.glb");
    let server = Server::start(&[helmet.to_str().unwrap()]);
    let report = api_report(&server, "webgl2", &[("scene", "DamagedHelmet")]);
    no_page_error(&report);
    let native = packed(&scene::load(&helmet).expect("DamagedHelmet"), Strategy::Mis);
    assert!(native.texture_images.len() >= 4, "the scene has JPEG textures");
    assert_eq!(report["info"]["name"], "DamagedHelmet");
    assert_eq!(report["textureChecksum"], native.texture_checksum(), "the page's texels differ");
    // The read-outs run every animation frame: they must not read the texels (the checksum
    // did, ~100-400 ms a frame on textured scenes, and the frame loop's bands fell to one row).
    let readouts: Vec<f64> =
        report["readoutMs"].as_array().expect("readoutMs").iter().filter_map(Value::as_f64).collect();
    assert!(readouts.len() >= 8, "too few animation frames to judge: {readouts:?}");
    let median = median(&readouts);
    assert!(median < 20.0, "the read-outs take {median:.1} ms per animation frame (median): {readouts:?}");
}

#[test]
fn the_second_visit_takes_the_scene_from_the_client_cache() {
    let server = Server::start(&[]);
    let report = browse(&server.url, "cache", &[("scene", "cornell-box"), ("size", "16x16")]);
    let visit = |name: &str| {
        let v = &report[name];
        no_page_error(v);
        (v["bundleRequests"].as_array().expect("requests").len(), v["bytesFetched"].as_u64().expect("bytes"))
    };
    let (requests, bytes) = visit("first");
    assert_eq!(requests, 1, "the first visit downloads the bundle once: {}", report["first"]);
    assert!(bytes > 0);
    let first = &report["first"];
    assert_eq!(first["usage"]["scenes"], 1, "{first}");
    assert_eq!(first["usage"]["bytes"].as_u64(), Some(bytes), "the cache holds the bundle: {first}");

    let (requests, bytes) = visit("second");
    assert_eq!((requests, bytes), (0, 0), "the second visit fetches no scene bytes: {}", report["second"]);
    assert_eq!(report["second"]["sources"][0]["fromCache"], true);
    let readout = report["second"]["readout"].as_str().unwrap_or("");
    assert!(readout.contains("1 scene"), "the page shows the cache use: {readout:?}");

    assert_eq!(report["cleared"]["usage"]["scenes"], 0, "clear cache empties it");
    let (requests, bytes) = visit("third");
    assert!(requests == 1 && bytes > 0, "after clearing, the scene is downloaded again: {}", report["third"]);
}

#[test]
fn camera_input_restarts_the_accumulation() {
    let server = Server::start(&[]);
    let report = browse(&server.url, "camera", &[("scene", "cornell-box"), ("size", "32x32")]);
    no_page_error(&report);
    let steps = &report["steps"];
    let step = |name: &str| steps[name].as_u64().unwrap_or_else(|| panic!("{name} in {steps}"));
    assert_eq!(step("beforeDrag"), 8);
    assert_eq!(step("afterDrag"), 0, "a mouse drag restarts the accumulation: {steps}");
    assert_eq!(step("afterDragRendered"), 8);
    assert_eq!(step("afterWheel"), 0, "the wheel restarts the accumulation: {steps}");
    assert_eq!(step("afterWheelRendered"), 3);
    assert_eq!(step("afterStrategy"), 0, "a strategy change restarts the accumulation: {steps}");
    // The drag turned the view: the image changed (the box's walls moved across the pixels).
    let image =
        |name: &str| -> Vec<f64> { report[name].as_array().expect("image").iter().filter_map(Value::as_f64).collect() };
    let (before, after) = (image("before"), image("after"));
    assert_eq!(before.len(), after.len());
    let changed = before
        .chunks_exact(4)
        .zip(after.chunks_exact(4))
        .filter(|(a, b)| (a[0] - b[0]).abs() > 0.5 * (a[0].abs() + 1.0))
        .count();
    assert!(changed > before.len() / 4 / 20, "the drag must move the view: {changed} pixels changed");
}

#[test]
fn a_bad_dropped_file_shows_an_error_and_the_page_keeps_working() {
    let server = Server::start(&[]);
    let dir = common::test_data("scenes/khronos/BoxTextured/glTF");
    let files: Vec<String> = ["BoxTextured.gltf", "BoxTextured0.bin", "CesiumLogoFlat.png"]
        .iter()
        .map(|f| dir.join(f).to_string_lossy().into_owned())
        .collect();
    let files = files.join(",");
    let report = browse(&server.url, "drop", &[("scene", "cornell-box"), ("size", "16x16"), ("files", &files)]);
    no_page_error(&report);
    let bad = report["badError"].as_str().expect("an error for the broken file");
    assert!(bad.contains("broken.glb"), "the error names the file: {bad}");
    assert_eq!(report["messageVisible"], true, "the error is shown on the page");
    let after = &report["afterBad"];
    assert_eq!(after["name"], "cornell-box", "the previous scene stays: {after}");
    assert_eq!(after["after"].as_u64(), after["before"].as_u64().map(|n| n + 2), "it keeps rendering: {after}");
    let good = &report["good"];
    assert!(good["error"].is_null(), "{good}");
    assert_eq!(good["info"]["name"], "BoxTextured.gltf", "{good}");
    assert_eq!(good["info"]["triangles"], 12);
    assert_eq!(good["info"]["features"]["textures"], true, "the dropped PNG was found: {good}");
    // Nothing lights BoxTextured: the page lights it with the default sky, as `serve` does,
    // and says so.
    assert_eq!(good["info"]["features"]["sky"], true, "{good}");
    let warnings = good["warnings"].as_str().unwrap_or_default();
    assert!(warnings.contains("lit by a uniform white sky"), "{good}");
    assert!(good["message"].as_str().unwrap_or_default().contains(warnings), "the page shows it: {good}");
    assert_eq!(good["spp"], 2);
}

/// A Draco-compressed GLB (`KHR_draco_mesh_compression`) dropped on the page is decoded in
/// wasm by the native loader's code: the same triangles as loaded natively, rendered.
#[test]
fn a_dropped_draco_file_is_decoded_in_the_page() {
    let server = Server::start(&[]);
    let path = common::test_data("scenes/generated/draco-grid.glb");
    let native = scene::load(&path).expect("the Draco GLB loads natively");
    let report =
        browse(&server.url, "drop", &[("scene", "cornell-box"), ("size", "16x16"), ("files", &path.to_string_lossy())]);
    no_page_error(&report);
    let good = &report["good"];
    assert!(good["error"].is_null(), "{good}");
    assert_eq!(good["info"]["name"], "draco-grid.glb", "{good}");
    assert_eq!(good["info"]["triangles"].as_u64(), Some(native.triangles.len() as u64), "{good}");
    assert_eq!(good["spp"], 2);
}

#[test]
fn a_scene_beyond_the_texture_limit_is_reported_on_the_page() {
    let server = Server::start(&[]);
    let report = browse(&server.url, "limits", &[("scene", "cornell-box"), ("size", "16x16"), ("limit", "4")]);
    let error = report["error"].as_str().expect("an error");
    assert!(error.contains("GL_MAX_TEXTURE_SIZE 4"), "{error}");
    assert!(report["messageText"].as_str().unwrap_or("").contains("does not fit"), "{report}");
}

#[test]
fn the_page_survives_webgl_context_loss() {
    let server = Server::start(&[]);
    let report = browse(&server.url, "context", &[("scene", "cornell-box"), ("size", "16x16")]);
    no_page_error(&report);
    let message = report["whileLost"]["message"].as_str().unwrap_or("");
    assert!(message.contains("lost"), "the loss is shown: {message:?}");
    let restored = &report["restored"];
    assert!(restored["error"].is_null(), "{restored}");
    assert_eq!(restored["spp"], 3, "rendering continues after the restore: {restored}");
    assert!(restored["sum"].as_f64().unwrap_or(0.0) > 0.0, "the restored renderer draws the scene");
}

/// The page shows what the CLI's PNG output stores with the same `--tonemap` and `--exposure`:
/// for a setting given in the URL and three chosen through the page's controls, the canvas's
/// pixels are within 2 8-bit steps of `to_display_srgb8` of the accumulation they show
/// (SwiftShader's pow and the CPU's differ in the last bits), and the settings differ.
#[test]
fn the_page_shows_the_tone_mapped_image_the_cli_writes() {
    use tracer::backend::Image;
    use tracer::output::{to_display_srgb8, Display, ToneMap};

    let server = Server::start(&[]);
    let report = browse(&server.url, "display", &[("scene", "cornell-box"), ("size", "16x16")]);
    no_page_error(&report);
    let expected = [("aces", 1.5), ("agx", -1.0), ("none", 0.0), ("neutral", 0.0)];
    let shots = report["shots"].as_array().expect("the display scenario's shots");
    assert_eq!(shots.len(), expected.len(), "{report}");
    let mut shown: Vec<Vec<u8>> = Vec::new();
    for (shot, (name, exposure)) in shots.iter().zip(expected) {
        assert_eq!(shot["toneMap"], name, "the page reports the tone map it was given");
        assert_eq!(shot["exposure"].as_f64(), Some(exposure), "the page reports the exposure it was given");
        let accumulation = &shot["accumulation"];
        let number = |v: &Value| v.as_f64().expect("a number");
        let (width, height) = (number(&accumulation["width"]) as u32, number(&accumulation["height"]) as u32);
        let spp = number(&accumulation["spp"]) as f32;
        let data: Vec<f32> = accumulation["data"].as_array().expect("data").iter().map(|v| number(v) as f32).collect();
        let pixels = data.chunks(4).map(|t| Vec3::new(t[0], t[1], t[2]) / spp).collect();
        let image = Image { width, height, pixels };
        let tone_map = ToneMap::from_name(name).expect("a tone map");
        let png = to_display_srgb8(&image, &Display { tone_map, exposure: exposure as f32 });
        let canvas: Vec<u8> = shot["pixels"].as_array().expect("pixels").iter().map(|v| number(v) as u8).collect();
        assert_eq!(canvas.len(), (width * height * 4) as usize, "one RGBA pixel per image pixel");
        let worst = (0..(width * height) as usize)
            .flat_map(|p| (0..3).map(move |c| (p, c)))
            .map(|(p, c)| canvas[p * 4 + c].abs_diff(png[p * 3 + c]))
            .max()
            .unwrap_or(0);
        assert!(worst <= 2, "{name} at {exposure} EV: the canvas is {worst} 8-bit steps from the PNG");
        shown.push(png);
    }
    for (i, a) in shown.iter().enumerate() {
        assert!(shown[i + 1..].iter().all(|b| a != b), "two display settings gave the same image: nothing is tested");
    }
}

/// The viewer's camera changes go through `GlRenderer::set_uniforms`, which must restart the
/// accumulation and render exactly what a renderer created at the new camera renders (same
/// seed, same device). Native GL (EGL), no browser.
#[test]
fn set_uniforms_renders_like_a_fresh_renderer() {
    use tracer::backend::gl::GlRenderer;
    let base = packed(&scene::cornell_box(), Strategy::Mis);
    let mut moved = base.clone();
    moved.scene.camera_position += Vec3::new(0.2, -0.1, 0.3);
    moved.scene.strategy = Strategy::Nee.uniform_value();
    let camera = (moved.scene.camera_position, moved.scene.strategy);

    let mut reused = GlRenderer::headless(base, 5).expect("GL");
    for _ in 0..3 {
        reused.render_frame().expect("frame");
    }
    reused
        .set_uniforms(&mut |s| {
            s.camera_position = camera.0;
            s.strategy = camera.1;
        })
        .expect("set_uniforms");
    assert_eq!(reused.frames(), 0);
    let mut fresh = GlRenderer::headless(moved, 5).expect("GL");
    for _ in 0..4 {
        reused.render_frame().expect("frame");
        fresh.render_frame().expect("frame");
    }
    let (a, b) = (reused.accumulation().expect("readback"), fresh.accumulation().expect("readback"));
    assert!(a.iter().zip(&b).all(|(x, y)| x == y), "same uniforms and seed must give the same accumulation");

    let err = reused.set_uniforms(&mut |s| s.width += 1).expect_err("the size is fixed");
    assert!(err.to_string().contains("fixed"), "{err}");
    assert_eq!(reused.packed().scene.width, SIZE, "a refused change leaves the size as it was");
}

/// The page's frame budget: no single GPU submission (a band of a frame) should take longer.
const BAND_BUDGET_MS: f64 = tracer::backend::frame_split::DEFAULT_BUDGET_MS;

/// Input-to-restart times (ms) of the `slow` scenario. `at_once`: each input reset the sample
/// counter before the driver's input call returned (unsplit, a pointer move waits for the
/// frame in flight before it is handled at all).
fn restart_latencies(report: &Value, at_once: bool) -> Vec<f64> {
    let restarts = report["restarts"].as_array().expect("restarts");
    restarts
        .iter()
        .map(|r| {
            let t = |k: &str| r[k].as_f64().unwrap_or_else(|| panic!("{k} in {r}"));
            if at_once {
                assert_eq!(r["sppAfterInput"], 0, "the input reset the sample counter at once: {r}");
            }
            assert!(t("inputAt") <= t("handledAt") && t("handledAt") <= t("submittedAt"), "{r}");
            assert!(t("submittedAt") <= t("doneAt"), "{r}");
            t("doneAt") - t("inputAt")
        })
        .collect()
}

fn median(values: &[f64]) -> f64 {
    let mut v = values.to_vec();
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

/// A slow device (SwiftShader: seconds per 640x480 frame of the Cornell box) stays responsive:
/// the page splits each frame into bands of at most the budget, one on the GPU at a time, so a
/// camera drag during a frame restarts the accumulation within a small multiple of the budget
/// (from the event to the restarted accumulation's first image done on the GPU: its preview, a
/// sixteenth of a frame, submitted whole; else its first band), not after the
/// frame in flight. Unsplit (`bandBudget=0`), the same input waits for the whole frame.
#[test]
fn camera_input_during_a_slow_frame_restarts_within_the_budget() {
    assert_input_restarts_within_the_budget("webgl2");
}

/// The same on WebGPU: bands are dispatches over fewer rows, each timed by the queue's
/// `onSubmittedWorkDone`.
#[test]
fn camera_input_during_a_slow_frame_restarts_within_the_budget_on_webgpu() {
    assert_input_restarts_within_the_budget("webgpu");
}

fn assert_input_restarts_within_the_budget(api: &str) {
    let server = Server::start(&[]);
    let budget = BAND_BUDGET_MS.to_string();
    let split = browse(
        &server.url,
        "slow",
        &[
            ("scene", "cornell-box"),
            ("size", "640x480"),
            ("bandBudget", &budget),
            ("inputs", "7"),
            ("api", api),
            // The megakernel's bands; under auto the page may measure and switch to the wavefront.
            ("schedule", "megakernel"),
        ],
    );
    no_page_error(&split);
    let info = &split["info"];
    let shown = if api == "webgpu" { "WebGPU" } else { "WebGL2" };
    assert_eq!(info["api"], shown, "the page runs the API asked for: {info}");
    let frame_ms = split["frameMs"].as_f64().expect("frameMs");
    let bands = info["bands"].as_u64().expect("bands");
    let band_ms = info["bandMs"].as_f64().expect("a measured band time");
    let latencies = restart_latencies(&split, true);
    eprintln!(
        "split ({api}): {} on {}: whole frame {frame_ms:.0} ms; {bands} bands of {} rows, ~{band_ms:.0} ms; the frame \
         loop {:.0} ms a frame; input to restarted band done (ms): {latencies:.0?}; read-out {:?}",
        info["name"],
        info["adapter"],
        info["bandRows"],
        split["loopFrameMs"].as_f64().unwrap_or(f64::NAN),
        split["readout"]
    );
    assert!(frame_ms > 4.0 * BAND_BUDGET_MS, "a slow device: a whole frame takes {frame_ms} ms");
    assert!(bands > 1, "the frame is split: {info}");
    // A band's share of a whole frame's GPU time fits the budget (one band's own measured time
    // is an upper bound that includes the fence's round trip, noisy on a loaded machine), within
    // the bound `frame_split`'s unit tests hold the policy to: where a band is seen done at the
    // first poll its height alternates about the target, up to 1.5 budgets (and the whole
    // frame's time is measured at another moment than the band's, on a machine shared with the
    // rest of the suite: CI saw 1.01 budgets).
    let band_rows = info["bandRows"].as_f64().expect("bandRows");
    let share = band_rows * frame_ms / info["height"].as_f64().expect("height");
    assert!(
        share <= 1.5 * BAND_BUDGET_MS,
        "bands fit the budget: {band_rows} rows of a {frame_ms:.0} ms frame: {info}"
    );
    let readout = split["readout"].as_str().unwrap_or("");
    // Read a moment before `info`: the band count may have moved since.
    let shown = readout
        .strip_prefix("frame split into ")
        .and_then(|r| r.split_once(&format!(" bands of ≤{budget} ms")))
        .and_then(|(n, _)| n.parse::<u32>().ok());
    assert!(shown.is_some_and(|n| n > 1), "the read-out says so: {readout:?}");
    // Within a small multiple of the budget: the band in flight, the restarted one, and the
    // browser's event, animation-frame and fence round trips, which on a loaded 2-core machine
    // (a whole frame 2x its idle time) took ~300 ms of a 34 ms band (4 budgets held idle).
    // That splitting is what shortens it is the comparison with the unsplit frame below.
    // Bands queued ahead keep the GPU busy: the frame loop's frames take at most 2x a frame in
    // one submission (one band in flight at a time took 2.4-3.4x here: the news of a done band
    // comes 2-3 animation frames late, and the GPU idled that long after every band).
    let loop_ms = split["loopFrameMs"].as_f64().expect("the frame loop completed frames");
    assert!(
        loop_ms <= 2.0 * frame_ms,
        "the frame loop takes {loop_ms:.0} ms a frame in bands, {frame_ms:.0} ms in one submission: {info}"
    );
    let m = median(&latencies);
    assert!(
        m <= 8.0 * BAND_BUDGET_MS,
        "median input-to-restart {m:.0} ms must be within 8 budgets of {BAND_BUDGET_MS} ms (whole frame {frame_ms:.0} ms): \
         {latencies:.0?}"
    );

    let unsplit = browse(
        &server.url,
        "slow",
        &[
            ("scene", "cornell-box"),
            ("size", "640x480"),
            ("bandBudget", "0"),
            ("inputs", "2"),
            ("settle", "2"),
            ("loopSeconds", "0"),
            ("api", api),
            ("schedule", "megakernel"),
        ],
    );
    no_page_error(&unsplit);
    let unsplit_latencies = restart_latencies(&unsplit, false);
    assert_eq!(unsplit["info"]["bands"], 1);
    assert!(unsplit["readout"].as_str().unwrap_or("").contains("not split"), "{}", unsplit["readout"]);
    eprintln!(
        "unsplit: whole frame {:.0} ms; input to restarted frame done (ms): {unsplit_latencies:.0?}; split/unsplit median \
         {:.3}",
        unsplit["frameMs"].as_f64().unwrap_or(f64::NAN),
        m / median(&unsplit_latencies)
    );
    assert!(m * 4.0 < median(&unsplit_latencies), "splitting shortens the restart: {m} vs {unsplit_latencies:?}");
}

/// A frame drawn in bands of rows (scissor rectangles of the same pass, as the page's frame
/// loop submits them) is the frame drawn whole, exactly: the per-pixel random sequence depends
/// on the pixel and the frame, not on the submission. Bands of uneven heights that change
/// within and across frames, through `GlRenderer::render_band` and through the fenced
/// `Pacer`; and a restart in the middle of a split frame leaves nothing of it behind. Native GL.
#[test]
fn a_frame_split_into_bands_is_the_unsplit_frame() {
    use tracer::backend::frame_split::Step;
    use tracer::backend::gl::GlRenderer;
    use tracer::backend::gl::Pacer;
    let scene = scene::cornell_box();
    let bvh = tracer::bvh::build(&scene.triangles).expect("BVH");
    let settings = RenderSettings { width: 40, height: 36, strategy: Strategy::Mis, max_depth: SERVED_MAX_DEPTH };
    let base = pack(&scene, &bvh, &settings).expect("pack");
    let renderer = || GlRenderer::headless(base.clone(), 3).expect("GL");
    common::bands::assert_bands_make_the_whole_frame(&mut renderer(), &mut renderer(), 36);

    // The page's loop: fenced bands queued ahead, heights from the measured (here: a
    // simulated 30 ms per step) times, each band whole 2x2 quads (rows left stay even).
    let mut paced = GlRenderer::headless(base.clone(), 3).expect("GL");
    let mut pacer = Pacer::new(36, Some(BAND_BUDGET_MS));
    let (mut now, mut submitted) = (0.0, 0);
    let even = |r: &GlRenderer, _| assert_eq!(r.rows_left() % tracer::backend::gl::QUAD_ROWS, 0, "a band of odd rows");
    while paced.frames() < 2 {
        now += 30.0;
        if let Step::Submitted { .. } = pacer.step(&mut paced, now, even).expect("step") {
            submitted += 1;
        }
    }
    pacer.forget(paced.gl());
    let mut two = GlRenderer::headless(base, 3).expect("GL");
    two.render_frame().expect("frame");
    two.render_frame().expect("frame");
    assert!(submitted > 2, "the pacer split the frames: {submitted} bands");
    common::bands::assert_same(&two, &paced, "paced bands");
}
