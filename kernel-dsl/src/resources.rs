//! The fields of a `#[resources]` struct as values a host can walk: the `#[kernel]` macro
//! implements [`Resources`] for the struct, so a runtime's bindings, the bundle's encoding
//! and the test harness's scene words come from the struct's one declaration instead of
//! lists typed by hand.

use glam::{UVec4, Vec3, Vec4};

use crate::{Atomics, Storage, Texels};

/// One field of a `#[resources]` struct, borrowed.
#[derive(Clone, Copy, Debug)]
pub enum Resource<'a> {
    /// Float texels: a data texture (RGBA32F) or a storage buffer of `vec4<f32>`.
    Vec4s(&'a Texels<Vec4>),
    /// Integer texels: a data texture (RGBA32UI) or a storage buffer of `vec4<u32>`.
    UVec4s(&'a Texels<UVec4>),
    F32(&'a f32),
    U32(&'a u32),
    Vec3(&'a Vec3),
    /// Read-write storage of a compute module (`#[kernel(compute)]`): WGSL and the CPU only.
    Vec4Storage(&'a Storage<Vec4>),
    UVec4Storage(&'a Storage<UVec4>),
    U32Storage(&'a Storage<u32>),
    F32Storage(&'a Storage<f32>),
    /// Atomic counters of a compute module: WGSL and the CPU only.
    Atomics(&'a Atomics),
}

/// One field of a `#[resources]` struct, borrowed mutably (to fill a default struct).
#[derive(Debug)]
pub enum ResourceMut<'a> {
    Vec4s(&'a mut Texels<Vec4>),
    UVec4s(&'a mut Texels<UVec4>),
    F32(&'a mut f32),
    U32(&'a mut u32),
    Vec3(&'a mut Vec3),
    Vec4Storage(&'a mut Storage<Vec4>),
    UVec4Storage(&'a mut Storage<UVec4>),
    U32Storage(&'a mut Storage<u32>),
    F32Storage(&'a mut Storage<f32>),
    Atomics(&'a mut Atomics),
}

impl Resource<'_> {
    /// The field's type as the kernel source (and the IR) spells it.
    pub fn dsl_type(&self) -> &'static str {
        match self {
            Resource::Vec4s(_) => "Texels<Vec4>",
            Resource::UVec4s(_) => "Texels<UVec4>",
            Resource::F32(_) => "f32",
            Resource::U32(_) => "u32",
            Resource::Vec3(_) => "Vec3",
            Resource::Vec4Storage(_) => "Storage<Vec4>",
            Resource::UVec4Storage(_) => "Storage<UVec4>",
            Resource::U32Storage(_) => "Storage<u32>",
            Resource::F32Storage(_) => "Storage<f32>",
            Resource::Atomics(_) => "Atomics",
        }
    }

    /// A read-write field of a compute module (storage or atomics), which only WGSL and the CPU
    /// have: a scene's read-only paths (data textures, bundles, GL uniforms) refuse it.
    pub fn is_compute(&self) -> bool {
        matches!(
            self,
            Resource::Vec4Storage(_)
                | Resource::UVec4Storage(_)
                | Resource::U32Storage(_)
                | Resource::F32Storage(_)
                | Resource::Atomics(_)
        )
    }

    /// Texel count of a texel array; `None` for a uniform.
    pub fn texels(&self) -> Option<usize> {
        match self {
            Resource::Vec4s(t) => Some(t.len()),
            Resource::UVec4s(t) => Some(t.len()),
            _ => None,
        }
    }
}

/// A type a `#[resources]` field may have. A field of any other type is a compile error at
/// the struct (this trait is not implemented for it).
pub trait ResourceField {
    fn resource(&self) -> Resource<'_>;
    fn resource_mut(&mut self) -> ResourceMut<'_>;
}

macro_rules! resource_field {
    ($($ty:ty => $variant:ident),* $(,)?) => {$(
        impl ResourceField for $ty {
            fn resource(&self) -> Resource<'_> {
                Resource::$variant(self)
            }
            fn resource_mut(&mut self) -> ResourceMut<'_> {
                ResourceMut::$variant(self)
            }
        }
    )*};
}
resource_field!(
    Texels<Vec4> => Vec4s,
    Texels<UVec4> => UVec4s,
    f32 => F32,
    u32 => U32,
    Vec3 => Vec3,
    Storage<Vec4> => Vec4Storage,
    Storage<UVec4> => UVec4Storage,
    Storage<u32> => U32Storage,
    Storage<f32> => F32Storage,
    Atomics => Atomics,
);

/// A `#[resources]` struct's fields by name, in declaration order (implemented by `#[kernel]`).
pub trait Resources {
    fn fields(&self) -> Vec<(&'static str, Resource<'_>)>;
    fn fields_mut(&mut self) -> Vec<(&'static str, ResourceMut<'_>)>;
}
