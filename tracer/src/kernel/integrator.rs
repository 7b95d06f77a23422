#[kernel_dsl::kernel]
pub mod integrator {
    //! The path tracer: Lambert or metal-roughness BRDF, normal maps, NEE over every light, MIS, Russian roulette.
    use glam::{Vec2, Vec3, Vec4, Vec4Swizzles};

    use crate::kernel::camera::camera_ray;
    use crate::kernel::intersect::MISS;
    use crate::kernel::lights::{
        area_pdf_to_solid_angle, finite_or_zero, light_pmf, power_heuristic, sample_light, sky_pdf, sky_radiance,
        triangle_emission,
    };
    use crate::kernel::metal_rough::{metal_rough_eval, metal_rough_pdf, metal_rough_sample, surface_at};
    use crate::kernel::normal_map::normal_mapped;
    use crate::kernel::rng::{pixel_seed, random_float};
    use crate::kernel::sampling::{onb_from_normal, onb_to_local, onb_to_world, sample_cosine_around, INV_PI};
    use crate::kernel::scene_data::{
        fetch_material, fetch_triangle, sample_texture, shading_normal, MaterialData, Scene, NONE, STRATEGY_BSDF,
        STRATEGY_MIS, STRATEGY_NEE,
    };
    use crate::kernel::texture_ref::texture_uv;
    use crate::kernel::traverse::{occluded, trace_closest, Hit};

    /// Russian roulette starts after this many path segments.
    pub const RR_START_DEPTH: u32 = 3;

    /// `p` moved off its surface along the facing geometric normal `n`, by an amount that
    /// scales with the coordinates' magnitude (floats lose absolute precision far from 0).
    pub fn offset_origin(scene: &Scene, p: Vec3, n: Vec3) -> Vec3 {
        let eps = (p.abs().max_element() + scene.scene_scale) * 4.0e-6;
        p + n * eps
    }

    /// MIS weight of emission found by a BSDF-sampled ray with pdf `bsdf_pdf` (0 for camera
    /// rays) when light sampling would have found it with `light_pdf`.
    pub fn hit_emission_weight(scene: &Scene, bsdf_pdf: f32, light_pdf: f32) -> f32 {
        if bsdf_pdf <= 0.0 || scene.strategy == STRATEGY_BSDF {
            1.0
        } else if scene.strategy == STRATEGY_NEE {
            0.0
        } else {
            power_heuristic(bsdf_pdf, light_pdf)
        }
    }

    /// One path sample through pixel (x, y): (radiance, 1), or zero when it was not finite.
    // Inlined into the CPU backend's row loop, which is also compiled for AVX2 (backend/cpu.rs).
    #[inline(always)]
    pub fn render_sample(scene: &Scene, x: u32, y: u32) -> Vec4 {
        let mut rng = pixel_seed(y * scene.width + x, scene.frame_seed);
        let film = Vec2::new(x as f32 + random_float(&mut rng), y as f32 + random_float(&mut rng));
        let lens = Vec2::new(random_float(&mut rng), random_float(&mut rng));
        let ray = camera_ray(scene, film, lens);
        let mut origin = ray.origin;
        let mut dir = ray.dir;
        let mut throughput = Vec3::ONE;
        let mut radiance = Vec3::ZERO;
        let mut bsdf_pdf = 0.0f32;
        let mut depth = 0u32;
        loop {
            let hit = trace_closest(scene, origin, dir, MISS);
            if hit.triangle == NONE {
                if scene.has_sky != 0 {
                    let mut light_pdf = 0.0;
                    if scene.strategy == STRATEGY_MIS && bsdf_pdf > 0.0 {
                        light_pdf = sky_pdf(scene, dir) * light_pmf(scene, scene.light_count - 1);
                    }
                    radiance += throughput * sky_radiance(scene, dir) * hit_emission_weight(scene, bsdf_pdf, light_pdf);
                }
                break;
            }
            let tri = fetch_triangle(scene, hit.triangle);
            let p = origin + dir * hit.t;
            let face = (tri.v1 - tri.v0).cross(tri.v2 - tri.v0);
            let area2 = face.length();
            if !(area2 > 0.0) {
                break;
            }
            let flip = if face.dot(dir) > 0.0 { -1.0 } else { 1.0 };
            let ng = face * (flip / area2);
            let mut ns = ng;
            if scene.has_shading != 0 {
                let n = shading_normal(scene, hit.triangle, hit.u, hit.v) * flip;
                let len = n.length();
                if len > 0.0 && n.dot(ng) > 0.0 {
                    ns = n / len;
                }
            }
            if scene.has_normal_map != 0 {
                ns = normal_mapped(scene, hit, tri.material, ns, flip, ng, -dir);
            }
            let material = fetch_material(scene, tri.material);

            // Emission found by this ray (one-sided: only the front face emits).
            if material.emission.max_element() > 0.0 && flip > 0.0 {
                let mut light_pdf = 0.0;
                if scene.strategy == STRATEGY_MIS && bsdf_pdf > 0.0 && tri.light != NONE {
                    let cos_light = -ng.dot(dir);
                    light_pdf = area_pdf_to_solid_angle(light_pmf(scene, tri.light), 0.5 * area2, hit.t, cos_light);
                }
                let e = triangle_emission(scene, hit.triangle, tri.material, hit.u, hit.v);
                radiance += throughput * e * hit_emission_weight(scene, bsdf_pdf, light_pdf);
            }
            if depth + 1 >= scene.max_depth {
                break;
            }

            if scene.has_metal_rough == 0 {
                let mut albedo = material.base_color;
                if scene.has_textures != 0 && material.base_texture != NONE {
                    let uv = texture_uv(scene, material.base_texture, hit.triangle, hit.u, hit.v);
                    albedo *= sample_texture(scene, material.base_texture, uv).xyz();
                }
                let surface = offset_origin(scene, p, ng);

                // Next event estimation.
                let u_light = Vec3::new(random_float(&mut rng), random_float(&mut rng), random_float(&mut rng));
                if scene.has_lights != 0 && scene.light_count > 0 {
                    let ls = sample_light(scene, surface, u_light);
                    let cos = ns.dot(ls.dir);
                    if ls.pdf > 0.0
                        && cos > 0.0
                        && ng.dot(ls.dir) > 0.0
                        && (ls.delta || scene.strategy != STRATEGY_BSDF)
                    {
                        let mut weight = 1.0;
                        if !ls.delta && scene.strategy == STRATEGY_MIS {
                            weight = power_heuristic(ls.pdf, cos * INV_PI);
                        }
                        let t_max = if ls.dist < MISS { ls.dist * (1.0 - 1.0e-4) } else { MISS };
                        if !occluded(scene, surface, ls.dir, t_max) {
                            radiance += throughput * albedo * (INV_PI * cos * weight / ls.pdf) * ls.radiance;
                        }
                    }
                }

                // Continue the path by sampling the Lambert BSDF (cosine-weighted).
                let next = sample_cosine_around(ns, random_float(&mut rng), random_float(&mut rng));
                let cos = ns.dot(next);
                if !(cos > 0.0) || ng.dot(next) <= 0.0 {
                    break;
                }
                bsdf_pdf = cos * INV_PI;
                throughput *= albedo;
                depth += 1;
                if depth >= RR_START_DEPTH {
                    let q = throughput.max_element().min(0.95);
                    if random_float(&mut rng) >= q {
                        break;
                    }
                    throughput /= q;
                }
                origin = surface;
                dir = next;
            } else {
                // glTF metal-roughness (`Features::metal_rough`): both lobes, MIS over both.
                let here = offset_origin(scene, p, ng);
                let bounce = metal_rough_bounce(scene, &mut rng, hit, material, tri.material, here, dir, ng, ns);
                radiance += throughput * bounce.direct;
                if !(bounce.pdf > 0.0) {
                    break;
                }
                bsdf_pdf = bounce.pdf;
                throughput *= bounce.weight;
                depth += 1;
                if depth >= RR_START_DEPTH {
                    let survival = throughput.max_element().min(0.95);
                    if random_float(&mut rng) >= survival {
                        break;
                    }
                    throughput /= survival;
                }
                origin = here;
                dir = bounce.dir;
            }
        }
        finite_or_zero(radiance)
    }

