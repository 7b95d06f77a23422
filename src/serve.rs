//! `lightport serve`: an HTTP/1.1 server on 127.0.0.1 for the web path tracer (hyper 1 on a
//! small tokio runtime): the page (`web/www/`), its wasm build (`web/pkg/`, served under
//! `/pkg/`), and one prebuilt bundle per scene, all from the table [`crate::site`] builds at start.
//!
//! # Routes
//! - `/` and `/index.html`: `web/www/index.html`; `/<path>`: any other file of `web/www/`;
//!   `/pkg/<path>`: the files of `web/pkg/`. `Cache-Control: no-cache` with an `ETag` (so a
//!   reload revalidates and gets `304`).
//! - `/scenes.json`: the served scenes (schema in [`crate::site`]), `no-cache`, `ETag`.
//! - `/bundles/<hash>.lpb`: a scene bundle (`tracer::bundle::decode` reads it), content-addressed
//!   by `<hash>` = SHA-256 of the uncompressed bundle (64 lowercase hex digits), `Cache-Control:
//!   public, max-age=31536000, immutable`, `ETag: "<hash>"` (`"<hash>-gzip"` for the gzip
//!   representation; `If-None-Match` with either gives `304`), `Content-Type:
//!   application/octet-stream`. Sent with `Content-Encoding: gzip` when the request's
//!   `Accept-Encoding` allows gzip (a browser's `fetch` then hands the page the uncompressed
//!   bytes), otherwise uncompressed; `Vary: Accept-Encoding`.
//!
//! # What it refuses
//! Only `GET` and `HEAD` (`405` with `Allow` otherwise). The request path is never joined to a
//! file-system path: it is looked up, exactly (query string ignored), in the table of routes, so
//! `..`, `%2e%2e`, backslashes, absolute or unknown paths and directories are all `404`. hyper
//! parses requests: heads over [`MAX_HEAD_BYTES`] or with more than [`MAX_HEADERS`] headers get
//! `431`, malformed ones `400`. A declared body over [`MAX_BODY_BYTES`] gets `413`, a chunked
//! request body `411`. A client has `--timeout` seconds to send each request head (a trickle of
//! bytes does not extend it; an idle keep-alive connection has as long for its next request),
//! after which hyper closes the connection; each write to a client must progress within
//! [`WRITE_TIMEOUT`]. At most [`MAX_CONNECTIONS`] connections are served at once; past that a
//! new one gets `503` and is closed.
//!
//! # Shutdown
//! `SIGINT`, `SIGTERM` and (with `--exit-on-stdin-eof`) the end of stdin stop accepting, let the
//! requests in progress finish (keep-alive connections are closed after their current answer;
//! at most [`GRACE`]), and exit with status 0.

use std::convert::Infallible;
use std::future::Future;
use std::io::Write;
use std::pin::Pin;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::task::{Context as TaskContext, Poll};
use std::time::Duration;

use anyhow::{bail, Context, Result};
use bytes::Bytes;
use http_body_util::{BodyExt, Full, Limited};
use hyper::body::Incoming;
use hyper::header::{self, HeaderValue};
use hyper::{Method, Request, Response, StatusCode};
use hyper_util::rt::{TokioIo, TokioTimer};
use tokio::io::{AsyncRead, AsyncWrite, ReadBuf};
use tokio::net::{TcpListener, TcpStream};
use tokio::sync::Notify;

use crate::site::{Site, SiteArgs};

/// Largest request head (request line and headers) accepted; larger gets `431`.
pub const MAX_HEAD_BYTES: usize = 16 * 1024;
/// Most request headers accepted; more gets `431`.
pub const MAX_HEADERS: usize = 64;
/// Largest request body accepted (and discarded: no route takes one); larger gets `413`.
pub const MAX_BODY_BYTES: u64 = 1024;
/// Connections served at once; more get `503`.
pub const MAX_CONNECTIONS: usize = 1024;
/// Longest a single write to a client may make no progress (a client that stops reading is dropped).
pub const WRITE_TIMEOUT: Duration = Duration::from_secs(20);
/// Longest the requests in progress may take to finish after a shutdown is asked for.
pub const GRACE: Duration = Duration::from_secs(5);

