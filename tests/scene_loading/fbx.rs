//! FBX loading (`tests/data/scenes/fbx/`, ufbx's own test files): each FBX against the OBJ the
//! same tool exported from the same model (triangles, bounds, and rendered images that agree
//! statistically), axis systems, ASCII against binary, embedded and external textures, what is
//! warned about, and mutated files, which must give an error or a scene and never a panic or a
//! hang.

use crate::common;

use std::panic::{catch_unwind, AssertUnwindSafe};
use std::path::PathBuf;
use std::time::{Duration, Instant};

use glam::{DVec3, Mat3, Vec3};
use tracer::backend::cpu::CpuRenderer;
use tracer::backend::Renderer;
use tracer::kernel::{RenderSettings, Strategy};
use tracer::pack::pack;
use tracer::scene::{self, Aabb, Camera, LoadOptions, Material, Scene, SceneError, Sky};
use tracer::stats::Estimate;

fn fbx_dir() -> PathBuf {
    common::test_data("scenes/fbx")
}

fn load(name: &str) -> Scene {
    scene::load(&fbx_dir().join(name)).unwrap_or_else(|e| panic!("{name}: {e}"))
}

/// Z-up (Blender's and 3ds Max's world) to glTF's Y-up: a -90° turn about +X, (x, y, z) ↦ (x, z, -y).
const Z_UP_TO_Y_UP: Mat3 = Mat3::from_cols(Vec3::X, Vec3::NEG_Z, Vec3::Y);

/// The twin pairs of the folder's README: the FBX, its OBJ export, and the map from the OBJ's
/// coordinates to the FBX's world (metres, +Y up). OBJ has no axis or unit metadata: the map is
/// the exporter's setting, read off the files (Blender 3.4's `y_up.obj` kept Blender's own
/// Z-up frame, its `z_up.obj` is Y-up and holds the cube alone; Maya's OBJ states centimetres).
struct Twin {
    fbx: &'static str,
    obj: &'static str,
    /// Applied to each OBJ position.
    obj_to_world: Mat3,
    /// Triangles of the FBX scene.
    triangles: usize,
    /// How many of them (the first, in node order) the OBJ holds.
    in_obj: usize,
}

fn twins() -> Vec<Twin> {
    vec![
        Twin {
            fbx: "blender_282_suzanne_7400_binary.fbx",
            obj: "blender_282_suzanne.obj",
            obj_to_world: Mat3::IDENTITY,
            triangles: 968,
            in_obj: 968,
        },
        Twin {
            fbx: "blender_282_suzanne_and_transform_7400_binary.fbx",
            obj: "blender_282_suzanne_and_transform.obj",
            obj_to_world: Mat3::IDENTITY,
            triangles: 1936,
            in_obj: 1936,
        },
        Twin {
            fbx: "blender_340_y_up_7400_binary.fbx",
            obj: "blender_340_y_up.obj",
            obj_to_world: Z_UP_TO_Y_UP,
            triangles: 26,
            in_obj: 26,
        },
        Twin {
            fbx: "blender_340_z_up_7400_binary.fbx",
            obj: "blender_340_z_up.obj",
            obj_to_world: Mat3::IDENTITY,
            triangles: 26,
            in_obj: 12,
        },
        // The OBJ says "This file uses centimeters": the FBX's unit scale turns them into metres.
        Twin {
            fbx: "maya_cube_7400_binary.fbx",
            obj: "maya_cube.obj",
            obj_to_world: Mat3::from_diagonal(Vec3::splat(0.01)),
            triangles: 12,
            in_obj: 12,
        },
    ]
}

/// The FBX scene, cut to the triangles its OBJ twin holds.
fn fbx_twin(twin: &Twin) -> Scene {
    let mut fbx = load(twin.fbx);
    assert_eq!(fbx.triangles.len(), twin.triangles, "{}", twin.fbx);
    fbx.triangles.truncate(twin.in_obj);
    fbx
}

fn obj_twin(twin: &Twin) -> Scene {
    let mut obj = load(twin.obj);
    for t in &mut obj.triangles {
        t.positions = t.positions.map(|p| twin.obj_to_world * p);
        t.normals = t.normals.map(|n| (twin.obj_to_world * n).normalize());
    }
    obj
}

