//! The kernel's `Scene` as 32-bit words, to hand it to a runtime in another process (the
//! browser runtimes: the page decodes it with the same code). Every field in declaration
//! order: an array as its texel count then its texels' words, a scalar as its bits, a `Vec3`
//! as three words. The fields are walked through `kernel_dsl::Resources` (generated from
//! `Scene`'s declaration), so a new field needs no edit here.

use glam::{UVec4, Vec3, Vec4};
use kernel_dsl::{Resource, ResourceMut, Resources, Texels};

use crate::kernel::scene_data::Scene;

/// The first word of an encoded scene ("LPSC"), then the format's version.
const MAGIC: u32 = 0x4353_504c;
const VERSION: u32 = 1;

trait SceneField: Sized {
    fn put(&self, out: &mut Vec<u32>);
    fn get(words: &mut Reader<'_>, field: &str) -> Result<Self, String>;
}

struct Reader<'a>(&'a [u32]);

impl Reader<'_> {
    fn take(&mut self, n: usize, field: &str) -> Result<&[u32], String> {
        if self.0.len() < n {
            return Err(format!("the encoded scene ends inside `{field}` ({} of {n} words left)", self.0.len()));
        }
        let (head, rest) = self.0.split_at(n);
        self.0 = rest;
        Ok(head)
    }
}

impl Reader<'_> {
    /// An array's texel count, then its texels' words (four each).
    fn take_texels(&mut self, field: &str) -> Result<&[u32], String> {
        let n = self.take(1, field)?[0];
        let words = (n as usize).checked_mul(4).ok_or_else(|| format!("`{field}` claims {n} texels"))?;
        self.take(words, field)
    }
}

impl SceneField for u32 {
    fn put(&self, out: &mut Vec<u32>) {
        out.push(*self);
    }
    fn get(words: &mut Reader<'_>, field: &str) -> Result<Self, String> {
        Ok(words.take(1, field)?[0])
    }
}

impl SceneField for f32 {
    fn put(&self, out: &mut Vec<u32>) {
        out.push(self.to_bits());
    }
    fn get(words: &mut Reader<'_>, field: &str) -> Result<Self, String> {
        Ok(f32::from_bits(words.take(1, field)?[0]))
    }
}

impl SceneField for Vec3 {
    fn put(&self, out: &mut Vec<u32>) {
        out.extend(self.to_array().map(f32::to_bits));
    }
    fn get(words: &mut Reader<'_>, field: &str) -> Result<Self, String> {
        let w = words.take(3, field)?;
        Ok(Vec3::new(f32::from_bits(w[0]), f32::from_bits(w[1]), f32::from_bits(w[2])))
    }
}

impl SceneField for Texels<Vec4> {
    fn put(&self, out: &mut Vec<u32>) {
        out.push(self.len() as u32);
        out.extend(self.as_slice().iter().flat_map(|t| t.to_array().map(f32::to_bits)));
    }
    fn get(words: &mut Reader<'_>, field: &str) -> Result<Self, String> {
        let w = words.take_texels(field)?;
        Ok(Texels::new(
            w.chunks_exact(4).map(|c| Vec4::from_array([0, 1, 2, 3].map(|k| f32::from_bits(c[k])))).collect(),
        ))
    }
}

impl SceneField for Texels<UVec4> {
    fn put(&self, out: &mut Vec<u32>) {
        out.push(self.len() as u32);
        out.extend(self.as_slice().iter().flat_map(|t| t.to_array()));
    }
    fn get(words: &mut Reader<'_>, field: &str) -> Result<Self, String> {
        let w = words.take_texels(field)?;
        Ok(Texels::new(w.chunks_exact(4).map(|c| UVec4::new(c[0], c[1], c[2], c[3])).collect()))
    }
}

/// `scene` as words (see the module docs).
pub fn encode_scene(scene: &Scene) -> Vec<u32> {
    encode_resources(scene)
}

