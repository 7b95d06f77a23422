//! The chart's unit tests: checkpoints, arguments, the web driver's reports.

use super::*;

#[test]
fn checkpoints_double_and_end_at_the_maximum() {
    assert_eq!(checkpoints(1), vec![1]);
    assert_eq!(checkpoints(8), vec![1, 2, 4, 8]);
    assert_eq!(checkpoints(12), vec![1, 2, 4, 8, 12]);
}

fn args(scenes: &[&str], out: &Path) -> ChartArgs {
    ChartArgs {
        scenes: scenes.iter().map(|s| s.to_string()).collect(),
        sky: None,
        pose: Default::default(),
        sky_intensity: 1.0,
        size: 8,
        spp: 16,
        reference_spp: 8,
        max_depth: 4,
        backends: vec![ChartBackend::Cpu],
        strategies: vec![ChartStrategy::Bsdf, ChartStrategy::Nee, ChartStrategy::Mis],
        schedules: vec![ChartSchedule::Megakernel, ChartSchedule::Wavefront],
        out_dir: out.join("chart"),
        reference_dir: out.join("reference"),
        seed: 1,
        web_timeout: 60.0,
        denoise: false,
    }
}

#[test]
fn the_furnace_chart_has_every_line_and_its_error_falls() {
    let dir = std::env::temp_dir().join(format!("lightport-chart-test-{}", std::process::id()));
    let a = args(&["furnace"], &dir);
    chart(&a).unwrap();
    let csv = std::fs::read_to_string(a.out_dir.join("furnace.csv")).unwrap();
    let rows: Vec<Vec<&str>> = csv.lines().skip(1).map(|l| l.split(',').collect()).collect();
    assert_eq!(rows.len(), 2 * 3 * 5, "2 schedules x 3 strategies x checkpoints 1, 2, 4, 8, 16:\n{csv}");
    let rmse = |r: &Vec<&str>| r[5].parse::<f64>().unwrap();
    for strategy in ["bsdf", "nee", "mis"] {
        let line = |schedule: &str| -> Vec<&Vec<&str>> {
            rows.iter().filter(|r| r[2] == strategy && r[10] == schedule).collect()
        };
        for schedule in ["megakernel", "wavefront"] {
            let line = line(schedule);
            assert_eq!(line.len(), 5, "{strategy}, {schedule}: a line of 5 checkpoints:\n{csv}");
            assert!(line.iter().all(|r| r[8] == "analytic" && r[7] == "0" && rmse(r).is_finite()));
            // 16x the samples: the RMSE of an unbiased estimate against the exact value falls
            // 4x (to 0.25, ± ~0.03 over these 192 values). A bias (a wrong reference, a
            // sampler that stopped converging) keeps it higher.
            assert!(rmse(line[4]) < 0.35 * rmse(line[0]), "{strategy}, {schedule}: {csv}");
        }
        // On the CPU the wavefront adds the megakernel's samples, bit for bit: the same
        // errors at every checkpoint (its own time).
        let errors = |schedule| line(schedule).iter().map(|r| (r[3], r[5], r[6])).collect::<Vec<_>>();
        assert_eq!(errors("wavefront"), errors("megakernel"), "{strategy}:\n{csv}");
    }
    let svg = std::fs::read_to_string(a.out_dir.join("furnace.svg")).unwrap();
    assert!(svg.starts_with("<svg") && svg.contains("slope"));
    for label in ["mis cpu, megakernel", "mis cpu, wavefront", "bsdf cpu, wavefront"] {
        assert!(svg.contains(label), "the chart's legend names {label:?}");
    }
    assert!(a.out_dir.join("furnace-equal-time.png").exists());
    let crops = std::fs::read_to_string(a.out_dir.join("furnace-equal-time.svg")).unwrap();
    for label in [
        "reference",
        "exact",
        "bsdf · cpu, megakernel",
        "nee · cpu, megakernel",
        "mis · cpu, megakernel",
        "mis · cpu, wavefront",
        " spp · ",
    ] {
        assert!(crops.contains(label), "the equal-time SVG labels {label:?}");
    }
    assert_eq!(crops.matches("data:image/png;base64,").count(), 7, "the reference and 6 crops");
    let _ = std::fs::remove_dir_all(dir);
}

