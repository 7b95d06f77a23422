#[kernel_dsl::kernel]
pub mod textures {
    //! Texture lookups in the scene's atlas (`Scene::texture_texels`, described per texture by
    //! `Scene::texture_info`): wrap modes, sRGB and linear decoding, bilinear filtering, and a
    //! material's textured base colour.

    use glam::{IVec2, UVec4, Vec2, Vec3, Vec4, Vec4Swizzles};

    use crate::kernel::scene_data::{MaterialData, Scene, NONE, TEXTURE_TEXELS_PER_ELEMENT, WRAP_CLAMP, WRAP_MIRROR};
    use crate::kernel::texture_ref::texture_uv;

    /// Texel coordinate `i` of an axis of `size` texels under a wrap mode.
    pub fn wrap_coordinate(i: i32, size: i32, mode: u32) -> i32 {
        wrap_pair(i, size, mode).x
    }

    /// `(wrap_coordinate(i, size, mode), wrap_coordinate(i + 1, size, mode))`, a bilinear
    /// lookup's two texels on one axis, with one remainder for both: the second follows from
    /// the first (the remainder is a SIMD driver's costliest step, see `euclid_remainder`).
    pub fn wrap_pair(i: i32, size: i32, mode: u32) -> IVec2 {
        if mode == WRAP_CLAMP {
            let first = i.clamp(0, size - 1);
            // clamp(i + 1) without computing i + 1, which overflows at i32::MAX.
            let second = if i < 0 {
                0
            } else if first < size - 1 {
                first + 1
            } else {
                first
            };
            IVec2::new(first, second)
        } else if mode == WRAP_MIRROR {
            let period = 2 * size;
            let m = euclid_remainder(i, period);
            let next = if m + 1 == period { 0 } else { m + 1 };
            IVec2::new(mirror_fold(m, size), mirror_fold(next, size))
        } else {
            let r = euclid_remainder(i, size);
            let next = if r + 1 == size { 0 } else { r + 1 };
            IVec2::new(r, next)
        }
    }

    /// A mirrored axis' texel for `m` in [0, 2 size): ascending, then descending.
    pub fn mirror_fold(m: i32, size: i32) -> i32 {
        if m < size {
            m
        } else {
            2 * size - 1 - m
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
        let a = word_alpha(word);
        Vec4::new(srgb_to_linear(r), srgb_to_linear(g), srgb_to_linear(b), a)
    }

    /// The packed word (8-bit RGBA, red in the low byte) of texel (x, y) of the texture `info`
    /// describes, the coordinates wrapped by its modes.
    pub fn texel_word(scene: &Scene, info: UVec4, x: i32, y: i32) -> u32 {
        let tx = wrap_coordinate(x, info.y as i32, info.w & 255);
        let ty = wrap_coordinate(y, info.z as i32, info.w >> 8);
        stored_word(scene, info, tx, ty)
    }

    /// The packed word of texel (tx, ty) of the texture `info` describes, the coordinates
    /// already within it.
    pub fn stored_word(scene: &Scene, info: UVec4, tx: i32, ty: i32) -> u32 {
        let i = info.x + (ty * info.y as i32 + tx) as u32;
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
        let a = word_alpha(word);
        Vec4::new(r, g, b, a)
    }

    /// Texel (x, y) of a colour texture as linear RGBA.
    pub fn texel(scene: &Scene, info: UVec4, x: i32, y: i32) -> Vec4 {
        decode_srgba8(texel_word(scene, info, x, y))
    }

    /// A packed texel decoded as colour (sRGB) or, when `data`, as linear data.
    pub fn decode_as(word: u32, data: bool) -> Vec4 {
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

    /// The four texels a bilinear lookup blends: columns `xs`, rows `ys` (wrapped), and the
    /// weights of the second column and row.
    #[derive(Clone, Copy, Debug, PartialEq)]
    pub struct Footprint {
        pub info: UVec4,
        pub xs: IVec2,
        pub ys: IVec2,
        pub weight: Vec2,
    }

    /// The footprint of a bilinear lookup of texture `index` at `uv`.
    pub fn footprint(scene: &Scene, index: u32, uv: Vec2) -> Footprint {
        let info = scene.texture_info.fetch(index);
        // Bounded so that the texel coordinates (and the next ones, + 1) fit an i32 for any uv;
        // beyond 2^30 an f32 cannot tell texels apart anyway. NaN stays NaN on every target.
        let x = bounded_coordinate(uv.x * info.y as f32 - 0.5);
        let y = bounded_coordinate(uv.y * info.z as f32 - 0.5);
        let x0 = x.floor();
        let y0 = y.floor();
        // Each axis wraps once for both of its texels: two remainders per lookup, not eight.
        Footprint {
            info,
            xs: wrap_pair(x0 as i32, info.y as i32, info.w & 255),
            ys: wrap_pair(y0 as i32, info.z as i32, info.w >> 8),
            weight: Vec2::new(x - x0, y - y0),
        }
    }

    /// Bilinear lookup of texture `index` at `uv`, its texels decoded as colour or as `data`.
    pub fn bilinear(scene: &Scene, index: u32, uv: Vec2, data: bool) -> Vec4 {
        let p = footprint(scene, index, uv);
        let fx = p.weight.x;
        let fy = p.weight.y;
        let top = decode_as(stored_word(scene, p.info, p.xs.x, p.ys.x), data) * (1.0 - fx)
            + decode_as(stored_word(scene, p.info, p.xs.y, p.ys.x), data) * fx;
        let bottom = decode_as(stored_word(scene, p.info, p.xs.x, p.ys.y), data) * (1.0 - fx)
            + decode_as(stored_word(scene, p.info, p.xs.y, p.ys.y), data) * fx;
        top * (1.0 - fy) + bottom * fy
    }

    /// The alpha of `bilinear(scene, index, uv, _)` alone, the same operations on it (both
    /// decodings take alpha as linear): the alpha-mask test reads no colour, and a compiler that
    /// keeps dead code would decode three sRGB channels (`powf`) per texel for nothing.
    pub fn bilinear_alpha(scene: &Scene, index: u32, uv: Vec2) -> f32 {
        let p = footprint(scene, index, uv);
        let fx = p.weight.x;
        let fy = p.weight.y;
        let top = word_alpha(stored_word(scene, p.info, p.xs.x, p.ys.x)) * (1.0 - fx)
            + word_alpha(stored_word(scene, p.info, p.xs.y, p.ys.x)) * fx;
        let bottom = word_alpha(stored_word(scene, p.info, p.xs.x, p.ys.y)) * (1.0 - fx)
            + word_alpha(stored_word(scene, p.info, p.xs.y, p.ys.y)) * fx;
        top * (1.0 - fy) + bottom * fy
    }

    /// A packed texel's alpha (its high byte), linear in both decodings.
    pub fn word_alpha(word: u32) -> f32 {
        (word >> 24) as f32 / 255.0
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
