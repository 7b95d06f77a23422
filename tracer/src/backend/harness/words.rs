//! Kernel values as harness words: each DSL value type's layout (the path and scalar type of
//! each 32-bit word, in the order codegen flattens it) and its bits, and the check of a Rust
//! layout against the generated one.

use glam::{IVec2, IVec3, IVec4, UVec2, UVec3, UVec4, Vec2, Vec3, Vec4};
use lightport_codegen::types::Scalar;

/// A DSL value type as harness words: its layout (path and scalar type of each word, in the
/// order codegen flattens it) and its bits.
pub trait Words: Sized {
    /// Appends one [`HarnessWord`] per word, paths starting with `path`.
    fn layout(path: &str, out: &mut Vec<HarnessWord>);
    fn push_words(&self, out: &mut Vec<u32>);
    /// Reads the value from the front of `words`, advancing it. Callers check lengths against
    /// the layout first; a short slice reads zeros rather than panicking.
    fn take_words(words: &mut &[u32]) -> Self;
}

/// `path.segment` (or `segment` at the top).
#[doc(hidden)]
pub fn join(path: &str, segment: &str) -> String {
    if path.is_empty() {
        segment.to_string()
    } else {
        format!("{path}.{segment}")
    }
}

fn take_word(words: &mut &[u32]) -> u32 {
    match words.split_first() {
        Some((first, rest)) => {
            *words = rest;
            *first
        }
        None => 0,
    }
}

macro_rules! scalar_words {
    ($($ty:ty: $scalar:ident, $to:expr, $from:expr;)*) => {$(
        impl Words for $ty {
            fn layout(path: &str, out: &mut Vec<HarnessWord>) {
                out.push(HarnessWord { path: path.to_string(), scalar: Scalar::$scalar });
            }
            fn push_words(&self, out: &mut Vec<u32>) {
                let to: fn($ty) -> u32 = $to;
                out.push(to(*self));
            }
            fn take_words(words: &mut &[u32]) -> Self {
                let from: fn(u32) -> $ty = $from;
                from(take_word(words))
            }
        }
    )*};
}

scalar_words! {
    u32: U32, |x| x, |w| w;
    i32: I32, |x| x as u32, |w| w as i32;
    f32: F32, f32::to_bits, f32::from_bits;
    bool: Bool, u32::from, |w| w != 0;
}

macro_rules! vector_words {
    ($($ty:ty: $elem:ty, [$($c:ident),*];)*) => {$(
        impl Words for $ty {
            fn layout(path: &str, out: &mut Vec<HarnessWord>) {
                $(<$elem>::layout(&join(path, stringify!($c)), out);)*
            }
            fn push_words(&self, out: &mut Vec<u32>) {
                $(self.$c.push_words(out);)*
            }
            fn take_words(words: &mut &[u32]) -> Self {
                $(let $c = <$elem>::take_words(words);)*
                <$ty>::new($($c),*)
            }
        }
    )*};
}

vector_words! {
    Vec2: f32, [x, y];
    Vec3: f32, [x, y, z];
    Vec4: f32, [x, y, z, w];
    UVec2: u32, [x, y];
    UVec3: u32, [x, y, z];
    UVec4: u32, [x, y, z, w];
    IVec2: i32, [x, y];
    IVec3: i32, [x, y, z];
    IVec4: i32, [x, y, z, w];
}

impl<T: Words + Copy + Default, const N: usize> Words for [T; N] {
    fn layout(path: &str, out: &mut Vec<HarnessWord>) {
        for i in 0..N {
            T::layout(&format!("{path}[{i}]"), out);
        }
    }
    fn push_words(&self, out: &mut Vec<u32>) {
        self.iter().for_each(|x| x.push_words(out));
    }
    fn take_words(words: &mut &[u32]) -> Self {
        let mut array = [T::default(); N];
        array.iter_mut().for_each(|x| *x = T::take_words(words));
        array
    }
}

/// The layout of field `name` of a struct, its type taken from `_field` (an accessor).
#[doc(hidden)]
pub fn field_layout<S, T: Words>(_field: fn(&S) -> &T, path: &str, out: &mut Vec<HarnessWord>) {
    T::layout(path, out);
}

/// Implements [`Words`] for kernel structs, fields in the IR's declaration order. The struct
/// pattern names every field (no `..`): a new field does not compile until it is listed, and
/// a wrong order is caught by the layout check against codegen (paths carry the field names).
#[macro_export]
macro_rules! harness_struct_words {
    ($($ty:path { $($field:ident),* $(,)? })*) => {$(
        impl $crate::backend::harness::Words for $ty {
            fn layout(path: &str, out: &mut Vec<$crate::backend::harness::HarnessWord>) {
                $($crate::backend::harness::field_layout(
                    |s: &$ty| &s.$field,
                    &$crate::backend::harness::join(path, stringify!($field)),
                    out,
                );)*
            }
            fn push_words(&self, out: &mut Vec<u32>) {
                let $ty { $($field),* } = self;
                $($crate::backend::harness::Words::push_words($field, out);)*
            }
            fn take_words(words: &mut &[u32]) -> Self {
                $ty { $($field: $crate::backend::harness::Words::take_words(words)),* }
            }
        }
    )*};
}

pub use lightport_codegen::HarnessWord;

