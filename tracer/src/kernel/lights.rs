#[kernel_dsl::kernel]
pub mod lights {
    //! Light sampling for next event estimation: one alias table over every emitter, chosen by power.

    use glam::{Vec2, Vec3, Vec4, Vec4Swizzles};

    use crate::kernel::alpha_mask::is_hole;
    use crate::kernel::intersect::MISS;
    use crate::kernel::sampling::{uniform_sample_triangle, INV_PI, PI};
    use crate::kernel::scene_data::{
        fetch_material, fetch_triangle, index_of, Scene, LIGHT_POINT, LIGHT_SKY, LIGHT_TEXELS, LIGHT_TRIANGLE, NONE,
    };
    use crate::kernel::texture_ref::texture_uv;
    use crate::kernel::textures::sample_texture;

    /// A sampled light direction as seen from a shading point.
    #[derive(Clone, Copy, Debug, PartialEq)]
    pub struct LightSample {
        /// Unit direction towards the light.
        pub dir: Vec3,
        /// Distance to the light sample (MISS for the sky).
        pub dist: f32,
        /// Emitted radiance (area lights, sky) or intensity / dist² (point lights).
        pub radiance: Vec3,
        /// Solid-angle pdf including the light selection (0 for an invalid sample).
        pub pdf: f32,
        /// Point lights cannot be hit by BSDF sampling: no MIS for them.
        pub delta: bool,
    }

    pub fn luminance(c: Vec3) -> f32 {
        c.dot(Vec3::new(0.2126, 0.7152, 0.0722))
    }

    /// Picks a light index from a uniform in [0, 1) with the alias table.
    pub fn choose_light(scene: &Scene, u: f32) -> u32 {
        let n = scene.light_count;
        let scaled = u * n as f32;
        let i = (scaled as u32).min(n - 1);
        let entry = scene.lights.fetch(i * LIGHT_TEXELS);
        if scaled - (i as f32) < entry.x {
            i
        } else {
            index_of(entry.y)
        }
    }

    /// Probability of choosing light `index`.
    pub fn light_pmf(scene: &Scene, index: u32) -> f32 {
        scene.lights.fetch(index * LIGHT_TEXELS).z
    }

    /// Emitted radiance of a triangle's material at barycentrics (u, v).
    // Inlined into the CPU backend's row loop, which is also compiled for AVX2 (backend/cpu.rs).
    #[inline(always)]
    pub fn triangle_emission(scene: &Scene, triangle: u32, material: u32, u: f32, v: f32) -> Vec3 {
        let m = fetch_material(scene, material);
        let mut e = m.emission;
        if scene.has_textures != 0 && m.emissive_texture != NONE {
            e *= sample_texture(scene, m.emissive_texture, texture_uv(scene, m.emissive_texture, triangle, u, v)).xyz();
        }
        e
    }

    /// Solid-angle pdf of sampling a point at distance `dist` on a triangle of `area` whose
    /// front faces the shading point under `cos_light`, including its selection probability.
    /// Emission is one-sided (glTF's counter-clockwise front face): zero from behind.
    pub fn area_pdf_to_solid_angle(pmf: f32, area: f32, dist: f32, cos_light: f32) -> f32 {
        if !(cos_light > 0.0) || !(area > 0.0) {
            0.0
        } else {
            pmf * dist * dist / (area * cos_light)
        }
    }

    /// The sky's direction for texture coordinates (u, v) (see `tracer::scene::Sky`).
    pub fn sky_direction(scene: &Scene, uv: Vec2) -> Vec3 {
        let phi = (uv.x - 0.5) * 2.0 * PI + scene.sky_rotation;
        let theta = uv.y * PI;
        let s = theta.sin();
        Vec3::new(s * phi.sin(), theta.cos(), -s * phi.cos())
    }

    /// Texel (column, row) of the sky seen along unit `dir`.
    pub fn sky_texel_coords(scene: &Scene, dir: Vec3) -> Vec2 {
        let phi = dir.x.atan2(-dir.z) - scene.sky_rotation;
        let u = phi * (0.5 * INV_PI) + 0.5;
        let u = u - u.floor();
        let v = dir.y.clamp(-1.0, 1.0).acos() * INV_PI;
        let w = scene.sky_width as f32;
        let h = scene.sky_height as f32;
        Vec2::new((u * w).floor().min(w - 1.0), (v * h).floor().min(h - 1.0))
    }

    /// Radiance of the sky texel `c` (column, row: `sky_texel_coords`).
    pub fn sky_texel_radiance(scene: &Scene, c: Vec2) -> Vec3 {
        let i = c.y as u32 * scene.sky_width + c.x as u32;
        scene.sky.fetch(i).xyz() * scene.sky_intensity
    }

