//! `lightport serve`: an HTTP server on 127.0.0.1 for the web path tracer: the page
//! (`web/www/`), its wasm build (`web/pkg/`, served under `/pkg/`), and one prebuilt bundle per
//! scene (`tracer::bundle`: loaded, BVH-built and packed at start, so the browser builds nothing).
//!
//! # Routes
//! - `/` and `/index.html`: `web/www/index.html`; `/<path>`: any other file of `web/www/`;
//!   `/pkg/<path>`: the files of `web/pkg/`. `Cache-Control: no-cache` with an `ETag` (so a
//!   reload revalidates and gets `304`).
//! - `/scenes.json`: the served scenes (schema below), `Cache-Control: no-cache`, `ETag`.
//! - `/bundles/<hash>.lpb`: a scene bundle (`tracer::bundle::decode` reads it), content-addressed
//!   by `<hash>` = SHA-256 of the uncompressed bundle (64 lowercase hex digits), `Cache-Control:
//!   public, max-age=31536000, immutable`, `ETag: "<hash>"` (`"<hash>-gzip"` for the gzip
//!   representation; `If-None-Match` with either gives `304`), `Content-Type:
//!   application/octet-stream`. Sent with `Content-Encoding: gzip` when the request's
//!   `Accept-Encoding` allows gzip (a browser's `fetch` then hands the page the uncompressed
//!   bytes), otherwise uncompressed; `Vary: Accept-Encoding`.
//!
//! # `/scenes.json`
//! ```json
//! {
//!   "bundle_version": 1,                 // tracer::bundle::VERSION of every bundle listed
//!   "scenes": [                          // in command-line order; the built-in Cornell box first
//!     {
//!       "name": "cornell-box",           // unique: file stem, "-2", "-3"... appended on clashes
//!       "url": "/bundles/<hash>.lpb",    // absolute path on this server
//!       "hash": "<hash>",                // SHA-256 (hex) of the uncompressed bundle: a cache key
//!       "bytes": { "raw": 5120, "gzip": 1234 },   // uncompressed and gzip-compressed sizes
//!       "triangles": 36,
//!       "lights": 2,
//!       "features": { "sky": false, "textures": false, "shading": false,
//!                     "point_lights": false, "emissive_triangles": true }
//!     }
//!   ]
//! }
//! ```
//!
//! # What it refuses
//! Only `GET` and `HEAD` (`405` with `Allow` otherwise). The request path is never joined to a
//! file-system path: it is looked up, exactly (query string ignored), in a table of routes built
//! at start, so `..`, `%2e%2e`, backslashes, absolute or unknown paths and directories are all
//! `404`. Request heads over [`MAX_HEAD_BYTES`] or [`MAX_HEADERS`] headers get `431`; a declared
//! body over [`MAX_BODY_BYTES`] `413`; a chunked request body `411`. A client has `--timeout`
//! seconds to send each request head (`408` after that) and each write to it must progress
//! within [`WRITE_TIMEOUT`], so a slow client holds one worker for a bounded time. A fixed
//! pool of [`WORKERS`] threads serves connections (HTTP/1.1 keep-alive); past [`QUEUE`] waiting
//! connections the server answers `503` at once.
//!
//! # Start-up
//! Every scene is loaded, BVH-built, packed, encoded and compressed before the server listens.
//! If any named scene fails, every failure is printed and `serve` exits non-zero without
//! serving: a scene the user asked for is never silently missing from the page. A missing
//! `web/pkg/` (or `web/www/`) is reported with the command that builds it; the bundles and
//! `/scenes.json` are served anyway.

use std::collections::HashMap;
use std::io::{Read, Write};
use std::net::{Shutdown, TcpListener, TcpStream};
use std::path::{Path, PathBuf};
use std::sync::mpsc::{self, Receiver, SyncSender, TrySendError};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use anyhow::{bail, Context, Result};
use sha2::{Digest, Sha256};

