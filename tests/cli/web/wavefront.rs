//! The wavefront schedule on the page's WebGPU (`?schedule=wavefront`): the same statistics
//! against the CPU as the megakernel's page tests, the read-out naming the schedule, and the
//! errors and notices where WebGL2 would have to run it; and `schedule=auto`, which measures
//! both schedules on the device and scene at hand and keeps the faster.

use super::{
    api_report, assert_page_agrees_with_cpu, assert_page_runs_and_agrees_with_cpu, browse, no_page_error,
    textured_scene, Server, STRATEGIES,
};
use serde_json::Value;
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
        assert!(info["scheduleChoice"].is_null(), "an explicit schedule is not measured: {info}");
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

/// The `autoschedule` scenario on the Cornell box at 32x32 on WebGPU, with `extra` options.
fn auto_report(server: &Server, extra: &[(&str, &str)]) -> Value {
    let mut options = vec![("scene", "cornell-box"), ("size", "32x32"), ("api", "webgpu"), ("schedule", "auto")];
    options.extend_from_slice(extra);
    let report = browse(&server.url, "autoschedule", &options);
    no_page_error(&report);
    eprintln!("auto {extra:?}: {}; read-out {}", report["info"]["scheduleChoice"], report["readout"]);
    report
}

/// The page runs what the choice says, names it in the read-out with the reason, and renders.
fn assert_runs_the_choice(report: &Value, chosen: &str, reason: &str) {
    let info = &report["info"];
    let choice = &info["scheduleChoice"];
    assert_eq!((&info["api"], &info["schedule"]), (&"WebGPU".into(), &chosen.into()), "{info}");
    assert_eq!(choice["chosen"], chosen, "{choice}");
    let adapter = info["adapter"].as_str().unwrap_or("");
    assert_eq!(report["readout"], format!("WebGPU, {chosen} ({reason}; {adapter})"), "the read-out: {report}");
    assert_eq!(report["rendered"]["spp"].as_u64().map(|s| s >= 2), Some(true), "it renders on: {report}");
    assert!(report["rendered"]["sum"].as_f64().unwrap_or(0.0) > 0.0, "it draws the scene: {report}");
}

/// `schedule=auto` on WebGPU measures: after the first frame the page times both schedules in
/// alternated turns (a warm-up frame of each, then 3 rounds of 2 frames), keeps the wavefront
/// only if its median frame time is more than 5 % below the megakernel's, says so in the
/// read-out and `sceneInfo().scheduleChoice`, and renders on with the winner.
#[test]
fn auto_measures_both_schedules_and_keeps_the_faster() {
    let server = Server::start(&[]);
    let report = auto_report(&server, &[]);
    let choice = &report["info"]["scheduleChoice"];
    assert_eq!(choice["state"], "measured", "{choice}");
    assert_eq!(choice["injected"], false, "{choice}");
    let turns = |key: &str| -> Vec<f64> {
        choice[key].as_array().unwrap_or_else(|| panic!("{key}: {choice}")).iter().filter_map(Value::as_f64).collect()
    };
    let (megakernel, wavefront) = (turns("megakernelTurnsMs"), turns("wavefrontTurnsMs"));
    assert_eq!((megakernel.len(), wavefront.len()), (3, 3), "3 rounds of each: {choice}");
    assert!(megakernel.iter().chain(&wavefront).all(|ms| *ms > 0.0), "every turn is timed: {choice}");
    for warm in ["megakernel", "wavefront"] {
        assert!(choice["warmUpMs"][warm].as_f64().is_some_and(|ms| ms > 0.0), "{warm}'s warm-up: {choice}");
    }
    let median = |mut v: Vec<f64>| {
        v.sort_by(f64::total_cmp);
        v[1]
    };
    let (mk, wf) = (median(megakernel), median(wavefront));
    assert_eq!((choice["megakernelMs"].as_f64(), choice["wavefrontMs"].as_f64()), (Some(mk), Some(wf)), "{choice}");
    let chosen = if wf < 0.95 * mk { "wavefront" } else { "megakernel" };
    let ratio = wf / mk;
    let reason = match chosen {
        "wavefront" => format!("auto: {ratio:.2}x the megakernel's frame time, measured"),
        _ if ratio < 1.0 => format!("auto: the wavefront took {ratio:.2}x its frame time, not 5 % less, measured"),
        _ => format!("auto: the wavefront took {ratio:.2}x its frame time, measured"),
    };
    assert_runs_the_choice(&report, chosen, &reason);
    assert!(report["notice"].is_null(), "nothing to explain: {report}");
}

