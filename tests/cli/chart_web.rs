//! `lightport chart --backends web`: the web client (served by `lightport serve`, driven in
//! headless Chromium by `tests/web/run.mjs chart`) as lines of the convergence chart, run through
//! the CLI end to end at a small size (SwiftShader is slow).
//!
//! Never skipped: like tests/cli/web.rs, these need `web/pkg/` (scripts/build-web.sh),
//! `tests/web/node_modules` (`npm ci` in tests/web), node and /usr/bin/chromium, and fail when the
//! web line is missing. The skip path (a missing piece gives a warning, not a failure of the
//! whole chart) is tested by pointing the chart at a Chromium that does not exist.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use std::sync::Mutex;

/// One browser at a time: Chromium on SwiftShader takes the machine's cores.
static BROWSER: Mutex<()> = Mutex::new(());

const SIZE: u32 = 16;

fn temp_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("lightport-chart-web-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    dir
}

/// Runs `lightport chart cornell` at 16x16 up to `spp`, with `extra` arguments: the megakernel
/// only (the web line is compared with the CPU's megakernel line; the wavefront lines are
/// tests/cli/commands.rs's).
fn chart(dir: &Path, spp: u32, extra: &[&str], env: &[(&str, &str)]) -> Output {
    let mut command = Command::new(env!("CARGO_BIN_EXE_lightport"));
    command
        .args(["chart", "cornell", "--size", &SIZE.to_string(), "--spp", &spp.to_string(), "--reference-spp", "64"])
        .args(["--schedules", "megakernel"])
        .arg("--out-dir")
        .arg(dir.join("chart"))
        .arg("--reference-dir")
        .arg(dir.join("reference"))
        .args(extra);
    for (k, v) in env {
        command.env(k, v);
    }
    let output = command.output().expect("lightport runs");
    eprintln!("{}", String::from_utf8_lossy(&output.stderr));
    println!("{}", String::from_utf8_lossy(&output.stdout));
    output
}

/// The CSV's rows as (backend, strategy, spp, seconds, rmse, rejected samples, denoised, relMSE).
type Row = (String, String, u32, f64, f64, u64, bool, f64);

fn rows(dir: &Path) -> Vec<Row> {
    let csv = std::fs::read_to_string(dir.join("chart/cornell.csv")).expect("the chart's CSV");
    csv.lines()
        .skip(1)
        .map(|line| {
            let f: Vec<&str> = line.split(',').collect();
            (
                f[1].to_string(),
                f[2].to_string(),
                f[3].parse().expect("spp"),
                f[4].parse().expect("seconds"),
                f[5].parse().expect("rmse"),
                f[7].parse().expect("rejected"),
                f[9].parse().expect("denoised"),
                f[6].parse().expect("rel_mse"),
            )
        })
        .collect()
}

#[test]
fn the_web_line_renders_the_same_samples_as_the_cpu_and_is_timed() {
    let _guard = BROWSER.lock().unwrap_or_else(|e| e.into_inner());
    let dir = temp_dir("line");
    let out = chart(&dir, 4, &["--backends", "cpu,web", "--strategies", "bsdf,mis"], &[]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "lightport chart failed: {stderr}");
    assert!(!stderr.contains("skipping the web backend"), "the web line is missing: {stderr}");
    let rows = rows(&dir);
    for strategy in ["bsdf", "mis"] {
        let line = |backend: &str| -> Vec<_> {
            rows.iter().filter(|r| r.0 == backend && r.1 == strategy).cloned().collect::<Vec<_>>()
        };
        let (web, cpu) = (line("web"), line("cpu"));
        assert_eq!(web.iter().map(|r| r.2).collect::<Vec<_>>(), [1, 2, 4], "web {strategy} checkpoints: {rows:?}");
        assert_eq!(cpu.len(), 3);
        let mut previous = 0.0;
        for (w, c) in web.iter().zip(&cpu) {
            assert!(w.3 > previous, "web {strategy}: render time must grow with the samples: {web:?}");
            previous = w.3;
            assert_eq!(w.5, 0, "web {strategy}: dropped samples");
            // Same packed scene and seed: the page draws the CPU backend's samples, so the
            // errors agree closely (only float rounding on SwiftShader can move a path); an
            // image from another scene, seed, strategy, sample count or row order would not.
            let relative = (w.4 - c.4).abs() / c.4;
            assert!(relative < 0.02, "web {strategy} at {} spp: RMSE {} vs CPU {} ({relative:.4})", w.2, w.4, c.4);
        }
    }
    let svg = std::fs::read_to_string(dir.join("chart/cornell.svg")).expect("the chart");
    assert!(svg.contains("mis web") && svg.contains("bsdf web"), "the chart's legend names the web lines");
    let crops = std::fs::read_to_string(dir.join("chart/cornell-equal-time.svg")).expect("the labelled crops");
    assert!(crops.contains("mis · web") && crops.contains("data:image/png;base64,"), "labelled web crop");
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(stdout.contains("| web | mis | 4 |"), "the summary has the web line: {stdout}");
    let _ = std::fs::remove_dir_all(dir);
}

