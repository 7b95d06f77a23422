//! `lightport chart`: speed against accuracy. Each scene is rendered with each strategy (BSDF,
//! NEE, MIS) on each backend (CPU, GL, web) at 1, 2, 4, ... samples per pixel; each checkpoint's
//! render time and error against a converged reference (RMSE and relMSE) go to a CSV and an SVG
//! chart (error against time, log-log, with the −½ slope an unbiased estimator's RMSE follows).
//!
//! The reference is analytic where the scene has one (`furnace`, `sky-plane`); otherwise a long
//! CPU MIS render with its own seed, cached as EXR under `--reference-dir` by a hash of
//! everything it depends on (scene file bytes, sky file bytes and settings, image size, depth,
//! samples, seed and the generated kernel source), with the key beside it in a `.txt` file
//! that must match for the cache to be used.
//!
//! Times count rendering only (GL: up to `glFinish`), not renderer creation, the GL driver's
//! shader compile (a throwaway renderer draws one frame first), image read-back or the error
//! computation.
//!
//! The web backend (`--backends web`) renders in the real web client: `lightport serve` serves
//! the page and its wasm build, and `tests/web/run.mjs chart` drives headless Chromium (WebGL2 on
//! SwiftShader here) through npm `playwright-core`, handing the page this chart's own bundle (the
//! same packed data as the other backends) and reading the accumulation back at each checkpoint.
//! The page times its frames itself (see [`web`]). Missing pieces (`web/pkg`, node, the npm
//! driver, Chromium) skip the backend with a warning naming the command that installs them.

use std::fmt::Write as _;
use std::hash::{Hash, Hasher};
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use anyhow::{bail, ensure, Context, Result};
use base64::Engine as _;
use glam::Vec3;
use tracer::backend::cpu::CpuRenderer;
use tracer::backend::gl::GlRenderer;
use tracer::backend::Image;
use tracer::pack::{pack, Features, Packed, RenderSettings, Strategy};
use tracer::scene::{self, Scene, Sky};

/// Seed of reference renders: never the default seed of the charted renders, so that their
/// errors are independent of the reference's.
const REFERENCE_SEED: u32 = 0x7EF0_0001;
/// Version of the reference cache key; bump when what a reference means changes.
const CACHE_VERSION: u32 = 1;

