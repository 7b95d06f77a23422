#[kernel_dsl::kernel]
pub mod normal_map {
    //! glTF normal maps (`Features::normal_map`): the tangent frame from the packed tangents,
    //! the tangent-space normal from the map, and the bend that keeps the result usable.
    //!
    //! Layout (only packed for scenes with normal maps; `Scene::tangent_first` and
    //! `Scene::normal_map_first` are 0 without): per triangle, `TANGENT_TEXELS` texels
    //! `[t0, w0]`, `[t1, w1]`, `[t2, w2]` at `scene.tangent_first + 3 * triangle` in `shading`
    //! (after the per-vertex normals and UVs: an extension of that array, not a new binding);
    //! per material one texel `[normal texture or -1, scale, 0, 0]` at
    //! `scene.normal_map_first + material` in `materials` (after the base texels).
    //!
    //! A mapped normal can face away from the viewer or send the mirror reflection of the view
    //! direction below the surface (maps baked for a smoother surface, strong `scale`, grazing
    //! views). [`bend_normal`] bends such a normal towards the geometric one until the
    //! reflection of the outgoing direction lies at least `MIN_REFLECTION_COSINE` above the
    //! geometric surface, as Cycles' "ensure valid reflection" does (after Schüßler et al.,
    //! "Microfacet-based Normal Mapping for Robust Monte Carlo Path Tracing", 2017, whose
    //! problem statement it solves cheaply): the bent normal is the half vector between the
    //! view direction and that clamped reflection, so it faces the viewer, lies above the
    //! geometric surface, and normals that already satisfy the condition are left unchanged.

    use glam::{Vec3, Vec4, Vec4Swizzles};

    use crate::kernel::instances::{instance_handedness, vector_to_world};
    use crate::kernel::scene_data::{index_of, Scene, NONE};

    use crate::kernel::texture_ref::texture_uv;
    use crate::kernel::textures::sample_data_texture;
    use crate::kernel::traverse::Hit;

    /// Texels per triangle of tangents in `shading`.
    pub const TANGENT_TEXELS: u32 = 3;
    /// Least cosine between the mirror reflection of the view direction about a bent normal
    /// and the geometric normal.
    pub const MIN_REFLECTION_COSINE: f32 = 0.01;

    /// A material's normal map (`Scene::materials` beyond the base texels).
    #[derive(Clone, Copy, Debug, PartialEq)]
    pub struct NormalMapData {
        /// Texture index or NONE.
        pub texture: u32,
        pub scale: f32,
    }

    pub fn fetch_normal_map(scene: &Scene, material: u32) -> NormalMapData {
        let t = scene.materials.fetch(scene.normal_map_first + material);
        NormalMapData { texture: index_of(t.x), scale: t.y }
    }

    /// The tangent interpolated at barycentrics (u, v): xyz not normalised, w the interpolated handedness.
    pub fn interpolated_tangent(scene: &Scene, triangle: u32, u: f32, v: f32) -> Vec4 {
        let base = scene.tangent_first + triangle * TANGENT_TEXELS;
        let t0 = scene.shading.fetch(base);
        let t1 = scene.shading.fetch(base + 1);
        let t2 = scene.shading.fetch(base + 2);
        t0 * (1.0 - u - v) + t1 * u + t2 * v
    }

    /// The tangent-space normal of a normal-map texel (linear RGB in [0, 1]) with glTF's
    /// `scale` on x and y (not normalised).
    pub fn tangent_space_normal(rgb: Vec3, scale: f32) -> Vec3 {
        let m = rgb * 2.0 - Vec3::ONE;
        Vec3::new(m.x * scale, m.y * scale, m.z)
    }

    /// Tangent-space normal `m` in the frame of the unit normal `n` and `tangent` (xyz
    /// Gram-Schmidt-orthogonalised to `n`; bitangent `w * cross(n, t)`, MikkTSpace's
    /// convention): a unit vector, or `n` when the tangent or the result is degenerate.
    pub fn perturb_normal(n: Vec3, tangent: Vec4, m: Vec3) -> Vec3 {
        let t = tangent.xyz() - n * n.dot(tangent.xyz());
        let t_len = t.length();
        let mut out = n;
        if t_len > 1.0e-6 {
            let t = t / t_len;
            let sign = if tangent.w < 0.0 { -1.0 } else { 1.0 };
            let b = n.cross(t) * sign;
            let p = t * m.x + b * m.y + n * m.z;
            let len = p.length();
            if len > 1.0e-6 && len < 1.0e30 {
                out = p / len;
            }
        }
        out
    }

    /// Unit normal `n` bent so that the mirror reflection of `wo` (unit, towards the viewer)
    /// lies at least `MIN_REFLECTION_COSINE` above the surface of unit geometric normal `ng`
    /// (which faces the viewer): unchanged when it already does, else the half vector of `wo`
    /// and the reflection clamped to that height. The result always faces the viewer and
    /// lies above the geometric surface.
    pub fn bend_normal(n: Vec3, ng: Vec3, wo: Vec3) -> Vec3 {
        let cos_n = n.dot(wo);
        let r = n * (2.0 * cos_n) - wo;
        let mut out = n;
        if !(cos_n > 0.0 && ng.dot(r) >= MIN_REFLECTION_COSINE) {
            let along = r - ng * ng.dot(r);
            let along_len = along.length();
            out = ng;
            if along_len > 1.0e-6 {
                let c = MIN_REFLECTION_COSINE;
                let bent = along * ((1.0 - c * c).sqrt() / along_len) + ng * c;
                let h = wo + bent;
                let h_len = h.length();
                if h_len > 1.0e-6 {
                    out = h / h_len;
                }
            }
        }
        out
    }

    /// The shading normal at `hit` of a triangle with material `material`: the facing shading
    /// normal `ns` (times `flip` it is the front one) perturbed by the material's normal map
    /// and bent ([`bend_normal`]) for the view direction `wo`; `ns` unchanged without a map.
    pub fn normal_mapped(scene: &Scene, hit: Hit, material: u32, ns: Vec3, flip: f32, ng: Vec3, wo: Vec3) -> Vec3 {
        let map = fetch_normal_map(scene, material);
        let mut n = ns;
        if map.texture != NONE {
            let mut tangent = interpolated_tangent(scene, hit.triangle, hit.u, hit.v);
            if scene.has_instances != 0 {
                let handedness = instance_handedness(scene, hit.instance);
                tangent = vector_to_world(scene, hit.instance, tangent.xyz()).extend(tangent.w * handedness);
            }
            let uv = texture_uv(scene, map.texture, hit.triangle, hit.u, hit.v);
            let rgb = sample_data_texture(scene, map.texture, uv).xyz();
            // The map is in the front face's frame; the facing normal flips with it.
            let front = perturb_normal(ns * flip, tangent, tangent_space_normal(rgb, map.scale));
            n = bend_normal(front * flip, ng, wo);
        }
        n
    }
}
