//! "Model no more than a scene needs", in numbers: for each test scene, its `Features`, the
//! size of the kernel variant generated for them, the GL driver's compile + link time and
//! first-frame time, and the packed data's GPU memory (used and allocated), each against the
//! all-features build (`Features::all()`) measured in the same run.
//!
//! ```sh
//! cargo run --release --example feature_sizes [-- REPEATS]
//! ```
//!
//! Times are medians of REPEATS (default 5) runs, alternating between the scene's variant and
//! the all-features kernel over the same data, on a headless EGL context (Mesa llvmpipe on a
//! machine without a GPU), with Mesa's on-disk shader cache disabled so that every compile is a
//! real one. llvmpipe compiles GLSL to its IR at link time and JITs machine code at the first
//! draw, so the first-frame column (renderer creation, uploads and one 1x1 frame) includes
//! what compile + link leaves out.
//!
//! WebGL2: the same variants compiled and linked in headless Chromium (ANGLE on SwiftShader
//! here) by the web page's `compileProgram` hook, driven by `tests/web/run.mjs compile` (node +
//! npm `playwright-core`) with the GPU program caches off and every source made unique; the time
//! runs from the first compile call until `getProgramParameter(LINK_STATUS)` returns (which waits
//! for the link whether or not the browser compiles in parallel). ANGLE's Vulkan backend goes on
//! building the program's pipeline (SwiftShader's JIT) in the background after that; deleting the
//! program waits for it, so the second WebGL2 column runs until a round trip queued behind the
//! deletion returns: the whole cost of the program, which a page pays before its first frame.
//! Each variant is measured right after the all-features kernel, REPEATS times, medians. The page is served by `lightport serve` from the same target
//! directory (`cargo build --release` first) and needs `web/pkg` (scripts/build-web.sh) and `npm
//! ci` in tests/web; without them the column says why it is empty.

use lightport::serve_child;

use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::{Duration, Instant};

use anyhow::{Context, Result};
use lightport_codegen::Target;
use tracer::backend::gl::texture_shape;
use tracer::backend::gl::{compile_program, GlRenderer, HeadlessContext};
use tracer::backend::Renderer;
use tracer::kernel::scene_data::SHADING_TEXELS;
use tracer::kernel::{Features, RenderSettings, Strategy};
use tracer::pack::{pack, Packed};
use tracer::scene::{self, Scene, Sky};

/// Texture size limit used for the memory layout (llvmpipe's GL_MAX_TEXTURE_SIZE).
const MAX_TEXTURE_SIZE: u32 = 16384;

/// Generated sizes of one kernel variant, and its GL times (one entry per repeat).
struct Variant {
    glsl: lightport_codegen::Generated,
    glsl_lines: usize,
    wgsl_bytes: usize,
    compile_link: Vec<Duration>,
    first_frame: Vec<Duration>,
}

struct Memory {
    used: usize,
    allocated: usize,
    /// What the all-features kernel needs bound for the same scene.
    all_features_allocated: usize,
}

fn shared(path: &str) -> std::path::PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/scenes").join(path)
}

fn median(mut times: Vec<Duration>) -> Duration {
    times.sort();
    times[times.len() / 2]
}

fn packed(scene: &Scene) -> Result<Packed> {
    let bvh = tracer::bvh::build(&scene.triangles).context("BVH")?;
    // 1x1: the first-frame time is then the driver's cost, not the path tracing.
    let settings = RenderSettings { width: 1, height: 1, strategy: Strategy::Mis, max_depth: 8 };
    Ok(pack(scene, &bvh, &settings)?)
}

impl Variant {
    fn new(features: Features) -> Result<Variant> {
        let glsl = tracer::kernel::path_tracer_shader(&features, Target::GlslEs300)?;
        let wgsl = tracer::kernel::path_tracer_shader(&features, Target::Wgsl)?;
        let glsl_lines = glsl.source.lines().count();
        Ok(Variant { glsl, glsl_lines, wgsl_bytes: wgsl.source.len(), compile_link: vec![], first_frame: vec![] })
    }

