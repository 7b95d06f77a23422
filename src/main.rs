//! The `lightport` command line.

mod animate;
mod bundle_scene;
mod chart;
mod export;
mod pose;
mod serve;
mod site;
mod sky;

use lightport::serve_child;

use std::path::{Path, PathBuf};
use std::process::ExitCode;

use anyhow::{bail, Context, Result};
use clap::{Parser, Subcommand};

#[derive(Parser)]
#[command(name = "lightport", version, about = "One path-tracing kernel for CPU, native GL, WebGL2 and WGSL")]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Path-trace a scene (glTF, GLB, OBJ or FBX, or an exported bundle `.lpb`; without SCENE, a
    /// built-in Cornell box) to an image.
    Render(RenderArgs),
    /// Speed against accuracy: render scenes with each strategy on each backend at increasing
    /// sample counts; write error-against-time charts (SVG), CSV and equal-time crops.
    Chart(chart::ChartArgs),
    /// Serve the web path tracer on 127.0.0.1: the page, its wasm, and a prebuilt bundle per
    /// scene (the built-in Cornell box plus SCENE...). See docs/serve.md.
    Serve(serve::ServeArgs),
    /// Write the site `serve` answers as files for any static host or CDN: the page, its wasm,
    /// scenes.json and a bundle per scene (the built-in Cornell box plus SCENE...). See
    /// docs/deploy.md.
    Export(export::ExportArgs),
    /// Regenerate the GLSL ES 3.00 and WGSL of every kernel module into shaders-generated/
    /// (each file validated first) and print them.
    Shaders {
        /// Do not write: exit non-zero and print a diff when the committed files are stale.
        #[arg(long)]
        check: bool,
        /// Output directory.
        #[arg(long, default_value = concat!(env!("CARGO_MANIFEST_DIR"), "/shaders-generated"))]
        dir: PathBuf,
        /// Do not print the generated code.
        #[arg(long, short)]
        quiet: bool,
    },
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Shaders { check, dir, quiet } => shaders(&dir, check, quiet),
        Command::Render(args) => render(&args),
        Command::Chart(args) => chart::chart(&args),
        Command::Serve(args) => serve::serve(&args),
        Command::Export(args) => export::export(&args),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e:#}");
            ExitCode::FAILURE
        }
    }
}

#[derive(clap::Args)]
struct RenderArgs {
    /// Scene file (.gltf, .glb, .obj, .fbx), a bundle `lightport export` wrote (.lpb, or any
    /// file that starts as one: rendered as packed, posed at --time when it moves), or a scene
    /// generated in code: `cornell` (the default), `metal-rough-spheres`, `glass-cornell`,
    /// `instanced-shapes` or `instanced-field` (10,000 placements, 102 M triangles; a file of
    /// that name takes precedence).
    scene: Option<PathBuf>,
    /// Equirectangular sky (.hdr or .exr), or `none`. Without it a scene that nothing lights
    /// (no emitter bright enough, no point light) gets a uniform white sky, with a warning.
    #[arg(long, value_name = "FILE|none")]
    sky: Option<sky::SkyArg>,
    /// Sky radiance multiplier.
    #[arg(long, default_value_t = 1.0)]
    sky_intensity: f32,
    /// Sky rotation about +Y, degrees.
    #[arg(long, default_value_t = 0.0)]
    sky_rotation: f32,
    /// Samples per pixel.
    #[arg(long, default_value_t = 64)]
    spp: u32,
    #[arg(long, default_value_t = 512)]
    width: u32,
    #[arg(long, default_value_t = 512)]
    height: u32,
    /// Sampling strategy: BSDF sampling only, next event estimation only, or both with MIS.
    #[arg(long, value_enum, default_value_t = StrategyArg::Mis)]
    strategy: StrategyArg,
    /// Maximum path length in segments.
    #[arg(long, default_value_t = 8)]
    max_depth: u32,
    /// Backend to render with.
    #[arg(long, value_enum, default_value_t = BackendArg::Cpu)]
    backend: BackendArg,
    /// How a frame's work is organised: one invocation per pixel following its path to the end
    /// (megakernel), or stages over a pool of paths with queues on the device (wavefront: cpu
    /// and wgpu; GL has no compute). `auto` picks the megakernel, the faster on every device
    /// measured so far (docs/wavefront.md).
    #[arg(long, value_enum, default_value_t = ScheduleArg::Auto)]
    schedule: ScheduleArg,
    /// Random seed (the same seed gives the same image).
    #[arg(long, default_value_t = 0)]
    seed: u32,
    /// Output image: .png (exposure, tone curve, sRGB) or .exr (linear float, untouched).
    #[arg(long, short, default_value = "out.png")]
    out: PathBuf,
    /// Tone curve for PNG output (EXR stays linear).
    #[arg(long, value_enum, default_value_t = ToneMapArg::Neutral)]
    tonemap: ToneMapArg,
    /// Exposure in stops for PNG output: radiance is scaled by 2^EV before the tone curve.
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true, value_name = "EV")]
    exposure: f32,
    /// Refuse the scene when loading it gives any warning (a texture that cannot be used, an
    /// unsupported feature, nothing lighting it) instead of rendering it anyway.
    #[arg(long)]
    strict: bool,
    #[command(flatten)]
    pose: pose::PoseArgs,
    /// Render the animation as this many frames, from --time to --until, each with --spp
    /// samples: one renderer takes each pose's geometry without recompiling. Writes each
    /// frame beside --out (out-000.png, ...) and the frames side by side as out-strip.png.
    #[arg(long, default_value_t = 1, value_name = "N")]
    frames: u32,
    /// With --frames: the time of the last frame, in seconds (default: the animation's end).
    #[arg(long, value_name = "SECONDS", allow_negative_numbers = true)]
    until: Option<f32>,
    /// Denoise the image written to --out: an edge-avoiding à-trous filter guided by the first
    /// hit's albedo, normal and depth, whose strength falls as the noise falls (`tracer::denoise`).
    #[arg(long)]
    denoise: bool,
    /// With --denoise, also write the noisy image here.
    #[arg(long, value_name = "PATH", requires = "denoise")]
    noisy: Option<PathBuf>,
    /// With --denoise, also write the filter's guide into this folder as linear EXR images:
    /// albedo.exr, normal.exr (xyz as rgb), depth.exr (distance along the ray; the sky 1e30)
    /// and emission.exr, e.g. for another denoiser.
    #[arg(long, value_name = "DIR", requires = "denoise")]
    aovs: Option<PathBuf>,
}

