//! What `lightport serve` answers and `lightport export` writes: one table from URL path to a
//! ready response body, built once (scenes loaded, BVH-built, packed, encoded, compressed; the
//! page's files read). The server looks requests up in it; the export writes each entry as a
//! file. Neither joins a request path to a file-system path.
//!
//! # `/scenes.json`
//! ```json
//! {
//!   "bundle_version": 1,                 // tracer::bundle::VERSION of every bundle listed
//!   "scenes": [                          // in command-line order; the built-in Cornell box first
//!     {
//!       "name": "cornell-box",           // unique: file stem, "-2", "-3"... appended on clashes
//!       "url": "bundles/<hash>.lpb",     // relative to scenes.json (served at /bundles/<hash>.lpb;
//!                                        // an exported site works under any path prefix)
//!       "hash": "<hash>",                // SHA-256 (hex) of the uncompressed bundle: a cache key
//!       "bytes": { "raw": 5120, "gzip": 1234 },   // uncompressed and gzip-compressed sizes
//!       "triangles": 36,
//!       "lights": 2,
//!       "warnings": [],                  // the loader's (e.g. a missing texture, a scene lit
//!                                        // by the default sky), shown by the page on load
//!       "features": { "sky": false, "textures": false, "shading": false,   // every
//!                     "point_lights": false, "emissive_triangles": true, ... } // `Features` flag
//!     }
//!   ]
//! }
//! ```

use std::collections::BTreeMap;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use anyhow::{bail, Context, Result};
use bytes::Bytes;
use sha2::{Digest, Sha256};

/// Size of the files accepted as static assets (the wasm module is a few MB).
const MAX_ASSET_BYTES: u64 = 256 << 20;
/// `Cache-Control` of content-addressed bundles: a URL never changes meaning.
pub const IMMUTABLE: &str = "public, max-age=31536000, immutable";
/// `Cache-Control` of everything else: kept, but revalidated (ETag) before each use.
pub const NO_CACHE: &str = "no-cache";

/// One response body, ready to send.
pub struct Resource {
    pub content_type: &'static str,
    pub cache_control: &'static str,
    /// SHA-256 (hex) of `identity`, the base of the ETags.
    pub hash: String,
    pub identity: Bytes,
    /// The gzip representation, where it is smaller.
    pub gzip: Option<Bytes>,
}

impl Resource {
    fn new(content_type: &'static str, cache_control: &'static str, identity: Vec<u8>, compress: bool) -> Result<Self> {
        let hash = hex(&Sha256::digest(&identity));
        let gzip = if compress { Some(gzip(&identity)?).filter(|g| g.len() < identity.len()) } else { None };
        Ok(Resource { content_type, cache_control, hash, identity: identity.into(), gzip: gzip.map(Bytes::from) })
    }

    pub fn etag(&self, gzip: bool) -> String {
        if gzip {
            format!("\"{}-gzip\"", self.hash)
        } else {
            format!("\"{}\"", self.hash)
        }
    }
}

fn hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02x}")).collect()
}

fn gzip(bytes: &[u8]) -> Result<Vec<u8>> {
    let mut encoder =
        flate2::write::GzEncoder::new(Vec::with_capacity(bytes.len() / 2), flate2::Compression::default());
    encoder.write_all(bytes)?;
    Ok(encoder.finish()?)
}

/// What to build a site from: the `serve` and `export` arguments they share.
#[derive(clap::Args)]
pub struct SiteArgs {
    /// Scenes to serve (.gltf, .glb, .obj, .fbx, or a built-in name: metal-rough-spheres,
    /// glass-cornell), after the built-in Cornell box.
    pub scenes: Vec<PathBuf>,
    /// Equirectangular sky (.hdr or .exr) added to every scene, or `none`. Without it a scene
    /// that nothing lights (no emitter bright enough, no point light) gets a uniform white sky,
    /// with a warning.
    #[arg(long, value_name = "FILE|none")]
    pub sky: Option<crate::sky::SkyArg>,
    /// Directory holding the page (`www/`) and its wasm build (`pkg/`) to use instead of the
    /// page built into this binary (a page being worked on: no rebuild of lightport needed).
    #[arg(long)]
    pub web: Option<PathBuf>,
    /// Refuse (build nothing) when loading a scene gives any warning, instead of using it anyway.
    #[arg(long)]
    pub strict: bool,
    #[command(flatten)]
    pub pose: crate::pose::PoseArgs,
}

