//! The glTF metal-roughness BRDF (`tracer::kernel::metal_rough`) on the CPU: its sampling
//! routine against its own pdf (chi-square, as Mitsuba's `chi2` tests), the pdf's integral,
//! directional albedo by quadrature against the sampled estimate (white furnace), the sample
//! weight against the closed form F G2 / G1, reciprocity, stability at the extremes, and the
//! metal-roughness texture's channels as a glTF file maps them.

use crate::common;

use common::sphere_grid::{chi_square_p_value, Grid, P, T};
use common::{chi_square, chi_square_critical_1e6, mean_variance, TestRng};
use glam::{DVec3, Vec2, Vec3};
use tracer::kernel::metal_rough::{
    metal_rough_eval, metal_rough_pdf, metal_rough_sample, metal_rough_surface, surface_at, Surface, MIN_ROUGHNESS,
};

const ROUGHNESS: [f32; 4] = [0.0, 0.2, 0.5, 1.0];
const METALLIC: [f32; 3] = [0.0, 0.5, 1.0];
/// Incident angles from the normal, degrees: grazing included.
const THETA_O: [f32; 4] = [0.0, 45.0, 75.0, 88.0];
const BASE: Vec3 = Vec3::new(0.9, 0.6, 0.3);

fn wo_at(theta_degrees: f32) -> Vec3 {
    let t = theta_degrees.to_radians();
    // Off the x axis, so that no symmetry of the frame hides an error.
    Vec3::new(t.sin() * 0.8, t.sin() * 0.6, t.cos()).normalize()
}

fn surface(metallic: f32, roughness: f32) -> Surface {
    metal_rough_surface(BASE, metallic, roughness, 1.0)
}

/// Chi-square of `metal_rough_sample` against `metal_rough_pdf`: the cells of [`Grid`], plus
/// one cell for samples that fail (below the horizon), whose expected share is what the pdf's
/// integral leaves to 1. Cells expected to hold fewer than 5 samples are pooled.
#[test]
fn sampling_matches_its_pdf() {
    const N: usize = 40_000;
    let mut rng = TestRng::new(7);
    let mut min_p = 1.0f64;
    let mut lines = Vec::new();
    for &roughness in &ROUGHNESS {
        for &metallic in &METALLIC {
            for &theta in &THETA_O {
                let s = surface(metallic, roughness);
                let wo = wo_at(theta);
                let grid = Grid::new(wo);
                let pdf_cells = grid.integrate(|wi| metal_rough_pdf(s, wo, wi) as f64);
                let integral: f64 = pdf_cells.iter().sum();
                let what = format!("roughness {roughness} metallic {metallic} θo {theta}°");
                assert!(integral <= 1.0 + 2e-3, "{what}: the pdf integrates to {integral} > 1");
                let mut observed = vec![0u64; T * P + 1];
                for _ in 0..N {
                    let u = Vec3::new(rng.f32(), rng.f32(), rng.f32());
                    let sample = metal_rough_sample(s, wo, u);
                    if sample.pdf > 0.0 {
                        observed[grid.cell(sample.dir)] += 1;
                    } else {
                        observed[T * P] += 1;
                    }
                }
                let mut expected: Vec<f64> = pdf_cells.iter().map(|p| p * N as f64).collect();
                expected.push((1.0 - integral).max(0.0) * N as f64);
                let (mut obs, mut exp) = (Vec::new(), Vec::new());
                let (mut pooled_o, mut pooled_e) = (0u64, 0.0f64);
                for (o, e) in observed.iter().zip(&expected) {
                    if *e < 5.0 {
                        pooled_o += o;
                        pooled_e += e;
                    } else {
                        obs.push(*o);
                        exp.push(*e);
                    }
                }
                if pooled_e >= 5.0 {
                    obs.push(pooled_o);
                    exp.push(pooled_e);
                } else {
                    assert!(pooled_o <= 12, "{what}: {pooled_o} samples where the pdf expects {pooled_e:.2}");
                }
                let dof = obs.len().max(2) - 1;
                let chi2 = if obs.len() > 1 { chi_square(&obs, &exp) } else { 0.0 };
                let p = chi_square_p_value(chi2, dof);
                min_p = min_p.min(p);
                lines.push(format!("{what:<40} ∫pdf {integral:.4}  chi2 {chi2:7.1} ({dof:3} dof)  p {p:.3}"));
                assert!(
                    chi2 < chi_square_critical_1e6(dof),
                    "{what}: chi-square {chi2:.1} ({dof} dof, p = {p:.2e}); observed {obs:?}, expected {exp:?}"
                );
            }
        }
    }
    println!("{}", lines.join("\n"));
    println!("smallest p-value over {} configurations: {min_p:.4}", lines.len());
}

