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
//!
//! A module under `#[kernel(compute)]` may also declare [`Storage`] arrays (read-write) and
//! [`Atomics`] counters in its resources: compute stages, generated for WGSL and the CPU only
//! (GLSL ES 3.00 has neither storage buffers nor atomics).

use std::sync::Arc;

use rayon::prelude::*;

mod resources;
mod storage;

pub use kernel_dsl_ir as ir;
pub use kernel_dsl_macros::kernel;
pub use resources::{Resource, ResourceField, ResourceMut, Resources};
pub use storage::{Atomics, Storage, StorageElement};

/// A read-only array of texels, addressed by a linear index.
///
/// On the CPU this is a slice; in GLSL it is a 2D data texture read with `texelFetch`
/// (row-major, `index % width`, `index / width`); in WGSL a read-only storage buffer.
/// `T` is `Vec4` (an RGBA32F texture) or `UVec4` (RGBA32UI).
///
/// The texels are shared (`Arc<[T]>`): cloning is cheap, so a large array (a texture atlas)
/// packed once can be reused by several packed scenes and renderers without copying.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Texels<T> {
    data: Arc<[T]>,
}

impl<T: Copy + Default> Texels<T> {
    /// Takes `data` (one copy into the shared allocation; [`Texels::from_fn`] and `collect`
    /// from an exact-size iterator write in place instead).
    pub fn new(data: Vec<T>) -> Self {
        Texels { data: data.into() }
    }

    /// `len` texels, texel `i` being `texel(i)`, written straight into the shared allocation.
    pub fn from_fn(len: usize, mut texel: impl FnMut(usize) -> T) -> Self {
        let mut data = Arc::<[T]>::new_uninit_slice(len);
        let Some(slots) = Arc::get_mut(&mut data) else {
            // Not reached (a new `Arc` is unique); the safe way round, should it ever be.
            return Texels { data: (0..len).map(texel).collect() };
        };
        for (i, slot) in slots.iter_mut().enumerate() {
            slot.write(texel(i));
        }
        // SAFETY: the loop above wrote every slot. (Should `texel` panic, the `Arc` is dropped
        // as `MaybeUninit`, which reads nothing.)
        Texels { data: unsafe { data.assume_init() } }
    }

    /// `count * N` texels written straight into the shared allocation in parallel (rayon), `N`
    /// at a time: texels `N * i .. N * i + N` are `group(i)`. For large arrays with a fixed
    /// number of texels per item (triangles).
    pub fn par_from_groups<const N: usize>(count: usize, group: impl Fn(usize) -> [T; N] + Sync) -> Self
    where
        T: Send + Sync,
    {
        if N == 0 {
            return Texels::new(Vec::new());
        }
        let mut data = Arc::<[T]>::new_uninit_slice(count * N);
        let Some(slots) = Arc::get_mut(&mut data) else {
            // Not reached (a new `Arc` is unique); the safe way round, should it ever be.
            return Texels { data: (0..count).flat_map(group).collect() };
        };
        slots.par_chunks_mut(N).with_min_len(1 << 12).enumerate().for_each(|(i, chunk)| {
            for (slot, texel) in chunk.iter_mut().zip(group(i)) {
                slot.write(texel);
            }
        });
        // SAFETY: the chunks cover every slot and each chunk (N slots) was written from the N
        // texels of its group. (Should `group` panic, rayon passes the panic on and the `Arc`
        // is dropped as `MaybeUninit`, which reads nothing.)
        Texels { data: unsafe { data.assume_init() } }
    }

    /// `len` texels filled by `fill` in place, starting from zero (`T::default()`): for arrays
    /// assembled from slices (a texture atlas), at copy speed and without an intermediate `Vec`.
    pub fn from_fill(len: usize, fill: impl FnOnce(&mut [T])) -> Self {
        let mut texels = Texels::from_fn(len, |_| T::default());
        if let Some(slots) = Arc::get_mut(&mut texels.data) {
            fill(slots);
        }
        texels
    }

    /// [`Texels::from_fill`] for large arrays: the zeros are written in parallel (rayon) before
    /// `fill` runs. The first write to a large fresh allocation is mostly page faults, which
    /// then happen on every thread instead of one.
    pub fn par_from_fill(len: usize, fill: impl FnOnce(&mut [T])) -> Self
    where
        T: Send + Sync,
    {
        let mut texels = Texels::par_from_groups::<1>(len, |_| [T::default()]);
        if let Some(slots) = Arc::get_mut(&mut texels.data) {
            fill(slots);
        }
        texels
    }

    /// The texel at `index`. Out of range reads return zero (as robust GPU access does)
    /// rather than panicking; kernels should not rely on it.
    #[inline(always)]
    pub fn fetch(&self, index: u32) -> T {
        match self.data.get(index as usize) {
            Some(texel) => *texel,
            None => out_of_range(),
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

/// The zero texel of an out-of-range fetch, kept out of line: kernels never rely on it, so the
/// bounds check in `fetch` stays one compare and a branch that is predicted not taken.
#[cold]
#[inline(never)]
fn out_of_range<T: Default>() -> T {
    T::default()
}

impl<T> From<Vec<T>> for Texels<T> {
    fn from(data: Vec<T>) -> Self {
        Texels { data: data.into() }
    }
}

impl<T> FromIterator<T> for Texels<T> {
    fn from_iter<I: IntoIterator<Item = T>>(iter: I) -> Self {
        Texels { data: iter.into_iter().collect() }
    }
}

#[cfg(test)]
mod tests {
    use super::Texels;

    #[test]
    fn texels_built_in_place_hold_what_they_were_given_and_share_on_clone() {
        let squares = Texels::from_fn(5, |i| (i * i) as u32);
        assert_eq!(squares.as_slice(), &[0, 1, 4, 9, 16]);
        let filled = Texels::from_fill(4, |t: &mut [u32]| t[1..3].copy_from_slice(&[7, 8]));
        assert_eq!(filled.as_slice(), &[0, 7, 8, 0]);
        let filled = Texels::par_from_fill(100_000, |t: &mut [u32]| t[1..3].copy_from_slice(&[7, 8]));
        assert_eq!(
            (&filled.as_slice()[..4], filled.as_slice()[4..].iter().all(|&t| t == 0)),
            (&[0, 7, 8, 0][..], true)
        );
        let collected: Texels<u32> = (0..3).collect();
        assert_eq!(collected, Texels::new(vec![0, 1, 2]));
        assert!(std::ptr::eq(squares.clone().as_slice(), squares.as_slice()));
        assert_eq!(Texels::<u32>::from_fn(0, |_| 1).len(), 0);
        let pairs = Texels::par_from_groups(10_000, |i| [i as u32, !(i as u32)]);
        assert!(pairs.as_slice().chunks(2).enumerate().all(|(i, p)| p == [i as u32, !(i as u32)]));
        assert_eq!(pairs.len(), 20_000);
        assert_eq!(Texels::<u32>::par_from_groups(0, |_| [1, 2, 3]).len(), 0);
        assert_eq!(Texels::<u32>::par_from_groups::<0>(5, |_| []).len(), 0);
    }

    #[test]
    fn out_of_range_fetch_is_zero() {
        let t = Texels::new(vec![5u32, 6]);
        assert_eq!((t.fetch(1), t.fetch(2), t.fetch(u32::MAX)), (6, 0, 0));
    }
}
