//! The HTTP target: raw requests sent to a running `lightport serve` over loopback.
//!
//! The server runs as the real binary in its own process, so this target depends only on what
//! the server does on the wire (whatever HTTP stack it is built on), not on its internals.
//! Each request is written, the sending half of the connection closed (so an incomplete
//! request cannot wait for the server's read timeout), and the answer read until the server
//! closes. An exchange passes when the server answers with an HTTP status below 500 or closes
//! the connection, within the time bound; it fails on a 5xx answer, a reply that is not HTTP,
//! no answer within the bound, or a server that died or printed a panic.
//!
//! Coverage guidance does not reach into the server process: under libFuzzer this target is a
//! mutational fuzzer (its structure-aware mutations are in [`crate::mutate::http`]).

use std::ffi::OsString;
use std::io::{BufRead, BufReader, ErrorKind, Read, Write};
use std::net::{Shutdown, SocketAddr, TcpStream};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::sync::{mpsc, Arc, Mutex};
use std::time::{Duration, Instant};

/// A `lightport serve` child process, killed when dropped and tied to this process by its stdin
/// (`--exit-on-stdin-eof`): a fuzzer that aborts on a finding must not leave a server behind.
pub struct Server {
    child: Child,
    pub addr: SocketAddr,
    stderr: Arc<Mutex<String>>,
}

/// The `lightport` binary: `$LIGHTPORT_BIN`, else the workspace's debug build.
pub fn default_binary() -> PathBuf {
    match std::env::var_os("LIGHTPORT_BIN") {
        Some(p) => PathBuf::from(p),
        None => Path::new(env!("CARGO_MANIFEST_DIR")).join("../target/debug/lightport"),
    }
}

impl Server {
    /// Starts `BINARY serve ARGS --port 0` and waits (up to 120 s) for its URL line.
    pub fn start(binary: &Path, args: &[OsString]) -> Result<Server, String> {
        let mut command = Command::new(binary);
        // The server exits when its stdin (held by `child`) closes, however this process ends: a
        // fuzzer that aborts on a finding leaves no server behind (the same tie the tests use).
        command
            .arg("serve")
            .args(args)
            .args(["--port", "0", "--exit-on-stdin-eof"])
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped());
        let mut child = command.spawn().map_err(|e| format!("cannot start {}: {e}", binary.display()))?;
        let stdout = child.stdout.take().ok_or("no stdout")?;
        let (tx, rx) = mpsc::channel();
        std::thread::spawn(move || {
            for line in BufReader::new(stdout).lines().map_while(Result::ok) {
                if tx.send(line).is_err() {
                    break;
                }
            }
        });
        let stderr = Arc::new(Mutex::new(String::new()));
        let mut pipe = child.stderr.take().ok_or("no stderr")?;
        let sink = Arc::clone(&stderr);
        std::thread::spawn(move || {
            let mut buf = [0u8; 4096];
            while let Ok(n) = pipe.read(&mut buf) {
                if n == 0 {
                    break;
                }
                if let Ok(mut s) = sink.lock() {
                    // Keep the start and the end of what it said, bounded.
                    if s.len() < 1 << 20 {
                        s.push_str(&String::from_utf8_lossy(&buf[..n]));
                    }
                }
            }
        });
        let deadline = Instant::now() + Duration::from_secs(120);
        let mut server = Server { child, addr: SocketAddr::from(([127, 0, 0, 1], 0)), stderr };
        while Instant::now() < deadline {
            match rx.recv_timeout(Duration::from_millis(100)) {
                Ok(line) => {
                    if let Some(url) = line.strip_prefix("serving ").and_then(|r| r.rsplit(' ').next()) {
                        let host = url.trim_start_matches("http://").trim_end_matches('/');
                        server.addr = host.parse().map_err(|e| format!("bad address in {line:?}: {e}"))?;
                        return Ok(server);
                    }
                }
                Err(mpsc::RecvTimeoutError::Timeout) => {}
                Err(mpsc::RecvTimeoutError::Disconnected) => break,
            }
            if let Ok(Some(status)) = server.child.try_wait() {
                return Err(format!("the server exited ({status}): {}", server.stderr_text()));
            }
        }
        Err(format!("the server did not start: {}", server.stderr_text()))
    }

    /// What the server printed on stderr so far.
    pub fn stderr_text(&self) -> String {
        self.stderr.lock().map(|s| s.clone()).unwrap_or_default()
    }

    /// An error when the server has exited or printed a panic.
    pub fn check_alive(&mut self) -> Result<(), String> {
        if let Ok(Some(status)) = self.child.try_wait() {
            return Err(format!("the server exited ({status}): {}", self.stderr_text()));
        }
        let text = self.stderr_text();
        if let Some(at) = text.find("panicked") {
            return Err(format!("the server panicked: {}", &text[at.saturating_sub(200)..(at + 800).min(text.len())]));
        }
        Ok(())
    }
}