/// The GPU backends chart the same analytic scene: lines for GL and for wgpu's megakernel and
/// wavefront whose error falls as the CPU's does (a backend that rendered another image, or did
/// not accumulate, would keep its error). GL has no wavefront: no line, no failure.
#[test]
fn gpu_backends_chart_the_furnace_too() {
    let dir = std::env::temp_dir().join(format!("lightport-chart-gpu-test-{}", std::process::id()));
    let mut a = args(&["furnace"], &dir);
    a.backends = vec![ChartBackend::Gl, ChartBackend::Wgpu];
    a.strategies = vec![ChartStrategy::Mis];
    chart(&a).unwrap();
    let csv = std::fs::read_to_string(a.out_dir.join("furnace.csv")).unwrap();
    let rows: Vec<Vec<&str>> = csv.lines().skip(1).map(|l| l.split(',').collect()).collect();
    for (backend, schedule) in [("gl", "megakernel"), ("wgpu", "megakernel"), ("wgpu", "wavefront")] {
        let line: Vec<&Vec<&str>> = rows.iter().filter(|r| r[1] == backend && r[10] == schedule).collect();
        assert_eq!(line.len(), 5, "{backend}, {schedule}: checkpoints 1, 2, 4, 8, 16:\n{csv}");
        let rmse = |r: &Vec<&str>| r[5].parse::<f64>().unwrap();
        assert!(line.iter().all(|r| r[7] == "0" && rmse(r).is_finite()), "{csv}");
        assert!(rmse(line[4]) < 0.35 * rmse(line[0]), "{backend}, {schedule}: {csv}");
    }
    assert_eq!(rows.len(), 15, "no GL wavefront:\n{csv}");
    let svg = std::fs::read_to_string(a.out_dir.join("furnace.svg")).unwrap();
    for label in ["mis gl", "mis wgpu, megakernel", "mis wgpu, wavefront"] {
        assert!(svg.contains(label), "the chart's legend names {label:?}");
    }
    assert!(!svg.contains("gl, wavefront"));
    let _ = std::fs::remove_dir_all(dir);
}

/// `--denoise`: each native line, of either schedule, has a denoised twin, on every runtime,
/// whose relative MSE at the last checkpoint is below its line's.
#[test]
fn denoised_lines_fall_below_their_noisy_twins() {
    let dir = std::env::temp_dir().join(format!("lightport-chart-denoise-test-{}", std::process::id()));
    let mut a = args(&["cornell"], &dir);
    (a.size, a.spp, a.reference_spp) = (24, 16, 1024);
    a.backends = vec![ChartBackend::Cpu, ChartBackend::Gl, ChartBackend::Wgpu];
    a.strategies = vec![ChartStrategy::Mis];
    a.denoise = true;
    chart(&a).unwrap();
    let csv = std::fs::read_to_string(a.out_dir.join("cornell.csv")).unwrap();
    let rows: Vec<Vec<&str>> = csv.lines().skip(1).map(|l| l.split(',').collect()).collect();
    for (backend, schedule) in [
        ("cpu", "megakernel"),
        ("gl", "megakernel"),
        ("wgpu", "megakernel"),
        ("cpu", "wavefront"),
        ("wgpu", "wavefront"),
    ] {
        let last = |denoised: &str| {
            let row = rows.iter().rfind(|r| r[1] == backend && r[9] == denoised && r[10] == schedule);
            let row = row.unwrap_or_else(|| panic!("{backend} {schedule}: no line (denoised {denoised}):\n{csv}"));
            (row[3].parse::<u32>().unwrap(), row[4].parse::<f64>().unwrap(), row[6].parse::<f64>().unwrap())
        };
        let ((spp, noisy_time, noisy), (spp_d, denoised_time, denoised)) = (last("false"), last("true"));
        assert_eq!((spp, spp_d), (16, 16), "{backend}:\n{csv}");
        // Relative MSE 7.1e-3 against 1.01e-2 on the CPU (the same image on every runtime,
        // up to float rounding); an image the filter left alone would keep its line's error.
        // (The RMSE is the light's anti-aliased edges at this size, 0.087 either way: the
        // filter leaves emission as it is.)
        assert!(denoised < 0.8 * noisy, "{backend}: relMSE {denoised} denoised, {noisy} noisy:\n{csv}");
        // The denoised line is rendered by a renderer of its own (with the guide): its time
        // is not the noisy line's plus the filter's, so only its presence is checked here.
        assert!(denoised_time > 0.0 && noisy_time > 0.0, "{backend}: times are recorded:\n{csv}");
    }
    let svg = std::fs::read_to_string(a.out_dir.join("cornell.svg")).unwrap();
    assert!(
        svg.contains("mis gl denoised") && svg.contains("mis cpu, megakernel denoised"),
        "the legend names the twins"
    );
    let _ = std::fs::remove_dir_all(dir);
}

