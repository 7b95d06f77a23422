//! Scene loading: every scene vendored in `tests/data/scenes/` (see `tests/data/README.md`),
//! the loaders' conventions (transforms, winding, units, cameras) on small glTF files written
//! here, and malformed input, which must give an error and never a panic. Beside this file:
//! moving scenes (`moving.rs`), shared meshes placed by instances (`instancing.rs`), Draco
//! (`draco.rs`), FBX (`fbx.rs`) and the glTF-Validator corpus (`validator_corpus.rs`).

#[path = "../common/mod.rs"]
mod common;
mod default_sky;
mod draco;
mod fbx;
mod instancing;
mod moving;
mod validator_corpus;
mod world_limit;

use std::path::PathBuf;

use glam::{Vec2, Vec3, Vec4};
use tracer::scene::{self, LoadOptions, Scene, SceneError, Wrap};

/// A scene file of the vendored test data, `rel` relative to `tests/data/scenes/`.
fn scene_file(rel: &str) -> PathBuf {
    common::test_data(&format!("scenes/{rel}"))
}

fn load(rel: &str) -> Scene {
    scene::load(&scene_file(rel)).unwrap_or_else(|e| panic!("{rel}: {e}"))
}

/// Every vendored scene (`tests/data/README.md`) with its triangle count.
const VENDORED: &[(&str, usize)] = &[
    ("cornell-box/CornellBox-Original.obj", 36),
    ("cornell-box/CornellBox-Original.gltf", 36),
    ("khronos/Box/glTF/Box.gltf", 12),
    ("khronos/Box/glTF-Binary/Box.glb", 12),
    ("khronos/BoxTextured/glTF/BoxTextured.gltf", 12),
    ("khronos/BoxTextured/glTF-Binary/BoxTextured.glb", 12),
    ("khronos/Duck/glTF/Duck.gltf", 4212),
    ("khronos/Duck/glTF-Binary/Duck.glb", 4212),
    ("khronos/DamagedHelmet/glTF-Binary/DamagedHelmet.glb", 15452),
    ("khronos/EmissiveStrengthTest/glTF/EmissiveStrengthTest.gltf", 90),
    ("khronos/EmissiveStrengthTest/glTF-Binary/EmissiveStrengthTest.glb", 90),
    ("extra/kajiya/emissive/triangle.glb", 1),
    ("missing-texture/MissingTexture.gltf", 24),
];

#[test]
fn vendored_scenes_load_with_their_triangle_counts() {
    let mut failures = Vec::new();
    for &(rel, triangles) in VENDORED {
        match scene::load(&scene_file(rel)) {
            Ok(s) => {
                s.validate().unwrap();
                if s.triangles.len() != triangles {
                    failures.push(format!("{rel}: {} triangles, expected {triangles}", s.triangles.len()));
                }
                println!(
                    "{rel}: {} triangles, {} materials, {} textures, {} emissive, {} point lights, {} warnings",
                    s.triangles.len(),
                    s.materials.len(),
                    s.textures.len(),
                    s.emissive_triangle_count(),
                    s.point_lights.len(),
                    s.warnings.len()
                );
                for w in &s.warnings {
                    println!("    warning: {w}");
                }
            }
            Err(e) => failures.push(format!("{rel}: {e}")),
        }
    }
    assert!(failures.is_empty(), "{failures:#?}");
}

fn strict() -> LoadOptions {
    LoadOptions { strict: true, ..Default::default() }
}

/// Two textured boxes (`tests/data/scenes/missing-texture/`), the second one's base colour image
/// absent, as in the Pica Pica diorama this test used before the test scenes were vendored.
#[test]
fn a_scene_loads_with_one_warning_for_its_missing_texture() {
    let path = scene_file("missing-texture/MissingTexture.gltf");
    let s = scene::load(&path).unwrap();
    assert_eq!(s.triangles.len(), 24);
    let missing: Vec<&String> = s.warnings.iter().filter(|w| w.contains("Label_baseColor.png")).collect();
    assert_eq!(missing.len(), 1, "{:?}", s.warnings);
    // The warning names the material that lost its texture; that material keeps its factors.
    let label = s.materials.iter().position(|m| missing[0].contains(&format!("{:?}", m.name))).expect("material named");
    let m = &s.materials[label];
    assert_eq!(m.name, "Label");
    assert_eq!(m.base_color_texture, None);
    assert!((m.base_color - Vec3::new(0.8, 0.3, 0.2)).abs().max_element() < 1e-6, "{m:?}");
    assert_eq!((m.metallic, m.roughness), (0.5, 0.7));
    // Its other texture is kept, and so is the other material's.
    assert!(m.metallic_roughness_texture.is_some(), "{m:?}");
    let decal = s.materials.iter().find(|m| m.name == "Decal").expect("Decal");
    assert!(decal.base_color_texture.is_some() && decal.is_emissive(), "{decal:?}");
    // One texture: the logo, Decal's base colour and Label's metal-roughness map.
    assert_eq!(s.textures.len(), 1);
    assert_eq!(decal.base_color_texture, m.metallic_roughness_texture);
    assert_eq!(s.materials.iter().filter(|m| m.base_color_texture.is_some()).count(), 1);
    let e = scene::load_with(&path, &strict()).unwrap_err();
    assert!(matches!(e, SceneError::Io { .. }) && e.to_string().contains("Label_baseColor.png"), "{e}");
}

