//! Normal maps (`Features::normal_map`, `tracer::kernel::normal_map`) on the CPU: MikkTSpace
//! tangents against analytic ones, a normal-mapped flat quad against the quad really tilted,
//! a flat map against no map, adversarial maps at grazing angles (bend, no leaks, energy
//! bounded under a white furnace), the Lambert-only kernel unchanged by the feature, and
//! loading (DamagedHelmet; a glTF's own `TANGENT`s).

use crate::common;

use common::{mean_variance, TestRng};
use glam::{Quat, Vec2, Vec3, Vec4, Vec4Swizzles};
use tracer::kernel::integrator::render_sample;
use tracer::kernel::normal_map::{bend_normal, normal_mapped, perturb_normal, MIN_REFLECTION_COSINE};
use tracer::kernel::traverse::Hit;
use tracer::kernel::Strategy;
use tracer::pack::Packed;
use tracer::scene::{Camera, Material, PointLight, Scene, Sky, Texture, Triangle, Wrap};

/// A texture of `width x height` RGB texels (alpha 255), as the loaders store them.
fn rgb_texture(width: u32, height: u32, texel: impl Fn(u32, u32) -> [u8; 3]) -> Texture {
    let texels: Vec<u32> = (0..width * height)
        .map(|i| {
            let [r, g, b] = texel(i % width, i / width);
            r as u32 | (g as u32) << 8 | (b as u32) << 16 | 0xff << 24
        })
        .collect();
    Texture { width, height, texels: texels.into(), wrap_s: Wrap::Repeat, wrap_t: Wrap::Repeat }
}

/// The two triangles of quad `q` (counter-clockwise from the front) with the generators'
/// texture coordinates: q0 (0, 1), q1 (1, 1), q2 (1, 0), q3 (0, 0).
fn quad(q: [Vec3; 4], material: u32) -> Vec<Triangle> {
    let uv = [Vec2::new(0.0, 1.0), Vec2::new(1.0, 1.0), Vec2::new(1.0, 0.0), Vec2::new(0.0, 0.0)];
    [[0, 1, 2], [0, 2, 3]]
        .iter()
        .map(|&[a, b, c]| {
            let positions = [q[a], q[b], q[c]];
            let n = (positions[1] - positions[0]).cross(positions[2] - positions[0]).normalize();
            Triangle {
                positions,
                normals: [n; 3],
                uvs: [uv[a], uv[b], uv[c]],
                uvs1: Default::default(),
                tangents: Default::default(),
                material,
            }
        })
        .collect()
}

/// A `size` m square in the xz-plane facing +Y, rotated by `rotation` about the origin: +u
/// along +X, the image's up (-v) along -Z.
fn square(size: f32, rotation: Quat, material: u32) -> Vec<Triangle> {
    let h = 0.5 * size;
    let q = [Vec3::new(-h, 0.0, h), Vec3::new(h, 0.0, h), Vec3::new(h, 0.0, -h), Vec3::new(-h, 0.0, -h)];
    quad(q.map(|p| rotation * p), material)
}

/// A scene of one square with `material`, its normal map `map` if any (tangents generated),
/// seen from `camera`.
fn square_scene(material: Material, map: Option<Texture>, rotation: Quat, camera: Camera) -> Scene {
    let mut scene =
        Scene { triangles: square(40.0, rotation, 0), materials: vec![material], camera, ..Scene::default() };
    if let Some(map) = map {
        scene.textures = vec![map];
        scene.materials[0].normal_texture = Some(0);
        scene.generate_tangents();
    }
    scene.validate().expect("valid scene");
    scene
}

/// Straight down onto the origin, a 0.2 m wide view.
fn top_camera() -> Camera {
    Camera::look_at(Vec3::new(0.0, 3.0, 0.0), Vec3::ZERO, Vec3::NEG_Z, 0.066)
}

fn pack(scene: &Scene, size: u32, strategy: Strategy) -> Packed {
    common::agreement::packed(scene, strategy, size, 4)
}

