#[kernel_dsl::kernel]
pub mod scene_data {
    //! The packed scene as the kernel reads it: one `#[resources]` struct (data textures and
    //! uniforms) and the functions that decode its texels. `tracer::pack` writes exactly this
    //! layout, using the constants below. Integers stored in float texels are exact float values
    //! (< 2^24), never raw bits: bit patterns of small integers are denormals, which GPUs may flush.

    use glam::{UVec4, Vec2, Vec3, Vec4, Vec4Swizzles};
    use kernel_dsl::Texels;

    use crate::kernel::texture_ref::texture_uv;

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
        pub nodes: Texels<Vec4>,
        /// Per node, its four children's stack entries (`traverse::stack_entry`): integers, not floats.
        pub node_children: Texels<UVec4>,
        pub materials: Texels<Vec4>,
        pub lights: Texels<Vec4>,
        /// Texels of every texture (8-bit RGBA as in the file, red low), 4 per element, each from a new element.
        pub texture_texels: Texels<UVec4>,
        /// Per texture (or reference: `kernel::texture_ref`): `[first texel, width, height, wrap_s | wrap_t << 8]`.
        pub texture_info: Texels<UVec4>,
        /// Equirectangular sky: `[radiance, conditional CDF within the row]`; `sky_rows`: `[marginal CDF, 0, 0, 0]`.
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

    /// Texel coordinate `i` of an axis of `size` texels under a wrap mode.
    pub fn wrap_coordinate(i: i32, size: i32, mode: u32) -> i32 {
        if mode == WRAP_CLAMP {
            i.clamp(0, size - 1)
        } else if mode == WRAP_MIRROR {
            let period = 2 * size;
            let m = ((i % period) + period) % period;
            if m < size {
                m
            } else {
                period - 1 - m
            }
        } else {
            ((i % size) + size) % size
        }
    }

    /// The sRGB transfer function's inverse (IEC 61966-2-1) for one channel in [0, 1].
    pub fn srgb_to_linear(c: f32) -> f32 {
        if c <= 0.04045 {
            c / 12.92
        } else {
            ((c + 0.055) / 1.055).powf(2.4)
        }
    }

    /// A packed texel (8-bit RGBA, red in the low byte, colour sRGB-encoded) as linear RGBA.
    pub fn decode_srgba8(word: u32) -> Vec4 {
        // Each byte is isolated as `x >> 24`: codegen knows such a value has at most 8 bits and
        // converts it to float directly (exact), without its rounding helper for full u32s.
        let r = ((word << 24) >> 24) as f32 / 255.0;
        let g = ((word << 16) >> 24) as f32 / 255.0;
        let b = ((word << 8) >> 24) as f32 / 255.0;
        let a = (word >> 24) as f32 / 255.0;
        Vec4::new(srgb_to_linear(r), srgb_to_linear(g), srgb_to_linear(b), a)
    }

    /// The packed word (8-bit RGBA, red in the low byte) of texel (x, y) of the texture `info`
    /// describes, the coordinates wrapped by its modes.
    pub fn texel_word(scene: &Scene, info: UVec4, x: i32, y: i32) -> u32 {
        let w = info.y as i32;
        let h = info.z as i32;
        let tx = wrap_coordinate(x, w, info.w & 255);
        let ty = wrap_coordinate(y, h, info.w >> 8);
        let i = info.x + (ty * w + tx) as u32;
        let four = scene.texture_texels.fetch(i / TEXTURE_TEXELS_PER_ELEMENT);
        let lane = i % TEXTURE_TEXELS_PER_ELEMENT;
        if lane == 0 {
            four.x
        } else if lane == 1 {
            four.y
        } else if lane == 2 {
            four.z
        } else {
            four.w
        }
    }

    /// A packed texel of a data texture (metal-roughness: no transfer function) as RGBA in [0, 1].
    pub fn decode_unorm8(word: u32) -> Vec4 {
        let r = ((word << 24) >> 24) as f32 / 255.0;
        let g = ((word << 16) >> 24) as f32 / 255.0;
        let b = ((word << 8) >> 24) as f32 / 255.0;
        let a = (word >> 24) as f32 / 255.0;
        Vec4::new(r, g, b, a)
    }

    /// Texel (x, y) of a colour texture as linear RGBA.
    pub fn texel(scene: &Scene, info: UVec4, x: i32, y: i32) -> Vec4 {
        decode_srgba8(texel_word(scene, info, x, y))
    }