#[test]
fn webp_textures_are_decoded_in_preference_to_their_fallback() {
    // BoxTextured with its texture's EXT_texture_webp image (solid red) beside the PNG fallback.
    let dir = scratch("webp");
    let gltf = std::fs::read_to_string(scene_file("khronos/BoxTextured/glTF/BoxTextured.gltf")).unwrap();
    let gltf = gltf
        .replace(r#""source": 0"#, r#""source": 0, "extensions": {"EXT_texture_webp": {"source": 1}}"#)
        .replace(r#""uri": "CesiumLogoFlat.png""#, r#""uri": "CesiumLogoFlat.png"}, {"uri": "red.webp""#)
        .replacen("{", r#"{"extensionsUsed": ["EXT_texture_webp"], "extensionsRequired": ["EXT_texture_webp"],"#, 1);
    for f in ["BoxTextured0.bin", "CesiumLogoFlat.png"] {
        std::fs::copy(scene_file(&format!("khronos/BoxTextured/glTF/{f}")), dir.join(f)).unwrap();
    }
    let webp = common::test_data("gltf-validator-tests/ext/EXT_texture_webp");
    for (file, alpha) in [("VP8L_red.webp", 1.0), ("VP8_red.webp", 1.0), ("VP8X_red_transparent.webp", 128.0 / 255.0)] {
        std::fs::copy(webp.join("data/image").join(file), dir.join("red.webp")).unwrap();
        std::fs::write(dir.join("box.gltf"), &gltf).unwrap();
        let s = scene::load_with(&dir.join("box.gltf"), &strict()).unwrap_or_else(|e| panic!("{file}: {e}"));
        assert!(s.warnings.is_empty(), "{file}: {:?}", s.warnings);
        assert_eq!(s.textures.len(), 1, "{file}");
        let t = &s.textures[0];
        let texel = t.linear(0).unwrap();
        assert!((texel.x - 1.0).abs() < 0.02 && texel.y < 0.02 && texel.z < 0.02, "{file}: {texel}");
        assert!((texel.w - alpha).abs() < 0.02, "{file}: alpha {}", texel.w);
    }
}

/// A glass vase in the manner of Khronos' GlassVaseFlowers and LightsPunctualLamp (which this
/// test read before the test scenes were vendored): three primitives, each with its own
/// transmissive, volumetric material, and a point light. Both extensions are supported (issue
/// 29): no warning, the materials carry them, and the light is kept.
#[test]
fn glass_vase_loads_its_transmission_and_volume() {
    let nodes = r#"[
        {"mesh": 0, "children": [1]},
        {"translation": [0, 2, 0], "extensions": {"KHR_lights_punctual": {"light": 0}}}
    ]"#;
    let glass = |name: &str| {
        format!(
            r#"{{"name": "{name}", "extensions": {{
                "KHR_materials_transmission": {{"transmissionFactor": 1.0}},
                "KHR_materials_volume": {{"thicknessFactor": 0.1, "attenuationDistance": 0.5}}}}}}"#
        )
    };
    let extra = format!(
        r#",
  "extensionsUsed": ["KHR_lights_punctual", "KHR_materials_transmission", "KHR_materials_volume"],
  "extensions": {{"KHR_lights_punctual": {{"lights": [{{"type": "point", "intensity": 5}}]}}}},
  "materials": [{}, {}, {}]"#,
        glass("glass"),
        glass("water"),
        glass("stem")
    );
    let one = r#"{"attributes": {"POSITION": 0}, "indices": 1"#;
    let json = gltf_json(&TRI, &[0, 1, 2], nodes, &extra).replace(
        &format!("[{one}}}]"),
        &format!("[{one}, \"material\": 0}}, {one}, \"material\": 1}}, {one}, \"material\": 2}}]"),
    );
    let vase = load_str(&json).unwrap();
    assert_eq!(vase.triangles.len(), 3);
    assert_eq!(vase.materials.len(), 3, "{:?}", vase.materials);
    assert_eq!(vase.point_lights.len(), 1);
    assert!(vase.warnings.is_empty(), "{:?}", vase.warnings);
    for m in &vase.materials {
        assert_eq!((m.transmission, m.ior, m.thickness, m.attenuation_distance), (1.0, 1.5, 0.1, 0.5), "{m:?}");
        assert!(m.has_volume() && m.attenuation_color == glam::Vec3::ONE, "{m:?}");
    }
}

/// GlassVaseFlowers as shipped (Khronos, CC0): its glass loads with no warning about
/// transmission or volume (the thickness texture needs none: a path tracer measures the path
/// through the geometry), refracts as a volume, and renders: finite, no sample rejected, and
/// the glass lets the sky through.
#[test]
fn glass_vase_flowers_loads_its_glass_and_renders() {
    use tracer::backend::{cpu::CpuRenderer, Renderer};
    let mut vase = scene::load(&common::test_data("scenes/extra/GlassVaseFlowers/glTF/GlassVaseFlowers.gltf")).unwrap();
    let about_glass: Vec<_> = vase
        .warnings
        .iter()
        .filter(|w| ["transmission", "volume", "thickness", "ior", "KHR_"].iter().any(|k| w.contains(k)))
        .collect();
    assert!(about_glass.is_empty(), "{:?}", vase.warnings);
    let glass = vase.materials.iter().find(|m| m.name == "GlassTransmission").expect("the vase's glass");
    assert!(glass.transmits() && glass.has_volume() && glass.ior == 1.5, "{glass:?}");
    vase.sky = Some(scene::Sky::uniform(Vec3::ONE));
    let packed = common::agreement::packed(&vase, tracer::kernel::Strategy::Mis, 24, 6);
    assert!(packed.features.transmission, "{:?}", packed.features);
    let mut r = CpuRenderer::new(packed, 3);
    for _ in 0..8 {
        r.render_frame().expect("frame");
    }
    assert_eq!(r.rejected_samples().expect("accumulation"), 0);
    let image = r.image().expect("image");
    assert!(image.pixels.iter().all(|p| p.is_finite()));
    let mean = image.mean();
    assert!(mean.min_element() > 0.1, "{mean}");
}

