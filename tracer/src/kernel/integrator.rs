#[kernel_dsl::kernel]
pub mod integrator {
    //! The path tracer: one path for every BSDF (`kernel::bsdf`), as pbrt-v4's and Mitsuba 3's.
    //! At each hit: emission found by the ray (MIS-weighted), a shading record ([`Shading`]),
    //! next event estimation over every light with MIS ([`sample_ld`]), one BSDF sample for the
    //! continuation, Russian roulette.
    use glam::{Vec2, Vec3, Vec4, Vec4Swizzles};

    use crate::kernel::bsdf::{
        bsdf_at, bsdf_eval, bsdf_normal, bsdf_pdf, bsdf_sample, glass_at, Bsdf, BSDF_DIELECTRIC, BSDF_METAL_ROUGH,
    };
    use crate::kernel::camera::camera_ray;
    use crate::kernel::dielectric::DELTA_PDF;
    use crate::kernel::instances::{instance_handedness, normal_to_world, world_triangle};
    use crate::kernel::intersect::MISS;
    use crate::kernel::lights::{
        area_pdf_to_solid_angle, finite_or_zero, light_pmf, luminance, power_heuristic, sample_light, sky_pdf,
        sky_texel_coords, sky_texel_radiance, triangle_emission,
    };
    use crate::kernel::metal_rough::metal_rough_albedo;
    use crate::kernel::normal_map::normal_mapped;
    use crate::kernel::rng::{pixel_jitter, pixel_seed, random_float, random_u32};
    use crate::kernel::sampling::{onb_from_normal, onb_to_local, onb_to_world, Onb};
    use crate::kernel::scene_data::{
        fetch_glass, fetch_material, shading_normal, Scene, TriangleData, NONE, STRATEGY_BSDF, STRATEGY_MIS,
        STRATEGY_NEE,
    };
    use crate::kernel::textures::base_color_at;
    use crate::kernel::traverse::{closest_candidate, occluded, Hit};
    use crate::kernel::traverse_masked::{before_any_hit, in_hole};

    /// Russian roulette starts after this many path segments.
    pub const RR_START_DEPTH: u32 = 3;
    /// Russian roulette keeps a path with probability max(throughput) up to this, never 1: a
    /// path whose throughput does not fall still ends.
    pub const RR_MAX_SURVIVAL: f32 = 0.95;
    /// Ray origins move off their surface by this times (the coordinates' magnitude plus the
    /// scene's scale): [`offset_origin`].
    pub const ORIGIN_OFFSET: f32 = 4.0e-6;
    /// A shadow ray towards a light at a finite distance stops at this fraction of it, short of
    /// the light's own surface.
    pub const SHADOW_RAY_SHORTENING: f32 = 1.0 - 1.0e-4;

    /// `p` moved off its surface along the facing geometric normal `n`, by an amount that
    /// scales with the coordinates' magnitude (floats lose absolute precision far from 0).
    pub fn offset_origin(scene: &Scene, p: Vec3, n: Vec3) -> Vec3 {
        let eps = (p.abs().max_element() + scene.scene_scale) * ORIGIN_OFFSET;
        p + n * eps
    }

    /// MIS weight of emission found by a BSDF-sampled ray with pdf `scatter_pdf` (0 for camera
    /// rays) when light sampling would have found it with `light_pdf`.
    pub fn hit_emission_weight(scene: &Scene, scatter_pdf: f32, light_pdf: f32) -> f32 {
        if scatter_pdf <= 0.0 || scene.strategy == STRATEGY_BSDF {
            1.0
        } else if scene.strategy == STRATEGY_NEE {
            0.0
        } else {
            power_heuristic(scatter_pdf, light_pdf)
        }
    }

    /// The normals at `hit` (of triangle `tri`, found along `dir`): `flip` 1 on the front face
    /// and -1 on the back, `ng` the unit geometric normal facing the ray's origin, `ns` the
    /// shading normal (interpolated where the scene has vertex normals, normal-mapped where it has
    /// normal maps) on `ng`'s side, `area2` twice the triangle's area. A degenerate triangle
    /// (`area2` not > 0) gets `-dir` for both normals.
    #[derive(Clone, Copy, Debug, PartialEq)]
    pub struct SurfaceNormals {
        pub ng: Vec3,
        pub ns: Vec3,
        pub flip: f32,
        pub area2: f32,
    }

