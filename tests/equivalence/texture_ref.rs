//! Texture references (`kernel::texture_ref`): the affine UV map on adversarial inputs, and
//! the scene functions (and the samplers that now go through them) on a generated square
//! whose textures are transformed and read on `TEXCOORD_1`, in every slot the kernel samples.

use super::*;
use tracer::kernel::{lights, normal_map, texture_ref, textures};
use tracer::scene::{Material, UvTransform};

use crate::common::texture_quads as quads;

/// Two products and two sums per coordinate: a few ULP where drivers contract to fma, relative
/// to the largest term (absolute near a cancelling sum).
const UV: Tolerance = Tolerance::ulps(8).with_absolute(1e-6);

/// The square with every slot textured: base colour and metal-roughness through the quarter
/// turn on `TEXCOORD_1`, emission through a scale on set 0, the normal map untransformed.
fn scene() -> tracer::scene::Scene {
    let uv0 = |i: usize| Vec2::from(quads::UVS[i]);
    let uv1 = |i: usize| Vec2::from(quads::UVS[i]) * 0.5 + Vec2::new(0.1, 0.2);
    let mut m = Material {
        base_color_texture: Some(0),
        metallic_roughness_texture: Some(0),
        emissive_texture: Some(0),
        normal_texture: Some(0),
        ..Material::metal_rough("all", Vec3::ONE, 0.5, 0.5)
    };
    m.emission = Vec3::ONE;
    let turn = UvTransform { texcoord: 1, ..quads::quarter_turn() };
    m.texture_uvs =
        [turn, UvTransform { scale: Vec2::new(3.0, -0.5), ..Default::default() }, turn, UvTransform::default(), turn];
    let mut s = quads::scene(quads::square(uv0, uv1), m);
    s.generate_tangents();
    s
}

#[test]
fn texture_reference_functions_agree() {
    let mut eq = equivalence();
    let mut r = TestRng::new(77);
    // The pure map: random matrices and UVs, specials (NaN, inf, huge) among them.
    let specials = special_floats();
    let maps: Vec<(UVec4, UVec4, Vec2)> = (0..1 << 14)
        .map(|i| {
            let lane = |r: &mut TestRng| {
                if i % 8 == 0 {
                    specials[r.next_u32() as usize % specials.len()]
                } else {
                    r.range(-4.0, 4.0)
                }
            };
            let row0 = UVec4::new(lane(&mut r).to_bits(), lane(&mut r).to_bits(), lane(&mut r).to_bits(), 0);
            let row1 = UVec4::new(lane(&mut r).to_bits(), lane(&mut r).to_bits(), lane(&mut r).to_bits(), 0);
            (row0, row1, Vec2::new(r.range(-3.0, 3.0), r.range(-3.0, 3.0)))
        })
        .collect();
    assert_equivalent(&mut eq, "transform_uv", &maps, |_, &(a, b, uv)| (texture_ref::transform_uv(a, b, uv),), UV);

    let scene = scene();
    let bvh = tracer::bvh::build(&scene.triangles).expect("BVH");
    let packed = pack(&scene, &bvh, &RenderSettings::default()).expect("pack");
    let f = packed.features;
    assert!(f.texture_transform && f.texcoord1 && f.normal_map && f.metal_rough, "{f:?}");
    eq.set_scene(&packed.scene).expect("scene uploads");
    eq.set_specialization(f.specialization());
    let k = eq.scene().clone();
    let references = k.texture_ref_first;
    assert_eq!(references, 3, "three references: the turn on set 1, the scale, the plain map");
    let points: Vec<(u32, u32, f32, f32)> = (0..1 << 12)
        .map(|_| {
            let (u, v) = (r.f32(), r.f32());
            let (u, v) = if u + v > 1.0 { (1.0 - u, 1.0 - v) } else { (u, v) };
            (r.next_u32() % references, r.next_u32() % packed.triangle_count as u32, u, v)
        })
        .collect();
    let barycentric: Vec<(u32, f32, f32)> = points.iter().map(|&(_, t, u, v)| (t, u, v)).collect();
    assert_equivalent(
        &mut eq,
        "texcoord1",
        &barycentric,
        |s, &(t, u, v)| (texture_ref::texcoord1(s, t, u, v),),
        Tolerance::ulps(4).with_absolute(1e-7),
    );
    for function in ["texture_uv", "referenced_uv"] {
        let cpu = if function == "texture_uv" { texture_ref::texture_uv } else { texture_ref::referenced_uv };
        assert_equivalent(&mut eq, function, &points, |s, &(i, t, u, v)| (cpu(s, i, t, u, v),), UV);
    }
    // The samplers that read through references: bilinear lookups (sRGB decode: a few ULP).
    let texels = Tolerance::ulps(64).with_absolute(1e-6);
    let emitting: Vec<(u32, u32, f32, f32)> = barycentric.iter().map(|&(t, u, v)| (t, 0, u, v)).collect();
    assert_equivalent(
        &mut eq,
        "triangle_emission",
        &emitting,
        |s, &(t, m, u, v)| (lights::triangle_emission(s, t, m, u, v),),
        texels,
    );
    let material = scene_data::fetch_material(&k, 0);
    let surfaces: Vec<(scene_data::MaterialData, u32, u32, f32, f32)> =
        barycentric.iter().map(|&(t, u, v)| (material, 0, t, u, v)).collect();
    assert_equivalent(
        &mut eq,
        "surface_at",
        &surfaces,
        |s, &(m, i, t, u, v)| (metal_rough::surface_at(s, m, i, t, u, v),),
        texels,
    );
    // Only mapped normals (as the CPU computes them, through the transformed UV) that need no
    // bend, away from its decision: this test is about the UV a normal map is read at; the bend
    // is `normal_map.rs`'s. (On SwiftShader, WebGL2 and WebGPU alike, the bend moved 4 of 4096
    // invocations of this colour-texture-as-normal-map by up to 1.7e-5, where llvmpipe and
    // lavapipe stay within 271 ULP: an open finding, in issue 14's note.)
    let wo = Vec3::new(0.3, 0.9, 0.1).normalize();
    let map = normal_map::fetch_normal_map(&k, 0);
    let hits: Vec<(Hit, u32, Vec3, f32, Vec3, Vec3)> = barycentric
        .iter()
        .filter(|&&(t, u, v)| {
            let uv = texture_ref::texture_uv(&k, map.texture, t, u, v);
            let rgb = textures::sample_data_texture(&k, map.texture, uv);
            let tangent = normal_map::interpolated_tangent(&k, t, u, v);
            let mapped = normal_map::perturb_normal(
                Vec3::Y,
                tangent,
                normal_map::tangent_space_normal(rgb.truncate(), map.scale),
            );
            let r = mapped * (2.0 * mapped.dot(wo)) - wo;
            mapped.dot(wo) > 1e-2 && r.y > normal_map::MIN_REFLECTION_COSINE + 1e-2
        })
        .map(|&(t, u, v)| (Hit { triangle: t, t: 1.0, u, v, instance: 0 }, 0, Vec3::Y, 1.0, Vec3::Y, wo))
        .collect();
    // This map (the colour texture read as normals) tilts most normals far enough to be bent:
    // some 185 of 4096 points are left, spread over the square.
    assert!(hits.len() >= 128, "{} cases", hits.len());
    assert_equivalent(
        &mut eq,
        "normal_mapped",
        &hits,
        |s, &(hit, m, ns, flip, ng, wo)| (normal_map::normal_mapped(s, hit, m, ns, flip, ng, wo),),
        Tolerance::ulps(64).with_absolute(2e-6).flushing_subnormals(),
    );
}