#[derive(clap::Args)]
pub struct ChartArgs {
    /// Scenes: `cornell`, `metal-rough-spheres` (built in), `furnace` (white furnace, analytic reference), `sky-plane`
    /// (diffuse plane under a uniform sky, analytic), a stability scene (`tiny-bright-light`,
    /// `large-light-close`, `sky-through-opening`, ...), or a .gltf/.glb/.obj/.fbx file. Default: cornell.
    pub scenes: Vec<String>,
    /// Equirectangular sky (.hdr or .exr) for every scene.
    #[arg(long)]
    pub sky: Option<PathBuf>,
    /// Sky radiance multiplier.
    #[arg(long, default_value_t = 1.0)]
    pub sky_intensity: f32,
    /// Image width and height.
    #[arg(long, default_value_t = 64)]
    pub size: u32,
    /// Largest sample count per pixel; checkpoints at 1, 2, 4, ... up to it.
    #[arg(long, default_value_t = 64)]
    pub spp: u32,
    /// Samples per pixel of reference renders (where no analytic one exists).
    #[arg(long, default_value_t = 4096)]
    pub reference_spp: u32,
    /// Maximum path length in segments.
    #[arg(long, default_value_t = 8)]
    pub max_depth: u32,
    /// Backends to chart (a backend that cannot start is skipped with a warning naming what is
    /// missing).
    #[arg(long, value_enum, value_delimiter = ',', default_values_t = [ChartBackend::Cpu, ChartBackend::Gl, ChartBackend::Web])]
    pub backends: Vec<ChartBackend>,
    /// Strategies to chart.
    #[arg(long, value_enum, value_delimiter = ',', default_values_t = [ChartStrategy::Bsdf, ChartStrategy::Nee, ChartStrategy::Mis])]
    pub strategies: Vec<ChartStrategy>,
    /// Where the CSV, SVG and equal-time PNG of each scene go.
    #[arg(long, default_value = "target/lightport-chart")]
    pub out_dir: PathBuf,
    /// Cache of reference renders.
    #[arg(long, default_value = "target/lightport-reference")]
    pub reference_dir: PathBuf,
    /// Seed of the charted renders.
    #[arg(long, default_value_t = 1)]
    pub seed: u32,
    /// Longest the web backend may take for one scene (browser start, page load and every
    /// line), in seconds; past it the browser is closed and the web backend skipped.
    #[arg(long, default_value_t = 1800.0)]
    pub web_timeout: f64,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum ChartBackend {
    Cpu,
    /// OpenGL ES 3.0 through headless EGL (Mesa llvmpipe without a GPU).
    Gl,
    /// WebGL2 in headless Chromium: the web client (`web/`) served by `lightport serve`.
    Web,
}

impl ChartBackend {
    fn name(self) -> &'static str {
        match self {
            ChartBackend::Cpu => "cpu",
            ChartBackend::Gl => "gl",
            ChartBackend::Web => "web",
        }
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum ChartStrategy {
    Bsdf,
    Nee,
    Mis,
}

impl From<ChartStrategy> for Strategy {
    fn from(s: ChartStrategy) -> Strategy {
        match s {
            ChartStrategy::Bsdf => Strategy::Bsdf,
            ChartStrategy::Nee => Strategy::Nee,
            ChartStrategy::Mis => Strategy::Mis,
        }
    }
}

/// A scene to chart, with how its reference is obtained.
struct ChartScene {
    /// File-name-safe name.
    slug: String,
    /// What identifies the scene's content in the reference cache key.
    identity: String,
    scene: Scene,
    /// Exact pixel value everywhere, for scenes that have one at the given depth.
    analytic: Option<Vec3>,
}

/// One measurement: a line (backend x strategy) at one sample count.
#[derive(Clone, Debug)]
struct Point {
    backend: ChartBackend,
    strategy: Strategy,
    spp: u32,
    seconds: f64,
    rmse: f64,
    rel_mse: f64,
    rejected: u64,
    image: Image,
}

/// Runs `lightport chart`.
pub fn chart(args: &ChartArgs) -> Result<()> {
    ensure!((1..=4096).contains(&args.size), "--size must be 1..=4096");
    ensure!(args.spp >= 1 && args.reference_spp >= 1, "--spp and --reference-spp must be at least 1");
    ensure!(args.max_depth >= 1, "--max-depth must be at least 1");
    ensure!(!args.backends.is_empty() && !args.strategies.is_empty(), "nothing to chart");
    ensure!(
        args.web_timeout.is_finite() && args.web_timeout > 0.0 && args.web_timeout <= 86400.0,
        "--web-timeout must be between 0 and 86400 seconds"
    );
    let names = if args.scenes.is_empty() { vec!["cornell".to_string()] } else { args.scenes.clone() };
    std::fs::create_dir_all(&args.out_dir).with_context(|| format!("creating {}", args.out_dir.display()))?;
    let kernel_hash = kernel_hash()?;
    for name in &names {
        let scene = chart_scene(name, args).with_context(|| format!("scene {name}"))?;
        run_scene(&scene, args, kernel_hash).with_context(|| format!("charting {name}"))?;
    }
    Ok(())
}

fn chart_scene(name: &str, args: &ChartArgs) -> Result<ChartScene> {
    let depth = args.max_depth as i32;
    let mut chart_scene = match name {
        "cornell" => ChartScene::builtin(name, scene::cornell_box(), None),
        "metal-rough-spheres" => ChartScene::builtin(name, scene::metal_rough_spheres(), None),
        "furnace" => {
            // Albedo a, emission E everywhere: a path of at most D segments collects
            // E (1 + a + ... + a^(D-1)) whatever the strategy.
            let (a, e) = (0.5f32, 1.0f32);
            let exact = e * (1.0 - a.powi(depth)) / (1.0 - a);
            ChartScene::builtin(name, scene::white_furnace(Vec3::splat(a), Vec3::splat(e)), Some(Vec3::splat(exact)))
        }
        "sky-plane" => {
            let (albedo, sky) = (0.6f32, Vec3::new(1.0, 0.5, 0.25));
            let mut s = scene::diffuse_plane(Vec3::splat(albedo));
            s.sky = Some(Sky::uniform(sky));
            // One bounce sees only the sky; it needs two segments.
            let exact = (args.max_depth >= 2).then_some(albedo * sky);
            ChartScene::builtin(name, s, exact)
        }
        _ => match scene::stability::stability_cases().into_iter().find(|c| c.name == name) {
            Some(case) => ChartScene::builtin(name, case.scene, None),
            None => {
                let path = Path::new(name);
                if !path.exists() {
                    bail!(
                        "{name} is neither a built-in scene (cornell, metal-rough-spheres, furnace, sky-plane, {}) nor an existing file",
                        scene::stability::stability_cases().iter().map(|c| c.name).collect::<Vec<_>>().join(", ")
                    );
                }
                let loaded = scene::load(path).with_context(|| format!("loading {}", path.display()))?;
                for w in &loaded.warnings {
                    eprintln!("warning: {w}");
                }
                let slug = path.file_stem().map_or("scene".into(), |s| slugify(&s.to_string_lossy()));
                let identity = format!("file {} ({:016x})", path.display(), hash_file(path)?);
                ChartScene { slug, identity, scene: loaded, analytic: None }
            }
        },
    };
    if let Some(sky_path) = &args.sky {
        let sky = scene::load_sky(sky_path, args.sky_intensity, 0.0)
            .with_context(|| format!("loading sky {}", sky_path.display()))?;
        chart_scene.scene.sky = Some(sky);
        chart_scene.analytic = None;
        let stem = sky_path.file_stem().map_or("sky".into(), |s| slugify(&s.to_string_lossy()));
        chart_scene.slug = format!("{}-{stem}", chart_scene.slug);
        write!(
            chart_scene.identity,
            "; sky {} ({:016x}) x {}",
            sky_path.display(),
            hash_file(sky_path)?,
            args.sky_intensity
        )?;
    }
    Ok(chart_scene)
}

impl ChartScene {
    fn builtin(name: &str, scene: Scene, analytic: Option<Vec3>) -> Self {
        // Built-in scenes are identified by name: the kernel hash covers their generators only
        // indirectly, so the cache version must be bumped when a generator changes.
        ChartScene { slug: slugify(name), identity: format!("built-in {name}"), scene, analytic }
    }
}

fn slugify(s: &str) -> String {
    s.chars().map(|c| if c.is_ascii_alphanumeric() || c == '-' { c.to_ascii_lowercase() } else { '-' }).collect()
}

fn hash_file(path: &Path) -> Result<u64> {
    let bytes = std::fs::read(path).with_context(|| format!("reading {}", path.display()))?;
    let mut h = std::collections::hash_map::DefaultHasher::new();
    bytes.hash(&mut h);
    Ok(h.finish())
}

/// Hash of the all-features kernel's generated GLSL: a change to the kernel changes it, which
/// invalidates cached references.
fn kernel_hash() -> Result<u64> {
    let generated = tracer::kernel::path_tracer_shader(&Features::all(), lightport_codegen::Target::GlslEs300)
        .context("generating the kernel")?;
    let mut h = std::collections::hash_map::DefaultHasher::new();
    generated.source.hash(&mut h);
    Ok(h.finish())
}

fn packed_scene(scene: &Scene, args: &ChartArgs, strategy: Strategy) -> Result<Packed> {
    let bvh = tracer::bvh::build(&scene.triangles).context("building the BVH")?;
    let settings = RenderSettings { width: args.size, height: args.size, strategy, max_depth: args.max_depth };
    pack(scene, &bvh, &settings).context("packing the scene")
}

/// The reference image and an estimate of its own mean squared error (0 when analytic).
fn reference(scene: &ChartScene, args: &ChartArgs, kernel_hash: u64) -> Result<(Vec<Vec3>, f64, &'static str)> {
    let pixels = (args.size * args.size) as usize;
    if let Some(exact) = scene.analytic {
        return Ok((vec![exact; pixels], 0.0, "analytic"));
    }
    let key = format!(
        "lightport reference v{CACHE_VERSION}\nscene: {identity}\nsize: {size}x{size}\nmax_depth: {depth}\nspp: {spp}\n\
         seed: {REFERENCE_SEED}\nstrategy: mis\nbackend: cpu\nkernel: {kernel_hash:016x}\n",
        identity = scene.identity,
        size = args.size,
        depth = args.max_depth,
        spp = args.reference_spp,
    );
    let mut h = std::collections::hash_map::DefaultHasher::new();
    key.hash(&mut h);
    let base = args.reference_dir.join(format!("{}-{:016x}", scene.slug, h.finish()));
    let (exr, txt) = (base.with_extension("exr"), base.with_extension("txt"));
    if let (Ok(stored), Ok(img)) = (std::fs::read_to_string(&txt), image::open(&exr)) {
        // The key's lines, then the noise estimate.
        if let Some(noise) = stored.strip_prefix(key.as_str()).and_then(|rest| rest.trim().strip_prefix("noise_mse: "))
        {
            let img = img.into_rgb32f();
            if img.width() == args.size && img.height() == args.size {
                let noise: f64 = noise.parse().context("reading the cached reference's noise")?;
                let pixels = img.pixels().map(|p| Vec3::new(p[0], p[1], p[2])).collect();
                return Ok((pixels, noise, "cached"));
            }
        }
    }
    let packed = packed_scene(&scene.scene, args, Strategy::Mis)?;
    let mut r = CpuRenderer::new(packed, REFERENCE_SEED);
    let bar = indicatif::ProgressBar::new(args.reference_spp as u64);
    bar.set_style(
        indicatif::ProgressStyle::with_template("{spinner} reference {msg} [{bar:30}] {pos}/{len} spp, eta {eta}")
            .expect("valid template")
            .progress_chars("=> "),
    );
    bar.set_message(scene.slug.clone());
    for _ in 0..args.reference_spp {
        r.render_frame();
        bar.inc(1);
    }
    bar.finish_and_clear();
    let image = r.image();
    ensure!(image.pixels.iter().all(|p| p.is_finite()), "the reference render is not finite");
    // The reference's own MSE: the per-pixel variance of its mean.
    let n = r.frames() as f64;
    let noise = r.variance().iter().map(|v| v.as_dvec3().element_sum()).sum::<f64>() / (3.0 * pixels as f64) / n;
    std::fs::create_dir_all(&args.reference_dir)
        .with_context(|| format!("creating {}", args.reference_dir.display()))?;
    tracer::output::write_image(&exr, &image, &tracer::output::Display::CLAMP)?;
    std::fs::write(&txt, format!("{key}noise_mse: {noise:e}\n"))
        .with_context(|| format!("writing {}", txt.display()))?;
    Ok((image.pixels, noise, "rendered"))
}

/// Powers of two up to `max`, and `max`.
fn checkpoints(max: u32) -> Vec<u32> {
    let mut c: Vec<u32> = std::iter::successors(Some(1u32), |s| s.checked_mul(2)).take_while(|s| *s <= max).collect();
    if c.last() != Some(&max) {
        c.push(max);
    }
    c
}

/// Either backend behind one interface, for the measurement loop.
/// Both boxed: the renderers differ in size by kilobytes (the GL one carries its pipeline state).
enum Renderer {
    Cpu(Box<CpuRenderer>),
    Gl(Box<GlRenderer>),
}

impl Renderer {
    fn new(backend: ChartBackend, packed: Packed, seed: u32) -> Result<Renderer> {
        Ok(match backend {
            ChartBackend::Cpu => Renderer::Cpu(Box::new(CpuRenderer::new(packed, seed))),
            ChartBackend::Gl => Renderer::Gl(Box::new(GlRenderer::headless(packed, seed)?)),
            ChartBackend::Web => bail!("the web backend renders in a browser (web::lines), not in this process"),
        })
    }