/// Largest request head (request line and headers) accepted; larger gets `431`.
pub const MAX_HEAD_BYTES: usize = 16 * 1024;
/// Most request headers accepted; more gets `431`.
pub const MAX_HEADERS: usize = 64;
/// Largest request body accepted (and discarded: no route takes one); larger gets `413`.
pub const MAX_BODY_BYTES: u64 = 1024;
/// Worker threads serving connections.
pub const WORKERS: usize = 16;
/// Accepted connections waiting for a worker before new ones get `503`.
pub const QUEUE: usize = 256;
/// Longest a single write to a client may block (a client that stops reading is dropped).
pub const WRITE_TIMEOUT: Duration = Duration::from_secs(20);
/// Requests served on one keep-alive connection before it is closed.
const MAX_REQUESTS_PER_CONNECTION: u32 = 1000;
/// Size of the files accepted as static assets (the wasm module is a few MB).
const MAX_ASSET_BYTES: u64 = 256 << 20;

#[derive(clap::Args)]
pub struct ServeArgs {
    /// Scenes to serve (.gltf, .glb, .obj, .fbx), after the built-in Cornell box.
    scenes: Vec<PathBuf>,
    /// Port on 127.0.0.1 (0: any free port; the URL printed says which).
    #[arg(long, default_value_t = 8080)]
    port: u16,
    /// Equirectangular sky (.hdr or .exr) added to every served scene.
    #[arg(long)]
    sky: Option<PathBuf>,
    /// Directory holding the page (`www/`) and its wasm build (`pkg/`).
    #[arg(long, default_value = concat!(env!("CARGO_MANIFEST_DIR"), "/web"))]
    web: PathBuf,
    /// Seconds a client has to send each request head.
    #[arg(long, default_value_t = 10.0)]
    timeout: f64,
    /// Exit when stdin reaches its end: for a parent (a test, `lightport chart`) that holds the
    /// other end of a pipe, which the kernel closes when the parent ends however it ends.
    #[arg(long)]
    exit_on_stdin_eof: bool,
    /// Refuse (serve nothing) when loading a scene gives any warning, instead of serving it anyway.
    #[arg(long)]
    strict: bool,
}

/// One response body, ready to send.
struct Resource {
    content_type: &'static str,
    cache_control: &'static str,
    /// SHA-256 (hex) of `identity`, the base of the ETags.
    hash: String,
    identity: Vec<u8>,
    /// The gzip representation, where it is smaller.
    gzip: Option<Vec<u8>>,
}

impl Resource {
    fn new(content_type: &'static str, cache_control: &'static str, identity: Vec<u8>, compress: bool) -> Result<Self> {
        let hash = hex(&Sha256::digest(&identity));
        let gzip = if compress { Some(gzip(&identity)?).filter(|g| g.len() < identity.len()) } else { None };
        Ok(Resource { content_type, cache_control, hash, identity, gzip })
    }