fn assert_bounds_close(what: &str, a: Aabb, b: Aabb) {
    let tolerance = 1e-5 * b.diagonal().length().max(1e-3);
    let off = (a.min - b.min).abs().max((a.max - b.max).abs()).max_element();
    assert!(off <= tolerance, "{what}: bounds {a:?} vs {b:?} ({off:e} apart, tolerance {tolerance:e})");
}

#[test]
fn twins_have_the_triangles_and_bounds_of_their_obj_exports() {
    for twin in twins() {
        let fbx = fbx_twin(&twin);
        let obj = obj_twin(&twin);
        println!(
            "{}: {} triangles, bounds {:?}, warnings {:?}",
            twin.fbx,
            fbx.triangles.len(),
            fbx.bounds(),
            fbx.warnings
        );
        assert_eq!(obj.triangles.len(), twin.in_obj, "{}", twin.obj);
        assert_bounds_close(twin.fbx, fbx.bounds(), obj.bounds());
    }
}

/// Renders `frames` frames of `size`² pixels and returns, per frame, the mean of each region of
/// a 4 x 4 grid and, last, of the whole image.
fn render_regions(scene: &Scene, size: u32, frames: u32, seed: u32) -> Vec<Vec<DVec3>> {
    let bvh = tracer::bvh::build(&scene.triangles).expect("BVH");
    let settings = RenderSettings { width: size, height: size, strategy: Strategy::Mis, max_depth: 3 };
    let mut r = CpuRenderer::new(pack(scene, &bvh, &settings).expect("pack"), seed);
    let mut per_frame = Vec::new();
    let mut previous = vec![DVec3::ZERO; 17];
    for _ in 0..frames {
        r.render_frame().expect("frame");
        let img = r.image().expect("image");
        let n = r.frames() as f64;
        let sums = common::region_means(size, 4, |i| img.pixels[i].as_dvec3() * n);
        per_frame.push(sums.iter().zip(&previous).map(|(s, p)| *s - *p).collect());
        previous = sums;
    }
    assert_eq!(r.rejected_samples().expect("accumulation"), 0, "no NaN/Inf may reach the accumulation buffer");
    per_frame
}

/// A scene as the renderer sees it under the same light (a uniform sky, no point lights),
/// from the same camera (framing the OBJ) and with one grey material (the OBJs come without
/// their MTL), so that only the geometry and normals of each loader's output differ.
fn under_the_same_light(mut s: Scene, camera: Camera) -> Scene {
    s.camera = camera;
    s.point_lights.clear();
    s.sky = Some(Sky::uniform(Vec3::ONE));
    s.materials = vec![Material::diffuse("grey", Vec3::splat(0.8))];
    s.textures.clear();
    s.triangles.iter_mut().for_each(|t| t.material = 0);
    s
}

#[test]
fn twins_render_like_their_obj_exports() {
    // Per region and channel, frame means of the two renders (different seeds) agree within
    // 5 combined standard errors (17 regions x 3 channels x 5 pairs: a false alarm at 5 sigma
    // is ~1 in 10^6 per comparison).
    for twin in twins() {
        let obj = obj_twin(&twin);
        let camera = Camera::framing(&obj.bounds());
        let fbx = under_the_same_light(fbx_twin(&twin), camera);
        let obj = under_the_same_light(obj, camera);
        let (a, b) = (render_regions(&fbx, 32, 96, 1), render_regions(&obj, 32, 96, 2));
        let mut worst = 0.0f64;
        for region in 0..17 {
            for c in 0..3 {
                let estimate = |runs: &[Vec<DVec3>]| {
                    Estimate::from_samples(&runs.iter().map(|f| f[region][c]).collect::<Vec<_>>())
                };
                let (ea, eb) = (estimate(&a), estimate(&b));
                let z = ea.z_score(&eb);
                worst = worst.max(z);
                assert!(
                    z < 5.0,
                    "{} vs {}, region {region} channel {c}: {} ± {} vs {} ± {} (z = {z:.1})",
                    twin.fbx,
                    twin.obj,
                    ea.mean,
                    ea.std_err,
                    eb.mean,
                    eb.std_err
                );
            }
        }
        println!("{}: largest z = {worst:.2}", twin.fbx);
    }
}

