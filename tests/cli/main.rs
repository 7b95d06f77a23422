//! The `lightport` command end to end, as a user runs it: `render`, `serve` (over raw TCP,
//! under load and fuzzed requests), `chart`, `export` behind nginx, and the page it serves in
//! headless Chromium on WebGL2 and WebGPU. Never skipped: without Chromium, node's
//! `tests/web/node_modules`, nginx or the wasm build, the tests fail and say what to install.

mod chart_web;
mod commands;
#[path = "../common/mod.rs"]
mod common;
mod export;
mod fuzz_http;
mod load;
mod render_bundle;
mod serve;
mod web;