    #[inline(always)]
    pub fn surface_normals(scene: &Scene, tri: TriangleData, hit: Hit, dir: Vec3) -> SurfaceNormals {
        let mut face = (tri.v1 - tri.v0).cross(tri.v2 - tri.v0);
        if scene.has_instances != 0 {
            // A mirroring instance reverses the winding of its triangles in world space.
            face *= instance_handedness(scene, hit.instance);
        }
        let area2 = face.length();
        let flip = if face.dot(dir) > 0.0 { -1.0 } else { 1.0 };
        let mut ng = -dir;
        if area2 > 0.0 {
            ng = face * (flip / area2);
        }
        let mut ns = ng;
        if scene.has_shading != 0 && area2 > 0.0 {
            let n = normal_to_world(scene, hit.instance, shading_normal(scene, hit.triangle, hit.u, hit.v)) * flip;
            let len = n.length();
            if len > 0.0 && n.dot(ng) > 0.0 {
                ns = n / len;
            }
        }
        if scene.has_normal_map != 0 && area2 > 0.0 {
            ns = normal_mapped(scene, hit, tri.material, ns, flip, ng, -dir);
        }
        SurfaceNormals { ng, ns, flip, area2 }
    }

    /// Distance the denoiser's guide gives a path that leaves to the sky: finite (sums of it
    /// stay finite), far beyond any surface.
    pub const SKY_DEPTH: f32 = 1.0e20;

    /// What the denoiser's guide reads from a path's first hit (`kernel::denoise`): its albedo
    /// (the base colour; a metal-roughness surface's directional albedo; 0 for the sky, which
    /// reflects nothing), shading normal (the reversed ray for the sky), distance (`SKY_DEPTH`
    /// for the sky) and the emission it sends to the camera (the sky's radiance for the sky).
    #[derive(Clone, Copy, Debug, PartialEq)]
    pub struct FirstHit {
        pub albedo: Vec3,
        pub normal: Vec3,
        pub depth: f32,
        pub emission: Vec3,
    }

    /// One sample and its share of the denoiser's guide, each field added to its own running
    /// sum by the entry point of a kernel built with `Features::denoise_guide`: `color` as
    /// [`render_sample`]'s; `albedo` the first hit's albedo and the luminance of the sample's
    /// reflected light (less the first hit's emission);
    /// `normal` its shading normal and distance; `emission` its emission towards the camera and
    /// that luminance squared (the two moments give the variance the filter scales with).
    #[derive(Clone, Copy, Debug, PartialEq)]
    pub struct GuidedSample {
        pub color: Vec4,
        pub albedo: Vec4,
        pub normal: Vec4,
        pub emission: Vec4,
    }

    /// One path sample through pixel (x, y): (radiance, 1), or zero when it was not finite.
    // Inlined into the CPU backend's row loop, which is also compiled for AVX2 (backend/cpu.rs).
    #[inline(always)]
    pub fn render_sample(scene: &Scene, x: u32, y: u32) -> Vec4 {
        let mut first = FirstHit { albedo: Vec3::ZERO, normal: Vec3::Z, depth: SKY_DEPTH, emission: Vec3::ZERO };
        trace_path(scene, x, y, &mut first)
    }

    /// [`render_sample`] with the path's first hit for the denoiser's guide.
    #[inline(always)]
    pub fn render_guided_sample(scene: &Scene, x: u32, y: u32) -> GuidedSample {
        let mut first = FirstHit { albedo: Vec3::ZERO, normal: Vec3::Z, depth: SKY_DEPTH, emission: Vec3::ZERO };
        let color = trace_path(scene, x, y, &mut first);
        // The moments of what the filter sees: the light reflected, without the emission (and
        // sky) the camera sees directly, which the filter leaves as it is. A pixel half sky,
        // half surface would otherwise count the sky's coverage as the surface's noise.
        let l = luminance(color.xyz() - first.emission);
        GuidedSample {
            color,
            albedo: first.albedo.extend(l),
            normal: first.normal.extend(first.depth),
            emission: first.emission.extend(l * l),
        }
    }