/// ∫ f(wo, wi) cos θi dωi by quadrature.
fn albedo_quadrature(s: Surface, wo: Vec3) -> f64 {
    Grid::new(wo).integrate(|wi| (metal_rough_eval(s, wo, wi) * wi.z.max(0.0)).as_dvec3().y).iter().sum()
}

/// White furnace: a white metal (F0 = 1) reflects at most what it receives, nearly all of it
/// when smooth, less the rougher it is; a white dielectric's diffuse part at most all of it, its
/// specular part at most the metal's. The
/// specification's single-scattering model loses energy at high roughness (69 % at roughness 1
/// and normal incidence, checked against the closed form): bounds are asserted, not equality.
/// The sampled estimate (mean weight) agrees with the quadrature.
#[test]
fn white_furnace_conserves_energy() {
    const N: usize = 20_000;
    let mut rng = TestRng::new(11);
    // Per incident angle (degrees as the index), the albedo of the previous (smoother) metal.
    let mut previous = [1.0 + 1e-3; 81];
    for (metallic, name) in [(1.0, "white metal"), (0.0, "white dielectric")] {
        for &roughness in &[0.0f32, 0.1, 0.3, 0.6, 1.0] {
            for &theta in &[0.0f32, 30.0, 60.0, 80.0] {
                let s = metal_rough_surface(Vec3::ONE, metallic, roughness, 1.0);
                let wo = wo_at(theta);
                let quadrature = albedo_quadrature(s, wo);
                let (mean, variance, n) = mean_variance((0..N).map(|_| {
                    let u = Vec3::new(rng.f32(), rng.f32(), rng.f32());
                    metal_rough_sample(s, wo, u).weight.y as f64
                }));
                let what = format!("{name} roughness {roughness} θo {theta}°");
                println!(
                    "{what:<36} albedo: quadrature {quadrature:.4}, sampled {mean:.4} ± {:.4}",
                    (variance / n as f64).sqrt()
                );
                if metallic == 1.0 {
                    assert!(quadrature <= 1.0 + 2e-3, "{what}: albedo {quadrature} > 1");
                } else {
                    // The specification's `fresnel_mix` weighs the diffuse lobe by 1 − F(V·H), not by
                    // what the specular lobe leaves: seen at an angle, a smooth white dielectric
                    // reflects more than it receives (1.35 at 80°). What holds: its diffuse part is
                    // at most 1, its specular part at most the white metal's (F ≤ 1).
                    let specular = albedo_quadrature(Surface { diffuse: Vec3::ZERO, ..s }, wo);
                    let metal = albedo_quadrature(metal_rough_surface(Vec3::ONE, 1.0, roughness, 1.0), wo);
                    let diffuse = quadrature - specular;
                    println!("{:<36} diffuse part {diffuse:.4}, specular part {specular:.4}", "");
                    assert!(diffuse <= 1.0 + 2e-3, "{what}: diffuse part {diffuse} > 1");
                    assert!(specular <= metal + 1e-4, "{what}: specular part {specular} > the white metal's {metal}");
                }
                // 5 standard errors, plus the quadrature's own error (~1e-4).
                let bound = 5.0 * (variance / n as f64).sqrt() + 1e-3;
                assert!((mean - quadrature).abs() <= bound, "{what}: sampled {mean} vs quadrature {quadrature}");
                if metallic == 1.0 && roughness <= 0.1 && theta <= 60.0 {
                    assert!(quadrature >= 0.985, "{what}: a smooth white metal must keep ~all energy: {quadrature}");
                }
                if metallic == 1.0 && roughness == 1.0 && theta == 0.0 {
                    // At α = 1, D = 1 / π and V = 1 / (2 (cos θi + cos θo)): at normal incidence
                    // E = ∫ μ / (1 + μ) dμ = 1 − ln 2 (single scattering loses 69 %).
                    let exact = 1.0 - std::f64::consts::LN_2;
                    assert!((quadrature - exact).abs() < 1e-3, "{what}: {quadrature}, 1 − ln 2 = {exact}");
                }
                if metallic == 1.0 {
                    assert!(quadrature <= previous[theta as usize] + 1e-4, "{what}: rougher metals reflect less");
                    previous[theta as usize] = quadrature;
                }
            }
        }
    }
}

