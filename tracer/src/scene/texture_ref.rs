//! How a material reads one of its textures: which texture coordinate set (`TEXCOORD_0` or
//! `TEXCOORD_1`) and glTF's `KHR_texture_transform` (offset, rotation, scale) on it.
//!
//! The transform is the extension's `T * R * S` on `(u, v, 1)`. Its rotation turns the UVs
//! counter-clockwise by `rotation` radians in the extension's own sense, which its example
//! pins down: `offset [0, 1]`, `rotation pi/2`, `scale [0.5, 0.5]` "utilizes only the lower
//! left quadrant of the source image, rotated clockwise 90°", i.e. `u' = 0.5 v`,
//! `v' = 1 - 0.5 u`. So `u' = sx (cos r) u + sy (sin r) v + ox` and
//! `v' = -sx (sin r) u + sy (cos r) v + oy` (the README's `mat3` literal read row by row;
//! three.js and the sample viewer agree, and `TextureTransformTest`'s green marker is this).

use glam::{Vec2, Vec3};
use serde_json::Value;

/// The texture coordinate sets the kernel carries.
pub const TEXCOORD_SETS: u32 = 2;

/// A texture reference's coordinate set and transform. The default reads `TEXCOORD_0` as it is.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct UvTransform {
    /// 0: `TEXCOORD_0` ([`super::Triangle::uvs`]), 1: `TEXCOORD_1` ([`super::Triangle::uvs1`]).
    pub texcoord: u32,
    pub offset: Vec2,
    /// Radians (see the module docs for the direction).
    pub rotation: f32,
    pub scale: Vec2,
}

impl Default for UvTransform {
    fn default() -> Self {
        UvTransform { texcoord: 0, offset: Vec2::ZERO, rotation: 0.0, scale: Vec2::ONE }
    }
}

impl UvTransform {
    /// Whether offset, rotation and scale leave UVs unchanged (the coordinate set aside).
    pub fn is_identity(&self) -> bool {
        self.offset == Vec2::ZERO && self.rotation == 0.0 && self.scale == Vec2::ONE
    }

    /// The two rows of the affine matrix: `u' = rows[0] . (u, v, 1)`, `v' = rows[1] . (u, v, 1)`.
    pub fn rows(&self) -> [Vec3; 2] {
        let (s, c) = self.rotation.sin_cos();
        let (sx, sy) = (self.scale.x, self.scale.y);
        [Vec3::new(c * sx, s * sy, self.offset.x), Vec3::new(-s * sx, c * sy, self.offset.y)]
    }

    /// `uv` transformed (what the kernel computes, in f32).
    pub fn apply(&self, uv: Vec2) -> Vec2 {
        let [a, b] = self.rows();
        Vec2::new(a.dot(uv.extend(1.0)), b.dot(uv.extend(1.0)))
    }

    /// Whether every number (and the matrix made of them) is finite.
    pub fn is_finite(&self) -> bool {
        self.offset.is_finite()
            && self.rotation.is_finite()
            && self.scale.is_finite()
            && self.rows().iter().all(|r| r.is_finite())
    }
}

/// Whether `m` samples some texture on `TEXCOORD_1`.
pub fn uses_texcoord1(m: &super::Material) -> bool {
    m.texture_slots().iter().zip(&m.texture_uvs).any(|(t, uv)| t.is_some() && uv.texcoord == 1)
}

/// Removes from `m` the textures it reads on `TEXCOORD_1` (for geometry that has none).
pub fn drop_texcoord1_textures(m: &mut super::Material) {
    let uvs = m.texture_uvs;
    for (slot, uv) in m.texture_slots_mut().into_iter().zip(uvs) {
        if uv.texcoord == 1 {
            *slot = None;
        }
    }
}

/// A glTF textureInfo's coordinate set and `KHR_texture_transform` (from its extension JSON,
/// `ext`). A transform whose numbers are not all finite numbers of the right shape is refused
/// with a message naming `what`; its `texCoord` overrides the textureInfo's `tex_coord`.
pub fn parse_gltf(tex_coord: u32, ext: Option<&Value>, what: &str) -> Result<UvTransform, String> {
    let mut t = UvTransform { texcoord: tex_coord, ..Default::default() };
    let Some(ext) = ext else {
        return Ok(t);
    };
    let obj = ext.as_object().ok_or_else(|| format!("{what}: KHR_texture_transform is not an object"))?;
    let number = |v: &Value, name: &str| -> Result<f32, String> {
        let x = v.as_f64().ok_or_else(|| format!("{what}: KHR_texture_transform {name} is not a number"))?;
        let x32 = x as f32;
        if !x32.is_finite() {
            return Err(format!("{what}: KHR_texture_transform {name} = {x} is not a finite f32"));
        }
        Ok(x32)
    };
    let pair = |name: &str| -> Result<Option<Vec2>, String> {
        let Some(v) = obj.get(name) else { return Ok(None) };
        match v.as_array().map(Vec::as_slice) {
            Some([x, y]) => Ok(Some(Vec2::new(number(x, name)?, number(y, name)?))),
            _ => Err(format!("{what}: KHR_texture_transform {name} must be an array of two numbers")),
        }
    };
    if let Some(o) = pair("offset")? {
        t.offset = o;
    }
    if let Some(s) = pair("scale")? {
        t.scale = s;
    }
    if let Some(r) = obj.get("rotation") {
        t.rotation = number(r, "rotation")?;
    }
    if let Some(set) = obj.get("texCoord") {
        t.texcoord = set
            .as_u64()
            .and_then(|s| u32::try_from(s).ok())
            .ok_or_else(|| format!("{what}: KHR_texture_transform texCoord {set} is not a non-negative integer"))?;
    }
    if !t.is_finite() {
        return Err(format!("{what}: KHR_texture_transform gives a matrix that is not finite"));
    }
    Ok(t)
}

#[cfg(test)]
mod tests {
    use serde_json::json;

    use super::*;

    #[test]
    fn the_extension_example_reads_the_lower_left_quadrant_rotated_clockwise() {
        let ext = json!({ "offset": [0, 1], "rotation": std::f32::consts::FRAC_PI_2, "scale": [0.5, 0.5] });
        let t = parse_gltf(0, Some(&ext), "m").unwrap();
        for (uv, want) in [((0.0, 0.0), (0.0, 1.0)), ((1.0, 0.0), (0.0, 0.5)), ((0.0, 1.0), (0.5, 1.0))] {
            let got = t.apply(Vec2::from(uv));
            assert!((got - Vec2::from(want)).length() < 1e-6, "{uv:?} -> {got} (want {want:?})");
        }
    }

    #[test]
    fn refuses_bad_numbers_and_shapes() {
        for bad in [
            json!({ "offset": [0, 1e39] }),
            json!({ "scale": [1] }),
            json!({ "rotation": "1" }),
            json!({ "texCoord": -1 }),
            json!(3),
        ] {
            let e = parse_gltf(0, Some(&bad), "material 0 baseColorTexture").unwrap_err();
            assert!(e.starts_with("material 0 baseColorTexture: KHR_texture_transform"), "{e}");
        }
        // A finite scale whose matrix is still finite is fine, as is the override.
        let t = parse_gltf(0, Some(&json!({ "scale": [2, 3], "texCoord": 1 })), "m").unwrap();
        assert_eq!((t.scale, t.texcoord), (Vec2::new(2.0, 3.0), 1));
    }
}