    /// Probability of sky texel (col, row) under the sky's CDFs.
    pub fn sky_texel_pmf(scene: &Scene, col: u32, row: u32) -> f32 {
        let row_hi = scene.sky_rows.fetch(row).x;
        let row_lo = if row > 0 { scene.sky_rows.fetch(row - 1).x } else { 0.0 };
        let base = row * scene.sky_width;
        let col_hi = scene.sky.fetch(base + col).w;
        let col_lo = if col > 0 { scene.sky.fetch(base + col - 1).w } else { 0.0 };
        (row_hi - row_lo) * (col_hi - col_lo)
    }

    /// Solid-angle pdf of sampling unit `dir` from the sky (without the light selection); `c`
    /// is its texel, `sky_texel_coords(scene, dir)`, whose radiance the caller also reads.
    pub fn sky_pdf(scene: &Scene, dir: Vec3, c: Vec2) -> f32 {
        let pmf = sky_texel_pmf(scene, c.x as u32, c.y as u32);
        sky_texel_pdf(scene, pmf, (1.0 - dir.y * dir.y).max(0.0).sqrt())
    }

    /// Solid-angle pdf of a direction at `sin_theta` in a sky texel of probability `pmf`
    /// (uniform within the texel in (u, v); the map's Jacobian, 2π² sin θ per unit of u and v).
    pub fn sky_texel_pdf(scene: &Scene, pmf: f32, sin_theta: f32) -> f32 {
        if !(sin_theta > 0.0) {
            0.0
        } else {
            pmf * (scene.sky_width * scene.sky_height) as f32 / (2.0 * PI * PI * sin_theta)
        }
    }

    /// The bucket of a guide table of `buckets` (a power of two: `u * buckets` is exact) that
    /// the uniform `u` in [0, 1) falls in.
    pub fn guide_bucket(u: f32, buckets: u32) -> u32 {
        ((u * buckets as f32) as u32).min(buckets - 1)
    }

    /// The row of the sky sampled by the uniform `u`: the first whose marginal CDF value exceeds
    /// `u` (the last if none does), by binary search between the row guide's bucket of `u` and
    /// the next (`tracer::pack::sky`: the same row as a search over every row).
    pub fn search_sky_row(scene: &Scene, u: f32) -> u32 {
        let buckets = (scene.sky_rows.fetch(0).z as u32).max(1);
        let k = guide_bucket(u, buckets);
        let mut lo = index_of(scene.sky_rows.fetch(k).y);
        let mut hi = scene.sky_height - 1;
        if k + 1 < buckets {
            hi = index_of(scene.sky_rows.fetch(k + 1).y);
        }
        while lo < hi {
            let mid = (lo + hi) / 2;
            if scene.sky_rows.fetch(mid).x > u {
                hi = mid;
            } else {
                lo = mid + 1;
            }
        }
        lo
    }

    /// Entry `i` of the column guides (`row * buckets + k`), four to a texel after the rows.
    pub fn sky_column_guide(scene: &Scene, i: u32) -> u32 {
        let t = scene.sky_rows.fetch(scene.sky_height + i / 4);
        let c = i % 4;
        let mut g = t.x;
        if c == 1 {
            g = t.y;
        } else if c == 2 {
            g = t.z;
        } else if c == 3 {
            g = t.w;
        }
        index_of(g)
    }

    /// The column of `row` sampled by the uniform `u`: the first whose CDF value within the row
    /// exceeds `u`, searched between the row's guide bucket of `u` and the next.
    pub fn search_sky_column(scene: &Scene, row: u32, u: f32) -> u32 {
        let base = row * scene.sky_width;
        let buckets = (scene.sky_rows.fetch(0).w as u32).max(1);
        let k = guide_bucket(u, buckets);
        let mut lo = sky_column_guide(scene, row * buckets + k);
        let mut hi = scene.sky_width - 1;
        if k + 1 < buckets {
            hi = sky_column_guide(scene, row * buckets + k + 1);
        }
        while lo < hi {
            let mid = (lo + hi) / 2;
            if scene.sky.fetch(base + mid).w > u {
                hi = mid;
            } else {
                lo = mid + 1;
            }
        }
        lo
    }