    fn render_frame(&mut self) -> Result<()> {
        match self {
            Renderer::Cpu(r) => r.render_frame(),
            Renderer::Gl(r) => r.render_frame()?,
        }
        Ok(())
    }

    /// Waits for queued work (GL), so that a clock read after it is honest.
    fn finish(&self) -> Result<()> {
        if let Renderer::Gl(r) = self {
            r.finish()?;
        }
        Ok(())
    }

    fn image(&self) -> Result<(Image, u64)> {
        Ok(match self {
            Renderer::Cpu(r) => (r.image(), r.rejected_samples()),
            Renderer::Gl(r) => (r.image()?, r.rejected_samples()?),
        })
    }
}

/// Renders one line (backend x strategy) through every checkpoint.
fn run_line(
    packed: &Packed,
    backend: ChartBackend,
    strategy: Strategy,
    args: &ChartArgs,
    reference: &[Vec3],
) -> Result<Vec<Point>> {
    if backend == ChartBackend::Gl {
        // The driver compiles (JITs) the shader at the first draw; a throwaway renderer pays
        // for it here, so the timed one does not.
        let mut warm = Renderer::new(backend, packed.clone(), args.seed ^ 0xFFFF)?;
        warm.render_frame()?;
        warm.finish()?;
    }
    let mut r = Renderer::new(backend, packed.clone(), args.seed)?;
    let mut points = Vec::new();
    let mut elapsed = Duration::ZERO;
    let mut frames = 0;
    for spp in checkpoints(args.spp) {
        let start = Instant::now();
        while frames < spp {
            r.render_frame()?;
            frames += 1;
        }
        r.finish()?;
        elapsed += start.elapsed();
        let (image, rejected) = r.image()?;
        points.push(Point {
            backend,
            strategy,
            spp,
            seconds: elapsed.as_secs_f64(),
            rmse: tracer::stats::rmse(&image.pixels, reference)?,
            rel_mse: tracer::stats::rel_mse(&image.pixels, reference)?,
            rejected,
            image,
        });
    }
    Ok(points)
}

fn run_scene(scene: &ChartScene, args: &ChartArgs, kernel_hash: u64) -> Result<()> {
    let (reference, noise_mse, source) = reference(scene, args, kernel_hash)?;
    println!(
        "{}: reference {source} ({}), its own RMSE ~ {:.2e}",
        scene.slug,
        if source == "analytic" { "exact".to_string() } else { format!("{} spp, CPU MIS", args.reference_spp) },
        noise_mse.sqrt()
    );
    let mut packed = packed_scene(&scene.scene, args, Strategy::Mis)?;
    let mut lines: Vec<Vec<Point>> = Vec::new();
    for &backend in &args.backends {
        if backend == ChartBackend::Web {
            let strategies: Vec<Strategy> = args.strategies.iter().map(|&s| s.into()).collect();
            match web::lines(&scene.slug, &packed, &strategies, args, &reference) {
                Ok(web_lines) => lines.extend(web_lines),
                Err(e) => eprintln!("warning: skipping the web backend: {e:#}"),
            }
            continue;
        }
        for &strategy in &args.strategies {
            let strategy = Strategy::from(strategy);
            packed.apply(&RenderSettings { width: args.size, height: args.size, strategy, max_depth: args.max_depth });
            match run_line(&packed, backend, strategy, args, &reference) {
                Ok(points) => lines.push(points),
                Err(e) if backend == ChartBackend::Gl => {
                    eprintln!("warning: skipping the GL backend: {e:#}");
                    break;
                }
                Err(e) => return Err(e),
            }
        }
    }
    let csv = args.out_dir.join(format!("{}.csv", scene.slug));
    std::fs::write(&csv, to_csv(&scene.slug, &lines, source)).with_context(|| format!("writing {}", csv.display()))?;
    let svg = args.out_dir.join(format!("{}.svg", scene.slug));
    let title =
        format!("{}: {}x{}, max depth {}, reference {source}", scene.slug, args.size, args.size, args.max_depth);
    draw_chart(&svg, &title, &lines).with_context(|| format!("drawing {}", svg.display()))?;
    let png = args.out_dir.join(format!("{}-equal-time.png", scene.slug));
    let labelled = args.out_dir.join(format!("{}-equal-time.svg", scene.slug));
    let reference_label =
        if source == "analytic" { "exact".to_string() } else { format!("{} spp · cpu mis", args.reference_spp) };
    let crops = equal_time_strip(&png, &labelled, args.size, &reference, &reference_label, &lines)?;
    print_summary(&lines);
    println!(
        "equal-time crops ({png}, labelled: {labelled}): reference, {crops}",
        png = png.display(),
        labelled = labelled.display()
    );
    println!("wrote {} and {}", csv.display(), svg.display());
    Ok(())
}

fn to_csv(slug: &str, lines: &[Vec<Point>], reference: &str) -> String {
    let mut out = String::from("scene,backend,strategy,spp,seconds,rmse,rel_mse,rejected_samples,reference\n");
    for p in lines.iter().flatten() {
        let _ = writeln!(
            out,
            "{slug},{},{},{},{:.6},{:.6e},{:.6e},{},{reference}",
            p.backend.name(),
            p.strategy.name(),
            p.spp,
            p.seconds,
            p.rmse,
            p.rel_mse,
            p.rejected
        );
    }
    out
}

/// Final checkpoint of each line: errors, fitted RMSE slope, and efficiency (1 / (MSE x time))
/// relative to CPU MIS.
fn print_summary(lines: &[Vec<Point>]) {
    let last = |l: &Vec<Point>| l.last().cloned();
    let baseline = lines
        .iter()
        .filter_map(last)
        .find(|p| p.backend == ChartBackend::Cpu && p.strategy == Strategy::Mis)
        .map(|p| p.rmse * p.rmse * p.seconds);
    println!("| backend | strategy | spp | seconds | RMSE | relMSE | RMSE slope vs time | efficiency vs cpu mis |");
    println!("|---|---|---|---|---|---|---|---|");
    for l in lines {
        let Some(p) = last(l) else { continue };
        let slope = tracer::stats::log_log_slope(&l.iter().map(|p| (p.seconds, p.rmse)).collect::<Vec<_>>());
        let efficiency = baseline.map_or("-".into(), |b| format!("{:.2}", b / (p.rmse * p.rmse * p.seconds)));
        println!(
            "| {} | {} | {} | {:.3} | {:.3e} | {:.3e} | {} | {efficiency} |",
            p.backend.name(),
            p.strategy.name(),
            p.spp,
            p.seconds,
            p.rmse,
            p.rel_mse,
            slope.map_or("-".into(), |s| format!("{s:.2}")),
        );
        if p.rejected > 0 {
            println!("  ({} non-finite samples were dropped)", p.rejected);
        }
    }
}

/// The equal-time comparison: the reference and, for each line, its checkpoint with the most
/// samples within the time every line reached (the smallest final time). Writes them side by
/// side as a PNG strip (scaled up 3x, unlabelled, in the returned order) and as a labelled SVG
/// grid (a row per backend, the reference first; each crop titled with its strategy, backend,
/// samples and time; the crops are embedded PNGs at their rendered size, drawn enlarged with
/// `image-rendering: pixelated`). Returns the order, sample counts and times, for the caption.
fn equal_time_strip(
    png: &Path,
    svg: &Path,
    size: u32,
    reference: &[Vec3],
    reference_label: &str,
    lines: &[Vec<Point>],
) -> Result<String> {
    let budget = lines.iter().filter_map(|l| l.last()).map(|p| p.seconds).fold(f64::INFINITY, f64::min);
    let picks: Vec<&Point> =
        lines.iter().filter_map(|l| l.iter().rev().find(|p| p.seconds <= budget).or(l.first())).collect();
    let scale = 3u32;
    let tile = size * scale;
    let count = picks.len() as u32 + 1;
    let mut pixels = vec![Vec3::ZERO; (tile * count * tile) as usize];
    let sources: Vec<&[Vec3]> =
        std::iter::once(reference).chain(picks.iter().map(|p| p.image.pixels.as_slice())).collect();
    for (i, src) in sources.iter().enumerate() {
        for y in 0..tile {
            for x in 0..tile {
                let s = src[((y / scale) * size + x / scale) as usize];
                pixels[(y * tile * count + i as u32 * tile + x) as usize] = s;
            }
        }
    }
    tracer::output::write_image(
        png,
        &Image { width: tile * count, height: tile, pixels },
        &tracer::output::Display::CLAMP,
    )?;
    let text = equal_time_svg(size, reference, reference_label, &picks, budget)?;
    std::fs::write(svg, text).with_context(|| format!("writing {}", svg.display()))?;
    Ok(picks
        .iter()
        .map(|p| format!("{} {} ({} spp, {:.3} s)", p.backend.name(), p.strategy.name(), p.spp, p.seconds))
        .collect::<Vec<_>>()
        .join(", "))
}

/// The labelled equal-time grid (see [`equal_time_strip`]).
fn equal_time_svg(
    size: u32,
    reference: &[Vec3],
    reference_label: &str,
    picks: &[&Point],
    budget: f64,
) -> Result<String> {
    // Rows: one per backend, in the order charted; the reference opens the first row.
    let mut rows: Vec<(ChartBackend, Vec<&Point>)> = Vec::new();
    for p in picks {
        match rows.iter_mut().find(|(b, _)| *b == p.backend) {
            Some((_, row)) => row.push(p),
            None => rows.push((p.backend, vec![p])),
        }
    }
    if rows.is_empty() {
        rows.push((ChartBackend::Cpu, Vec::new()));
    }
    let columns = 1 + rows.iter().map(|(_, r)| r.len()).max().unwrap_or(0);
    let (tile, gap, label, title) = (size.max(160), 10u32, 34u32, 30u32);
    let (width, height) =
        ((columns as u32 * (tile + gap) + gap).max(420), title + rows.len() as u32 * (label + tile + gap) + gap);
    let mut out = String::new();
    write!(
        out,
        "<svg xmlns=\"http://www.w3.org/2000/svg\" xmlns:xlink=\"http://www.w3.org/1999/xlink\" \
         width=\"{width}\" height=\"{height}\" viewBox=\"0 0 {width} {height}\" font-family=\"sans-serif\">\n\
         <rect width=\"100%\" height=\"100%\" fill=\"white\"/>\n\
         <text x=\"{gap}\" y=\"20\" font-size=\"15\">Equal time: ≤ {} per line (the shortest line's total)</text>\n",
        seconds(budget)
    )?;
    let cell = |out: &mut String, row: usize, column: usize, heading: &str, detail: &str, pixels: &[Vec3]| {
        let x = gap + column as u32 * (tile + gap);
        let y = title + row as u32 * (label + tile + gap);
        let png = png_bytes(&Image { width: size, height: size, pixels: pixels.to_vec() })?;
        write!(
            out,
            "<text x=\"{x}\" y=\"{}\" font-size=\"13\" font-weight=\"bold\">{heading}</text>\n\
             <text x=\"{x}\" y=\"{}\" font-size=\"12\" fill=\"#444\">{detail}</text>\n\
             <image x=\"{x}\" y=\"{}\" width=\"{tile}\" height=\"{tile}\" preserveAspectRatio=\"none\" \
             style=\"image-rendering:pixelated\" xlink:href=\"data:image/png;base64,{}\"/>\n",
            y + 14,
            y + 29,
            y + label,
            base64::engine::general_purpose::STANDARD.encode(&png)
        )?;
        anyhow::Ok(())
    };
    cell(&mut out, 0, 0, "reference", reference_label, reference)?;
    for (r, (_, row)) in rows.iter().enumerate() {
        for (c, p) in row.iter().enumerate() {
            let heading = format!("{} · {}", p.strategy.name(), p.backend.name());
            let detail = format!("{} spp · {}", p.spp, seconds(p.seconds));
            cell(&mut out, r, c + 1, &heading, &detail, &p.image.pixels)?;
        }
    }
    out.push_str("</svg>\n");
    Ok(out)
}

/// A duration for a label, to about 3 significant digits.
fn seconds(s: f64) -> String {
    if s >= 1.0 {
        format!("{s:.2} s")
    } else if s >= 0.01 {
        format!("{s:.3} s")
    } else {
        format!("{:.2} ms", s * 1e3)
    }
}

/// An image as PNG bytes, tone-mapped like the CLI's PNG output.
fn png_bytes(image: &Image) -> Result<Vec<u8>> {
    let mut png = Vec::new();
    let encoder = image::codecs::png::PngEncoder::new(&mut png);
    image::ImageEncoder::write_image(
        encoder,
        &tracer::output::to_srgb8(image),
        image.width,
        image.height,
        image::ExtendedColorType::Rgb8,
    )
    .context("encoding a PNG")?;
    Ok(png)
}

fn draw_chart(path: &Path, title: &str, lines: &[Vec<Point>]) -> Result<()> {
    use plotters::prelude::*;

    let root = SVGBackend::new(path, (1100, 500)).into_drawing_area();
    root.fill(&WHITE)?;
    let root = root.titled(title, ("sans-serif", 18))?;
    let (left, right) = root.split_horizontally(550);
    let all: Vec<&Point> = lines.iter().flatten().collect();
    let positive = |v: f64| v > 0.0 && v.is_finite();
    let range = |values: Vec<f64>| -> (f64, f64) {
        let lo = values.iter().copied().filter(|v| positive(*v)).fold(f64::INFINITY, f64::min);
        let hi = values.iter().copied().filter(|v| positive(*v)).fold(0.0, f64::max);
        if lo.is_finite() && hi > 0.0 {
            // Whole decades, so that every axis has at least two labelled powers of ten.
            (10f64.powf(lo.log10().floor()), 10f64.powf(hi.log10().ceil()).max(10.0 * lo))
        } else {
            (1e-6, 1.0)
        }
    };
    let (t0, t1) = range(all.iter().map(|p| p.seconds).collect());
    type Metric = fn(&Point) -> f64;
    let panels: [(&DrawingArea<SVGBackend, plotters::coord::Shift>, &str, Metric, f64); 2] =
        [(&left, "RMSE", |p| p.rmse, -0.5), (&right, "relMSE", |p| p.rel_mse, -1.0)];
    for (area, name, metric, slope) in panels {
        let (y0, y1) = range(all.iter().map(|p| metric(p)).collect());
        let mut chart = ChartBuilder::on(area)
            .margin(12)
            .x_label_area_size(40)
            .y_label_area_size(70)
            .caption(format!("{name} against render time"), ("sans-serif", 15))
            .build_cartesian_2d((t0..t1).log_scale(), (y0..y1).log_scale())?;
        chart
            .configure_mesh()
            .x_desc("render time (s, log)")
            .y_desc(format!("{name} (log)"))
            .y_labels(8)
            .y_label_formatter(&|v| format!("{v:.0e}"))
            .x_label_formatter(&|v| format!("{v:.0e}"))
            .light_line_style(WHITE.mix(0.0))
            .draw()?;
        for line in lines {
            let Some(first) = line.first() else { continue };
            let color = match first.strategy {
                Strategy::Bsdf => RGBColor(214, 39, 40),
                Strategy::Nee => RGBColor(31, 119, 180),
                Strategy::Mis => RGBColor(44, 160, 44),
            };
            let points: Vec<(f64, f64)> =
                line.iter().map(|p| (p.seconds, metric(p))).filter(|(t, e)| positive(*t) && positive(*e)).collect();
            let label = format!("{} {}", first.strategy.name(), first.backend.name());
            let style = ShapeStyle { color: color.to_rgba(), filled: true, stroke_width: 2 };
            match first.backend {
                ChartBackend::Cpu => {
                    chart.draw_series(LineSeries::new(points.clone(), style))?.label(label).legend(move |(x, y)| {
                        PathElement::new(vec![(x, y), (x + 18, y)], ShapeStyle { stroke_width: 2, ..style })
                    });
                    chart.draw_series(points.iter().map(|p| Circle::new(*p, 3, style)))?;
                }
                ChartBackend::Gl => {
                    chart.draw_series(DashedLineSeries::new(points.clone(), 6, 4, style))?.label(label).legend(
                        move |(x, y)| {
                            PathElement::new(vec![(x, y), (x + 18, y)], ShapeStyle { stroke_width: 1, ..style })
                        },
                    );
                    chart.draw_series(points.iter().map(|p| TriangleMarker::new(*p, 4, style)))?;
                }
                ChartBackend::Web => {
                    chart.draw_series(DashedLineSeries::new(points.clone(), 2, 3, style))?.label(label).legend(
                        move |(x, y)| {
                            PathElement::new(vec![(x, y), (x + 18, y)], ShapeStyle { stroke_width: 1, ..style })
                        },
                    );
                    chart.draw_series(points.iter().map(|p| Cross::new(*p, 4, style)))?;
                }
            }
        }
        // The guide: an unbiased estimator's RMSE falls as time^-1/2 (its MSE as time^-1),
        // drawn through the first CPU MIS point (or the first point at all).
        let anchor = lines
            .iter()
            .find(|l| l.first().is_some_and(|p| p.backend == ChartBackend::Cpu && p.strategy == Strategy::Mis))
            .or(lines.first())
            .and_then(|l| l.first())
            .map(|p| (p.seconds, metric(p)))
            .filter(|(t, e)| positive(*t) && positive(*e));
        if let Some((ta, ea)) = anchor {
            let guide: Vec<(f64, f64)> = [t0, t1].iter().map(|t| (*t, ea * (t / ta).powf(slope))).collect();
            let gray = ShapeStyle { color: RGBColor(120, 120, 120).to_rgba(), filled: false, stroke_width: 1 };
            chart
                .draw_series(DashedLineSeries::new(guide, 3, 5, gray))?
                .label(if slope == -0.5 { "slope −½ (unbiased)" } else { "slope −1 (unbiased)" })
                .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 18, y)], gray));
        }
        chart
            .configure_series_labels()
            .position(SeriesLabelPosition::UpperRight)
            .background_style(WHITE.mix(0.85))
            .border_style(RGBColor(160, 160, 160))
            .label_font(("sans-serif", 12))
            .draw()?;
    }
    root.present()?;
    Ok(())
}