/// Smith's Λ for GGX, written from its definition (Heitz 2014), in f64.
fn smith_lambda(alpha: f64, cos: f64) -> f64 {
    let tan2 = (1.0 - cos * cos).max(0.0) / (cos * cos);
    0.5 * ((1.0 + alpha * alpha * tan2).sqrt() - 1.0)
}

/// For a pure metal the specular lobe is always sampled and visible-normal sampling's weight
/// is F · G2(wo, wi) / G1(wo) (Heitz 2018, eq. 19), computed here independently.
#[test]
fn metal_sample_weight_is_fresnel_times_g2_over_g1() {
    let mut rng = TestRng::new(5);
    let mut worst = 0.0f64;
    for &roughness in &[MIN_ROUGHNESS, 0.2, 0.5, 1.0] {
        for &theta in &THETA_O {
            let s = surface(1.0, roughness);
            let wo = wo_at(theta);
            let alpha = (roughness as f64).powi(2);
            for _ in 0..2000 {
                let u = Vec3::new(rng.f32(), rng.f32(), rng.f32());
                let sample = metal_rough_sample(s, wo, u);
                if sample.pdf <= 0.0 {
                    continue;
                }
                let (wo64, wi64) = (wo.as_dvec3(), sample.dir.as_dvec3());
                let h = (wo64 + wi64).normalize();
                let c = 1.0 - wo64.dot(h);
                let f = BASE.as_dvec3() + (DVec3::ONE - BASE.as_dvec3()) * c.powi(5);
                let g2 = 1.0 / (1.0 + smith_lambda(alpha, wo64.z) + smith_lambda(alpha, wi64.z));
                let g1 = 1.0 / (1.0 + smith_lambda(alpha, wo64.z));
                let expected = f * (g2 / g1);
                let got = sample.weight.as_dvec3();
                let error = ((got - expected).abs() / expected.max(DVec3::splat(1e-3))).max_element();
                worst = worst.max(error);
                assert!(error < 2e-3, "roughness {roughness} θo {theta}°: weight {got} vs F G2 / G1 = {expected}");
            }
        }
    }
    println!("largest relative error of the metal weight against F G2 / G1: {worst:.2e}");
}

/// f(wo, wi) = f(wi, wo), and the pdf is the density `metal_rough_sample` reports.
#[test]
fn brdf_is_reciprocal_and_sample_pdfs_are_the_pdf() {
    let mut rng = TestRng::new(3);
    let upper = |rng: &mut TestRng| {
        let v = rng.unit_vector();
        Vec3::new(v.x, v.y, v.z.abs().max(1e-3)).normalize()
    };
    for i in 0..20_000 {
        let s = metal_rough_surface(
            Vec3::new(rng.f32(), rng.f32(), rng.f32()),
            rng.f32(),
            if i % 7 == 0 { 0.0 } else { rng.f32() },
            1.0,
        );
        let (a, b) = (upper(&mut rng), upper(&mut rng));
        let (ab, ba) = (metal_rough_eval(s, a, b), metal_rough_eval(s, b, a));
        let scale = ab.max(ba).max_element().max(1e-6);
        assert!((ab - ba).abs().max_element() <= 1e-4 * scale, "{s:?}: f({a}, {b}) = {ab} but f({b}, {a}) = {ba}");
        let sample = metal_rough_sample(s, a, Vec3::new(rng.f32(), rng.f32(), rng.f32()));
        if sample.pdf > 0.0 {
            let pdf = metal_rough_pdf(s, a, sample.dir);
            assert!((sample.pdf - pdf).abs() <= 1e-5 * pdf, "{s:?}: sample pdf {} vs pdf {pdf}", sample.pdf);
            let value = metal_rough_eval(s, a, sample.dir) * (sample.dir.z / pdf);
            let scale = value.max_element().max(1e-6);
            assert!((sample.weight - value).abs().max_element() <= 1e-5 * scale, "{s:?}: weight vs f cos / pdf");
        }
    }
}

