//! Load on `lightport serve` over loopback: keep-alive clients fetching the page, `scenes.json`
//! and a multi-megabyte bundle in turn, plus slow clients dripping a request head a byte at a
//! time; prints requests/s, p50/p99 latency per route, errors and the server's peak RSS.
//!
//! ```sh
//! cargo build --release && cargo run --release --example load -- [--clients 64] [--seconds 20] [--slow 16]
//! ```
//!
//! The server serves the Cornell box under the venice_sunset sky (an ~8 MB bundle, sent gzip
//! or plain by turns). `examples/load.rs` is its command line; `tests/cli/load.rs` runs a short
//! version (8 clients, 3 s) asserting no errors and a bounded RSS.

use std::io::{BufRead, BufReader, Read, Write};
use std::net::TcpStream;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use crate::serve_child;

pub struct Options {
    pub exe: PathBuf,
    pub clients: usize,
    pub seconds: f64,
    pub slow: usize,
}

/// What one run measured.
pub struct Report {
    /// Per route: (label, latencies in seconds, bytes received).
    pub routes: Vec<(String, Vec<f64>, u64)>,
    pub errors: Vec<String>,
    pub elapsed: f64,
    /// The server's peak resident set (VmHWM), bytes.
    pub peak_rss: u64,
    /// Its resident set after start-up, before the load.
    pub start_rss: u64,
    /// Slow clients cut off by the server (out of those started).
    pub slow_cut_off: usize,
}

fn rss(pid: u32, field: &str) -> u64 {
    let status = std::fs::read_to_string(format!("/proc/{pid}/status")).unwrap_or_default();
    let line = status.lines().find(|l| l.starts_with(field)).unwrap_or("");
    line.split_whitespace().nth(1).and_then(|v| v.parse::<u64>().ok()).unwrap_or(0) * 1024
}

/// Reads one response: status and body length (bodies are read and dropped).
fn read_response(reader: &mut BufReader<TcpStream>) -> std::io::Result<(u16, u64)> {
    let mut line = String::new();
    reader.read_line(&mut line)?;
    let status = line
        .split(' ')
        .nth(1)
        .and_then(|s| s.parse().ok())
        .ok_or_else(|| std::io::Error::new(std::io::ErrorKind::InvalidData, format!("bad status line {line:?}")))?;
    let mut length = 0u64;
    loop {
        let mut h = String::new();
        reader.read_line(&mut h)?;
        let h = h.trim_end();
        if h.is_empty() {
            break;
        }
        if let Some((n, v)) = h.split_once(':') {
            if n.eq_ignore_ascii_case("content-length") {
                length = v.trim().parse().unwrap_or(0);
            }
        }
    }
    std::io::copy(&mut reader.by_ref().take(length), &mut std::io::sink())?;
    Ok((status, length))
}