    /// One path sample through pixel (x, y), as [`render_sample`] returns it; where the scene
    /// asks for the denoiser's guide (`has_denoise_guide`), the path's first hit in `first`.
    /// The megakernel schedule: one invocation follows its path to the end, each segment's
    /// extension ray, shading and shadow ray in turn. The wavefront schedule (`kernel::wavefront`)
    /// runs the same three steps ([`trace_closest`](crate::kernel::traverse::trace_closest), [`shade_hit`], [`occluded`]) as stages
    /// over a pool of paths.
    ///
    /// With alpha masks, a segment's closest hit in a hole is passed through here: the path
    /// loop's next iteration searches again behind it (`traverse_masked::visible_hit`'s search,
    /// one candidate per iteration), with no loop of its own around traversal and no hole test
    /// on `trace_closest`'s path. SIMD drivers pay for that code's presence on every ray, holes
    /// or not (llvmpipe: LittlestTokyo's masks 1.18-1.22x per sample with it, a median 1.08x here).
    #[inline(always)]
    pub fn trace_path(scene: &Scene, x: u32, y: u32, first: &mut FirstHit) -> Vec4 {
        let mut path = start_path(scene, x, y, scene.frame_seed, scene.frame_index);
        // The hole the segment's ray last passed through, and how many it has.
        let mut behind = before_any_hit();
        let mut holes = 0u32;
        loop {
            // Without masks `behind` stays before any hit: `trace_closest`'s own search.
            let hit = closest_candidate(scene, path.origin, path.dir, MISS, behind, false);
            if scene.has_alpha_mask != 0 {
                if in_hole(scene, hit, holes) {
                    behind = hit;
                    holes += 1;
                    continue;
                }
                behind = before_any_hit();
                holes = 0;
            }
            let mut shadow = no_shadow_ray();
            let go_on = shade_hit(scene, &mut path, hit, first, &mut shadow);
            if shadow.t_max > 0.0 && !occluded(scene, shadow.origin, shadow.dir, shadow.t_max) {
                path.radiance += shadow.contribution;
            }
            if !go_on {
                break;
            }
        }
        finite_or_zero(path.radiance)
    }

    /// A path between two of its segments: the ray it continues along, what it carries
    /// (`throughput`) and has gathered (`radiance`), the pdf of the BSDF sample that chose `dir`
    /// (0 for the camera ray), the segments it has (`depth`) and its random stream.
    #[derive(Clone, Copy, Debug, PartialEq)]
    pub struct PathState {
        pub origin: Vec3,
        pub dir: Vec3,
        pub throughput: Vec3,
        pub radiance: Vec3,
        pub scatter_pdf: f32,
        pub depth: u32,
        pub rng: u32,
    }

    /// The shadow ray of a light sample: what it adds to the path's radiance (already
    /// multiplied by the throughput) unless something lies between `origin` and `origin + dir *
    /// t_max`. `t_max` 0: no shadow ray.
    #[derive(Clone, Copy, Debug, PartialEq)]
    pub struct ShadowRay {
        pub origin: Vec3,
        pub dir: Vec3,
        pub t_max: f32,
        pub contribution: Vec3,
    }

    /// No shadow ray (`t_max` 0).
    pub fn no_shadow_ray() -> ShadowRay {
        ShadowRay { origin: Vec3::ZERO, dir: Vec3::Z, t_max: 0.0, contribution: Vec3::ZERO }
    }

    /// The camera path through pixel (x, y) of the frame with `frame_seed` and `frame_index`
    /// (the scene's own for the megakernel; the wavefront's generate stage passes the frame it
    /// is filling).
    #[inline(always)]
    pub fn start_path(scene: &Scene, x: u32, y: u32, frame_seed: u32, frame_index: u32) -> PathState {
        let pixel = y * scene.width + x;
        let mut rng = pixel_seed(pixel, frame_seed);
        let film = Vec2::new(x as f32, y as f32) + pixel_jitter(pixel, frame_seed, frame_index);
        // The stream's first two numbers stay unused (they were the film position's): xorshift's
        // first outputs after seeding are correlated from frame to frame, and a path that used
        // them stopped converging (the furnace chart's NEE line plateaued at 16 spp).
        random_u32(&mut rng);
        random_u32(&mut rng);
        let lens = Vec2::new(random_float(&mut rng), random_float(&mut rng));
        let ray = camera_ray(scene, film, lens);
        PathState {
            origin: ray.origin,
            dir: ray.dir,
            throughput: Vec3::ONE,
            radiance: Vec3::ZERO,
            scatter_pdf: 0.0,
            depth: 0,
            rng,
        }
    }