/// Out-of-range glass parameters (ior below 1, a transmission above 1, negative thickness and
/// attenuation distance, a colour above 1) are each replaced by the specification's default
/// with a warning that names the material, the value and the default; `--strict` refuses them.
#[test]
fn bad_glass_values_are_warned_with_their_defaults() {
    let nodes = r#"[{"mesh": 0}]"#;
    let extra = r#",
  "extensionsUsed": ["KHR_materials_transmission", "KHR_materials_ior", "KHR_materials_volume"],
  "materials": [{"name": "bad glass", "extensions": {
      "KHR_materials_transmission": {"transmissionFactor": 1.5},
      "KHR_materials_ior": {"ior": 0.5},
      "KHR_materials_volume": {"thicknessFactor": -1, "attenuationDistance": -2,
                               "attenuationColor": [2, 0.5, 0.5]}}}]"#;
    let json = gltf_json(&TRI, &[0, 1, 2], nodes, extra).replace(r#""indices": 1}"#, r#""indices": 1, "material": 0}"#);
    let scene = load_str(&json).unwrap();
    let m = &scene.materials[0];
    assert_eq!((m.transmission, m.ior, m.thickness), (0.0, 1.5, 0.0), "{m:?}");
    assert_eq!(m.attenuation_distance, f32::INFINITY);
    assert_eq!(m.attenuation_color, glam::Vec3::ONE);
    for (name, value, default) in [
        ("transmissionFactor", "1.5", "0"),
        ("ior", "0.5", "1.5"),
        ("thicknessFactor", "-1", "0"),
        ("attenuationDistance", "-2", "inf"),
        ("attenuationColor", "[2, 0.5, 0.5]", "[1, 1, 1]"),
    ] {
        let w: Vec<_> = scene.warnings.iter().filter(|w| w.contains(name)).collect();
        assert_eq!(w.len(), 1, "{name}: {:?}", scene.warnings);
        assert!(w[0].contains("bad glass") && w[0].contains(value) && w[0].contains(default), "{w:?}");
    }
    let err =
        scene::load_gltf_slice(json.as_bytes(), None, &LoadOptions { strict: true, ..Default::default() }).unwrap_err();
    assert!(err.to_string().contains("bad glass") || err.to_string().contains("material"), "{err}");
}

#[test]
fn cornell_box_gltf_obj_and_embedded_agree() {
    let obj = load("cornell-box/CornellBox-Original.obj");
    let gltf = load("cornell-box/CornellBox-Original.gltf");
    let embedded = scene::cornell_box();
    for (name, s) in [("obj", &obj), ("gltf", &gltf), ("embedded", &embedded)] {
        assert_eq!(s.triangles.len(), 36, "{name}");
        assert_eq!(s.emissive_triangle_count(), 2, "{name}");
        let emission = s.materials.iter().map(|m| m.emission).find(|e| e.max_element() > 0.0).unwrap();
        assert!((emission - Vec3::new(17.0, 12.0, 4.0)).abs().max_element() < 0.02, "{name}: {emission}");
        let b = s.bounds();
        let e = embedded.bounds();
        assert!(
            (b.min - e.min).abs().max_element() < 1e-5 && (b.max - e.max).abs().max_element() < 1e-5,
            "{name}: {b:?}"
        );
        let power = s.emitted_power();
        assert!((power - embedded.emitted_power()).abs().max_element() < 0.05, "{name}: {power}");
        let red = s.materials.iter().find(|m| m.name == "leftWall").unwrap();
        assert!((red.base_color - Vec3::new(0.63, 0.065, 0.05)).abs().max_element() < 1e-6);
    }
    // The glTF has a camera node at (0, 1, 3) looking -Z; the OBJ gets one framing the box.
    assert!((gltf.camera.position - Vec3::new(0.0, 1.0, 3.0)).length() < 1e-6);
    assert!((gltf.camera.forward() - Vec3::NEG_Z).length() < 1e-6);
    assert!((gltf.camera.yfov - 0.6911).abs() < 1e-6);
    let c = obj.camera;
    assert!(c.position.z > 1.0 && (c.forward() - Vec3::NEG_Z).length() < 1e-6);
}

#[test]
fn textures_and_emission_are_decoded_to_linear() {
    let boxed = load("khronos/BoxTextured/glTF-Binary/BoxTextured.glb");
    assert_eq!(boxed.textures.len(), 1);
    let t = &boxed.textures[0];
    assert_eq!((t.width, t.height), (256, 256));
    assert_eq!(t.texels.len(), 256 * 256);
    // Texels stay sRGB-encoded 8-bit RGBA; `linear` decodes them as the kernel does.
    let linear: Vec<Vec4> = (0..t.texels.len()).filter_map(|i| t.linear(i)).collect();
    assert!(linear.iter().all(|v| v.min_element() >= 0.0 && v.max_element() <= 1.0));
    assert!(linear.iter().any(|v| v.x != linear[0].x), "the texture is not one flat colour");
    assert_eq!((t.wrap_s, t.wrap_t), (Wrap::Repeat, Wrap::Repeat));
    let m = &boxed.materials[boxed.triangles[0].material as usize];
    assert_eq!(m.base_color_texture, Some(0));

    // DamagedHelmet: five JPEG images in the GLB's buffer.
    let helmet = load("khronos/DamagedHelmet/glTF-Binary/DamagedHelmet.glb");
    let m = &helmet.materials[0];
    assert!(m.base_color_texture.is_some() && m.emissive_texture.is_some());
    assert!(m.emission.max_element() > 0.0);
    assert!(helmet.emissive_triangle_count() > 0);

    // EmissiveStrengthTest: emissiveFactor x KHR_materials_emissive_strength.
    let strength = load("khronos/EmissiveStrengthTest/glTF/EmissiveStrengthTest.gltf");
    let max = strength.materials.iter().map(|m| m.emission.max_element()).fold(0.0, f32::max);
    assert!(max > 1.5, "strength not applied: max emission {max}");

    // JPEG and PNG textures as files beside a .gltf (StainedGlassLamp's glTF-JPG-PNG form, 12 MB,
    // was read here before the test scenes were vendored): BoxTextured with its PNG as base
    // colour and the helmet's emissive JPEG, cut out of its GLB, as emissive texture.
    let dir = scratch("jpg-png");
    for f in ["BoxTextured0.bin", "CesiumLogoFlat.png"] {
        std::fs::copy(scene_file(&format!("khronos/BoxTextured/glTF/{f}")), dir.join(f)).unwrap();
    }
    let jpeg = glb_image(&std::fs::read(scene_file("khronos/DamagedHelmet/glTF-Binary/DamagedHelmet.glb")).unwrap(), 2);
    assert_eq!(jpeg[..3], [0xFF, 0xD8, 0xFF], "a JPEG");
    std::fs::write(dir.join("emissive.jpg"), &jpeg).unwrap();
    let gltf = std::fs::read_to_string(scene_file("khronos/BoxTextured/glTF/BoxTextured.gltf")).unwrap();
    let gltf = gltf
        .replace(
            r#""name": "Texture""#,
            r#""name": "Texture", "emissiveFactor": [1, 1, 1], "emissiveTexture": {"index": 1}"#,
        )
        .replace(r#""source": 0"#, r#""source": 0}, {"sampler": 0, "source": 1"#)
        .replace(r#""uri": "CesiumLogoFlat.png""#, r#""uri": "CesiumLogoFlat.png"}, {"uri": "emissive.jpg""#);
    std::fs::write(dir.join("jpg-png.gltf"), gltf).unwrap();
    let lamp = scene::load_with(&dir.join("jpg-png.gltf"), &strict()).unwrap();
    assert_eq!(lamp.textures.len(), 2, "{:?}", lamp.warnings);
    let m = &lamp.materials[0];
    assert!(m.base_color_texture.is_some() && m.emissive_texture.is_some(), "{m:?}");
    assert_ne!(m.base_color_texture, m.emissive_texture);
    let emissive = &lamp.textures[m.emissive_texture.unwrap() as usize];
    assert!(emissive.width > 256 && emissive.height > 256, "the JPEG is the helmet's: {}", emissive.width);
    assert!(lamp.emissive_triangle_count() > 0);
}

/// The bytes of image `index` of a GLB whose images are buffer views of its BIN chunk.
fn glb_image(glb: &[u8], index: usize) -> Vec<u8> {
    let u32_at = |at: usize| u32::from_le_bytes(glb[at..at + 4].try_into().unwrap()) as usize;
    let json_len = u32_at(12);
    let json: serde_json::Value = serde_json::from_slice(&glb[20..20 + json_len]).unwrap();
    let bin = &glb[20 + json_len + 8..];
    let view = &json["bufferViews"][json["images"][index]["bufferView"].as_u64().unwrap() as usize];
    let offset = view["byteOffset"].as_u64().unwrap_or(0) as usize;
    bin[offset..offset + view["byteLength"].as_u64().unwrap() as usize].to_vec()
}

#[test]
fn duck_node_transform_is_applied() {
    let duck = load("khronos/Duck/glTF/Duck.gltf");
    // The Duck's mesh is authored in centimetres and scaled by its node (0.01): the world
    // bounds are around 1.6 m, not 160.
    let size = duck.bounds().diagonal();
    assert!(size.max_element() < 5.0 && size.max_element() > 0.5, "{size}");
    let glb = load("khronos/Duck/glTF-Binary/Duck.glb");
    assert_eq!(duck.triangles, glb.triangles);
}

#[test]
fn skies_load() {
    let sky = scene::load_sky(&scene_file("hdri/venice_sunset_1k.hdr"), 2.0, 0.5).unwrap();
    assert_eq!((sky.width, sky.height), (1024, 512));
    assert_eq!(sky.texels.len(), 1024 * 512);
    assert_eq!((sky.intensity, sky.rotation), (2.0, 0.5));
    assert!(sky.texels.iter().all(|t| t.is_finite() && t.min_element() >= 0.0));
    assert!(sky.texels.iter().any(|t| t.max_element() > 1.0), "HDR data expected");
    let tiny = scene::load_sky(&scene_file("hdri/spot1Lux.hdr"), 1.0, 0.0).unwrap();
    assert!(tiny.width > 0 && tiny.height > 0);
    // An OpenEXR sky, written here (Tungsten's reference render of Bitterli's Cornell box, 2.7 MB,
    // was read here before the test scenes were vendored): its values come back.
    let dir = scratch("exr-sky");
    let radiance = |x: u32, y: u32| [x as f32 * 0.25, y as f32 * 2.0, 40.0];
    image::Rgb32FImage::from_fn(16, 8, |x, y| image::Rgb(radiance(x, y))).save(dir.join("sky.exr")).unwrap();
    let exr = scene::load_sky(&dir.join("sky.exr"), 1.0, 0.0).unwrap();
    assert_eq!((exr.width, exr.height), (16, 8));
    assert!(exr.width > 0 && exr.texels.len() == (exr.width * exr.height) as usize);
    for (i, t) in exr.texels.iter().enumerate() {
        let expected = Vec3::from(radiance(i as u32 % 16, i as u32 / 16));
        assert!((*t - expected).abs().max_element() < 1e-3 * expected.max_element(), "texel {i}: {t}");
    }

    let missing = scene::load_sky(&scene_file("hdri/does-not-exist.hdr"), 1.0, 0.0).unwrap_err();
    assert!(matches!(missing, SceneError::Io { .. }), "{missing}");
    assert!(scene::load_sky(&scene_file("hdri/venice_sunset_1k.hdr"), f32::NAN, 0.0).is_err());
    assert!(scene::load_sky(&scene_file("hdri/venice_sunset_1k.hdr"), -1.0, 0.0).is_err());
    assert!(scene::load_sky(&scene_file("cornell-box/CornellBox-Original.obj"), 1.0, 0.0).is_err());

    // The documented mapping: up is row 0, -Z is the image centre.
    let s = tracer::scene::Sky::uniform(Vec3::ONE);
    assert!((s.direction_to_uv(Vec3::Y).y).abs() < 1e-6);
    assert!((s.direction_to_uv(Vec3::NEG_Z) - Vec2::new(0.5, 0.5)).length() < 1e-6);
    assert!((s.direction_to_uv(Vec3::X).x - 0.75).abs() < 1e-6);
}

// ---------------------------------------------------------------------------------------------
// Small glTF files written by the tests.

/// A scratch directory for one test.
fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("lightport-scene-test-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn base64(data: &[u8]) -> String {
    const A: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let mut s = String::new();
    for c in data.chunks(3) {
        let n =
            (u32::from(c[0]) << 16) | (u32::from(*c.get(1).unwrap_or(&0)) << 8) | u32::from(*c.get(2).unwrap_or(&0));
        for k in 0..4 {
            if k <= c.len() {
                s.push(A[(n >> (18 - 6 * k)) as usize & 63] as char);
            } else {
                s.push('=');
            }
        }
    }
    s
}

/// A PNG (signature, IHDR for RGBA8, empty IDAT, IEND) claiming `w` x `h` pixels, with no
/// pixel data.
fn png_header(w: u32, h: u32) -> Vec<u8> {
    fn crc32(data: &[u8]) -> u32 {
        let mut crc = !0u32;
        for &b in data {
            crc ^= u32::from(b);
            for _ in 0..8 {
                crc = if crc & 1 != 0 { (crc >> 1) ^ 0xEDB8_8320 } else { crc >> 1 };
            }
        }
        !crc
    }
    let mut chunk = b"IHDR".to_vec();
    chunk.extend(w.to_be_bytes());
    chunk.extend(h.to_be_bytes());
    chunk.extend([8, 6, 0, 0, 0]);
    let mut png = b"\x89PNG\r\n\x1a\n".to_vec();
    png.extend(13u32.to_be_bytes());
    png.extend(&chunk);
    png.extend(crc32(&chunk).to_be_bytes());
    for empty in [b"IDAT", b"IEND"] {
        png.extend(0u32.to_be_bytes());
        png.extend(empty);
        png.extend(crc32(empty).to_be_bytes());
    }
    png
}

fn f32_bytes(v: &[f32]) -> Vec<u8> {
    v.iter().flat_map(|x| x.to_le_bytes()).collect()
}

fn u16_bytes(v: &[u16]) -> Vec<u8> {
    v.iter().flat_map(|x| x.to_le_bytes()).collect()
}

/// One triangle in the z = 0 plane facing +Z: (0,0,0), (1,0,0), (0,1,0).
const TRI: [f32; 9] = [0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0];

/// A glTF with one indexed triangle mesh: `positions` (3 floats each), u16 `indices`, in one
/// data-URI buffer; `nodes` and extra top-level JSON members are spliced in.
fn gltf_json(positions: &[f32], indices: &[u16], nodes: &str, extra: &str) -> String {
    let mut buf = f32_bytes(positions);
    let pos_len = buf.len();
    buf.extend(u16_bytes(indices));
    let n = positions.len() / 3;
    format!(
        r#"{{
  "asset": {{"version": "2.0"}},
  "scene": 0,
  "scenes": [{{"nodes": [0]}}],
  "nodes": {nodes},
  "meshes": [{{"primitives": [{{"attributes": {{"POSITION": 0}}, "indices": 1}}]}}],
  "buffers": [{{"byteLength": {len}, "uri": "data:application/octet-stream;base64,{b64}"}}],
  "bufferViews": [
    {{"buffer": 0, "byteOffset": 0, "byteLength": {pos_len}}},
    {{"buffer": 0, "byteOffset": {pos_len}, "byteLength": {idx_len}}}
  ],
  "accessors": [
    {{"bufferView": 0, "componentType": 5126, "count": {n}, "type": "VEC3", "min": [0,0,0], "max": [1,1,1]}},
    {{"bufferView": 1, "componentType": 5123, "count": {ni}, "type": "SCALAR"}}
  ]{extra}
}}"#,
        len = buf.len(),
        b64 = base64(&buf),
        idx_len = indices.len() * 2,
        ni = indices.len(),
    )
}

fn load_str(json: &str) -> Result<Scene, SceneError> {
    scene::load_gltf_slice(json.as_bytes(), None, &LoadOptions::default())
}

#[test]
fn node_transforms_normals_and_winding() {
    // Parent translates by (10, 0, 0); child mirrors x (negative determinant) via a matrix.
    let nodes = r#"[
        {"translation": [10, 0, 0], "children": [1]},
        {"matrix": [-2,0,0,0, 0,1,0,0, 0,0,1,0, 0,0,0,1], "mesh": 0}
    ]"#;
    let s = load_str(&gltf_json(&TRI, &[0, 1, 2], nodes, "")).unwrap();
    assert_eq!(s.triangles.len(), 1);
    let t = s.triangles[0];
    let mut xs: Vec<f32> = t.positions.iter().map(|p| p.x).collect();
    xs.sort_by(f32::total_cmp);
    assert_eq!(xs, vec![8.0, 10.0, 10.0]);
    // Mirroring keeps the face pointing +Z: winding was flipped, flat normals follow it.
    let geometric = (t.positions[1] - t.positions[0]).cross(t.positions[2] - t.positions[0]);
    assert!(geometric.z > 0.0, "{t:?}");
    assert!(t.normals.iter().all(|n| (*n - Vec3::Z).length() < 1e-6), "{t:?}");
    // No camera in the file: a generated one frames the bounds.
    assert!(s.camera.position.z > 0.0);
}