#[derive(Clone, Copy, clap::ValueEnum)]
enum StrategyArg {
    Bsdf,
    Nee,
    Mis,
}

#[derive(Clone, Copy, clap::ValueEnum)]
enum ToneMapArg {
    /// Clamp to [0, 1] (bright radiance clips to white).
    None,
    /// Khronos PBR Neutral: base colours kept, highlights rolled off to white.
    Neutral,
    /// ACES filmic (Stephen Hill's fit).
    Aces,
    /// AgX (default look).
    Agx,
}

impl From<ToneMapArg> for tracer::output::ToneMap {
    fn from(t: ToneMapArg) -> Self {
        match t {
            ToneMapArg::None => Self::None,
            ToneMapArg::Neutral => Self::Neutral,
            ToneMapArg::Aces => Self::Aces,
            ToneMapArg::Agx => Self::Agx,
        }
    }
}

#[derive(Clone, Copy, clap::ValueEnum)]
enum ScheduleArg {
    Megakernel,
    Wavefront,
    Auto,
}

impl ScheduleArg {
    fn schedule(self) -> tracer::backend::Schedule {
        match self {
            ScheduleArg::Megakernel => tracer::backend::Schedule::Megakernel,
            ScheduleArg::Wavefront => tracer::backend::Schedule::Wavefront,
            ScheduleArg::Auto => tracer::backend::Schedule::auto(),
        }
    }
}

#[derive(Clone, Copy, clap::ValueEnum)]
enum BackendArg {
    Cpu,
    /// OpenGL ES 3.0 through a headless EGL context (any GL driver; Mesa llvmpipe without a GPU).
    Gl,
    /// The WGSL kernel as a compute shader through wgpu (Vulkan/Metal/DX12; Mesa lavapipe
    /// without a GPU).
    Wgpu,
}

impl BackendArg {
    fn kind(self) -> tracer::backend::RendererKind {
        match self {
            BackendArg::Cpu => tracer::backend::RendererKind::Cpu,
            BackendArg::Gl => tracer::backend::RendererKind::Gl,
            BackendArg::Wgpu => tracer::backend::RendererKind::Wgpu,
        }
    }
}