/// Every sample of `frames` frames of `packed`: (radiance, finite).
fn samples(packed: &Packed, frames: u32) -> Vec<Vec4> {
    let mut k = packed.scene.clone();
    let mut out = Vec::new();
    for f in 0..frames {
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

fn mean_luminance(samples: &[Vec4]) -> (f64, f64, usize) {
    mean_variance(samples.iter().map(|s| s.xyz().dot(Vec3::splat(1.0 / 3.0)) as f64))
}

/// The byte encoding of a unit tangent-space normal, and the normal those bytes decode to.
fn encode(m: Vec3) -> ([u8; 3], Vec3) {
    let bytes = m.to_array().map(|c| ((c * 0.5 + 0.5) * 255.0).round().clamp(0.0, 255.0) as u8);
    let decoded = Vec3::from_array(bytes.map(|b| b as f32 / 255.0 * 2.0 - 1.0)).normalize();
    (bytes, decoded)
}

// ---------------------------------------------------------------------------------------------
// (1) MikkTSpace tangents against analytic ones.

/// The angle in degrees between two directions.
fn degrees(a: Vec3, b: Vec3) -> f32 {
    a.normalize().dot(b.normalize()).clamp(-1.0, 1.0).acos().to_degrees()
}

#[test]
fn mikktspace_tangents_match_analytic_ones_on_planes() {
    // The square, and the same square with u mirrored: the tangent follows +u, the handedness
    // makes the bitangent point up the image (-v) as glTF's normal maps expect.
    for mirrored in [false, true] {
        let mut scene = square_scene(Material::diffuse("m", Vec3::ONE), None, Quat::IDENTITY, top_camera());
        scene.textures = vec![rgb_texture(1, 1, |_, _| [128, 128, 255])];
        scene.materials[0].normal_texture = Some(0);
        if mirrored {
            for t in &mut scene.triangles {
                t.uvs = t.uvs.map(|uv| Vec2::new(1.0 - uv.x, uv.y));
            }
        }
        scene.generate_tangents();
        let expected_t = if mirrored { Vec3::NEG_X } else { Vec3::X };
        for t in &scene.triangles {
            for (c, tangent) in t.tangents.iter().enumerate() {
                assert!(degrees(tangent.xyz(), expected_t) < 1e-3, "mirrored {mirrored}: {tangent}");
                assert!((tangent.xyz().length() - 1.0).abs() < 1e-5);
                let bitangent = t.normals[c].cross(tangent.xyz()) * tangent.w;
                assert!(degrees(bitangent, Vec3::NEG_Z) < 1e-3, "mirrored {mirrored}: bitangent {bitangent}");
            }
        }
    }
}

/// A UV sphere of unit radius: u = longitude / 2π, v = colatitude / π (v = 0 at +Y, the top
/// of the image), smooth normals, counter-clockwise from outside.
fn uv_sphere(rings: u32, segments: u32) -> Vec<Triangle> {
    let point = |i: u32, j: u32| {
        let (theta, phi) =
            (std::f32::consts::PI * i as f32 / rings as f32, std::f32::consts::TAU * j as f32 / segments as f32);
        let p = Vec3::new(theta.sin() * phi.cos(), theta.cos(), -theta.sin() * phi.sin());
        (p, Vec2::new(j as f32 / segments as f32, i as f32 / rings as f32))
    };
    let mut out = Vec::new();
    for i in 0..rings {
        for j in 0..segments {
            let corners = [point(i, j), point(i + 1, j), point(i + 1, j + 1), point(i, j + 1)];
            for [a, b, c] in [[0, 1, 2], [0, 2, 3]] {
                let mut tri = [corners[a], corners[b], corners[c]];
                let face = (tri[1].0 - tri[0].0).cross(tri[2].0 - tri[0].0);
                if face.length() < 1e-7 {
                    continue; // the poles' degenerate halves
                }
                if face.dot(tri[0].0 + tri[1].0 + tri[2].0) < 0.0 {
                    tri.swap(1, 2);
                }
                out.push(Triangle {
                    positions: tri.map(|c| c.0),
                    normals: tri.map(|c| c.0.normalize()),
                    uvs: tri.map(|c| c.1),
                    uvs1: Default::default(),
                    tangents: Default::default(),
                    material: 0,
                });
            }
        }
    }
    out
}

#[test]
fn mikktspace_tangents_match_analytic_ones_on_a_sphere() {
    let mut scene = Scene {
        triangles: uv_sphere(48, 96),
        materials: vec![Material { normal_texture: Some(0), ..Material::diffuse("m", Vec3::ONE) }],
        textures: vec![rgb_texture(1, 1, |_, _| [128, 128, 255])],
        ..Scene::default()
    };
    scene.generate_tangents();
    let mut worst = 0.0f32;
    let mut sum = 0.0f64;
    let mut checked = 0;
    for t in &scene.triangles {
        for c in 0..3 {
            let p = t.positions[c];
            let theta = p.y.clamp(-1.0, 1.0).acos();
            // Away from the poles, where longitude (and so the tangent) is undefined.
            if !(0.3..=std::f32::consts::PI - 0.3).contains(&theta) {
                continue;
            }
            let phi = (-p.z).atan2(p.x);
            // dP/du ∝ (-sin φ, 0, -cos φ); up the image (-v, towards +Y) is -dP/dθ.
            let analytic_t = Vec3::new(-phi.sin(), 0.0, -phi.cos());
            let analytic_up = -Vec3::new(theta.cos() * phi.cos(), -theta.sin(), -theta.cos() * phi.sin());
            let tangent = t.tangents[c];
            let angle = degrees(tangent.xyz(), analytic_t);
            worst = worst.max(angle);
            sum += angle as f64;
            let bitangent = t.normals[c].cross(tangent.xyz()) * tangent.w;
            assert!(bitangent.dot(analytic_up) > 0.99, "handedness at {p}: bitangent {bitangent} vs {analytic_up}");
            checked += 1;
        }
    }
    let mean = sum / checked as f64;
    println!("sphere: {checked} corners, tangent angle mean {mean:.3}°, worst {worst:.3}°");
    assert!(checked > 10_000, "{checked}");
    // MikkTSpace averages the faces around a vertex, each face's tangent off by up to half a
    // segment's turn (1.9° on this 48 x 96 sphere), most near the poles.
    assert!(worst < 2.5 && mean < 1.0, "tangents from the analytic ones: mean {mean}°, worst {worst}°");
}

// ---------------------------------------------------------------------------------------------
// (2) A normal-mapped flat square renders like the square tilted; a flat map like no map.

/// A point light far away in direction `dir`, giving irradiance 1 at normal incidence.
fn far_light(dir: Vec3) -> PointLight {
    let d = 1000.0;
    PointLight { position: dir.normalize() * d, intensity: Vec3::splat(d * d) }
}

#[test]
fn tilted_normal_map_renders_like_tilted_geometry() {
    // From the side the map tilts towards: cos 0.99 tilted, 0.73 flat.
    let light = Vec3::new(0.8, 1.0, -0.5).normalize();
    // Tilted 35° towards tangent-space azimuth 30°: both channels (x: +u, y: up the image) used.
    let (a, b) = (35f32.to_radians(), 30f32.to_radians());
    let (bytes, m) = encode(Vec3::new(a.sin() * b.cos(), a.sin() * b.sin(), a.cos()));
    // World normal: x along +u (+X), y up the image (-Z), z the surface normal (+Y).
    let tilted = Vec3::new(m.x, m.z, -m.y);
    let materials = [
        ("Lambert", Material::diffuse("white", Vec3::splat(0.8))),
        ("metal-rough", Material::metal_rough("metal", Vec3::splat(0.8), 1.0, 0.5)),
    ];
    for (name, material) in materials {
        let render = |map: Option<Texture>, rotation: Quat| {
            let mut scene = square_scene(material.clone(), map, rotation, top_camera());
            scene.point_lights = vec![far_light(light)];
            let packed = pack(&scene, 16, Strategy::Mis);
            let s = samples(&packed, 4);
            assert!(s.iter().all(|s| s.w == 1.0), "{name}: every sample finite");
            (mean_luminance(&s).0, packed.features)
        };
        let (mapped, features) = render(Some(rgb_texture(2, 2, |_, _| bytes)), Quat::IDENTITY);
        assert!(features.normal_map && features.textures, "{features:?}");
        let (geometry, features) = render(None, Quat::from_rotation_arc(Vec3::Y, tilted));
        assert!(!features.normal_map, "{features:?}");
        let (flat, _) = render(None, Quat::IDENTITY);
        println!("{name}: normal-mapped {mapped:.5}, tilted geometry {geometry:.5}, flat {flat:.5}");
        assert!((mapped / geometry - 1.0).abs() < 2e-3, "{name}: mapped {mapped} vs tilted {geometry}");
        assert!((mapped / flat - 1.0).abs() > 0.1, "{name}: the tilt must show ({mapped} vs flat {flat})");
        if name == "Lambert" {
            // Lambert under a far point light of irradiance 1: albedo / π · cos.
            let expected = 0.8 / std::f64::consts::PI * tilted.dot(light) as f64;
            assert!((mapped / expected - 1.0).abs() < 2e-3, "{mapped} vs analytic {expected}");
        }
    }
}

#[test]
fn flat_normal_map_renders_like_no_map() {
    for strategy in [Strategy::Mis, Strategy::Bsdf] {
        let render = |map: Option<Texture>| {
            let camera = Camera::look_at(Vec3::new(0.0, 1.5, 2.5), Vec3::ZERO, Vec3::Y, 0.8);
            let mut scene = square_scene(Material::diffuse("white", Vec3::splat(0.7)), map, Quat::IDENTITY, camera);
            scene.sky = Some(Sky::uniform(Vec3::ONE));
            scene.point_lights = vec![far_light(Vec3::new(-0.3, 1.0, 0.2))];
            let packed = pack(&scene, 24, strategy);
            mean_variance(samples(&packed, 24).iter().map(|s| s.xyz().dot(Vec3::splat(1.0 / 3.0)) as f64))
        };
        let (with_map, var_a, n) = render(Some(rgb_texture(4, 4, |_, _| [128, 128, 255])));
        let (without, var_b, _) = render(None);
        let sigma = ((var_a + var_b) / n as f64).sqrt();
        println!("{strategy:?}: flat map {with_map:.5}, no map {without:.5} (σ {sigma:.1e})");
        // The map's 128 decodes to 0.0039, a 0.3° tilt: within 4σ of the noise plus 0.2%.
        assert!((with_map - without).abs() < 4.0 * sigma + 2e-3 * without, "{with_map} vs {without}");
    }
}

// ---------------------------------------------------------------------------------------------
// (3) Adversarial maps: never below the surface, no leaks, energy bounded.

/// A map of random bytes with the worst texels mixed in: straight backwards (0, 0, 0 decodes
/// to -1, -1, -1), tangent to the surface, along -z.
fn adversarial_map(seed: u64) -> Texture {
    let mut r = TestRng::new(seed);
    let nasty = [[0, 0, 0], [255, 128, 128], [0, 128, 128], [128, 255, 127], [128, 128, 0], [255, 255, 128]];
    let texels: Vec<[u8; 3]> = (0..64)
        .map(|i| if i % 3 == 0 { nasty[i / 3 % nasty.len()] } else { [0, 1, 2].map(|_| (r.next_u32() % 256) as u8) })
        .collect();
    rgb_texture(8, 8, |x, y| texels[(y * 8 + x) as usize])
}

#[test]
fn bent_normals_face_the_viewer_and_keep_the_reflection_above_the_surface() {
    let mut r = TestRng::new(77);
    let mut bent = 0;
    for i in 0..200_000 {
        let ng = r.unit_vector();
        // Views down to 1e-6 from the horizon.
        let wo = {
            let v = r.unit_vector();
            let v = v - ng * v.dot(ng);
            let height = if i % 4 == 0 { 10f32.powf(-r.range(0.0, 6.0)) } else { r.f32() };
            (v.normalize_or(ng.any_orthonormal_vector()) + ng * height).normalize()
        };
        let n = match i % 5 {
            0 => -ng,
            1 => (ng.any_orthonormal_vector() + ng * 1e-7).normalize(),
            _ => r.unit_vector(),
        };
        assert!(ng.dot(wo) > 0.0);
        let out = bend_normal(n, ng, wo);
        assert!(out.is_finite() && (out.length() - 1.0).abs() < 1e-4, "{n} {ng} {wo} -> {out}");
        assert!(out.dot(ng) > 0.0 && out.dot(wo) > 0.0, "{n} {ng} {wo} -> {out}");
        let reflected = out * 2.0 * out.dot(wo) - wo;
        assert!(reflected.dot(ng) >= MIN_REFLECTION_COSINE - 1e-4, "{n} {ng} {wo} -> {out}: {reflected}");
        let valid = n.dot(wo) > 0.0 && (n * 2.0 * n.dot(wo) - wo).dot(ng) >= MIN_REFLECTION_COSINE;
        if valid {
            assert_eq!(out, n, "a valid normal is left alone");
        } else {
            bent += 1;
        }
    }
    assert!(bent > 50_000, "{bent} bent");
    // Degenerate tangents or maps fall back to the unperturbed normal; results are unit.
    let n = Vec3::Y;
    assert_eq!(perturb_normal(n, Vec4::ZERO, Vec3::X), n);
    assert_eq!(perturb_normal(n, Vec4::new(0.0, 2.0, 0.0, 1.0), Vec3::X), n, "tangent along the normal");
    assert_eq!(perturb_normal(n, Vec4::new(1.0, 0.0, 0.0, 1.0), Vec3::ZERO), n, "zero map normal");
    let p = perturb_normal(n, Vec4::new(1.0, 0.3, 0.0, -1.0), Vec3::new(1.0, 1.0, 1.0));
    assert!((p.length() - 1.0).abs() < 1e-6 && (p - Vec3::new(1.0, 1.0, 1.0).normalize()).length() < 1e-6, "{p}");
}

/// Grazing and steep cameras over a square with an adversarial map.
fn adversarial_cameras() -> Vec<Camera> {
    [1.0f32, 5.0, 30.0, 80.0]
        .iter()
        .map(|elevation| {
            let e = elevation.to_radians();
            Camera::look_at(Vec3::new(0.0, e.sin(), e.cos()) * 4.0, Vec3::ZERO, Vec3::Y, 0.3)
        })
        .collect()
}

#[test]
fn adversarial_maps_stay_finite_and_on_the_viewer_side() {
    let scene = square_scene(
        Material::diffuse("white", Vec3::ONE),
        Some(adversarial_map(3)),
        Quat::IDENTITY,
        adversarial_cameras()[0],
    );
    let packed = pack(&scene, 8, Strategy::Mis);
    let k = &packed.scene;
    let mut r = TestRng::new(9);
    for i in 0..100_000 {
        let triangle = r.next_u32() % packed.triangle_count as u32;
        let (u, v) = (r.f32(), r.f32());
        let (u, v) = if u + v > 1.0 { (1.0 - u, 1.0 - v) } else { (u, v) };
        let tri = tracer::kernel::scene_data::fetch_triangle(k, triangle);
        let face = (tri.v1 - tri.v0).cross(tri.v2 - tri.v0).normalize();
        // Either side, down to 1e-6 from the horizon.
        let flip = if i % 2 == 0 { 1.0 } else { -1.0 };
        let ng = face * flip;
        let side = Vec3::new(r.range(-1.0, 1.0), 0.0, r.range(-1.0, 1.0)).normalize_or(Vec3::X);
        let wo = (side + ng * 10f32.powf(-r.range(0.0, 6.0))).normalize();
        let hit = Hit { triangle, t: 1.0, u, v, instance: 0 };
        let n = normal_mapped(k, hit, tri.material, ng, flip, ng, wo);
        assert!(n.is_finite() && (n.length() - 1.0).abs() < 1e-4, "{n}");
        assert!(n.dot(ng) > 0.0 && n.dot(wo) > 0.0, "{n} with ng {ng}, wo {wo}");
    }
}

#[test]
fn adversarial_maps_leak_no_light_through_the_surface() {
    for (c, camera) in adversarial_cameras().into_iter().enumerate() {
        for material in [Material::diffuse("white", Vec3::ONE), Material::metal_rough("metal", Vec3::ONE, 1.0, 0.2)] {
            let mut scene = square_scene(material, Some(adversarial_map(c as u64)), Quat::IDENTITY, camera);
            // The light is under the square; the camera above it.
            scene.point_lights =
                vec![PointLight { position: Vec3::new(0.3, -0.5, 0.1), intensity: Vec3::splat(100.0) }];
            let packed = pack(&scene, 16, Strategy::Mis);
            assert!(packed.features.normal_map);
            let s = samples(&packed, 8);
            assert!(s.iter().all(|s| s.w == 1.0), "camera {c}: every sample finite");
            let lit = s.iter().filter(|s| s.xyz() != Vec3::ZERO).count();
            assert_eq!(lit, 0, "camera {c}: {lit} samples lit by a light behind the surface");
        }
    }
}

#[test]
fn adversarial_maps_keep_energy_bounded_in_a_white_furnace() {
    // A white square (albedo 1) under a uniform sky of radiance 1: each pixel's expected value
    // is the albedo of the shading model over the geometric hemisphere, at most 1.
    for (c, camera) in adversarial_cameras().into_iter().enumerate() {
        for (name, material) in [
            ("Lambert", Material::diffuse("white", Vec3::ONE)),
            ("metal", Material::metal_rough("metal", Vec3::ONE, 1.0, 0.3)),
        ] {
            for strategy in [Strategy::Bsdf, Strategy::Mis] {
                let mut scene = square_scene(material.clone(), Some(adversarial_map(c as u64)), Quat::IDENTITY, camera);
                scene.sky = Some(Sky::uniform(Vec3::ONE));
                let packed = pack(&scene, 16, strategy);
                let s = samples(&packed, 32);
                assert!(s.iter().all(|s| s.w == 1.0), "{name}, camera {c}: every sample finite");
                let (mean, variance, n) = mean_luminance(&s);
                let sigma = (variance / n as f64).sqrt();
                println!("{name} camera {c} {strategy:?}: mean {mean:.4} ± {sigma:.4}");
                assert!(mean <= 1.0 + 4.0 * sigma + 1e-4, "{name}, camera {c}, {strategy:?}: {mean} ± {sigma}");
                assert!(mean > 0.3, "{name}, camera {c}: {mean} (the map must not black the surface out)");
            }
        }
    }
}

// ---------------------------------------------------------------------------------------------
// (5) Loading.

#[test]
fn damaged_helmet_loads_with_normal_maps_and_renders_finite() {
    let mut scene =
        tracer::scene::load(&common::test_data("scenes/khronos/DamagedHelmet/glTF-Binary/DamagedHelmet.glb"))
            .expect("loads");
    assert!(scene.materials.iter().any(|m| m.normal_texture.is_some()), "DamagedHelmet has a normal map");
    assert!(!scene.warnings.iter().any(|w| w.contains("normal")), "{:?}", scene.warnings);
    let with_tangents = scene.triangles.iter().filter(|t| t.tangents[0] != Vec4::ZERO).count();
    println!("{with_tangents} of {} triangles have tangents", scene.triangles.len());
    assert!(with_tangents * 100 > scene.triangles.len() * 99, "{with_tangents}");
    for t in &scene.triangles {
        for (n, tangent) in t.normals.iter().zip(&t.tangents) {
            if *tangent != Vec4::ZERO {
                assert!((tangent.xyz().length() - 1.0).abs() < 1e-4 && tangent.w.abs() == 1.0, "{tangent}");
                assert!(
                    n.dot(tangent.xyz()).abs() < 0.1,
                    "MikkTSpace tangents are orthogonal to the normal: {n} {tangent}"
                );
            }
        }
    }
    // A dim sky and a light to one side: normals show in the shading.
    scene.sky = Some(Sky::uniform(Vec3::splat(0.1)));
    let bounds = scene.bounds();
    let radius = bounds.diagonal().length();
    let light = bounds.center() + Vec3::new(1.0, 1.0, 1.0) * radius;
    scene.point_lights = vec![PointLight { position: light, intensity: Vec3::splat(3.0 * radius * radius) }];
    // Close enough that the helmet fills the frame.
    scene.camera = Camera::look_at(bounds.center() + Vec3::Z * 0.8 * radius, bounds.center(), Vec3::Y, 0.5);
    let size = 48;
    let frames = 4;
    let packed = pack(&scene, size, Strategy::Mis);
    assert!(packed.features.normal_map && packed.features.metal_rough, "{:?}", packed.features);
    let s = samples(&packed, frames);
    let rejected = s.iter().filter(|s| s.w != 1.0).count();
    assert_eq!(rejected, 0, "{rejected} non-finite samples");
    // The same scene without its normal maps: about as bright overall (NaNs turned into black
    // pixels, or normals flipped away from the light, would show), different pixel by pixel.
    for m in &mut scene.materials {
        m.normal_texture = None;
    }
    let plain = pack(&scene, size, Strategy::Mis);
    assert!(!plain.features.normal_map);
    let p = samples(&plain, frames);
    // CPU time with and without the maps, alternated (printed only; medians of 5).
    let mut times = [Vec::new(), Vec::new()];
    for _ in 0..5 {
        for (i, k) in [&packed, &plain].iter().enumerate() {
            let start = std::time::Instant::now();
            std::hint::black_box(samples(k, 1));
            times[i].push(start.elapsed().as_secs_f64());
        }
    }
    for t in &mut times {
        t.sort_by(f64::total_cmp);
    }
    println!("DamagedHelmet CPU frame, with / without normal maps: {:.3}", times[0][2] / times[1][2]);
    // Samples clamped to 1: a few specular fireflies would otherwise decide the means.
    let clamped =
        |s: &[Vec4]| mean_variance(s.iter().map(|s| s.xyz().min(Vec3::ONE).dot(Vec3::splat(1.0 / 3.0)) as f64)).0;
    let (mapped, unmapped) = (clamped(&s), clamped(&p));
    let pixel_mean =
        |s: &[Vec4], i: usize| (0..frames as usize).map(|f| s[f * s.len() / frames as usize + i].xyz()).sum::<Vec3>();
    let pixels = (size * size) as usize;
    let differing = (0..pixels)
        .filter(|&i| {
            (pixel_mean(&s, i) - pixel_mean(&p, i)).abs().max_element()
                > 0.05 * pixel_mean(&p, i).max_element().max(0.05)
        })
        .count();
    println!("DamagedHelmet {size}x{size}: normal-mapped {mapped:.4}, without maps {unmapped:.4}; {differing} of {pixels} pixels differ by > 5 %");
    assert!((mapped / unmapped - 1.0).abs() < 0.15, "{mapped} vs {unmapped}");
    assert!(differing * 16 > pixels, "the normal map must change the shading: {differing} pixels");
}

/// A one-quad glTF (in the xy-plane facing +Z, u along +X) with a normal map, with or without
/// a `TANGENT` attribute: the file's tangents are used as given, else MikkTSpace's.
fn quad_gltf(with_tangents: bool) -> Scene {
    let dir = std::env::temp_dir().join(format!("lightport-nm-{}-{with_tangents}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let mut png = Vec::new();
    image::ImageEncoder::write_image(
        image::codecs::png::PngEncoder::new(&mut png),
        &[128, 128, 255, 255],
        1,
        1,
        image::ExtendedColorType::Rgba8,
    )
    .unwrap();
    std::fs::write(dir.join("n.png"), png).unwrap();
    let positions: [[f32; 3]; 4] = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 1.0, 0.0], [0.0, 1.0, 0.0]];
    let uvs: [[f32; 2]; 4] = [[0.0, 1.0], [1.0, 1.0], [1.0, 0.0], [0.0, 0.0]];
    // Deliberately not MikkTSpace's (+X, +1): rotated in the plane and left-handed.
    let tangents: [[f32; 4]; 4] = [[0.6, 0.8, 0.0, -1.0]; 4];
    let indices: [u16; 6] = [0, 1, 2, 0, 2, 3];
    let mut bin = Vec::new();
    positions.iter().flatten().for_each(|f| bin.extend(f.to_le_bytes()));
    uvs.iter().flatten().for_each(|f| bin.extend(f.to_le_bytes()));
    tangents.iter().flatten().for_each(|f| bin.extend(f.to_le_bytes()));
    indices.iter().for_each(|i| bin.extend(i.to_le_bytes()));
    std::fs::write(dir.join("quad.bin"), &bin).unwrap();
    let tangent_attribute = if with_tangents { r#", "TANGENT": 3"# } else { "" };
    let gltf = format!(
        r#"{{
      "asset": {{"version": "2.0"}},
      "scene": 0, "scenes": [{{"nodes": [0]}}], "nodes": [{{"mesh": 0, "rotation": [0, 0.7071068, 0, 0.7071068]}}],
      "meshes": [{{"primitives": [{{"attributes": {{"POSITION": 0, "TEXCOORD_0": 1{tangent_attribute}}}, "indices": 2, "material": 0}}]}}],
      "materials": [{{"normalTexture": {{"index": 0, "scale": 0.5}}}}],
      "textures": [{{"source": 0}}],
      "images": [{{"uri": "n.png"}}],
      "buffers": [{{"uri": "quad.bin", "byteLength": 156}}],
      "bufferViews": [{{"buffer": 0, "byteOffset": 0, "byteLength": 48}},
                      {{"buffer": 0, "byteOffset": 48, "byteLength": 32}},
                      {{"buffer": 0, "byteOffset": 144, "byteLength": 12}},
                      {{"buffer": 0, "byteOffset": 80, "byteLength": 64}}],
      "accessors": [
        {{"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3", "min": [0, 0, 0], "max": [1, 1, 0]}},
        {{"bufferView": 1, "componentType": 5126, "count": 4, "type": "VEC2"}},
        {{"bufferView": 2, "componentType": 5123, "count": 6, "type": "SCALAR"}},
        {{"bufferView": 3, "componentType": 5126, "count": 4, "type": "VEC4"}}]
    }}"#
    );
    std::fs::write(dir.join("quad.gltf"), gltf).unwrap();
    let scene = tracer::scene::load(&dir.join("quad.gltf")).expect("the quad loads");
    std::fs::remove_dir_all(&dir).ok();
    scene
}

#[test]
fn gltf_tangents_are_used_when_present_and_generated_otherwise() {
    // The node turns the quad 90° about +Y: mesh +X becomes world -Z, mesh +Y stays.
    let turn = Quat::from_rotation_y(std::f32::consts::FRAC_PI_2);
    let from_file = quad_gltf(true);
    assert!(from_file.warnings.is_empty(), "{:?}", from_file.warnings);
    assert_eq!(from_file.materials[0].normal_scale, 0.5);
    assert!(from_file.materials[0].normal_texture.is_some());
    let expected = (turn * Vec3::new(0.6, 0.8, 0.0)).extend(-1.0);
    for t in &from_file.triangles {
        for tangent in t.tangents {
            assert!((tangent - expected).abs().max_element() < 1e-5, "file tangent {tangent}, expected {expected}");
        }
    }
    let generated = quad_gltf(false);
    let expected = (turn * Vec3::X).extend(1.0);
    for t in &generated.triangles {
        for tangent in t.tangents {
            assert!(
                (tangent - expected).abs().max_element() < 1e-5,
                "MikkTSpace tangent {tangent}, expected {expected}"
            );
        }
    }
    // Packed: the scale and the tangents reach the kernel.
    let mut scene = from_file;
    scene.sky = Some(Sky::uniform(Vec3::ONE));
    let packed = pack(&scene, 4, Strategy::Mis);
    assert!(packed.features.normal_map);
    let map = tracer::kernel::normal_map::fetch_normal_map(&packed.scene, 0);
    assert_eq!((map.texture, map.scale), (0, 0.5));
    let t = tracer::kernel::normal_map::interpolated_tangent(&packed.scene, 0, 0.2, 0.3);
    assert!((t - (turn * Vec3::new(0.6, 0.8, 0.0)).extend(-1.0)).abs().max_element() < 1e-5, "{t}");
}

// ---------------------------------------------------------------------------------------------
// Specialisation: the tangent-frame code and data only where a scene has normal maps.

#[test]
fn only_normal_mapped_scenes_carry_the_tangent_frame() {
    use lightport_codegen::Target;
    let mapped = square_scene(
        Material::diffuse("white", Vec3::ONE),
        Some(rgb_texture(1, 1, |_, _| [200, 128, 255])),
        Quat::IDENTITY,
        top_camera(),
    );
    let mut textured = mapped.clone();
    textured.materials[0] = Material { base_color_texture: Some(0), ..Material::diffuse("white", Vec3::ONE) };
    let mut storage_buffers = Vec::new();
    for (scene, on) in [(&mapped, true), (&textured, false)] {
        let mut scene = scene.clone();
        scene.sky = Some(Sky::uniform(Vec3::ONE));
        let packed = pack(&scene, 4, Strategy::Mis);
        assert_eq!(packed.features.normal_map, on);
        assert!(packed.features.textures && packed.features.shading);
        let k = &packed.scene;
        let (triangles, materials) = (packed.triangle_count, scene.materials.len());
        // Tangents extend `shading` and the maps `materials` only with the feature.
        let extra = if on { 3 } else { 0 };
        assert_eq!(k.shading.len(), triangles * (4 + extra));
        assert_eq!(k.materials.len(), materials * (2 + extra / 3));
        let wgsl = tracer::kernel::path_tracer_shader(&packed.features, Target::Wgsl).unwrap().source;
        let glsl = tracer::kernel::path_tracer_shader(&packed.features, Target::GlslEs300).unwrap().source;
        println!("normal_map {on}: kernel GLSL {} bytes, WGSL {} bytes", glsl.len(), wgsl.len());
        storage_buffers.push(wgsl.matches("var<storage").count());
        for target in [Target::GlslEs300, Target::Wgsl] {
            let source = tracer::kernel::path_tracer_shader(&packed.features, target).unwrap().source;
            for name in ["normal_mapped", "bend_normal", "tangent_first", "normal_map_first"] {
                assert_eq!(source.contains(name), on, "{target:?}: {name} present: {on}");
            }
        }
    }
    // WebGPU's default is 8 storage buffers per stage: normal maps add none.
    println!("WGSL storage buffers with / without normal maps: {storage_buffers:?}");
    assert_eq!(storage_buffers[0], storage_buffers[1]);
}

/// Bundles carry the feature and its layout, and refuse offsets that do not match the arrays.
#[test]
fn bundles_carry_normal_maps_and_refuse_a_wrong_layout() {
    let mut scene = square_scene(
        Material::diffuse("white", Vec3::ONE),
        Some(rgb_texture(2, 2, |x, _| [200 - 50 * x as u8, 128, 255])),
        Quat::IDENTITY,
        top_camera(),
    );
    scene.sky = Some(Sky::uniform(Vec3::ONE));
    let packed = pack(&scene, 8, Strategy::Mis);
    let decoded = tracer::bundle::decode(&tracer::bundle::encode(&packed)).expect("round trip");
    assert!(decoded.features.normal_map);
    assert_eq!(decoded.scene.has_normal_map, 1);
    assert_eq!(
        (decoded.scene.tangent_first, decoded.scene.normal_map_first),
        (packed.scene.tangent_first, packed.scene.normal_map_first)
    );
    assert_eq!(decoded.scene.shading, packed.scene.shading);
    assert_eq!(samples(&decoded, 1), samples(&packed, 1), "the same image from the bundle");
    for (what, change) in [
        ("tangent_first", (|p: &mut Packed| p.scene.tangent_first += 3) as fn(&mut Packed)),
        ("normal_map_first", |p: &mut Packed| p.scene.normal_map_first = 1),
        ("has_normal_map", |p: &mut Packed| p.scene.has_normal_map = 0),
        // A normal-map texture beyond the textures (the kernel would fetch its info past the
        // end: a panic on the CPU, a clamped or zero read on GPUs).
        ("normal-map texture", |p: &mut Packed| {
            let first = p.scene.normal_map_first as usize;
            let mut texels = p.scene.materials.as_slice().to_vec();
            texels[first].x = 99.0;
            p.scene.materials = texels.into();
        }),
    ] {
        let mut bad = packed.clone();
        change(&mut bad);
        let err = tracer::bundle::decode(&tracer::bundle::encode(&bad)).expect_err(what);
        assert!(err.to_string().contains("normal"), "{what}: {err}");
    }
}