#[test]
fn normals_use_the_inverse_transpose() {
    // A tilted triangle (plane x + y + z = 1) with matching normals, under a non-uniform
    // scale and a rotation: only the inverse-transpose keeps the normals perpendicular.
    let mut buf = f32_bytes(&[1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0]);
    buf.extend(f32_bytes(&[1.0 / 3f32.sqrt(); 9]));
    let json = format!(
        r#"{{"asset": {{"version": "2.0"}}, "scenes": [{{"nodes": [0]}}],
        "nodes": [{{"scale": [1, 1, 5], "rotation": [0.38268343, 0, 0, 0.9238795], "mesh": 0}}],
        "meshes": [{{"primitives": [{{"attributes": {{"POSITION": 0, "NORMAL": 1}}}}]}}],
        "buffers": [{{"byteLength": 72, "uri": "data:application/octet-stream;base64,{}"}}],
        "bufferViews": [{{"buffer": 0, "byteLength": 72, "byteStride": 12}}],
        "accessors": [
          {{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3", "min": [0,0,0], "max": [1,1,1]}},
          {{"bufferView": 0, "byteOffset": 36, "componentType": 5126, "count": 3, "type": "VEC3"}}
        ]}}"#,
        base64(&buf)
    );
    let s = load_str(&json).unwrap();
    let t = s.triangles[0];
    let flat = (t.positions[1] - t.positions[0]).cross(t.positions[2] - t.positions[0]).normalize();
    for n in t.normals {
        assert!((n - flat).length() < 1e-5, "normal {n} vs geometric {flat}");
    }
}