    /// One more measurement of compile + link on `context`, and of a renderer's creation and
    /// first 1x1 frame over `packed` with this variant's features.
    fn measure(&mut self, context: &HeadlessContext, packed: &Packed, features: Features) -> Result<()> {
        // Renderers make their own contexts current: take this one back first.
        context.make_current()?;
        let gl = context.glow();
        let start = Instant::now();
        let program = compile_program(&gl, &self.glsl)?;
        self.compile_link.push(start.elapsed());
        // SAFETY: the program was created on this context, which is current.
        unsafe { glow::HasContext::delete_program(&gl, program) };

        let mut p = packed.clone();
        // The all-features variant runs over the scene's own data: arrays it does not use
        // are bound as one zero texel, as the renderer does for any declared array.
        p.features = features;
        let start = Instant::now();
        let mut r = GlRenderer::headless(p, 0)?;
        r.render_frame()?;
        r.finish()?;
        self.first_frame.push(start.elapsed());
        Ok(())
    }
}

fn memory(packed: &Packed) -> Result<Memory> {
    let arrays = packed.arrays(MAX_TEXTURE_SIZE)?;
    let used = arrays.iter().map(|a| a.texels * a.texel_bytes).sum();
    let allocated: usize = arrays.iter().map(|a| a.allocated() * a.texel_bytes).sum();
    // The all-features kernel reads per-vertex normals and UVs for every hit, so it needs the
    // shading array even for flat scenes; every other array it declares but the scene lacks is
    // one zero texel (11 arrays in all, `metal_rough` included).
    let mut all = allocated;
    if !packed.features.shading {
        let texels = packed.triangle_count * SHADING_TEXELS as usize;
        let (w, h) = texture_shape(texels, MAX_TEXTURE_SIZE).context("shading array too large")?;
        all += w as usize * h as usize * 16;
    }
    all += (11 - arrays.len() - usize::from(!packed.features.shading)) * 16;
    Ok(Memory { used, allocated, all_features_allocated: all })
}

fn feature_list(f: &Features) -> String {
    let names: Vec<&str> = f.flags().iter().filter(|flag| flag.on).map(|flag| flag.name).collect();
    if names.is_empty() {
        "none".into()
    } else {
        names.join("+")
    }
}

fn kib(bytes: usize) -> String {
    format!("{:.1}", bytes as f64 / 1024.0)
}

/// WebGL2 times of one program, one entry per repeat (ms).
struct WebTimes {
    /// Until `LINK_STATUS` returns.
    link: Vec<f64>,
    /// Until the GPU process has finished with the program (background pipeline build included).
    built: Vec<f64>,
}

