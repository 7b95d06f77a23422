//! The web backend: the chart's lines rendered by the web client in headless Chromium.
//!
//! `lightport serve --port 0` (this executable) serves the page (`web/www/`) and its wasm build
//! (`web/pkg/`); `tests/web/run.mjs chart` (node + npm `playwright-core`) opens it with
//! `?bundle=...&size=...&seed=...&paused=1`, answering the bundle URL with this chart's own
//! bundle ([`tracer::bundle`] of the packed scene the other backends render), so the page
//! renders the same data with the same seed. For each strategy the page restarts the
//! accumulation and renders up to each checkpoint; it times, with `performance.now()`, the
//! frames it renders (accumulation pass and the display pass to the canvas) and the wait for
//! them to finish (a 1-pixel `readPixels`). Not timed: browser start, page load, bundle decode
//! and upload, shader compile, one warm-up frame (the driver JITs the kernel at its first draw,
//! as the GL backend's throwaway renderer pays for natively) and the float read-back after each
//! checkpoint. The driver writes the accumulations (rgb sums and finite-sample counts) as JSON.
//!
//! With `--denoise` (`run.mjs chart --denoise 1`) each strategy also has a denoised twin,
//! denoised in the page by the page's own denoiser (`web/src/denoise/`: its passes on WebGL2,
//! the remodulation `tracer::denoise::denoise_on`): after the raw lines the page's renderer is
//! recreated with the denoiser's guide (the page's own denoise schedule off), warmed up by an
//! untimed frame and an untimed denoise (the filter's shaders are compiled at the first), and
//! each strategy rendered to each checkpoint again; at each the page denoises the accumulation
//! once (`denoiseNow`). As the native twins' points, a point's time is the twin's rendering so
//! far (with the guide) plus that checkpoint's whole denoise (read-backs, passes and
//! remodulation, timed by the page); its image is the denoised one the page shows (means, not
//! sums).

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use anyhow::{bail, ensure, Context, Result};
use glam::Vec3;
use serde_json::Value;
use tracer::backend::Image;

use crate::serve_child::{start_serve, Killed};
use tracer::kernel::Strategy;
use tracer::pack::Packed;

use super::{checkpoints, ChartArgs, ChartBackend, Point};

/// The web client's directory (`www/` and the wasm build in `pkg/`), as `lightport serve`'s default.
const WEB_DIR: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/web");
/// The node driver and its `node_modules`.
const DRIVER_DIR: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/web");
/// How long `lightport serve` may take to print its URL.
const SERVER_START: Duration = Duration::from_secs(120);

/// What the web backend needs, found: Chromium's path is passed on to the driver.
pub(super) struct Tools {
    chromium: PathBuf,
}

/// Checks every prerequisite; the error names each missing one and the command that
/// installs it.
pub(super) fn prerequisites() -> Result<Tools> {
    let mut missing = Vec::new();
    if !Path::new(WEB_DIR).join("pkg/lightport_web_bg.wasm").is_file() {
        missing.push(format!("{WEB_DIR}/pkg (the wasm build): run scripts/build-web.sh"));
    }
    let node = Command::new("node").arg("--version").stdout(Stdio::null()).stderr(Stdio::null()).status();
    if !node.is_ok_and(|s| s.success()) {
        missing.push("node: apt-get install nodejs npm".into());
    }
    if !Path::new(DRIVER_DIR).join("node_modules/playwright-core").is_dir() {
        missing.push(format!("{DRIVER_DIR}/node_modules (npm playwright-core): run `npm ci` in tests/web"));
    }
    let chromium = std::env::var_os("CHROMIUM").map_or_else(|| PathBuf::from("/usr/bin/chromium"), PathBuf::from);
    if !chromium.is_file() {
        missing.push(format!("{} (Chromium): apt-get install chromium", chromium.display()));
    }
    if !missing.is_empty() {
        bail!("missing {} (scripts/test.sh installs them all)", missing.join("; "));
    }
    Ok(Tools { chromium })
}

/// Starts `lightport serve --port 0` (this executable) and returns it with its URL.
fn start_server() -> Result<(Killed, String)> {
    let exe = std::env::current_exe().context("finding the lightport executable")?;
    start_serve(&exe, &[], SERVER_START, false)
}