fn render(args: &RenderArgs) -> Result<()> {
    use std::time::Instant;
    use tracer::kernel::denoise::ATROUS_ITERATIONS as ATROUS_PASSES;

    if args.spp == 0 {
        bail!("--spp must be at least 1");
    }
    if !args.exposure.is_finite() || args.exposure.abs() > 64.0 {
        bail!("--exposure must be a finite number of stops within ±64");
    }
    let settings = render_settings(args);
    let Some((mut packed, load_time, build_time, read_out)) = prepare(args, &settings)? else {
        return Ok(());
    };
    // --denoise: the path tracer sums the filter's guide beside the image, in the same pass.
    packed.set_denoise_guide(args.denoise);
    let features = packed.features;
    let lights = packed.light_count;

    let bar = indicatif::ProgressBar::new(args.spp as u64);
    bar.set_style(
        indicatif::ProgressStyle::with_template("{spinner} rendering [{bar:40}] {pos}/{len} spp, {per_sec}, eta {eta}")
            .expect("valid template")
            .progress_chars("=> "),
    );
    let t3 = Instant::now();
    let schedule = args.schedule.schedule();
    let mut r = tracer::backend::create_scheduled(args.backend.kind(), schedule, packed, args.seed)
        .with_context(|| format!("starting the {} backend ({})", args.backend.kind().name(), schedule.name()))?;
    for _ in 0..args.spp {
        r.render_frame()?;
        // Wait for each frame so that the progress bar tells the truth.
        r.finish()?;
        bar.inc(1);
    }
    // One read-back for both the image and the count of dropped samples.
    let accumulation = r.accumulation()?;
    let image = tracer::backend::mean_image(args.width, args.height, r.frames(), &accumulation);
    let rejected = tracer::backend::rejected_samples(r.frames(), &accumulation);
    let render_time = t3.elapsed();
    bar.finish_and_clear();
    let display = tracer::output::Display { tone_map: args.tonemap.into(), exposure: args.exposure };
    let denoised = args.denoise.then(|| denoise(r.as_mut(), &image)).transpose()?;
    if let (Some(noisy), Some(_)) = (&args.noisy, &denoised) {
        tracer::output::write_image(noisy, &image, &display)?;
    }
    if let (Some(dir), Some((_, times))) = (&args.aovs, &denoised) {
        write_aovs(dir, args.width, args.height, &times.aovs)?;
    }
    let written = denoised.as_ref().map_or(&image, |(d, _)| &d.image);
    tracer::output::write_image(&args.out, written, &display)?;

    let samples = args.spp as f64 * args.width as f64 * args.height as f64;
    println!("scene        {}", args.scene.as_ref().map_or("built-in Cornell box".into(), |p| p.display().to_string()));
    println!("triangles    {}", read_out.triangles);
    println!("lights       {lights} (features: {features:?})");
    println!("load         {:.1} ms{}", load_time.as_secs_f64() * 1e3, read_out.load);
    println!("BVH + pack   {:.1} ms ({})", build_time.as_secs_f64() * 1e3, read_out.levels);
    println!(
        "render       {:.2} s, {} spp at {}x{}, {:.2} M samples/s ({:?} backend, {}, {:?} strategy)",
        render_time.as_secs_f64(),
        args.spp,
        args.width,
        args.height,
        samples / render_time.as_secs_f64() / 1e6,
        r.describe().runtime,
        schedule.name(),
        settings.strategy.name()
    );
    if rejected > 0 {
        println!("warning      {rejected} non-finite samples were dropped");
    }
    if let Some((d, times)) = &denoised {
        println!(
            "denoise      {:.1} ms: guide read-back {:.1} ms, filter {:.1} ms ({} backend, {} à-trous passes)",
            (times.guide + times.filter).as_secs_f64() * 1e3,
            times.guide.as_secs_f64() * 1e3,
            times.filter.as_secs_f64() * 1e3,
            r.describe().runtime,
            ATROUS_PASSES
        );
        if d.replaced > 0 {
            println!("warning      {} non-finite pixels were replaced before denoising", d.replaced);
        }
        if let Some(noisy) = &args.noisy {
            println!("wrote        {} (noisy)", noisy.display());
        }
        if let Some(dir) = &args.aovs {
            println!("wrote        {}/{{albedo,normal,depth,emission}}.exr (the guide)", dir.display());
        }
    }
    println!("wrote        {}", args.out.display());
    Ok(())
}

