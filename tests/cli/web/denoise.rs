//! The page's denoiser (web/src/denoise/) against the CLI's: the canvas with the Denoise control
//! on shows what `lightport render --denoise` writes for the same scene, size, spp and seed on
//! the matching native runtime (GL for WebGL2, wgpu for WebGPU), the control off shows the raw
//! image, the read-out says which, and bad input (no scene, a 1xN image, a lost context) gives
//! clear read-outs and no error.

use std::path::Path;
use std::process::Command;

use serde_json::Value;

use super::{browse, no_page_error, Server};

/// The comparison's size, samples per pixel and seed (the page's default seed is 1).
const SIZE: u32 = 32;
const SPP: u32 = 8;
const SEED: &str = "1";

/// `lightport render cornell --denoise` on `backend` into `dir`: (denoised, noisy) PNG pixels,
/// RGB rows from the top.
fn cli_render(backend: &str, dir: &Path) -> (Vec<u8>, Vec<u8>) {
    let (out, noisy) = (dir.join(format!("{backend}.png")), dir.join(format!("{backend}-noisy.png")));
    let size = SIZE.to_string();
    let o = Command::new(env!("CARGO_BIN_EXE_lightport"))
        .args(["render", "cornell", "--backend", backend, "--width", &size, "--height", &size])
        .args(["--spp", &SPP.to_string(), "--seed", SEED, "--max-depth", &super::SERVED_MAX_DEPTH.to_string()])
        .arg("--denoise")
        .arg("--out")
        .arg(&out)
        .arg("--noisy")
        .arg(&noisy)
        .output()
        .expect("run lightport");
    assert!(o.status.success(), "lightport render --denoise: {}", String::from_utf8_lossy(&o.stderr));
    let read = |p: &Path| image::open(p).expect("a PNG").into_rgb8().into_raw();
    (read(&out), read(&noisy))
}

/// The canvas's RGBA pixels of a shot.
fn canvas(shot: &Value) -> Vec<u8> {
    let pixels = shot["pixels"].as_array().expect("the canvas's pixels");
    pixels.iter().map(|v| v.as_u64().expect("a byte") as u8).collect()
}

/// Per 8-bit channel |canvas - png|: (mean, the 99th percentile, max).
fn difference(canvas: &[u8], png: &[u8]) -> (f64, u8, u8) {
    assert_eq!(canvas.len() / 4, png.len() / 3, "the canvas and the PNG differ in size");
    let mut d: Vec<u8> =
        canvas.chunks(4).zip(png.chunks(3)).flat_map(|(c, p)| (0..3).map(move |i| c[i].abs_diff(p[i]))).collect();
    let mean = d.iter().map(|&x| x as f64).sum::<f64>() / d.len() as f64;
    d.sort_unstable();
    (mean, d[d.len() * 99 / 100], *d.last().unwrap_or(&0))
}

