//! Lightport in the browser. Compiled to wasm32 and wrapped by `wasm-bindgen` (see
//! `scripts/build-web.sh`), it exports [`Viewer`](viewer::Viewer): the native GL or wgpu backend's
//! renderer on a WebGL2 or WebGPU canvas. The page (`web/www/`) runs the frame loop, the camera input and
//! the client-side bundle cache; `docs/web.md` describes the whole.
//!
//! The camera and the dropped-file loader are plain Rust, unit-tested natively; only the viewer
//! needs a browser.

pub mod camera;
#[cfg(target_arch = "wasm32")]
pub mod denoise;
pub mod files;
#[cfg(target_arch = "wasm32")]
pub mod harness;
#[cfg(target_arch = "wasm32")]
mod heap;
#[cfg(target_arch = "wasm32")]
mod js;
#[cfg(target_arch = "wasm32")]
pub mod runtime;
pub mod schedule_choice;
#[cfg(target_arch = "wasm32")]
pub mod viewer;