#[test]
fn references_are_cached_under_their_settings() {
    let dir = std::env::temp_dir().join(format!("lightport-chart-cache-{}", std::process::id()));
    let mut a = args(&["cornell"], &dir);
    let scene = chart_scene("cornell", &a).unwrap();
    let (first, _, source) = reference(&scene, &a, 1).unwrap();
    assert_eq!(source, "rendered");
    let (again, _, source) = reference(&scene, &a, 1).unwrap();
    assert_eq!((source, &again), ("cached", &first));
    // Another kernel or sample count is another reference.
    assert_eq!(reference(&scene, &a, 2).unwrap().2, "rendered");
    a.reference_spp = 4;
    assert_eq!(reference(&scene, &a, 1).unwrap().2, "rendered");
    let _ = std::fs::remove_dir_all(dir);
}

#[test]
fn unknown_scenes_and_bad_settings_are_errors() {
    let dir = std::env::temp_dir();
    let e = chart(&args(&["no-such-scene"], &dir)).unwrap_err();
    assert!(format!("{e:#}").contains("neither a built-in scene"), "{e:#}");
    let mut a = args(&["cornell"], &dir);
    a.spp = 0;
    assert!(chart(&a).is_err());
}

/// A driver report for one strategy at 2x2, checkpoints 1 and 2, whose accumulation is
/// `value` per sample.
fn report(value: f64) -> serde_json::Value {
    let data = |spp: f64| (0..4).flat_map(|_| [value * spp, value * spp, value * spp, spp]).collect::<Vec<f64>>();
    serde_json::json!({
        "gl": { "renderer": "test", "version": "test" },
        "warmUpMs": 1.0,
        "lines": [{ "strategy": "mis", "points": [
            { "spp": 1, "ms": 2.0, "width": 2, "height": 2, "data": data(1.0) },
            { "spp": 2, "ms": 5.0, "width": 2, "height": 2, "data": data(2.0) },
        ]}],
    })
}

/// `report(value)` with a denoised twin whose denoised image is `denoised` everywhere.
fn denoised_report(value: f64, denoised: f64) -> serde_json::Value {
    let mut r = report(value);
    let data = vec![denoised; 4 * 3];
    let twin = serde_json::json!({ "strategy": "mis", "denoised": true, "points": [
        { "spp": 1, "ms": 3.0, "width": 2, "height": 2, "data": data, "accepted": 4.0 },
        { "spp": 2, "ms": 7.0, "width": 2, "height": 2, "data": data, "accepted": 7.0 },
    ]});
    r["lines"].as_array_mut().unwrap().push(twin);
    r
}

