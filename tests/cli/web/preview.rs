//! The preview (docs/web.md, "The first frame, accounted for"): after a scene loads, the page's
//! first image is the view rendered at a quarter of each side by the same kernel, shown
//! upscaled until the first full-resolution frame is complete; its samples are never
//! accumulated; `?preview=0` turns it off. On WebGL2 and WebGPU (the megakernel).

use serde_json::Value;
use tracer::kernel::Strategy;
use tracer::scene;

use super::{assert_page_runs_and_agrees_with_cpu, browse, no_page_error, Server, SIZE};

/// The page as a person opens it (the frame loop running), the Cornell box at 320x240.
fn opened(server: &Server, api: &str, extra: &[(&str, &str)]) -> Value {
    let mut options = vec![("scene", "cornell-box"), ("size", "320x240"), ("api", api), ("schedule", "megakernel")];
    options.extend_from_slice(extra);
    let report = browse(&server.url, "preview", &options);
    no_page_error(&report);
    report
}

fn ms(value: &Value, what: &str) -> f64 {
    value.as_f64().unwrap_or_else(|| panic!("{what} is a number: {value}"))
}

/// The first image shown after the load is the preview: 80x60, on the canvas upscaled (every 4x4
/// block of the 320x240 canvas one colour, not all black) while no full frame is done (0 spp),
/// the read-out says so; it is finished before the first full-resolution frame, which then
/// replaces it, and the first-frame accounting reports both (the preview's GPU time a part of
/// its own). After a camera move the new view is previewed the same way, then replaced.
#[test]
fn the_first_image_after_a_load_is_an_upscaled_preview_before_the_first_full_frame() {
    let server = Server::start(&[]);
    for api in ["webgl2", "webgpu"] {
        let report = opened(&server, api, &[]);
        let shot = &report["shot"];
        assert_preview_on_canvas(shot, api, "the load");
        let readout = shot["readout"].as_str().unwrap_or("");
        assert!(readout.contains("preview 80×60"), "api={api}: the image read-out says so: {readout:?}");

        let settled = &report["settled"]["info"]["preview"];
        assert_eq!(settled["rendered"], 1, "api={api}: one preview after the load: {settled}");
        let image = &report["firstImage"];
        assert_eq!(image["preview"], true, "api={api}: the first image is the preview: {image}");
        assert_eq!((image["width"].as_u64(), image["height"].as_u64()), (Some(80), Some(60)));
        let split = &report["firstFrame"];
        let (image_ms, frame_ms) = (ms(&image["totalMs"], "firstImage.totalMs"), ms(&split["totalMs"], "totalMs"));
        assert!(image_ms < frame_ms, "api={api}: the preview ({image_ms} ms) before the full frame ({frame_ms} ms)");
        assert!((ms(&split["firstImageMs"], "firstImageMs") - image_ms).abs() < 1e-6, "{split}");
        let (shown_at, done_at) =
            (ms(&report["firstImageMs"], "firstImageMs"), ms(&report["firstFrameMs"], "firstFrameMs"));
        assert!(shown_at < done_at, "api={api}: on screen before the full frame: {shown_at} vs {done_at}");
        assert!(ms(&split["previewMs"], "previewMs") > 0.0, "api={api}: the preview's GPU time: {split}");
        assert_eq!(split["preview"]["width"], 80, "{split}");
        eprintln!(
            "preview ({api}): first image {image_ms:.0} ms (preview GPU {:.0} ms), first full frame {frame_ms:.0} ms \
             (GPU {:.0} ms)",
            ms(&split["previewMs"], "previewMs"),
            ms(&split["gpuMs"], "gpuMs")
        );
        assert_eq!(report["info"]["preview"]["state"], "replaced", "api={api}: {}", report["info"]["preview"]);
        let now = report["imageReadout"].as_str().unwrap_or("");
        assert!(!now.contains("preview"), "api={api}: the full frame is shown: {now:?}");
        let accounted = report["firstFrameReadout"].as_str().unwrap_or("");
        assert!(accounted.starts_with("first image (preview 80×60)"), "api={api}: {accounted:?}");

        // A camera move restarts the accumulation, and the new view is previewed in turn.
        assert_preview_on_canvas(&report["afterMove"], api, "a camera move");
        let replaced = &report["replacedAfterMove"];
        assert_eq!(
            (replaced["rendered"].as_u64(), replaced["state"].as_str()),
            (Some(2), Some("replaced")),
            "{replaced}"
        );
        assert_eq!(report["previews"].as_array().map(Vec::len), Some(2), "api={api}: {}", report["previews"]);
    }
}

/// A restart is previewed only where whole frames were measured to exceed the band budget:
/// unsplit (`bandBudget=0`, one submission per frame) the load's preview shows as ever, but a
/// camera move is drawn whole, without a second one (a fast device playing an animation would
/// otherwise preview every pose and never render a full frame).
#[test]
fn a_restart_is_not_previewed_where_frames_are_whole() {
    let server = Server::start(&[]);
    let report = opened(&server, "webgl2", &[("bandBudget", "0")]);
    assert_eq!(report["info"]["bands"].as_u64(), Some(1), "not split: {}", report["info"]);
    // (Unsplit, the full frame follows the preview at the next animation frame: too soon to
    // copy the canvas reliably, so the preview is known by its count.)
    let settled = &report["settled"]["info"]["preview"];
    assert_eq!(settled["rendered"], 1, "one preview after the load: {settled}");
    assert!(report["afterMove"].is_null(), "a preview after a camera move: {}", report["previews"]);
    let after = &report["replacedAfterMove"];
    assert_eq!(after["rendered"].as_u64(), Some(1), "{after}");
    assert_eq!(report["previews"].as_array().map(Vec::len), Some(1), "{}", report["previews"]);
}

