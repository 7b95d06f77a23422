#[kernel_dsl::kernel]
pub mod scene_data {
    //! The packed scene as the kernel reads it: one `#[resources]` struct (data textures and
    //! uniforms) and the functions that decode its texels (texture lookups: `kernel::textures`;
    //! alpha masks: `kernel::alpha_mask`). `tracer::pack` writes exactly this
    //! layout, using the constants below. Integers stored in float texels are exact float values
    //! (< 2^24), never raw bits: bit patterns of small integers are denormals, which GPUs may flush.

    use glam::{UVec4, Vec2, Vec3, Vec4, Vec4Swizzles};
    use kernel_dsl::Texels;

    /// Texels per triangle in `triangles`: `[v0, material]`, `[v1, light index or -1]`, `[v2, alpha-masked 1 or 0]`.
    pub const TRIANGLE_TEXELS: u32 = 3;
    /// Texels per triangle in `shading`: `[n0, u0]`, `[n1, v0]`, `[n2, u1]`, `[v1, u2, v2, 0]`.
    pub const SHADING_TEXELS: u32 = 4;
    /// Texels per node of the 4-wide BVH in `nodes`, one lane per child: the box planes
    /// `[min x]`, `[max x]`, `[min y]`, `[max y]`, `[min z]`, `[max z]`. Unused slots have an
    /// empty box (min `f32::MAX`, max `-f32::MAX`) that every ray misses. Node 0 is the root.
    /// The children themselves are in `node_children` (one texel per node).
    pub const NODE_TEXELS: u32 = 6;
    /// Texels per material: `[base colour, base texture or -1]`, `[emission, emissive texture or -1]`.
    pub const MATERIAL_TEXELS: u32 = 2;
    /// Texels per light: `[alias threshold, alias index, pmf, kind]`, then by kind: a triangle
    /// `[triangle index, unit front normal]`, `[area, 0, 0, 0]` (fixed per light, so light
    /// sampling does not recompute them); a point light `[position, 0]`, `[intensity, 0]`; the
    /// sky two zero texels.
    pub const LIGHT_TEXELS: u32 = 3;
    pub const LIGHT_TRIANGLE: u32 = 0;
    pub const LIGHT_POINT: u32 = 1;
    pub const LIGHT_SKY: u32 = 2;
    /// Texels per element of `texture_texels` (one `u32` each in a `UVec4`).
    pub const TEXTURE_TEXELS_PER_ELEMENT: u32 = 4;
    /// No index (stored as -1.0 in float texels).
    pub const NONE: u32 = 0xffffffff;
    pub const WRAP_REPEAT: u32 = 0;
    pub const WRAP_CLAMP: u32 = 1;
    pub const WRAP_MIRROR: u32 = 2;