/// WebGL2 times of each fragment shader in `fragments` (name, source), measured in that order
/// each repeat, in headless Chromium. Returns the renderer's description too.
fn webgl2_compile_times(fragments: &[(String, String)], repeats: u32) -> Result<(String, Vec<WebTimes>)> {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let lightport = match std::env::var_os("LIGHTPORT") {
        Some(path) => PathBuf::from(path),
        // target/<profile>/examples/feature_sizes -> target/<profile>/lightport
        None => std::env::current_exe()?
            .parent()
            .and_then(Path::parent)
            .context("locating the target directory")?
            .join("lightport"),
    };
    anyhow::ensure!(
        lightport.is_file(),
        "{} is missing: build it with `cargo build --release` (or set LIGHTPORT=path)",
        lightport.display()
    );
    anyhow::ensure!(
        root.join("web/pkg/lightport_web_bg.wasm").is_file(),
        "web/pkg is missing: run scripts/build-web.sh"
    );
    anyhow::ensure!(
        root.join("tests/web/node_modules/playwright-core").is_dir(),
        "tests/web/node_modules is missing: run `npm ci` in tests/web"
    );
    let (_server, url) = serve_child::start_serve(&lightport, &[], Duration::from_secs(120), true)?;

    let temp = std::env::temp_dir();
    let (shaders, report) = (
        temp.join(format!("lightport-feature-sizes-{}.json", std::process::id())),
        temp.join(format!("lightport-feature-sizes-{}-out.json", std::process::id())),
    );
    let fragments: Vec<serde_json::Value> =
        fragments.iter().map(|(name, source)| serde_json::json!({ "name": name, "source": source })).collect();
    let input = serde_json::json!({ "vertex": lightport_codegen::fullscreen_vertex_shader(), "fragments": fragments });
    std::fs::write(&shaders, serde_json::to_vec(&input)?)?;
    let status = serve_child::run_tied(
        Command::new("node")
            .current_dir(root.join("tests/web"))
            .args(["run.mjs", "compile", "--url", &url, "--repeats", &repeats.to_string(), "--deadline", "3000"])
            .arg("--shaders")
            .arg(&shaders)
            .arg("--out")
            .arg(&report)
            .arg("--exit-on-stdin-eof"),
    )
    .context("running node (apt-get install nodejs npm)");
    let _ = std::fs::remove_file(&shaders);
    let status = status?;
    anyhow::ensure!(status.success(), "tests/web/run.mjs compile failed ({status})");
    let text = std::fs::read_to_string(&report).context("the driver's report")?;
    let _ = std::fs::remove_file(&report);
    let value: serde_json::Value = serde_json::from_str(&text)?;
    if let Some(error) = value.get("error").filter(|e| !e.is_null()) {
        anyhow::bail!("the page reported: {error}");
    }
    let numbers = |v: &serde_json::Value| -> Option<Vec<f64>> {
        v.as_array().map(|a| a.iter().filter_map(serde_json::Value::as_f64).collect())
    };
    let times = value["times"]
        .as_array()
        .context("no times")?
        .iter()
        .map(|t| {
            let (link, settled) = (numbers(&t["ms"])?, numbers(&t["settledMs"])?);
            let built = link.iter().zip(&settled).map(|(a, b)| a + b).collect();
            Some(WebTimes { link, built })
        })
        .collect::<Option<Vec<_>>>()
        .context("malformed times")?;
    anyhow::ensure!(
        times.len() == input["fragments"].as_array().map_or(0, Vec::len)
            && times.iter().all(|t| t.link.len() == repeats as usize && t.built.len() == repeats as usize),
        "the driver measured {} programs, not every one {repeats} times",
        times.len()
    );
    let gl = &value["gl"];
    let renderer = format!(
        "{} ({}; KHR_parallel_shader_compile {})",
        gl["renderer"].as_str().unwrap_or("?"),
        gl["version"].as_str().unwrap_or("?"),
        if gl["parallelCompile"] == true { "present, not used" } else { "absent" }
    );
    Ok((renderer, times))
}

fn median_f64(mut values: Vec<f64>) -> f64 {
    values.sort_by(f64::total_cmp);
    values[values.len() / 2]
}

/// `scene` without its normal maps: the same scene without `Features::normal_map`.
fn without_normal_maps(mut scene: Scene) -> Scene {
    for m in &mut scene.materials {
        m.normal_texture = None;
    }
    scene
}

/// `scene` with every material opaque (glTF `alphaMode` OPAQUE): without `Features::alpha_mask`.
fn opaque(mut scene: Scene) -> Scene {
    for m in &mut scene.materials {
        m.alpha_cutoff = None;
    }
    scene
}

/// `scene` with every material made one the Lambert kernel renders (metallic 0, roughness 1, no
/// metal-roughness texture): the same geometry and lights without `Features::metal_rough`.
fn lambert(mut scene: Scene) -> Scene {
    for m in &mut scene.materials {
        (m.metallic, m.roughness, m.metallic_roughness_texture) = (0.0, 1.0, None);
    }
    scene
}

/// `scene` with every texture read through a `KHR_texture_transform` (`Features::texture_transform`).
fn transformed(mut scene: Scene) -> Scene {
    let t = tracer::scene::UvTransform { offset: glam::Vec2::new(0.25, 0.5), rotation: 0.3, ..Default::default() };
    for m in &mut scene.materials {
        m.texture_uvs = [t; 5];
    }
    scene
}

/// `scene` with every non-emissive material transmissive glass with an absorbing volume
/// (`Features::transmission`, `Features::volume`).
fn glass(mut scene: Scene) -> Scene {
    for m in scene.materials.iter_mut().filter(|m| !m.is_emissive()) {
        m.transmission = 1.0;
        m.thickness = 1.0;
        m.attenuation_color = glam::Vec3::new(0.9, 0.7, 0.5);
        m.attenuation_distance = 1.0;
    }
    scene
}

