//! Lightport's tracer: scenes, BVH, packing, the path-tracing kernel (written in the
//! kernel DSL) and the backends that run it.

pub mod bvh;
pub mod kernel;
pub mod scene;