/// Renders every strategy's line in the browser; see the module's documentation.
pub(super) fn lines(
    slug: &str,
    packed: &Packed,
    strategies: &[Strategy],
    args: &ChartArgs,
    reference: &[Vec3],
) -> Result<Vec<Vec<Point>>> {
    let tools = prerequisites()?;
    let deadline = Duration::from_secs_f64(args.web_timeout);
    let temp = std::env::temp_dir();
    let stem = format!("lightport-chart-{}-{slug}", std::process::id());
    let (bundle, report) = (temp.join(format!("{stem}.lpb")), temp.join(format!("{stem}.json")));
    std::fs::write(&bundle, tracer::bundle::encode_named(slug, packed))
        .with_context(|| format!("writing {}", bundle.display()))?;
    let result = (|| {
        let (_server, url) = start_server()?;
        let spp: Vec<String> = checkpoints(args.spp).iter().map(u32::to_string).collect();
        let names: Vec<&str> = strategies.iter().map(|s| s.name()).collect();
        let size = format!("{0}x{0}", args.size);
        let mut command = Command::new("node");
        command
            .current_dir(DRIVER_DIR)
            .args(["run.mjs", "chart", "--url", &url, "--size", &size])
            .args(["--seed", &args.seed.to_string(), "--strategies", &names.join(","), "--checkpoints"])
            .arg(spp.join(","))
            .arg("--deadline")
            .arg(format!("{}", args.web_timeout))
            .arg("--bundle")
            .arg(&bundle)
            .arg("--out")
            .arg(&report)
            .arg("--exit-on-stdin-eof")
            .args(["--denoise", if args.denoise { "1" } else { "0" }])
            .env("CHROMIUM", &tools.chromium);
        let start = Instant::now();
        let mut driver = Killed::spawn_tied(&mut command).context("starting node tests/web/run.mjs")?;
        // The driver gives up by itself at the deadline (closing the browser); this is the
        // backstop should node itself hang.
        let status = loop {
            if let Some(status) = driver.child().try_wait()? {
                break status;
            }
            if start.elapsed() > deadline + Duration::from_secs(30) {
                bail!("the browser driver did not finish within --web-timeout {} s", args.web_timeout);
            }
            std::thread::sleep(Duration::from_millis(100));
        };
        match status.code() {
            Some(0) => {}
            Some(3) => bail!("the page did not finish within --web-timeout {} s", args.web_timeout),
            _ => bail!("tests/web/run.mjs chart failed ({status}); its output is above"),
        }
        let text = std::fs::read_to_string(&report).with_context(|| format!("reading {}", report.display()))?;
        let value: Value = serde_json::from_str(&text).context("the driver's report is not JSON")?;
        from_report(&value, strategies, args.size, &checkpoints(args.spp), reference, args.denoise)
    })();
    let _ = std::fs::remove_file(&bundle);
    let _ = std::fs::remove_file(&report);
    result
}

/// The lines of the driver's report, checked against what was asked for: a line per strategy
/// and, with `denoise`, its denoised twin after it.
pub(super) fn from_report(
    report: &Value,
    strategies: &[Strategy],
    size: u32,
    checkpoints: &[u32],
    reference: &[Vec3],
    denoise: bool,
) -> Result<Vec<Vec<Point>>> {
    if let Some(error) = report.get("error").filter(|e| !e.is_null()) {
        let error = error.as_str().map_or_else(|| error.to_string(), str::to_owned);
        let hint = if error.contains("another kernel") { " (scripts/build-web.sh rebuilds the page)" } else { "" };
        bail!("the page reported: {error}{hint}");
    }
    let gl = &report["gl"];
    println!(
        "web: headless Chromium, {} ({}); untimed warm-up frame {:.0} ms",
        gl["renderer"].as_str().unwrap_or("?"),
        gl["version"].as_str().unwrap_or("?"),
        report["warmUpMs"].as_f64().unwrap_or(f64::NAN)
    );
    let reported = report["lines"].as_array().context("the report has no lines")?;
    let (twins, raw): (Vec<&Value>, Vec<&Value>) = reported.iter().partition(|l| l["denoised"] == true);
    ensure!(raw.len() == strategies.len(), "{} lines reported, {} asked for", raw.len(), strategies.len());
    let expected = if denoise { strategies.len() } else { 0 };
    ensure!(twins.len() == expected, "{} denoised lines reported, {expected} asked for", twins.len());
    for twin in &twins {
        let ms: Vec<String> = twin["points"]
            .as_array()
            .into_iter()
            .flatten()
            .map(|p| format!("{} spp {:.1}", p["spp"], p["filterMs"].as_f64().unwrap_or(f64::NAN)))
            .collect();
        println!(
            "web: {} denoised in the page, ms per denoise: {}",
            twin["strategy"].as_str().unwrap_or("?"),
            ms.join(", ")
        );
    }
    let mut lines = Vec::new();
    for (i, &strategy) in strategies.iter().enumerate() {
        lines.push(line_points(raw[i], strategy, false, size, checkpoints, reference)?);
        if denoise {
            lines.push(line_points(twins[i], strategy, true, size, checkpoints, reference)?);
        }
    }
    Ok(lines)
}

