//! A moving glTF on the page (`web/src/playback.rs`): it plays on WebGL2 and WebGPU.

use super::{browse, no_page_error, Server};
use crate::common;

/// A dropped glTF whose animation moves a skinned, morphed mesh and three placements plays on
/// the page: the controls show, the read-out says what moves, the accumulation restarts at
/// each pose set, two poses differ and a pose shown again renders as before; the frame loop
/// moves the time on while playing (the accumulation restarting, so it stays small) and
/// accumulates once paused. On WebGL2 and WebGPU.
#[test]
fn a_moving_gltf_plays_on_the_page() {
    let server = Server::start(&[]);
    let path = std::env::temp_dir().join(format!("lightport-moving-{}.gltf", std::process::id()));
    std::fs::write(&path, common::moving_parts_gltf()).expect("writes the scene");
    let options = tracer::scene::LoadOptions { keep_motion: true, ..Default::default() };
    let native = tracer::scene::load_with(&path, &options).expect("loads natively");
    let duration = native.motion.as_ref().expect("it moves").duration();
    for api in ["webgl2", "webgpu"] {
        let file = path.to_string_lossy();
        let report = browse(
            &server.url,
            "animation",
            &[("scene", "cornell-box"), ("size", "16x16"), ("files", &file), ("api", api)],
        );
        no_page_error(&report);
        let loaded = &report["loaded"];
        assert_eq!(loaded["api"].as_str().map(str::to_lowercase).as_deref(), Some(api), "{loaded}");
        assert_eq!(loaded["controlsShown"], true, "{api}: {loaded}");
        let animation = &loaded["animation"];
        assert!((animation["duration"].as_f64().unwrap_or(0.0) - duration as f64).abs() < 1e-6, "{api}: {animation}");
        assert_eq!(animation["playing"], true, "{api}: plays by default");
        let readout = report["readout"].as_str().unwrap_or("");
        assert!(readout.contains("animated: 3 moving placements and 1 skinned or morphed meshes"), "{api}: {readout}");
        let poses = report["poses"].as_array().expect("poses");
        for p in poses {
            assert_eq!((p["restarted"].as_u64(), p["spp"].as_u64()), (Some(0), Some(2)), "{api}: {}", p["t"]);
        }
        let sum = |p: &serde_json::Value| -> f64 {
            p["data"].as_array().map_or(0.0, |d| d.iter().filter_map(|v| v.as_f64()).sum())
        };
        let sums: Vec<f64> = poses.iter().map(sum).collect();
        assert!(sums[0] > 2.0 * 256.0, "{api}: the scene is black: {sums:?}");
        assert!(
            poses[0]["data"] != poses[1]["data"],
            "{api}: the poses at 0 and 0.8 s render the same image: {sums:?}"
        );
        assert!(poses[0]["data"] == poses[2]["data"], "{api}: the pose at 0 s renders differently again: {sums:?}");
        let playing = &report["playing"];
        let (start, moved) = (playing["start"].as_f64().unwrap_or(0.0), playing["moved"].as_f64().unwrap_or(0.0));
        assert!(moved != start, "{api}: the time did not move while playing: {playing}");
        assert!(playing["maxSppWhilePlaying"].as_u64() <= Some(2), "{api}: it accumulated while moving: {playing}");
        let (paused, after) = (playing["pausedAt"].as_u64().unwrap_or(0), playing["afterPause"].as_u64().unwrap_or(0));
        assert!(after >= paused + 3, "{api}: paused, it did not accumulate: {playing}");
    }
    let _ = std::fs::remove_file(&path);
}
