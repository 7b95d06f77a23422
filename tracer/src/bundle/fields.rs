//! Each field of [`Packed`] as an entry under its path: texel arrays, uniforms, flags, counts,
//! and the kernel's `Scene` and `Features` walked through their one declaration each.

use std::borrow::Cow;

use glam::{UVec4, Vec3, Vec4};
use kernel_dsl::{Resource, ResourceMut, Resources, Texels};

use super::format::{f32s, u32s, ElementType, Reader, Writer};
use super::BundleError;
use crate::kernel::features::Features;
use crate::kernel::scene_data::Scene;
use crate::pack::Packed;

/// A value stored in a bundle under a name.
pub(super) trait Field: Sized {
    fn write(&self, name: &str, w: &mut Writer);
    fn read(name: &str, r: &mut Reader) -> Result<Self, BundleError>;
}

/// A fixed-size texel or vector: `COMPONENTS` elements of one type.
trait Texel: Copy + Default {
    const ELEMENT: ElementType;
    const COMPONENTS: u8;
    fn put(&self, out: &mut Vec<u8>);
    fn get(data: &[u8]) -> Vec<Self>;
}

impl Texel for Vec4 {
    const ELEMENT: ElementType = ElementType::F32;
    const COMPONENTS: u8 = 4;
    fn put(&self, out: &mut Vec<u8>) {
        for c in self.to_array() {
            out.extend_from_slice(&c.to_le_bytes());
        }
    }
    fn get(data: &[u8]) -> Vec<Self> {
        let v: Vec<f32> = f32s(data).collect();
        v.chunks_exact(4).map(Vec4::from_slice).collect()
    }
}

impl Texel for UVec4 {
    const ELEMENT: ElementType = ElementType::U32;
    const COMPONENTS: u8 = 4;
    fn put(&self, out: &mut Vec<u8>) {
        for c in self.to_array() {
            out.extend_from_slice(&c.to_le_bytes());
        }
    }
    fn get(data: &[u8]) -> Vec<Self> {
        let v: Vec<u32> = u32s(data).collect();
        v.chunks_exact(4).map(UVec4::from_slice).collect()
    }
}

impl Texel for Vec3 {
    const ELEMENT: ElementType = ElementType::F32;
    const COMPONENTS: u8 = 3;
    fn put(&self, out: &mut Vec<u8>) {
        for c in self.to_array() {
            out.extend_from_slice(&c.to_le_bytes());
        }
    }
    fn get(data: &[u8]) -> Vec<Self> {
        let v: Vec<f32> = f32s(data).collect();
        v.chunks_exact(3).map(Vec3::from_slice).collect()
    }
}

impl Texel for f32 {
    const ELEMENT: ElementType = ElementType::F32;
    const COMPONENTS: u8 = 1;
    fn put(&self, out: &mut Vec<u8>) {
        out.extend_from_slice(&self.to_le_bytes());
    }
    fn get(data: &[u8]) -> Vec<Self> {
        f32s(data).collect()
    }
}

impl Texel for u32 {
    const ELEMENT: ElementType = ElementType::U32;
    const COMPONENTS: u8 = 1;
    fn put(&self, out: &mut Vec<u8>) {
        out.extend_from_slice(&self.to_le_bytes());
    }
    fn get(data: &[u8]) -> Vec<Self> {
        u32s(data).collect()
    }
}

impl<T: Texel> Field for Texels<T> {
    fn write(&self, name: &str, w: &mut Writer) {
        w.entry(name, T::ELEMENT, T::COMPONENTS, self.len() as u64, |out| {
            for t in self.as_slice() {
                t.put(out);
            }
        });
    }
    fn read(name: &str, r: &mut Reader) -> Result<Self, BundleError> {
        Ok(Texels::new(T::get(r.take(name, T::ELEMENT, T::COMPONENTS)?.data()?)))
    }
}

/// Uniforms: one texel-like value.
macro_rules! single_value_fields {
    ($($ty:ty),*) => {$(
        impl Field for $ty {
            fn write(&self, name: &str, w: &mut Writer) {
                w.entry(name, <$ty as Texel>::ELEMENT, <$ty as Texel>::COMPONENTS, 1, |out| self.put(out));
            }
            fn read(name: &str, r: &mut Reader) -> Result<Self, BundleError> {
                let data = r.scalar(name, <$ty as Texel>::ELEMENT, <$ty as Texel>::COMPONENTS)?;
                Ok(<$ty as Texel>::get(data)[0])
            }
        }
    )*};
}
single_value_fields!(Vec3, f32, u32);

impl Field for bool {
    fn write(&self, name: &str, w: &mut Writer) {
        w.entry(name, ElementType::U8, 1, 1, |out| out.push(*self as u8));
    }
    fn read(name: &str, r: &mut Reader) -> Result<Self, BundleError> {
        match r.scalar(name, ElementType::U8, 1)?[0] {
            0 => Ok(false),
            1 => Ok(true),
            v => Err(BundleError::InvalidValue { field: name.to_string(), reason: format!("flag {v} is not 0 or 1") }),
        }
    }
}

impl Field for usize {
    fn write(&self, name: &str, w: &mut Writer) {
        w.entry(name, ElementType::U64, 1, 1, |out| out.extend_from_slice(&(*self as u64).to_le_bytes()));
    }
    fn read(name: &str, r: &mut Reader) -> Result<Self, BundleError> {
        let data = r.scalar(name, ElementType::U64, 1)?;
        let v = u64::from_le_bytes(data.try_into().expect("a u64 entry of count 1 holds 8 bytes"));
        usize::try_from(v).map_err(|_| BundleError::InvalidValue {
            field: name.to_string(),
            reason: format!("{v} does not fit this platform's usize"),
        })
    }
}