    /// One segment's end: `hit` is what `path`'s ray found. Adds the emission it found
    /// (MIS-weighted), samples a light (the shadow ray in `shadow`, which the caller traces)
    /// and the BSDF, applies Russian roulette and moves `path` onto its next ray. Returns
    /// whether the path goes on. Where the scene asks for the denoiser's guide, the first
    /// segment fills `first`.
    #[inline(always)]
    pub fn shade_hit(
        scene: &Scene,
        path: &mut PathState,
        hit: Hit,
        first: &mut FirstHit,
        shadow: &mut ShadowRay,
    ) -> bool {
        let origin = path.origin;
        let dir = path.dir;
        let depth = path.depth;
        let scatter_pdf = path.scatter_pdf;
        if scene.has_denoise_guide != 0 && depth == 0 {
            first.normal = -dir;
            if hit.triangle != NONE {
                first.depth = hit.t;
            }
        }
        if hit.triangle == NONE {
            if scene.has_sky != 0 {
                // The texel is looked up once, for its pdf and its radiance.
                let texel = sky_texel_coords(scene, dir);
                let mut light_pdf = 0.0;
                if scene.strategy == STRATEGY_MIS && scatter_pdf > 0.0 {
                    light_pdf = sky_pdf(scene, dir, texel) * light_pmf(scene, scene.light_count - 1);
                }
                let sky = path.throughput
                    * sky_texel_radiance(scene, texel)
                    * hit_emission_weight(scene, scatter_pdf, light_pdf);
                path.radiance += sky;
                if scene.has_denoise_guide != 0 && depth == 0 {
                    // The sky the camera sees is its emission: not noise, kept out of the filter.
                    first.emission = sky;
                }
            }
            return false;
        }
        let tri = world_triangle(scene, hit.triangle, hit.instance);
        let p = origin + dir * hit.t;
        let normals = surface_normals(scene, tri, hit, dir);
        if !(normals.area2 > 0.0) {
            return false;
        }
        let flip = normals.flip;
        let ng = normals.ng;
        let ns = normals.ns;
        let area2 = normals.area2;
        let material = fetch_material(scene, tri.material);
        if scene.has_denoise_guide != 0 && depth == 0 {
            first.albedo = base_color_at(scene, material, hit.triangle, hit.u, hit.v);
            first.normal = ns;
        }
        if scene.has_volume != 0 && flip < 0.0 {
            // The segment that ends here, at a back face, ran inside this material's volume.
            path.throughput *= volume_transmittance(scene, tri.material, hit.t);
        }

        // Emission found by this ray (one-sided: only the front face emits).
        if material.emission.max_element() > 0.0 && flip > 0.0 {
            let mut light_pdf = 0.0;
            if scene.strategy == STRATEGY_MIS && scatter_pdf > 0.0 && tri.light != NONE {
                let cos_light = -ng.dot(dir);
                light_pdf = area_pdf_to_solid_angle(light_pmf(scene, tri.light), 0.5 * area2, hit.t, cos_light);
            }
            let e = triangle_emission(scene, hit.triangle, tri.material, hit.u, hit.v);
            path.radiance += path.throughput * e * hit_emission_weight(scene, scatter_pdf, light_pdf);
            if scene.has_denoise_guide != 0 && depth == 0 {
                first.emission = e;
            }
        }
        if depth + 1 >= scene.max_depth {
            return false;
        }

        // The shading record (built here: as a function's result it would be more words than
        // the equivalence harness reads back), then one light sample and one BSDF sample,
        // whatever the BSDF.
        // The stream in a local: naga's SPIR-V writer fails on a pointer to a field of a
        // pointer parameter (`&mut path.rng`), so it is written back before each return below.
        let mut rng = path.rng;
        let bsdf = if scene.has_transmission != 0 {
            glass_at(scene, material, tri.material, hit, flip, random_float(&mut rng))
        } else {
            bsdf_at(scene, material, tri.material, hit)
        };
        let frame = onb_from_normal(bsdf_normal(scene, bsdf, ns, ng, dir));
        let sh = Shading { p: offset_origin(scene, p, ng), ng, frame, wo: onb_to_local(frame, -dir), bsdf };
        if scene.has_denoise_guide != 0 && depth == 0 && scene.has_metal_rough != 0 && bsdf.kind == BSDF_METAL_ROUGH {
            // What the surface reflects of smooth light, specular included (not its base
            // colour alone): a glossy or dark surface then leaves the filter smooth
            // illumination too.
            first.albedo = metal_rough_albedo(bsdf.surface, sh.wo.z);
        }
        *shadow = sample_ld(scene, sh, &mut rng);
        shadow.contribution = path.throughput * shadow.contribution;
        let bs = bsdf_sample(scene, sh.bsdf, sh.wo, &mut rng);
        path.rng = rng;
        let next = onb_to_world(sh.frame, bs.dir);
        // No sample (a delta lobe's DELTA_PDF is one), or one on the wrong side of the geometric
        // surface (a reflection continues above it, a refraction below).
        if (if scene.has_transmission != 0 {
            !(bs.pdf > 0.0 || bs.pdf == DELTA_PDF) || !(ng.dot(next) * bs.dir.z > 0.0)
        } else {
            !(bs.pdf > 0.0) || ng.dot(next) <= 0.0
        }) {
            return false;
        }
        path.scatter_pdf = bs.pdf;
        path.throughput *= bs.weight;
        path.depth = depth + 1;
        if path.depth >= RR_START_DEPTH {
            let q = path.throughput.max_element().min(RR_MAX_SURVIVAL);
            let survive = random_float(&mut rng);
            path.rng = rng;
            if survive >= q {
                return false;
            }
            path.throughput /= q;
        }
        path.origin = sh.p;
        if scene.has_transmission != 0 && bs.dir.z < 0.0 {
            path.origin = offset_origin(scene, p, -ng);
        }
        path.dir = next;
        true
    }