#[test]
fn y_up_and_z_up_exports_load_to_the_same_geometry() {
    // The same Blender scene, exported with Y up and with Z up: ufbx's axis conversion must
    // bring both to glTF's +Y up, triangle for triangle.
    let y = load("blender_340_y_up_7400_binary.fbx");
    let z = load("blender_340_z_up_7400_binary.fbx");
    assert_eq!(y.triangles.len(), z.triangles.len());
    assert_bounds_close("Y-up vs Z-up export", z.bounds(), y.bounds());
    for (i, (a, b)) in y.triangles.iter().zip(&z.triangles).enumerate() {
        let off = a.positions.iter().zip(&b.positions).map(|(p, q)| (*p - *q).length()).fold(0.0, f32::max);
        assert!(off < 1e-5, "triangle {i}: {:?} vs {:?}", a.positions, b.positions);
        let normals = a.normals.iter().zip(&b.normals).map(|(p, q)| (*p - *q).length()).fold(0.0, f32::max);
        assert!(normals < 1e-5, "triangle {i} normals: {:?} vs {:?}", a.normals, b.normals);
    }
    // The point light and the camera go through the same conversion.
    assert_eq!(y.point_lights.len(), 1);
    assert_eq!(z.point_lights.len(), 1);
    let (ly, lz) = (y.point_lights[0], z.point_lights[0]);
    assert!((ly.position - lz.position).length() < 1e-4 && ly.intensity == lz.intensity, "{ly:?} vs {lz:?}");
    let (cy, cz) = (y.camera, z.camera);
    assert!((cy.position - cz.position).length() < 1e-4, "{cy:?} vs {cz:?}");
    assert!((cy.forward() - cz.forward()).length() < 1e-5 && (cy.yfov - cz.yfov).abs() < 1e-6, "{cy:?} vs {cz:?}");
}

#[test]
fn ascii_and_binary_exports_load_to_the_same_scene() {
    let binary = load("maya_cube_7400_binary.fbx");
    for other in ["maya_cube_7400_ascii.fbx", "maya_cube_6100_binary.fbx"] {
        let s = load(other);
        assert_eq!(s.triangles.len(), binary.triangles.len(), "{other}");
        for (i, (a, b)) in s.triangles.iter().zip(&binary.triangles).enumerate() {
            let close = |x: &[Vec3; 3], y: &[Vec3; 3]| x.iter().zip(y).all(|(p, q)| (*p - *q).length() < 1e-6);
            assert!(close(&a.positions, &b.positions), "{other} triangle {i}: {a:?} vs {b:?}");
            assert!(close(&a.normals, &b.normals), "{other} triangle {i} normals: {a:?} vs {b:?}");
            let uvs = a.uvs.iter().zip(&b.uvs).all(|(p, q)| (*p - *q).length() < 1e-6);
            assert!(uvs && a.material == b.material, "{other} triangle {i}: {a:?} vs {b:?}");
        }
        assert_eq!(s.materials, binary.materials, "{other}");
        assert_eq!(s.point_lights, binary.point_lights, "{other}");
        let c =
            (s.camera.position - binary.camera.position).length() + (s.camera.target - binary.camera.target).length();
        assert!(c < 1e-5 && (s.camera.yfov - binary.camera.yfov).abs() < 1e-6, "{other}: {:?}", s.camera);
    }
}

/// The texels of a PNG in `textures/`, packed as the scene's (sRGBA8, red in the low byte).
fn png_texels(name: &str) -> (u32, u32, Vec<u32>) {
    let bytes = std::fs::read(fbx_dir().join("textures").join(name)).unwrap();
    let image = image::load_from_memory(&bytes).unwrap().into_rgba8();
    let texels = image.pixels().map(|p| u32::from_le_bytes(p.0)).collect();
    (image.width(), image.height(), texels)
}