/// Both outcomes of auto's rule, on injected times (`?autoScheduleTimes=MK,WF`, test only; the
/// measurement still runs): 0.50x keeps the wavefront, 0.97x (within 5 %) and 2.00x the
/// megakernel.
#[test]
fn auto_keeps_the_wavefront_only_when_more_than_5_percent_faster() {
    let server = Server::start(&[]);
    for (times, chosen, reason) in [
        ("100,50", "wavefront", "auto: 0.50x the megakernel's frame time, measured"),
        ("100,97", "megakernel", "auto: the wavefront took 0.97x its frame time, not 5 % less, measured"),
        ("50,100", "megakernel", "auto: the wavefront took 2.00x its frame time, measured"),
    ] {
        let report = auto_report(&server, &[("autoScheduleTimes", times)]);
        let choice = &report["info"]["scheduleChoice"];
        assert_eq!((&choice["state"], &choice["injected"]), (&"measured".into(), &true.into()), "{choice}");
        assert!(choice["measuredWavefrontMs"].as_f64().is_some_and(|ms| ms > 0.0), "still measured: {choice}");
        assert_runs_the_choice(&report, chosen, reason);
        if chosen == "wavefront" {
            // The switch restarted the accumulation once: of the page's frames (the first, the
            // megakernel's 7 measured ones, then the frame loop's on the wavefront until the
            // scenario paused it) only those after the switch count, and the 2 rendered then.
            // At most those: the first frame may be the warm-up's (CI saw 5 of 10 - 8 + 2, the
            // frame loop's first frame completed by the measurement's warm-up turn); without the
            // restart all 10 + 2 would count.
            let page_frames = report["framesBefore"].as_u64().expect("framesBefore");
            let spp = report["rendered"]["spp"].as_u64().expect("spp");
            assert!((2..=page_frames - 7 + 2).contains(&spp), "{spp} spp of {page_frames} + 2 frames: {report}");
        }
    }
}

/// After auto switched to the wavefront (its outcome injected), the page's image still agrees
/// with the CPU's statistically: the switch restarted the accumulation, the wavefront renders
/// the scene as the megakernel does.
#[test]
fn the_wavefront_auto_chose_agrees_with_the_cpu() {
    let server = Server::start(&[]);
    let extra = [("measure", "1"), ("autoScheduleTimes", "100,50")];
    let scene = tracer::scene::cornell_box();
    let report = assert_page_runs_and_agrees_with_cpu(
        &server,
        "cornell-box",
        &scene,
        Strategy::Mis,
        "webgpu",
        "auto",
        &extra,
        "wavefront",
    );
    assert_eq!(report["choice"]["chosen"], "wavefront", "{}", report["choice"]);
}

/// A wavefront that cannot be built (a device allowing fewer storage buffers than its stages
/// bind, though enough for the megakernel): auto keeps the megakernel with a notice, no error.
/// A camera move during the measurement interrupts it: it starts again once the view has
/// stayed put (and decides); a lost device gives it up: the megakernel stays (on a new device)
/// and the page renders on.
#[test]
fn auto_keeps_the_megakernel_when_the_measurement_fails_or_is_given_up() {
    let server = Server::start(&[]);
    let failed = auto_report(&server, &[("maxStorageBuffers", "6")]);
    let choice = &failed["info"]["scheduleChoice"];
    assert_eq!(choice["state"], "failed", "{choice}");
    assert!(choice["error"].as_str().unwrap_or("").contains("max_storage_buffers_per_shader_stage"), "{choice}");
    let notice = failed["notice"].as_str().unwrap_or("");
    assert!(notice.contains("the megakernel runs") && notice.contains("wavefront"), "{notice:?}");
    assert_eq!(failed["messageKind"], "info", "a notice, not an error: {failed}");
    assert_runs_the_choice(&failed, "megakernel", "auto: the wavefront failed while measured");

    // Interrupted by a camera move, the measurement starts again once the view stays put.
    let moved = auto_report(&server, &[("during", "orbit"), ("autoScheduleTimes", "100,50")]);
    let choice = &moved["info"]["scheduleChoice"];
    assert_eq!((&choice["state"], &choice["tries"]), (&"measured".into(), &2.into()), "{moved}");
    assert_runs_the_choice(&moved, "wavefront", choice["reason"].as_str().unwrap_or(""));

    let lost = auto_report(&server, &[("during", "lose")]);
    assert_eq!(lost["deviceRecoveries"], 1, "{lost}");
    assert_eq!(lost["info"]["scheduleChoice"]["state"], "abandoned", "{lost}");
    let reason = lost["info"]["scheduleChoice"]["reason"].as_str().unwrap_or("").to_string();
    assert!(reason.starts_with("auto: not measured, "), "{reason:?}");
    assert_runs_the_choice(&lost, "megakernel", &reason);
}