#[test]
fn lights_cameras_and_units() {
    let nodes = r#"[
        {"mesh": 0, "children": [1, 2, 3]},
        {"translation": [0, 2, 0], "extensions": {"KHR_lights_punctual": {"light": 0}}},
        {"translation": [1, 0, 0], "extensions": {"KHR_lights_punctual": {"light": 1}}},
        {"translation": [0, 0, 5], "rotation": [0, 0.70710677, 0, 0.70710677], "camera": 0}
    ]"#;
    let extra = r#",
  "extensionsUsed": ["KHR_lights_punctual"],
  "extensions": {"KHR_lights_punctual": {"lights": [
      {"type": "point", "color": [1, 0.5, 0.25], "intensity": 10},
      {"type": "spot", "intensity": 3, "spot": {"outerConeAngle": 0.5}}
  ]}},
  "cameras": [{"type": "perspective", "perspective": {"yfov": 0.5, "znear": 0.1}}]"#;
    let s = load_str(&gltf_json(&TRI, &[0, 1, 2], nodes, extra)).unwrap();
    assert_eq!(s.point_lights.len(), 2);
    assert_eq!(s.point_lights[0].position, Vec3::new(0.0, 2.0, 0.0));
    assert_eq!(s.point_lights[0].intensity, Vec3::new(10.0, 5.0, 2.5));
    assert_eq!(s.point_lights[1].intensity, Vec3::splat(3.0));
    assert!(s.warnings.iter().any(|w| w.contains("spot")), "{:?}", s.warnings);
    // The camera is rotated 90° about +Y: it looks down -X.
    assert!((s.camera.position - Vec3::new(0.0, 0.0, 5.0)).length() < 1e-6);
    assert!((s.camera.forward() - Vec3::NEG_X).length() < 1e-5, "{:?}", s.camera);
    assert_eq!(s.camera.yfov, 0.5);
    assert!(s.camera.focus_distance > 0.0);
}

