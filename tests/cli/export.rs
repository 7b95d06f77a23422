//! `lightport export` end to end: the site it writes, served by a real static server (nginx,
//! Debian's `nginx`, with `docs/nginx.conf`) under a path prefix, and the page run against it in
//! headless Chromium (tests/web/run.mjs): it renders, and a second visit downloads no bundle.
//! Never skipped: without nginx the test fails and says what to install.

use crate::common::browser;
use lightport::serve_child;

use std::io::{Read, Write};
use std::net::TcpStream;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use std::time::{Duration, Instant};

use browser::{browse, no_page_error};

const NGINX: &str = "/usr/sbin/nginx";

/// A directory removed on drop.
struct TempDir(PathBuf);

impl TempDir {
    fn new(tag: &str) -> TempDir {
        let nanos = std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH).unwrap().subsec_nanos();
        let dir = std::env::temp_dir().join(format!("lightport-export-{tag}-{}-{nanos}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        TempDir(dir)
    }
}

impl Drop for TempDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

fn export(args: &[&std::ffi::OsStr]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_lightport")).arg("export").args(args).output().expect("run lightport export")
}

fn sha256_hex(bytes: &[u8]) -> String {
    use sha2::Digest;
    sha2::Sha256::digest(bytes).iter().map(|b| format!("{b:02x}")).collect()
}

/// nginx on a free loopback port serving `root` with docs/nginx.conf; its pid, logs and temp
/// files in `dir`. Stopped when dropped, and when this test binary ends however it ends (it runs
/// under a watcher tied to this process: `serve_child::Killed::spawn_watched`).
struct Nginx {
    _process: serve_child::Killed,
    port: u16,
}

impl Nginx {
    fn start(dir: &Path, root: &Path) -> Nginx {
        assert!(Path::new(NGINX).is_file(), "nginx is missing: apt-get install nginx (scripts/test.sh does)");
        let port = std::net::TcpListener::bind("127.0.0.1:0").unwrap().local_addr().unwrap().port();
        let snippet = Path::new(env!("CARGO_MANIFEST_DIR")).join("docs/nginx.conf");
        let d = dir.display();
        let config = format!(
            "daemon off;\nmaster_process off;\nworker_processes 1;\npid {d}/nginx.pid;\nerror_log {d}/error.log warn;\n\
             events {{ worker_connections 64; }}\n\
             http {{\n  access_log {d}/access.log;\n  client_body_temp_path {d}/body;\n  proxy_temp_path {d}/proxy;\n  \
             fastcgi_temp_path {d}/fastcgi;\n  uwsgi_temp_path {d}/uwsgi;\n  scgi_temp_path {d}/scgi;\n  \
             server {{\n    listen 127.0.0.1:{port};\n    root {};\n    include {};\n  }}\n}}\n",
            root.display(),
            snippet.display()
        );
        let conf = dir.join("nginx.conf");
        std::fs::write(&conf, config).unwrap();
        let error_log = dir.join("error.log");
        let args =
            ["-p".as_ref(), dir.as_os_str(), "-c".as_ref(), conf.as_os_str(), "-e".as_ref(), error_log.as_os_str()];
        let process = serve_child::Killed::spawn_watched(Path::new(NGINX), &args).expect("start nginx");
        let deadline = Instant::now() + Duration::from_secs(20);
        while TcpStream::connect(("127.0.0.1", port)).is_err() {
            let log = std::fs::read_to_string(&error_log).unwrap_or_default();
            assert!(Instant::now() < deadline, "nginx did not listen on port {port} within 20 s: {log}");
            std::thread::sleep(Duration::from_millis(50));
        }
        Nginx { _process: process, port }
    }
}

/// A response over a fresh connection: status, headers (names lowercase), body.
struct Response {
    status: u16,
    headers: Vec<(String, String)>,
    body: Vec<u8>,
}

impl Response {
    fn header(&self, name: &str) -> Option<&str> {
        self.headers.iter().find(|(n, _)| n == name).map(|(_, v)| v.as_str())
    }
}

fn get(port: u16, path: &str, headers: &[(&str, &str)]) -> Response {
    let mut s = TcpStream::connect(("127.0.0.1", port)).unwrap();
    s.set_read_timeout(Some(Duration::from_secs(30))).unwrap();
    let mut request = format!("GET {path} HTTP/1.1\r\nHost: 127.0.0.1\r\nConnection: close\r\n");
    for (n, v) in headers {
        request.push_str(&format!("{n}: {v}\r\n"));
    }
    s.write_all(format!("{request}\r\n").as_bytes()).unwrap();
    let mut all = Vec::new();
    s.read_to_end(&mut all).unwrap();
    let end = all.windows(4).position(|w| w == b"\r\n\r\n").expect("a response head");
    let head = String::from_utf8_lossy(&all[..end]).to_string();
    let mut lines = head.lines();
    let status = lines.next().unwrap().split(' ').nth(1).unwrap().parse().unwrap();
    let headers = lines
        .filter_map(|l| l.split_once(':'))
        .map(|(n, v)| (n.trim().to_ascii_lowercase(), v.trim().to_string()))
        .collect();
    Response { status, headers, body: all[end + 4..].to_vec() }
}

#[test]
fn an_export_served_by_nginx_renders_and_caches() {
    let dir = TempDir::new("nginx");
    // Under a path prefix, as on a static host's subdirectory: the page's URLs are relative.
    let site = dir.0.join("www/demo");
    let out = export(&["--out".as_ref(), site.as_os_str(), "--precompress".as_ref()]);
    assert!(out.status.success(), "export failed: {}", String::from_utf8_lossy(&out.stderr));
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(stdout.contains("exported 1 scene(s)"), "{stdout}");

    // The files: the page, the wasm, the list and the content-addressed bundle with its
    // precompressed siblings, each decoding to the bundle's bytes.
    for file in [
        "index.html",
        "main.js",
        "cache.js",
        "first_frame.js",
        "webgpu_recovery.js",
        "pkg/lightport_web.js",
        "pkg/lightport_web_bg.wasm",
    ] {
        assert!(site.join(file).is_file(), "{file} is missing");
    }
    let list: serde_json::Value = serde_json::from_slice(&std::fs::read(site.join("scenes.json")).unwrap()).unwrap();
    let scene = &list["scenes"][0];
    let (hash, url) = (scene["hash"].as_str().unwrap(), scene["url"].as_str().unwrap());
    assert_eq!(url, format!("bundles/{hash}.lpb"));
    let bundle = std::fs::read(site.join(url)).unwrap();
    assert_eq!(sha256_hex(&bundle), hash);
    assert_eq!(tracer::bundle::Bundle::decode(&bundle).unwrap().name, "cornell-box");
    let mut gunzipped = Vec::new();
    flate2::read::GzDecoder::new(&std::fs::read(site.join(format!("{url}.gz"))).unwrap()[..])
        .read_to_end(&mut gunzipped)
        .unwrap();
    assert_eq!(gunzipped, bundle);
    let mut unbrotlied = Vec::new();
    brotli::Decompressor::new(&std::fs::read(site.join(format!("{url}.br"))).unwrap()[..], 1 << 16)
        .read_to_end(&mut unbrotlied)
        .unwrap();
    assert_eq!(unbrotlied, bundle);

    let nginx = Nginx::start(&dir.0, &dir.0.join("www"));
    let port = nginx.port;
    // The headers docs/deploy.md asks for, as nginx sends them with docs/nginx.conf.
    let zipped = get(port, &format!("/demo/{url}"), &[("Accept-Encoding", "gzip")]);
    assert_eq!(zipped.status, 200);
    assert_eq!(zipped.header("cache-control"), Some("public, max-age=31536000, immutable"));
    assert_eq!(zipped.header("content-type"), Some("application/octet-stream"));
    assert_eq!(zipped.header("content-encoding"), Some("gzip"), "the precompressed file is served");
    assert_eq!(zipped.header("vary"), Some("Accept-Encoding"));
    let plain = get(port, &format!("/demo/{url}"), &[]);
    assert_eq!((plain.header("content-encoding"), plain.body.len()), (None, bundle.len()));
    for (path, ty) in [
        ("/demo/", "text/html; charset=utf-8"),
        ("/demo/scenes.json", "application/json"),
        ("/demo/main.js", "text/javascript"),
        ("/demo/pkg/lightport_web_bg.wasm", "application/wasm"),
    ] {
        let r = get(port, path, &[]);
        assert_eq!((r.status, r.header("content-type")), (200, Some(ty)), "{path}");
        assert_eq!(r.header("cache-control"), Some("no-cache"), "{path}");
        let etag = r.header("etag").unwrap_or_else(|| panic!("{path}: no ETag"));
        assert_eq!(get(port, path, &[("If-None-Match", etag)]).status, 304, "{path} revalidates");
    }

    let report =
        browse(&format!("http://127.0.0.1:{port}/demo/"), "cache", &[("scene", "cornell-box"), ("size", "16x16")]);
    let visit = |name: &str| {
        let v = &report[name];
        no_page_error(v);
        (v["bundleRequests"].as_array().expect("requests").len(), v["bytesFetched"].as_u64().expect("bytes"))
    };
    let (requests, bytes) = visit("first");
    assert_eq!(
        (requests, bytes),
        (1, bundle.len() as u64),
        "the first visit downloads the bundle: {}",
        report["first"]
    );
    assert!(report["first"]["sum"].as_f64().unwrap_or(0.0) > 0.0, "the page rendered the scene: {}", report["first"]);
    let (requests, bytes) = visit("second");
    assert_eq!((requests, bytes), (0, 0), "the second visit downloads no bundle bytes: {}", report["second"]);
    assert_eq!(report["second"]["sources"][0]["fromCache"], true);
    assert!(report["second"]["sum"].as_f64().unwrap_or(0.0) > 0.0, "rendered from the cache: {}", report["second"]);
}

#[test]
fn export_refuses_a_non_empty_directory_and_a_missing_wasm_build() {
    let dir = TempDir::new("refuse");
    std::fs::write(dir.0.join("keep.txt"), "mine").unwrap();
    let out = export(&["--out".as_ref(), dir.0.as_os_str()]);
    assert_eq!(out.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&out.stderr).contains("is not empty"), "{}", String::from_utf8_lossy(&out.stderr));
    assert_eq!(std::fs::read_to_string(dir.0.join("keep.txt")).unwrap(), "mine");

