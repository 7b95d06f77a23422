#[kernel_dsl::kernel]
pub mod texture_ref {
    //! Texture references (`Features::texture_transform`, `Features::texcoord1`): the UV a
    //! texture is sampled at, on the texture coordinate set it asks for (glTF `texCoord`, 0 or
    //! 1) and through its `KHR_texture_transform`.
    //!
    //! Layout (only packed for scenes that use one of the two; `Scene::texture_ref_first` and
    //! `Scene::texcoord1_first` are 0 without): with either feature, a material's texture index
    //! names a texture *reference* (an image and sampler read through one transform on one UV
    //! set; `tracer::pack` dedupes them), `texture_info` holds one entry per reference, then from
    //! `scene.texture_ref_first` `TEXTURE_REF_TEXELS` per reference: `[a, b, c, set]`,
    //! `[d, e, f, 0]` with `u' = a u + b v + c`, `v' = d u + e v + f` (f32 bits in the lanes). With
    //! `Features::texcoord1`, per triangle `TEXCOORD1_TEXELS` texels `[u0, v0, u1, v1]`,
    //! `[u2, v2, 0, 0]` of the second UV set at `scene.texcoord1_first + 2 * triangle` in
    //! `shading` (after the normals, UVs and tangents: no new binding).

    use glam::{UVec4, Vec2};

    use crate::kernel::scene_data::{texcoord, Scene};

    /// Texels per texture reference after the references' `texture_info` entries.
    pub const TEXTURE_REF_TEXELS: u32 = 2;
    /// Texels per triangle of the second UV set in `shading`.
    pub const TEXCOORD1_TEXELS: u32 = 2;

    /// The second UV set (`TEXCOORD_1`) interpolated at barycentrics (u, v).
    pub fn texcoord1(scene: &Scene, triangle: u32, u: f32, v: f32) -> Vec2 {
        let base = scene.texcoord1_first + triangle * TEXCOORD1_TEXELS;
        let a = scene.shading.fetch(base);
        let b = scene.shading.fetch(base + 1);
        Vec2::new(a.x, a.y) * (1.0 - u - v) + Vec2::new(a.z, a.w) * u + Vec2::new(b.x, b.y) * v
    }

    /// `uv` through the affine map of a reference's two texels (see the module docs).
    pub fn transform_uv(row0: UVec4, row1: UVec4, uv: Vec2) -> Vec2 {
        let u = f32::from_bits(row0.x) * uv.x + f32::from_bits(row0.y) * uv.y + f32::from_bits(row0.z);
        let v = f32::from_bits(row1.x) * uv.x + f32::from_bits(row1.y) * uv.y + f32::from_bits(row1.z);
        Vec2::new(u, v)
    }

    /// Where texture (reference) `texture` is sampled at barycentrics (u, v) of `triangle`:
    /// `texcoord` without either feature, else [`referenced_uv`].
    pub fn texture_uv(scene: &Scene, texture: u32, triangle: u32, u: f32, v: f32) -> Vec2 {
        if scene.has_texture_transform != 0 || scene.has_texcoord1 != 0 {
            referenced_uv(scene, texture, triangle, u, v)
        } else {
            texcoord(scene, triangle, u, v)
        }
    }

    /// The UV of texture reference `texture`: on its UV set, through its transform.
    pub fn referenced_uv(scene: &Scene, texture: u32, triangle: u32, u: f32, v: f32) -> Vec2 {
        let base = scene.texture_ref_first + texture * TEXTURE_REF_TEXELS;
        let row0 = scene.texture_info.fetch(base);
        let mut uv = if scene.has_texcoord1 != 0 && row0.w == 1 {
            texcoord1(scene, triangle, u, v)
        } else {
            texcoord(scene, triangle, u, v)
        };
        if scene.has_texture_transform != 0 {
            uv = transform_uv(row0, scene.texture_info.fetch(base + 1), uv);
        }
        uv
    }
}
