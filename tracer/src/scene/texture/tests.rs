//! Decoding into the packed layout, the shared atlas, forgiving loads, size checks.

use super::*;

#[test]
fn widening_whole_blocks_matches_widening_texel_by_texel() {
    for channels in 1..=3 {
        for count in [15, 16, 17, 40, 100] {
            let packed: Vec<u8> = (0..count * channels).map(|i| (i * 7 + channels) as u8).collect();
            let expected: Vec<u8> = packed
                .chunks(channels)
                .flat_map(|p| match channels {
                    1 => [p[0], p[0], p[0], 255],
                    2 => [p[0], p[0], p[0], p[1]],
                    _ => [p[0], p[1], p[2], 255],
                })
                .collect();
            let mut bytes = vec![0u8; 4 * count];
            bytes[..packed.len()].copy_from_slice(&packed);
            widen_to_rgba_in_place(&mut bytes, channels);
            assert_eq!(bytes, expected, "{channels} channels, {count} texels");
        }
    }
}

#[test]
fn widening_in_place_gives_rgba_for_every_channel_count() {
    // Three texels per layout, packed at the start of a 12-byte buffer.
    let cases: [(usize, &[u8], [u8; 12]); 4] = [
        (1, &[10, 20, 30], [10, 10, 10, 255, 20, 20, 20, 255, 30, 30, 30, 255]),
        (2, &[10, 1, 20, 2, 30, 3], [10, 10, 10, 1, 20, 20, 20, 2, 30, 30, 30, 3]),
        (3, &[1, 2, 3, 4, 5, 6, 7, 8, 9], [1, 2, 3, 255, 4, 5, 6, 255, 7, 8, 9, 255]),
        (4, &[1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12], [1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12]),
    ];
    for (channels, packed, expected) in cases {
        let mut bytes = [0u8; 12];
        bytes[..packed.len()].copy_from_slice(packed);
        widen_to_rgba_in_place(&mut bytes, channels);
        assert_eq!(bytes, expected, "{channels} channels");
    }
}

fn png(image: DynamicImage) -> Vec<u8> {
    let mut out = Cursor::new(Vec::new());
    image.write_to(&mut out, ImageFormat::Png).unwrap();
    out.into_inner()
}

fn header(bytes: &[u8]) -> ImageHeader {
    match probe_srgb(bytes, "test", u64::MAX).unwrap() {
        Probed::Image(header) => header,
        Probed::Unsupported(f) => panic!("unsupported {f}"),
    }
}

fn decode(bytes: &[u8]) -> Texture {
    let header = header(bytes);
    let texture = PendingTexture { image: 0, wrap_s: Wrap::Repeat, wrap_t: Wrap::Repeat };
    decode_textures(&[(bytes, &header)], &[texture], &[]).map_err(|f| f[0].1.to_string()).unwrap().remove(0)
}

#[test]
fn every_png_layout_decodes_to_packed_srgba8() {
    let rgba = image::RgbaImage::from_fn(3, 2, |x, y| image::Rgba([x as u8 * 80, y as u8 * 200, 7, 100 + x as u8]));
    let expected = |keep_alpha: bool, grey: bool| -> Vec<u32> {
        rgba.pixels()
            .map(|p| {
                let [r, g, b, a] = p.0;
                let (r, g, b) = if grey { (r, r, r) } else { (r, g, b) };
                u32::from_le_bytes([r, g, b, if keep_alpha { a } else { 255 }])
            })
            .collect()
    };
    let rgb = DynamicImage::ImageRgba8(rgba.clone()).to_rgb8();
    assert_eq!(*decode(&png(DynamicImage::ImageRgba8(rgba.clone()))).texels, expected(true, false));
    assert_eq!(*decode(&png(DynamicImage::ImageRgb8(rgb))).texels, expected(false, false));
    // Grey images: the red channel as the grey level.
    let luma = image::GrayImage::from_fn(3, 2, |x, y| image::Luma([rgba.get_pixel(x, y).0[0]]));
    let luma_alpha = image::GrayAlphaImage::from_fn(3, 2, |x, y| {
        image::LumaA([rgba.get_pixel(x, y).0[0], rgba.get_pixel(x, y).0[3]])
    });
    assert_eq!(*decode(&png(DynamicImage::ImageLuma8(luma))).texels, expected(false, true));
    assert_eq!(*decode(&png(DynamicImage::ImageLumaA8(luma_alpha))).texels, expected(true, true));
    // 16 bits per channel: rounded to 8.
    let deep = image::ImageBuffer::<image::Rgba<u16>, _>::from_fn(1, 1, |_, _| image::Rgba([65535, 257 * 9, 0, 65535]));
    assert_eq!(*decode(&png(DynamicImage::ImageRgba16(deep))).texels, [u32::from_le_bytes([255, 9, 0, 255])]);
}

