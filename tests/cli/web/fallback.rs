//! Under the page's `api=auto`, any WebGPU failure hands the scene to WebGL2 with a notice that
//! speaks to a person (and fades), never a black canvas or wgpu's native advice.

use super::{browse, no_page_error, Server};

/// Chromium with the GPU process disabled (`--disable-gpu`) gives a WebGPU device that dies at
/// its first frame and no new one: auto moves to WebGL2, renders, and says why in a notice
/// (an 'info' box, not an error) that names no native driver packages.
#[test]
fn a_webgpu_device_that_dies_falls_back_to_webgl2() {
    let server = Server::start(&[]);
    let report = browse(
        &server.url,
        "fallback",
        &[("scene", "cornell-box"), ("size", "16x16"), ("api", "auto"), ("browser", "webgl2")],
    );
    no_page_error(&report);
    assert_eq!(report["settled"], true, "the page settles on an API: {report}");
    assert_eq!(report["info"]["api"], "WebGL2", "{report}");
    assert_eq!(report["rendered"]["spp"], 2, "WebGL2 renders: {report}");
    assert!(report["rendered"]["sum"].as_f64().unwrap_or(0.0) > 0.0, "the scene is drawn: {report}");
    let notice = report["notice"].as_str().unwrap_or("");
    assert!(notice.contains("WebGL2 runs") && notice.contains("WebGPU"), "the notice says why: {notice:?}");
    for native in ["apt-get", "vulkan not requested", "mesa"] {
        assert!(!notice.to_lowercase().contains(native), "no native advice ({native}): {notice:?}");
    }
    assert_eq!(report["messageKind"], "info", "a notice, not an error: {report}");
}

/// A device lost again and again: the page recreates it twice, then auto moves to WebGL2 (and
/// keeps rendering) with a notice counting the losses.
#[test]
fn a_webgpu_device_lost_again_and_again_falls_back_to_webgl2() {
    let server = Server::start(&[]);
    let report = browse(
        &server.url,
        "deviceloss",
        &[("scene", "cornell-box"), ("size", "16x16"), ("api", "auto"), ("losses", "3")],
    );
    no_page_error(&report);
    let restored = &report["restored"];
    assert_eq!(restored["recoveries"], 2, "two new devices, then none: {restored}");
    assert_eq!(restored["info"]["api"], "WebGL2", "{restored}");
    assert_eq!(restored["spp"], 3, "rendering continues on WebGL2: {restored}");
    assert!(restored["sum"].as_f64().unwrap_or(0.0) > 0.0, "{restored}");
    let notice = restored["info"]["notice"].as_str().unwrap_or("");
    assert!(notice.contains("lost 3 times"), "the notice counts the losses: {notice:?}");
}
