//! The `lightport render` command line: forgiving loading, `--strict`, and the warning for a
//! scene that nothing lights.

use crate::common;

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use common::test_data;

fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("lightport-cli-{}-{name}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// `lightport render SCENE ARGS` at a tiny size, writing into `dir`; `scene` relative to
/// `tests/data/scenes/`.
fn render(scene: &str, args: &[&str], dir: &Path) -> Output {
    Command::new(env!("CARGO_BIN_EXE_lightport"))
        .arg("render")
        .arg(test_data(&format!("scenes/{scene}")))
        .args(["--width", "8", "--height", "8", "--spp", "1", "--out"])
        .arg(dir.join("out.png"))
        .args(args)
        .output()
        .expect("run lightport")
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

#[test]
fn a_missing_texture_is_a_warning_and_strict_refuses_it() {
    let dir = scratch("missing-texture");
    // Two textured boxes; the second one's base colour image is not there.
    let scene = "missing-texture/MissingTexture.gltf";
    let lenient = render(scene, &[], &dir);
    let err = stderr(&lenient);
    assert!(lenient.status.success(), "{err}");
    let warned: Vec<&str> = err.lines().filter(|l| l.contains("Label_baseColor.png")).collect();
    assert!(warned.len() == 1 && warned[0].starts_with("warning: "), "{err}");
    assert!(dir.join("out.png").is_file());
    std::fs::remove_file(dir.join("out.png")).unwrap();

    let strict = render(scene, &["--strict"], &dir);
    let err = stderr(&strict);
    assert!(!strict.status.success(), "{err}");
    assert!(err.starts_with("error: ") && err.contains("Label_baseColor.png"), "{err}");
    assert!(!dir.join("out.png").exists(), "an image was written anyway");
    std::fs::remove_dir_all(dir).ok();
}

/// A file that is not there, or an image that cannot be written, is one error line that names
/// the file and says the operating system's reason once (it was printed twice: the error's
/// message held its cause and anyhow's chain printed it again).
#[test]
fn a_file_that_cannot_be_read_or_written_is_one_clear_error() {
    let dir = scratch("unreadable");
    let missing = render("missing/nothing-here.glb", &[], &dir);
    let err = stderr(&missing);
    assert!(!missing.status.success(), "{err}");
    let reason = "No such file or directory";
    assert!(err.starts_with("error: ") && err.contains("nothing-here.glb"), "{err}");
    assert_eq!(err.matches(reason).count(), 1, "the reason once: {err}");

    let unwritable = dir.join("no-such-dir/out.png");
    let o = Command::new(env!("CARGO_BIN_EXE_lightport"))
        .args(["render", "--width", "8", "--height", "8", "--spp", "1", "--out"])
        .arg(&unwritable)
        .output()
        .expect("run lightport");
    let err = stderr(&o);
    assert!(!o.status.success(), "{err}");
    let line = err.lines().find(|l| l.starts_with("error: ")).unwrap_or_default();
    assert!(line.contains("out.png") && line.matches(reason).count() == 1, "{err}");
    std::fs::remove_dir_all(dir).ok();
}

/// A scene that nothing lights is lit by the default white sky, with a warning that says so
/// and names `--sky`; `--sky none` keeps it black (and warns that it will be); `--strict`
/// refuses it; a sky of its own lights it with no warning.
#[test]
fn an_unlit_scene_is_lit_by_the_default_sky_and_warned_about() {
    let dir = scratch("unlit");
    // Khronos' Box: one material, which does not emit, and no sky.
    let unlit = "khronos/Box/glTF-Binary/Box.glb";
    let mean = |o: &Output| {
        assert!(o.status.success(), "{}", stderr(o));
        let pixels = image::open(dir.join("out.png")).expect("a PNG").into_rgb8().into_raw();
        pixels.iter().map(|&c| f64::from(c)).sum::<f64>() / pixels.len() as f64
    };
    let lit = render(unlit, &[], &dir);
    let err = stderr(&lit);
    assert!(err.contains("warning: nothing lights the scene") && err.contains("lit by a uniform white sky"), "{err}");
    assert!(err.contains("--sky FILE.hdr") && err.contains("--sky none"), "{err}");
    // The box fills most of the view and reflects the sky: far from black.
    let lit_mean = mean(&lit);
    assert!(lit_mean > 60.0, "the default sky lights the box: mean {lit_mean}");

    let dark = render(unlit, &["--sky", "none"], &dir);
    assert!(stderr(&dark).contains("it will render black"), "{}", stderr(&dark));
    assert_eq!(mean(&dark), 0.0, "--sky none keeps the scene unlit");

    let strict = render(unlit, &["--strict"], &dir);
    assert!(!strict.status.success() && stderr(&strict).contains("nothing lights the scene"), "{}", stderr(&strict));

    let sky = test_data("scenes/hdri/venice_sunset_1k.hdr");
    let lit = render(unlit, &["--strict", "--sky", sky.to_str().unwrap()], &dir);
    assert!(lit.status.success(), "{}", stderr(&lit));
    assert!(!stderr(&lit).contains("warning"), "{}", stderr(&lit));
    // The built-in Cornell box has its light.
    let cornell = Command::new(env!("CARGO_BIN_EXE_lightport"))
        .args(["render", "--strict", "--width", "8", "--height", "8", "--spp", "1", "--out"])
        .arg(dir.join("cornell.png"))
        .output()
        .unwrap();
    assert!(cornell.status.success() && !stderr(&cornell).contains("warning"), "{}", stderr(&cornell));
    std::fs::remove_dir_all(dir).ok();
}

/// `render --denoise` writes the denoised image to `--out` and, with `--noisy`, the noisy one
/// too, on every native runtime (the moments come from each frame's accumulation); the two
/// differ and the denoised one is smoother. With `--aovs`, the guide as four EXR images (the
/// Cornell box's albedos within [0, 1], unit normals). `--noisy` and `--aovs` alone are refused.
#[test]
fn render_denoise_writes_the_denoised_and_the_noisy_image() {
    let dir = scratch("denoise");
    for backend in ["cpu", "gl", "wgpu"] {
        let (out, noisy) = (dir.join(format!("{backend}.exr")), dir.join(format!("{backend}-noisy.exr")));
        let o = Command::new(env!("CARGO_BIN_EXE_lightport"))
            .args(["render", "--backend", backend, "--width", "24", "--height", "24", "--spp", "8", "--denoise"])
            .arg("--out")
            .arg(&out)
            .arg("--noisy")
            .arg(&noisy)
            .arg("--aovs")
            .arg(dir.join(format!("{backend}-aovs")))
            .output()
            .expect("run lightport");
        let stdout = String::from_utf8_lossy(&o.stdout);
        assert!(o.status.success(), "{backend}: {}{stdout}", stderr(&o));
        assert!(stdout.contains("denoise ") && stdout.contains("(noisy)"), "{backend}: {stdout}");
        let read = |p: &Path| image::open(p).expect("an EXR").into_rgb32f().into_raw();
        let aov = |name: &str| read(&dir.join(format!("{backend}-aovs/{name}.exr")));
        let (albedo, normal, depth) = (aov("albedo"), aov("normal"), aov("depth"));
        assert_eq!((albedo.len(), normal.len(), depth.len(), aov("emission").len()), (24 * 24 * 3, 1728, 1728, 1728));
        assert!(albedo.iter().all(|a| (0.0..=1.0).contains(a)), "{backend}: albedo out of [0, 1]");
        assert!(
            normal.chunks(3).all(|n| (n[0] * n[0] + n[1] * n[1] + n[2] * n[2] - 1.0).abs() < 1e-3),
            "{backend}: normals are not unit"
        );
        assert!(depth.iter().all(|d| *d > 0.0), "{backend}: the box is in front of the camera");
        let (denoised, noisy) = (read(&out), read(&noisy));
        // Roughness: the mean squared difference between horizontal neighbours.
        let roughness = |v: &[f32]| -> f64 {
            let row = 24 * 3;
            let pairs = v.chunks(row).flat_map(|r| r.windows(4).map(|w| (w[3] - w[0]) as f64));
            pairs.map(|d| d * d).sum::<f64>() / v.len() as f64
        };
        assert_ne!(denoised, noisy, "{backend}");
        assert!(roughness(&denoised) < roughness(&noisy), "{backend}: the denoised image is not smoother");
    }
    let o = Command::new(env!("CARGO_BIN_EXE_lightport"))
        .args(["render", "--width", "8", "--height", "8", "--spp", "1", "--noisy"])
        .arg(dir.join("alone.png"))
        .output()
        .expect("run lightport");
    assert!(!o.status.success() && stderr(&o).contains("--denoise"), "{}", stderr(&o));
    let o = Command::new(env!("CARGO_BIN_EXE_lightport"))
        .args(["render", "--width", "8", "--height", "8", "--spp", "1", "--aovs"])
        .arg(dir.join("aovs-alone"))
        .output()
        .expect("run lightport");
    assert!(!o.status.success() && stderr(&o).contains("--denoise"), "{}", stderr(&o));
}

/// `render --frames N` renders the animation as N poses with one renderer (each pose's
/// geometry taken without recompiling), writes each frame and a strip of them side by side,
/// and prints a row per frame; the poses differ. A scene that does not move is a clear error.
#[test]
fn render_frames_writes_each_pose_and_a_strip() {
    let dir = scratch("frames");
    let sky = test_data("scenes/hdri/venice_sunset_1k.hdr");
    for backend in ["cpu", "gl", "wgpu"] {
        let out = dir.join(format!("{backend}.png"));
        let o = Command::new(env!("CARGO_BIN_EXE_lightport"))
            .arg("render")
            .arg(test_data("scenes/generated/animated-skinned-instanced.gltf"))
            .args(["--backend", backend, "--width", "16", "--height", "12", "--spp", "2", "--frames", "3"])
            .args(["--until", "1", "--out"])
            .arg(&out)
            .arg("--sky")
            .arg(&sky)
            .output()
            .expect("run lightport");
        let stdout = String::from_utf8_lossy(&o.stdout);
        assert!(o.status.success(), "{backend}: {}{stdout}", stderr(&o));
        assert!(stdout.contains("1 skinned or morphed meshes"), "{backend}: {stdout}");
        assert!(!stderr(&o).contains("created again"), "{backend}: recompiled: {}", stderr(&o));
        let frame = |k: usize| image::open(dir.join(format!("{backend}-{k:03}.png"))).expect("a frame").into_rgb8();
        let frames: Vec<_> = (0..3).map(frame).collect();
        assert!(frames.iter().all(|f| f.dimensions() == (16, 12)), "{backend}");
        assert!(frames[0] != frames[2], "{backend}: the first and last poses look the same");
        let strip = image::open(dir.join(format!("{backend}-strip.png"))).expect("the strip").into_rgb8();
        assert_eq!(strip.dimensions(), (48, 12), "{backend}");
        assert_eq!(strip.get_pixel(32 + 5, 7), frames[2].get_pixel(5, 7), "{backend}: the strip's third frame");
    }
    let o = render("cornell-box/CornellBox-Original.gltf", &["--frames", "2"], &dir);
    assert!(!o.status.success() && stderr(&o).contains("needs an animated scene"), "{}", stderr(&o));
}

/// `render --schedule`: the CPU's wavefront writes the megakernel's image bit for bit, wgpu's
/// renders the box, the read-out names the schedule; GL has none: a clear error. With
/// `--denoise` the CPU's wavefront writes the megakernel's denoised image and guide bit for bit
/// (it accumulates the same guide), and wgpu's denoises too.
#[test]
fn render_schedule_chooses_the_wavefront_or_refuses_it_clearly() {
    let dir = scratch("schedule");
    let run = |args: &[&str], out: &str| {
        Command::new(env!("CARGO_BIN_EXE_lightport"))
            .args(["render", "--width", "20", "--height", "16", "--spp", "3"])
            .args(args)
            .arg("--out")
            .arg(dir.join(out))
            .output()
            .expect("run lightport")
    };
    let read = |name: &str| image::open(dir.join(name)).expect("an EXR").into_rgb32f().into_raw();
    for (schedule, out) in [("megakernel", "mega.exr"), ("wavefront", "wave.exr"), ("auto", "auto.exr")] {
        let o = run(&["--schedule", schedule], out);
        let stdout = String::from_utf8_lossy(&o.stdout);
        assert!(o.status.success(), "{schedule}: {}", stderr(&o));
        let runs = if schedule == "auto" { "megakernel" } else { schedule };
        assert!(stdout.contains(&format!("\"cpu\" backend, {runs}")), "{schedule}: {stdout}");
    }
    assert_eq!(read("wave.exr"), read("mega.exr"), "the CPU's wavefront adds the megakernel's samples");
    assert_eq!(read("auto.exr"), read("mega.exr"));
    let o = run(&["--schedule", "wavefront", "--backend", "wgpu"], "wgpu.exr");
    assert!(o.status.success(), "{}", stderr(&o));
    let lit = read("wgpu.exr").iter().filter(|v| **v > 0.0).count();
    assert!(lit > 20 * 16, "the wgpu wavefront renders the box ({lit} lit values)");
    let o = run(&["--schedule", "wavefront", "--backend", "gl"], "gl.png");
    assert!(!o.status.success() && stderr(&o).contains("no compute shaders"), "{}", stderr(&o));
    let aovs = |name: &str| dir.join(name).to_str().expect("a UTF-8 path").to_string();
    for schedule in ["megakernel", "wavefront"] {
        let (aov_dir, noisy) = (aovs(&format!("{schedule}-aovs")), aovs(&format!("{schedule}-noisy.exr")));
        let args = ["--schedule", schedule, "--denoise", "--aovs", &aov_dir, "--noisy", &noisy];
        let o = run(&args, &format!("{schedule}-denoised.exr"));
        let stdout = String::from_utf8_lossy(&o.stdout);
        assert!(o.status.success(), "{schedule} --denoise: {}", stderr(&o));
        assert!(stdout.contains("denoise ") && stdout.contains(&format!("backend, {schedule}")), "{stdout}");
    }
    let same = read("wavefront-denoised.exr") == read("megakernel-denoised.exr");
    assert!(same, "the wavefront's denoised image is not the megakernel's");
    assert_ne!(read("wavefront-denoised.exr"), read("wavefront-noisy.exr"), "the filter ran");
    for aov in ["albedo", "normal", "depth", "emission"] {
        let (wave, mega) = (format!("wavefront-aovs/{aov}.exr"), format!("megakernel-aovs/{aov}.exr"));
        assert!(read(&wave) == read(&mega), "the wavefront's {aov} is not the megakernel's");
    }
    let o = run(&["--schedule", "wavefront", "--backend", "wgpu", "--denoise"], "wgpu-denoised.exr");
    assert!(o.status.success(), "wgpu wavefront --denoise: {}", stderr(&o));
    let lit = read("wgpu-denoised.exr").iter().filter(|v| **v > 0.0).count();
    assert!(lit > 20 * 16, "the wgpu wavefront denoises the box ({lit} lit values)");
}

/// `lightport chart` charts the wavefront by default: on the CPU and wgpu each strategy has a
/// megakernel line and a wavefront line (the CSV's `schedule` column, the summary and the
/// legend name them); GL has the megakernel only; `--schedules megakernel` leaves them out.
#[test]
fn chart_draws_a_wavefront_line_beside_each_megakernel_line() {
    let dir = scratch("chart-schedules");
    let chart = |extra: &[&str]| {
        Command::new(env!("CARGO_BIN_EXE_lightport"))
            .args(["chart", "furnace", "--size", "8", "--spp", "4", "--strategies", "nee,mis", "--out-dir"])
            .arg(dir.join("chart"))
            .args(extra)
            .output()
            .expect("run lightport")
    };
    let o = chart(&["--backends", "cpu,gl,wgpu"]);
    let stdout = String::from_utf8_lossy(&o.stdout).into_owned();
    assert!(o.status.success(), "{}", stderr(&o));
    let csv = std::fs::read_to_string(dir.join("chart/furnace.csv")).expect("the CSV");
    assert!(csv.starts_with("scene,backend,strategy,") && csv.lines().next().unwrap().ends_with(",schedule"), "{csv}");
    let lines = |backend: &str, schedule: &str| {
        csv.lines()
            .filter(|l| l.starts_with(&format!("furnace,{backend},")) && l.ends_with(&format!(",{schedule}")))
            .count()
    };
    // 2 strategies x checkpoints 1, 2, 4.
    for (backend, schedule, rows) in [
        ("cpu", "megakernel", 6),
        ("cpu", "wavefront", 6),
        ("gl", "megakernel", 6),
        ("gl", "wavefront", 0),
        ("wgpu", "megakernel", 6),
        ("wgpu", "wavefront", 6),
    ] {
        assert_eq!(lines(backend, schedule), rows, "{backend}, {schedule}:\n{csv}");
    }
    for label in ["| cpu, wavefront | mis |", "| wgpu, wavefront | nee |", "| wgpu, megakernel | mis |", "| gl | mis |"]
    {
        assert!(stdout.contains(label), "the summary has {label:?}:\n{stdout}");
    }
    let svg = std::fs::read_to_string(dir.join("chart/furnace.svg")).expect("the chart");
    assert!(
        svg.contains("mis wgpu, wavefront") && svg.contains("nee cpu, wavefront"),
        "the legend names the wavefront lines"
    );
    let o = chart(&["--backends", "cpu", "--schedules", "megakernel"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let csv = std::fs::read_to_string(dir.join("chart/furnace.csv")).expect("the CSV");
    assert!(!csv.contains(",wavefront") && csv.lines().count() == 1 + 6, "{csv}");
    let _ = std::fs::remove_dir_all(dir);
}