#[test]
fn textures_are_decoded_into_one_atlas_in_the_packed_layout() {
    // A 3x1 image shown by two textures (other wrap modes: a copy each) and a 2x3 one.
    let a = image::RgbaImage::from_fn(3, 1, |x, _| image::Rgba([x as u8 + 1, 2, 3, 4]));
    let b = image::RgbaImage::from_fn(2, 3, |x, y| image::Rgba([10 * y as u8 + x as u8, 0, 0, 255]));
    let (a, b) = (png(DynamicImage::ImageRgba8(a)), png(DynamicImage::ImageRgba8(b)));
    let (ha, hb) = (header(&a), header(&b));
    let pending = |image, wrap_s| PendingTexture { image, wrap_s, wrap_t: Wrap::Repeat };
    let textures = [pending(0, Wrap::Repeat), pending(1, Wrap::Repeat), pending(0, Wrap::ClampToEdge)];
    let mut emitter = Material::emissive("e", Vec3::ONE, Vec3::ONE);
    emitter.emissive_texture = Some(1);
    let decoded =
        decode_textures(&[(&a, &ha), (&b, &hb)], &textures, &[emitter]).map_err(|f| f[0].1.to_string()).unwrap();
    let atlas = decoded[0].texels.atlas();
    assert!(decoded.iter().all(|t| std::ptr::eq(t.texels.atlas().as_slice(), atlas.as_slice())));
    let firsts: Vec<usize> = decoded.iter().map(|t| t.texels.first_element()).collect();
    assert_eq!(firsts, [0, 1, 3]);
    let first = UVec4::from_array([1, 2, 3, 0].map(|x| if x == 0 { 0 } else { u32::from_le_bytes([x, 2, 3, 4]) }));
    let second = [0u8, 1, 10, 11, 20, 21].map(|r| u32::from_le_bytes([r, 0, 0, 255]));
    assert_eq!(
        atlas.as_slice(),
        &[first, UVec4::from_slice(&second[..4]), UVec4::new(second[4], second[5], 0, 0), first]
    );
    assert_eq!(*decoded[1].texels, second);
    assert_eq!((decoded[2].wrap_s, decoded[2].width, decoded[2].height), (Wrap::ClampToEdge, 3, 1));
    // The emissive texture's mean was computed while decoding; it is the one computed later.
    assert!(decoded[1].texels.mean_luminance.get().is_some() && decoded[0].texels.mean_luminance.get().is_none());
    let fresh: TextureTexels = decoded[1].texels.to_vec().into();
    assert_eq!(decoded[1].texels.mean_luminance().to_bits(), fresh.mean_luminance().to_bits());
    assert_eq!(fresh, decoded[1].texels);
    // A corrupt image is an error, named by its index.
    let mut cut = b.clone();
    cut.truncate(b.len() - 20);
    let Err(failures) = decode_textures(&[(&a, &ha), (&cut, &hb)], &textures, &[]) else { panic!("decoded") };
    assert!(matches!(failures[..], [(1, SceneError::Image { .. })]), "{:?}", failures);
}