/// `shot` (the canvas copied while a preview showed, after `what`) is the preview: 80x60
/// upscaled on the 320x240 canvas (every 4x4 block one colour, the scene lit), while no full
/// frame had been done since the restart (0 spp).
fn assert_preview_on_canvas(shot: &Value, api: &str, what: &str) {
    assert!(shot.is_object(), "api={api}: the canvas showed a preview after {what}");
    assert_eq!((shot["width"].as_u64(), shot["height"].as_u64()), (Some(320), Some(240)), "api={api}");
    assert_eq!((shot["preview"]["width"].as_u64(), shot["preview"]["height"].as_u64()), (Some(80), Some(60)));
    assert_eq!(shot["spp"], 0, "api={api}, {what}: no full frame was done while the preview showed");
    let pixels: Vec<u8> =
        shot["pixels"].as_array().expect("pixels").iter().map(|v| v.as_u64().unwrap() as u8).collect();
    assert_eq!(pixels.len(), 320 * 240 * 4);
    let pixel = |x: usize, y: usize| &pixels[(y * 320 + x) * 4..(y * 320 + x) * 4 + 4];
    let mut blocks_off = 0;
    for by in 0..60 {
        for bx in 0..80 {
            let first = pixel(bx * 4, by * 4);
            let uniform = (0..16).all(|i| pixel(bx * 4 + i % 4, by * 4 + i / 4) == first);
            blocks_off += usize::from(!uniform);
        }
    }
    assert_eq!(blocks_off, 0, "api={api}, {what}: every 4x4 block of the canvas is one preview pixel");
    let lit = pixels.chunks_exact(4).filter(|p| p[..3].iter().any(|&c| c > 0)).count();
    assert!(lit > 320 * 240 / 2, "api={api}, {what}: the preview shows the scene ({lit} lit pixels)");
}

/// `?preview=0`: no preview is rendered or shown; the first image is the first full frame,
/// drawn as its bands are done at most every `PROGRESS_MS`.
#[test]
fn preview_0_shows_no_preview() {
    let server = Server::start(&[]);
    for api in ["webgl2", "webgpu"] {
        let report = opened(&server, api, &[("preview", "0")]);
        assert!(report["shot"].is_null(), "api={api}: no preview on the canvas");
        assert_eq!(report["previews"].as_array().map(Vec::len), Some(0), "api={api}: {}", report["previews"]);
        assert!(report["afterMove"].is_null(), "api={api}: no preview after a camera move either");
        assert_eq!(report["info"]["preview"]["state"], "off", "api={api}");
        let (image, split) = (&report["firstImage"], &report["firstFrame"]);
        assert_eq!(image["preview"], false, "api={api}: {image}");
        assert_eq!((image["width"].as_u64(), image["height"].as_u64()), (Some(320), Some(240)));
        assert_eq!(ms(&split["previewMs"], "previewMs"), 0.0, "{split}");
        assert!((ms(&image["totalMs"], "firstImage.totalMs") - ms(&split["totalMs"], "totalMs")).abs() < 1e-6);
        let accounted = report["firstFrameReadout"].as_str().unwrap_or("");
        assert!(!accounted.contains("preview"), "api={api}: {accounted:?}");
        // Without a preview the first frame shows as its bands are done: its first band at
        // once, then at most every PROGRESS_MS (a draw per band made every animation frame
        // wait for the bands queued on SwiftShader: docs/web.md, "The first frame's rows").
        let info = &report["settled"]["info"];
        let draws = info["preview"]["bandDraws"].as_f64().expect("bandDraws");
        let first_frame_ms = ms(&report["firstFrameMs"], "firstFrameMs");
        let most = (first_frame_ms / tracer::backend::preview::PROGRESS_MS).floor() + 2.0;
        eprintln!("api={api}: {draws} of the first frame's bands drawn, {} bands a frame now, first frame at {first_frame_ms:.0} ms", info["bands"]);
        assert!(
            draws >= 1.0 && draws <= most,
            "api={api}: {draws} bands of the first frame drawn in {first_frame_ms:.0} ms (1 to {most}): {info}"
        );
    }
}

/// After a preview the accumulation still agrees with the CPU backend (the statistics of
/// `the_browser_agrees_with_the_cpu_*`, every pixel's sample count exactly the frames
/// rendered): the preview's samples are not accumulated.
#[test]
fn the_accumulation_after_a_preview_agrees_with_the_cpu() {
    let server = Server::start(&[]);
    let size = SIZE / 4;
    for api in ["webgl2", "webgpu"] {
        let (scene, mis) = (scene::cornell_box(), Strategy::Mis);
        let extra = [("preview", "1")];
        let report = assert_page_runs_and_agrees_with_cpu(
            &server,
            "cornell-box",
            &scene,
            mis,
            api,
            "megakernel",
            &extra,
            "megakernel",
        );
        let preview = &report["preview"];
        assert_eq!(preview["state"], "shown", "api={api}: a preview was rendered first: {preview}");
        assert_eq!((preview["width"].as_u64(), preview["height"].as_u64()), (Some(size as u64), Some(size as u64)));
    }
}