    /// Samples one light for the shading point `p`. `u` are three uniforms in [0, 1).
    // Inlined into the CPU backend's row loop, which is also compiled for AVX2 (backend/cpu.rs).
    #[inline(always)]
    pub fn sample_light(scene: &Scene, p: Vec3, u: Vec3) -> LightSample {
        let none = LightSample { dir: Vec3::Y, dist: 0.0, radiance: Vec3::ZERO, pdf: 0.0, delta: false };
        let index = choose_light(scene, u.x);
        let head = scene.lights.fetch(index * LIGHT_TEXELS);
        let data = scene.lights.fetch(index * LIGHT_TEXELS + 1);
        let kind = index_of(head.w);
        let pmf = head.z;
        if kind == LIGHT_TRIANGLE && scene.has_triangle_lights != 0 {
            let tri_index = index_of(data.x);
            let tri = fetch_triangle(scene, tri_index);
            let b = uniform_sample_triangle(u.y, u.z);
            let q = tri.v0 * (1.0 - b.x - b.y) + tri.v1 * b.x + tri.v2 * b.y;
            let to_light = q - p;
            let dist2 = to_light.dot(to_light);
            if !(dist2 > 0.0) {
                return none;
            }
            let dist = dist2.sqrt();
            let dir = to_light / dist;
            let normal = Vec3::new(data.y, data.z, data.w);
            let area = scene.lights.fetch(index * LIGHT_TEXELS + 2).x;
            let pdf = area_pdf_to_solid_angle(pmf, area, dist, -normal.dot(dir));
            if scene.has_alpha_mask != 0 && tri.masked && is_hole(scene, tri_index, tri.material, b.x, b.y) {
                return none; // a hole of an alpha-masked emitter emits nothing (BSDF rays pass through)
            } else if !(pdf > 0.0) {
                return none;
            }
            let radiance = triangle_emission(scene, tri_index, tri.material, b.x, b.y);
            LightSample { dir, dist, radiance, pdf, delta: false }
        } else if kind == LIGHT_POINT && scene.has_point_lights != 0 {
            let intensity = scene.lights.fetch(index * LIGHT_TEXELS + 2).xyz();
            let to_light = data.xyz() - p;
            let dist2 = to_light.dot(to_light);
            if !(dist2 > 0.0) {
                return none;
            }
            let dist = dist2.sqrt();
            LightSample { dir: to_light / dist, dist, radiance: intensity / dist2, pdf: pmf, delta: true }
        } else if kind == LIGHT_SKY && scene.has_sky != 0 {
            let row = search_sky_row(scene, u.y);
            let col = search_sky_column(scene, row, u.z);
            let base = row * scene.sky_width; // uniform within the chosen texel, from what is left of u.y, u.z
            let lo = if col > 0 { scene.sky.fetch(base + col - 1).w } else { 0.0 };
            let texel = scene.sky.fetch(base + col);
            let hi = texel.w;
            let fu = if hi > lo { ((u.z - lo) / (hi - lo)).clamp(0.0, 0.999999) } else { 0.5 };
            let row_lo = if row > 0 { scene.sky_rows.fetch(row - 1).x } else { 0.0 };
            let row_hi = scene.sky_rows.fetch(row).x;
            let fv = if row_hi > row_lo { ((u.y - row_lo) / (row_hi - row_lo)).clamp(0.0, 0.999999) } else { 0.5 };
            let uv = Vec2::new((col as f32 + fu) / scene.sky_width as f32, (row as f32 + fv) / scene.sky_height as f32);
            let dir = sky_direction(scene, uv);
            // The chosen texel's probability and radiance, as fetched for the search, rather
            // than the texel looked up again from `dir` (`sky_texel_coords`: an atan2 and an
            // acos; the Cornell box under a sky took 0.84x the CPU time per sample on the CPU
            // backend without them, 0.97x on llvmpipe, whose compiler had merged some): the same
            // texel, but where `dir` rounds across a texel's edge.
            let pdf = sky_texel_pdf(scene, (row_hi - row_lo) * (hi - lo), (uv.y * PI).sin()) * pmf;
            if !(pdf > 0.0) {
                return none;
            }
            LightSample { dir, dist: MISS, radiance: texel.xyz() * scene.sky_intensity, pdf, delta: false }
        } else {
            none
        }
    }
    /// The power heuristic (β = 2) weight of a strategy with pdf `a` against one with pdf `b`.
    pub fn power_heuristic(a: f32, b: f32) -> f32 {
        let a2 = a * a;
        let b2 = b * b;
        if a2 + b2 > 0.0 {
            a2 / (a2 + b2)
        } else {
            0.0
        }
    }

    /// Makes a radiance sample safe to accumulate: (rgb, 1) when finite, else (0, 0, 0, 0) so
    /// that the host can count rejected samples.
    pub fn finite_or_zero(c: Vec3) -> Vec4 {
        if c.x.is_finite() && c.y.is_finite() && c.z.is_finite() {
            c.extend(1.0)
        } else {
            Vec4::ZERO
        }
    }
}