fn texture_matches(s: &Scene, index: Option<u32>, png: &str) -> bool {
    let Some(t) = index.and_then(|i| s.textures.get(i as usize)) else { return false };
    let (w, h, texels) = png_texels(png);
    t.width == w && t.height == h && t.texels.iter().eq(texels.iter())
}

#[test]
fn external_and_embedded_textures_decode() {
    // External: `textures\checkerboard_*.png` relative to the file (a Windows path).
    let external = load("blender_293_textures_7400_binary.fbx");
    println!("external: {:?}\nwarnings {:?}", external.materials, external.warnings);
    let m = external.materials.iter().find(|m| m.base_color_texture.is_some()).expect("a base colour texture");
    assert!(texture_matches(&external, m.base_color_texture, "checkerboard_diffuse.png"), "{m:?}");
    assert!(m.is_emissive() && texture_matches(&external, m.emissive_texture, "checkerboard_emissive.png"), "{m:?}");
    assert!(external.warnings.iter().any(|w| w.contains("metalness")), "{:?}", external.warnings);

    // Embedded in the file (no image files next to it): the same images.
    let embedded = load("blender_293_embedded_textures_7400_binary.fbx");
    println!("embedded: {:?}", embedded.materials);
    let m = embedded.materials.iter().find(|m| m.base_color_texture.is_some()).expect("a base colour texture");
    assert!(texture_matches(&embedded, m.base_color_texture, "checkerboard_diffuse.png"), "{m:?}");
    assert!(m.is_emissive() && texture_matches(&embedded, m.emissive_texture, "checkerboard_emissive.png"), "{m:?}");
}

fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("lightport-fbx-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

#[test]
fn texture_paths_fall_back_to_the_file_name_and_missing_files_are_named() {
    let fbx = "blender_293_textures_7400_binary.fbx";
    let reference = load(fbx);
    // The images next to the file instead of in `textures/`: the relative path misses, the
    // absolute one (D:\Dev\...) is another machine's, the bare file name is found.
    let dir = scratch("flat");
    std::fs::copy(fbx_dir().join(fbx), dir.join(fbx)).unwrap();
    for entry in std::fs::read_dir(fbx_dir().join("textures")).unwrap() {
        let entry = entry.unwrap();
        std::fs::copy(entry.path(), dir.join(entry.file_name())).unwrap();
    }
    let flat = scene::load(&dir.join(fbx)).unwrap();
    assert_eq!(flat.materials, reference.materials);
    assert_eq!(flat.textures, reference.textures);

    // No images at all: a warning naming each image and the materials rendering with their
    // factors instead; a strict load refuses with an I/O error naming the image.
    let bare = scratch("bare");
    std::fs::copy(fbx_dir().join(fbx), bare.join(fbx)).unwrap();
    let s = scene::load(&bare.join(fbx)).unwrap();
    assert!(s.textures.is_empty(), "{:?}", s.textures);
    assert!(
        s.warnings
            .iter()
            .any(|w| w.contains("texture ignored") && w.contains("checkerboard_") && w.contains("factors")),
        "{:?}",
        s.warnings
    );
    assert!(s.materials.iter().all(|m| m.base_color_texture.is_none() && m.emissive_texture.is_none()));
    let e = scene::load_with(&bare.join(fbx), &LoadOptions { strict: true, ..Default::default() }).unwrap_err();
    assert!(matches!(&e, SceneError::Io { path, .. } if path.to_string_lossy().contains("checkerboard_")), "{e}");
    let _ = std::fs::remove_dir_all(dir);
    let _ = std::fs::remove_dir_all(bare);
}

#[test]
fn materials_cameras_and_unsupported_content() {
    // Several materials on one mesh: each face keeps its own.
    let multi = load("blender_suzanne_multimaterial_7400_binary.fbx");
    let used: std::collections::BTreeSet<u32> = multi.triangles.iter().map(|t| t.material).collect();
    println!("multimaterial: {:?} used {used:?}", multi.materials);
    assert!(used.len() >= 2, "{used:?}");

    // A skinned character: its bind pose, and skinning named in the warnings.
    let barbarian = load("blender_293_barbarian_7400_binary.fbx");
    println!("barbarian: {} triangles, warnings {:?}", barbarian.triangles.len(), barbarian.warnings);
    assert!(barbarian.warnings.iter().any(|w| w.contains("skinning")), "{:?}", barbarian.warnings);
    assert!(barbarian.warnings.iter().any(|w| w.contains("directional lights")), "{:?}", barbarian.warnings);
    // Its camera (Blender's, 49.1° vertical field of view) looks at the character: the scene's
    // centre is inside its view cone.
    let c = barbarian.camera;
    assert!((c.yfov.to_degrees() - 49.13).abs() < 0.01, "{c:?}");
    let to_centre = (barbarian.bounds().center() - c.position).normalize();
    assert!(c.forward().angle_between(to_centre) < 0.5 * c.yfov, "{c:?} vs {to_centre}");

    // 3ds Max's PBR material: the base colour is read, metal-roughness is warned about.
    let max = load("max_pbr_metal_rough_material_7700_ascii.fbx");
    println!("max: {:?}\nwarnings {:?}", max.materials, max.warnings);
    assert!(max.warnings.iter().any(|w| w.contains("metalness")), "{:?}", max.warnings);
}

/// xorshift64 for the mutations (deterministic).
fn next(state: &mut u64) -> u64 {
    *state ^= *state << 13;
    *state ^= *state >> 7;
    *state ^= *state << 17;
    *state
}

#[test]
fn mutated_fbx_files_never_panic_or_hang() {
    let mut files: Vec<PathBuf> = std::fs::read_dir(fbx_dir())
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "fbx"))
        .collect();
    files.sort();
    assert_eq!(files.len(), 13, "the FBX test files changed");
    // Mutants sit next to a copy of `textures/`, so external textures resolve as for the
    // originals and their images are decoded too.
    let dir = scratch("mutated");
    std::fs::create_dir_all(dir.join("textures")).unwrap();
    for entry in std::fs::read_dir(fbx_dir().join("textures")).unwrap() {
        let entry = entry.unwrap();
        std::fs::copy(entry.path(), dir.join("textures").join(entry.file_name())).unwrap();
    }
    let (mut loaded, mut refused, mut panicked) = (0, 0, Vec::new());
    let mut slowest = (Duration::ZERO, String::new());
    let mut state = 0x9E37_79B9_7F4A_7C15u64;
    for path in &files {
        let original = std::fs::read(path).unwrap();
        let name = path.file_name().unwrap().to_string_lossy().into_owned();
        let mut mutants: Vec<(String, Vec<u8>)> = Vec::new();
        for cut in [0, 1, 20, 27, 64, 200, original.len() / 3, original.len() / 2, original.len() - 1] {
            mutants.push((format!("{name} cut to {cut} bytes"), original[..cut].to_vec()));
        }
        for round in 0..24 {
            let mut bytes = original.clone();
            let flips = 1 + round % 8;
            for _ in 0..flips {
                let at = (next(&mut state) % bytes.len() as u64) as usize;
                bytes[at] ^= 1 << (next(&mut state) % 8);
            }
            mutants.push((format!("{name} with {flips} flipped bits (round {round})"), bytes));
        }
        for (what, bytes) in mutants {
            let mutant = dir.join(&name);
            std::fs::write(&mutant, &bytes).unwrap();
            let t0 = Instant::now();
            let result = catch_unwind(AssertUnwindSafe(|| scene::load(&mutant)));
            let took = t0.elapsed();
            if took > slowest.0 {
                slowest = (took, what.clone());
            }
            match result {
                Ok(Ok(s)) => {
                    s.validate().unwrap_or_else(|e| panic!("{what}: loaded an invalid scene: {e}"));
                    loaded += 1;
                }
                Ok(Err(_)) => refused += 1,
                Err(_) => panicked.push(what),
            }
        }
    }
    println!("{loaded} mutants loaded, {refused} refused; slowest {:?} ({})", slowest.0, slowest.1);
    assert!(panicked.is_empty(), "panicked on: {panicked:#?}");
    assert!(slowest.0 < Duration::from_secs(5), "{} took {:?}", slowest.1, slowest.0);
    assert!(refused > 0 && loaded > 0, "the mutations should both break and spare files");
    let _ = std::fs::remove_dir_all(dir);
}