/// One reported line's points. Raw: `data` is the accumulation (rgb sums and the count of
/// finite samples per pixel); denoised: the denoised image (rgb means) and `accepted`, the
/// accumulation's count of finite samples.
fn line_points(
    line: &Value,
    strategy: Strategy,
    denoised: bool,
    size: u32,
    checkpoints: &[u32],
    reference: &[Vec3],
) -> Result<Vec<Point>> {
    let kind = if denoised { " denoised" } else { "" };
    ensure!(line["strategy"] == strategy.name(), "line {} reported for {}{kind}", line["strategy"], strategy.name());
    let reported = line["points"].as_array().context("a line without points")?;
    ensure!(reported.len() == checkpoints.len(), "{}{kind}: {} checkpoints reported", strategy.name(), reported.len());
    let pixels = (size * size) as usize;
    let mut points = Vec::new();
    for (p, &spp) in reported.iter().zip(checkpoints) {
        let what = || format!("{}{kind} at {spp} spp", strategy.name());
        ensure!(p["spp"].as_u64() == Some(spp as u64), "{}: the report says {} spp", what(), p["spp"]);
        ensure!(
            (p["width"].as_u64(), p["height"].as_u64()) == (Some(size as u64), Some(size as u64)),
            "{}: the page rendered {}x{}, not {size}x{size}",
            what(),
            p["width"],
            p["height"]
        );
        let ms = p["ms"].as_f64().filter(|ms| ms.is_finite() && *ms >= 0.0);
        let ms = ms.with_context(|| format!("{}: no render time", what()))?;
        let data = p["data"].as_array().with_context(|| format!("{}: no image", what()))?;
        let values: Vec<f32> = data.iter().map(|v| v.as_f64().map_or(f32::NAN, |v| v as f32)).collect();
        let (pixels_rgb, accepted) = if denoised {
            ensure!(data.len() == pixels * 3, "{}: {} values for {pixels} RGB pixels", what(), data.len());
            let accepted = p["accepted"].as_f64().filter(|a| a.is_finite() && *a >= 0.0);
            let accepted = accepted.with_context(|| format!("{}: no count of accepted samples", what()))?;
            (values.chunks_exact(3).map(Vec3::from_slice).collect::<Vec<_>>(), accepted)
        } else {
            ensure!(data.len() == pixels * 4, "{}: {} values for {pixels} RGBA pixels", what(), data.len());
            let n = spp as f32;
            let accepted: f64 = values.chunks_exact(4).map(|t| t[3] as f64).sum();
            (values.chunks_exact(4).map(|t| Vec3::new(t[0], t[1], t[2]) / n).collect(), accepted)
        };
        let image = Image { width: size, height: size, pixels: pixels_rgb };
        points.push(Point {
            backend: ChartBackend::Web,
            schedule: tracer::backend::Schedule::Megakernel,
            strategy,
            denoised,
            spp,
            seconds: ms / 1e3,
            rmse: tracer::stats::rmse(&image.pixels, reference)?,
            rel_mse: tracer::stats::rel_mse(&image.pixels, reference)?,
            rejected: (spp as u64 * pixels as u64).saturating_sub(accepted.round() as u64),
            image,
        });
    }
    Ok(points)
}
