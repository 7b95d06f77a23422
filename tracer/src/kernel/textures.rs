#[kernel_dsl::kernel]
pub mod textures {
    //! Texture lookups in the scene's atlas (`Scene::texture_texels`, described per texture by
    //! `Scene::texture_info`): wrap modes, sRGB and linear decoding, bilinear filtering, and a
    //! material's textured base colour.

    use glam::{UVec4, Vec2, Vec3, Vec4, Vec4Swizzles};

    use crate::kernel::scene_data::{MaterialData, Scene, NONE, TEXTURE_TEXELS_PER_ELEMENT, WRAP_CLAMP, WRAP_MIRROR};
    use crate::kernel::texture_ref::texture_uv;

    /// Texel coordinate `i` of an axis of `size` texels under a wrap mode.
    pub fn wrap_coordinate(i: i32, size: i32, mode: u32) -> i32 {
        if mode == WRAP_CLAMP {
            i.clamp(0, size - 1)
        } else if mode == WRAP_MIRROR {
            let period = 2 * size;
            let m = euclid_remainder(i, period);
            if m < size {
                m
            } else {
                period - 1 - m
            }
        } else {
            euclid_remainder(i, size)
        }
    }

    /// `i.rem_euclid(n)` for n >= 1 with one unsigned division: a negative i is -(a + 1) with
    /// a = !i >= 0, whose remainder is n - 1 - a % n. SIMD drivers (llvmpipe, SwiftShader) have
    /// no vector integer division (they divide lane by lane, and SwiftShader's JIT compiles each
    /// division slowly) and run both wraps' branches: `((i % n) + n) % n` was four signed
    /// divisions per coordinate of every texel lookup (issue 31).
    pub fn euclid_remainder(i: i32, n: i32) -> i32 {
        let negative = i < 0;
        let a = if negative { (i as u32) ^ 0xffff_ffff } else { i as u32 };
        let r = (a % (n as u32)) as i32;
        if negative {
            n - 1 - r
        } else {
            r
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
}
