//! Texture texels: 8-bit sRGBA packed four to a `UVec4`, decoded in the kernel.

#[test]
fn decode_srgba8_matches_the_sampled_decoding_for_every_byte() {
    use tracer::kernel::textures::decode_srgba8;
    let linear = |v: u32| tracer::scene::srgb_to_linear(v as f32 / 255.0);
    for v in 0..=255u32 {
        // A different byte in every channel, so a swapped channel or shift shows.
        let (r, g, b, a) = (v, 255 - v, v ^ 0x5a, (v * 7) & 255);
        let decoded = decode_srgba8(r | g << 8 | b << 16 | a << 24);
        // The same f32 operations as the loader's conversion: bit-exact on the CPU.
        assert_eq!(decoded, glam::Vec4::new(linear(r), linear(g), linear(b), a as f32 / 255.0), "byte {v}");
    }
}

#[test]
fn texel_reads_its_lane_of_the_packed_element() {
    use glam::UVec4;
    use tracer::kernel::scene_data::{Scene, WRAP_CLAMP};
    use tracer::kernel::textures::texel;
    // A 3x2 texture starting at atlas texel 4 (element 1), after another texture's element.
    let words: Vec<u32> = (0..6u32).map(|i| u32::from_le_bytes([40 * i as u8, 255 - 40 * i as u8, 9, 255])).collect();
    let scene = Scene {
        texture_texels: kernel_dsl::Texels::new(vec![
            UVec4::splat(0xffff_ffff),
            UVec4::new(words[0], words[1], words[2], words[3]),
            UVec4::new(words[4], words[5], 0, 0),
        ]),
        ..Default::default()
    };
    let info = UVec4::new(4, 3, 2, WRAP_CLAMP | WRAP_CLAMP << 8);
    for y in 0..2 {
        for x in 0..3 {
            let expected = tracer::scene::srgba8_to_linear(words[(y * 3 + x) as usize]);
            assert_eq!(texel(&scene, info, x, y), expected, "texel ({x}, {y})");
        }
    }
}

/// `euclid_remainder` (the repeat and mirror wraps' one division) is `rem_euclid` for every
/// divisor a texture's axis or mirror period can have (up to 2 x 16,384) and every i32: both
/// ends, around multiples of the divisor, and random values in between.
#[test]
fn euclid_remainder_is_rem_euclid_for_every_texture_size() {
    use tracer::kernel::textures::euclid_remainder;
    let max = 2 * tracer::scene::MAX_TEXTURE_DIMENSION as i32;
    let mut state = 0x9e37_79b9u32;
    let mut next = || {
        state ^= state << 13;
        state ^= state >> 17;
        state ^= state << 5;
        state
    };
    let mut divisors: Vec<i32> = (1..=64).chain([255, 256, 257, 1000, 4095, 4096, 16384, max - 1, max]).collect();
    divisors.extend((0..200).map(|_| 1 + (next() % max as u32) as i32));
    for &n in &divisors {
        let mut values: Vec<i32> = vec![i32::MIN, i32::MIN + 1, i32::MAX, i32::MAX - 1, -1, 0, 1];
        for k in [-(1 << 20), -3, -2, -1, 0, 1, 2, 3, 1 << 20, i32::MAX / n, i32::MIN / n] {
            let base = k.wrapping_mul(n);
            values.extend((-2..=2).map(|d| base.wrapping_add(d)));
        }
        values.extend((0..2000).map(|_| next() as i32));
        values.extend((0..2000).map(|_| (next() % 200_000) as i32 - 100_000));
        for i in values {
            assert_eq!(euclid_remainder(i, n), i.rem_euclid(n), "{i} rem_euclid {n}");
        }
    }
}

