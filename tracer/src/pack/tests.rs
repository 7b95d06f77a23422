//! Packing's tests: textures, lights and the checks against the kernel's limits.

use glam::{UVec4, Vec3, Vec4};

use super::*;
use crate::kernel::scene_data::{self, LIGHT_TEXELS, LIGHT_TRIANGLE};
use crate::scene::{cornell_box, srgb_to_linear, Material, Texture, Wrap};

fn texture(width: u32, height: u32, first_word: u32) -> Texture {
    let texels = (0..width * height).map(|i| first_word + i).collect();
    Texture { width, height, texels, wrap_s: Wrap::Repeat, wrap_t: Wrap::ClampToEdge }
}

/// The Cornell box with a 3-texel and a 5-texel texture, the first one used by a material.
fn textured_box() -> Scene {
    let mut scene = cornell_box();
    scene.textures = vec![texture(3, 1, 100), texture(5, 1, 200)];
    scene.materials[0].base_color_texture = Some(0);
    scene
}

#[test]
fn triangle_lights_carry_their_unit_normal_and_area() {
    let scene = cornell_box();
    let bvh = crate::bvh::build(&scene.triangles).unwrap();
    let packed = pack(&scene, &bvh, &RenderSettings::default()).unwrap();
    let k = &packed.scene;
    let lights: Vec<&[Vec4]> = k.lights.as_slice().chunks(LIGHT_TEXELS as usize).collect();
    let triangle_lights: Vec<_> = lights.iter().filter(|l| l[0].w as u32 == LIGHT_TRIANGLE).collect();
    assert_eq!(triangle_lights.len(), 2, "the Cornell box light is one quad");
    for l in triangle_lights {
        let t = crate::kernel::scene_data::fetch_triangle(k, l[1].x as u32);
        let face = (t.v1 - t.v0).cross(t.v2 - t.v0);
        let normal = Vec3::new(l[1].y, l[1].z, l[1].w);
        assert!((normal - face.normalize()).length() < 1e-6, "{normal} vs {face}");
        assert_eq!(l[2].x, 0.5 * face.length());
        // The ceiling light faces down into the room.
        assert!(normal.y < -0.99, "{normal}");
    }
}

#[test]
fn textures_start_on_element_boundaries_and_keep_their_texels() {
    let scene = textured_box();
    let packed = pack_textures(&scene);
    assert!(packed.used);
    // 3 texels fill one element (one lane left zero); the second texture starts at texel 4.
    let info = packed.info.as_slice();
    assert_eq!(info[0], UVec4::new(0, 3, 1, scene_data::WRAP_REPEAT | scene_data::WRAP_CLAMP << 8));
    assert_eq!(info[1].x, 4);
    assert_eq!(
        packed.texels.as_slice(),
        &[UVec4::new(100, 101, 102, 0), UVec4::new(200, 201, 202, 203), UVec4::new(204, 0, 0, 0)]
    );
}

/// The Cornell box with textures decoded as loaders do (one shared atlas): a 3x1 and a 2x3.
fn loaded_textures_box() -> Scene {
    use crate::scene::texture::{decode_textures, probe_srgb, PendingTexture, Probed};
    let png = |w, h| {
        let image = image::RgbaImage::from_fn(w, h, |x, y| image::Rgba([x as u8, y as u8, 7, 200]));
        let mut out = std::io::Cursor::new(Vec::new());
        image.write_to(&mut out, image::ImageFormat::Png).unwrap();
        out.into_inner()
    };
    let files = [png(3, 1), png(2, 3)];
    let headers: Vec<_> = files
        .iter()
        .map(|f| match probe_srgb(f, "test", u64::MAX).unwrap() {
            Probed::Image(h) => h,
            Probed::Unsupported(_) => unreachable!(),
        })
        .collect();
    let images: Vec<_> = files.iter().map(|f| f.as_slice()).zip(&headers).collect();
    let pending = |image| PendingTexture { image, wrap_s: Wrap::Repeat, wrap_t: Wrap::Repeat };
    let mut scene = cornell_box();
    scene.textures = decode_textures(&images, &[pending(0), pending(1)], &[]).unwrap();
    scene.materials[0].base_color_texture = Some(1);
    scene
}

/// `textures` as if its texels had been made in code (no image files kept).
fn without_files(mut textures: PackedTextures) -> PackedTextures {
    textures.images.iter_mut().for_each(|i| i.file = None);
    textures
}

#[test]
fn loaded_textures_are_shared_and_others_copied_into_the_same_layout() {
    let scene = loaded_textures_box();
    let packed = pack_textures(&scene);
    assert!(std::ptr::eq(packed.texels.as_slice(), scene.textures[0].texels.atlas().as_slice()));
    // The same texels in textures of their own: copied, the same bytes.
    let mut copied = scene.clone();
    for t in &mut copied.textures {
        t.texels = t.texels.to_vec().into();
    }
    let copy = pack_textures(&copied);
    assert!(!std::ptr::eq(copy.texels.as_slice(), packed.texels.as_slice()));
    // The same, but for the image files the loaded textures keep (texels made in code have none).
    assert!(packed.images.iter().all(|i| i.file.is_some()) && copy.images.iter().all(|i| i.file.is_none()));
    assert_eq!(copy, without_files(packed));
    // Reordered, or one dropped: the shared atlas no longer matches the layout.
    let mut reordered = scene.clone();
    reordered.textures.reverse();
    let mut expected = reordered.clone();
    for t in &mut expected.textures {
        t.texels = t.texels.to_vec().into();
    }
    assert_eq!(without_files(pack_textures(&reordered)), pack_textures(&expected));
    let mut first_only = scene.clone();
    first_only.textures.truncate(1);
    first_only.materials[0].base_color_texture = Some(0);
    let packed = pack_textures(&first_only);
    assert_eq!(packed.texels.len(), 1);
    assert_eq!(packed.texels.as_slice()[0].w, 0);
}

