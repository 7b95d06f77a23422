//! `lightport chart`: speed against accuracy. Each scene is rendered with each strategy (BSDF,
//! NEE, MIS) on each backend (CPU, GL, wgpu, web) at 1, 2, 4, ... samples per pixel; each checkpoint's
//! render time and error against a converged reference (RMSE and relMSE) go to a CSV and an SVG
//! chart (error against time, log-log, with the −½ slope an unbiased estimator's RMSE follows).
//!
//! The CPU and wgpu runtimes chart each strategy under both schedules (`--schedules`): a
//! megakernel line and a wavefront line (`docs/wavefront.md`), labelled e.g. "mis wgpu,
//! wavefront"; GL and the web backend have the megakernel only (no compute). On the CPU the two
//! schedules add the same samples, so their lines differ in time only.
//!
//! The reference is analytic where the scene has one (`furnace`, `sky-plane`); otherwise a long
//! CPU MIS render with its own seed, cached as EXR under `--reference-dir` by a hash of
//! everything it depends on (scene file bytes, sky file bytes and settings, image size, depth,
//! samples, seed and the generated kernel source), with the key beside it in a `.txt` file
//! that must match for the cache to be used.
//!
//! Times count rendering only (GL: up to `glFinish`; wgpu: until the queue is idle), not
//! renderer creation, the driver's shader compile (a throwaway renderer draws one frame first),
//! image read-back or the error computation.
//!
//! With `--denoise` each line (either schedule) has a denoised twin (`render --denoise`'s filter, its passes on
//! the line's runtime; the web backend's denoised in the page by the page's own denoiser): at
//! each checkpoint the same image, denoised; its time is the line's (rendered again with the
//! denoiser's guide) plus that checkpoint's denoise: the read-backs of the accumulation and the
//! guide, the filter passes and the remodulation.
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
use glam::Vec3;
use tracer::backend::cpu::CpuRenderer;
use tracer::backend::{Image, Renderer, RendererKind, Schedule};
use tracer::kernel::{Features, RenderSettings, Strategy};
use tracer::pack::{pack, Packed};
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
    /// `large-light-close`, `sky-through-opening`, ...), a .gltf/.glb/.obj/.fbx file, or a bundle
    /// `lightport export` wrote (.lpb: its packed scene, posed at --time). Default: cornell.
    pub scenes: Vec<String>,
    /// Equirectangular sky (.hdr or .exr) for every scene, or `none`. Without it a scene that
    /// nothing lights (no emitter bright enough, no point light) gets a uniform white sky, with a
    /// warning.
    #[arg(long, value_name = "FILE|none")]
    pub sky: Option<crate::sky::SkyArg>,
    #[command(flatten)]
    pub pose: crate::pose::PoseArgs,
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
    #[arg(long, value_enum, value_delimiter = ',', default_values_t = [ChartBackend::Cpu, ChartBackend::Gl, ChartBackend::Wgpu, ChartBackend::Web])]
    pub backends: Vec<ChartBackend>,
    /// Strategies to chart.
    #[arg(long, value_enum, value_delimiter = ',', default_values_t = [ChartStrategy::Bsdf, ChartStrategy::Nee, ChartStrategy::Mis])]
    pub strategies: Vec<ChartStrategy>,
    /// Schedules to chart on the runtimes that have both (CPU and wgpu: a line per strategy and
    /// schedule); GL and the web backend render the megakernel only.
    #[arg(long, value_enum, value_delimiter = ',', default_values_t = [ChartSchedule::Megakernel, ChartSchedule::Wavefront])]
    pub schedules: Vec<ChartSchedule>,
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
    /// Also chart each line denoised (`render --denoise`'s filter on the line's runtime; the
    /// web backend's by the page's denoiser), timed with everything the filter costs.
    #[arg(long)]
    pub denoise: bool,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum ChartBackend {
    Cpu,
    /// OpenGL ES 3.0 through headless EGL (Mesa llvmpipe without a GPU).
    Gl,
    /// The WGSL kernel as a compute shader through wgpu (Vulkan; Mesa lavapipe without a GPU).
    Wgpu,
    /// WebGL2 in headless Chromium: the web client (`web/`) served by `lightport serve`.
    Web,
}

