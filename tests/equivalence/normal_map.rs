//! Normal maps (`kernel::normal_map`): the pure functions on adversarial inputs, and the scene
//! functions on DamagedHelmet's packed normal-mapped data.

use super::*;

/// Normalisations (`sqrt`, division) and a cross product: GPU rounding of a few ULP in each,
/// compounded; components lie in [-1, 1]. Measured on llvmpipe; see the printout.
const NORMAL_MAP: Tolerance = Tolerance::ulps(64).with_absolute(2e-6).flushing_subnormals();

/// Whether `bend_normal(n, ng, wo)` is within `margin` of its decision (left alone or bent),
/// where GPU rounding may take the other branch.
fn near_bend_decision(n: Vec3, ng: Vec3, wo: Vec3, margin: f32) -> bool {
    let cos_n = n.dot(wo);
    let r = n * (2.0 * cos_n) - wo;
    cos_n.abs() < margin || (ng.dot(r) - tracer::kernel::normal_map::MIN_REFLECTION_COSINE).abs() < margin
}

#[test]
fn normal_map_functions_agree() {
    use tracer::kernel::normal_map;
    let mut eq = equivalence();
    let mut r = TestRng::new(41);
    // Pure functions: texel decoding, the tangent frame, the bend, adversarial inputs included.
    let texels: Vec<(Vec3, f32)> =
        (0..1 << 14).map(|_| (Vec3::new(r.f32(), r.f32(), r.f32()), r.range(-3.0, 3.0))).collect();
    assert_equivalent(
        &mut eq,
        "tangent_space_normal",
        &texels,
        |_, &(rgb, scale)| (normal_map::tangent_space_normal(rgb, scale),),
        NORMAL_MAP,
    );
    let frames: Vec<(Vec3, glam::Vec4, Vec3)> = (0..1 << 14)
        .map(|i| {
            let n = r.unit_vector();
            let t = match i % 16 {
                0 => glam::Vec4::ZERO,
                1 => (n * 2.0).extend(1.0),
                _ => r.vec3(1.0).extend(r.range(-1.0, 1.0)),
            };
            (n, t, r.vec3(1.0))
        })
        .filter(|&(n, t, m)| {
            // Away from the degenerate-tangent and zero-normal cut-offs: a tangent nearly along
            // the normal magnifies rounding by 1 / |tangent - normal part| (1.2e-5 absolute
            // measured at 1e-3).
            let tt = t.truncate() - n * n.dot(t.truncate());
            (tt.length() > 0.05 || t == glam::Vec4::ZERO || tt.length() < 1e-7) && m.length() > 0.05
        })
        .collect();
    assert_equivalent(
        &mut eq,
        "perturb_normal",
        &frames,
        |_, &(n, t, m)| (normal_map::perturb_normal(n, t, m),),
        NORMAL_MAP,
    );
    let bends: Vec<(Vec3, Vec3, Vec3)> = (0..1 << 15)
        .map(|i| {
            let ng = r.unit_vector();
            let v = r.unit_vector();
            let height = if i % 4 == 0 { 10f32.powf(-r.range(0.0, 5.0)) } else { r.f32() };
            let wo = ((v - ng * v.dot(ng)).normalize_or(ng.any_orthonormal_vector()) + ng * height).normalize();
            let n = if i % 7 == 0 { -ng } else { r.unit_vector() };
            (n, ng, wo)
        })
        .filter(|&(n, ng, wo)| !near_bend_decision(n, ng, wo, 1e-4))
        .collect();
    // Bent normals normalise a component that can be short (the reflection nearly along the
    // geometric normal) and sums of nearly opposite grazing vectors: 1.2e-5 absolute measured.
    assert_equivalent(
        &mut eq,
        "bend_normal",
        &bends,
        |_, &(n, ng, wo)| (normal_map::bend_normal(n, ng, wo),),
        NORMAL_MAP.with_absolute(3e-5),
    );

    // Scene functions on DamagedHelmet, which has a normal map.
    let scene =
        tracer::scene::load(&test_data("scenes/khronos/DamagedHelmet/glTF-Binary/DamagedHelmet.glb")).expect("loads");
    let bvh = tracer::bvh::build(&scene.triangles).expect("BVH");
    let packed = pack(&scene, &bvh, &RenderSettings::default()).expect("pack");
    assert!(packed.features.normal_map, "{:?}", packed.features);
    eq.set_scene(&packed.scene).expect("scene uploads");
    eq.set_specialization(packed.features.specialization());
    let k = eq.scene().clone();
    let triangles = packed.triangle_count as u32;
    let materials = (k.materials.len() as u32 - k.normal_map_first).min(k.normal_map_first / 2);
    let indices: Vec<(u32,)> = (0..materials).map(|i| (i,)).collect();
    assert_equivalent(
        &mut eq,
        "fetch_normal_map",
        &indices,
        |s, &(i,)| (normal_map::fetch_normal_map(s, i),),
        Tolerance::EXACT,
    );
    let barycentric: Vec<(u32, f32, f32)> = (0..1 << 15)
        .map(|_| {
            let (u, v) = (r.f32(), r.f32());
            let (u, v) = if u + v > 1.0 { (1.0 - u, 1.0 - v) } else { (u, v) };
            (r.next_u32() % triangles, u, v)
        })
        .collect();
    assert_equivalent(
        &mut eq,
        "interpolated_tangent",
        &barycentric,
        |s, &(i, u, v)| (normal_map::interpolated_tangent(s, i, u, v),),
        Tolerance::ulps(4).with_absolute(1e-7),
    );
    // Whole shading normals at random points, views down to grazing, both faces.
    let hits: Vec<(Hit, u32, Vec3, f32, Vec3, Vec3)> = barycentric
        .iter()
        .enumerate()
        .filter_map(|(j, &(i, u, v))| {
            let tri = scene_data::fetch_triangle(&k, i);
            let face = (tri.v1 - tri.v0).cross(tri.v2 - tri.v0).normalize_or_zero();
            let flip = if j % 2 == 0 { 1.0 } else { -1.0 };
            let ng = face * flip;
            let n = scene_data::shading_normal(&k, i, u, v).normalize_or_zero() * flip;
            let side = r.unit_vector();
            let wo = ((side - ng * side.dot(ng)).normalize_or_zero() + ng * 10f32.powf(-r.range(0.0, 4.0)))
                .normalize_or_zero();
            let ns = if n.dot(ng) > 0.0 { n } else { ng };
            let hit = Hit { triangle: i, t: 1.0, u, v, instance: 0 };
            // Skip cases near the bend's decision for the mapped normal as the CPU computes it.
            let mapped = {
                let map = normal_map::fetch_normal_map(&k, tri.material);
                let uv = scene_data::texcoord(&k, i, u, v);
                let rgb = textures::sample_data_texture(&k, map.texture, uv);
                let t = normal_map::interpolated_tangent(&k, i, u, v);
                normal_map::perturb_normal(ns * flip, t, normal_map::tangent_space_normal(rgb.truncate(), map.scale))
                    * flip
            };
            (face != Vec3::ZERO && wo != Vec3::ZERO && !near_bend_decision(mapped, ng, wo, 1e-3)).then_some((
                hit,
                tri.material,
                ns,
                flip,
                ng,
                wo,
            ))
        })
        .collect();
    assert!(hits.len() > barycentric.len() / 2, "{} cases", hits.len());
    assert_equivalent(
        &mut eq,
        "normal_mapped",
        &hits,
        |s, &(hit, m, ns, flip, ng, wo)| (normal_map::normal_mapped(s, hit, m, ns, flip, ng, wo),),
        // The bilinear weights add their own few ULP before the frame and the bend.
        NORMAL_MAP.with_absolute(3e-5),
    );
}
