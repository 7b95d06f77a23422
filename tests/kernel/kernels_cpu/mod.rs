//! The kernel functions (`tracer::kernel::*`) as ordinary Rust on the CPU: reference values
//! for the RNG, distributions of the samplers (chi-square / Monte Carlo estimates with fixed
//! seeds), and the ray intersection routines on hand-checked and adversarial inputs.
//!
//! These are the reference semantics: the shader backends are compared against the same
//! functions elsewhere.

mod intersect;
mod rng;
mod sampling;
mod textures;
mod tonemap;