impl Field for String {
    fn write(&self, name: &str, w: &mut Writer) {
        w.entry(name, ElementType::U8, 1, self.len() as u64, |out| out.extend_from_slice(self.as_bytes()));
    }
    fn read(name: &str, r: &mut Reader) -> Result<Self, BundleError> {
        let data = r.take(name, ElementType::U8, 1)?.data()?;
        String::from_utf8(data.to_vec())
            .map_err(|_| BundleError::InvalidValue { field: name.to_string(), reason: "not UTF-8".into() })
    }
}

fn field_name(prefix: &str, field: &str) -> String {
    if prefix.is_empty() {
        field.to_string()
    } else {
        format!("{prefix}.{field}")
    }
}

/// The packed scene, field by field, except that the texture atlas travels as its images
/// ([`super::textures`]) and the sky as its file ([`super::sky`]): `scene.texture_texels`,
/// `scene.sky` and `scene.sky_rows` are stored empty when there are images or a file, and
/// decoded from them on reading.
impl Field for Packed {
    fn write(&self, prefix: &str, w: &mut Writer) {
        let Packed { scene, features, triangle_count, light_count, texture_images, sky_file } = self;
        let name = |field| field_name(prefix, field);
        let mut stored = Cow::Borrowed(scene);
        if !texture_images.is_empty() {
            stored.to_mut().texture_texels = Texels::default();
        }
        if sky_file.is_some() {
            let scene = stored.to_mut();
            (scene.sky, scene.sky_rows) = (Texels::default(), Texels::default());
        }
        stored.write(&name("scene"), w);
        features.write(&name("features"), w);
        triangle_count.write(&name("triangle_count"), w);
        light_count.write(&name("light_count"), w);
        super::textures::write(texture_images, &scene.texture_texels, w);
        super::sky::write(sky_file.as_ref(), w);
    }
    fn read(prefix: &str, r: &mut Reader) -> Result<Self, BundleError> {
        let name = |field| field_name(prefix, field);
        let mut scene = Scene::read(&name("scene"), r)?;
        let features = Features::read(&name("features"), r)?;
        let triangle_count = usize::read(&name("triangle_count"), r)?;
        let light_count = usize::read(&name("light_count"), r)?;
        let (atlas, texture_images) = super::textures::read(r)?;
        if !texture_images.is_empty() {
            if !scene.texture_texels.is_empty() {
                return Err(BundleError::Inconsistent("the texture atlas is stored as texels and as images".into()));
            }
            scene.texture_texels = atlas;
        }
        let sky_file = super::sky::read(r, &mut scene)?;
        Ok(Packed { scene, features, triangle_count, light_count, texture_images, sky_file })
    }
}
/// The feature flags, each under `<prefix>.<flag>` in declaration order, then the stack size.
impl Field for Features {
    fn write(&self, prefix: &str, w: &mut Writer) {
        for flag in self.flags() {
            flag.on.write(&field_name(prefix, flag.name), w);
        }
        self.traversal_stack.write(&field_name(prefix, "traversal_stack"), w);
    }
    fn read(prefix: &str, r: &mut Reader) -> Result<Self, BundleError> {
        let mut features = Features::default();
        for (flag, on) in features.flags_mut() {
            *on = Field::read(&field_name(prefix, flag), r)?;
        }
        features.traversal_stack = Field::read(&field_name(prefix, "traversal_stack"), r)?;
        Ok(features)
    }
}
/// The kernel's `Scene`, each field under `<prefix>.<field>` in declaration order, walked
/// through `kernel_dsl::Resources` (generated from `Scene`'s one declaration).
impl Field for Scene {
    fn write(&self, prefix: &str, w: &mut Writer) {
        for (field, value) in self.fields() {
            let name = field_name(prefix, field);
            match value {
                Resource::Vec4s(t) => t.write(&name, w),
                Resource::UVec4s(t) => t.write(&name, w),
                Resource::F32(x) => x.write(&name, w),
                Resource::U32(x) => x.write(&name, w),
                Resource::Vec3(v) => v.write(&name, w),
                // Unreachable by construction: `Scene` is the resources of a rendering kernel
                // (GLSL and WGSL), which has no storage or atomics (compute modules only).
                Resource::Vec4Storage(_)
                | Resource::UVec4Storage(_)
                | Resource::U32Storage(_)
                | Resource::F32Storage(_)
                | Resource::Atomics(_) => {}
            }
        }
    }
    fn read(prefix: &str, r: &mut Reader) -> Result<Self, BundleError> {
        let mut scene = Scene::default();
        for (field, slot) in scene.fields_mut() {
            let name = field_name(prefix, field);
            match slot {
                ResourceMut::Vec4s(t) => *t = Field::read(&name, r)?,
                ResourceMut::UVec4s(t) => *t = Field::read(&name, r)?,
                ResourceMut::F32(x) => *x = Field::read(&name, r)?,
                ResourceMut::U32(x) => *x = Field::read(&name, r)?,
                ResourceMut::Vec3(v) => *v = Field::read(&name, r)?,
                // Unreachable by construction, as in `write`: `Scene` has no storage or atomics.
                ResourceMut::Vec4Storage(_)
                | ResourceMut::UVec4Storage(_)
                | ResourceMut::U32Storage(_)
                | ResourceMut::F32Storage(_)
                | ResourceMut::Atomics(_) => {}
            }
        }
        Ok(scene)
    }
}