/// The page on `api` (denoise on by default, or through `?denoise=1`) against the CLI on
/// `backend`.
///
/// Tolerance: the page and the CLI trace the same samples (same kernel, seed and frame seeds),
/// but SwiftShader and llvmpipe/lavapipe round differently, so a few paths take another branch
/// and their pixels differ; the raw canvas against the CLI's `--noisy` PNG measures exactly
/// that. The filter is a weighted mean of neighbours (with weights that depend on those
/// pixels), so it spreads such differences but does not grow them: the denoised canvas must be
/// within the raw difference plus 2 8-bit steps in the mean and in the 99th percentile. The
/// read-out and the raw image are checked too: showing the raw image while saying "denoised"
/// (or the reverse) fails, since at 8 spp the filter moves the image far more than the
/// runtimes' rounding does (asserted: the denoised and noisy PNGs are further apart than the
/// bound).
fn assert_page_denoises_like_the_cli(api: &str, backend: &str, default: bool) {
    let server = Server::start(&[]);
    let size = format!("{SIZE}x{SIZE}");
    let spp = SPP.to_string();
    let mut options = vec![("scene", "cornell-box"), ("size", size.as_str()), ("spp", spp.as_str()), ("api", api)];
    if default {
        options.push(("default", "1"));
    }
    let report = browse(&server.url, "denoise", &options);
    no_page_error(&report);
    let shown = if api == "webgpu" { "WebGPU" } else { "WebGL2" };
    assert_eq!(report["info"]["api"], shown, "the page runs the API asked for: {}", report["info"]);
    assert_eq!(report["checked"], true, "the Denoise control is on: {report:?}");
    let on = &report["on"];
    assert!(on["denoise"]["error"].is_null(), "the denoiser failed: {}", on["denoise"]);
    assert_eq!(on["denoise"]["shownSpp"], SPP, "the canvas shows the accumulation denoised at {SPP} spp");
    assert_eq!(on["spp"], SPP, "{}", on["denoise"]);
    assert_eq!(report["readoutOn"], format!("denoised at {SPP} spp"), "the read-out with denoise on");
    assert_eq!(report["readoutOff"], "raw (denoise off)", "the read-out with denoise off");
    assert_eq!(report["off"]["denoise"]["shownSpp"], Value::Null, "off: nothing denoised is shown");

    let dir = std::env::temp_dir().join(format!("lightport-web-denoise-{}-{api}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("a scratch folder");
    let (denoised, noisy) = cli_render(backend, &dir);
    let _ = std::fs::remove_dir_all(&dir);
    let (on_pixels, off_pixels) = (canvas(on), canvas(&report["off"]));
    let raw = difference(&off_pixels, &noisy);
    let den = difference(&on_pixels, &denoised);
    let filter_moves = difference(&on_pixels, &noisy);
    let apart = difference(&off_pixels, &denoised);
    eprintln!(
        "{api} vs {backend} at {SIZE}x{SIZE}, {SPP} spp: raw canvas vs --noisy PNG: mean {:.3}, p99 {}, max {}; \
         denoised canvas vs --denoise PNG: mean {:.3}, p99 {}, max {}; denoised canvas vs noisy PNG: mean {:.2}; \
         raw canvas vs denoised PNG: mean {:.2}; filter {} ms, guide {} ms",
        raw.0,
        raw.1,
        raw.2,
        den.0,
        den.1,
        den.2,
        filter_moves.0,
        apart.0,
        on["denoise"]["filterMs"],
        on["denoise"]["guideMs"]
    );
    assert!(
        den.0 <= raw.0 + 2.0 && den.1 <= raw.1.saturating_add(2),
        "{api}: the denoised canvas is {den:?} (mean, p99, max) 8-bit steps from the CLI's --denoise PNG on {backend}; \
         the raw canvas is {raw:?} from its --noisy PNG"
    );
    assert!(
        raw.0 <= 2.0 && raw.1 <= 8,
        "{api}: the raw canvas is {raw:?} from the CLI's --noisy PNG on {backend}: not the same samples"
    );
    // What makes the comparison able to fail: the filter moves the image well beyond the bound.
    assert!(apart.0 > raw.0 + 4.0, "{api}: denoising changed too little to be seen ({apart:?})");
}

#[test]
fn the_page_shows_the_denoised_image_the_cli_writes_on_webgl2() {
    assert_page_denoises_like_the_cli("webgl2", "gl", true);
}

#[test]
fn the_page_shows_the_denoised_image_the_cli_writes_on_webgpu() {
    assert_page_denoises_like_the_cli("webgpu", "wgpu", false);
}

/// Bad input: the control switched with no scene loaded, a 1x7 image, and on WebGL2 switched
/// while the context is lost: no page error, clear read-outs, and denoising resumes after the
/// context is restored.
#[test]
fn the_page_denoiser_survives_bad_input() {
    let server = Server::start(&[]);
    for api in ["webgl2", "webgpu"] {
        let report = browse(&server.url, "denoiseedges", &[("scene", "cornell-box"), ("size", "1x7"), ("api", api)]);
        no_page_error(&report);
        let steps = &report["steps"];
        let no_scene = &steps["noScene"];
        assert!(no_scene["error"].is_null(), "{api}: switching with no scene: {no_scene}");
        assert_eq!(no_scene["readout"], "raw (no scene)", "{api}: {no_scene}");
        let thin = &steps["thin"];
        assert!(thin["error"].is_null() && thin["denoise"]["error"].is_null(), "{api}: 1x7: {thin}");
        assert_eq!(thin["denoise"]["shownSpp"], 8, "{api}: a 1x7 image is denoised: {}", thin["denoise"]);
        assert_eq!(thin["readout"], "denoised at 8 spp", "{api}: {thin}");
        assert_eq!(thin["shot"]["pixels"].as_array().map(Vec::len), Some(7 * 4), "{api}: 1x7 RGBA");
        if api == "webgl2" {
            let lost = &steps["lost"];
            assert!(lost["error"].is_null(), "switching during a context loss: {lost}");
            assert_eq!(lost["readout"], "raw (the WebGL context is lost)", "nothing renders while it is lost: {lost}");
            let restored = &steps["restored"];
            assert!(restored["error"].is_null() && restored["denoise"]["error"].is_null(), "{restored}");
            assert_eq!(restored["readout"], "denoised at 4 spp", "denoising resumes after the restore: {restored}");
        }
    }
}