/// The web backend: the chart's lines rendered by the web client in headless Chromium.
///
/// `lightport serve --port 0` (this executable) serves the page (`web/www/`) and its wasm build
/// (`web/pkg/`); `tests/web/run.mjs chart` (node + npm `playwright-core`) opens it with
/// `?bundle=...&size=...&seed=...&paused=1`, answering the bundle URL with this chart's own
/// bundle ([`tracer::bundle`] of the packed scene the other backends render), so the page
/// renders the same data with the same seed. For each strategy the page restarts the
/// accumulation and renders up to each checkpoint; it times, with `performance.now()`, the
/// frames it renders (accumulation pass and the display pass to the canvas) and the wait for
/// them to finish (a 1-pixel `readPixels`). Not timed: browser start, page load, bundle decode
/// and upload, shader compile, one warm-up frame (the driver JITs the kernel at its first draw,
/// as the GL backend's throwaway renderer pays for natively) and the float read-back after each
/// checkpoint. The driver writes the accumulations (rgb sums and finite-sample counts) as JSON.
mod web {
    use std::path::{Path, PathBuf};
    use std::process::{Command, Stdio};
    use std::time::{Duration, Instant};

    use anyhow::{bail, ensure, Context, Result};
    use glam::Vec3;
    use serde_json::Value;
    use tracer::backend::Image;