    fn etag(&self, gzip: bool) -> String {
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

/// Everything the server answers, built once at start.
struct Site {
    routes: HashMap<String, Resource>,
    request_timeout: Duration,
}

/// What start-up measured for one scene.
struct SceneReport {
    name: String,
    triangles: usize,
    raw_bytes: usize,
    gzip_bytes: usize,
    prepare: Duration,
    encode: Duration,
    decode: Duration,
    compress: Duration,
}

pub fn serve(args: &ServeArgs) -> Result<()> {
    if !(args.timeout.is_finite() && args.timeout > 0.0 && args.timeout <= 3600.0) {
        bail!("--timeout must be between 0 and 3600 seconds");
    }
    if args.exit_on_stdin_eof {
        exit_on_stdin_eof();
    }
    let mut routes = HashMap::new();
    let reports = add_scenes(args, &mut routes)?;
    add_assets(&args.web, &mut routes)?;

    println!(
        "{:<24} {:>10} {:>12} {:>12} {:>6} {:>12} {:>9} {:>9} {:>9}",
        "scene", "triangles", "raw bytes", "gzip bytes", "gzip", "load+BVH+pack", "encode", "decode", "gzip"
    );
    for r in &reports {
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

    let listener = TcpListener::bind(("127.0.0.1", args.port))
        .with_context(|| format!("cannot listen on 127.0.0.1:{} (is the port in use? try --port 0)", args.port))?;
    let addr = listener.local_addr()?;
    let site = Arc::new(Site { routes, request_timeout: Duration::from_secs_f64(args.timeout) });
    println!("serving {} scene(s) at http://{addr}/", reports.len());
    std::io::stdout().flush()?;
    run(listener, site)
}

/// Ends the process when stdin reaches its end (or fails): started before the scenes load, so
/// that a parent that ends during a long start-up leaves nothing behind either.
fn exit_on_stdin_eof() {
    std::thread::spawn(|| {
        let _ = std::io::copy(&mut std::io::stdin().lock(), &mut std::io::sink());
        // Not eprintln!: it panics when stderr is a pipe whose reader (the parent) is gone.
        let _ = writeln!(std::io::stderr(), "stdin closed (--exit-on-stdin-eof): exiting");
        std::process::exit(0);
    });
}

/// Loads, builds, packs, encodes and compresses every scene; all failures are reported together.
fn add_scenes(args: &ServeArgs, routes: &mut HashMap<String, Resource>) -> Result<Vec<SceneReport>> {
    let sky = match &args.sky {
        Some(path) => {
            Some(tracer::scene::load_sky(path, 1.0, 0.0).with_context(|| format!("loading sky {}", path.display()))?)
        }
        None => None,
    };
    let mut sources: Vec<(String, Option<&Path>)> = vec![("cornell-box".to_string(), None)];
    for path in &args.scenes {
        let stem = path.file_stem().map_or("scene".into(), |s| s.to_string_lossy().to_string());
        let mut name = stem.clone();
        let mut n = 2;
        while sources.iter().any(|(existing, _)| *existing == name) {
            name = format!("{stem}-{n}");
            n += 1;
        }
        sources.push((name, Some(path)));
    }

    let mut reports = Vec::new();
    let mut entries = Vec::new();
    let mut failures = Vec::new();
    for (name, path) in sources {
        let t0 = Instant::now();
        let packed = (|| -> Result<tracer::pack::Packed> {
            let mut scene = match path {
                Some(path) => tracer::scene::load_with(path, &tracer::scene::LoadOptions { strict: args.strict })?,
                None => tracer::scene::cornell_box(),
            };
            if sky.is_some() {
                scene.sky = sky.clone();
            }
            crate::report_warnings(&scene, &format!("{name}: "), args.strict)?;
            let bvh = tracer::bvh::build(&scene.triangles).context("building the BVH")?;
            tracer::pack::pack(&scene, &bvh, &tracer::pack::RenderSettings::default()).context("packing")
        })();
        let packed = match packed {
            Ok(p) => p,
            Err(e) => {
                failures.push(format!("{}: {e:#}", path.map_or(name.clone(), |p| p.display().to_string())));
                continue;
            }
        };
        let prepare = t0.elapsed();
        let t1 = Instant::now();
        let bytes = tracer::bundle::encode_named(&name, &packed);
        let encode = t1.elapsed();
        // What the page will do (in wasm): a bundle that does not decode is a bug worth
        // stopping for, and the time is a hint of the page's load time.
        let t_decode = Instant::now();
        tracer::bundle::decode(&bytes).with_context(|| format!("{name}: the encoded bundle does not decode"))?;
        let decode = t_decode.elapsed();
        let t2 = Instant::now();
        let bundle = Resource::new("application/octet-stream", IMMUTABLE, bytes, true)?;
        let compress = t2.elapsed();
        let gzip_bytes = bundle.gzip.as_ref().map_or(bundle.identity.len(), Vec::len);
        let url = format!("/bundles/{}.{}", bundle.hash, tracer::bundle::EXTENSION);
        let f = packed.features;
        entries.push(serde_json::json!({
            "name": name,
            "url": url,
            "hash": bundle.hash,
            "bytes": { "raw": bundle.identity.len(), "gzip": gzip_bytes },
            "triangles": packed.triangle_count,
            "lights": packed.light_count,
            "features": {
                "sky": f.sky, "textures": f.textures, "shading": f.shading,
                "point_lights": f.point_lights, "emissive_triangles": f.emissive_triangles,
            },
        }));
        reports.push(SceneReport {
            name,
            triangles: packed.triangle_count,
            raw_bytes: bundle.identity.len(),
            gzip_bytes,
            prepare,
            encode,
            decode,
            compress,
        });
        routes.insert(url, bundle);
    }
    if !failures.is_empty() {
        for f in &failures {
            eprintln!("error: {f}");
        }
        bail!(
            "{} of {} scene(s) failed to load; nothing is served (fix or leave out the scene(s) above)",
            failures.len(),
            failures.len() + reports.len()
        );
    }
    let list = serde_json::json!({ "bundle_version": tracer::bundle::VERSION, "scenes": entries });
    let json = serde_json::to_vec_pretty(&list)?;
    routes.insert("/scenes.json".into(), Resource::new("application/json", NO_CACHE, json, true)?);
    Ok(reports)
}

const IMMUTABLE: &str = "public, max-age=31536000, immutable";
const NO_CACHE: &str = "no-cache";

/// Content type by extension, and whether the format is worth compressing.
fn content_type(path: &Path) -> (&'static str, bool) {
    let ext = path.extension().and_then(|e| e.to_str()).unwrap_or("").to_ascii_lowercase();
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

/// Adds the page (`<web>/www/` at `/`) and its wasm build (`<web>/pkg/` at `/pkg/`): regular
/// files only (symbolic links are not followed, so nothing outside the tree is reachable),
/// names of letters, digits, `-`, `_` and `.` without a leading dot, read into memory now.
fn add_assets(web: &Path, routes: &mut HashMap<String, Resource>) -> Result<()> {
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
    for (route, path) in files {
        if routes.contains_key(&route) {
            eprintln!("warning: {} is hidden by the server's own {route}", path.display());
            continue;
        }
        let (ty, compress) = content_type(&path);
        let bytes = std::fs::read(&path).with_context(|| format!("reading {}", path.display()))?;
        if route == "/index.html" {
            routes.insert("/".into(), Resource::new(ty, NO_CACHE, bytes.clone(), compress)?);
        }
        routes.insert(route, Resource::new(ty, NO_CACHE, bytes, compress)?);
    }
    Ok(())
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

/// Accepts connections and hands them to the worker pool; never returns unless accepting fails.
fn run(listener: TcpListener, site: Arc<Site>) -> Result<()> {
    let (sender, receiver): (SyncSender<TcpStream>, Receiver<TcpStream>) = mpsc::sync_channel(QUEUE);
    let receiver = Arc::new(Mutex::new(receiver));
    for i in 0..WORKERS {
        let receiver = Arc::clone(&receiver);
        let site = Arc::clone(&site);
        std::thread::Builder::new().name(format!("serve-{i}")).spawn(move || loop {
            // The lock is held only while waiting for the next connection, not while serving it.
            let next = receiver.lock().map(|r| r.recv());
            match next {
                Ok(Ok(stream)) => serve_connection(stream, &site),
                _ => return,
            }
        })?;
    }
    for stream in listener.incoming() {
        let stream = match stream {
            Ok(s) => s,
            // A connection that failed before it was accepted (reset, out of descriptors):
            // keep accepting the others.
            Err(e) => {
                eprintln!("warning: accept failed: {e}");
                std::thread::sleep(Duration::from_millis(10));
                continue;
            }
        };
        if let Err(TrySendError::Full(mut stream)) = sender.try_send(stream) {
            let _ = stream.set_write_timeout(Some(Duration::from_secs(1)));
            let _ =
                write_simple(&mut stream, 503, "the server is busy; try again", &[("Retry-After", "1".into())], false);
        }
    }
    Ok(())
}

/// The parts of a request the server looks at.
struct RequestHead {
    method: String,
    path: String,
    keep_alive: bool,
    accepts_gzip: bool,
    if_none_match: Option<String>,
    content_length: u64,
    chunked: bool,
}

enum ReadOutcome {
    Request(RequestHead, usize),
    /// The client closed the connection, or sent nothing before the timeout, between requests.
    Closed,
    /// Answer with this status and close.
    Refuse(u16, &'static str),
}

fn serve_connection(mut stream: TcpStream, site: &Site) {
    let _ = stream.set_nodelay(true);
    let _ = stream.set_write_timeout(Some(WRITE_TIMEOUT));
    let mut buffer = Vec::with_capacity(4096);
    for _ in 0..MAX_REQUESTS_PER_CONNECTION {
        let (head, head_len) = match read_head(&mut stream, &mut buffer, site.request_timeout) {
            ReadOutcome::Request(head, len) => (head, len),
            ReadOutcome::Closed => return,
            ReadOutcome::Refuse(status, message) => {
                let _ = write_simple(&mut stream, status, message, &[], false);
                let _ = stream.shutdown(Shutdown::Write);
                return;
            }
        };
        buffer.drain(..head_len);
        // Bodies are never used: refuse large or unframed ones, discard small ones.
        if head.chunked {
            let _ = write_simple(&mut stream, 411, "request bodies must have a Content-Length", &[], false);
            return;
        }
        if head.content_length > MAX_BODY_BYTES {
            let _ = write_simple(&mut stream, 413, "request body too large", &[], false);
            return;
        }
        if !discard_body(&mut stream, &mut buffer, head.content_length as usize, site.request_timeout) {
            return;
        }
        let keep_alive = head.keep_alive;
        let written = respond(&mut stream, site, &head, keep_alive);
        if written.is_err() || !keep_alive {
            let _ = stream.shutdown(Shutdown::Write);
            return;
        }
    }
}

/// Reads until `buffer` holds a complete request head, within `timeout` from now.
fn read_head(stream: &mut TcpStream, buffer: &mut Vec<u8>, timeout: Duration) -> ReadOutcome {
    let deadline = Instant::now() + timeout;
    loop {
        if !buffer.is_empty() {
            let mut headers = [httparse::EMPTY_HEADER; MAX_HEADERS];
            let mut request = httparse::Request::new(&mut headers);
            match request.parse(buffer) {
                // The whole head may arrive at once: its size is checked here too.
                Ok(httparse::Status::Complete(len)) if len > MAX_HEAD_BYTES => {
                    return ReadOutcome::Refuse(431, "request head too large")
                }
                Ok(httparse::Status::Complete(len)) => {
                    return match RequestHead::from_parsed(&request) {
                        Ok(head) => ReadOutcome::Request(head, len),
                        Err(message) => ReadOutcome::Refuse(400, message),
                    }
                }
                Ok(httparse::Status::Partial) => {}
                Err(httparse::Error::TooManyHeaders) => return ReadOutcome::Refuse(431, "too many request headers"),
                Err(_) => return ReadOutcome::Refuse(400, "malformed request"),
            }
        }
        if buffer.len() > MAX_HEAD_BYTES {
            return ReadOutcome::Refuse(431, "request head too large");
        }
        let now = Instant::now();
        if now >= deadline {
            return if buffer.is_empty() { ReadOutcome::Closed } else { ReadOutcome::Refuse(408, "request timeout") };
        }
        if stream.set_read_timeout(Some(deadline - now)).is_err() {
            return ReadOutcome::Closed;
        }
        let mut chunk = [0u8; 4096];
        match stream.read(&mut chunk) {
            Ok(0) => return ReadOutcome::Closed,
            Ok(n) => buffer.extend_from_slice(&chunk[..n]),
            Err(e) if matches!(e.kind(), std::io::ErrorKind::WouldBlock | std::io::ErrorKind::TimedOut) => {
                return if buffer.is_empty() {
                    ReadOutcome::Closed
                } else {
                    ReadOutcome::Refuse(408, "request timeout")
                };
            }
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
            Err(_) => return ReadOutcome::Closed,
        }
    }
}

/// Reads and drops `len` body bytes (some may already be in `buffer`); false if the client failed.
fn discard_body(stream: &mut TcpStream, buffer: &mut Vec<u8>, len: usize, timeout: Duration) -> bool {
    let buffered = len.min(buffer.len());
    buffer.drain(..buffered);
    let mut left = len - buffered;
    let deadline = Instant::now() + timeout;
    let mut chunk = [0u8; 1024];
    while left > 0 {
        let now = Instant::now();
        if now >= deadline || stream.set_read_timeout(Some(deadline - now)).is_err() {
            return false;
        }
        match stream.read(&mut chunk[..left.min(1024)]) {
            Ok(0) | Err(_) => return false,
            Ok(n) => left -= n,
        }
    }
    true
}

impl RequestHead {
    fn from_parsed(request: &httparse::Request) -> Result<RequestHead, &'static str> {
        let method = request.method.ok_or("no method")?.to_string();
        let path = request.path.ok_or("no path")?.to_string();
        let version = request.version.ok_or("no version")?;
        let mut connection = String::new();
        let mut accept_encoding = String::new();
        let mut if_none_match: Option<String> = None;
        let mut content_length: Option<u64> = None;
        let mut chunked = false;
        for h in request.headers.iter() {
            let value = std::str::from_utf8(h.value).map_err(|_| "a header value is not UTF-8")?.trim();
            let name = h.name.to_ascii_lowercase();
            match name.as_str() {
                "connection" => connection = format!("{connection},{}", value.to_ascii_lowercase()),
                "accept-encoding" => accept_encoding = format!("{accept_encoding},{}", value.to_ascii_lowercase()),
                "if-none-match" => {
                    if_none_match = Some(match if_none_match {
                        Some(v) => format!("{v},{value}"),
                        None => value.to_string(),
                    })
                }
                "content-length" => {
                    let n: u64 = value.parse().map_err(|_| "invalid Content-Length")?;
                    if content_length.is_some_and(|m| m != n) {
                        return Err("conflicting Content-Length headers");
                    }
                    content_length = Some(n);
                }
                "transfer-encoding" => chunked = true,
                _ => {}
            }
        }
        let has_token = |list: &str, token: &str| list.split(',').any(|t| t.trim() == token);
        let keep_alive =
            if version == 0 { has_token(&connection, "keep-alive") } else { !has_token(&connection, "close") };
        Ok(RequestHead {
            method,
            path,
            keep_alive,
            accepts_gzip: accepts_gzip(&accept_encoding),
            if_none_match,
            content_length: content_length.unwrap_or(0),
            chunked,
        })
    }
}

/// Whether an `Accept-Encoding` list (lowercase) allows gzip: `gzip`, `x-gzip` or `*` with q > 0.
fn accepts_gzip(list: &str) -> bool {
    let mut star = None;
    for item in list.split(',') {
        let mut parts = item.split(';');
        let coding = parts.next().unwrap_or("").trim();
        let q = parts
            .filter_map(|p| p.trim().strip_prefix("q="))
            .filter_map(|q| q.trim().parse::<f32>().ok())
            .next()
            .unwrap_or(1.0);
        match coding {
            "gzip" | "x-gzip" => return q > 0.0,
            "*" => star = Some(q > 0.0),
            _ => {}
        }
    }
    star.unwrap_or(false)
}

/// Whether an `If-None-Match` value names one of `etags` (weak comparison, as RFC 9110 asks).
fn matches_etag(if_none_match: &str, etags: &[String]) -> bool {
    if_none_match
        .split(',')
        .map(str::trim)
        .any(|tag| tag == "*" || etags.iter().any(|e| tag.trim_start_matches("W/") == e))
}

fn respond(stream: &mut TcpStream, site: &Site, head: &RequestHead, keep_alive: bool) -> std::io::Result<()> {
    let is_head = match head.method.as_str() {
        "GET" => false,
        "HEAD" => true,
        _ => {
            return write_simple(stream, 405, "only GET and HEAD", &[("Allow", "GET, HEAD".into())], keep_alive);
        }
    };
    // The route table is the allow-list: the path is only ever a key, never a file name.
    let path = head.path.split(['?', '#']).next().unwrap_or("");
    let Some(resource) = site.routes.get(path) else {
        return write_simple(stream, 404, "not found", &[], keep_alive);
    };
    let use_gzip = head.accepts_gzip && resource.gzip.is_some();
    let etag = resource.etag(use_gzip);
    let mut headers: Vec<(&str, String)> = vec![
        ("Content-Type", resource.content_type.into()),
        ("Cache-Control", resource.cache_control.into()),
        ("ETag", etag),
        ("X-Content-Type-Options", "nosniff".into()),
    ];
    if resource.gzip.is_some() {
        headers.push(("Vary", "Accept-Encoding".into()));
    }
    if let Some(inm) = &head.if_none_match {
        if matches_etag(inm, &[resource.etag(false), resource.etag(true)]) {
            return write_response(stream, 304, &headers, None, keep_alive);
        }
    }
    let body = match (&resource.gzip, use_gzip) {
        (Some(g), true) => {
            headers.push(("Content-Encoding", "gzip".into()));
            g
        }
        _ => &resource.identity,
    };
    headers.push(("Content-Length", body.len().to_string()));
    write_response(stream, 200, &headers, if is_head { None } else { Some(body) }, keep_alive)
}

fn reason(status: u16) -> &'static str {
    match status {
        200 => "OK",
        304 => "Not Modified",
        400 => "Bad Request",
        404 => "Not Found",
        405 => "Method Not Allowed",
        408 => "Request Timeout",
        411 => "Length Required",
        413 => "Content Too Large",
        431 => "Request Header Fields Too Large",
        503 => "Service Unavailable",
        _ => "",
    }
}

/// A short plain-text response (errors).
fn write_simple(
    stream: &mut TcpStream,
    status: u16,
    message: &str,
    extra: &[(&str, String)],
    keep_alive: bool,
) -> std::io::Result<()> {
    let body = format!("{status} {}: {message}\n", reason(status));
    let mut headers: Vec<(&str, String)> = vec![
        ("Content-Type", "text/plain; charset=utf-8".into()),
        ("Cache-Control", "no-store".into()),
        ("Content-Length", body.len().to_string()),
    ];
    headers.extend(extra.iter().cloned());
    write_response(stream, status, &headers, Some(body.as_bytes()), keep_alive)
}

fn write_response(
    stream: &mut TcpStream,
    status: u16,
    headers: &[(&str, String)],
    body: Option<&[u8]>,
    keep_alive: bool,
) -> std::io::Result<()> {
    let mut head = format!("HTTP/1.1 {status} {}\r\nServer: lightport\r\n", reason(status));
    for (name, value) in headers {
        head.push_str(&format!("{name}: {value}\r\n"));
    }
    head.push_str(if keep_alive { "Connection: keep-alive\r\n\r\n" } else { "Connection: close\r\n\r\n" });
    stream.write_all(head.as_bytes())?;
    if let Some(body) = body {
        stream.write_all(body)?;
    }
    stream.flush()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn accept_encoding_lists() {
        assert!(accepts_gzip("gzip, deflate, br"));
        assert!(accepts_gzip(",br;q=1.0, gzip;q=0.5"));
        assert!(!accepts_gzip("gzip;q=0"));
        assert!(!accepts_gzip("br, identity"));
        assert!(accepts_gzip("*"));
        assert!(!accepts_gzip("*;q=0"));
        assert!(!accepts_gzip(""));
    }

    #[test]
    fn etag_matching() {
        let tags = ["\"abc\"".to_string(), "\"abc-gzip\"".to_string()];
        assert!(matches_etag("\"abc\"", &tags));
        assert!(matches_etag("\"x\", W/\"abc-gzip\"", &tags));
        assert!(matches_etag("*", &tags));
        assert!(!matches_etag("\"ab\"", &tags));
    }
}