/// `scene` with every texture read on `TEXCOORD_1`, a copy of set 0 (`Features::texcoord1`).
fn on_texcoord1(mut scene: Scene) -> Scene {
    for t in &mut scene.triangles {
        t.uvs1 = t.uvs;
    }
    for m in &mut scene.materials {
        m.texture_uvs = [tracer::scene::UvTransform { texcoord: 1, ..Default::default() }; 5];
    }
    scene
}

fn main() -> Result<()> {
    // Every compile must be a real one, not a hit in Mesa's on-disk cache. Set before the first
    // EGL call, while the process has one thread.
    std::env::set_var("MESA_SHADER_CACHE_DISABLE", "true");
    let repeats: u32 = std::env::args().nth(1).map(|a| a.parse()).transpose().context("REPEATS")?.unwrap_or(5).max(1);

    let with_sky = |mut s: Scene, sky: Sky| {
        s.sky = Some(sky);
        s
    };
    let venice = scene::load_sky(&shared("hdri/venice_sunset_1k.hdr"), 1.0, 0.0).context("venice sky")?;
    let load = |p: &str| scene::load(&shared(p)).with_context(|| format!("loading {p}"));
    let scenes: Vec<(&str, Scene)> = vec![
        ("Cornell box (built-in)", scene::cornell_box()),
        (
            "sky-lit plane (uniform sky)",
            with_sky(scene::diffuse_plane(glam::Vec3::splat(0.6)), Sky::uniform(glam::Vec3::ONE)),
        ),
        ("BoxTextured (glTF, texture)", load("khronos/BoxTextured/glTF/BoxTextured.gltf")?),
        (
            "BoxTextured + venice_sunset sky",
            with_sky(load("khronos/BoxTextured/glTF/BoxTextured.gltf")?, venice.clone()),
        ),
        ("DamagedHelmet (emissive texture, normal map)", load("khronos/DamagedHelmet/glTF/DamagedHelmet.gltf")?),
        (
            "DamagedHelmet without its normal map",
            without_normal_maps(load("khronos/DamagedHelmet/glTF/DamagedHelmet.gltf")?),
        ),
        ("BoxTextured, texture transformed", transformed(load("khronos/BoxTextured/glTF/BoxTextured.gltf")?)),
        ("BoxTextured, texture on TEXCOORD_1", on_texcoord1(load("khronos/BoxTextured/glTF/BoxTextured.gltf")?)),
        ("LightsPunctualLamp (point lights)", load("khronos/LightsPunctualLamp/glTF/LightsPunctualLamp.gltf")?),
        ("LittlestTokyo", load("threejs/LittlestTokyo.glb")?),
        ("MetalRoughSpheres (built-in, metal-roughness)", scene::metal_rough_spheres()),
        ("MetalRoughSpheres, every material Lambert", lambert(scene::metal_rough_spheres())),
        ("alpha-masked screen (built-in, alpha mask)", scene::alpha_masked_screen()),
        ("alpha-masked screen, every material opaque", opaque(scene::alpha_masked_screen())),
        ("MetalRoughSpheres, every sphere absorbing glass", glass(scene::metal_rough_spheres())),
    ];

    let context = HeadlessContext::new()?;
    let renderer = GlRenderer::headless(packed(&scenes[0].1)?, 0)?.info().renderer.clone();
    println!(
        "GL: {renderer}; medians of {repeats}; Mesa shader cache off. Each scene's variant and the all-features \
         kernel are measured alternately over the scene's data; ratios are variant / all-features."
    );
    let mut all = Variant::new(Features::all())?;
    let mut rows = Vec::new();
    let mut sources = Vec::new();
    let mut memory_rows = Vec::new();
    for (name, scene) in &scenes {
        let p = packed(scene)?;
        let mut v = Variant::new(p.features)?;
        let (mut all_compile, mut all_frame) = (Vec::new(), Vec::new());
        for _ in 0..repeats {
            // Alternating, so that the shared machine's load falls on both alike.
            let before = all.compile_link.len();
            all.measure(&context, &p, Features::all())?;
            all_compile.extend_from_slice(&all.compile_link[before..]);
            all_frame.extend_from_slice(&all.first_frame[before..]);
            v.measure(&context, &p, p.features)?;
        }
        let ratio = |a: f64, b: f64| format!("{:.2}", a / b);
        let ms = |d: Duration| d.as_secs_f64() * 1e3;
        let (compile, frame) = (median(v.compile_link.clone()), median(v.first_frame.clone()));
        let (base_compile, base_frame) = (median(all_compile), median(all_frame));
        rows.push(format!(
            "| {name} | {} | {} | {} ({}) | {} ({}) | {} ({}) | {:.1} ({}) | {:.1} ({}) |",
            p.triangle_count,
            feature_list(&p.features),
            v.glsl.source.len(),
            ratio(v.glsl.source.len() as f64, all.glsl.source.len() as f64),
            v.glsl_lines,
            ratio(v.glsl_lines as f64, all.glsl_lines as f64),
            v.wgsl_bytes,
            ratio(v.wgsl_bytes as f64, all.wgsl_bytes as f64),
            ms(compile),
            ratio(ms(compile), ms(base_compile)),
            ms(frame),
            ratio(ms(frame), ms(base_frame)),
        ));
        sources.push(v.glsl.source.clone());
        memory_rows.push((name, memory(&p)?));
    }

    // WebGL2: each variant right after the all-features kernel, REPEATS times.
    let fragments: Vec<(String, String)> = sources
        .iter()
        .enumerate()
        .flat_map(|(i, source)| {
            [(format!("all-features ({i})"), all.glsl.source.clone()), (format!("variant {i}"), source.clone())]
        })
        .collect();
    eprintln!("WebGL2: compiling {} programs x {repeats} in headless Chromium...", fragments.len());
    let (web_baseline, web_columns) = match webgl2_compile_times(&fragments, repeats) {
        Ok((renderer, times)) => {
            println!("WebGL2: {renderer}; GPU program caches off; medians of {repeats}.");
            let baseline = |pick: fn(&WebTimes) -> &Vec<f64>| {
                median_f64(times.iter().step_by(2).flat_map(|t| pick(t).clone()).collect())
            };
            let baseline =
                format!("{:.1} | {:.1}", baseline(|t: &WebTimes| &t.link), baseline(|t: &WebTimes| &t.built));
            let columns: Vec<String> = times
                .chunks_exact(2)
                .map(|pair| {
                    let cell = |pick: fn(&WebTimes) -> &Vec<f64>| {
                        let (base, variant) = (median_f64(pick(&pair[0]).clone()), median_f64(pick(&pair[1]).clone()));
                        format!("{variant:.1} ({:.2})", variant / base)
                    };
                    format!("{} | {}", cell(|t: &WebTimes| &t.link), cell(|t: &WebTimes| &t.built))
                })
                .collect();
            (baseline, columns)
        }
        Err(e) => {
            eprintln!("warning: WebGL2 compile times not measured: {e:#}");
            ("not measured | not measured".to_string(), vec!["not measured | not measured".to_string(); rows.len()])
        }
    };
    println!();
    println!(
        "| scene | triangles | features | GLSL bytes | GLSL lines | WGSL bytes | GL compile+link ms | \
         GL first frame ms | WebGL2 compile+link ms | WebGL2 until the pipeline is built ms |"
    );
    println!("|---|---|---|---|---|---|---|---|---|---|");
    println!(
        "| all features (baseline) | - | {} | {} | {} | {} | {:.1} | {:.1} | {web_baseline} |",
        feature_list(&Features::all()),
        all.glsl.source.len(),
        all.glsl_lines,
        all.wgsl_bytes,
        median(all.compile_link.clone()).as_secs_f64() * 1e3,
        median(all.first_frame.clone()).as_secs_f64() * 1e3,
    );
    for (row, web) in rows.iter().zip(&web_columns) {
        println!("{row} {web} |");
    }
    println!();
    println!("Packed scene data on the GPU (RGBA32F/RGBA32UI textures, power-of-two widths up to {MAX_TEXTURE_SIZE}):");
    println!();
    println!("| scene | used KiB | allocated KiB | used / allocated | all-features kernel allocated KiB | variant / all-features |");
    println!("|---|---|---|---|---|---|");
    for (name, m) in memory_rows {
        println!(
            "| {name} | {} | {} | {:.3} | {} | {:.3} |",
            kib(m.used),
            kib(m.allocated),
            m.used as f64 / m.allocated as f64,
            kib(m.all_features_allocated),
            m.allocated as f64 / m.all_features_allocated as f64
        );
    }
    Ok(())
}
