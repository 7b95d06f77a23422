//! Texture references (`Features::texture_transform`, `Features::texcoord1`,
//! `tracer::kernel::texture_ref`): a square textured through `KHR_texture_transform` or on
//! `TEXCOORD_1` renders pixel for pixel like the same square with those UVs written into
//! `TEXCOORD_0` (CPU kernel, same seeds), for every texture slot the kernel samples; the
//! glTF loader's parsing and its warnings and errors; specialisation (no code, no data, no
//! binding without the features); bundles.

use crate::common;
use crate::common::texture_quads as quads;

use glam::{Vec2, Vec3, Vec4};
use quads::{base_textured, quarter_turn, quarter_turn_by_hand, scene, square, UVS};
use tracer::kernel::integrator::render_sample;
use tracer::kernel::Strategy;
use tracer::pack::Packed;
use tracer::scene::{Material, Scene, UvTransform};

fn pack(scene: &Scene) -> Packed {
    // Two segments: the camera ray's hit and its light sample; no Russian roulette.
    common::agreement::packed(scene, Strategy::Mis, 32, 2)
}

/// Two frames of every pixel (radiance), the CPU kernel.
fn render(scene: &Scene) -> Vec<Vec4> {
    let packed = pack(scene);
    let mut k = packed.scene.clone();
    let mut out = Vec::new();
    for f in 0..2u32 {
        k.frame_seed = f.wrapping_mul(0x9e37_79b9);
        k.frame_index = f;
        for y in 0..k.height {
            for x in 0..k.width {
                out.push(render_sample(&k, x, y));
            }
        }
    }
    out
}

/// Largest difference between two renders relative to the brightest pixel, and the number of
/// pixels differing by more than 1 % of it.
fn difference(a: &[Vec4], b: &[Vec4]) -> (f32, usize) {
    let peak = a.iter().chain(b).map(|p| p.truncate().max_element()).fold(0.0, f32::max);
    assert!(peak > 0.0, "the renders are black");
    let diffs: Vec<f32> = a.iter().zip(b).map(|(x, y)| (*x - *y).abs().max_element() / peak).collect();
    (diffs.iter().copied().fold(0.0, f32::max), diffs.iter().filter(|&&d| d > 0.01).count())
}

fn uv0(i: usize) -> Vec2 {
    Vec2::from(UVS[i])
}

/// Asserts that `a` and `b` render the same, and `b` differently from `other`.
fn assert_same_image(what: &str, a: &Scene, b: &Scene, other: &Scene) {
    let (ra, rb, ro) = (render(a), render(b), render(other));
    let (same, same_count) = difference(&ra, &rb);
    let (apart, apart_count) = difference(&rb, &ro);
    println!("{what}: max difference {same:.2e} ({same_count} pixels > 1 %); against the untransformed square {apart:.2} ({apart_count} pixels)");
    assert!(same < 1e-3 && same_count == 0, "{what}: {same} ({same_count} pixels)");
    assert!(apart_count > ra.len() / 8, "{what}: the transform must change the image ({apart_count} pixels)");
}

#[test]
fn transformed_textures_render_like_pre_transformed_uvs_in_every_slot() {
    let t = quarter_turn();
    let by_hand = |i: usize| quarter_turn_by_hand(uv0(i));
    // Base colour (Lambert), base colour and metal-roughness (glTF BRDF), emission.
    let lambert = |uv| base_textured(uv);
    let metal = |uv: UvTransform| {
        let mut m = Material {
            base_color_texture: Some(0),
            metallic_roughness_texture: Some(0),
            ..Material::metal_rough("metal", Vec3::ONE, 1.0, 1.0)
        };
        m.texture_uvs[0] = uv;
        m.texture_uvs[2] = uv;
        m
    };
    let emissive = |uv: UvTransform| {
        let mut m = Material { emissive_texture: Some(0), ..Material::emissive("e", Vec3::splat(0.2), Vec3::ONE) };
        m.texture_uvs[1] = uv;
        m
    };
    let cases: [(&str, &dyn Fn(UvTransform) -> Material); 3] =
        [("base colour", &lambert), ("metal-roughness", &metal), ("emissive", &emissive)];
    for (what, material) in cases {
        let transformed = scene(square(uv0, uv0), material(t));
        let pre = scene(square(by_hand, uv0), material(UvTransform::default()));
        let plain = scene(square(uv0, uv0), material(UvTransform::default()));
        assert!(pack(&transformed).features.texture_transform, "{what}");
        assert!(!pack(&pre).features.texture_transform, "{what}");
        assert_same_image(what, &transformed, &pre, &plain);
    }
}