/// No NaN, infinity or negative value at grazing angles, at the roughness clamp (and below
/// it), at roughness 1, for the extreme uniforms and for black, white and metal surfaces.
#[test]
fn stable_at_grazing_angles_and_the_roughness_clamp() {
    let top = 1.0 - f32::EPSILON / 2.0;
    let cosines = [1.0, 0.5, 1e-2, 1e-4, 1e-6, 1e-9, f32::MIN_POSITIVE];
    let mut checked = 0;
    for &roughness in &[0.0f32, 1e-6, MIN_ROUGHNESS, 0.05, 0.5, 1.0] {
        for &metallic in &[0.0f32, 0.5, 1.0] {
            for base in [Vec3::ZERO, Vec3::ONE, BASE] {
                let s = metal_rough_surface(base, metallic, roughness, 1.0);
                for &c in &cosines {
                    let wo = Vec3::new((1.0 - c * c).sqrt(), 0.0, c).normalize();
                    for u in [0.0, 0.5, top] {
                        for v in [0.0, 0.5, top] {
                            for lobe in [0.0, top] {
                                let sample = metal_rough_sample(s, wo, Vec3::new(u, v, lobe));
                                let ok = sample.pdf.is_finite()
                                    && sample.pdf >= 0.0
                                    && sample.weight.is_finite()
                                    && sample.weight.min_element() >= 0.0
                                    && sample.dir.is_finite();
                                assert!(ok, "{s:?} wo {wo} u ({u}, {v}, {lobe}): {sample:?}");
                                for &c2 in &cosines {
                                    let wi = Vec3::new(-(1.0 - c2 * c2).sqrt(), 0.0, c2).normalize();
                                    let f = metal_rough_eval(s, wo, wi);
                                    let pdf = metal_rough_pdf(s, wo, wi);
                                    assert!(f.is_finite() && f.min_element() >= 0.0, "{s:?} f({wo}, {wi}) = {f}");
                                    assert!(pdf.is_finite() && pdf >= 0.0, "{s:?} pdf({wo}, {wi}) = {pdf}");
                                    checked += 1;
                                }
                            }
                        }
                    }
                }
            }
        }
    }
    println!("{checked} evaluations finite and non-negative");
}

