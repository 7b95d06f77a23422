//! The kernel and what makes it: code generation (every generated file, its validation, its
//! Rust-source tags), the kernel functions as Rust on the CPU, BVH building and the kernel's
//! traversal of it. No GPU needed.

mod bvh;
mod codegen;
#[path = "../common/mod.rs"]
mod common;
mod kernels_cpu;
mod traversal_kernel;