    /// One bounce at a glTF metal-roughness surface: the light sampled there (next event
    /// estimation, MIS-weighted, not yet multiplied by the path throughput) and the BRDF-sampled
    /// continuation (`pdf` 0 ends the path).
    #[derive(Clone, Copy, Debug, PartialEq)]
    pub struct Bounce {
        pub direct: Vec3,
        pub dir: Vec3,
        pub pdf: f32,
        pub weight: Vec3,
    }

    /// Next event estimation and BRDF sampling at `surface` (the hit moved off the surface),
    /// reached along `dir`, with facing geometric normal `ng` and shading normal `ns`.
    #[allow(clippy::too_many_arguments)]
    pub fn metal_rough_bounce(
        scene: &Scene,
        rng: &mut u32,
        hit: Hit,
        material: MaterialData,
        material_index: u32,
        surface: Vec3,
        dir: Vec3,
        ng: Vec3,
        ns: Vec3,
    ) -> Bounce {
        let s = surface_at(scene, material, material_index, hit.triangle, hit.u, hit.v);
        // The BRDF needs the viewer above its normal: the shading normal while it is, else the
        // geometric one (which always faces the viewer).
        let n = if ns.dot(dir) < 0.0 { ns } else { ng };
        let frame = onb_from_normal(n);
        let wo = onb_to_local(frame, -dir);
        let mut direct = Vec3::ZERO;
        let u_light = Vec3::new(random_float(rng), random_float(rng), random_float(rng));
        if scene.has_lights != 0 && scene.light_count > 0 {
            let ls = sample_light(scene, surface, u_light);
            let wi = onb_to_local(frame, ls.dir);
            if ls.pdf > 0.0 && wi.z > 0.0 && ng.dot(ls.dir) > 0.0 && (ls.delta || scene.strategy != STRATEGY_BSDF) {
                let mut weight = 1.0;
                if !ls.delta && scene.strategy == STRATEGY_MIS {
                    weight = power_heuristic(ls.pdf, metal_rough_pdf(s, wo, wi));
                }
                let t_max = if ls.dist < MISS { ls.dist * (1.0 - 1.0e-4) } else { MISS };
                if !occluded(scene, surface, ls.dir, t_max) {
                    direct = metal_rough_eval(s, wo, wi) * (wi.z * weight / ls.pdf) * ls.radiance;
                }
            }
        }
        let u = Vec3::new(random_float(rng), random_float(rng), random_float(rng));
        let sample = metal_rough_sample(s, wo, u);
        let next = onb_to_world(frame, sample.dir);
        let pdf = if ng.dot(next) > 0.0 { sample.pdf } else { 0.0 };
        Bounce { direct, dir: next, pdf, weight: sample.weight }
    }
}