#[test]
fn strips_fans_and_non_indexed_primitives() {
    let quad = [0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 1.0, 1.0, 0.0];
    let json = |mode: u32, indexed: bool| {
        let buf = f32_bytes(&quad);
        let indices = if indexed { r#", "indices": 1"# } else { "" };
        let mut all = buf.clone();
        all.extend(u16_bytes(&[0, 1, 2, 3]));
        format!(
            r#"{{"asset": {{"version": "2.0"}}, "scenes": [{{"nodes": [0]}}], "nodes": [{{"mesh": 0}}],
            "meshes": [{{"primitives": [{{"attributes": {{"POSITION": 0}}, "mode": {mode}{indices}}}]}}],
            "buffers": [{{"byteLength": 56, "uri": "data:application/octet-stream;base64,{}"}}],
            "bufferViews": [{{"buffer": 0, "byteLength": 48}}, {{"buffer": 0, "byteOffset": 48, "byteLength": 8}}],
            "accessors": [
              {{"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3", "min": [0,0,0], "max": [1,1,0]}},
              {{"bufferView": 1, "componentType": 5123, "count": 4, "type": "SCALAR"}}
            ]}}"#,
            base64(&all)
        )
    };
    // Strip 0,1,2,3 -> (0,1,2), (1,3,2): both facing +Z.
    for (mode, count) in [(5, 2), (6, 2)] {
        for indexed in [false, true] {
            let s = load_str(&json(mode, indexed)).unwrap();
            assert_eq!(s.triangles.len(), count, "mode {mode}");
            if mode == 5 {
                for t in &s.triangles {
                    assert!(t.normals[0].z > 0.99, "mode {mode}: {t:?}");
                }
            }
        }
    }
    // Points and lines are skipped with a warning; with nothing else it is an error.
    let err = load_str(&json(0, false)).unwrap_err();
    assert!(matches!(err, SceneError::NoTriangles(_)), "{err}");
    assert!(err.to_string().contains("POINTS") || err.to_string().contains("Points"), "{err}");
}

