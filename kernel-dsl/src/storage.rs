//! Read-write data of compute kernels (`#[kernel(compute)]` modules): [`Storage`] arrays and
//! [`Atomics`] counters, shared by every invocation of a stage.
//!
//! On the CPU a stage runs as many rayon tasks at once, each holding `&Resources`, so both
//! types are arrays of [`AtomicU32`] words accessed with `Relaxed` ordering: no `unsafe`, no
//! data race, and on x86 a relaxed load or store is a plain `mov`. That is also WGSL's model:
//! storage accesses of different invocations are unordered within a dispatch, and WGSL's
//! atomics are relaxed. A stage that reads what another invocation of the same dispatch
//! writes (other than through atomics) has a race on the GPU too; write such stages as two
//! dispatches.

use std::fmt;
use std::marker::PhantomData;
use std::sync::atomic::{AtomicU32, Ordering::Relaxed};

use glam::{UVec4, Vec4};

/// An element type of [`Storage`]: `Vec4`, `UVec4`, `u32` or `f32`, as 32-bit words.
pub trait StorageElement: Copy + Default + fmt::Debug {
    /// 32-bit words per element.
    const WORDS: usize;
    /// The type as the kernel source spells it (`Vec4`).
    const DSL_TYPE: &'static str;
    /// Writes the element's `WORDS` words into `out`.
    fn to_words(self, out: &mut [u32]);
    /// The element from its `WORDS` words.
    fn from_words(words: &[u32]) -> Self;
}

impl StorageElement for u32 {
    const WORDS: usize = 1;
    const DSL_TYPE: &'static str = "u32";
    fn to_words(self, out: &mut [u32]) {
        out[0] = self;
    }
    fn from_words(words: &[u32]) -> Self {
        words[0]
    }
}

impl StorageElement for f32 {
    const WORDS: usize = 1;
    const DSL_TYPE: &'static str = "f32";
    fn to_words(self, out: &mut [u32]) {
        out[0] = self.to_bits();
    }
    fn from_words(words: &[u32]) -> Self {
        f32::from_bits(words[0])
    }
}

impl StorageElement for Vec4 {
    const WORDS: usize = 4;
    const DSL_TYPE: &'static str = "Vec4";
    fn to_words(self, out: &mut [u32]) {
        for (o, v) in out.iter_mut().zip(self.to_array()) {
            *o = v.to_bits();
        }
    }
    fn from_words(words: &[u32]) -> Self {
        Vec4::new(
            f32::from_bits(words[0]),
            f32::from_bits(words[1]),
            f32::from_bits(words[2]),
            f32::from_bits(words[3]),
        )
    }
}

impl StorageElement for UVec4 {
    const WORDS: usize = 4;
    const DSL_TYPE: &'static str = "UVec4";
    fn to_words(self, out: &mut [u32]) {
        out[..4].copy_from_slice(&self.to_array());
    }
    fn from_words(words: &[u32]) -> Self {
        UVec4::new(words[0], words[1], words[2], words[3])
    }
}

fn zeroed_words(len: usize) -> Box<[AtomicU32]> {
    (0..len).map(|_| AtomicU32::new(0)).collect()
}

/// A read-write array shared by all invocations of a compute stage, addressed by a linear
/// index: `load` and `store` on the CPU (atomic words, relaxed), a `var<storage, read_write>`
/// buffer in WGSL. GLSL ES 3.00 has no storage buffers: compute modules are WGSL and CPU only.
///
/// Element `i` of several concurrent invocations: a `store` is not torn per 32-bit word, but a
/// `Vec4` written by one invocation while another reads it may be read half old, half new (as
/// on a GPU). Kernels give each element one writer per dispatch.
pub struct Storage<T: StorageElement> {
    words: Box<[AtomicU32]>,
    _element: PhantomData<T>,
}

impl<T: StorageElement> Storage<T> {
    /// `len` zero elements.
    pub fn new(len: usize) -> Self {
        Storage { words: zeroed_words(len * T::WORDS), _element: PhantomData }
    }

    /// The elements of `data`.
    pub fn from_slice(data: &[T]) -> Self {
        let s = Storage::new(data.len());
        s.write_slice(0, data);
        s
    }

    pub fn len(&self) -> usize {
        self.words.len() / T::WORDS
    }