#[test]
fn unused_textures_are_not_packed() {
    let mut scene = textured_box();
    scene.materials[0].base_color_texture = None;
    let packed = pack_textures(&scene);
    assert!(!packed.used && packed.texels.is_empty() && packed.info.is_empty());
}

#[test]
fn emissive_texture_mean_is_the_linear_mean_luminance() {
    let mut scene = cornell_box();
    // Two texels: sRGB grey 188 (linear 0.5029) and black, alpha ignored: the mean of the
    // linear values, not of the encoded ones (188 / 255 / 2 = 0.369).
    scene.textures = vec![Texture {
        width: 2,
        height: 1,
        texels: vec![0x00bc_bcbc, 0xff00_0000].into(),
        wrap_s: Wrap::Repeat,
        wrap_t: Wrap::Repeat,
    }];
    scene.materials.push(Material { emissive_texture: Some(0), ..Material::emissive("e", Vec3::ONE, Vec3::ONE) });
    let mean = pack_textures(&scene).emissive_mean_luminance;
    assert_eq!(mean.len(), 1);
    let expected = 0.5 * srgb_to_linear(188.0 / 255.0);
    assert!((mean[0].unwrap() - expected).abs() < 1e-6 && (expected - 0.2515).abs() < 1e-3, "{mean:?}");
}

#[test]
fn packed_textures_share_their_arrays_with_the_packed_scene() {
    let scene = textured_box();
    let bvh = crate::bvh::build(&scene.triangles).unwrap();
    let textures = pack_textures(&scene);
    let packed = pack_with_textures(&scene, &bvh, &textures, &RenderSettings::default()).unwrap();
    assert!(std::ptr::eq(packed.scene.texture_texels.as_slice(), textures.texels.as_slice()));
    let whole = pack(&scene, &bvh, &RenderSettings::default()).unwrap().scene;
    assert_eq!(packed.scene.texture_texels, whole.texture_texels);
    assert_eq!(packed.scene.texture_info, whole.texture_info);
    assert_eq!(packed.scene.materials, whole.materials);
}

#[test]
fn textures_of_another_scene_are_refused() {
    let scene = textured_box();
    let bvh = crate::bvh::build(&scene.triangles).unwrap();
    let mut other = textured_box();
    other.textures[1] = texture(4, 2, 0);
    let settings = RenderSettings::default();
    let err = pack_with_textures(&scene, &bvh, &pack_textures(&other), &settings).unwrap_err();
    assert_eq!(err, PackError::TexturesMismatch);
    let err = pack_with_textures(&scene, &bvh, &pack_textures(&cornell_box()), &settings).unwrap_err();
    assert_eq!(err, PackError::TexturesMismatch);
}

#[test]
fn leaves_beyond_the_stack_encoding_are_refused() {
    let scene = cornell_box();
    let mut bvh = crate::bvh::build(&scene.triangles).unwrap();
    let leaf = bvh.nodes.iter_mut().find(|n| n.count > 0).unwrap();
    leaf.count = 256;
    let err = pack(&scene, &bvh, &RenderSettings::default()).unwrap_err();
    assert_eq!(err, PackError::LeafTooLarge { triangles: 256, max: 255 });
}
#[test]
fn light_selection_stays_finite_for_lights_of_extreme_power() {
    // Loaders refuse more than 1e12, but a scene built in code may hold anything finite:
    // f32::MAX / 2 times 4π overflows f32. Its share must not turn the mean, the floor or any
    // pmf into inf/NaN, and the dim light keeps the floor share.
    let mut scene = cornell_box();
    scene.point_lights = vec![
        crate::scene::PointLight { position: Vec3::new(0.0, 1.0, 0.0), intensity: Vec3::splat(f32::MAX / 2.0) },
        crate::scene::PointLight { position: Vec3::new(0.2, 1.0, 0.0), intensity: Vec3::splat(1e-30) },
    ];
    let bvh = crate::bvh::build(&scene.triangles).unwrap();
    let packed = pack(&scene, &bvh, &RenderSettings::default()).unwrap();
    let lights = packed.scene.lights.as_slice();
    let pmfs: Vec<f32> = lights.chunks(LIGHT_TEXELS as usize).map(|l| l[0].z).collect();
    assert!(pmfs.iter().all(|p| p.is_finite() && *p > 0.0), "{pmfs:?}");
    assert!((pmfs.iter().sum::<f32>() - 1.0).abs() < 1e-5, "{pmfs:?}");
    assert!(lights.iter().all(|t| t.is_finite()));
}