/// The packed scene `render` renders, the time loading it took and the time building its BVH
/// and packing it took, and what to print about it; `None` when `--frames` rendered the
/// animation instead. Textures are packed while the BVH builds; a bundle is packed already.
fn prepare(
    args: &RenderArgs,
    settings: &tracer::kernel::RenderSettings,
) -> Result<Option<(tracer::pack::Packed, std::time::Duration, std::time::Duration, Prepared)>> {
    let t0 = std::time::Instant::now();
    if let Some(path) = args.scene.as_deref().filter(|p| bundle_scene::is_bundle(p)) {
        bundle_scene::refuse_sky(
            sky::SkyArg::file(args.sky.as_ref()).is_some(),
            args.sky_intensity,
            args.sky_rotation,
        )?;
        let bundle = bundle_scene::load(path, &args.pose, args.strict)?;
        if args.frames > 1 {
            animate::render_bundle_frames(args, bundle, settings)?;
            return Ok(None);
        }
        let load_time = t0.elapsed();
        let read_out = Prepared::of_bundle(&bundle);
        let mut packed = bundle.packed;
        packed.apply(settings);
        return Ok(Some((packed, load_time, std::time::Duration::ZERO, read_out)));
    }
    let scene = load_scene(args)?;
    let load_time = t0.elapsed();
    if args.frames > 1 {
        animate::render_frames(args, scene, settings)?;
        return Ok(None);
    }
    let t1 = std::time::Instant::now();
    let (bvh, packed) = tracer::pack::build_and_pack(&scene, settings).context("building the BVH and packing")?;
    let read_out = Prepared::of_scene(&scene, &bvh, &packed);
    Ok(Some((packed, load_time, t1.elapsed(), read_out)))
}

/// What `render` prints about the scene it packed: its triangles, how its BVH is laid out, and
/// what loading it was (a bundle: decoded and posed).
struct Prepared {
    triangles: String,
    levels: String,
    load: String,
}

impl Prepared {
    fn of_scene(scene: &tracer::scene::Scene, bvh: &tracer::bvh::Bvh, packed: &tracer::pack::Packed) -> Prepared {
        let levels = match scene.instances.len() {
            0 => format!("{} BVH nodes", bvh.nodes.len()),
            n => format!(
                "two levels: {n} placements of {} meshes, {} triangles stored, {} placed",
                scene.meshes.len(),
                packed.triangle_count,
                scene.placed_triangle_count()
            ),
        };
        Prepared { triangles: scene.triangles.len().to_string(), levels, load: String::new() }
    }

    fn of_bundle(bundle: &bundle_scene::BundleScene) -> Prepared {
        let p = &bundle.packed;
        let levels = match p.features.instances {
            false => format!("one level of {} wide BVH nodes, as the bundle carries it", p.scene.node_children.len()),
            true => format!("two levels: {} placements, as the bundle carries them", p.placement_count()),
        };
        let load = match bundle.describe_motion() {
            Some(motion) => format!(" (bundle \"{}\" decoded and posed: {motion})", bundle.name),
            None => format!(" (bundle \"{}\" decoded)", bundle.name),
        };
        Prepared { triangles: format!("{} stored", p.triangle_count), levels, load }
    }
}

/// The scene `render` renders: loaded (with its motion kept for --frames), or generated, with
/// its sky; its warnings printed (an error under --strict).
fn load_scene(args: &RenderArgs) -> Result<tracer::scene::Scene> {
    let mut options = args.pose.load_options(args.strict)?;
    options.keep_motion = args.frames > 1;
    let builtin = args.scene.as_ref().filter(|p| !p.exists()).and_then(|p| tracer::scene::builtin(p.to_str()?));
    let mut scene = match (&args.scene, builtin) {
        (_, Some(generated)) => generated,
        (Some(path), None) => {
            tracer::scene::load_with(path, &options).with_context(|| format!("loading {}", path.display()))?
        }
        (None, None) => tracer::scene::cornell_box(),
    };
    args.pose.apply_to_generated(&mut scene)?;
    if let Some(sky) = sky::SkyArg::file(args.sky.as_ref()) {
        let s = tracer::scene::load_sky(sky, args.sky_intensity, args.sky_rotation.to_radians())
            .with_context(|| format!("loading sky {}", sky.display()))?;
        scene.sky = Some(s);
    }
    sky::light_unless_told(&mut scene, args.sky.as_ref());
    report_warnings(&scene, "", args.strict)?;
    Ok(scene)
}

fn render_settings(args: &RenderArgs) -> tracer::kernel::RenderSettings {
    use tracer::kernel::Strategy;
    tracer::kernel::RenderSettings {
        width: args.width,
        height: args.height,
        strategy: match args.strategy {
            StrategyArg::Bsdf => Strategy::Bsdf,
            StrategyArg::Nee => Strategy::Nee,
            StrategyArg::Mis => Strategy::Mis,
        },
        max_depth: args.max_depth,
    }
}

/// Where `render --denoise` spent its time: reading the guide the path tracer accumulated back
/// and the filter passes (on the renderer's runtime, read-back included); and the guide's AOVs.
struct DenoiseTimes {
    guide: std::time::Duration,
    filter: std::time::Duration,
    aovs: Vec<tracer::denoise::Aov>,
}

