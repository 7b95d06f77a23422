//! Lightport's tracer: scenes, BVH, packing, the path-tracing kernel (written in the
//! kernel DSL) and the backends that run it.

pub mod backend;
pub mod bundle;
pub mod bvh;
pub mod denoise;
pub mod kernel;
pub mod output;
pub mod pack;
pub mod scene;
pub mod stats;
