//! The browser runtimes of the harness: WebGL2 and WebGPU in headless Chromium, as [`Runtime`]s
//! driven from native code.
//!
//! The page (`web/www/harness.html`, `harness.js`) runs the `lightport-web` wasm module, whose
//! `HarnessRuntime` (`web/src/harness.rs`) is the REAL [`GlHarness`](super::GlHarness) on a
//! WebGL2 context and the real [`WgpuHarness`](super::WgpuHarness) on a WebGPU device, over a
//! [`Program`] linked from the same IR modules the native runtimes use (sent as JSON): the
//! shaders, layouts and scene bindings are exactly the native ones. A node driver
//! (`tests/web/harness.mjs`: npm `playwright-core`, Debian's `/usr/bin/chromium` with the flags
//! of DESIGN.md plus `--enable-unsafe-webgpu`) serves the page on `http://127.0.0.1` (a secure
//! context, which WebGPU needs) and relays requests: one JSON line per request on its stdin, one
//! `@lp `-prefixed JSON line per reply on its stdout, words as base64 of their little-endian
//! bytes.
//!
//! - One Chromium per process: [`BrowserSession::shared`] starts it on first use; every
//!   runtime of every test in the binary talks to its page, one request at a time.
//! - It dies with the process: the driver exits when its stdin (a pipe only this process holds)
//!   ends, closing the browser, however this process ends.
//! - A hung page gives up: a request without a reply within [`BrowserOptions::deadline`] ends
//!   the driver and is an error, as is every later request on that session.
//! - Bad replies (not JSON, wrong word counts, an error from the page) are
//!   [`HarnessError::Browser`], never panics.

use std::collections::{BTreeMap, HashMap};
use std::io::{BufRead, BufReader, Write};
use std::path::{Path, PathBuf};
use std::process::{Child, ChildStdin, Command, Stdio};
use std::sync::mpsc::{Receiver, RecvTimeoutError};
use std::sync::{Arc, Mutex, OnceLock};
use std::time::{Duration, Instant};

use base64::engine::general_purpose::STANDARD as BASE64;
use base64::Engine;
use lightport_codegen::{Program, Target};
use serde_json::{json, Value};

use super::{encode_resources, encode_scene, generated_layout, harness_selection, Backend, HarnessError, Runtime};
use crate::kernel::denoise::FilterImage;
use crate::kernel::scene_data::Scene;
use crate::kernel::ShaderError;
use glam::Vec4;

/// Where the driver, the page and the browser are, and how long to wait for them.
#[derive(Clone, Debug)]
pub struct BrowserOptions {
    /// The repository root (holding `tests/web/harness.mjs`, `web/www/` and `web/pkg/`).
    pub root: PathBuf,
    pub node: PathBuf,
    pub chromium: PathBuf,
    /// The longest one request may take (a shader compile, a run) before the session gives up.
    pub deadline: Duration,
    /// The longest the browser may take to start and load the page.
    pub startup: Duration,
}

impl Default for BrowserOptions {
    /// The repository this crate is in; `LIGHTPORT_BROWSER_DEADLINE` (seconds) overrides the
    /// 600 s request deadline.
    fn default() -> Self {
        let deadline = std::env::var("LIGHTPORT_BROWSER_DEADLINE").ok().and_then(|s| s.parse().ok()).unwrap_or(600);
        BrowserOptions {
            root: Path::new(env!("CARGO_MANIFEST_DIR")).join(".."),
            node: "node".into(),
            chromium: std::env::var_os("CHROMIUM").map_or_else(|| "/usr/bin/chromium".into(), PathBuf::from),
            deadline: Duration::from_secs(deadline),
            startup: Duration::from_secs(180),
        }
    }
}

/// A wrong reply to inject, to see the checks on the browser's replies fail (tests).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Corruption {
    /// The page flips the lowest bit of this output word of the next run's reply.
    FlipWord(usize),
    /// The driver drops the last word of the next run's reply.
    DropLastWord,
    /// The driver answers the next run with a line that is not JSON.
    NotJson,
    /// The page never answers the next run (a hung page).
    Hang,
}

struct Driver {
    child: Child,
    stdin: Option<ChildStdin>,
    replies: Receiver<String>,
}