#[derive(clap::Args)]
pub struct ServeArgs {
    #[command(flatten)]
    site: SiteArgs,
    /// Port on 127.0.0.1 (0: any free port; the URL printed says which).
    #[arg(long, default_value_t = 8080)]
    port: u16,
    /// Seconds a client has to send each request head.
    #[arg(long, default_value_t = 10.0)]
    timeout: f64,
    /// Exit when stdin reaches its end: for a parent (a test, `lightport chart`) that holds the
    /// other end of a pipe, which the kernel closes when the parent ends however it ends.
    #[arg(long)]
    exit_on_stdin_eof: bool,
}

/// Set once the server listens: from then on, the end of stdin shuts it down gracefully.
static SERVING: AtomicBool = AtomicBool::new(false);
/// Notified when stdin ends while serving.
static STDIN_CLOSED: Notify = Notify::const_new();

pub fn serve(args: &ServeArgs) -> Result<()> {
    if !(args.timeout.is_finite() && args.timeout > 0.0 && args.timeout <= 3600.0) {
        bail!("--timeout must be between 0 and 3600 seconds");
    }
    if args.exit_on_stdin_eof {
        exit_on_stdin_eof();
    }
    let site = Site::build(&args.site)?;
    site.print_reports();
    // Two workers: every answer is a precomputed body, so the work is the copying to sockets.
    let runtime = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .thread_name("serve")
        .enable_all()
        .build()
        .context("starting the tokio runtime")?;
    let timeout = Duration::from_secs_f64(args.timeout);
    runtime.block_on(async {
        let listener = TcpListener::bind(("127.0.0.1", args.port))
            .await
            .with_context(|| format!("cannot listen on 127.0.0.1:{} (is the port in use? try --port 0)", args.port))?;
        let addr = listener.local_addr()?;
        println!("serving {} scene(s) at http://{addr}/", site.reports.len());
        std::io::stdout().flush()?;
        SERVING.store(true, Ordering::SeqCst);
        run(listener, Arc::new(site), timeout).await
    })
}

/// Asks for a shutdown when stdin reaches its end (or fails). Started before the scenes load:
/// a parent that ends during a long start-up leaves nothing behind either (the process exits at
/// once then); once serving, the shutdown is graceful, with an exit after [`GRACE`] regardless.
fn exit_on_stdin_eof() {
    std::thread::spawn(|| {
        let _ = std::io::copy(&mut std::io::stdin().lock(), &mut std::io::sink());
        // Not eprintln!: it panics when stderr is a pipe whose reader (the parent) is gone.
        let _ = writeln!(std::io::stderr(), "stdin closed (--exit-on-stdin-eof): exiting");
        if SERVING.load(Ordering::SeqCst) {
            STDIN_CLOSED.notify_one();
            std::thread::sleep(GRACE + Duration::from_secs(1));
        }
        std::process::exit(0);
    });
}

/// Resolves when the server should stop: `SIGINT`, `SIGTERM` or the end of stdin.
async fn shutdown_requested() -> &'static str {
    #[cfg(unix)]
    let terminate = async {
        match tokio::signal::unix::signal(tokio::signal::unix::SignalKind::terminate()) {
            Ok(mut s) => {
                s.recv().await;
            }
            Err(_) => std::future::pending().await,
        }
    };
    #[cfg(not(unix))]
    let terminate = std::future::pending::<()>();
    tokio::select! {
        _ = tokio::signal::ctrl_c() => "SIGINT",
        _ = terminate => "SIGTERM",
        _ = STDIN_CLOSED.notified() => "the end of stdin",
    }
}