    use crate::serve_child::{start_serve, Killed};
    use tracer::pack::{Packed, Strategy};

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
            from_report(&value, strategies, args.size, &checkpoints(args.spp), reference)
        })();
        let _ = std::fs::remove_file(&bundle);
        let _ = std::fs::remove_file(&report);
        result
    }

    /// The lines of the driver's report, checked against what was asked for.
    pub(super) fn from_report(
        report: &Value,
        strategies: &[Strategy],
        size: u32,
        checkpoints: &[u32],
        reference: &[Vec3],
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
        ensure!(
            reported.len() == strategies.len(),
            "{} lines reported, {} asked for",
            reported.len(),
            strategies.len()
        );
        let pixels = (size * size) as usize;
        let mut lines = Vec::new();
        for (line, &strategy) in reported.iter().zip(strategies) {
            ensure!(line["strategy"] == strategy.name(), "line {} reported for {}", line["strategy"], strategy.name());
            let reported = line["points"].as_array().context("a line without points")?;
            ensure!(
                reported.len() == checkpoints.len(),
                "{}: {} checkpoints reported",
                strategy.name(),
                reported.len()
            );
            let mut points = Vec::new();
            for (p, &spp) in reported.iter().zip(checkpoints) {
                let what = || format!("{} at {spp} spp", strategy.name());
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
                ensure!(data.len() == pixels * 4, "{}: {} values for {pixels} RGBA pixels", what(), data.len());
                let values: Vec<f32> = data.iter().map(|v| v.as_f64().map_or(f32::NAN, |v| v as f32)).collect();
                let n = spp as f32;
                let image = Image {
                    width: size,
                    height: size,
                    pixels: values.chunks_exact(4).map(|t| Vec3::new(t[0], t[1], t[2]) / n).collect(),
                };
                let accepted: f64 = values.chunks_exact(4).map(|t| t[3] as f64).sum();
                points.push(Point {
                    backend: ChartBackend::Web,
                    strategy,
                    spp,
                    seconds: ms / 1e3,
                    rmse: tracer::stats::rmse(&image.pixels, reference)?,
                    rel_mse: tracer::stats::rel_mse(&image.pixels, reference)?,
                    rejected: (spp as u64 * pixels as u64).saturating_sub(accepted.round() as u64),
                    image,
                });
            }
            lines.push(points);
        }
        Ok(lines)
    }
}