/// Every route, and what start-up measured.
pub struct Site {
    /// URL path (`/`, `/index.html`, `/pkg/...`, `/scenes.json`, `/bundles/<hash>.lpb`) to body.
    pub routes: BTreeMap<String, Resource>,
    pub reports: Vec<SceneReport>,
}

/// What start-up measured for one scene.
pub struct SceneReport {
    pub name: String,
    pub triangles: usize,
    pub raw_bytes: usize,
    pub gzip_bytes: usize,
    pub prepare: Duration,
    pub encode: Duration,
    pub decode: Duration,
    pub compress: Duration,
}

impl Site {
    /// Loads every scene (all failures reported together) and reads the page's files.
    pub fn build(args: &SiteArgs) -> Result<Site> {
        let mut site = Site { routes: BTreeMap::new(), reports: Vec::new() };
        site.add_scenes(args)?;
        match &args.web {
            Some(dir) => site.add_assets(&dir_files(dir)?)?,
            None => {
                let files: Vec<(String, Vec<u8>)> =
                    embedded::FILES.iter().map(|(route, bytes)| (route.to_string(), bytes.to_vec())).collect();
                if !files.iter().any(|(route, _)| route.starts_with("/pkg/")) {
                    eprintln!(
                        "warning: this lightport binary was built without the page's wasm (web/pkg/ was missing). Run `bash scripts/build-web.sh`, then rebuild lightport (`cargo build` / `cargo install --path .`), or pass --web DIR"
                    );
                }
                site.add_assets(&files)?;
            }
        }
        Ok(site)
    }

    /// The start-up table: one row per scene.
    pub fn print_reports(&self) {
        println!(
            "{:<24} {:>10} {:>12} {:>12} {:>6} {:>12} {:>9} {:>9} {:>9}",
            "scene", "triangles", "raw bytes", "gzip bytes", "gzip", "load+BVH+pack", "encode", "decode", "gzip"
        );
        for r in &self.reports {
            println!(
                "{:<24} {:>10} {:>12} {:>12} {:>5.1}% {:>10.1} ms {:>6.1} ms {:>6.1} ms {:>6.1} ms",
                r.name,
                r.triangles,
                r.raw_bytes,
                r.gzip_bytes,
                100.0 * r.gzip_bytes as f64 / r.raw_bytes.max(1) as f64,
                r.prepare.as_secs_f64() * 1e3,
                r.encode.as_secs_f64() * 1e3,
                r.decode.as_secs_f64() * 1e3,
                r.compress.as_secs_f64() * 1e3
            );
        }
    }