#[test]
fn textures_on_texcoord1_render_like_the_same_uvs_on_texcoord0() {
    // Set 0 is deliberately useless (one point): only set 1 can give the pattern.
    let nowhere = |_| Vec2::splat(0.3);
    let on_set1 = UvTransform { texcoord: 1, ..Default::default() };
    let set1 = scene(square(nowhere, uv0), base_textured(on_set1));
    let set0 = scene(square(uv0, nowhere), base_textured(UvTransform::default()));
    let wrong_set = scene(square(nowhere, uv0), base_textured(UvTransform::default()));
    let p = pack(&set1);
    assert!(p.features.texcoord1 && !p.features.texture_transform, "{:?}", p.features);
    assert_same_image("TEXCOORD_1", &set1, &set0, &wrong_set);
    // Both at once: the transform applies to set 1.
    let both = scene(square(nowhere, uv0), base_textured(UvTransform { texcoord: 1, ..quarter_turn() }));
    let by_hand = scene(square(|i| quarter_turn_by_hand(uv0(i)), nowhere), base_textured(UvTransform::default()));
    assert_same_image("TEXCOORD_1 transformed", &both, &by_hand, &wrong_set);
}

// ---------------------------------------------------------------------------------------------
// Specialisation and layout.

#[test]
fn only_scenes_with_texture_references_carry_their_code_and_data() {
    use lightport_codegen::Target;
    let plain = scene(square(uv0, uv0), base_textured(UvTransform::default()));
    let transformed = scene(square(uv0, uv0), base_textured(quarter_turn()));
    let set1 = scene(square(uv0, uv0), base_textured(UvTransform { texcoord: 1, ..Default::default() }));
    let mut storage_buffers = Vec::new();
    for (scene, transform, texcoord1) in [(&plain, false, false), (&transformed, true, false), (&set1, false, true)] {
        let p = pack(scene);
        assert_eq!((p.features.texture_transform, p.features.texcoord1), (transform, texcoord1));
        let k = &p.scene;
        let refs = transform || texcoord1;
        // One texture: one reference, two transform texels after it.
        assert_eq!(k.texture_info.len(), if refs { 3 } else { 1 });
        assert_eq!(k.texture_ref_first, refs as u32);
        assert_eq!(k.shading.len(), p.triangle_count * if texcoord1 { 6 } else { 4 });
        for target in [Target::GlslEs300, Target::Wgsl] {
            let source = tracer::kernel::path_tracer_shader(&p.features, target).unwrap().source;
            for (name, present) in [
                ("referenced_uv", refs),
                ("texture_ref_first", refs),
                ("transform_uv", transform),
                ("texcoord1", texcoord1),
            ] {
                assert_eq!(source.contains(name), present, "{target:?} {:?}: {name}", p.features);
            }
            if target == Target::Wgsl {
                storage_buffers.push(source.matches("var<storage").count());
            }
        }
    }
    // WebGPU's default is 8 storage buffers per stage: texture references add none.
    println!("WGSL storage buffers plain / transformed / TEXCOORD_1: {storage_buffers:?}");
    assert!(storage_buffers.iter().all(|&n| n == storage_buffers[0]), "{storage_buffers:?}");
}