impl ChartBackend {
    fn name(self) -> &'static str {
        match self {
            ChartBackend::Cpu => "cpu",
            ChartBackend::Gl => "gl",
            ChartBackend::Wgpu => "wgpu",
            ChartBackend::Web => "web",
        }
    }

    /// Whether the backend runs the wavefront schedule (compute shaders and atomics, or the CPU).
    fn has_wavefront(self) -> bool {
        matches!(self, ChartBackend::Cpu | ChartBackend::Wgpu)
    }

    /// The schedules of `wanted` this backend charts, in order.
    fn schedules(self, wanted: &[ChartSchedule]) -> Vec<Schedule> {
        let mut out: Vec<Schedule> = Vec::new();
        for s in wanted.iter().map(|&s| Schedule::from(s)) {
            if (s == Schedule::Megakernel || self.has_wavefront()) && !out.contains(&s) {
                out.push(s);
            }
        }
        out
    }
}

/// A schedule to chart (`tracer::backend::Schedule`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum ChartSchedule {
    /// One invocation follows each path to its end: every backend.
    Megakernel,
    /// Stages over a pool of paths with queues (`docs/wavefront.md`): CPU and wgpu.
    Wavefront,
}

impl From<ChartSchedule> for Schedule {
    fn from(s: ChartSchedule) -> Schedule {
        match s {
            ChartSchedule::Megakernel => Schedule::Megakernel,
            ChartSchedule::Wavefront => Schedule::Wavefront,
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
    scene: Source,
    /// Exact pixel value everywhere, for scenes that have one at the given depth.
    analytic: Option<Vec3>,
}

/// What a chart renders: a scene, packed for each strategy; or a bundle's packed scene (posed at
/// `--time`: `crate::bundle_scene`), whose uniforms are set for each.
enum Source {
    Scene(Box<Scene>),
    Packed(Box<Packed>),
}

/// One measurement: a line (backend x schedule x strategy) at one sample count.
#[derive(Clone, Debug)]
struct Point {
    backend: ChartBackend,
    /// The megakernel on GL and the web backend.
    schedule: Schedule,
    strategy: Strategy,
    /// A point of a denoised line (`--denoise`).
    denoised: bool,
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
    ensure!(!args.backends.is_empty() && !args.strategies.is_empty() && !args.schedules.is_empty(), "nothing to chart");
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
                if crate::bundle_scene::is_bundle(path) {
                    return bundle_chart_scene(path, args);
                }
                let loaded = scene::load_with(path, &args.pose.load_options(false)?)
                    .with_context(|| format!("loading {}", path.display()))?;
                for w in &loaded.warnings {
                    eprintln!("warning: {w}");
                }
                let slug = path.file_stem().map_or("scene".into(), |s| slugify(&s.to_string_lossy()));
                let identity = format!("file {} ({:016x})", path.display(), hash_file(path)?);
                ChartScene { slug, identity, scene: Source::Scene(Box::new(loaded)), analytic: None }
            }
        },
    };
    // The pose is part of what a reference was rendered from.
    if let Source::Scene(scene) = &mut chart_scene.scene {
        args.pose.apply_to_generated(scene)?;
    }
    let pose = args.pose.describe();
    if !pose.is_empty() {
        write!(chart_scene.identity, ", posed: {pose}")?;
    }
    if let Some(sky_path) = crate::sky::SkyArg::file(args.sky.as_ref()) {
        let sky = scene::load_sky(sky_path, args.sky_intensity, 0.0)
            .with_context(|| format!("loading sky {}", sky_path.display()))?;
        match &mut chart_scene.scene {
            Source::Scene(scene) => scene.sky = Some(sky),
            // `bundle_chart_scene` refused the sky.
            Source::Packed(_) => bail!("--sky cannot be added to a bundle (its sky is packed in it)"),
        }
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
    if let Source::Scene(scene) = &mut chart_scene.scene {
        if let Some(warning) = crate::sky::light_unless_told(scene, args.sky.as_ref()) {
            eprintln!("warning: {warning}");
            write!(chart_scene.identity, "; the default white sky")?;
        }
    }
    Ok(chart_scene)
}

/// A bundle to chart (`lightport export` wrote it): its packed scene posed at `--time`; `--sky`
/// and `--sky-intensity` are refused (its sky is packed in it), as `render` refuses them.
fn bundle_chart_scene(path: &Path, args: &ChartArgs) -> Result<ChartScene> {
    crate::bundle_scene::refuse_sky(crate::sky::SkyArg::file(args.sky.as_ref()).is_some(), args.sky_intensity, 0.0)?;
    let bundle = crate::bundle_scene::load(path, &args.pose, false)?;
    // "-bundle": charted beside its scene file in one run, the two write their own files.
    let name = if bundle.name.is_empty() {
        path.file_stem().map_or("scene".into(), |s| s.to_string_lossy().into_owned())
    } else {
        bundle.name.clone()
    };
    let slug = format!("{}-bundle", slugify(&name));
    let mut identity = format!("bundle {} ({:016x})", path.display(), hash_file(path)?);
    let pose = args.pose.describe();
    if !pose.is_empty() {
        write!(identity, ", posed: {pose}")?;
    }
    Ok(ChartScene { slug, identity, scene: Source::Packed(Box::new(bundle.packed)), analytic: None })
}