    /// Loads, builds, packs, encodes and compresses every scene; all failures are reported together.
    fn add_scenes(&mut self, args: &SiteArgs) -> Result<()> {
        let sky = match crate::sky::SkyArg::file(args.sky.as_ref()) {
            Some(path) => Some(
                tracer::scene::load_sky(path, 1.0, 0.0).with_context(|| format!("loading sky {}", path.display()))?,
            ),
            None => None,
        };
        let mut entries = Vec::new();
        let mut failures = Vec::new();
        for (name, path) in scene_names(&args.scenes) {
            let t0 = Instant::now();
            // A scene whose animation moves something keeps its motion (unless flattened): its
            // bundle carries the motion section, and its pose is packed as a moving scene's.
            let packed = (|| -> Result<(tracer::pack::Packed, Option<tracer::scene::Scene>, Vec<String>)> {
                let builtin = path.filter(|p| !p.exists()).and_then(|p| tracer::scene::builtin(p.to_str()?));
                let mut options = args.pose.load_options(args.strict)?;
                options.keep_motion = !args.pose.flatten;
                let mut scene = match (path, builtin) {
                    (_, Some(generated)) => generated,
                    (Some(path), None) => tracer::scene::load_with(path, &options)?,
                    (None, None) => tracer::scene::cornell_box(),
                };
                args.pose.apply_to_generated(&mut scene)?;
                if sky.is_some() {
                    scene.sky = sky.clone();
                }
                crate::sky::light_unless_told(&mut scene, args.sky.as_ref());
                // The page shows them too, as it shows a dropped file's.
                let warnings = crate::report_warnings(&scene, &format!("{name}: "), args.strict)?;
                let settings = tracer::kernel::RenderSettings::default();
                if scene.motion.is_some() {
                    let (moving, packed) = tracer::pack::MovingScene::new(scene, &settings).context("packing")?;
                    return Ok((packed, Some(moving.scene().clone()), warnings));
                }
                let bvh = tracer::pack::static_bvh(&scene).context("building the BVH")?;
                Ok((tracer::pack::pack(&scene, &bvh, &settings).context("packing")?, None, warnings))
            })();
            let (packed, moving, warnings) = match packed {
                Ok(p) => p,
                Err(e) => {
                    failures.push(format!("{}: {e:#}", path.map_or(name.clone(), |p| p.display().to_string())));
                    continue;
                }
            };
            let prepare = t0.elapsed();
            let t1 = Instant::now();
            let bytes = match &moving {
                Some(scene) => tracer::bundle::encode_scene(&name, &packed, scene),
                None => tracer::bundle::encode_named(&name, &packed),
            };
            let encode = t1.elapsed();
            // What the page will do (in wasm): a bundle that does not decode is a bug worth
            // stopping for, and the time is a hint of the page's load time.
            let t_decode = Instant::now();
            tracer::bundle::decode(&bytes).with_context(|| format!("{name}: the encoded bundle does not decode"))?;
            let decode = t_decode.elapsed();
            let t2 = Instant::now();
            let bundle = Resource::new("application/octet-stream", IMMUTABLE, bytes, true)?;
            let compress = t2.elapsed();
            let gzip_bytes = bundle.gzip.as_ref().map_or(bundle.identity.len(), Bytes::len);
            let url = format!("bundles/{}.{}", bundle.hash, tracer::bundle::EXTENSION);
            let f = packed.features;
            entries.push(serde_json::json!({
                "name": name,
                "url": url,
                "hash": bundle.hash,
                "bytes": { "raw": bundle.identity.len(), "gzip": gzip_bytes },
                "triangles": packed.triangle_count,
                "lights": packed.light_count,
                "warnings": warnings,
                "features": f.flags().iter().map(|flag| (flag.name.to_string(), flag.on.into())).collect::<serde_json::Map<_, _>>(),
            }));
            self.reports.push(SceneReport {
                name,
                triangles: packed.triangle_count,
                raw_bytes: bundle.identity.len(),
                gzip_bytes,
                prepare,
                encode,
                decode,
                compress,
            });
            self.routes.insert(format!("/{url}"), bundle);
        }
        if !failures.is_empty() {
            for f in &failures {
                eprintln!("error: {f}");
            }
            bail!(
                "{} of {} scene(s) failed to load; nothing is served (fix or leave out the scene(s) above)",
                failures.len(),
                failures.len() + self.reports.len()
            );
        }
        let list = serde_json::json!({ "bundle_version": tracer::bundle::VERSION, "scenes": entries });
        let json = serde_json::to_vec_pretty(&list)?;
        self.routes.insert("/scenes.json".into(), Resource::new("application/json", NO_CACHE, json, true)?);
        Ok(())
    }

    /// Adds the page's files (route, bytes), `/index.html` also at `/`.
    fn add_assets(&mut self, files: &[(String, Vec<u8>)]) -> Result<()> {
        for (route, bytes) in files {
            if self.routes.contains_key(route) {
                eprintln!("warning: the page's {route} is hidden by the server's own");
                continue;
            }
            let (ty, compress) = content_type(route);
            if route == "/index.html" {
                self.routes.insert("/".into(), Resource::new(ty, NO_CACHE, bytes.clone(), compress)?);
            }
            self.routes.insert(route.clone(), Resource::new(ty, NO_CACHE, bytes.clone(), compress)?);
        }
        Ok(())
    }
}

/// The page built into the binary by build.rs (the same file rules as [`dir_files`]).
mod embedded {
    include!(concat!(env!("OUT_DIR"), "/embedded_web.rs"));
}

