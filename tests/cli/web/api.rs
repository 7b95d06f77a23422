//! Which graphics API the page runs on and what its start costs (the `api` and `deviceloss`
//! scenarios of `tests/web/api.mjs`): the API asked for and its read-out, the first frame's
//! split (the kernel compiled while the bundle decodes), a WebGPU limit's fallback to WebGL2,
//! and a lost WebGPU device.

use serde_json::Value;

use super::{browse, no_page_error, Server};

/// Runs the `api` scenario: which API the page chose, its read-out and message.
pub(super) fn api_report(server: &Server, api: &str, extra: &[(&str, &str)]) -> Value {
    let mut options = vec![("scene", "cornell-box"), ("size", "16x16"), ("api", api)];
    options.extend_from_slice(extra);
    browse(&server.url, "api", &options)
}

/// The page runs WebGPU when asked, and by default (auto) where the browser offers it, WebGL2
/// when asked; the read-out names the API and the adapter, and both render the scene.
#[test]
fn the_page_runs_and_shows_the_api_asked_for() {
    let server = Server::start(&[]);
    for (api, shown) in [("webgpu", "WebGPU"), ("auto", "WebGPU"), ("webgl2", "WebGL2")] {
        let report = api_report(&server, api, &[]);
        no_page_error(&report);
        let info = &report["info"];
        assert_eq!(info["api"], shown, "api={api}: {info}");
        assert_eq!(info["apiRequested"], api, "{info}");
        assert!(info["notice"].is_null(), "api={api}: nothing to explain: {info}");
        let adapter = info["adapter"].as_str().unwrap_or("");
        assert!(!adapter.is_empty(), "api={api}: the adapter is named: {info}");
        if shown == "WebGPU" {
            assert!(adapter.to_lowercase().contains("swiftshader"), "Chromium's WebGPU adapter here: {adapter:?}");
        }
        let readout = report["readout"].as_str().unwrap_or("");
        let named = if shown == "WebGPU" { format!("{shown}, megakernel") } else { shown.to_string() };
        assert_eq!(readout, format!("{named} ({adapter})"), "api={api}: the read-out");
        let rendered = &report["rendered"];
        assert_eq!(rendered["spp"], 2, "{report}");
        assert!(rendered["sum"].as_f64().unwrap_or(0.0) > 0.0, "api={api}: it draws the scene: {rendered}");
    }
}

/// The page accounts for its first frame on either API: the time from navigation to the first
/// finished frame splits into download, decode, upload, compile and the first frame's GPU time,
/// each measured (non-zero), none overlapping another (their sum is within the total), and the
/// read-out shows the split. The kernel is compiled while the bundle is decoded
/// (web/src/viewer/prepare.rs; `prepare=0`: after), and the renderer so made draws exactly
/// what one made after the decode draws.
#[test]
fn the_page_splits_the_time_to_its_first_frame() {
    let server = Server::start(&[]);
    for api in ["webgl2", "webgpu"] {
        let report = api_report(&server, api, &[]);
        no_page_error(&report);
        let after = api_report(&server, api, &[("prepare", "0")]);
        no_page_error(&after);
        let split = &report["firstFrame"];
        assert_eq!(split["compiledWhileDecoding"], true, "api={api}: {split}");
        assert_eq!(after["firstFrame"]["compiledWhileDecoding"], false, "api={api}: {}", after["firstFrame"]);
        let sum = |r: &Value| r["rendered"]["sum"].as_f64().unwrap_or(f64::NAN);
        assert!(
            sum(&report) > 0.0 && sum(&report) == sum(&after),
            "api={api}: {} against {}",
            report["rendered"],
            after["rendered"]
        );
        assert!(split.is_object(), "api={api}: the page reports no first-frame split: {report}");
        let ms = |key: &str| split[key].as_f64().unwrap_or_else(|| panic!("api={api}: no {key} in {split}"));
        let parts = ["downloadMs", "decodeMs", "uploadMs", "compileMs", "gpuMs"];
        for key in parts {
            assert!(ms(key) > 0.0, "api={api}: {key} is measured: {split}");
        }
        let total = ms("totalMs");
        // The page is paused (frames from the test hook): no preview, whose GPU time would be a
        // part of its own (tests/cli/web/preview.rs).
        assert_eq!(ms("previewMs"), 0.0, "{split}");
        let sum: f64 = parts.iter().map(|k| ms(k)).sum();
        assert!(
            sum <= total + 1.0,
            "api={api}: the parts ({sum} ms) overlap: more than the total ({total} ms): {split}"
        );
        assert!((ms("otherMs") - (total - sum)).abs() < 1e-6, "{split}");
        if api == "webgl2" {
            // SwiftShader compiles the program at its first draw: here the warm-up draw, which
            // the load waits for as compile (by reading a pixel back: `gl.finish()` returns at
            // once in Chromium, and the compile was counted in the upload or the frame).
            let (compile, later) = (ms("compileMs"), ms("uploadMs") + ms("gpuMs"));
            assert!(compile > later, "api={api}: the compile ({compile} ms) is counted in what follows: {split}");
        }
        // The page's first scene counts from navigation start, as firstFrameMs does.
        let first = report["firstFrameMs"].as_f64().unwrap_or(f64::NAN);
        assert!((total - first).abs() < 100.0, "api={api}: total {total} ms, first frame at {first} ms: {split}");
        let readout = report["firstFrameReadout"].as_str().unwrap_or("");
        for word in ["download", "decode", "upload", "compile", "GPU"] {
            assert!(readout.contains(word), "api={api}: the read-out shows {word}: {readout:?}");
        }
        assert!(readout.starts_with(&format!("{:.2} s", total / 1000.0)), "api={api}: {readout:?} vs {total} ms");
    }
}