    /// Everything the kernel reads. On the CPU the `Texels` are slices of the packed arrays; in
    /// GLSL they are data textures (`scene_<field>`) and the scalars are uniforms.
    #[resources]
    #[derive(Clone, Debug, Default)]
    pub struct Scene {
        pub triangles: Texels<Vec4>,
        pub shading: Texels<Vec4>,
        /// Two-level scenes (`Features::instances`) append their instances (`kernel::instances`).
        pub nodes: Texels<Vec4>,
        /// Per node, its four children's stack entries (`traverse::stack_entry`): integers, not floats.
        pub node_children: Texels<UVec4>,
        pub materials: Texels<Vec4>,
        pub lights: Texels<Vec4>,
        /// Texels of every texture (8-bit RGBA as in the file, red low), 4 per element, each from a new element.
        pub texture_texels: Texels<UVec4>,
        /// Per texture (or reference: `kernel::texture_ref`): `[first texel, width, height, wrap_s | wrap_t << 8]`.
        pub texture_info: Texels<UVec4>,
        /// Equirectangular sky: `[radiance, conditional CDF within the row]`; `sky_rows`: `[marginal CDF,
        /// row guide, ...]` per row, then the column guides (the layout: `tracer::pack::sky`).
        pub sky: Texels<Vec4>,
        pub sky_rows: Texels<Vec4>,
        /// Per material, `[metallic, roughness, metal-roughness texture or -1, specular (1) or Lambert (0)]`.
        pub metal_rough: Texels<Vec4>,
        pub tangent_first: u32,
        pub normal_map_first: u32,
        pub alpha_mask_first: u32,
        pub texture_ref_first: u32,
        pub texcoord1_first: u32,
        /// Where the glass section of `materials` starts (`Features::transmission`; 0 without).
        pub transmission_first: u32,
        /// Where the instances start in `nodes` (`Features::instances`, `kernel::instances`; 0 without).
        pub instance_first: u32,
        /// The camera: `camera_right` scaled by tan(fov/2) * aspect, `camera_up` by tan(fov/2).
        pub camera_position: Vec3,
        pub camera_right: Vec3,
        pub camera_up: Vec3,
        pub camera_forward: Vec3,
        pub lens_radius: f32,
        pub focus_distance: f32,
        pub width: u32,
        pub height: u32,
        pub frame_seed: u32,
        /// Frames rendered before this one since the accumulation restarted (`rng::pixel_jitter`).
        pub frame_index: u32,
        pub max_depth: u32,
        /// 0: BSDF sampling only, 1: next event estimation only, 2: MIS (power heuristic).
        pub strategy: u32,
        pub light_count: u32,
        pub sky_width: u32,
        pub sky_height: u32,
        pub sky_intensity: f32,
        pub sky_rotation: f32,
        /// Largest absolute coordinate of the scene: scales self-intersection offsets.
        pub scene_scale: f32,
        /// Closest-hit traversal pushes leaves below this stack depth, intersects them beyond (`tracer::pack`).
        pub leaf_stack_limit: u32,
        /// Feature flags (0 or 1): codegen specialises on them, removing unused features' code and data.
        pub has_sky: u32,
        pub has_textures: u32,
        pub has_shading: u32,
        pub has_lights: u32,
        pub has_triangle_lights: u32,
        pub has_point_lights: u32,
        pub has_metal_rough: u32,
        pub has_normal_map: u32,
        pub has_alpha_mask: u32,
        pub has_texture_transform: u32,
        pub has_texcoord1: u32,
        pub has_transmission: u32,
        pub has_volume: u32,
        pub has_denoise_guide: u32,
        pub has_instances: u32,
    }

    pub const STRATEGY_BSDF: u32 = 0;
    pub const STRATEGY_NEE: u32 = 1;
    pub const STRATEGY_MIS: u32 = 2;

    /// A triangle's vertices and indices, as the kernel needs them.
    #[derive(Clone, Copy, Debug, PartialEq)]
    pub struct TriangleData {
        pub v0: Vec3,
        pub v1: Vec3,
        pub v2: Vec3,
        pub material: u32,
        /// Index in the light table, or NONE.
        pub light: u32,
        /// Its material is alpha-masked (`Features::alpha_mask`; always false without).
        pub masked: bool,
    }

    #[derive(Clone, Copy, Debug, PartialEq)]
    pub struct MaterialData {
        pub base_color: Vec3,
        pub base_texture: u32,
        pub emission: Vec3,
        pub emissive_texture: u32,
    }

    /// A float texel component holding an index (-1 for none).
    pub fn index_of(x: f32) -> u32 {
        if x < 0.0 {
            NONE
        } else {
            x as u32
        }
    }

    pub fn fetch_triangle(scene: &Scene, index: u32) -> TriangleData {
        let base = index * TRIANGLE_TEXELS;
        let a = scene.triangles.fetch(base);
        let b = scene.triangles.fetch(base + 1);
        let c = scene.triangles.fetch(base + 2);
        TriangleData {
            v0: a.xyz(),
            v1: b.xyz(),
            v2: c.xyz(),
            material: index_of(a.w),
            light: index_of(b.w),
            masked: c.w > 0.0,
        }
    }