    let web = dir.0.join("web");
    std::fs::create_dir_all(web.join("www")).unwrap();
    std::fs::write(web.join("www/index.html"), "<!doctype html>").unwrap();
    let site = dir.0.join("site");
    let out = export(&["--out".as_ref(), site.as_os_str(), "--web".as_ref(), web.as_os_str()]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{stderr}");
    assert!(stderr.contains("scripts/build-web.sh"), "the error says what to run: {stderr}");
    assert!(!site.join("scenes.json").exists(), "nothing is written");
}

/// An installed binary (a copy far from the repository, run from another directory) serves and
/// exports the page built into it: the same bytes as web/www and web/pkg.
#[test]
fn an_installed_binary_serves_and_exports_its_built_in_page() {
    let repo = Path::new(env!("CARGO_MANIFEST_DIR"));
    let wasm = std::fs::read(repo.join("web/pkg/lightport_web_bg.wasm"))
        .expect("web/pkg/ is missing: run scripts/build-web.sh, then build lightport again (it embeds the page)");
    let index = std::fs::read(repo.join("web/www/index.html")).unwrap();
    let dir = TempDir::new("installed");
    let (bin, elsewhere) = (dir.0.join("bin"), dir.0.join("elsewhere"));
    std::fs::create_dir_all(&bin).unwrap();
    std::fs::create_dir_all(&elsewhere).unwrap();
    let exe = bin.join("lightport");
    std::fs::copy(env!("CARGO_BIN_EXE_lightport"), &exe).unwrap();

    let out = Command::new(&exe).current_dir(&elsewhere).args(["export", "--out", "site"]).output().unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    assert!(std::fs::read(elsewhere.join("site/pkg/lightport_web_bg.wasm")).unwrap() == wasm, "the exported wasm");
    assert_eq!(std::fs::read(elsewhere.join("site/index.html")).unwrap(), index);

    let mut server = serve_child::Killed::spawn_tied(
        Command::new(&exe)
            .current_dir(&elsewhere)
            .args(["serve", "--port", "0", "--exit-on-stdin-eof"])
            .stdout(std::process::Stdio::piped())
            .stderr(std::process::Stdio::piped()),
    )
    .unwrap();
    let stdout = server.child().stdout.take().unwrap();
    let mut stderr = server.child().stderr.take().unwrap();
    let line = std::io::BufRead::lines(std::io::BufReader::new(stdout))
        .map_while(Result::ok)
        .find(|l| l.starts_with("serving "))
        .expect("the server's URL line");
    let port: u16 = line.trim_end_matches('/').rsplit(':').next().unwrap().parse().unwrap();
    let page = get(port, "/", &[]);
    assert_eq!((page.status, page.body), (200, index));
    let served = get(port, "/pkg/lightport_web_bg.wasm", &[]);
    assert_eq!(served.header("content-type"), Some("application/wasm"));
    assert!(served.status == 200 && served.body == wasm, "the served wasm ({} bytes)", served.body.len());
    drop(server);
    let mut said = String::new();
    let _ = stderr.read_to_string(&mut said);
    assert!(!said.contains("warning"), "{said}");
}

/// `export` (and `serve`, which share the scene options) poses a scene as `render` does: the
/// bundle of an animated scene at `--time 0` differs from the one at `--time 1`, the Cornell
/// box's does not, and a time that is not a number is refused. The animated scene's bundle
/// carries its motion section (`tracer/src/bundle/motion.rs`).
#[test]
fn export_poses_the_scene_at_the_time_asked() {
    let scene = crate::common::test_data("scenes/generated/animated-skinned-instanced.gltf");
    let dir = TempDir::new("pose");
    let bundles_at = |time: &str| -> Vec<String> {
        let out_dir = dir.0.join(format!("t{time}"));
        let out = export(&[
            scene.as_os_str(),
            "--time".as_ref(),
            time.as_ref(),
            "--out".as_ref(),
            out_dir.as_os_str(),
            "--web".as_ref(),
            Path::new(env!("CARGO_MANIFEST_DIR")).join("web").as_os_str(),
        ]);
        assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
        let mut names: Vec<String> = std::fs::read_dir(out_dir.join("bundles"))
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        names.sort();
        // The moving scene's bundle carries its motion section, the Cornell box's none.
        let moving = names
            .iter()
            .map(|n| std::fs::read(out_dir.join("bundles").join(n)).unwrap())
            .filter(|b| tracer::bundle::Bundle::decode(b).unwrap().moving.is_some())
            .count();
        assert_eq!(moving, 1, "one bundle with a motion section: {names:?}");
        names
    };
    let (at_0, at_1) = (bundles_at("0"), bundles_at("1"));
    assert_eq!(at_0.len(), 2, "the Cornell box and the scene: {at_0:?}");
    let same: Vec<&String> = at_0.iter().filter(|b| at_1.contains(b)).collect();
    assert_eq!(same.len(), 1, "only the Cornell box's bundle is the same at both times: {at_0:?} {at_1:?}");
    let out = export(&[
        scene.as_os_str(),
        "--time".as_ref(),
        "NaN".as_ref(),
        "--out".as_ref(),
        dir.0.join("nan").as_os_str(),
    ]);
    assert_eq!(out.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&out.stderr).contains("--time"), "{}", String::from_utf8_lossy(&out.stderr));
}
