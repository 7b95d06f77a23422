//! Child processes that end with their parent, and `lightport serve --port 0` as one, for what
//! drives the web page: `lightport chart`'s web line, `examples/feature_sizes.rs`, `tests/cli/web.rs`
//! and `tests/cli/export.rs`, through the `lightport` package's library.
//!
//! # Why a stdin pipe
//! A child started here gets a pipe as its stdin whose write end only this process holds (std
//! opens pipes close-on-exec, so no other child inherits it), and the child is told to exit at
//! end of file (`lightport serve --exit-on-stdin-eof`, `tests/web/run.mjs --exit-on-stdin-eof`).
//! The kernel closes that end whenever this process ends, however it ends: a test that panics,
//! a test binary that returns with a child in a `static` (statics are never dropped), `exit`,
//! abort or `SIGKILL`. Dropping a [`Killed`] also kills the child at once. `PR_SET_PDEATHSIG`
//! was the alternative and is not used: it fires when the *thread* that spawned the child ends
//! (each Rust test runs on its own thread, so a server shared through a `static` would die with
//! the first test), it is Linux-only, and it is lost across a set-uid exec. A program that
//! cannot watch a pipe (nginx in tests/cli/export.rs) runs under a `sh` that does it for it
//! ([`Killed::spawn_watched`]).

// Each includer uses a different part of this file.
#![allow(dead_code)]

use std::io::{BufRead, BufReader};
use std::path::Path;
use std::process::{Child, ChildStdin, Command, ExitStatus, Stdio};
use std::time::Duration;

use anyhow::{bail, Context, Result};

/// A child process killed (and waited for) when dropped; its stdin is a pipe held open until
/// then, so a child that exits at end of file on stdin also ends when this process ends.
pub struct Killed {
    child: Child,
    lifeline: Option<ChildStdin>,
    /// Dropped by closing the lifeline and waiting (up to 10 s) before killing: a watcher
    /// ([`Killed::spawn_watched`]) killed at once would leave its program running.
    graceful: bool,
}

impl Killed {
    /// Spawns `command` with a stdin pipe that only this process holds (see the module docs):
    /// the child must exit at end of file on its stdin to end with this process.
    pub fn spawn_tied(command: &mut Command) -> std::io::Result<Killed> {
        let mut child = command.stdin(Stdio::piped()).spawn()?;
        let lifeline = child.stdin.take();
        Ok(Killed { child, lifeline, graceful: false })
    }

    /// Spawns `program ARGS` under `sh`, which watches the stdin pipe for it: at its end (this
    /// process ended, or the handle was dropped) `sh` stops the program with `SIGTERM` and waits
    /// for it. For programs that do not exit at end of file on stdin themselves (nginx). The
    /// program's own stdin is `/dev/null`; its output goes where `command`'s would.
    pub fn spawn_watched(program: &Path, args: &[&std::ffi::OsStr]) -> std::io::Result<Killed> {
        let mut command = Command::new("sh");
        command
            .arg("-c")
            .arg(r#""$@" </dev/null & program=$!; cat >/dev/null; kill -TERM "$program" 2>/dev/null; wait "$program""#)
            .arg("sh")
            .arg(program)
            .args(args);
        let mut watched = Killed::spawn_tied(&mut command)?;
        watched.graceful = true;
        Ok(watched)
    }

    pub fn child(&mut self) -> &mut Child {
        &mut self.child
    }

    /// Waits for the child to exit (the pipe stays open until then).
    pub fn wait(mut self) -> std::io::Result<ExitStatus> {
        self.child.wait()
    }
}

impl Drop for Killed {
    fn drop(&mut self) {
        if self.graceful {
            drop(self.lifeline.take());
            let deadline = std::time::Instant::now() + Duration::from_secs(10);
            while std::time::Instant::now() < deadline {
                if let Ok(Some(_)) = self.child.try_wait() {
                    return;
                }
                std::thread::sleep(Duration::from_millis(20));
            }
        }
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// Runs `command` as [`Killed::spawn_tied`] does and waits for it.
pub fn run_tied(command: &mut Command) -> std::io::Result<ExitStatus> {
    Killed::spawn_tied(command)?.wait()
}

/// Starts `exe serve --port 0 ARGS` and waits up to `timeout` for the URL it prints. Its stderr
/// is passed on to ours when `echo_stderr`; either way, the error for a server that prints no
/// URL quotes its first lines. The server's output keeps being drained (a full pipe would
/// block it); it exits when the returned handle is dropped or this process ends.
pub fn start_serve(exe: &Path, args: &[&str], timeout: Duration, echo_stderr: bool) -> Result<(Killed, String)> {
    let mut server = Killed::spawn_tied(
        Command::new(exe)
            .args(["serve", "--port", "0", "--exit-on-stdin-eof"])
            .args(args)
            .stdout(Stdio::piped())
            .stderr(Stdio::piped()),
    )
    .with_context(|| format!("starting {} serve", exe.display()))?;
    let stdout = server.child().stdout.take().context("the server's stdout")?;
    let stderr = server.child().stderr.take().context("the server's stderr")?;
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