impl Drop for Driver {
    /// Closes the driver's stdin (it closes the browser and exits), then kills it if it has not
    /// exited within 10 s.
    fn drop(&mut self) {
        drop(self.stdin.take());
        let deadline = Instant::now() + Duration::from_secs(10);
        while Instant::now() < deadline {
            if let Ok(Some(_)) = self.child.try_wait() {
                return;
            }
            std::thread::sleep(Duration::from_millis(20));
        }
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// One headless Chromium with the harness page, and its node driver.
pub struct BrowserSession {
    /// The driver, or why this session stopped.
    driver: Mutex<Result<Driver, String>>,
    deadline: Duration,
    /// What the page reported at start (user agent).
    pub info: String,
}

static SHARED: OnceLock<Result<Arc<BrowserSession>, String>> = OnceLock::new();

impl BrowserSession {
    /// The session every runtime of this process shares, started on first use (never dropped:
    /// it ends with the process, see the module docs).
    pub fn shared() -> Result<Arc<BrowserSession>, HarnessError> {
        let session = SHARED.get_or_init(|| BrowserSession::start(&BrowserOptions::default()).map(Arc::new));
        session.clone().map_err(|detail| HarnessError::Browser { backend: Backend::WebGl2, detail })
    }

    /// Starts the driver and waits until the page is ready. Never skipped: a missing piece is
    /// an error naming the command that installs it.
    pub fn start(options: &BrowserOptions) -> Result<BrowserSession, String> {
        let web_tests = options.root.join("tests/web");
        let missing = [
            (
                web_tests.join("node_modules/playwright-core"),
                "tests/web/node_modules is missing: run `npm ci` in tests/web",
            ),
            (options.root.join("web/pkg/lightport_web_bg.wasm"), "web/pkg/ is missing: run scripts/build-web.sh"),
            (options.chromium.clone(), "Chromium is missing: apt-get install chromium"),
        ];
        if let Some((_, message)) = missing.iter().find(|(path, _)| !path.exists()) {
            return Err(message.to_string());
        }
        let mut child = Command::new(&options.node)
            .current_dir(&web_tests)
            .arg("harness.mjs")
            .arg("--root")
            .arg(&options.root)
            .env("CHROMIUM", &options.chromium)
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .spawn()
            .map_err(|e| format!("starting `node tests/web/harness.mjs` (apt-get install nodejs npm): {e}"))?;
        let stdin = child.stdin.take();
        let stdout = child.stdout.take().ok_or("the driver's stdout")?;
        let (sender, replies) = std::sync::mpsc::channel();
        std::thread::spawn(move || {
            for line in BufReader::new(stdout).lines().map_while(Result::ok) {
                match line.strip_prefix("@lp ") {
                    Some(reply) => {
                        if sender.send(reply.to_string()).is_err() {
                            break;
                        }
                    }
                    None => eprintln!("harness.mjs: {line}"),
                }
            }
        });
        let mut driver = Driver { child, stdin, replies };
        let ready = receive(&mut driver, options.startup, "starting the browser")?;
        match serde_json::from_str::<Value>(&ready) {
            Ok(v) if v["ok"] == true => Ok(BrowserSession {
                driver: Mutex::new(Ok(driver)),
                deadline: options.deadline,
                info: v["userAgent"].as_str().unwrap_or_default().to_string(),
            }),
            Ok(v) => Err(format!("the harness page did not start: {}", v["error"])),
            Err(e) => Err(format!("the driver's first line is not JSON ({e}): {ready}")),
        }
    }

    /// Sends one request and returns its reply's fields (`ok` true), or the error.
    fn request(&self, backend: Backend, request: &Value) -> Result<Value, HarnessError> {
        let error = |detail: String| HarnessError::Browser { backend, detail };
        let op = request["op"].as_str().unwrap_or("?").to_string();
        let mut slot = self.driver.lock().unwrap_or_else(|p| p.into_inner());
        let driver = match &mut *slot {
            Ok(driver) => driver,
            Err(why) => return Err(error(format!("the browser session ended earlier: {why}"))),
        };
        let mut line = serde_json::to_string(request).map_err(|e| error(e.to_string()))?;
        line.push('\n');
        let sent = match driver.stdin.as_mut() {
            Some(stdin) => stdin.write_all(line.as_bytes()).and_then(|()| stdin.flush()),
            None => Err(std::io::ErrorKind::BrokenPipe.into()),
        };
        let reply = match sent {
            Ok(()) => receive(driver, self.deadline, &op),
            Err(e) => Err(format!("writing `{op}` to the driver: {e}")),
        };
        let reply = match reply {
            Ok(reply) => reply,
            Err(why) => {
                // The driver is dropped here: its stdin closes, it closes the browser and exits.
                *slot = Err(why.clone());
                return Err(error(why));
            }
        };
        drop(slot);
        let value: Value = serde_json::from_str(&reply)
            .map_err(|e| error(format!("`{op}`: the driver's reply is not JSON ({e}): {:.200}", reply)))?;
        if value["ok"] != true {
            let detail = value["error"].as_str().map_or_else(|| value.to_string(), str::to_string);
            return Err(error(format!("`{op}`: {detail}")));
        }
        Ok(value)
    }
}

/// The next reply line, or why there is none within `deadline`.
fn receive(driver: &mut Driver, deadline: Duration, what: &str) -> Result<String, String> {
    match driver.replies.recv_timeout(deadline) {
        Ok(line) => Ok(line),
        Err(RecvTimeoutError::Timeout) => {
            Err(format!("gave up on `{what}` after {:.0} s without a reply (a hung page?)", deadline.as_secs_f64()))
        }
        Err(RecvTimeoutError::Disconnected) => {
            let status = driver.child.wait().map(|s| s.to_string()).unwrap_or_else(|e| e.to_string());
            Err(format!("the driver exited during `{what}` ({status}); its messages are above"))
        }
    }
}

fn words_base64(words: &[u32]) -> String {
    BASE64.encode(bytemuck::cast_slice::<u32, u8>(words))
}

fn base64_words(text: &str) -> Result<Vec<u32>, String> {
    let bytes = BASE64.decode(text).map_err(|e| format!("words are not base64: {e}"))?;
    if bytes.len() % 4 != 0 {
        return Err(format!("{} bytes of words: not a multiple of 4", bytes.len()));
    }
    Ok(bytes.chunks_exact(4).map(|c| u32::from_le_bytes([c[0], c[1], c[2], c[3]])).collect())
}

/// WebGL2 or WebGPU in the page of a [`BrowserSession`]: a [`Runtime`] like the native ones.
pub struct BrowserRuntime {
    backend: Backend,
    session: Arc<BrowserSession>,
    /// The page's handle of this runtime's harness.
    id: u64,
    program: Program,
    specialize: BTreeMap<String, u32>,
    /// Layouts of the functions the page compiled (under `specialize`).
    layouts: HashMap<String, lightport_codegen::Harness>,
    corruption: Option<Corruption>,
    info: String,
}

impl BrowserRuntime {
    /// A harness for `backend` (WebGL2 or WebGPU) in `session`'s page, over `program` linked
    /// from `modules` (the page links the same modules).
    pub fn new(
        session: Arc<BrowserSession>,
        backend: Backend,
        program: Program,
        modules: &[kernel_dsl::ir::Module],
    ) -> Result<BrowserRuntime, HarnessError> {
        let kind = match backend {
            Backend::WebGl2 => "webgl2",
            Backend::WebGpu => "webgpu",
            _ => return Err(HarnessError::Browser { backend, detail: "not a browser runtime".into() }),
        };
        let modules = serde_json::to_string(modules)
            .map_err(|e| HarnessError::Browser { backend, detail: format!("the IR as JSON: {e}") })?;
        let reply = session.request(backend, &json!({ "op": "create", "runtime": kind, "modules": modules }))?;
        let id = reply["id"]
            .as_u64()
            .ok_or_else(|| HarnessError::Browser { backend, detail: format!("`create` returned no id: {reply}") })?;
        let info = reply["info"].as_str().unwrap_or_default().to_string();
        Ok(BrowserRuntime {
            backend,
            session,
            id,
            program,
            specialize: BTreeMap::new(),
            layouts: HashMap::new(),
            corruption: None,
            info,
        })
    }

    /// The page's renderer (WebGL2) or adapter (WebGPU).
    pub fn info(&self) -> &str {
        &self.info
    }

    /// Makes the next [`run_words`](Runtime::run_words) reply wrong in the given way.
    pub fn corrupt_next_run(&mut self, corruption: Corruption) {
        self.corruption = Some(corruption);
    }

    fn error(&self, detail: String) -> HarnessError {
        HarnessError::Browser { backend: self.backend, detail }
    }

    /// The denoiser's filter passes over `image` in the page (`GlFilter` on WebGL2,
    /// `WgpuFilter` on WebGPU, as `Renderer::denoise_passes` runs them natively): the last
    /// pass's output per pixel, and the milliseconds the page measured around them (the passes
    /// and their read-back; not the pass's compile, nor the transfer to and from the page).
    pub fn run_filter(&mut self, image: &FilterImage) -> Result<(Vec<Vec4>, f64), HarnessError> {
        let words = words_base64(&encode_resources(image));
        let reply = self.request(json!({ "op": "filter", "words": words }))?;
        let text = reply["words"].as_str().ok_or_else(|| self.error("`filter`: no words".into()))?;
        let words = base64_words(text).map_err(|e| self.error(format!("`filter`: {e}")))?;
        let pixels = image.width as usize * image.height as usize;
        if words.len() != pixels * 4 {
            return Err(self.error(format!("`filter`: {} words for {pixels} pixels", words.len())));
        }
        let ms = reply["ms"].as_f64().ok_or_else(|| self.error("`filter`: no time".into()))?;
        Ok((
            words.chunks_exact(4).map(|t| Vec4::from_array([t[0], t[1], t[2], t[3]].map(f32::from_bits))).collect(),
            ms,
        ))
    }

    fn request(&self, mut request: Value) -> Result<Value, HarnessError> {
        request["id"] = json!(self.id);
        self.session.request(self.backend, &request)
    }
}

impl Runtime for BrowserRuntime {
    fn as_any_mut(&mut self) -> &mut dyn std::any::Any {
        self
    }

    fn backend(&self) -> Backend {
        self.backend
    }

    fn set_scene(&mut self, scene: &Scene) -> Result<(), HarnessError> {
        self.request(json!({ "op": "scene", "words": words_base64(&encode_scene(scene)) }))?;
        Ok(())
    }

    /// Sent with the next request that compiles or runs (this one cannot fail).
    fn set_specialization(&mut self, specialize: BTreeMap<String, u32>) {
        if self.specialize != specialize {
            self.specialize = specialize;
            self.layouts.clear();
        }
    }

    /// The layout codegen gives natively, checked against the one the page compiled.
    fn layout(&mut self, function: &str) -> Result<lightport_codegen::Harness, HarnessError> {
        if let Some(layout) = self.layouts.get(function) {
            return Ok(layout.clone());
        }
        let target = if self.backend == Backend::WebGpu { Target::Wgsl } else { Target::GlslEs300 };
        let generated =
            self.program.emit(target, &harness_selection(function, &self.specialize)).map_err(ShaderError::from)?;
        let layout = generated_layout(function, &generated)?;
        let reply = self.request(json!({ "op": "layout", "function": function, "specialize": self.specialize }))?;
        let page = (reply["inputWords"].as_u64(), reply["outputWords"].as_u64());
        if page != (Some(layout.input_words.into()), Some(layout.output_words.into())) {
            return Err(HarnessError::Layout {
                function: function.to_string(),
                detail: format!(
                    "the page's shader takes {:?} and gives {:?} words, the native codegen {} and {}",
                    page.0, page.1, layout.input_words, layout.output_words
                ),
            });
        }
        self.layouts.insert(function.to_string(), layout.clone());
        Ok(layout)
    }

    fn run_words(&mut self, function: &str, invocations: usize, input: &[u32]) -> Result<Vec<u32>, HarnessError> {
        let layout = self.layout(function)?;
        let (in_words, out_words) = (layout.input_words as usize, layout.output_words as usize);
        if input.len() != invocations * in_words {
            return Err(HarnessError::Layout {
                function: function.to_string(),
                detail: format!("{} input words for {invocations} invocations of {in_words} words", input.len()),
            });
        }
        let corrupt = match self.corruption.take() {
            None => Value::Null,
            Some(Corruption::FlipWord(k)) => json!({ "flip": k }),
            Some(Corruption::DropLastWord) => json!("truncate"),
            Some(Corruption::NotJson) => json!("garbage"),
            Some(Corruption::Hang) => json!("hang"),
        };
        let reply = self.request(json!({
            "op": "run",
            "function": function,
            "invocations": invocations,
            "specialize": self.specialize,
            "words": words_base64(input),
            "corrupt": corrupt,
        }))?;
        let text = reply["words"].as_str().ok_or_else(|| self.error(format!("`run {function}`: no words")))?;
        let words = base64_words(text).map_err(|e| self.error(format!("`run {function}`: {e}")))?;
        if words.len() != invocations * out_words {
            return Err(self.error(format!(
                "`run {function}`: the page returned {} words for {invocations} invocations of {out_words}",
                words.len()
            )));
        }
        Ok(words)
    }
}

impl Drop for BrowserRuntime {
    fn drop(&mut self) {
        // Frees the page's harness; a session that already ended has nothing to free.
        let _ = self.request(json!({ "op": "drop" }));
    }
}