pub fn run(options: &Options) -> anyhow::Result<Report> {
    // The sky vendored for the tests (tests/data/README.md): tests/cli/load.rs runs this.
    let sky = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/scenes/hdri/venice_sunset_1k.hdr");
    let sky = sky.to_string_lossy().into_owned();
    let (mut server, url) =
        serve_child::start_serve(&options.exe, &["--sky", &sky, "--timeout", "2"], Duration::from_secs(120), false)?;
    let pid = server.child().id();
    let port: u16 = url.trim_end_matches('/').rsplit(':').next().unwrap_or("").parse()?;
    let list: serde_json::Value = {
        let mut s = TcpStream::connect(("127.0.0.1", port))?;
        s.write_all(b"GET /scenes.json HTTP/1.1\r\nHost: x\r\nConnection: close\r\n\r\n")?;
        let mut all = String::new();
        s.read_to_string(&mut all)?;
        serde_json::from_str(all.split_once("\r\n\r\n").map_or("", |(_, b)| b))?
    };
    let bundle = format!("/{}", list["scenes"][0]["url"].as_str().unwrap_or(""));
    let start_rss = rss(pid, "VmRSS:");
    let routes: Vec<(String, String, bool)> = vec![
        ("page /".into(), "/".into(), true),
        ("scenes.json".into(), "/scenes.json".into(), true),
        ("bundle (gzip)".into(), bundle.clone(), true),
        ("bundle (plain)".into(), bundle, false),
    ];
    let deadline = Instant::now() + Duration::from_secs_f64(options.seconds);
    let stop = Arc::new(AtomicBool::new(false));
    let slow: Vec<_> = (0..options.slow)
        .map(|_| {
            let stop = Arc::clone(&stop);
            std::thread::spawn(move || -> bool {
                // One byte every 200 ms: a head that never completes within the server's timeout.
                let Ok(mut s) = TcpStream::connect(("127.0.0.1", port)) else { return false };
                for byte in b"GET / HTTP/1.1\r\nHost: x\r\nX-Slow: ".iter().cycle() {
                    if stop.load(Ordering::Relaxed) || s.write_all(&[*byte]).is_err() {
                        break;
                    }
                    std::thread::sleep(Duration::from_millis(200));
                }
                // Cut off: the write failed (or the run ended first).
                !stop.load(Ordering::Relaxed)
            })
        })
        .collect();
    let clients: Vec<_> = (0..options.clients)
        .map(|i| {
            let routes = routes.clone();
            std::thread::spawn(move || {
                let mut latencies = vec![Vec::new(); routes.len()];
                let mut bytes = vec![0u64; routes.len()];
                let mut errors = Vec::new();
                let mut connection: Option<(TcpStream, BufReader<TcpStream>)> = None;
                let mut n = i;
                while Instant::now() < deadline && errors.len() < 10 {
                    let r = n % routes.len();
                    n += 1;
                    if connection.is_none() {
                        match TcpStream::connect(("127.0.0.1", port)).and_then(|s| {
                            s.set_read_timeout(Some(Duration::from_secs(30)))?;
                            Ok((s.try_clone()?, BufReader::with_capacity(1 << 16, s)))
                        }) {
                            Ok(c) => connection = Some(c),
                            Err(e) => {
                                errors.push(format!("connect: {e}"));
                                continue;
                            }
                        }
                    }
                    let (stream, reader) = connection.as_mut().expect("connected");
                    let encoding = if routes[r].2 { "Accept-Encoding: gzip\r\n" } else { "" };
                    let request = format!("GET {} HTTP/1.1\r\nHost: x\r\n{encoding}\r\n", routes[r].1);
                    let t0 = Instant::now();
                    let answer = stream.write_all(request.as_bytes()).and_then(|()| read_response(reader));
                    match answer {
                        Ok((200, length)) => {
                            latencies[r].push(t0.elapsed().as_secs_f64());
                            bytes[r] += length;
                        }
                        Ok((status, _)) => errors.push(format!("{}: status {status}", routes[r].1)),
                        Err(e) => {
                            errors.push(format!("{}: {e}", routes[r].1));
                            connection = None;
                        }
                    }
                }
                (latencies, bytes, errors)
            })
        })
        .collect();
    let t0 = Instant::now();
    let mut report = Report {
        routes: routes.iter().map(|r| (r.0.clone(), Vec::new(), 0)).collect(),
        errors: Vec::new(),
        elapsed: 0.0,
        peak_rss: 0,
        start_rss,
        slow_cut_off: 0,
    };
    for client in clients {
        let (latencies, bytes, errors) = client.join().map_err(|_| anyhow::anyhow!("a client panicked"))?;
        for (r, l) in latencies.into_iter().enumerate() {
            report.routes[r].1.extend(l);
            report.routes[r].2 += bytes[r];
        }
        report.errors.extend(errors);
    }
    report.elapsed = t0.elapsed().as_secs_f64();
    report.peak_rss = rss(pid, "VmHWM:");
    stop.store(true, Ordering::Relaxed);
    report.slow_cut_off = slow.into_iter().filter_map(|s| s.join().ok()).filter(|&cut| cut).count();
    if let Ok(Some(status)) = server.child().try_wait() {
        report.errors.push(format!("the server exited: {status}"));
    }
    Ok(report)
}

fn percentile(sorted: &[f64], p: f64) -> f64 {
    if sorted.is_empty() {
        return f64::NAN;
    }
    sorted[((sorted.len() - 1) as f64 * p).round() as usize]
}

pub fn print(report: &Report, options: &Options) {
    println!(
        "{} keep-alive clients for {:.1} s, {} slow clients dripping a byte per 200 ms\n",
        options.clients, report.elapsed, options.slow
    );
    println!("| route | requests | requests/s | MB/s | p50 (ms) | p99 (ms) |");
    println!("|---|---|---|---|---|---|");
    let mut total = 0;
    for (label, latencies, bytes) in &report.routes {
        let mut sorted = latencies.clone();
        sorted.sort_by(f64::total_cmp);
        total += sorted.len();
        println!(
            "| {label} | {} | {:.0} | {:.1} | {:.2} | {:.2} |",
            sorted.len(),
            sorted.len() as f64 / report.elapsed,
            *bytes as f64 / report.elapsed / 1e6,
            percentile(&sorted, 0.5) * 1e3,
            percentile(&sorted, 0.99) * 1e3
        );
    }
    println!("| all | {total} | {:.0} | | | |", total as f64 / report.elapsed);
    println!(
        "\nerrors: {}; slow clients cut off: {} of {}; server RSS {:.1} MB after start, peak {:.1} MB",
        report.errors.len(),
        report.slow_cut_off,
        options.slow,
        report.start_rss as f64 / 1e6,
        report.peak_rss as f64 / 1e6
    );
    for e in report.errors.iter().take(10) {
        println!("  {e}");
    }
}