#[test]
fn images_that_do_not_decode_are_dropped_and_their_materials_named() {
    // Image 1 is cut short: it probes but does not decode. Textures 0 and 2 show image 0.
    let a = png(DynamicImage::ImageRgba8(image::RgbaImage::from_fn(3, 1, |x, _| image::Rgba([x as u8, 0, 0, 255]))));
    let b = png(DynamicImage::ImageRgba8(image::RgbaImage::from_fn(2, 3, |_, _| image::Rgba([9, 9, 9, 255]))));
    let mut cut = b.clone();
    cut.truncate(b.len() - 20);
    let (ha, hb) = (header(&a), header(&cut));
    let pending = |image, wrap_s| PendingTexture { image, wrap_s, wrap_t: Wrap::Repeat };
    let textures = vec![pending(0, Wrap::Repeat), pending(1, Wrap::Repeat), pending(0, Wrap::ClampToEdge)];
    let mut materials = vec![Material::diffuse("plain", Vec3::ONE), Material::diffuse("", Vec3::ONE)];
    materials[0].base_color_texture = Some(2);
    materials[1].base_color_texture = Some(1);
    materials[1].emission = Vec3::ONE;
    materials[1].emissive_texture = Some(0);
    let images = [(a.as_slice(), &ha), (cut.as_slice(), &hb)];

    let mut problems = ImageProblems::default();
    let strict =
        decode_textures_forgiving(&images, textures.clone_pending(), &mut materials.clone(), &mut problems, true);
    assert!(matches!(strict, Err(SceneError::Image { .. })));

    let mut problems = ImageProblems::default();
    let decoded = decode_textures_forgiving(&images, textures, &mut materials, &mut problems, false).unwrap();
    // The failed texture is gone; the others keep their order, the materials follow them.
    assert_eq!(decoded.len(), 2);
    assert_eq!((decoded[1].wrap_s, decoded[1].width), (Wrap::ClampToEdge, 3));
    assert_eq!(materials[0].base_color_texture, Some(1));
    assert_eq!((materials[1].base_color_texture, materials[1].emissive_texture), (None, Some(0)));
    let mut warnings = super::super::Warnings::default();
    problems.warn(&mut warnings);
    let warnings = warnings.into_vec();
    assert_eq!(warnings.len(), 1, "{warnings:?}");
    assert!(warnings[0].contains("image test") && warnings[0].contains("material 1 renders"), "{warnings:?}");
}

/// Copies of pending textures (the type is not `Clone`: loaders never copy them).
trait ClonePending {
    fn clone_pending(&self) -> Vec<PendingTexture>;
}

impl ClonePending for Vec<PendingTexture> {
    fn clone_pending(&self) -> Vec<PendingTexture> {
        self.iter().map(|t| PendingTexture { image: t.image, wrap_s: t.wrap_s, wrap_t: t.wrap_t }).collect()
    }
}

#[test]
fn an_image_too_short_for_its_declared_size_is_refused_before_decoding() {
    // A real 64 x 64 RGBA PNG, then the same bytes claiming 8192 x 8192 (the IHDR CRC is
    // not checked by the header probe, so only the size check can refuse it early).
    let small = png(DynamicImage::ImageRgba8(image::RgbaImage::new(64, 64)));
    assert!(matches!(probe_srgb(&small, "small", u64::MAX), Ok(Probed::Image(_))));
    assert_eq!(check_backed(&small, ImageFormat::Png, 64, 64), Ok(()));
    let err = check_backed(&small, ImageFormat::Png, 8192, 8192).unwrap_err();
    assert!(err.contains("8192 x 8192") && err.contains("truncated"), "{err}");
    // 8192 x 8192 RGBA8 rows: 8192 x (1 + 32768) bytes, deflated at most 1032:1.
    assert!(err.contains(&(8192u64 * 32769).div_ceil(1032).to_string()), "{err}");
    // JPEG: one bit per 8 x 8 block at least.
    assert!(check_backed(&[0; 100], ImageFormat::Jpeg, 80, 80).is_ok());
    assert!(check_backed(&[0; 100], ImageFormat::Jpeg, 8192, 8192).is_err());
    assert!(check_backed(&[0; 16384], ImageFormat::Jpeg, 8192, 1024).is_ok());
}

#[test]
fn linear_texels_decode_the_srgb_colour_and_keep_alpha_linear() {
    let v = srgba8_to_linear(u32::from_le_bytes([255, 0, 188, 51]));
    assert_eq!(v.x, 1.0);
    assert_eq!(v.y, 0.0);
    assert!((v.z - srgb_to_linear(188.0 / 255.0)).abs() < 1e-7 && (v.z - 0.5).abs() < 0.01, "{v}");
    assert_eq!(v.w, 0.2);
}
