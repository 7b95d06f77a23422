//! `lightport serve --port 0` as a child process, for what drives the web page: `lightport
//! chart`'s web line, `examples/feature_sizes.rs` and `tests/web.rs`. It is started, its URL is
//! read from its output, its output keeps being drained (a full pipe would block the server),
//! and it is killed when dropped. The `lightport` package has no library, so the example and the
//! test include this file with `#[path]`; it needs only `std` and `anyhow`.

use std::io::{BufRead, BufReader};
use std::path::Path;
use std::process::{Child, Command, Stdio};
use std::time::Duration;

use anyhow::{bail, Context, Result};

/// A child process killed (and waited for) when dropped.
pub struct Killed(pub Child);

impl Drop for Killed {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

/// Starts `exe serve --port 0 ARGS` and waits up to `timeout` for the URL it prints. Its stderr
/// is passed on to ours when `echo_stderr`; either way, the error for a server that prints no
/// URL quotes its first lines.
pub fn start_serve(exe: &Path, args: &[&str], timeout: Duration, echo_stderr: bool) -> Result<(Killed, String)> {
    let mut child = Command::new(exe)
        .args(["serve", "--port", "0"])
        .args(args)
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .with_context(|| format!("starting {} serve", exe.display()))?;
    let stdout = child.stdout.take().context("the server's stdout")?;
    let stderr = child.stderr.take().context("the server's stderr")?;
    let server = Killed(child);
    let (sender, receiver) = std::sync::mpsc::channel();
    std::thread::spawn(move || {
        let mut sent = false;
        for line in BufReader::new(stdout).lines().map_while(Result::ok) {
            if !sent {
                if let Some(at) = line.find("http://") {
                    let _ = sender.send(line[at..].trim().to_owned());
                    sent = true;
                }
            }
        }
    });
    let errors = std::thread::spawn(move || {
        let mut text = String::new();
        for (i, line) in BufReader::new(stderr).lines().map_while(Result::ok).enumerate() {
            if echo_stderr {
                eprintln!("{line}");
            }
            if i < 50 {
                text.push_str(&line);
                text.push('\n');
            }
        }
        text
    });
    match receiver.recv_timeout(timeout) {
        Ok(url) => Ok((server, url)),
        Err(_) => {
            drop(server);
            let said = errors.join().unwrap_or_default();
            bail!("`{} serve --port 0 {}` printed no URL: {}", exe.display(), args.join(" "), said.trim())
        }
    }
}