/// `wrap_pair` (a bilinear lookup's two texels on one axis, from one remainder) is the wrap of
/// `i` and of `i + 1` under each mode, computed here independently in i64 (so `i32::MAX + 1`
/// too), for axes of 1 texel to the largest, around the multiples of the axis and of the mirror
/// period where the second texel turns back; and `wrap_coordinate` is its first texel.
#[test]
fn wrap_pair_is_the_wrap_of_a_texel_and_the_next() {
    use tracer::kernel::scene_data::{WRAP_CLAMP, WRAP_MIRROR, WRAP_REPEAT};
    use tracer::kernel::textures::{wrap_coordinate, wrap_pair};
    let wrap = |i: i64, n: i64, mode: u32| -> i32 {
        (match mode {
            WRAP_CLAMP => i.clamp(0, n - 1),
            WRAP_MIRROR => {
                let m = i.rem_euclid(2 * n);
                if m < n {
                    m
                } else {
                    2 * n - 1 - m
                }
            }
            _ => i.rem_euclid(n),
        }) as i32
    };
    let max = tracer::scene::MAX_TEXTURE_DIMENSION as i32;
    let mut state = 0x2545_f491u32;
    let mut next = || {
        state ^= state << 13;
        state ^= state >> 17;
        state ^= state << 5;
        state
    };
    let sizes: Vec<i32> = (1..=40).chain([255, 256, 257, 1000, 4096, max - 1, max]).collect();
    for &n in &sizes {
        let mut values: Vec<i32> = vec![i32::MIN, i32::MIN + 1, i32::MAX, i32::MAX - 1];
        for k in [-(1 << 16), -4, -3, -2, -1, 0, 1, 2, 3, 4, 1 << 16, i32::MAX / n, i32::MIN / n] {
            let base = k.wrapping_mul(n);
            values.extend((-2..=2).map(|d| base.wrapping_add(d)));
        }
        values.extend((0..500).map(|_| next() as i32));
        values.extend((0..500).map(|_| (next() % 20_000) as i32 - 10_000));
        for i in values {
            for mode in [WRAP_CLAMP, WRAP_MIRROR, WRAP_REPEAT] {
                let pair = wrap_pair(i, n, mode);
                let expected = glam::IVec2::new(wrap(i as i64, n as i64, mode), wrap(i as i64 + 1, n as i64, mode));
                assert_eq!(pair, expected, "texels {i} and {i} + 1 of {n} under wrap mode {mode}");
                assert_eq!(wrap_coordinate(i, n, mode), expected.x, "texel {i} of {n} under wrap mode {mode}");
            }
        }
    }
}

/// `bilinear_alpha` (the alpha-mask test's lookup) is the alpha of the full lookup, bit for bit
/// on the CPU, for both decodings, every wrap mode and uv inside, on the edges of and far
/// outside a texture whose texels differ in every byte.
#[test]
fn bilinear_alpha_is_the_alpha_of_the_full_lookup() {
    use glam::{UVec4, Vec2};
    use tracer::kernel::scene_data::Scene;
    use tracer::kernel::textures::{bilinear, bilinear_alpha};
    let (w, h) = (5u32, 3u32);
    let words: Vec<u32> = (0..w * h)
        .map(|i| u32::from_le_bytes([17 * i as u8, 255 - 9 * i as u8, 3 * i as u8, 11 + 16 * i as u8]))
        .collect();
    let mut elements: Vec<UVec4> = words
        .chunks(4)
        .map(|c| UVec4::new(c[0], *c.get(1).unwrap_or(&0), *c.get(2).unwrap_or(&0), *c.get(3).unwrap_or(&0)))
        .collect();
    elements.push(UVec4::ZERO);
    let infos: Vec<UVec4> = (0..9).map(|m| UVec4::new(0, w, h, (m % 3) | ((m / 3) << 8))).collect();
    let scene = Scene {
        texture_texels: kernel_dsl::Texels::new(elements),
        texture_info: kernel_dsl::Texels::new(infos.clone()),
        ..Default::default()
    };
    let mut uvs = vec![Vec2::ZERO, Vec2::ONE, Vec2::new(-0.1, 1.1), Vec2::new(-7.3, 9.9), Vec2::splat(1.0e6)];
    uvs.extend((0..400).map(|k| Vec2::new((k % 20) as f32 * 0.13 - 1.0, (k / 20) as f32 * 0.17 - 1.2)));
    for index in 0..infos.len() as u32 {
        for &uv in &uvs {
            for data in [false, true] {
                let full = bilinear(&scene, index, uv, data).w;
                assert_eq!(bilinear_alpha(&scene, index, uv).to_bits(), full.to_bits(), "texture {index} at {uv}");
            }
        }
    }
}
