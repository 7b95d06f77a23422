//! Glass (`kernel::dielectric`, `bsdf::glass_at`, `integrator::volume_transmittance`): the
//! rough dielectric's pure functions over roughness × index × both hemispheres (from outside,
//! from inside, thin-walled, smooth), and the scene functions on the glass Cornell box with a
//! transmission texture added.

use tracer::kernel::bsdf::glass_at;
use tracer::kernel::dielectric::{
    self, dielectric_eval, dielectric_pdf, dielectric_sample, fresnel_dielectric, glass_surface, refract_dir,
    refraction_half,
};
use tracer::kernel::integrator::volume_transmittance;
use tracer::kernel::metal_rough::{sample_ggx_vndf, Surface, MIN_COSINE};

use super::*;

/// As the metal-roughness lobe's (`kernels.rs`): the GGX peak grows as 1 / α² and half
/// vectors are normalised from sums; and Fresnel's `sqrt(1 − sin²θt)` magnifies GPU rounding
/// of wo·h near the critical angle: 2.2e-4 relative (3,700 ULP) measured on llvmpipe for a
/// ray leaving glass 0.8 % short of total internal reflection.
const DIELECTRIC: Tolerance = Tolerance::ulps(8192).with_absolute(1e-6).flushing_subnormals();

/// Sampled directions: the visible normal's rounding (1e-5 absolute, `kernels.rs`' `VNDF`)
/// doubled by reflection and magnified by refraction's `sqrt(1 − sin²θt)` near the critical
/// angle: 4.1e-5 absolute measured on llvmpipe (a direction 1e-4 above the horizon), pdfs
/// 0.4 % apart where the lobe is narrowest.
const DIELECTRIC_SAMPLE: Tolerance = Tolerance::ulps(8192).with_absolute(5e-5).flushing_subnormals();

/// How close to a branch of the dielectric functions a case may come before GPU rounding
/// could take the other branch: such cases are left out (and counted).
const MARGIN: f32 = 1e-4;

/// A unit vector with |z| at least `min_z`, on the side of `sign`.
fn direction(r: &mut TestRng, sign: f32, min_z: f32) -> Vec3 {
    let v = r.unit_vector();
    Vec3::new(v.x, v.y, v.z.abs().max(min_z) * sign).normalize()
}

/// A glass surface: smooth (a delta lobe) one case in six, else roughness over (0, 1]; from
/// outside (η = ior), from inside (1 / ior) or thin-walled; ior from 1 (index-matched: a
/// delta lobe, see `dielectric::INDEX_MATCHED`) to 2.4.
fn glass_case(r: &mut TestRng, i: usize) -> Surface {
    let roughness = if i.is_multiple_of(6) { 0.0 } else { r.range(0.05, 1.0) };
    let ior = match i % 17 {
        0 => 1.0,
        1 => r.range(1.0, 1.01),
        _ => r.range(1.1, 2.4),
    };
    let tint = Vec3::new(r.f32(), r.f32(), r.f32());
    match i % 3 {
        0 => glass_surface(tint, roughness, ior, false),
        1 => glass_surface(tint, roughness, 1.0 / ior, false),
        _ => glass_surface(tint, roughness, ior, true),
    }
}

/// Whether GPU rounding could send `(s, wo, wi)` down another branch of `dielectric_eval` or
/// `dielectric_pdf`: the horizon cut-offs, the side of `wi`, microfacets seen edge-on, the
/// critical angle.
fn near_decision(s: Surface, wo: Vec3, wi: Vec3) -> bool {
    let eta = s.f0.x;
    let near = |x: f32, at: f32| (x - at).abs() < MARGIN;
    if near(wo.z, MIN_COSINE) || near(wi.z.abs(), MIN_COSINE) || near(wi.z, 0.0) {
        return true;
    }
    let h = if wi.z > 0.0 || s.f0.y > 0.0 {
        (wo + Vec3::new(wi.x, wi.y, wi.z.abs())).normalize()
    } else {
        refraction_half(wo, wi, eta)
    };
    let c = wo.dot(h);
    h == Vec3::ZERO || near(c, 0.0) || near(wi.dot(h), 0.0) || near((1.0 - c * c) / (eta * eta), 1.0)
}

/// Whether GPU rounding could make `dielectric_sample(s, wo, u)` choose differently: reflect
/// or refract (u.z against Fresnel), total internal reflection, then the sampled direction's
/// own decisions.
fn near_sample_decision(s: Surface, wo: Vec3, u: Vec3) -> bool {
    let eta = s.f0.x;
    let h = if dielectric::is_delta(s) { Vec3::Z } else { sample_ggx_vndf(s.alpha, wo, u.x, u.y) };
    let c = wo.dot(h);
    let f = fresnel_dielectric(c, eta);
    if (u.z - f).abs() < MARGIN || ((1.0 - c * c) / (eta * eta) - 1.0).abs() < MARGIN || c.abs() < MARGIN {
        return true;
    }
    let sample = dielectric_sample(s, wo, u);
    !dielectric::is_delta(s) && sample.pdf > 0.0 && near_decision(s, wo, sample.dir)
}

