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