#[test]
fn web_reports_become_points_and_bad_ones_errors() {
    let reference = vec![Vec3::splat(0.5); 4];
    let lines = web::from_report(&report(0.5), &[Strategy::Mis], 2, &[1, 2], &reference, false).unwrap();
    let line = &lines[0];
    assert_eq!(line.iter().map(|p| (p.spp, p.seconds)).collect::<Vec<_>>(), [(1, 0.002), (2, 0.005)]);
    assert!(line.iter().all(|p| p.rmse == 0.0 && p.rejected == 0 && p.backend == ChartBackend::Web));
    let off = web::from_report(&report(0.75), &[Strategy::Mis], 2, &[1, 2], &reference, false).unwrap();
    assert!((off[0][1].rmse - 0.25).abs() < 1e-6, "the mean of the sums is compared: {}", off[0][1].rmse);

    let refused_with = |report: serde_json::Value, strategies: &[Strategy], size: u32, spp: &[u32], denoise| {
        let reference = &reference[..(size * size) as usize];
        format!("{:#}", web::from_report(&report, strategies, size, spp, reference, denoise).unwrap_err())
    };
    let refused =
        |report, strategies: &[Strategy], size, spp: &[u32]| refused_with(report, strategies, size, spp, false);
    let mut error = report(0.5);
    error["error"] = "no WebGL2".into();
    assert!(refused(error, &[Strategy::Mis], 2, &[1, 2]).contains("the page reported: no WebGL2"));
    assert!(refused(report(0.5), &[Strategy::Nee], 2, &[1, 2]).contains("reported for nee"));
    assert!(refused(report(0.5), &[Strategy::Mis], 2, &[1, 4]).contains("says 2 spp"));
    assert!(refused(report(0.5), &[Strategy::Mis], 1, &[1, 2]).contains("not 1x1"));
    assert!(refused(report(0.5), &[Strategy::Mis, Strategy::Bsdf], 2, &[1, 2]).contains("1 lines reported"));
    let mut short = report(0.5);
    short["lines"][0]["points"][1]["data"] = serde_json::json!([1.0, 2.0]);
    assert!(refused(short, &[Strategy::Mis], 2, &[1, 2]).contains("2 values for 4 RGBA pixels"));
    let mut no_time = report(0.5);
    no_time["lines"][0]["points"][0]["ms"] = serde_json::Value::Null;
    assert!(refused(no_time, &[Strategy::Mis], 2, &[1, 2]).contains("no render time"));
    assert!(refused(serde_json::json!({}), &[Strategy::Mis], 2, &[1, 2]).contains("no lines"));

    // `--denoise`: the twin follows its line; its image is a mean (not divided again), its
    // dropped samples come from `accepted`.
    let lines = web::from_report(&denoised_report(0.75, 0.5), &[Strategy::Mis], 2, &[1, 2], &reference, true);
    let lines = lines.unwrap();
    assert_eq!(lines.len(), 2);
    assert!(lines[0].iter().all(|p| !p.denoised) && lines[1].iter().all(|p| p.denoised));
    assert!(lines[0][1].rmse > 0.2, "the raw line is off: {}", lines[0][1].rmse);
    let twin = &lines[1];
    assert_eq!(twin.iter().map(|p| (p.spp, p.seconds, p.rejected)).collect::<Vec<_>>(), [(1, 0.003, 0), (2, 0.007, 1)]);
    assert!(twin.iter().all(|p| p.rmse == 0.0 && p.backend == ChartBackend::Web && p.strategy == Strategy::Mis));
    let denoise = |r, spp: &[u32]| refused_with(r, &[Strategy::Mis], 2, spp, true);
    assert!(denoise(report(0.5), &[1, 2]).contains("0 denoised lines reported, 1 asked for"));
    assert!(refused(denoised_report(0.5, 0.5), &[Strategy::Mis], 2, &[1, 2]).contains("1 denoised lines reported, 0"));
    let mut rgba = denoised_report(0.5, 0.5);
    rgba["lines"][1]["points"][0]["data"] = serde_json::json!(vec![0.5; 16]);
    assert!(denoise(rgba, &[1, 2]).contains("mis denoised at 1 spp: 16 values for 4 RGB pixels"));
    let mut uncounted = denoised_report(0.5, 0.5);
    uncounted["lines"][1]["points"][1]["accepted"] = serde_json::Value::Null;
    assert!(denoise(uncounted, &[1, 2]).contains("mis denoised at 2 spp: no count of accepted samples"));
    let mut wrong = denoised_report(0.5, 0.5);
    wrong["lines"][1]["strategy"] = "nee".into();
    assert!(denoise(wrong, &[1, 2]).contains("line \"nee\" reported for mis denoised"));
    let mut late = denoised_report(0.5, 0.5);
    late["lines"][1]["points"][1]["spp"] = 4.into();
    assert!(denoise(late, &[1, 2]).contains("mis denoised at 2 spp: the report says 4 spp"));
}

#[test]
fn slugs_are_file_name_safe() {
    assert_eq!(slugify("Box Textured/x.y"), "box-textured-x-y");
}