#[test]
fn references_are_deduplicated_and_materials_name_them() {
    let mut s = scene(square(uv0, uv0), base_textured(quarter_turn()));
    // A second material: the same texture and transform (shared), and untransformed (a new one).
    let mut second = base_textured(quarter_turn());
    second.emission = Vec3::ONE;
    second.emissive_texture = Some(0);
    s.materials.push(second);
    let p = pack(&s);
    let k = &p.scene;
    assert_eq!(k.texture_ref_first, 2, "two references");
    let m = |i: u32| tracer::kernel::scene_data::fetch_material(k, i);
    assert_eq!((m(0).base_texture, m(1).base_texture, m(1).emissive_texture), (0, 0, 1));
    // The reference's matrix as the kernel reads it is the transform's (at a point of the
    // first packed triangle, whose set-0 UV the kernel interpolates the same way).
    let uv = tracer::kernel::texture_ref::referenced_uv(k, 0, 0, 0.25, 0.5);
    let want = quarter_turn_by_hand(tracer::kernel::scene_data::texcoord(k, 0, 0.25, 0.5));
    assert!((uv - want).length() < 1e-5, "{uv} (want {want})");
}

#[test]
fn bundles_carry_texture_references_and_refuse_a_wrong_layout() {
    let mut s = scene(square(uv0, uv0), base_textured(UvTransform { texcoord: 1, ..quarter_turn() }));
    s.materials[0].normal_texture = Some(0);
    s.generate_tangents();
    let packed = pack(&s);
    assert!(packed.features.texture_transform && packed.features.texcoord1 && packed.features.normal_map);
    let decoded = tracer::bundle::decode(&tracer::bundle::encode(&packed)).expect("round trip");
    assert_eq!(decoded.features, packed.features);
    assert_eq!(
        (decoded.scene.texture_ref_first, decoded.scene.texcoord1_first),
        (packed.scene.texture_ref_first, packed.scene.texcoord1_first)
    );
    assert_eq!(decoded.scene.texture_info, packed.scene.texture_info);
    for (what, change) in [
        ("texture_ref_first", (|p: &mut Packed| p.scene.texture_ref_first += 1) as fn(&mut Packed)),
        ("texcoord1_first", |p: &mut Packed| p.scene.texcoord1_first -= 2),
        ("has_texcoord1", |p: &mut Packed| p.scene.has_texcoord1 = 0),
        ("has_texture_transform", |p: &mut Packed| p.scene.has_texture_transform = 0),
        ("texture_info", |p: &mut Packed| {
            let mut info = p.scene.texture_info.as_slice().to_vec();
            info.pop();
            p.scene.texture_info = info.into();
        }),
    ] {
        let mut bad = packed.clone();
        change(&mut bad);
        let err = tracer::bundle::decode(&tracer::bundle::encode(&bad)).expect_err(what);
        println!("{what}: {err}");
    }
}

// ---------------------------------------------------------------------------------------------
// Loading.