/// Accepts connections until a shutdown is asked for, then lets the ones in progress finish.
async fn run(listener: TcpListener, site: Arc<Site>, timeout: Duration) -> Result<()> {
    let graceful = hyper_util::server::graceful::GracefulShutdown::new();
    let permits = Arc::new(tokio::sync::Semaphore::new(MAX_CONNECTIONS));
    let shutdown = shutdown_requested();
    tokio::pin!(shutdown);
    loop {
        let (stream, _peer) = tokio::select! {
            accepted = listener.accept() => match accepted {
                Ok(connection) => connection,
                // A connection that failed before it was accepted (reset, out of descriptors):
                // keep accepting the others.
                Err(e) => {
                    let _ = writeln!(std::io::stderr(), "warning: accept failed: {e}");
                    tokio::time::sleep(Duration::from_millis(10)).await;
                    continue;
                }
            },
            why = &mut shutdown => {
                let _ = writeln!(std::io::stderr(), "{why}: shutting down (finishing the requests in progress)");
                break;
            }
        };
        let _ = stream.set_nodelay(true);
        let io = TokioIo::new(WriteTimeout::new(stream));
        let permit = permits.clone().try_acquire_owned();
        let busy = permit.is_err();
        let site = Arc::clone(&site);
        let service = hyper::service::service_fn(move |request| {
            let site = Arc::clone(&site);
            async move { Ok::<_, Infallible>(if busy { busy_response() } else { respond(&site, request, timeout).await }) }
        });
        let mut builder = hyper::server::conn::http1::Builder::new();
        builder
            .timer(TokioTimer::new())
            .header_read_timeout(if busy { Duration::from_secs(1) } else { timeout })
            .max_buf_size(MAX_HEAD_BYTES.max(8192) + 1024)
            .max_header_size(MAX_HEAD_BYTES)
            .max_headers(MAX_HEADERS)
            .keep_alive(!busy)
            // A client may send its request and close its sending half (the fuzz target does).
            .half_close(true);
        let connection = graceful.watch(builder.serve_connection(io, service));
        tokio::spawn(async move {
            // Errors are the client's (reset, timed out, malformed): nothing to do but close.
            let _ = connection.await;
            drop(permit);
        });
    }
    drop(listener);
    if tokio::time::timeout(GRACE, graceful.shutdown()).await.is_err() {
        let _ = writeln!(std::io::stderr(), "some connections did not finish within {GRACE:?}: closing them");
    }
    Ok(())
}

type Answer = Response<Full<Bytes>>;

/// A short plain-text response (errors).
fn simple(status: StatusCode, message: &str) -> Answer {
    let body = format!("{} {}: {message}\n", status.as_u16(), status.canonical_reason().unwrap_or(""));
    let mut r = Response::new(Full::new(Bytes::from(body)));
    *r.status_mut() = status;
    let h = r.headers_mut();
    h.insert(header::CONTENT_TYPE, HeaderValue::from_static("text/plain; charset=utf-8"));
    h.insert(header::CACHE_CONTROL, HeaderValue::from_static("no-store"));
    h.insert(header::SERVER, HeaderValue::from_static("lightport"));
    r
}

fn busy_response() -> Answer {
    let mut r = simple(StatusCode::SERVICE_UNAVAILABLE, "the server is busy; try again");
    r.headers_mut().insert(header::RETRY_AFTER, HeaderValue::from_static("1"));
    r
}

/// The header's values joined with commas (lists such as `Accept-Encoding`).
fn header_list(request: &Request<Incoming>, name: header::HeaderName) -> String {
    let values = request.headers().get_all(name).iter().filter_map(|v| v.to_str().ok());
    values.collect::<Vec<_>>().join(",")
}