/// A glTF whose `metallicRoughnessTexture` has a texel with green 255, blue 0 (rough
/// dielectric) and one with green 128, blue 255 (half-rough metal): the kernel reads roughness
/// from green and metallic from blue, as linear data.
#[test]
fn metal_roughness_texture_channels_follow_gltf() {
    use tracer::kernel::scene_data::fetch_material;
    let dir = std::env::temp_dir().join(format!("lightport-mr-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    // 2 x 1 texels, (R, G, B, A): (0, 255, 0, 255), then (0, 128, 255, 255): 128 tells linear
    // (0.502) from sRGB (0.216) decoding.
    let mut png = Vec::new();
    let texels = [0u8, 255, 0, 255, 0, 128, 255, 255];
    image::ImageEncoder::write_image(
        image::codecs::png::PngEncoder::new(&mut png),
        &texels,
        2,
        1,
        image::ExtendedColorType::Rgba8,
    )
    .unwrap();
    std::fs::write(dir.join("mr.png"), png).unwrap();
    // One quad, u from 0 to 1 across x.
    let positions: [[f32; 3]; 4] = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 1.0, 0.0], [0.0, 1.0, 0.0]];
    let uvs: [[f32; 2]; 4] = [[0.0, 0.5], [1.0, 0.5], [1.0, 0.5], [0.0, 0.5]];
    let indices: [u16; 6] = [0, 1, 2, 0, 2, 3];
    let mut bin = Vec::new();
    positions.iter().flatten().for_each(|f| bin.extend(f.to_le_bytes()));
    uvs.iter().flatten().for_each(|f| bin.extend(f.to_le_bytes()));
    indices.iter().for_each(|i| bin.extend(i.to_le_bytes()));
    std::fs::write(dir.join("quad.bin"), &bin).unwrap();
    let gltf = r#"{
      "asset": {"version": "2.0"},
      "scene": 0, "scenes": [{"nodes": [0]}], "nodes": [{"mesh": 0}],
      "meshes": [{"primitives": [{"attributes": {"POSITION": 0, "TEXCOORD_0": 1}, "indices": 2, "material": 0}]}],
      "materials": [{"pbrMetallicRoughness": {"baseColorFactor": [0.8, 0.8, 0.8, 1],
          "metallicFactor": 1.0, "roughnessFactor": 1.0, "metallicRoughnessTexture": {"index": 0}}}],
      "textures": [{"source": 0, "sampler": 0}],
      "samplers": [{"wrapS": 33071, "wrapT": 33071}],
      "images": [{"uri": "mr.png"}],
      "buffers": [{"uri": "quad.bin", "byteLength": 92}],
      "bufferViews": [{"buffer": 0, "byteOffset": 0, "byteLength": 48},
                      {"buffer": 0, "byteOffset": 48, "byteLength": 32},
                      {"buffer": 0, "byteOffset": 80, "byteLength": 12}],
      "accessors": [
        {"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3", "min": [0, 0, 0], "max": [1, 1, 0]},
        {"bufferView": 1, "componentType": 5126, "count": 4, "type": "VEC2"},
        {"bufferView": 2, "componentType": 5123, "count": 6, "type": "SCALAR"}]
    }"#;
    std::fs::write(dir.join("quad.gltf"), gltf).unwrap();
    let mut scene = tracer::scene::load(&dir.join("quad.gltf")).expect("the quad loads");
    std::fs::remove_dir_all(&dir).ok();
    assert!(scene.warnings.is_empty(), "{:?}", scene.warnings);
    let material = &scene.materials[0];
    assert_eq!((material.metallic, material.roughness), (1.0, 1.0));
    assert!(material.metallic_roughness_texture.is_some(), "the metal-roughness texture is loaded");
    scene.sky = Some(tracer::scene::Sky::uniform(Vec3::ONE));
    let packed = common::agreement::packed(&scene, tracer::kernel::Strategy::Mis, 4, 4);
    assert!(packed.features.metal_rough && packed.features.textures, "{:?}", packed.features);
    let k = &packed.scene;
    // Barycentrics of texture coordinate u = `x` on packed triangle 0 (both have v = 0.5).
    let at = |x: f32| {
        let uv = |b: Vec2| tracer::kernel::scene_data::texcoord(k, 0, b.x, b.y).x;
        let (u0, u1, u2) = (uv(Vec2::ZERO), uv(Vec2::X), uv(Vec2::Y));
        // Along the edge from the vertex with the smallest u to the one with the largest.
        let corners = [(u0, Vec2::ZERO), (u1, Vec2::X), (u2, Vec2::Y)];
        let lo = corners.iter().min_by(|a, b| a.0.total_cmp(&b.0)).unwrap();
        let hi = corners.iter().max_by(|a, b| a.0.total_cmp(&b.0)).unwrap();
        let b = lo.1.lerp(hi.1, (x - lo.0) / (hi.0 - lo.0));
        let tri = tracer::kernel::scene_data::fetch_triangle(k, 0);
        surface_at(k, fetch_material(k, tri.material), tri.material, 0, b.x, b.y)
    };
    // Texel centres: u = 0.25 (green 255, blue 0) and u = 0.75 (green 128, blue 255).
    let rough_dielectric = at(0.25);
    let metal = at(0.75);
    let base = Vec3::splat(0.8);
    // Blue 0 → metallic 0: f0 = 0.04, c_diff = base. Green 1 → roughness 1.
    assert!((rough_dielectric.f0 - Vec3::splat(0.04)).abs().max_element() < 1e-6, "{rough_dielectric:?}");
    assert!((rough_dielectric.diffuse - base).abs().max_element() < 1e-6, "{rough_dielectric:?}");
    assert!((rough_dielectric.alpha - 1.0).abs() < 1e-6, "{rough_dielectric:?}");
    // Blue 1 → metal: f0 = base, no diffuse. Green 128 → roughness 128 / 255 (linear).
    assert!((metal.f0 - base).abs().max_element() < 1e-6, "{metal:?}");
    assert!(metal.diffuse.max_element() < 1e-6, "{metal:?}");
    let roughness = 128.0f32 / 255.0;
    assert!((metal.alpha - roughness * roughness).abs() < 1e-5, "{metal:?}");
}