/// `render --aovs`: the guide's four images as linear EXR files in `dir`.
fn write_aovs(dir: &Path, width: u32, height: u32, aovs: &[tracer::denoise::Aov]) -> Result<()> {
    std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    type Plane = fn(&tracer::denoise::Aov) -> glam::Vec3;
    let planes: [(&str, Plane); 4] = [
        ("albedo", |a| a.albedo),
        ("normal", |a| a.normal),
        ("depth", |a| glam::Vec3::splat(a.depth)),
        ("emission", |a| a.emission),
    ];
    for (name, plane) in planes {
        let image = tracer::output::Image { width, height, pixels: aovs.iter().map(plane).collect() };
        tracer::output::write_image(&dir.join(format!("{name}.exr")), &image, &tracer::output::Display::CLAMP)?;
    }
    Ok(())
}

/// `image` denoised (`tracer::denoise`) with the guide `renderer` accumulated, the filter
/// passes on `renderer`'s runtime, and how long that took.
fn denoise(
    renderer: &mut dyn tracer::backend::Renderer,
    image: &tracer::output::Image,
) -> Result<(tracer::denoise::Denoised, DenoiseTimes)> {
    let start = std::time::Instant::now();
    let guide = tracer::denoise::Guide::read(renderer)?;
    let guide_time = start.elapsed();
    let start = std::time::Instant::now();
    let denoised = tracer::denoise::denoise_on(renderer, image, &guide)?;
    Ok((denoised, DenoiseTimes { guide: guide_time, filter: start.elapsed(), aovs: guide.aovs }))
}

/// Prints a loaded scene's warnings (its loader's, and [`tracer::scene::Scene::unlit_warning`]
/// once its sky is set), each prefixed with `prefix`; with `strict`, any warning is an error.
/// Returns them (unprefixed).
pub(crate) fn report_warnings(scene: &tracer::scene::Scene, prefix: &str, strict: bool) -> Result<Vec<String>> {
    let warnings: Vec<String> = scene.warnings.iter().cloned().chain(scene.unlit_warning()).collect();
    if strict && !warnings.is_empty() {
        bail!("--strict: the scene has {} warning(s): {}", warnings.len(), warnings.join("; "));
    }
    for w in &warnings {
        eprintln!("warning: {prefix}{w}");
    }
    Ok(warnings)
}

fn shaders(dir: &Path, check: bool, quiet: bool) -> Result<()> {
    let files = tracer::kernel::generated_shaders()?;
    if check {
        let mut stale = Vec::new();
        for f in &files {
            let path = dir.join(&f.name);
            let committed = std::fs::read_to_string(&path).unwrap_or_default();
            if committed != f.source {
                let diff = similar::TextDiff::from_lines(&committed, &f.source);
                println!(
                    "{}",
                    diff.unified_diff().header(&format!("committed {}", f.name), &format!("generated {}", f.name))
                );
                stale.push(f.name.clone());
            }
        }
        let expected: Vec<&str> = files.iter().map(|f| f.name.as_str()).collect();
        for entry in std::fs::read_dir(dir).with_context(|| format!("reading {}", dir.display()))? {
            let name = entry?.file_name().to_string_lossy().to_string();
            if (name.ends_with(".glsl") || name.ends_with(".wgsl")) && !expected.contains(&name.as_str()) {
                println!("{name}: no kernel module generates it any more");
                stale.push(name);
            }
        }
        if !stale.is_empty() {
            bail!(
                "shaders-generated/ is stale ({}): run `cargo run -- shaders` and commit the result",
                stale.join(", ")
            );
        }
        println!("shaders-generated/ is up to date ({} files)", files.len());
        return Ok(());
    }
    std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    for entry in std::fs::read_dir(dir)? {
        let path = entry?.path();
        let ext = path.extension().and_then(|e| e.to_str());
        if matches!(ext, Some("glsl" | "wgsl")) && !files.iter().any(|f| path.ends_with(&f.name)) {
            std::fs::remove_file(&path).with_context(|| format!("removing stale {}", path.display()))?;
        }
    }
    for f in &files {
        let path = dir.join(&f.name);
        std::fs::write(&path, &f.source).with_context(|| format!("writing {}", path.display()))?;
        if !quiet {
            println!("// ===== shaders-generated/{} =====\n{}", f.name, f.source);
        }
    }
    eprintln!("wrote {} validated files to {}", files.len(), dir.display());
    Ok(())
}