#[test]
fn dielectric_functions_agree() {
    let mut eq = equivalence();
    let mut r = TestRng::new(57);

    let fresnel: Vec<(f32, f32)> = (0..1 << 14)
        .map(|i| (r.f32(), if i % 2 == 0 { r.range(1.0, 2.4) } else { 1.0 / r.range(1.0, 2.4) }))
        .filter(|&(c, eta)| ((1.0 - c * c) / (eta * eta) - 1.0).abs() > MARGIN)
        .collect();
    assert_equivalent(
        &mut eq,
        "fresnel_dielectric",
        &fresnel,
        |_, &(c, eta)| (fresnel_dielectric(c, eta),),
        Tolerance::ulps(64).with_absolute(1e-7).flushing_subnormals(),
    );

    // Refraction through a microfacet facing the incident direction, short of the critical angle.
    let refractions: Vec<(Vec3, Vec3, f32)> = (0..1 << 14)
        .map(|i| {
            let h = direction(&mut r, 1.0, 0.05);
            let wo = (r.unit_vector() + h * 1.2).normalize();
            (wo, h, if i % 2 == 0 { r.range(1.0, 2.4) } else { 1.0 / r.range(1.0, 2.4) })
        })
        .filter(|&(wo, h, eta)| {
            let c = wo.dot(h);
            c > MARGIN && (1.0 - c * c) / (eta * eta) < 1.0 - MARGIN
        })
        .collect();
    assert_equivalent(
        &mut eq,
        "refract_dir",
        &refractions,
        |_, &(wo, h, eta)| (refract_dir(wo, h, eta),),
        // `sqrt(1 − sin²θt)` near the critical angle magnifies GPU rounding of sin²θt:
        // 3.7e-6 absolute measured on llvmpipe (components lie in [-1, 1]).
        Tolerance::ulps(256).with_absolute(1e-5).flushing_subnormals(),
    );
    let halves: Vec<(Vec3, Vec3, f32)> =
        refractions.iter().map(|&(wo, h, eta)| (wo, refract_dir(wo, h, eta), eta)).collect();
    assert_equivalent(
        &mut eq,
        "refraction_half",
        &halves,
        |_, &(wo, wi, eta)| (refraction_half(wo, wi, eta),),
        Tolerance::ulps(256).with_absolute(1e-6).flushing_subnormals(),
    );

    let surfaces: Vec<(Vec3, f32, f32, bool)> =
        (0..1 << 12).map(|i| (Vec3::new(r.f32(), r.f32(), r.f32()), r.f32(), r.range(0.4, 2.4), i % 2 == 0)).collect();
    let surfaces: Vec<(Vec3, f32, f32, bool)> =
        surfaces.into_iter().filter(|&(_, roughness, _, _)| (roughness - 0.045).abs() > MARGIN).collect();
    assert_equivalent(
        &mut eq,
        "glass_surface",
        &surfaces,
        |_, &(tint, roughness, eta, thin)| (glass_surface(tint, roughness, eta, thin),),
        Tolerance::ulps(1).flushing_subnormals(),
    );

    // f and pdf for both hemispheres: reflection and refraction, grazing included.
    let pairs: Vec<(Surface, Vec3, Vec3)> = (0..1 << 15)
        .map(|i| {
            let s = glass_case(&mut r, i);
            let wo = direction(&mut r, 1.0, 1e-3);
            let wi = direction(&mut r, if i % 4 == 0 { 1.0 } else { -1.0 }, 1e-3);
            (s, wo, wi)
        })
        .collect();
    let kept: Vec<(Surface, Vec3, Vec3)> =
        pairs.iter().copied().filter(|&(s, wo, wi)| !near_decision(s, wo, wi)).collect();
    assert!(kept.len() > pairs.len() * 9 / 10, "{} of {} cases left", kept.len(), pairs.len());
    let eval = assert_equivalent(
        &mut eq,
        "dielectric_eval",
        &kept,
        |_, &(s, wo, wi)| (dielectric_eval(s, wo, wi),),
        DIELECTRIC,
    );
    let nonzero = eval.outputs[0].1.iter().filter(|(f,)| f.max_element() > 0.0).count();
    // Delta lobes (a quarter of the cases) and microfacets that cannot connect the pair give 0.
    assert!(nonzero > kept.len() / 3, "only {nonzero} of {} cases transmit or reflect anything", kept.len());
    assert_equivalent(&mut eq, "dielectric_pdf", &kept, |_, &(s, wo, wi)| (dielectric_pdf(s, wo, wi),), DIELECTRIC);

    // Sampling: delta and rough, reflection and refraction, total internal reflection.
    let sampled: Vec<(Surface, Vec3, Vec3)> = (0..1 << 15)
        .map(|i| (glass_case(&mut r, i), direction(&mut r, 1.0, 1e-3), Vec3::new(r.f32(), r.f32(), r.f32())))
        .collect();
    let kept: Vec<(Surface, Vec3, Vec3)> =
        sampled.iter().copied().filter(|&(s, wo, u)| !near_sample_decision(s, wo, u)).collect();
    assert!(kept.len() > sampled.len() * 9 / 10, "{} of {} cases left", kept.len(), sampled.len());
    let out = assert_equivalent(
        &mut eq,
        "dielectric_sample",
        &kept,
        |_, &(s, wo, u)| (dielectric_sample(s, wo, u),),
        DIELECTRIC_SAMPLE,
    );
    let refracted = out.outputs[0].1.iter().filter(|(b,)| b.dir.z < 0.0 && b.pdf != 0.0).count();
    let delta = out.outputs[0].1.iter().filter(|(b,)| b.pdf == dielectric::DELTA_PDF).count();
    assert!(refracted > kept.len() / 4 && delta > kept.len() / 10, "{refracted} refracted, {delta} delta samples");
}