    pub fn is_empty(&self) -> bool {
        self.words.is_empty()
    }

    /// Element `index`; zero out of range (as [`crate::Texels::fetch`]; kernels should not rely
    /// on it).
    #[inline]
    pub fn load(&self, index: u32) -> T {
        let start = index as usize * T::WORDS;
        match self.words.get(start..start + T::WORDS) {
            Some(words) => {
                let mut w = [0u32; 4];
                for (o, a) in w.iter_mut().zip(words) {
                    *o = a.load(Relaxed);
                }
                T::from_words(&w[..T::WORDS])
            }
            None => T::default(),
        }
    }

    /// Sets element `index`; out of range it does nothing (kernels should not rely on it).
    #[inline]
    pub fn store(&self, index: u32, value: T) {
        let start = index as usize * T::WORDS;
        if let Some(words) = self.words.get(start..start + T::WORDS) {
            let mut w = [0u32; 4];
            value.to_words(&mut w[..T::WORDS]);
            for (a, v) in words.iter().zip(w) {
                a.store(v, Relaxed);
            }
        }
    }

    /// Every element (a host read, e.g. after a stage ran).
    pub fn to_vec(&self) -> Vec<T> {
        (0..self.len()).map(|i| self.load(i as u32)).collect()
    }

    /// Sets elements `start..start + data.len()` (a host write); those beyond the end are
    /// ignored.
    pub fn write_slice(&self, start: usize, data: &[T]) {
        for (i, v) in data.iter().enumerate() {
            if let Ok(index) = u32::try_from(start + i) {
                self.store(index, *v);
            }
        }
    }

    /// The array as 32-bit words, element after element (what a GPU buffer holds).
    pub fn words(&self) -> Vec<u32> {
        self.words.iter().map(|w| w.load(Relaxed)).collect()
    }
}

impl<T: StorageElement> Default for Storage<T> {
    fn default() -> Self {
        Storage::new(0)
    }
}

impl<T: StorageElement> Clone for Storage<T> {
    fn clone(&self) -> Self {
        Storage { words: self.words.iter().map(|w| AtomicU32::new(w.load(Relaxed))).collect(), _element: PhantomData }
    }
}

impl<T: StorageElement> fmt::Debug for Storage<T> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "Storage<{}>", T::DSL_TYPE)?;
        f.debug_list().entries(self.to_vec()).finish()
    }
}

impl<T: StorageElement + PartialEq> PartialEq for Storage<T> {
    fn eq(&self, other: &Self) -> bool {
        self.to_vec() == other.to_vec()
    }
}

/// An array of `u32` counters updated atomically by the invocations of a compute stage (queue
/// heads, counts): `atomic_*` on the CPU (`AtomicU32`, relaxed), a `var<storage, read_write>`
/// buffer of `atomic<u32>` in WGSL (`atomicAdd`, ...), whose atomics are relaxed too. Each
/// operation is atomic on its own; there is no ordering with other memory. Out of range an
/// operation does nothing and returns 0 (kernels should not rely on it).
#[derive(Default)]
pub struct Atomics {
    counters: Box<[AtomicU32]>,
}

impl Atomics {
    /// `len` counters at zero.
    pub fn new(len: usize) -> Self {
        Atomics { counters: zeroed_words(len) }
    }

    /// Counters with the values of `data`.
    pub fn from_slice(data: &[u32]) -> Self {
        Atomics { counters: data.iter().map(|v| AtomicU32::new(*v)).collect() }
    }

    pub fn len(&self) -> usize {
        self.counters.len()
    }

    pub fn is_empty(&self) -> bool {
        self.counters.is_empty()
    }

    #[inline]
    fn with(&self, index: u32, op: impl FnOnce(&AtomicU32) -> u32) -> u32 {
        self.counters.get(index as usize).map_or(0, op)
    }

    /// Adds `value` (wrapping); returns the old value.
    #[inline]
    pub fn atomic_add(&self, index: u32, value: u32) -> u32 {
        self.with(index, |a| a.fetch_add(value, Relaxed))
    }

    /// Subtracts `value` (wrapping); returns the old value.
    #[inline]
    pub fn atomic_sub(&self, index: u32, value: u32) -> u32 {
        self.with(index, |a| a.fetch_sub(value, Relaxed))
    }