/// `--denoise`: the web line's twin is denoised in the page (its own denoiser: WebGL2 passes,
/// the same remodulation) from the same samples as the CPU's twin, so the two denoised images
/// agree closely; it is timed with the rendering (with the guide) and the denoise.
#[test]
fn the_web_line_has_a_twin_denoised_in_the_page() {
    let _guard = BROWSER.lock().unwrap_or_else(|e| e.into_inner());
    let dir = temp_dir("denoise");
    let out = chart(&dir, 16, &["--backends", "cpu,web", "--strategies", "mis", "--denoise"], &[]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "lightport chart failed: {stderr}");
    assert!(!stderr.contains("skipping the web backend"), "the web lines are missing: {stderr}");
    let rows = rows(&dir);
    let line = |backend: &str, denoised: bool| -> Vec<_> {
        rows.iter().filter(|r| r.0 == backend && r.1 == "mis" && r.6 == denoised).cloned().collect::<Vec<_>>()
    };
    let (web, web_raw, cpu, cpu_raw) = (line("web", true), line("web", false), line("cpu", true), line("cpu", false));
    let spp = [1, 2, 4, 8, 16];
    for l in [&web, &web_raw, &cpu, &cpu_raw] {
        assert_eq!(l.iter().map(|r| r.2).collect::<Vec<_>>(), spp, "every line at every checkpoint: {rows:?}");
    }
    for ((w, c), raw) in web.iter().zip(&cpu).zip(&web_raw) {
        assert_eq!(w.5, 0, "web denoised at {} spp: dropped samples", w.2);
        // Same samples, the same filter (its passes agree across runtimes to ~1e-5) and the
        // same remodulation: the denoised images' errors agree closely (measured: to 7 digits).
        // The raw image, or one denoised without the remodulation, would not (at 16 spp the
        // filter takes a third off the relMSE).
        for (what, web, cpu) in [("RMSE", w.4, c.4), ("relMSE", w.7, c.7)] {
            let relative = (web - cpu).abs() / cpu;
            assert!(relative < 0.01, "web denoised at {} spp: {what} {web} vs CPU denoised {cpu} ({relative:.4})", w.2);
        }
        assert!(w.3.is_finite() && w.3 > 0.0, "web denoised at {} spp: {} s (raw {} s)", w.2, w.3, raw.3);
    }
    let (last, last_raw) = (web.last().unwrap(), web_raw.last().unwrap());
    // Timed: rendered again (with the guide) and denoised, so its time grows with the frames and
    // at 16 spp is about the raw line's or more (not the denoise's alone, nor in other units).
    // Single frames are too short to compare: one of the raw line's took 72 ms once, 9 ms usually.
    assert!(last.3 > web[0].3, "web denoised: {} s at 16 spp, {} s at 1 spp", last.3, web[0].3);
    assert!(last.3 > 0.5 * last_raw.3, "web denoised at 16 spp: {} s, raw {} s", last.3, last_raw.3);
    assert!(last.7 < 0.8 * last_raw.7, "denoised relMSE {} at 16 spp, raw {}: {rows:?}", last.7, last_raw.7);
    let svg = std::fs::read_to_string(dir.join("chart/cornell.svg")).expect("the chart");
    assert!(svg.contains("mis web denoised"), "the chart's legend names the web twin");
    let _ = std::fs::remove_dir_all(dir);
}

#[test]
fn a_missing_browser_skips_the_web_backend_with_the_command_that_installs_it() {
    let dir = temp_dir("missing");
    let out =
        chart(&dir, 2, &["--backends", "cpu,web", "--strategies", "mis"], &[("CHROMIUM", "/nonexistent/chromium")]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "a missing browser must not fail the chart: {stderr}");
    assert!(
        stderr.contains("warning: skipping the web backend") && stderr.contains("apt-get install chromium"),
        "{stderr}"
    );
    let rows = rows(&dir);
    assert!(rows.iter().all(|r| r.0 == "cpu") && rows.len() == 2, "{rows:?}");
    let _ = std::fs::remove_dir_all(dir);
}

#[test]
fn a_page_that_does_not_finish_in_time_is_given_up() {
    let _guard = BROWSER.lock().unwrap_or_else(|e| e.into_inner());
    let dir = temp_dir("timeout");
    let start = std::time::Instant::now();
    // Starting Chromium and loading the page alone takes longer than this.
    let out = chart(&dir, 2, &["--backends", "web", "--strategies", "mis", "--web-timeout", "0.5"], &[]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stderr}");
    assert!(stderr.contains("did not finish within --web-timeout 0.5 s"), "{stderr}");
    assert!(start.elapsed().as_secs() < 60, "the deadline must stop the browser promptly");
    assert!(rows(&dir).is_empty());
    let _ = std::fs::remove_dir_all(dir);
}

#[test]
fn bad_web_settings_are_errors() {
    let dir = temp_dir("bad");
    let out = chart(&dir, 1, &["--backends", "web", "--web-timeout", "0"], &[]);
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("--web-timeout must be"));
    let _ = std::fs::remove_dir_all(dir);
}