/// The integrator's BSDF interface (`kernel::bsdf`) over both kinds: each sample's pdf is
/// `bsdf_pdf` and its weight `bsdf_eval · cos / pdf`; Lambert is the albedo over π with the
/// cosine pdf; a scene without `Features::metal_rough` gets Lambert whatever the material, and
/// each kind draws the uniforms it always drew (Lambert two, metal-roughness three), so the
/// Cornell box's random sequence is the one it had before the interface.
#[test]
fn bsdf_interface_dispatches_on_the_kind_and_agrees_with_itself() {
    use tracer::kernel::bsdf::{bsdf_eval, bsdf_pdf, bsdf_sample, Bsdf, BSDF_LAMBERT, BSDF_METAL_ROUGH};
    use tracer::kernel::rng::random_float;
    let lambert_scene = common::agreement::packed(&tracer::scene::cornell_box(), tracer::kernel::Strategy::Mis, 4, 4);
    let mr_scene =
        common::agreement::packed(&tracer::scene::metal_rough_spheres(), tracer::kernel::Strategy::Mis, 4, 4);
    assert!(!lambert_scene.features.metal_rough && mr_scene.features.metal_rough);
    let albedo = Vec3::new(0.7, 0.5, 0.2);
    let lambert =
        Bsdf { kind: BSDF_LAMBERT, surface: Surface { diffuse: albedo, f0: Vec3::ZERO, alpha: 1.0, specular: 0.0 } };
    let cases = [
        (&lambert_scene.scene, lambert, 2),
        // A metal-roughness BSDF in a scene without the feature is Lambert over its diffuse albedo.
        (&lambert_scene.scene, Bsdf { kind: BSDF_METAL_ROUGH, surface: surface(0.0, 0.5) }, 2),
        (&mr_scene.scene, Bsdf { kind: BSDF_METAL_ROUGH, surface: surface(0.0, 0.5) }, 3),
        (&mr_scene.scene, Bsdf { kind: BSDF_METAL_ROUGH, surface: surface(1.0, 0.2) }, 3),
    ];
    let mut rng = TestRng::new(27);
    for (i, &(scene, b, draws)) in cases.iter().enumerate() {
        let lambert_here = scene.has_metal_rough == 0;
        for theta in THETA_O {
            let wo = wo_at(theta);
            for _ in 0..2000 {
                let seed = rng.next_u64() as u32 | 1;
                let (mut state, mut reference) = (seed, seed);
                let s = bsdf_sample(scene, b, wo, &mut state);
                for _ in 0..draws {
                    random_float(&mut reference);
                }
                assert_eq!(state, reference, "case {i}: {draws} uniforms drawn");
                if s.pdf <= 0.0 || s.pdf.is_nan() {
                    assert!(!lambert_here, "case {i}: Lambert always samples ({s:?})");
                    continue;
                }
                let pdf = bsdf_pdf(scene, b, wo, s.dir);
                assert!((pdf - s.pdf).abs() <= 1e-4 * pdf, "case {i}: pdf {pdf} vs {s:?}");
                let f = bsdf_eval(scene, b, wo, s.dir);
                let weight = f * (s.dir.z / s.pdf);
                assert!((weight - s.weight).abs().max_element() <= 1e-4 * weight.max_element().max(1.0), "case {i}");
                if lambert_here {
                    assert!((f - b.surface.diffuse / std::f32::consts::PI).abs().max_element() < 1e-6, "case {i}");
                    assert!((s.pdf - s.dir.z / std::f32::consts::PI).abs() < 1e-6, "case {i}");
                    assert_eq!(s.weight, b.surface.diffuse, "case {i}");
                }
            }
        }
    }
    // Below the surface: no reflection.
    let below = Vec3::new(0.3, 0.0, -0.9).normalize();
    assert_eq!(bsdf_eval(&lambert_scene.scene, lambert, wo_at(30.0), below), Vec3::ZERO);
    assert_eq!(bsdf_pdf(&lambert_scene.scene, lambert, wo_at(30.0), below), 0.0);
}