    pub fn fetch_material(scene: &Scene, index: u32) -> MaterialData {
        let a = scene.materials.fetch(index * MATERIAL_TEXELS);
        let b = scene.materials.fetch(index * MATERIAL_TEXELS + 1);
        MaterialData {
            base_color: a.xyz(),
            base_texture: index_of(a.w),
            emission: b.xyz(),
            emissive_texture: index_of(b.w),
        }
    }

    /// Interpolated shading normal (not normalised) at barycentrics (u, v).
    pub fn shading_normal(scene: &Scene, index: u32, u: f32, v: f32) -> Vec3 {
        let base = index * SHADING_TEXELS;
        let n0 = scene.shading.fetch(base).xyz();
        let n1 = scene.shading.fetch(base + 1).xyz();
        let n2 = scene.shading.fetch(base + 2).xyz();
        n0 * (1.0 - u - v) + n1 * u + n2 * v
    }

    /// Interpolated texture coordinates at barycentrics (u, v).
    pub fn texcoord(scene: &Scene, index: u32, u: f32, v: f32) -> Vec2 {
        let base = index * SHADING_TEXELS;
        let uv0 = Vec2::new(scene.shading.fetch(base).w, scene.shading.fetch(base + 1).w);
        let rest = scene.shading.fetch(base + 3);
        let uv1 = Vec2::new(scene.shading.fetch(base + 2).w, rest.x);
        let uv2 = Vec2::new(rest.y, rest.z);
        uv0 * (1.0 - u - v) + uv1 * u + uv2 * v
    }

    /// A material's metal-roughness parameters (`Scene::metal_rough`).
    #[derive(Clone, Copy, Debug, PartialEq)]
    pub struct MetalRoughData {
        pub metallic: f32,
        pub roughness: f32,
        /// Metal-roughness texture (B: metallic, G: roughness, multiplying the factors) or NONE.
        pub texture: u32,
        /// 1: the glTF model; 0: Lambert.
        pub specular: f32,
    }

    pub fn fetch_metal_rough(scene: &Scene, index: u32) -> MetalRoughData {
        let t = scene.metal_rough.fetch(index);
        MetalRoughData { metallic: t.x, roughness: t.y, texture: index_of(t.z), specular: t.w }
    }

    // ---------------------------------------------------------------------------------------
    // Glass.
    //
    // glTF `KHR_materials_transmission`, `KHR_materials_ior` and `KHR_materials_volume`
    // (`Features::transmission`, `Features::volume`; `kernel::dielectric`). Layout (only packed
    // for scenes with a transmissive material; `Scene::transmission_first` is 0 without): per
    // material two texels at `scene.transmission_first + 2 * material` in `materials`:
    // `[transmission factor, ior, transmission texture or -1, thin-walled 1 or 0]`,
    // `[absorption coefficient σa (per scene unit, RGB), 0]` (σa = −ln(attenuation colour) /
    // attenuation distance; 0 without a volume or with an infinite distance).

    /// Texels per material in the glass section of `materials`.
    pub const GLASS_TEXELS: u32 = 2;

    /// A material's glass parameters.
    #[derive(Clone, Copy, Debug, PartialEq)]
    pub struct GlassData {
        /// `transmission`: the share of the non-metallic part that is transmitted (0: opaque).
        pub transmission: f32,
        pub ior: f32,
        /// Transmission texture (red channel, linear, multiplies `transmission`) or NONE.
        pub texture: u32,
        /// No volume behind the surface: it transmits without bending.
        pub thin: bool,
        /// Beer–Lambert absorption coefficient inside the volume.
        pub sigma_a: Vec3,
    }

    pub fn fetch_glass(scene: &Scene, material: u32) -> GlassData {
        let a = scene.materials.fetch(scene.transmission_first + material * GLASS_TEXELS);
        let b = scene.materials.fetch(scene.transmission_first + material * GLASS_TEXELS + 1);
        GlassData { transmission: a.x, ior: a.y, texture: index_of(a.z), thin: a.w > 0.0, sigma_a: b.xyz() }
    }
}