    /// A surface point as the BSDF sees it: the origin of the rays leaving it (the hit moved off
    /// the surface), its facing geometric normal, the BSDF's local frame and the direction to
    /// the viewer in it, and the BSDF.
    #[derive(Clone, Copy, Debug, PartialEq)]
    pub struct Shading {
        pub p: Vec3,
        pub ng: Vec3,
        pub frame: Onb,
        pub wo: Vec3,
        pub bsdf: Bsdf,
    }

    /// Next event estimation at `sh`: one light sampled (three uniforms from `rng`, drawn
    /// whether or not the scene has lights), the BSDF evaluated towards it, MIS-weighted
    /// against BSDF sampling: the shadow ray and what it adds unless occluded (not yet
    /// multiplied by the path throughput), or [`no_shadow_ray`].
    #[inline(always)]
    pub fn sample_ld(scene: &Scene, sh: Shading, rng: &mut u32) -> ShadowRay {
        let u_light = Vec3::new(random_float(rng), random_float(rng), random_float(rng));
        let mut shadow = no_shadow_ray();
        if scene.has_lights != 0 && scene.light_count > 0 {
            let ls = sample_light(scene, sh.p, u_light);
            let wi = onb_to_local(sh.frame, ls.dir);
            if ls.pdf > 0.0
                // With glass: a rough dielectric sees light from both sides, a delta lobe none (it is
                // left to BSDF sampling), every other BSDF from above.
                && (if scene.has_transmission != 0 {
                    (sh.bsdf.kind != BSDF_DIELECTRIC && wi.z > 0.0)
                        || (sh.bsdf.kind == BSDF_DIELECTRIC && sh.bsdf.surface.alpha > 0.0 && wi.z != 0.0)
                } else {
                    wi.z > 0.0
                })
                && (if scene.has_transmission != 0 { sh.ng.dot(ls.dir) * wi.z > 0.0 } else { sh.ng.dot(ls.dir) > 0.0 })
                && (ls.delta || scene.strategy != STRATEGY_BSDF)
            {
                let mut weight = 1.0;
                if !ls.delta && scene.strategy == STRATEGY_MIS {
                    weight = power_heuristic(ls.pdf, bsdf_pdf(scene, sh.bsdf, sh.wo, wi));
                }
                // With glass, a light seen through a rough dielectric (below the surface): the
                // shadow ray leaves from `sh.p` moved back through the surface by twice its offset.
                shadow.origin = if scene.has_transmission != 0 && wi.z < 0.0 {
                    sh.p - sh.ng * (2.0 * (sh.p.abs().max_element() + scene.scene_scale) * ORIGIN_OFFSET)
                } else {
                    sh.p
                };
                shadow.dir = ls.dir;
                shadow.t_max = if ls.dist < MISS { ls.dist * SHADOW_RAY_SHORTENING } else { MISS };
                shadow.contribution = bsdf_eval(scene, sh.bsdf, sh.wo, wi)
                    * ((if scene.has_transmission != 0 { wi.z.abs() } else { wi.z }) * weight / ls.pdf)
                    * ls.radiance;
            }
        }
        shadow
    }

    /// Beer–Lambert transmittance `exp(−σa t)` of a segment of length `t` inside the volume of
    /// material `material` (`Features::volume`). One medium at a time: a ray leaving a volume
    /// is taken to be outside every volume (nested or overlapping volumes are not modelled).
    pub fn volume_transmittance(scene: &Scene, material: u32, t: f32) -> Vec3 {
        let sigma = fetch_glass(scene, material).sigma_a;
        Vec3::new((-sigma.x * t).exp(), (-sigma.y * t).exp(), (-sigma.z * t).exp())
    }
}
