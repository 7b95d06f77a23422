//! The kernel DSL: a Rust subset that compiles as ordinary Rust (so kernels run on the CPU)
//! and, through the [`kernel`] attribute, also exposes its syntax as an [`ir::Module`] that
//! `lightport-codegen` turns into GLSL ES 3.00 and WGSL.
//!
//! ```
//! #[kernel_dsl::kernel]
//! pub mod demo {
//!     pub fn half(x: f32) -> f32 {
//!         x * 0.5
//!     }
//! }
//! assert_eq!(demo::half(3.0), 1.5);
//! assert_eq!(demo::kernel_ir().items.len(), 1);
//! ```
//!
//! Resources (scene data read by the kernel) are declared as a struct marked
//! `#[resources]` whose fields are [`Texels`] (data textures, read with `fetch`) or plain
//! values (uniforms). Kernel functions take it as `&Resources`; on the CPU it is an ordinary
//! struct, in shaders the parameter disappears and the fields become globals.

pub use kernel_dsl_ir as ir;
pub use kernel_dsl_macros::kernel;

/// A read-only array of texels, addressed by a linear index.
///
/// On the CPU this is a slice; in GLSL it is a 2D data texture read with `texelFetch`
/// (row-major, `index % width`, `index / width`); in WGSL a read-only storage buffer.
/// `T` is `Vec4` (an RGBA32F texture) or `UVec4` (RGBA32UI).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Texels<T> {
    data: Vec<T>,
}

impl<T: Copy + Default> Texels<T> {
    pub fn new(data: Vec<T>) -> Self {
        Texels { data }
    }

    /// The texel at `index`. Out of range reads return zero (as robust GPU access does)
    /// rather than panicking; kernels should not rely on it.
    #[inline(always)]
    pub fn fetch(&self, index: u32) -> T {
        match self.data.get(index as usize) {
            Some(texel) => *texel,
            None => T::default(),
        }
    }

    pub fn len(&self) -> usize {
        self.data.len()
    }

    pub fn is_empty(&self) -> bool {
        self.data.is_empty()
    }

    pub fn as_slice(&self) -> &[T] {
        &self.data
    }
}

impl<T> From<Vec<T>> for Texels<T> {
    fn from(data: Vec<T>) -> Self {
        Texels { data }
    }
}