#[test]
fn sparse_accessors_override_values() {
    // Dense positions all zero; sparse sets element 1 -> (1,0,0) and element 2 -> (0,1,0).
    let mut buf = f32_bytes(&[0.0; 9]);
    buf.extend(u16_bytes(&[1, 2]));
    buf.extend(f32_bytes(&[1.0, 0.0, 0.0, 0.0, 1.0, 0.0]));
    let json = format!(
        r#"{{"asset": {{"version": "2.0"}}, "scenes": [{{"nodes": [0]}}], "nodes": [{{"mesh": 0}}],
        "meshes": [{{"primitives": [{{"attributes": {{"POSITION": 0}}}}]}}],
        "buffers": [{{"byteLength": {}, "uri": "data:application/octet-stream;base64,{}"}}],
        "bufferViews": [{{"buffer": 0, "byteLength": 36}}, {{"buffer": 0, "byteOffset": 36, "byteLength": 4}},
                        {{"buffer": 0, "byteOffset": 40, "byteLength": 24}}],
        "accessors": [{{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3", "min": [0,0,0], "max": [1,1,0],
           "sparse": {{"count": 2, "indices": {{"bufferView": 1, "componentType": 5123}}, "values": {{"bufferView": 2}}}}}}]}}"#,
        buf.len(),
        base64(&buf)
    );
    let s = load_str(&json).unwrap();
    assert_eq!(s.triangles[0].positions[1], Vec3::X);
    assert_eq!(s.triangles[0].positions[2], Vec3::Y);
    // Sparse index out of range is an error.
    let bad = json.replace(r#""count": 2, "indices""#, r#""count": 3, "indices""#);
    assert!(load_str(&bad).is_err());
}

// ---------------------------------------------------------------------------------------------
// Malformed input: every case is an error, none panics.

fn expect_error(what: &str, result: Result<Scene, SceneError>) -> SceneError {
    match result {
        Ok(s) => panic!("{what}: loaded {} triangles, expected an error", s.triangles.len()),
        Err(e) => {
            println!("{what}: {e}");
            e
        }
    }
}

