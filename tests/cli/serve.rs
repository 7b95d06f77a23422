//! `lightport serve` end to end: the real binary on a free port of 127.0.0.1, spoken to over
//! raw TCP (so malformed, oversized, slow and concurrent requests can be sent as they are).
//!
//! One server is shared by the tests that only read (it takes a few seconds to start); each
//! test's traffic is bounded in count and time.

use crate::common;

use std::io::{BufRead, BufReader, Read, Write};
use std::net::TcpStream;
use std::path::PathBuf;
use std::process::{Child, ChildStdin, Command, Stdio};
use std::sync::{mpsc, Arc, Mutex, OnceLock};
use std::time::{Duration, Instant};

/// The server's --timeout in these tests (seconds): short, so the slow-client test is quick.
const SERVER_TIMEOUT_S: u64 = 2;

/// A scene of the vendored test data (`rel` relative to `tests/data/scenes/`), as the command
/// line takes it.
fn scene_path(rel: &str) -> String {
    common::test_data(&format!("scenes/{rel}")).to_str().expect("a UTF-8 path").to_owned()
}

struct Server {
    child: Child,
    /// The server's stdin (`--exit-on-stdin-eof`): the kernel closes it when this test binary
    /// ends, however it ends, and the server exits then, also the one in a `static`, which is
    /// never dropped.
    lifeline: Option<ChildStdin>,
    port: u16,
    /// The page directory given to the server (kept alive as long as the server).
    _web: TempDir,
    stderr: Arc<Mutex<String>>,
    /// What it printed on stdout before the URL (the table of scenes).
    startup: Vec<String>,
}

impl Server {
    /// Waits (up to 10 s) for `needle` on the server's stderr: it is printed before the URL, but
    /// read by another thread.
    fn stderr_contains(&self, needle: &str) -> bool {
        let deadline = Instant::now() + Duration::from_secs(10);
        while Instant::now() < deadline {
            if self.stderr.lock().unwrap().contains(needle) {
                return true;
            }
            std::thread::sleep(Duration::from_millis(20));
        }
        false
    }
}