/// The page of `--web DIR`: `DIR/www/` at `/` and its wasm build `DIR/pkg/` at `/pkg/`; regular
/// files only (symbolic links are not followed, so nothing outside the tree is reachable),
/// names of letters, digits, `-`, `_` and `.` without a leading dot, read into memory now.
fn dir_files(web: &Path) -> Result<Vec<(String, Vec<u8>)>> {
    let www = web.join("www");
    let pkg = web.join("pkg");
    let mut files = Vec::new();
    if www.is_dir() {
        collect_files(&www, "/", 0, &mut files)?;
    } else {
        eprintln!("warning: {} not found: the page is not served (only /scenes.json and the bundles)", www.display());
    }
    if pkg.is_dir() {
        collect_files(&pkg, "/pkg/", 0, &mut files)?;
    } else {
        eprintln!(
            "warning: {} is missing: the page's wasm is not built. Run `bash scripts/build-web.sh`, then restart `lightport serve`",
            pkg.display()
        );
    }
    files
        .into_iter()
        .map(|(route, path)| Ok((route, std::fs::read(&path).with_context(|| format!("reading {}", path.display()))?)))
        .collect()
}

/// The scenes' unique names in order, the built-in Cornell box (no path) first: each file's stem,
/// with "-2", "-3"... appended on clashes.
fn scene_names(paths: &[PathBuf]) -> Vec<(String, Option<&Path>)> {
    let mut sources: Vec<(String, Option<&Path>)> = vec![("cornell-box".to_string(), None)];
    for path in paths {
        let stem = path.file_stem().map_or("scene".into(), |s| s.to_string_lossy().to_string());
        let mut name = stem.clone();
        let mut n = 2;
        while sources.iter().any(|(existing, _)| *existing == name) {
            name = format!("{stem}-{n}");
            n += 1;
        }
        sources.push((name, Some(path)));
    }
    sources
}

/// Content type by extension, and whether the format is worth compressing.
pub fn content_type(path: &str) -> (&'static str, bool) {
    let ext = Path::new(path).extension().and_then(|e| e.to_str()).unwrap_or("").to_ascii_lowercase();
    match ext.as_str() {
        "html" | "htm" => ("text/html; charset=utf-8", true),
        "js" | "mjs" => ("text/javascript", true),
        "wasm" => ("application/wasm", true),
        "css" => ("text/css; charset=utf-8", true),
        "json" | "map" => ("application/json", true),
        "svg" => ("image/svg+xml", true),
        "txt" | "md" => ("text/plain; charset=utf-8", true),
        "ts" => ("text/plain; charset=utf-8", true),
        "png" => ("image/png", false),
        "jpg" | "jpeg" => ("image/jpeg", false),
        "ico" => ("image/x-icon", false),
        "webp" => ("image/webp", false),
        _ => ("application/octet-stream", true),
    }
}

fn collect_files(dir: &Path, prefix: &str, depth: u32, out: &mut Vec<(String, PathBuf)>) -> Result<()> {
    const MAX_DEPTH: u32 = 8;
    let mut entries: Vec<_> = std::fs::read_dir(dir)
        .with_context(|| format!("reading {}", dir.display()))?
        .collect::<Result<_, _>>()
        .with_context(|| format!("reading {}", dir.display()))?;
    entries.sort_by_key(|e| e.file_name());
    for entry in entries {
        let path = entry.path();
        let name = entry.file_name().to_string_lossy().to_string();
        let safe = !name.starts_with('.') && name.chars().all(|c| c.is_ascii_alphanumeric() || "-_.".contains(c));
        let kind = entry.file_type()?;
        if !safe || kind.is_symlink() {
            eprintln!("note: not serving {} (hidden, unusual name or symbolic link)", path.display());
        } else if kind.is_dir() && depth < MAX_DEPTH {
            collect_files(&path, &format!("{prefix}{name}/"), depth + 1, out)?;
        } else if kind.is_file() && entry.metadata()?.len() <= MAX_ASSET_BYTES {
            out.push((format!("{prefix}{name}"), path));
        } else {
            eprintln!("note: not serving {} (too deep or too large)", path.display());
        }
    }
    Ok(())
}