#[test]
fn malformed_gltf_is_refused() {
    let ok = gltf_json(&TRI, &[0, 1, 2], r#"[{"mesh": 0}]"#, "");
    load_str(&ok).unwrap();

    let e = expect_error("index out of range", load_str(&gltf_json(&TRI, &[0, 1, 5], r#"[{"mesh": 0}]"#, "")));
    assert!(e.to_string().contains("out of range"), "{e}");

    let mut nan = TRI;
    nan[4] = f32::NAN;
    let e = expect_error("NaN position", load_str(&gltf_json(&nan, &[0, 1, 2], r#"[{"mesh": 0}]"#, "")));
    assert!(e.to_string().contains("not finite"), "{e}");
    let mut inf = TRI;
    inf[0] = f32::INFINITY;
    expect_error("infinite position", load_str(&gltf_json(&inf, &[0, 1, 2], r#"[{"mesh": 0}]"#, "")));

    let e = expect_error(
        "huge accessor count",
        load_str(&ok.replace(r#""count": 3, "type": "VEC3""#, r#""count": 2000000000, "type": "VEC3""#)),
    );
    assert!(matches!(e, SceneError::Malformed(_) | SceneError::TooLarge(_)), "{e}");

    let e = expect_error(
        "bufferView past the buffer",
        load_str(&ok.replace(r#""byteOffset": 0, "byteLength": 36"#, r#""byteOffset": 0, "byteLength": 3600"#)),
    );
    assert!(e.to_string().contains("extends past"), "{e}");

    expect_error("node cycle", load_str(&gltf_json(&TRI, &[0, 1, 2], r#"[{"mesh": 0, "children": [0]}]"#, "")));
    expect_error("missing node", load_str(&gltf_json(&TRI, &[0, 1, 2], r#"[{"mesh": 0, "children": [7]}]"#, "")));
    expect_error("not whole triangles", load_str(&gltf_json(&TRI, &[0, 1], r#"[{"mesh": 0}]"#, "")));
    expect_error("bad base64", load_str(&ok.replace("base64,", "base64,*")));
    expect_error("no scene content", load_str(r#"{"asset": {"version": "2.0"}}"#));
    expect_error("wrong version, nothing in it", load_str(r#"{"asset": {"version": "1.0"}}"#));
    expect_error(
        "unknown required extension",
        load_str(&gltf_json(
            &TRI,
            &[0, 1, 2],
            r#"[{"mesh": 0}]"#,
            r#", "extensionsRequired": ["EXT_unknown"], "extensionsUsed": ["EXT_unknown"]"#,
        )),
    );
    expect_error("POSITION accessor out of range", load_str(&ok.replace(r#""POSITION": 0"#, r#""POSITION": 9"#)));
    expect_error("JSON garbage", load_str("{\"asset\": [}"));
}

#[test]
fn malformed_files_are_refused() {
    let dir = scratch("malformed");
    let write = |name: &str, bytes: &[u8]| {
        let p = dir.join(name);
        std::fs::write(&p, bytes).unwrap();
        p
    };

    // Truncated .glb files, at many lengths.
    let glb = std::fs::read(scene_file("khronos/BoxTextured/glTF-Binary/BoxTextured.glb")).unwrap();
    for len in [0, 3, 4, 11, 12, 19, 20, 100, glb.len() / 2, glb.len() - 1] {
        let p = write("truncated.glb", &glb[..len]);
        expect_error(&format!("glb truncated to {len} bytes"), scene::load(&p));
    }
    // A GLB whose header claims more than the file has, and one whose BIN chunk is cut short.
    let mut lying = glb.clone();
    lying[8..12].copy_from_slice(&(glb.len() as u32 * 2).to_le_bytes());
    expect_error("glb length too large", scene::load(&write("lying.glb", &lying)));

    // Garbage and empty files of every type.
    let mut garbage = Vec::new();
    let mut x = 0x1234_5678u32;
    for _ in 0..4096 {
        x ^= x << 13;
        x ^= x >> 17;
        x ^= x << 5;
        garbage.push(x as u8);
    }
    for ext in ["gltf", "glb", "obj", "fbx"] {
        expect_error(&format!("garbage .{ext}"), scene::load(&write(&format!("garbage.{ext}"), &garbage)));
        expect_error(&format!("empty .{ext}"), scene::load(&write(&format!("empty.{ext}"), b"")));
    }
    let mut magic_garbage = b"glTF\x02\0\0\0".to_vec();
    magic_garbage.extend_from_slice(&(garbage.len() as u32 + 12).to_le_bytes());
    magic_garbage.extend_from_slice(&garbage);
    expect_error("glb magic + garbage", scene::load(&write("magic.glb", &magic_garbage)));
    expect_error("unknown extension", scene::load(&write("scene.blend", b"...")));
    expect_error("missing file", scene::load(&dir.join("nope.gltf")));

    // Missing .bin.
    let gltf = std::fs::read_to_string(scene_file("khronos/Box/glTF/Box.gltf")).unwrap();
    let e = expect_error("missing .bin", scene::load(&write("missing-bin.gltf", gltf.as_bytes())));
    assert!(matches!(e, SceneError::Io { .. }) && e.to_string().contains("Box0.bin"), "{e}");

    // Truncated .bin.
    let bin = std::fs::read(scene_file("khronos/Box/glTF/Box0.bin")).unwrap();
    write("Box0.bin", &bin[..bin.len() / 2]);
    let e = expect_error("truncated .bin", scene::load(&write("truncated-bin.gltf", gltf.as_bytes())));
    assert!(e.to_string().contains("truncated"), "{e}");

    // A texture that cannot be used (missing, unreadable, corrupt, truncated): a warning naming
    // the file and the material, which keeps its factors; an error when loading is strict.
    let textured = std::fs::read_to_string(scene_file("khronos/BoxTextured/glTF/BoxTextured.gltf")).unwrap();
    std::fs::copy(scene_file("khronos/BoxTextured/glTF/BoxTextured0.bin"), dir.join("BoxTextured0.bin")).unwrap();
    let p = write("missing-texture.gltf", textured.as_bytes());
    let forgiven = |what: &str| {
        let s = scene::load(&p).unwrap_or_else(|e| panic!("{what}: {e}"));
        assert!(s.textures.is_empty() && s.materials.iter().all(|m| m.base_color_texture.is_none()), "{what}");
        let named = s.warnings.iter().filter(|w| w.contains("CesiumLogoFlat.png") && w.contains("\"Texture\""));
        assert_eq!(named.count(), 1, "{what}: {:?}", s.warnings);
        let e = expect_error(what, scene::load_with(&p, &strict()));
        assert!(e.to_string().contains("CesiumLogoFlat.png"), "{what}: {e}");
    };
    forgiven("missing texture");
    std::fs::create_dir_all(dir.join("CesiumLogoFlat.png")).unwrap();
    forgiven("unreadable texture (a folder)");
    std::fs::remove_dir(dir.join("CesiumLogoFlat.png")).unwrap();

    // An image whose header claims an absurd size is refused before its pixels are decoded.
    for (w, h) in [(16384u32, 8192u32), (100_000, 4)] {
        write("CesiumLogoFlat.png", &png_header(w, h));
        let e = expect_error(&format!("{w} x {h} texture"), scene::load_with(&p, &strict()));
        assert!(matches!(e, SceneError::TooLarge(_)) || e.to_string().contains("limit"), "{e}");
    }

    write("CesiumLogoFlat.png", &garbage[..100]);
    forgiven("corrupt texture");
    let mut png = std::fs::read(scene_file("khronos/BoxTextured/glTF/CesiumLogoFlat.png")).unwrap();
    png.truncate(png.len() / 2);
    write("CesiumLogoFlat.png", &png);
    forgiven("truncated texture (fails when its pixels are decoded)");

    // OBJ: out-of-range face, missing MTL, NaN vertex.
    expect_error("obj face out of range", scene::load(&write("bad-face.obj", b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 9\n")));
    let e = expect_error(
        "obj missing mtl",
        scene::load(&write("no-mtl.obj", b"mtllib nope.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")),
    );
    assert!(e.to_string().contains("nope.mtl"), "{e}");
    expect_error("obj NaN", scene::load(&write("nan.obj", b"v 0 0 nan\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")));
    expect_error("obj no faces", scene::load(&write("nofaces.obj", b"v 0 0 0\n")));
    // tobj slices MTL lines at byte offsets; whatever it does with a keyword that is not
    // ASCII after leading blanks, loading must return (an error or a scene), not panic.
    write("odd.mtl", " newmtl a\n \u{e9} 1\n".as_bytes());
    let _ = scene::load(&write("odd.obj", b"mtllib odd.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl a\nf 1 2 3\n"));

    // A well-formed OBJ with texture coordinates: v is flipped to glTF's convention.
    let s =
        scene::load(&write("uv.obj", b"v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 0 1\nf 1/1 2/2 3/3\n")).unwrap();
    assert_eq!(s.triangles[0].uvs, [Vec2::new(0.0, 1.0), Vec2::new(1.0, 1.0), Vec2::new(0.0, 0.0)]);
    assert!(s.triangles[0].normals[0].z > 0.99);

    let _ = std::fs::remove_dir_all(&dir);
}