#[cfg(test)]
mod tests {
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
            sky_intensity: 1.0,
            size: 8,
            spp: 16,
            reference_spp: 8,
            max_depth: 4,
            backends: vec![ChartBackend::Cpu],
            strategies: vec![ChartStrategy::Bsdf, ChartStrategy::Nee, ChartStrategy::Mis],
            out_dir: out.join("chart"),
            reference_dir: out.join("reference"),
            seed: 1,
            web_timeout: 60.0,
        }
    }

    #[test]
    fn the_furnace_chart_has_every_line_and_its_error_falls() {
        let dir = std::env::temp_dir().join(format!("lightport-chart-test-{}", std::process::id()));
        let a = args(&["furnace"], &dir);
        chart(&a).unwrap();
        let csv = std::fs::read_to_string(a.out_dir.join("furnace.csv")).unwrap();
        let rows: Vec<Vec<&str>> = csv.lines().skip(1).map(|l| l.split(',').collect()).collect();
        assert_eq!(rows.len(), 3 * 5, "3 strategies x checkpoints 1, 2, 4, 8, 16:\n{csv}");
        for strategy in ["bsdf", "nee", "mis"] {
            let line: Vec<&Vec<&str>> = rows.iter().filter(|r| r[2] == strategy).collect();
            let rmse = |r: &Vec<&str>| r[5].parse::<f64>().unwrap();
            assert!(line.iter().all(|r| r[8] == "analytic" && r[7] == "0" && rmse(r).is_finite()));
            // 16x the samples: the RMSE of an unbiased estimate against the exact value falls
            // 4x (to 0.25, ± ~0.03 over these 192 values). A bias (a wrong reference, a
            // sampler that stopped converging) keeps it higher.
            assert!(rmse(line[4]) < 0.35 * rmse(line[0]), "{strategy}: {csv}");
        }
        let svg = std::fs::read_to_string(a.out_dir.join("furnace.svg")).unwrap();
        assert!(svg.starts_with("<svg") && svg.contains("mis cpu") && svg.contains("slope"));
        assert!(a.out_dir.join("furnace-equal-time.png").exists());
        let crops = std::fs::read_to_string(a.out_dir.join("furnace-equal-time.svg")).unwrap();
        for label in ["reference", "exact", "bsdf · cpu", "nee · cpu", "mis · cpu", " spp · "] {
            assert!(crops.contains(label), "the equal-time SVG labels {label:?}");
        }
        assert_eq!(crops.matches("data:image/png;base64,").count(), 4, "the reference and 3 crops");
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

    #[test]
    fn web_reports_become_points_and_bad_ones_errors() {
        let reference = vec![Vec3::splat(0.5); 4];
        let lines = web::from_report(&report(0.5), &[Strategy::Mis], 2, &[1, 2], &reference).unwrap();
        let line = &lines[0];
        assert_eq!(line.iter().map(|p| (p.spp, p.seconds)).collect::<Vec<_>>(), [(1, 0.002), (2, 0.005)]);
        assert!(line.iter().all(|p| p.rmse == 0.0 && p.rejected == 0 && p.backend == ChartBackend::Web));
        let off = web::from_report(&report(0.75), &[Strategy::Mis], 2, &[1, 2], &reference).unwrap();
        assert!((off[0][1].rmse - 0.25).abs() < 1e-6, "the mean of the sums is compared: {}", off[0][1].rmse);

        let refused = |report: serde_json::Value, strategies: &[Strategy], size: u32, spp: &[u32]| {
            format!(
                "{:#}",
                web::from_report(&report, strategies, size, spp, &reference[..(size * size) as usize]).unwrap_err()
            )
        };
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
    }

    #[test]
    fn slugs_are_file_name_safe() {
        assert_eq!(slugify("Box Textured/x.y"), "box-textured-x-y");
    }
}