#[test]
fn glass_scene_functions_agree() {
    let mut eq = equivalence();
    let mut r = TestRng::new(59);
    // The glass Cornell box, its smooth sphere's transmission modulated by a checker texture.
    let mut scene = tracer::scene::glass_cornell();
    let checker = scene.textures.len() as u32;
    scene.textures.push(tracer::scene::alpha_checker(4));
    scene.materials[5].transmission_texture = Some(checker);
    let bvh = tracer::bvh::build(&scene.triangles).expect("BVH");
    let packed = pack(&scene, &bvh, &RenderSettings::default()).expect("pack");
    let f = packed.features;
    assert!(f.transmission && f.volume && f.textures, "{f:?}");
    eq.set_scene(&packed.scene).expect("scene uploads");
    eq.set_specialization(f.specialization());
    let k = eq.scene().clone();

    let materials: Vec<(u32,)> = (0..scene.materials.len() as u32).map(|i| (i,)).collect();
    assert_equivalent(
        &mut eq,
        "fetch_glass",
        &materials,
        |s, &(i,)| (scene_data::fetch_glass(s, i),),
        Tolerance::EXACT,
    );
    let segments: Vec<(u32, f32)> =
        (0..1 << 12).map(|i| (i % scene.materials.len() as u32, r.range(0.0, 3.0))).collect();
    assert_equivalent(
        &mut eq,
        "volume_transmittance",
        &segments,
        |s, &(m, t)| (volume_transmittance(s, m, t),),
        Tolerance::ulps(16).with_absolute(1e-7).flushing_subnormals(),
    );

    // glass_at at random points of every triangle, from both sides, with the lobe choice's
    // uniform away from the transmissive share (where rounding could pick the other lobe).
    let triangles = packed.triangle_count as u32;
    let hits: Vec<(scene_data::MaterialData, u32, Hit, f32, f32)> = (0..1 << 14)
        .filter_map(|i| {
            let (u, v) = (r.f32(), r.f32());
            let (u, v) = if u + v > 1.0 { (1.0 - u, 1.0 - v) } else { (u, v) };
            let triangle = r.next_u32() % triangles;
            let m = scene_data::fetch_triangle(&k, triangle).material;
            let hit = Hit { triangle, t: 1.0, u, v, instance: 0 };
            let flip = if i % 2 == 0 { 1.0 } else { -1.0 };
            let lobe = r.f32();
            let material = scene_data::fetch_material(&k, m);
            let glass = glass_at(&k, material, m, hit, flip, 0.0);
            let opaque = glass_at(&k, material, m, hit, flip, 1.0 - 1e-7);
            // Where the two lobes differ, stay off the share that separates them.
            let share =
                (0..=1000).map(|j| j as f32 / 1000.0).find(|&x| glass_at(&k, material, m, hit, flip, x) != glass);
            let near = glass != opaque && share.is_some_and(|x| (lobe - x).abs() < 2e-3);
            (!near).then_some((material, m, hit, flip, lobe))
        })
        .collect();
    let out = assert_equivalent(
        &mut eq,
        "glass_at",
        &hits,
        |s, &(material, m, hit, flip, lobe)| (glass_at(s, material, m, hit, flip, lobe),),
        Tolerance::ulps(16).with_absolute(1e-6).flushing_subnormals(),
    );
    let dielectric = out.outputs[0].1.iter().filter(|(b,)| b.kind == tracer::kernel::bsdf::BSDF_DIELECTRIC).count();
    assert!(dielectric > hits.len() / 10, "only {dielectric} of {} points are glass", hits.len());
}