/// A one-square glTF with a 2 x 2 PNG as its base colour texture read through `texture_info`
/// (the JSON of a textureInfo's extra members), with a `TEXCOORD_1` when `with_uv1`.
fn square_gltf(texture_info: &str, with_uv1: bool) -> Result<Scene, tracer::scene::SceneError> {
    use std::sync::atomic::{AtomicU32, Ordering};
    static N: AtomicU32 = AtomicU32::new(0);
    let n = N.fetch_add(1, Ordering::Relaxed);
    let dir = std::env::temp_dir().join(format!("lightport-tt-{}-{n}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let mut png = Vec::new();
    image::ImageEncoder::write_image(
        image::codecs::png::PngEncoder::new(&mut png),
        &[255, 0, 0, 255, 0, 255, 0, 255, 0, 0, 255, 255, 255, 255, 255, 255],
        2,
        2,
        image::ExtendedColorType::Rgba8,
    )
    .unwrap();
    std::fs::write(dir.join("t.png"), png).unwrap();
    let positions: [[f32; 3]; 4] = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 1.0, 0.0], [0.0, 1.0, 0.0]];
    let uvs: [[f32; 2]; 4] = [[0.0, 1.0], [1.0, 1.0], [1.0, 0.0], [0.0, 0.0]];
    let uvs1: [[f32; 2]; 4] = [[0.5, 0.5], [0.75, 0.5], [0.75, 0.25], [0.5, 0.25]];
    let indices: [u16; 6] = [0, 1, 2, 0, 2, 3];
    let mut bin = Vec::new();
    positions.iter().flatten().for_each(|f| bin.extend(f.to_le_bytes()));
    uvs.iter().flatten().for_each(|f| bin.extend(f.to_le_bytes()));
    uvs1.iter().flatten().for_each(|f| bin.extend(f.to_le_bytes()));
    indices.iter().for_each(|i| bin.extend(i.to_le_bytes()));
    std::fs::write(dir.join("square.bin"), &bin).unwrap();
    let uv1_attribute = if with_uv1 { r#", "TEXCOORD_1": 3"# } else { "" };
    let gltf = format!(
        r#"{{
      "asset": {{"version": "2.0"}}, "extensionsUsed": ["KHR_texture_transform"],
      "scene": 0, "scenes": [{{"nodes": [0]}}], "nodes": [{{"mesh": 0}}],
      "meshes": [{{"primitives": [{{"attributes": {{"POSITION": 0, "TEXCOORD_0": 1{uv1_attribute}}}, "indices": 2, "material": 0}}]}}],
      "materials": [{{"pbrMetallicRoughness": {{"baseColorTexture": {{"index": 0 {texture_info}}}}}}}],
      "textures": [{{"source": 0}}],
      "images": [{{"uri": "t.png"}}],
      "buffers": [{{"uri": "square.bin", "byteLength": 124}}],
      "bufferViews": [{{"buffer": 0, "byteOffset": 0, "byteLength": 48}},
                      {{"buffer": 0, "byteOffset": 48, "byteLength": 32}},
                      {{"buffer": 0, "byteOffset": 112, "byteLength": 12}},
                      {{"buffer": 0, "byteOffset": 80, "byteLength": 32}}],
      "accessors": [
        {{"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3", "min": [0, 0, 0], "max": [1, 1, 0]}},
        {{"bufferView": 1, "componentType": 5126, "count": 4, "type": "VEC2"}},
        {{"bufferView": 2, "componentType": 5123, "count": 6, "type": "SCALAR"}},
        {{"bufferView": 3, "componentType": 5126, "count": 4, "type": "VEC2"}}]
    }}"#
    );
    std::fs::write(dir.join("square.gltf"), gltf).unwrap();
    let scene = tracer::scene::load(&dir.join("square.gltf"));
    std::fs::remove_dir_all(&dir).ok();
    scene
}