impl ChartScene {
    fn builtin(name: &str, scene: Scene, analytic: Option<Vec3>) -> Self {
        // Built-in scenes are identified by name: the kernel hash covers their generators only
        // indirectly, so the cache version must be bumped when a generator changes.
        ChartScene {
            slug: slugify(name),
            identity: format!("built-in {name}"),
            scene: Source::Scene(Box::new(scene)),
            analytic,
        }
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

fn packed_scene(scene: &Source, args: &ChartArgs, strategy: Strategy) -> Result<Packed> {
    let settings = RenderSettings { width: args.size, height: args.size, strategy, max_depth: args.max_depth };
    let scene = match scene {
        Source::Scene(scene) => scene,
        Source::Packed(packed) => {
            let mut packed = packed.as_ref().clone();
            packed.apply(&settings);
            return Ok(packed);
        }
    };
    let bvh = tracer::pack::static_bvh(scene).context("building the BVH")?;
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
        r.render_frame()?;
        bar.inc(1);
    }
    bar.finish_and_clear();
    let image = r.image()?;
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

/// An in-process renderer of `backend` under `schedule` (the web backend renders in a
/// browser: [`web::lines`]).
fn renderer(backend: ChartBackend, schedule: Schedule, packed: Packed, seed: u32) -> Result<Box<dyn Renderer>> {
    let kind = match backend {
        ChartBackend::Cpu => RendererKind::Cpu,
        ChartBackend::Gl => RendererKind::Gl,
        ChartBackend::Wgpu => RendererKind::Wgpu,
        ChartBackend::Web => bail!("the web backend renders in a browser (web::lines), not in this process"),
    };
    Ok(tracer::backend::create_scheduled(kind, schedule, packed, seed)?)
}

impl Point {
    /// " denoised" for a denoised line's point, else nothing: what labels append.
    fn suffix(&self) -> &'static str {
        if self.denoised {
            " denoised"
        } else {
            ""
        }
    }

    /// The runtime of the point's line as labels name it: the backend, and on the backends
    /// with two schedules the schedule ("wgpu, wavefront", "cpu, megakernel", "gl").
    fn runtime(&self) -> String {
        if self.backend.has_wavefront() {
            format!("{}, {}", self.backend.name(), self.schedule.name())
        } else {
            self.backend.name().to_string()
        }
    }
}

/// Renders one line (backend x schedule x strategy) through every checkpoint; with
/// `--denoise`, its denoised twin too, from a renderer of its own that accumulates the
/// denoiser's guide (so the guide's cost is on the denoised line only), whichever the schedule.
fn run_line(packed: &Packed, line: Line, args: &ChartArgs, reference: &[Vec3]) -> Result<Vec<Vec<Point>>> {
    let mut lines = vec![run_checkpoints(packed, line, args, reference, false)?];
    if args.denoise {
        let mut guided = packed.clone();
        guided.set_denoise_guide(true);
        lines.push(run_checkpoints(&guided, line, args, reference, true)?);
    }
    Ok(lines)
}

/// What a line renders with.
#[derive(Clone, Copy, Debug)]
struct Line {
    backend: ChartBackend,
    schedule: Schedule,
    strategy: Strategy,
}

/// One line's points: rendered to every checkpoint and, if `denoised`, denoised there on the
/// renderer's runtime (`packed` must carry the denoiser's guide); each point's time is the
/// rendering's so far and, if denoised, that checkpoint's denoising (read-backs included), as
/// for a render to that many samples denoised once.
fn run_checkpoints(
    packed: &Packed,
    line: Line,
    args: &ChartArgs,
    reference: &[Vec3],
    denoised: bool,
) -> Result<Vec<Point>> {
    let Line { backend, schedule, .. } = line;
    if backend != ChartBackend::Cpu {
        // The driver compiles (JITs) the shader at the first draw; a throwaway renderer pays
        // for it here, so the timed one does not.
        let mut warm = renderer(backend, schedule, packed.clone(), args.seed ^ 0xFFFF)?;
        warm.render_frame()?;
        warm.finish()?;
    }
    let mut r = renderer(backend, schedule, packed.clone(), args.seed)?;
    let mut points = Vec::new();
    let mut elapsed = Duration::ZERO;
    let mut frames = 0;
    for spp in checkpoints(args.spp) {
        while frames < spp {
            let start = Instant::now();
            r.render_frame()?;
            r.finish()?;
            elapsed += start.elapsed();
            frames += 1;
        }
        // One read-back for the image and the dropped samples (not timed).
        let accumulation = r.accumulation()?;
        let (width, height) = (packed.scene.width, packed.scene.height);
        let mut image = tracer::backend::mean_image(width, height, r.frames(), &accumulation);
        let rejected = tracer::backend::rejected_samples(r.frames(), &accumulation);
        let mut seconds = elapsed.as_secs_f64();
        if denoised {
            let start = Instant::now();
            let guide = tracer::denoise::Guide::read(r.as_ref())?;
            image = tracer::denoise::denoise_on(r.as_mut(), &image, &guide)?.image;
            seconds += start.elapsed().as_secs_f64();
        }
        points.push(point(line, denoised, spp, seconds, rejected, image, reference)?);
    }
    // The line is what it says: a wavefront renderer counts its rays (a megakernel has no
    // counters), read once after the timed frames.
    let (runtime, counts) = (backend.name(), r.wavefront_counts());
    match (schedule, counts) {
        (Schedule::Wavefront, None) => {
            bail!("the {runtime} wavefront line was rendered by a megakernel (no ray counters)")
        }
        (Schedule::Wavefront, Some(c)) => ensure!(c.segments > 0, "the {runtime} wavefront traced no path segments"),
        (Schedule::Megakernel, Some(_)) => bail!("the {runtime} megakernel line was rendered by a wavefront"),
        (Schedule::Megakernel, None) => {}
    }
    Ok(points)
}

/// A checkpoint's point: `image`'s errors against `reference`.
fn point(
    line: Line,
    denoised: bool,
    spp: u32,
    seconds: f64,
    rejected: u64,
    image: Image,
    reference: &[Vec3],
) -> Result<Point> {
    Ok(Point {
        backend: line.backend,
        schedule: line.schedule,
        strategy: line.strategy,
        denoised,
        spp,
        seconds,
        rmse: tracer::stats::rmse(&image.pixels, reference)?,
        rel_mse: tracer::stats::rel_mse(&image.pixels, reference)?,
        rejected,
        image,
    })
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
        let schedules = backend.schedules(&args.schedules);
        if schedules.is_empty() {
            eprintln!("warning: skipping the {} backend: it has no wavefront schedule (no compute)", backend.name());
        }
        for schedule in schedules {
            for &strategy in &args.strategies {
                let strategy = Strategy::from(strategy);
                let settings =
                    RenderSettings { width: args.size, height: args.size, strategy, max_depth: args.max_depth };
                packed.apply(&settings);
                match run_line(&packed, Line { backend, schedule, strategy }, args, &reference) {
                    Ok(line_and_twin) => lines.extend(line_and_twin),
                    Err(e) if backend != ChartBackend::Cpu => {
                        eprintln!("warning: skipping the {} backend's {}: {e:#}", backend.name(), schedule.name());
                        break;
                    }
                    Err(e) => return Err(e),
                }
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
    let mut out =
        String::from("scene,backend,strategy,spp,seconds,rmse,rel_mse,rejected_samples,reference,denoised,schedule\n");
    for p in lines.iter().flatten() {
        let _ = writeln!(
            out,
            "{slug},{},{},{},{:.6},{:.6e},{:.6e},{},{reference},{},{}",
            p.backend.name(),
            p.strategy.name(),
            p.spp,
            p.seconds,
            p.rmse,
            p.rel_mse,
            p.rejected,
            p.denoised,
            p.schedule.name()
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
        .find(|p| {
            p.backend == ChartBackend::Cpu
                && p.schedule == Schedule::Megakernel
                && p.strategy == Strategy::Mis
                && !p.denoised
        })
        .map(|p| p.rmse * p.rmse * p.seconds);
    println!(
        "| backend | strategy | spp | seconds | RMSE | relMSE | RMSE slope vs time | efficiency vs cpu mis (megakernel) |"
    );
    println!("|---|---|---|---|---|---|---|---|");
    for l in lines {
        let Some(p) = last(l) else { continue };
        let slope = tracer::stats::log_log_slope(&l.iter().map(|p| (p.seconds, p.rmse)).collect::<Vec<_>>());
        let efficiency = baseline.map_or("-".into(), |b| format!("{:.2}", b / (p.rmse * p.rmse * p.seconds)));
        println!(
            "| {} | {}{} | {} | {:.3} | {:.3e} | {:.3e} | {} | {efficiency} |",
            p.runtime(),
            p.strategy.name(),
            p.suffix(),
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

mod plot;
mod web;

use plot::{draw_chart, equal_time_strip};

#[cfg(test)]
mod tests;