    /// Texel (x, y) decoded as colour (sRGB) or, when `data`, as linear data.
    pub fn texel_as(scene: &Scene, info: UVec4, x: i32, y: i32, data: bool) -> Vec4 {
        let word = texel_word(scene, info, x, y);
        if data {
            decode_unorm8(word)
        } else {
            decode_srgba8(word)
        }
    }

    /// The base colour of `material` (its fetched data) at barycentrics (u, v) of `triangle`:
    /// the factor times the base colour texture, when there is one.
    pub fn base_color_at(scene: &Scene, material: MaterialData, triangle: u32, u: f32, v: f32) -> Vec3 {
        let mut base = material.base_color;
        if scene.has_textures != 0 && material.base_texture != NONE {
            let uv = texture_uv(scene, material.base_texture, triangle, u, v);
            base *= sample_texture(scene, material.base_texture, uv).xyz();
        }
        base
    }

    /// Bilinear lookup of colour texture `index` at `uv` (glTF convention: v = 0 is the top row).
    pub fn sample_texture(scene: &Scene, index: u32, uv: Vec2) -> Vec4 {
        bilinear(scene, index, uv, false)
    }

    /// Bilinear lookup of data texture `index` (metal-roughness) at `uv`, its bytes taken as linear.
    pub fn sample_data_texture(scene: &Scene, index: u32, uv: Vec2) -> Vec4 {
        bilinear(scene, index, uv, true)
    }

    /// Bilinear lookup of texture `index` at `uv`, its texels decoded as colour or as `data`.
    pub fn bilinear(scene: &Scene, index: u32, uv: Vec2, data: bool) -> Vec4 {
        let info = scene.texture_info.fetch(index);
        // Bounded so that the texel coordinates (and the next ones, + 1) fit an i32 for any uv;
        // beyond 2^30 an f32 cannot tell texels apart anyway. NaN stays NaN on every target.
        let x = bounded_coordinate(uv.x * info.y as f32 - 0.5);
        let y = bounded_coordinate(uv.y * info.z as f32 - 0.5);
        let fx = x - x.floor();
        let fy = y - y.floor();
        let x0 = x.floor() as i32;
        let y0 = y.floor() as i32;
        let top = texel_as(scene, info, x0, y0, data) * (1.0 - fx) + texel_as(scene, info, x0 + 1, y0, data) * fx;
        let bottom =
            texel_as(scene, info, x0, y0 + 1, data) * (1.0 - fx) + texel_as(scene, info, x0 + 1, y0 + 1, data) * fx;
        top * (1.0 - fy) + bottom * fy
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

    /// `v` within ±1e9, NaN kept as Rust's `clamp` keeps it. Not `clamp` itself, whose NaN
    /// result is the target's (docs/dsl.md), and NaN tested first, from its bits: llvmpipe turns
    /// the two comparisons into a clamp too, which returns a bound for NaN.
    #[allow(clippy::manual_clamp)] // on purpose: see above
    pub fn bounded_coordinate(v: f32) -> f32 {
        if v.is_nan() {
            v
        } else if v > 1.0e9 {
            1.0e9
        } else if v < -1.0e9 {
            -1.0e9
        } else {
            v
        }
    }

    // ---------------------------------------------------------------------------------------
    // Alpha masks.
    //
    // glTF `alphaMode` MASK (`Features::alpha_mask`): texels whose coverage (base colour
    // alpha, `baseColorFactor.a` times the base colour texture's alpha at the hit) is below
    // the material's `alphaCutoff` are holes for every ray. The test runs inside traversal
    // (`traverse::intersect_leaf`, `traverse::leaf_occludes`), so a rejected hit lets the ray
    // go on to the next candidate, and in light sampling (a point sampled in a hole of an
    // emitter emits nothing).
    //
    // Layout (only packed for scenes with masked materials; `Scene::alpha_mask_first` is 0
    // without): per triangle, the w of its third texel in `triangles` is 1 when its material is
    // masked (else 0, as without the feature), so unmasked triangles cost one comparison of a
    // texel traversal has already fetched; per material one texel
    // `[base colour texture or -1, baseColorFactor.a, alphaCutoff, 0]` at
    // `scene.alpha_mask_first + material` in `materials` (after the base texels and the normal
    // maps: an extension of that array, not a new binding).

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
            a *= sample_texture(scene, mask.texture, uv).w;
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