    /// Sets the minimum of the counter and `value`; returns the old value.
    #[inline]
    pub fn atomic_min(&self, index: u32, value: u32) -> u32 {
        self.with(index, |a| a.fetch_min(value, Relaxed))
    }

    /// Sets the maximum of the counter and `value`; returns the old value.
    #[inline]
    pub fn atomic_max(&self, index: u32, value: u32) -> u32 {
        self.with(index, |a| a.fetch_max(value, Relaxed))
    }

    /// Sets `value`; returns the old value.
    #[inline]
    pub fn atomic_exchange(&self, index: u32, value: u32) -> u32 {
        self.with(index, |a| a.swap(value, Relaxed))
    }

    #[inline]
    pub fn atomic_load(&self, index: u32) -> u32 {
        self.with(index, |a| a.load(Relaxed))
    }

    #[inline]
    pub fn atomic_store(&self, index: u32, value: u32) {
        self.with(index, |a| {
            a.store(value, Relaxed);
            0
        });
    }

    /// Every counter (a host read).
    pub fn to_vec(&self) -> Vec<u32> {
        self.counters.iter().map(|a| a.load(Relaxed)).collect()
    }
}

impl Clone for Atomics {
    fn clone(&self) -> Self {
        Atomics::from_slice(&self.to_vec())
    }
}

impl fmt::Debug for Atomics {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str("Atomics")?;
        f.debug_list().entries(self.to_vec()).finish()
    }
}

impl PartialEq for Atomics {
    fn eq(&self, other: &Self) -> bool {
        self.to_vec() == other.to_vec()
    }
}

#[cfg(test)]
mod tests {
    use super::{Atomics, Storage};
    use glam::{UVec4, Vec4};
    use rayon::prelude::*;

    #[test]
    fn storage_round_trips_each_element_type_and_is_zero_out_of_range() {
        let v = Storage::from_slice(&[Vec4::new(1.0, -0.0, f32::NAN, 4.0), Vec4::ONE]);
        assert_eq!(v.len(), 2);
        assert_eq!(v.load(1), Vec4::ONE);
        assert_eq!(v.load(0).y.to_bits(), (-0.0f32).to_bits());
        assert!(v.load(0).z.is_nan());
        assert_eq!(v.load(2), Vec4::ZERO);
        v.store(7, Vec4::ONE);
        assert_eq!(v.words().len(), 8);
        let u = Storage::<UVec4>::new(3);
        u.store(2, UVec4::new(1, 2, 3, u32::MAX));
        assert_eq!(u.to_vec(), vec![UVec4::ZERO, UVec4::ZERO, UVec4::new(1, 2, 3, u32::MAX)]);
        let f = Storage::<f32>::new(2);
        f.write_slice(1, &[2.5, 9.0]);
        assert_eq!(f.to_vec(), vec![0.0, 2.5]);
        let w = Storage::<u32>::from_slice(&[5, 6]);
        assert_eq!((w.load(1), w.load(u32::MAX)), (6, 0));
        assert!(Storage::<u32>::default().is_empty());
        assert_eq!(w.clone(), w);
    }

    #[test]
    fn atomics_from_many_threads_lose_nothing() {
        let a = Atomics::new(2);
        let slots = Storage::<u32>::new(10_000);
        (0..10_000u32).into_par_iter().for_each(|i| {
            let at = a.atomic_add(0, 1);
            slots.store(at, i);
            a.atomic_max(1, i);
        });
        let mut seen = slots.to_vec();
        seen.sort_unstable();
        assert_eq!(seen, (0..10_000).collect::<Vec<_>>());
        assert_eq!(a.to_vec(), vec![10_000, 9_999]);
        assert_eq!(a.atomic_sub(0, 10_001), 10_000);
        assert_eq!(a.atomic_load(0), u32::MAX, "wrapping");
        assert_eq!(a.atomic_min(1, 3), 9_999);
        assert_eq!(a.atomic_exchange(1, 8), 3);
        a.atomic_store(0, 4);
        assert_eq!(a.to_vec(), vec![4, 8]);
        assert_eq!((a.atomic_add(2, 1), a.atomic_load(9)), (0, 0), "out of range");
        a.atomic_store(2, 1);
        assert_eq!(a.len(), 2);
    }
}