async fn respond(site: &Site, request: Request<Incoming>, timeout: Duration) -> Answer {
    // Bodies are never used: refuse large or unframed ones, read and drop small ones (within
    // the request timeout, so a declared body that never comes does not hold the connection).
    if request.headers().contains_key(header::TRANSFER_ENCODING) {
        return simple(StatusCode::LENGTH_REQUIRED, "request bodies must have a Content-Length");
    }
    if hyper::body::Body::size_hint(request.body()).lower() > MAX_BODY_BYTES {
        return simple(StatusCode::PAYLOAD_TOO_LARGE, "request body too large");
    }
    // HEAD is answered as GET is: hyper sends the head only.
    if !matches!(*request.method(), Method::GET | Method::HEAD) {
        let mut r = simple(StatusCode::METHOD_NOT_ALLOWED, "only GET and HEAD");
        r.headers_mut().insert(header::ALLOW, HeaderValue::from_static("GET, HEAD"));
        return r;
    }
    let accepts_gzip = accepts_gzip(&header_list(&request, header::ACCEPT_ENCODING).to_ascii_lowercase());
    let if_none_match = header_list(&request, header::IF_NONE_MATCH);
    let path = request.uri().path().to_owned();
    let body = Limited::new(request.into_body(), MAX_BODY_BYTES as usize);
    if !matches!(tokio::time::timeout(timeout, body.collect()).await, Ok(Ok(_))) {
        let mut r = simple(StatusCode::BAD_REQUEST, "the request body did not arrive");
        r.headers_mut().insert(header::CONNECTION, HeaderValue::from_static("close"));
        return r;
    }

    // The route table is the allow-list: the path is only ever a key, never a file name.
    let Some(resource) = site.routes.get(&path) else {
        return simple(StatusCode::NOT_FOUND, "not found");
    };
    let use_gzip = accepts_gzip && resource.gzip.is_some();
    let not_modified =
        !if_none_match.is_empty() && matches_etag(&if_none_match, &[resource.etag(false), resource.etag(true)]);
    let body = match (&resource.gzip, use_gzip) {
        _ if not_modified => Bytes::new(),
        (Some(g), true) => g.clone(),
        _ => resource.identity.clone(),
    };
    let length = body.len();
    let mut r = Response::new(Full::new(body));
    let h = r.headers_mut();
    h.insert(header::SERVER, HeaderValue::from_static("lightport"));
    h.insert(header::CONTENT_TYPE, HeaderValue::from_static(resource.content_type));
    h.insert(header::CACHE_CONTROL, HeaderValue::from_static(resource.cache_control));
    if let Ok(etag) = HeaderValue::from_str(&resource.etag(use_gzip)) {
        h.insert(header::ETAG, etag);
    }
    h.insert(header::X_CONTENT_TYPE_OPTIONS, HeaderValue::from_static("nosniff"));
    if resource.gzip.is_some() {
        h.insert(header::VARY, HeaderValue::from_static("Accept-Encoding"));
    }
    if not_modified {
        *r.status_mut() = StatusCode::NOT_MODIFIED;
        return r;
    }
    if use_gzip {
        h.insert(header::CONTENT_ENCODING, HeaderValue::from_static("gzip"));
    }
    // hyper sends no body for HEAD, but this length (the GET's).
    h.insert(header::CONTENT_LENGTH, HeaderValue::from(length));
    r
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

/// A TCP stream whose writes fail with `TimedOut` once one has made no progress for
/// [`WRITE_TIMEOUT`] (hyper has no write timeout; reads are bounded by its header timeout).
struct WriteTimeout {
    stream: TcpStream,
    /// Running while a write is pending; reset by every write that progresses.
    stalled: Option<Pin<Box<tokio::time::Sleep>>>,
}

impl WriteTimeout {
    fn new(stream: TcpStream) -> Self {
        WriteTimeout { stream, stalled: None }
    }

    /// Maps a pending write to an error once it has been pending too long.
    fn check<T>(&mut self, cx: &mut TaskContext<'_>, poll: Poll<std::io::Result<T>>) -> Poll<std::io::Result<T>> {
        if poll.is_ready() {
            self.stalled = None;
            return poll;
        }
        let timer = self.stalled.get_or_insert_with(|| Box::pin(tokio::time::sleep(WRITE_TIMEOUT)));
        match timer.as_mut().poll(cx) {
            Poll::Ready(()) => Poll::Ready(Err(std::io::Error::new(
                std::io::ErrorKind::TimedOut,
                "the client has not read for too long",
            ))),
            Poll::Pending => Poll::Pending,
        }
    }
}

impl AsyncRead for WriteTimeout {
    fn poll_read(
        mut self: Pin<&mut Self>,
        cx: &mut TaskContext<'_>,
        buf: &mut ReadBuf<'_>,
    ) -> Poll<std::io::Result<()>> {
        Pin::new(&mut self.stream).poll_read(cx, buf)
    }
}

impl AsyncWrite for WriteTimeout {
    fn poll_write(mut self: Pin<&mut Self>, cx: &mut TaskContext<'_>, buf: &[u8]) -> Poll<std::io::Result<usize>> {
        let poll = Pin::new(&mut self.stream).poll_write(cx, buf);
        self.check(cx, poll)
    }

    fn poll_write_vectored(
        mut self: Pin<&mut Self>,
        cx: &mut TaskContext<'_>,
        bufs: &[std::io::IoSlice<'_>],
    ) -> Poll<std::io::Result<usize>> {
        let poll = Pin::new(&mut self.stream).poll_write_vectored(cx, bufs);
        self.check(cx, poll)
    }

    fn is_write_vectored(&self) -> bool {
        self.stream.is_write_vectored()
    }

    fn poll_flush(mut self: Pin<&mut Self>, cx: &mut TaskContext<'_>) -> Poll<std::io::Result<()>> {
        let poll = Pin::new(&mut self.stream).poll_flush(cx);
        self.check(cx, poll)
    }

    fn poll_shutdown(mut self: Pin<&mut Self>, cx: &mut TaskContext<'_>) -> Poll<std::io::Result<()>> {
        let poll = Pin::new(&mut self.stream).poll_shutdown(cx);
        self.check(cx, poll)
    }
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