impl Drop for Server {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// A directory removed on drop.
struct TempDir(PathBuf);

impl TempDir {
    fn new(tag: &str) -> TempDir {
        let nanos = std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH).unwrap().subsec_nanos();
        let dir = std::env::temp_dir().join(format!("lightport-serve-{tag}-{}-{nanos}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        TempDir(dir)
    }
}

impl Drop for TempDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

/// A page tree like the real one, plus things that must not be served: a file outside `www/`,
/// a hidden file, and a symbolic link pointing outside.
fn web_dir(with_pkg: bool) -> TempDir {
    let web = TempDir::new("web");
    let www = web.0.join("www");
    std::fs::create_dir_all(www.join("js")).unwrap();
    std::fs::write(www.join("index.html"), "<!doctype html><title>lightport</title>").unwrap();
    std::fs::write(www.join("js/app.js"), "export const answer = 42;\n".repeat(50)).unwrap();
    std::fs::write(www.join(".secret"), "hidden").unwrap();
    std::fs::write(web.0.join("outside.txt"), "not an asset").unwrap();
    #[cfg(unix)]
    std::os::unix::fs::symlink(web.0.join("outside.txt"), www.join("link.txt")).unwrap();
    if with_pkg {
        std::fs::create_dir_all(web.0.join("pkg")).unwrap();
        // The wasm magic and version, then filler.
        let mut wasm = b"\0asm\x01\0\0\0".to_vec();
        wasm.extend(std::iter::repeat_n(0u8, 1000));
        std::fs::write(web.0.join("pkg/web_bg.wasm"), wasm).unwrap();
        std::fs::write(web.0.join("pkg/web.js"), "export default function init() {}\n").unwrap();
    }
    web
}

/// Starts `lightport serve ARGS --port 0` and waits for the URL line (or the exit).
fn start(args: &[&str], web: TempDir) -> Result<Server, (Option<i32>, String)> {
    let mut child = Command::new(env!("CARGO_BIN_EXE_lightport"))
        .arg("serve")
        .args(args)
        .args(["--port", "0", "--timeout", &SERVER_TIMEOUT_S.to_string(), "--exit-on-stdin-eof", "--web"])
        .arg(&web.0)
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("start lightport");
    let lifeline = child.stdin.take().unwrap();
    let (tx, rx) = mpsc::channel();
    let stdout = child.stdout.take().unwrap();
    std::thread::spawn(move || {
        for line in BufReader::new(stdout).lines().map_while(Result::ok) {
            let _ = tx.send(line);
        }
    });
    // Everything printed on stderr so far (the pipe stays open while the server runs).
    let stderr = Arc::new(Mutex::new(String::new()));
    let mut stderr_pipe = child.stderr.take().unwrap();
    let sink = Arc::clone(&stderr);
    let stderr_reader = std::thread::spawn(move || {
        let mut buf = [0u8; 4096];
        while let Ok(n) = stderr_pipe.read(&mut buf) {
            if n == 0 {
                break;
            }
            sink.lock().unwrap().push_str(&String::from_utf8_lossy(&buf[..n]));
        }
    });
    // After the exit, the reader ends at the pipe's end: all of stderr is there.
    let exited = |child: &mut Child, reader: std::thread::JoinHandle<()>, stderr: &Mutex<String>| {
        let status = child.wait().unwrap();
        reader.join().unwrap();
        Err((status.code(), stderr.lock().unwrap().clone()))
    };
    let deadline = Instant::now() + Duration::from_secs(120);
    let mut startup = Vec::new();
    loop {
        match rx.recv_timeout(Duration::from_millis(100)) {
            Ok(line) => {
                if let Some(rest) = line.strip_prefix("serving ") {
                    let url = rest.rsplit(' ').next().unwrap();
                    let port = url.trim_end_matches('/').rsplit(':').next().unwrap().parse().unwrap();
                    return Ok(Server { child, lifeline: Some(lifeline), port, _web: web, stderr, startup });
                }
                startup.push(line);
            }
            Err(mpsc::RecvTimeoutError::Timeout) => {}
            Err(mpsc::RecvTimeoutError::Disconnected) => return exited(&mut child, stderr_reader, &stderr),
        }
        if let Ok(Some(_)) = child.try_wait() {
            return exited(&mut child, stderr_reader, &stderr);
        }
        assert!(Instant::now() < deadline, "the server did not start within 120 s");
    }
}

/// The server with the Cornell box and a textured scene, shared by the read-only tests.
fn server() -> &'static Server {
    static SERVER: OnceLock<Server> = OnceLock::new();
    SERVER.get_or_init(|| {
        let textured = scene_path("khronos/BoxTextured/glTF-Binary/BoxTextured.glb");
        start(&[&textured], web_dir(true)).unwrap_or_else(|(code, err)| panic!("serve exited ({code:?}): {err}"))
    })
}

#[derive(Debug)]
struct Response {
    status: u16,
    headers: Vec<(String, String)>,
    body: Vec<u8>,
}

impl Response {
    fn header(&self, name: &str) -> Option<&str> {
        self.headers.iter().find(|(n, _)| n.eq_ignore_ascii_case(name)).map(|(_, v)| v.as_str())
    }
}

fn connect(port: u16) -> TcpStream {
    let s = TcpStream::connect(("127.0.0.1", port)).unwrap();
    s.set_read_timeout(Some(Duration::from_secs(30))).unwrap();
    s
}

/// Reads one response; `head_only` for answers to HEAD (a Content-Length but no body).
fn read_response(reader: &mut BufReader<TcpStream>, head_only: bool) -> Response {
    let mut line = String::new();
    reader.read_line(&mut line).unwrap();
    let status = line.split(' ').nth(1).unwrap_or_else(|| panic!("bad status line {line:?}")).parse().unwrap();
    let mut headers = Vec::new();
    loop {
        let mut h = String::new();
        reader.read_line(&mut h).unwrap();
        let h = h.trim_end();
        if h.is_empty() {
            break;
        }
        let (n, v) = h.split_once(':').unwrap();
        headers.push((n.trim().to_string(), v.trim().to_string()));
    }
    let mut r = Response { status, headers, body: Vec::new() };
    let len: usize = r.header("content-length").map_or(0, |v| v.parse().unwrap());
    if !head_only && status != 304 {
        r.body.resize(len, 0);
        reader.read_exact(&mut r.body).unwrap();
    }
    r
}

/// Sends raw bytes on a fresh connection and reads one response.
fn raw(port: u16, request: &[u8]) -> Response {
    let mut s = connect(port);
    s.write_all(request).unwrap();
    let head_only = request.starts_with(b"HEAD ");
    read_response(&mut BufReader::new(s), head_only)
}

fn get(port: u16, path: &str, headers: &[(&str, &str)]) -> Response {
    let mut req = format!("GET {path} HTTP/1.1\r\nHost: 127.0.0.1\r\nConnection: close\r\n");
    for (n, v) in headers {
        req.push_str(&format!("{n}: {v}\r\n"));
    }
    req.push_str("\r\n");
    raw(port, req.as_bytes())
}

fn scenes_json(port: u16) -> serde_json::Value {
    let r = get(port, "/scenes.json", &[]);
    assert_eq!(r.status, 200);
    serde_json::from_slice(&r.body).unwrap()
}

fn gunzip(bytes: &[u8]) -> Vec<u8> {
    let mut out = Vec::new();
    flate2::read::GzDecoder::new(bytes).read_to_end(&mut out).unwrap();
    out
}

fn sha256_hex(bytes: &[u8]) -> String {
    use sha2::Digest;
    sha2::Sha256::digest(bytes).iter().map(|b| format!("{b:02x}")).collect()
}

#[test]
fn serves_the_page_and_the_wasm_with_their_content_types() {
    let s = server();
    for (path, ty) in [
        ("/", "text/html; charset=utf-8"),
        ("/index.html", "text/html; charset=utf-8"),
        ("/js/app.js", "text/javascript"),
        ("/pkg/web.js", "text/javascript"),
        ("/pkg/web_bg.wasm", "application/wasm"),
        ("/scenes.json", "application/json"),
    ] {
        let r = get(s.port, path, &[]);
        assert_eq!((r.status, r.header("content-type")), (200, Some(ty)), "{path}");
        assert_eq!(r.header("cache-control"), Some("no-cache"), "{path}");
        assert!(r.header("etag").is_some(), "{path}");
    }
    let wasm = get(s.port, "/pkg/web_bg.wasm", &[]);
    assert!(wasm.body.starts_with(b"\0asm"), "uncompressed when gzip is not accepted");
    assert!(s.stderr_contains("not serving"), "skipped files are reported: {}", s.stderr.lock().unwrap());
}

#[test]
fn traversal_and_unknown_paths_are_404() {
    let s = server();
    for path in [
        "/../outside.txt",
        "/js/../../outside.txt",
        "/%2e%2e/outside.txt",
        "/%2E%2E%2Foutside.txt",
        "/js/%2e%2e/index.html",
        "/..%5coutside.txt",
        "/js\\..\\index.html",
        "\\index.html",
        "//etc/passwd",
        "/etc/passwd",
        "/web/outside.txt",
        "/outside.txt",
        "/.secret",
        "/link.txt",
        "/js",
        "/js/",
        "/pkg/",
        "/bundles/",
        "/bundles/0000000000000000000000000000000000000000000000000000000000000000.lpb",
        "/index.html%00.js",
        "/no-such-file.html",
        "*",
        "index.html",
    ] {
        let r = raw(s.port, format!("GET {path} HTTP/1.1\r\nHost: x\r\nConnection: close\r\n\r\n").as_bytes());
        // hyper refuses a target that starts with a backslash as malformed (no URI form allows
        // it); the others parse and are looked up, in vain.
        let expected = if path.starts_with('\\') { 400 } else { 404 };
        assert_eq!(r.status, expected, "{path}");
        assert!(!String::from_utf8_lossy(&r.body).contains("not an asset"), "{path} leaked a file");
    }
    // A query string does not change the route.
    assert_eq!(get(s.port, "/index.html?v=1", &[]).status, 200);
}

#[test]
fn only_get_and_head_are_allowed() {
    let s = server();
    for method in ["POST", "PUT", "DELETE", "OPTIONS", "PATCH", "TRACE", "BREW"] {
        let r =
            raw(s.port, format!("{method} /index.html HTTP/1.1\r\nHost: x\r\nContent-Length: 0\r\n\r\n").as_bytes());
        assert_eq!((r.status, r.header("allow")), (405, Some("GET, HEAD")), "{method}");
    }
    let head = raw(s.port, b"HEAD /index.html HTTP/1.1\r\nHost: x\r\nConnection: close\r\n\r\n");
    let get = get(s.port, "/index.html", &[]);
    assert_eq!(head.status, 200);
    assert_eq!(head.header("content-length"), get.header("content-length"));
    assert!(head.body.is_empty());
}

#[test]
fn oversized_and_malformed_requests_are_refused() {
    let s = server();
    let long_header = format!("GET / HTTP/1.1\r\nHost: x\r\nX-Filler: {}\r\n\r\n", "a".repeat(20_000));
    assert_eq!(raw(s.port, long_header.as_bytes()).status, 431);
    let long_path = format!("GET /{} HTTP/1.1\r\nHost: x\r\n\r\n", "a".repeat(20_000));
    assert_eq!(raw(s.port, long_path.as_bytes()).status, 431);
    let many: String = (0..100).map(|i| format!("X-H{i}: v\r\n")).collect();
    assert_eq!(raw(s.port, format!("GET / HTTP/1.1\r\nHost: x\r\n{many}\r\n").as_bytes()).status, 431);
    assert_eq!(raw(s.port, b"GET / HTTP/1.1\r\nHost: x\r\nContent-Length: 100000000\r\n\r\n").status, 413);
    assert_eq!(raw(s.port, b"POST / HTTP/1.1\r\nHost: x\r\nContent-Length: 5000\r\n\r\n").status, 413);
    assert_eq!(raw(s.port, b"GET / HTTP/1.1\r\nHost: x\r\nTransfer-Encoding: chunked\r\n\r\n").status, 411);
    assert_eq!(raw(s.port, b"GET / HTTP/1.1\r\nHost: x\r\nContent-Length: -1\r\n\r\n").status, 400);
    assert_eq!(raw(s.port, b"\x16\x03\x01\x02\x00 not http\r\n\r\n").status, 400);
    // A small body is read and dropped; the request is answered.
    let r = raw(s.port, b"GET /index.html HTTP/1.1\r\nHost: x\r\nConnection: close\r\nContent-Length: 5\r\n\r\nhello");
    assert_eq!(r.status, 200);
}

#[test]
fn a_slow_client_is_cut_off_and_does_not_block_others() {
    let s = server();
    let start = Instant::now();
    let mut slow = connect(s.port);
    slow.write_all(b"GET /index.html HTTP/1.1\r\nHost: x\r\n").unwrap();
    // Others are served meanwhile.
    assert_eq!(get(s.port, "/index.html", &[]).status, 200);
    // The head never completes: the connection is closed after the server's timeout, without an
    // answer (hyper has no automatic response to a header timeout), and a trickle of header
    // lines, one every 250 ms for as long as the connection lasts, does not extend it.
    slow.set_read_timeout(Some(Duration::from_millis(250))).unwrap();
    let mut answer = Vec::new();
    let closed = loop {
        let mut buf = [0u8; 256];
        match slow.read(&mut buf) {
            Ok(0) => break true,
            Ok(n) => answer.extend_from_slice(&buf[..n]),
            Err(e) if matches!(e.kind(), std::io::ErrorKind::WouldBlock | std::io::ErrorKind::TimedOut) => {}
            Err(_) => break true,
        }
        if start.elapsed() > Duration::from_secs(SERVER_TIMEOUT_S + 20) {
            break false;
        }
        let _ = slow.write_all(b"X-Trickle: 1\r\n");
    };
    let waited = start.elapsed();
    assert!(closed, "a trickling client was still connected after {waited:?}");
    assert!(waited >= Duration::from_secs(SERVER_TIMEOUT_S), "cut off before the timeout: {waited:?}");
    assert!(answer.is_empty(), "answered {:?}", String::from_utf8_lossy(&answer));
    // An idle connection is closed silently after the timeout.
    let mut idle = connect(s.port);
    let mut buf = [0u8; 16];
    assert_eq!(idle.read(&mut buf).unwrap_or(0), 0);
}

#[test]
fn keep_alive_serves_several_requests_on_one_connection() {
    let s = server();
    let mut stream = connect(s.port);
    // Two pipelined requests and then a third after the answers.
    stream.write_all(b"GET /index.html HTTP/1.1\r\nHost: x\r\n\r\nGET /js/app.js HTTP/1.1\r\nHost: x\r\n\r\n").unwrap();
    let mut reader = BufReader::new(stream.try_clone().unwrap());
    assert_eq!(read_response(&mut reader, false).header("content-type"), Some("text/html; charset=utf-8"));
    assert_eq!(read_response(&mut reader, false).header("content-type"), Some("text/javascript"));
    stream.write_all(b"GET /scenes.json HTTP/1.1\r\nHost: x\r\nConnection: close\r\n\r\n").unwrap();
    let last = read_response(&mut reader, false);
    assert_eq!((last.status, last.header("connection")), (200, Some("close")));
}

#[test]
fn scenes_json_lists_content_addressed_bundles() {
    let s = server();
    let list = scenes_json(s.port);
    assert_eq!(list["bundle_version"], tracer::bundle::VERSION);
    let scenes = list["scenes"].as_array().unwrap();
    let names: Vec<&str> = scenes.iter().map(|s| s["name"].as_str().unwrap()).collect();
    assert_eq!(names, ["cornell-box", "BoxTextured"]);
    assert_eq!(scenes[0]["triangles"], 36);
    assert_eq!(scenes[0]["features"]["emissive_triangles"], true);
    assert_eq!(scenes[1]["features"]["textures"], true);
    // The Cornell box has its light; nothing lights BoxTextured, so it gets the default sky,
    // and the page is told why (it shows the warnings when it loads the scene).
    assert_eq!((&scenes[0]["features"]["sky"], &scenes[0]["warnings"]), (&false.into(), &serde_json::json!([])));
    assert_eq!(scenes[1]["features"]["sky"], true);
    let warnings = scenes[1]["warnings"].as_array().unwrap();
    assert!(
        warnings.len() == 1 && warnings[0].as_str().unwrap().contains("lit by a uniform white sky"),
        "{warnings:?}"
    );
    for scene in scenes {
        let hash = scene["hash"].as_str().unwrap();
        // Relative to /scenes.json, so that an exported site works under any path.
        assert_eq!(scene["url"].as_str().unwrap(), format!("bundles/{hash}.lpb"));
        let r = get(s.port, &format!("/{}", scene["url"].as_str().unwrap()), &[]);
        assert_eq!(r.status, 200);
        assert_eq!(r.header("content-encoding"), None, "no Accept-Encoding: identity");
        assert_eq!(r.body.len() as u64, scene["bytes"]["raw"].as_u64().unwrap());
        assert_eq!(sha256_hex(&r.body), hash, "the name is the hash of the bytes");
        let bundle = tracer::bundle::Bundle::decode(&r.body).unwrap();
        assert_eq!(bundle.name, scene["name"].as_str().unwrap());
        assert_eq!(bundle.packed.triangle_count as u64, scene["triangles"].as_u64().unwrap());
    }
}

#[test]
fn bundles_are_immutable_gzip_and_revalidate_with_etags() {
    let s = server();
    let list = scenes_json(s.port);
    let scene = &list["scenes"][1];
    let url = &format!("/{}", scene["url"].as_str().unwrap());
    let hash = scene["hash"].as_str().unwrap();

    let plain = get(s.port, url, &[("Accept-Encoding", "br;q=1, identity")]);
    let zipped = get(s.port, url, &[("Accept-Encoding", "gzip, deflate, br")]);
    for r in [&plain, &zipped] {
        assert_eq!(r.status, 200);
        assert_eq!(r.header("cache-control"), Some("public, max-age=31536000, immutable"));
        assert_eq!(r.header("content-type"), Some("application/octet-stream"));
        assert_eq!(r.header("vary"), Some("Accept-Encoding"));
    }
    assert_eq!(plain.header("content-encoding"), None);
    assert_eq!(plain.header("etag"), Some(format!("\"{hash}\"").as_str()));
    assert_eq!(zipped.header("content-encoding"), Some("gzip"));
    assert_eq!(zipped.body.len() as u64, scene["bytes"]["gzip"].as_u64().unwrap());
    assert!(zipped.body.len() < plain.body.len());
    assert_eq!(gunzip(&zipped.body), plain.body);
    assert_eq!(get(s.port, url, &[("Accept-Encoding", "gzip;q=0")]).header("content-encoding"), None);

    // Either representation's ETag (strong or weak) revalidates; another does not.
    for tag in [plain.header("etag").unwrap(), zipped.header("etag").unwrap(), &format!("W/\"{hash}\""), "*"] {
        let r = get(s.port, url, &[("If-None-Match", tag), ("Accept-Encoding", "gzip")]);
        assert_eq!(r.status, 304, "{tag}");
        assert!(r.body.is_empty());
        assert_eq!(r.header("cache-control"), Some("public, max-age=31536000, immutable"));
    }
    assert_eq!(get(s.port, url, &[("If-None-Match", "\"something-else\"")]).status, 200);
    let page = get(s.port, "/index.html", &[]);
    assert_eq!(get(s.port, "/index.html", &[("If-None-Match", page.header("etag").unwrap())]).status, 304);
}

#[test]
fn many_concurrent_clients_are_all_served() {
    let s = server();
    let list = scenes_json(s.port);
    let url = format!("/{}", list["scenes"][0]["url"].as_str().unwrap());
    let expected_len = list["scenes"][0]["bytes"]["raw"].as_u64().unwrap() as usize;
    let port = s.port;
    let clients: Vec<_> = (0..64)
        .map(|i| {
            let url = url.clone();
            std::thread::spawn(move || {
                // A mix of bundles (plain and gzip), the page and unknown paths.
                match i % 4 {
                    0 => {
                        let r = get(port, &url, &[]);
                        r.status == 200 && r.body.len() == expected_len
                    }
                    1 => {
                        let r = get(port, &url, &[("Accept-Encoding", "gzip")]);
                        r.status == 200 && gunzip(&r.body).len() == expected_len
                    }
                    2 => get(port, "/pkg/web_bg.wasm", &[]).status == 200,
                    _ => get(port, "/nope", &[]).status == 404,
                }
            })
        })
        .collect();
    let ok = clients.into_iter().map(|c| c.join()).filter(|r| matches!(r, Ok(true))).count();
    assert_eq!(ok, 64, "every client gets a correct answer");
}

/// Expects `serve ARGS` to refuse to start, naming `expect` on stderr.
fn refuses(args: &[&str], expect: &[&str]) {
    match start(args, web_dir(true)) {
        Ok(s) => panic!("served anyway: {}", s.stderr.lock().unwrap()),
        Err((code, stderr)) => {
            assert_eq!(code, Some(1), "{stderr}");
            for e in expect {
                assert!(stderr.contains(e), "stderr lacks {e:?}:\n{stderr}");
            }
        }
    }
}

#[test]
fn missing_or_malformed_scenes_stop_the_server_at_start() {
    let dir = TempDir::new("bad-scenes");
    let broken = dir.0.join("broken.gltf");
    std::fs::write(&broken, "{ this is not json").unwrap();
    let missing = dir.0.join("missing.glb");
    let good = scene_path("khronos/Box/glTF-Binary/Box.glb");
    let (broken, missing) = (broken.to_str().unwrap(), missing.to_str().unwrap());
    refuses(&[missing], &["missing.glb", "1 of 2 scene(s) failed to load"]);
    // Every failure is reported, even next to scenes that load.
    refuses(&[&good, broken, missing], &["broken.gltf", "missing.glb", "2 of 4 scene(s) failed to load"]);
    refuses(&["--sky", missing], &["loading sky"]);
}

#[test]
fn strict_refuses_scenes_with_warnings() {
    // A base colour image that is not there; a scene with no emissive material and no sky.
    let missing_texture = scene_path("missing-texture/MissingTexture.gltf");
    let unlit = scene_path("khronos/Box/glTF-Binary/Box.glb");
    refuses(&["--strict", &missing_texture], &["Label_baseColor.png", "1 of 2 scene(s) failed to load"]);
    refuses(&["--strict", &unlit], &["nothing lights the scene", "--sky", "1 of 2 scene(s) failed to load"]);
}

#[test]
fn a_missing_wasm_build_is_reported_with_the_command_that_builds_it() {
    let s = start(&[], web_dir(false)).unwrap_or_else(|(code, err)| panic!("serve exited ({code:?}): {err}"));
    assert!(s.stderr_contains("scripts/build-web.sh"), "{}", s.stderr.lock().unwrap());
    assert_eq!(get(s.port, "/pkg/web_bg.wasm", &[]).status, 404);
    assert_eq!(get(s.port, "/scenes.json", &[]).status, 200);
}

#[test]
fn names_are_unique_and_start_up_prints_the_sizes() {
    let a = scene_path("khronos/Box/glTF-Binary/Box.glb");
    let b = scene_path("khronos/Box/glTF/Box.gltf");
    let s = start(&[&a, &b], web_dir(true)).unwrap_or_else(|(code, err)| panic!("serve exited ({code:?}): {err}"));
    let list = scenes_json(s.port);
    let names: Vec<&str> = list["scenes"].as_array().unwrap().iter().map(|s| s["name"].as_str().unwrap()).collect();
    assert_eq!(names, ["cornell-box", "Box", "Box-2"]);
    // The same content gives the same bundle except for its name: different hashes.
    assert_ne!(list["scenes"][1]["hash"], list["scenes"][2]["hash"]);
    // One table row per scene: name, triangles, raw and gzip bytes as served.
    for scene in list["scenes"].as_array().unwrap() {
        let row = s.startup.iter().find(|l| l.split_whitespace().next() == scene["name"].as_str());
        let row: Vec<&str> =
            row.unwrap_or_else(|| panic!("no row for {scene}: {:?}", s.startup)).split_whitespace().collect();
        assert_eq!(
            row[1..4],
            [&scene["triangles"], &scene["bytes"]["raw"], &scene["bytes"]["gzip"]].map(|v| v.to_string())
        );
    }
}

#[test]
fn the_server_exits_when_its_parent_ends() {
    let mut s = start(&[], web_dir(false)).unwrap_or_else(|(code, err)| panic!("serve exited ({code:?}): {err}"));
    // What the kernel does to the pipe when this process ends, however it ends.
    drop(s.lifeline.take());
    let deadline = Instant::now() + Duration::from_secs(10);
    loop {
        if let Some(status) = s.child.try_wait().unwrap() {
            assert!(status.success(), "{status}");
            break;
        }
        assert!(Instant::now() < deadline, "the server still runs 10 s after its stdin closed");
        std::thread::sleep(Duration::from_millis(50));
    }
    assert!(s.stderr_contains("stdin closed"), "{}", s.stderr.lock().unwrap());
}

#[test]
fn sigterm_lets_the_request_in_progress_finish() {
    let mut s = start(&[], web_dir(false)).unwrap_or_else(|(code, err)| panic!("serve exited ({code:?}): {err}"));
    // A request in progress: its declared body is still arriving when the signal comes.
    let mut stream = connect(s.port);
    stream.write_all(b"GET /scenes.json HTTP/1.1\r\nHost: x\r\nContent-Length: 5\r\n\r\nhe").unwrap();
    std::thread::sleep(Duration::from_millis(200));
    let kill = Command::new("kill").args(["-TERM", &s.child.id().to_string()]).status().expect("kill");
    assert!(kill.success());
    assert!(s.stderr_contains("SIGTERM: shutting down"), "{}", s.stderr.lock().unwrap());
    // No new connections once shutting down.
    let deadline = Instant::now() + Duration::from_secs(5);
    while TcpStream::connect(("127.0.0.1", s.port)).is_ok() {
        assert!(Instant::now() < deadline, "still accepting connections after SIGTERM");
        std::thread::sleep(Duration::from_millis(50));
    }
    // The request in progress is answered in full, and its connection then closed.
    stream.write_all(b"llo").unwrap();
    let mut reader = BufReader::new(stream);
    let r = read_response(&mut reader, false);
    assert_eq!(r.status, 200);
    assert!(serde_json::from_slice::<serde_json::Value>(&r.body).is_ok(), "the whole scene list");
    let mut rest = Vec::new();
    assert_eq!(reader.read_to_end(&mut rest).unwrap_or(0), 0, "closed after the answer");
    let deadline = Instant::now() + Duration::from_secs(10);
    let status = loop {
        if let Some(status) = s.child.try_wait().unwrap() {
            break status;
        }
        assert!(Instant::now() < deadline, "the server still runs 10 s after SIGTERM");
        std::thread::sleep(Duration::from_millis(50));
    };
    assert!(status.success(), "{status}");
}