mod kernel_structs {
    use crate::kernel::alpha_mask::AlphaMaskData;
    use crate::kernel::bsdf::Bsdf;
    use crate::kernel::camera::Ray;
    use crate::kernel::instances::InstanceRay;
    use crate::kernel::integrator::{FirstHit, GuidedSample, PathState, Shading, ShadowRay, SurfaceNormals};
    use crate::kernel::intersect::TriangleHit;
    use crate::kernel::lights::LightSample;
    use crate::kernel::metal_rough::{BrdfSample, Surface};
    use crate::kernel::normal_map::NormalMapData;
    use crate::kernel::sampling::Onb;
    use crate::kernel::scene_data::{GlassData, MaterialData, MetalRoughData, TriangleData};
    use crate::kernel::textures::Footprint;
    use crate::kernel::traverse::{Hit, NodeHits};

    harness_struct_words! {
        Ray { origin, dir }
        TriangleHit { t, u, v }
        Hit { triangle, t, u, v, instance }
        NodeHits { t, entries }
        TriangleData { v0, v1, v2, material, light, masked }
        MaterialData { base_color, base_texture, emission, emissive_texture }
        Onb { tangent, bitangent, normal }
        LightSample { dir, dist, radiance, pdf, delta }
        Surface { diffuse, f0, alpha, specular }
        BrdfSample { dir, pdf, weight }
        MetalRoughData { metallic, roughness, texture, specular }
        Bsdf { kind, surface }
        Shading { p, ng, frame, wo, bsdf }
        NormalMapData { texture, scale }
        AlphaMaskData { texture, alpha, cutoff }
        Footprint { info, xs, ys, weight }
        GlassData { transmission, ior, texture, thin, sigma_a }
        GuidedSample { color, albedo, normal, emission }
        FirstHit { albedo, normal, depth, emission }
        InstanceRay { origin, dir, root }
        SurfaceNormals { ng, ns, flip, area2 }
        PathState { origin, dir, throughput, radiance, scatter_pdf, depth, rng }
        ShadowRay { origin, dir, t_max, contribution }
    }
}

/// A function's arguments or results: a tuple of [`Words`] values, element `i` being the
/// `i`-th non-resource parameter (inputs) or, for outputs, the return value followed by the
/// final value of each `&mut` parameter.
pub trait Values: Sized {
    /// One [`HarnessWord`] per word; paths start with `#i` for tuple element `i`.
    fn layout() -> Vec<HarnessWord>;
    fn push_words(&self, out: &mut Vec<u32>);
    fn take_words(words: &mut &[u32]) -> Self;
}

macro_rules! tuple_values {
    ($(($($t:ident $i:tt),*))*) => {$(
        impl<$($t: Words),*> Values for ($($t,)*) {
            fn layout() -> Vec<HarnessWord> {
                let mut out = Vec::new();
                $($t::layout(concat!("#", stringify!($i)), &mut out);)*
                out
            }
            fn push_words(&self, out: &mut Vec<u32>) {
                $(self.$i.push_words(out);)*
            }
            fn take_words(words: &mut &[u32]) -> Self {
                ($($t::take_words(words),)*)
            }
        }
    )*};
}

tuple_values! {
    (A 0)
    (A 0, B 1)
    (A 0, B 1, C 2)
    (A 0, B 1, C 2, D 3)
    (A 0, B 1, C 2, D 3, E 4)
    (A 0, B 1, C 2, D 3, E 4, F 5)
}

/// The top-level segment of a path (`origin` of `origin.x`, `#0` of `#0.x`) and the rest.
pub(super) fn split_top(path: &str) -> (&str, &str) {
    match path.find(['.', '[']) {
        Some(i) => (&path[..i], &path[i..]),
        None => (path, ""),
    }
}

fn same_scalar(a: Scalar, b: Scalar) -> bool {
    let word = |s| if s == Scalar::USize { Scalar::U32 } else { s };
    word(a) == word(b)
}

/// Checks that `rust` (from [`Values::layout`]) matches `generated` (codegen's): same words,
/// same scalar types, same paths below the top level, and the same grouping into top-level
/// values (parameters / results).
pub fn check_layout(what: &str, rust: &[HarnessWord], generated: &[HarnessWord]) -> Result<(), String> {
    let describe = |l: &[HarnessWord]| l.iter().map(|w| format!("{} {:?}", w.path, w.scalar)).collect::<Vec<_>>();
    if rust.len() != generated.len() {
        return Err(format!(
            "{what}: the Rust values have {} words, the shader {} (Rust {:?}; shader {:?})",
            rust.len(),
            generated.len(),
            describe(rust),
            describe(generated)
        ));
    }
    for (i, (r, g)) in rust.iter().zip(generated).enumerate() {
        let (r_top, r_rest) = split_top(&r.path);
        let (g_top, g_rest) = split_top(&g.path);
        let same_group = i == 0 || {
            let (pr, _) = split_top(&rust[i - 1].path);
            let (pg, _) = split_top(&generated[i - 1].path);
            (pr == r_top) == (pg == g_top)
        };
        if !same_scalar(r.scalar, g.scalar) || r_rest != g_rest || !same_group {
            return Err(format!(
                "{what} word {i}: Rust `{}` ({:?}) vs shader `{}` ({:?})",
                r.path, r.scalar, g.path, g.scalar
            ));
        }
    }
    Ok(())
}