/// The scene [`encode_scene`] encoded, or why `words` is not one.
pub fn decode_scene(words: &[u32]) -> Result<Scene, String> {
    decode_resources(words)
}

/// Any `#[resources]` struct as words, as [`encode_scene`] encodes the `Scene` (e.g. the
/// denoiser's `FilterImage`, for the browser's filter passes).
pub fn encode_resources(resources: &dyn Resources) -> Vec<u32> {
    let mut out = vec![MAGIC, VERSION];
    for (_, field) in resources.fields() {
        match field {
            Resource::Vec4s(t) => t.put(&mut out),
            Resource::UVec4s(t) => t.put(&mut out),
            Resource::F32(x) => x.put(&mut out),
            Resource::U32(x) => x.put(&mut out),
            Resource::Vec3(v) => v.put(&mut out),
            // Scene words carry read-only resources (what the harness's functions read):
            // a compute struct's storage and atomics are not encoded, and `decode_resources`
            // refuses a struct that has them.
            Resource::Vec4Storage(_)
            | Resource::UVec4Storage(_)
            | Resource::U32Storage(_)
            | Resource::F32Storage(_)
            | Resource::Atomics(_) => {}
        }
    }
    out
}

/// The struct [`encode_resources`] encoded, or why `words` is not one.
pub fn decode_resources<R: Resources + Default>(words: &[u32]) -> Result<R, String> {
    if words.get(..2) != Some(&[MAGIC, VERSION][..]) {
        return Err(format!("not an encoded scene of version {VERSION} (starts {:x?})", &words[..words.len().min(2)]));
    }
    let mut reader = Reader(&words[2..]);
    let mut scene = R::default();
    for (name, field) in scene.fields_mut() {
        let r = &mut reader;
        match field {
            ResourceMut::Vec4s(t) => *t = SceneField::get(r, name)?,
            ResourceMut::UVec4s(t) => *t = SceneField::get(r, name)?,
            ResourceMut::F32(x) => *x = SceneField::get(r, name)?,
            ResourceMut::U32(x) => *x = SceneField::get(r, name)?,
            ResourceMut::Vec3(v) => *v = SceneField::get(r, name)?,
            ResourceMut::Vec4Storage(_)
            | ResourceMut::UVec4Storage(_)
            | ResourceMut::U32Storage(_)
            | ResourceMut::F32Storage(_)
            | ResourceMut::Atomics(_) => {
                return Err(format!(
                "field `{name}` is storage or atomics (a compute module's): scene words hold read-only resources only"
            ))
            }
        }
    }
    if !reader.0.is_empty() {
        return Err(format!("{} words after the encoded scene", reader.0.len()));
    }
    Ok(scene)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn scenes_round_trip_and_bad_words_are_refused() {
        let scene = Scene {
            triangles: Texels::new(vec![Vec4::new(1.0, -0.0, f32::NAN, 4.0); 3]),
            texture_info: Texels::new(vec![UVec4::new(1, 2, 3, u32::MAX)]),
            camera_up: Vec3::new(0.5, 1.5, -2.0),
            max_depth: 7,
            sky_rotation: 0.25,
            has_normal_map: 1,
            ..Scene::default()
        };
        let words = encode_scene(&scene);
        let back = decode_scene(&words).expect("decodes");
        assert_eq!(encode_scene(&back), words);
        assert_eq!(back.triangles.len(), 3);
        assert_eq!(back.triangles.as_slice()[0].y.to_bits(), (-0.0f32).to_bits());
        assert!(back.triangles.as_slice()[0].z.is_nan());
        assert_eq!((back.max_depth, back.camera_up, back.has_normal_map), (7, scene.camera_up, 1));
        assert!(decode_scene(&words[..words.len() - 1]).unwrap_err().contains("has_instances"));
        assert!(decode_scene(&[words.as_slice(), &[0]].concat()).unwrap_err().contains("after"));
        assert!(decode_scene(&words[1..]).unwrap_err().contains("not an encoded scene"));
        assert!(decode_scene(&[]).is_err());
    }
}