impl Drop for Server {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// How the server answered one request.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Answer {
    /// An HTTP response with this status (the first one, when it answered several).
    Status(u16),
    /// It closed the connection without answering (e.g. on an incomplete request).
    Closed,
}

/// Sends `request` to `addr`, closes the sending half, and reads until the server closes; the
/// answer, or why it fails (see the module docs).
pub fn exchange(addr: SocketAddr, request: &[u8], bound: Duration) -> Result<Answer, String> {
    let start = Instant::now();
    let mut stream =
        TcpStream::connect_timeout(&addr, bound).map_err(|e| format!("cannot connect to the server: {e}"))?;
    stream.set_write_timeout(Some(bound)).ok();
    stream.set_nodelay(true).ok();
    match stream.write_all(request) {
        Ok(()) => {}
        // The server may refuse (and close) before reading everything: a valid answer.
        Err(e) if matches!(e.kind(), ErrorKind::BrokenPipe | ErrorKind::ConnectionReset) => {}
        Err(e) => return Err(format!("writing the request: {e}")),
    }
    let _ = stream.shutdown(Shutdown::Write);
    let mut answer = Vec::new();
    let mut buf = [0u8; 16 << 10];
    loop {
        let left = bound.checked_sub(start.elapsed()).filter(|d| !d.is_zero());
        let Some(left) = left else {
            return Err(format!("no end of the answer within {bound:?} ({} bytes so far)", answer.len()));
        };
        stream.set_read_timeout(Some(left)).ok();
        match stream.read(&mut buf) {
            Ok(0) => break,
            Ok(n) => {
                // Only the status line matters; keep memory bounded for large bodies.
                if answer.len() < 64 {
                    answer.extend_from_slice(&buf[..n]);
                }
            }
            Err(e) if e.kind() == ErrorKind::ConnectionReset => break,
            Err(e) if matches!(e.kind(), ErrorKind::WouldBlock | ErrorKind::TimedOut) => {
                return Err(format!("no end of the answer within {bound:?} ({} bytes so far)", answer.len()))
            }
            Err(e) => return Err(format!("reading the answer: {e}")),
        }
    }
    if answer.is_empty() {
        return Ok(Answer::Closed);
    }
    let status = parse_status(&answer).ok_or_else(|| {
        format!("the answer is not HTTP: {:?}", String::from_utf8_lossy(&answer[..answer.len().min(64)]))
    })?;
    if status >= 500 {
        return Err(format!("the server answered {status}"));
    }
    Ok(Answer::Status(status))
}

/// The status code of `HTTP/1.x NNN ...`.
fn parse_status(answer: &[u8]) -> Option<u16> {
    let rest = answer.strip_prefix(b"HTTP/1.")?;
    let code = rest.get(2..5)?;
    if rest.get(1) != Some(&b' ') || !code.iter().all(u8::is_ascii_digit) {
        return None;
    }
    std::str::from_utf8(code).ok()?.parse().ok()
}

/// The server the HTTP target runs against: the Cornell box OBJ (quick to load), the
/// repository's page, a 2 s request timeout.
pub fn start_default_server(binary: &Path) -> Result<Server, String> {
    let scene = crate::seeds::shared_dir().join("scenes/cornell-box/CornellBox-Original.obj");
    let web = Path::new(env!("CARGO_MANIFEST_DIR")).join("../web");
    let args: Vec<OsString> = vec![scene.into(), "--timeout".into(), "2".into(), "--web".into(), web.into()];
    Server::start(binary, &args)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn status_lines() {
        assert_eq!(parse_status(b"HTTP/1.1 404 Not Found\r\n"), Some(404));
        assert_eq!(parse_status(b"HTTP/1.0 200 OK"), Some(200));
        assert_eq!(parse_status(b"HTTP/1.1 20"), None);
        assert_eq!(parse_status(b"garbage"), None);
    }
}
