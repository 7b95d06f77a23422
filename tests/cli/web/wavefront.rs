//! The wavefront schedule on the page's WebGPU (`?schedule=wavefront`): the same statistics
//! against the CPU as the megakernel's page tests, the read-out naming the schedule, and the
//! errors and notices where WebGL2 would have to run it.

use super::{api_report, assert_page_agrees_with_cpu, no_page_error, textured_scene, Server, STRATEGIES};
use tracer::kernel::Strategy;
use tracer::scene;

/// The Cornell box on the page's WebGPU wavefront agrees with the CPU, each strategy.
#[test]
fn the_page_wavefront_agrees_with_the_cpu_on_the_cornell_box() {
    let server = Server::start(&[]);
    for strategy in STRATEGIES {
        assert_page_agrees_with_cpu(&server, "cornell-box", &scene::cornell_box(), strategy, "webgpu", "wavefront");
    }
}

/// Textures and an HDR sky (BoxTextured under venice_sunset), the metal-roughness spheres and
/// glass through the page's WebGPU wavefront.
#[test]
fn the_page_wavefront_agrees_with_the_cpu_on_textures_metal_and_glass() {
    let (server, scene) = textured_scene();
    assert_page_agrees_with_cpu(&server, "BoxTextured", &scene, Strategy::Mis, "webgpu", "wavefront");
    drop(server);
    let server = Server::start(&["metal-rough-spheres", "glass-cornell"]);
    for (name, scene) in
        [("metal-rough-spheres", scene::metal_rough_spheres()), ("glass-cornell", scene::glass_cornell())]
    {
        assert_page_agrees_with_cpu(&server, name, &scene, Strategy::Mis, "webgpu", "wavefront");
    }
}

/// The read-out names the schedule that runs ("WebGPU, wavefront"), under auto's API too; the
/// wavefront asked of WebGL2 is an error that says why; under auto's fallback to WebGL2 the
/// megakernel runs and the notice says the wavefront needs WebGPU.
#[test]
fn the_page_names_its_schedule_and_webgl2_refuses_the_wavefront() {
    let server = Server::start(&[]);
    for api in ["webgpu", "auto"] {
        let report = api_report(&server, api, &[("schedule", "wavefront")]);
        no_page_error(&report);
        let info = &report["info"];
        assert_eq!((&info["api"], &info["schedule"]), (&"WebGPU".into(), &"wavefront".into()), "{info}");
        assert_eq!(info["scheduleRequested"], "wavefront", "{info}");
        let readout = report["readout"].as_str().unwrap_or("");
        assert!(readout.starts_with("WebGPU, wavefront ("), "api={api}: the read-out: {readout:?}");
        assert_eq!(report["rendered"]["spp"], 2, "two whole frames: {report}");
        assert!(report["rendered"]["sum"].as_f64().unwrap_or(0.0) > 0.0, "it draws the scene: {report}");
    }

    let webgl2 = api_report(&server, "webgl2", &[("schedule", "wavefront")]);
    let error = webgl2["error"].as_str().unwrap_or("");
    assert!(error.contains("WebGL2") && error.contains("compute shaders"), "{webgl2}");
    assert!(webgl2["rendered"].is_null(), "nothing renders: {webgl2}");

    // Auto's fallback (a WebGPU limit the scene exceeds): WebGL2's megakernel, and why.
    let fallback = api_report(&server, "auto", &[("schedule", "wavefront"), ("maxStorageBuffers", "2")]);
    no_page_error(&fallback);
    assert_eq!((&fallback["info"]["api"], &fallback["info"]["schedule"]), (&"WebGL2".into(), &"megakernel".into()));
    let notice = fallback["notice"].as_str().unwrap_or("");
    assert!(notice.contains("the wavefront needs WebGPU"), "{notice:?}");
}
