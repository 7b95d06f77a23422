#[kernel_dsl::kernel]
pub mod alpha_mask {
    //! Alpha masks.
    //!
    //! glTF `alphaMode` MASK (`Features::alpha_mask`): texels whose coverage (base colour
    //! alpha, `baseColorFactor.a` times the base colour texture's alpha at the hit) is below
    //! the material's `alphaCutoff` are holes for every ray. The test runs in traversal, out of
    //! its loop (`traverse_masked::closest_visible_one_level`, `occluded_masked_one_level`), so
    //! a rejected hit lets the ray go on to the next candidate, and in light sampling (a point
    //! sampled in a hole of an emitter emits nothing).
    //!
    //! Layout (only packed for scenes with masked materials; `Scene::alpha_mask_first` is 0
    //! without): per triangle, the w of its third texel in `triangles` is 1 when its material is
    //! masked (else 0, as without the feature), so unmasked triangles cost one comparison of a
    //! texel traversal has already fetched; per material one texel
    //! `[base colour texture or -1, baseColorFactor.a, alphaCutoff, 0]` at
    //! `scene.alpha_mask_first + material` in `materials` (after the base texels and the normal
    //! maps: an extension of that array, not a new binding).

    use glam::Vec2;

    use crate::kernel::scene_data::{index_of, Scene, NONE};
    use crate::kernel::texture_ref::texture_uv;
    use crate::kernel::textures::bilinear_alpha;

    /// A masked material's coverage inputs (`Scene::materials` beyond the base texels).
    #[derive(Clone, Copy, Debug, PartialEq)]
    pub struct AlphaMaskData {
        /// Base colour texture (its alpha multiplies `alpha`) or NONE.
        pub texture: u32,
        /// `baseColorFactor.a`.
        pub alpha: f32,
        /// Coverage below this is a hole.
        pub cutoff: f32,
    }

    pub fn fetch_alpha_mask(scene: &Scene, material: u32) -> AlphaMaskData {
        let t = scene.materials.fetch(scene.alpha_mask_first + material);
        AlphaMaskData { texture: index_of(t.x), alpha: t.y, cutoff: t.z }
    }

    /// Coverage of `mask` at texture coordinates `uv`: the factor times the texture's alpha.
    pub fn coverage(scene: &Scene, mask: AlphaMaskData, uv: Vec2) -> f32 {
        let mut a = mask.alpha;
        if scene.has_textures != 0 && mask.texture != NONE {
            a *= bilinear_alpha(scene, mask.texture, uv);
        }
        a
    }

    /// Whether the point at barycentrics (u, v) of triangle `triangle` (material `material`)
    /// is a hole: the triangle is masked (`TriangleData::masked`, which the caller has
    /// fetched and tests first) and its coverage there is below the cutoff (a NaN coverage is
    /// opaque).
    pub fn is_hole(scene: &Scene, triangle: u32, material: u32, u: f32, v: f32) -> bool {
        let mask = fetch_alpha_mask(scene, material);
        let mut uv = Vec2::ZERO;
        if scene.has_shading != 0 && mask.texture != NONE {
            // The base colour texture's UV: its UV set and transform, as shading reads it.
            uv = texture_uv(scene, mask.texture, triangle, u, v);
        }
        coverage(scene, mask, uv) < mask.cutoff
    }
}