#[test]
fn gltf_transforms_and_texture_coordinate_sets_are_read() {
    let ext = r#", "extensions": {"KHR_texture_transform": {"offset": [0.5, -0.25], "rotation": 0.3, "scale": [2, 3], "texCoord": 1}}"#;
    let s = square_gltf(ext, true).expect("loads");
    assert!(s.warnings.is_empty(), "{:?}", s.warnings);
    let m = &s.materials[0];
    assert!(m.base_color_texture.is_some());
    let want = UvTransform { texcoord: 1, offset: Vec2::new(0.5, -0.25), rotation: 0.3, scale: Vec2::new(2.0, 3.0) };
    assert_eq!(m.texture_uvs[0], want);
    // TEXCOORD_1 reaches the triangles (corner 1 of the first triangle is vertex 1).
    assert_eq!(s.triangles[0].uvs1[1], Vec2::new(0.75, 0.5));
    assert_eq!(s.triangles[0].uvs[1], Vec2::new(1.0, 1.0));
    // The textureInfo's own texCoord: 1, no extension.
    let s = square_gltf(r#", "texCoord": 1"#, true).expect("loads");
    assert_eq!(s.materials[0].texture_uvs[0], UvTransform { texcoord: 1, ..Default::default() });
    assert!(pack(&s).features.texcoord1);
    // The extension's texCoord overrides the textureInfo's.
    let s = square_gltf(r#", "texCoord": 1, "extensions": {"KHR_texture_transform": {"texCoord": 0}}"#, true)
        .expect("loads");
    assert_eq!(s.materials[0].texture_uvs[0].texcoord, 0);
}

#[test]
fn gltf_texture_coordinate_problems_are_warnings() {
    // texCoord 1 on a primitive without TEXCOORD_1: the texture is ignored there.
    let s = square_gltf(r#", "texCoord": 1"#, false).expect("loads with a warning");
    println!("{:?}", s.warnings);
    assert!(s.warnings.iter().any(|w| w.contains("TEXCOORD_1")), "{:?}", s.warnings);
    let m = &s.materials[s.triangles[0].material as usize];
    assert_eq!(m.base_color_texture, None, "the texture is ignored where there is no TEXCOORD_1");
    assert!(!pack(&s).features.texcoord1);
    // texCoord 2 and beyond: not supported, the texture is dropped.
    for info in [r#", "texCoord": 2"#, r#", "extensions": {"KHR_texture_transform": {"texCoord": 5}}"#] {
        let s = square_gltf(info, true).expect("loads with a warning");
        println!("{:?}", s.warnings);
        assert!(s.warnings.iter().any(|w| w.contains("not supported")), "{:?}", s.warnings);
        assert_eq!(s.materials[0].base_color_texture, None);
    }
}

#[test]
fn gltf_transforms_that_are_not_finite_are_refused() {
    for (ext, needle) in [
        (r#"{"offset": [1e39, 0]}"#, "offset"),
        (r#"{"rotation": -1e300}"#, "rotation"),
        (r#"{"scale": [1, "2"]}"#, "scale"),
        (r#"{"scale": [1]}"#, "scale"),
        (r#"{"texCoord": -1}"#, "texCoord"),
    ] {
        let info = format!(r#", "extensions": {{"KHR_texture_transform": {ext}}}"#);
        let err = square_gltf(&info, true).expect_err(ext).to_string();
        println!("{ext}: {err}");
        assert!(err.contains("KHR_texture_transform") && err.contains(needle), "{ext}: {err}");
        assert!(err.contains("baseColorTexture"), "names the texture: {err}");
    }
}

// ---------------------------------------------------------------------------------------------
// The transform itself, against the extension's own example.

#[test]
fn the_extension_example_reads_the_lower_left_quadrant_rotated_clockwise() {
    use tracer::scene::texture_ref::parse_gltf;
    // "This example utilizes only the lower left quadrant of the source image, rotated
    // clockwise 90°" (KHR_texture_transform README): u' = 0.5 v, v' = 1 - 0.5 u.
    let ext = serde_json::json!({ "offset": [0, 1], "rotation": std::f32::consts::FRAC_PI_2, "scale": [0.5, 0.5] });
    let t = parse_gltf(0, Some(&ext), "m").unwrap();
    for (uv, want) in
        [((0.0, 0.0), (0.0, 1.0)), ((1.0, 0.0), (0.0, 0.5)), ((0.0, 1.0), (0.5, 1.0)), ((1.0, 1.0), (0.5, 0.5))]
    {
        let got = t.apply(Vec2::from(uv));
        assert!((got - Vec2::from(want)).length() < 1e-6, "{uv:?} -> {got} (want {want:?})");
    }
    // The hand-written quarter turn of the render tests is the same convention.
    let q = quarter_turn();
    for uv in [Vec2::new(0.1, 0.7), Vec2::new(-2.0, 3.5)] {
        assert!((q.apply(uv) - quarter_turn_by_hand(uv)).length() < 1e-5);
    }
}

#[test]
fn transform_parsing_refuses_bad_shapes_and_reads_the_override() {
    use serde_json::json;
    use tracer::scene::texture_ref::parse_gltf;
    for bad in [
        json!({ "offset": [0, 1e39] }),
        json!({ "scale": [1] }),
        json!({ "rotation": "1" }),
        json!({ "texCoord": -1 }),
        json!(3),
    ] {
        let e = parse_gltf(0, Some(&bad), "material 0 baseColorTexture").unwrap_err();
        assert!(e.starts_with("material 0 baseColorTexture: KHR_texture_transform"), "{e}");
    }
    let t = parse_gltf(0, Some(&json!({ "scale": [2, 3], "texCoord": 1 })), "m").unwrap();
    assert_eq!((t.scale, t.texcoord), (Vec2::new(2.0, 3.0), 1));
    assert_eq!(parse_gltf(1, None, "m").unwrap(), UvTransform { texcoord: 1, ..Default::default() });
}
