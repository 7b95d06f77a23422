//! `lightport render --frames N`: the scene's animation as N frames, rendered by one renderer
//! that takes each pose's geometry (`Renderer::take_geometry`) without recompiling its kernel;
//! each frame written beside --out, the frames side by side as a strip, and a table of where
//! each frame's time went.

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{bail, Context, Result};
use tracer::backend::{create, RenderError, Renderer};
use tracer::kernel::RenderSettings;
use tracer::output::{Display, Image};
use tracer::pack::{MovingScene, PackError};
use tracer::scene::Scene;

use crate::bundle_scene::BundleScene;
use crate::RenderArgs;

/// Renders `scene` (loaded with its motion kept) as `args.frames` poses from `--time` to
/// `--until`.
pub fn render_frames(args: &RenderArgs, scene: Scene, settings: &RenderSettings) -> Result<()> {
    let Some(motion) = &scene.motion else {
        bail!("--frames needs an animated scene: this one has no animation that moves anything");
    };
    let what = motion.describe();
    let started = Instant::now();
    let (moving, packed) = MovingScene::new(scene, settings).context("building the BVH and packing")?;
    let name = args.scene.as_ref().map_or(String::new(), |p| p.display().to_string());
    println!("scene        {name} ({what})");
    println!("first pack   {:.1} ms (the static level's BVH and the textures, built once)", ms(started));
    render_poses(args, moving, packed)
}

/// Renders a bundle's moving scene (posed at `--time`) as `args.frames` poses from `--time` to
/// `--until`, as [`render_frames`] renders a scene file's.
pub fn render_bundle_frames(args: &RenderArgs, bundle: BundleScene, settings: &RenderSettings) -> Result<()> {
    let what = bundle.describe_motion();
    let (Some(moving), Some(what)) = (bundle.moving, what) else {
        bail!("--frames needs an animated scene: this bundle has no motion section (its scene does not move)");
    };
    // `load` posed the bundle's arrays at --time and packed that pose already.
    let mut packed = MovingScene::for_kernel(bundle.packed);
    packed.apply(settings);
    let name = args.scene.as_ref().map_or(String::new(), |p| p.display().to_string());
    println!("scene        {name} (bundle \"{}\": {what})", bundle.name);
    render_poses(args, moving, packed)
}

/// Renders `moving` (posed at `--time`, `packed` that pose for the kernel) at `args.frames`
/// times from `--time` to `--until`.
fn render_poses(args: &RenderArgs, mut moving: MovingScene, mut packed: tracer::pack::Packed) -> Result<()> {
    let (from, until) = (args.pose.time, args.until.unwrap_or(moving.duration()));
    if !until.is_finite() {
        bail!("--until must be a finite number of seconds");
    }
    packed.set_denoise_guide(args.denoise);
    let kind = args.backend.kind();
    let mut renderer =
        create(kind, packed, args.seed).with_context(|| format!("starting the {} backend", kind.name()))?;
    let display = Display { tone_map: args.tonemap.into(), exposure: args.exposure };
    let mut frames = Vec::new();
    println!("frame  time (s)   pose (ms)   pack (ms)   upload (ms)   render (ms)   written");
    for k in 0..args.frames {
        let time = from + (until - from) * k as f32 / (args.frames - 1) as f32;
        // The first frame is the pose the scene was loaded and the renderer created with.
        let (pose_ms, pack_ms, upload_ms) = match k {
            0 => (0.0, 0.0, 0.0),
            _ => next_pose(&mut renderer, &mut moving, time, args)?,
        };
        let rendering = Instant::now();
        for _ in 0..args.spp {
            renderer.render_frame()?;
        }
        let mut image = renderer.image()?;
        if args.denoise {
            image = crate::denoise(renderer.as_mut(), &image)?.0.image;
        }
        let render_ms = ms(rendering);
        let path = numbered(&args.out, &format!("{k:03}"));
        tracer::output::write_image(&path, &image, &display)?;
        println!(
            "{k:>5}  {time:>8.3}   {pose_ms:>9.1}   {pack_ms:>9.1}   {upload_ms:>11.1}   {render_ms:>11.1}   {}",
            path.display()
        );
        frames.push(image);
    }
    let strip = numbered(&args.out, "strip");
    tracer::output::write_image(&strip, &side_by_side(&frames), &display)?;
    println!("wrote        {} ({} frames side by side)", strip.display(), frames.len());
    Ok(())
}

/// Poses the scene at `time`, packs it and hands it to the renderer: the milliseconds each took.
fn next_pose(
    renderer: &mut Box<dyn Renderer>,
    moving: &mut MovingScene,
    time: f32,
    args: &RenderArgs,
) -> Result<(f64, f64, f64)> {
    let posing = Instant::now();
    let known = moving.scene().warnings.len();
    moving.pose(time)?;
    report_pose_warnings(moving.scene(), known, args.strict)?;
    let pose_ms = ms(posing);
    let packing = Instant::now();
    let moved = moving.pack()?;
    let pack_ms = ms(packing);
    let uploading = Instant::now();
    take(renderer, moving, moved, args)?;
    renderer.finish()?;
    Ok((pose_ms, pack_ms, ms(uploading)))
}

/// Hands `moved` to the renderer; a pose that needs another kernel variant gets a new renderer.
fn take(
    renderer: &mut Box<dyn Renderer>,
    moving: &MovingScene,
    moved: tracer::pack::Packed,
    args: &RenderArgs,
) -> Result<()> {
    match renderer.take_geometry(moved) {
        Err(e @ RenderError::Pack(PackError::KernelChanged { .. })) => {
            let mut packed = moving.pack_for_kernel()?;
            // A bundle's first pose was packed for another image size, strategy and depth.
            packed.apply(&crate::render_settings(args));
            packed.set_denoise_guide(args.denoise);
            eprintln!("note: this pose needs another kernel variant: the renderer is created again ({e})");
            *renderer = create(args.backend.kind(), packed, args.seed)?;
            Ok(())
        }
        other => Ok(other?),
    }
}

/// `out` with `-{tag}` before its extension (out.png -> out-007.png).
fn numbered(out: &Path, tag: &str) -> PathBuf {
    let stem = out.file_stem().map_or("out".into(), |s| s.to_string_lossy().into_owned());
    let ext = out.extension().map_or("png".into(), |e| e.to_string_lossy().into_owned());
    out.with_file_name(format!("{stem}-{tag}.{ext}"))
}

/// The frames (all of one size) left to right in one image.
fn side_by_side(frames: &[Image]) -> Image {
    let (w, h) = frames.first().map_or((0, 0), |f| (f.width, f.height));
    let mut pixels = Vec::with_capacity((w * h) as usize * frames.len());
    for y in 0..h as usize {
        for f in frames {
            pixels.extend_from_slice(&f.pixels[y * w as usize..(y + 1) * w as usize]);
        }
    }
    Image { width: w * frames.len() as u32, height: h, pixels }
}

fn ms(since: Instant) -> f64 {
    since.elapsed().as_secs_f64() * 1e3
}

/// Prints the warnings a pose added to `scene`'s (those from `known` on: a placement the
/// animation drops there, `Scene::pose`); with `strict`, any is an error.
pub fn report_pose_warnings(scene: &Scene, known: usize, strict: bool) -> Result<()> {
    let new = scene.warnings.get(known..).unwrap_or_default();
    if strict && !new.is_empty() {
        bail!("--strict: posing the scene gave {} warning(s): {}", new.len(), new.join("; "));
    }
    for w in new {
        eprintln!("warning: {w}");
    }
    Ok(())
}