/// A scene that needs more storage buffers than the WebGPU device allows (a test override of
/// the device's limit): auto falls back to WebGL2 and says why, naming the limit and the
/// numbers; an explicit `api=webgpu` shows that error instead.
#[test]
fn a_scene_beyond_a_webgpu_limit_falls_back_to_webgl2() {
    let server = Server::start(&[]);
    let limit = [("maxStorageBuffers", "2")];
    let auto = api_report(&server, "auto", &limit);
    no_page_error(&auto);
    assert_eq!(auto["info"]["api"], "WebGL2", "auto falls back: {}", auto["info"]);
    let notice = auto["notice"].as_str().unwrap_or("");
    assert!(
        notice.contains("max_storage_buffers_per_shader_stage")
            && notice.contains("allows 2")
            && notice.contains("WebGL2"),
        "the notice names the limit and the sizes: {notice:?}"
    );
    assert!(auto["messageText"].as_str().unwrap_or("").contains("max_storage_buffers_per_shader_stage"), "{auto}");
    assert_eq!(auto["rendered"]["spp"], 2, "WebGL2 renders it: {auto}");

    let explicit = api_report(&server, "webgpu", &limit);
    let error = explicit["error"].as_str().unwrap_or("");
    assert!(error.contains("max_storage_buffers_per_shader_stage") && error.contains("allows 2"), "{explicit}");
    assert!(explicit["rendered"].is_null(), "nothing renders: {explicit}");
}

/// WebGPU device loss (the hook destroys the device): the page requests a new device,
/// recreates the renderer (of the same schedule) from the scene in memory and keeps rendering.
#[test]
fn the_page_survives_webgpu_device_loss() {
    let server = Server::start(&[]);
    for schedule in ["megakernel", "wavefront"] {
        let options = [("scene", "cornell-box"), ("size", "16x16"), ("api", "webgpu"), ("schedule", schedule)];
        let report = browse(&server.url, "deviceloss", &options);
        no_page_error(&report);
        assert_eq!(report["info"]["api"], "WebGPU", "{report}");
        assert_eq!(report["before"], 4);
        let restored = &report["restored"];
        assert_eq!(restored["recoveries"], 1, "{schedule}: one new device: {restored}");
        assert_eq!(restored["sppAfterLoss"], 0, "{schedule}: the renderer was recreated: {restored}");
        assert_eq!(restored["spp"], 3, "{schedule}: rendering continues on the new device: {restored}");
        assert_eq!((&restored["info"]["api"], &restored["info"]["schedule"]), (&"WebGPU".into(), &schedule.into()));
        assert!(restored["info"]["webGpuLost"].is_null(), "{restored}");
        assert!(restored["sum"].as_f64().unwrap_or(0.0) > 0.0, "{schedule}: the new renderer draws: {restored}");
    }
}
