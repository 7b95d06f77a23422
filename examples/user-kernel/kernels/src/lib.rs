//! A user's own kernels: the crate a build script depends on to generate their shaders (a build
//! script cannot depend on the crate it builds, so the kernels live here, beside the app).

/// Escape-time colouring of a Julia set: one pixel per invocation, no scene data.
#[kernel_dsl::kernel]
pub mod julia {
    use glam::{Vec2, Vec3, Vec4};

    /// Iterations before a point counts as inside the set.
    pub const MAX_ITERATIONS: u32 = 96;
    /// |z|² beyond which the orbit escapes (a large radius smooths the colouring).
    pub const ESCAPE_RADIUS_SQUARED: f32 = 256.0;
    pub const LN_2: f32 = core::f32::consts::LN_2;
    pub const TAU: f32 = core::f32::consts::TAU;

    /// Smooth iteration count of z → z² + c from `z`: `MAX_ITERATIONS` inside the set.
    pub fn escape_time(start: Vec2, c: Vec2) -> f32 {
        let mut z = start;
        let mut i = 0u32;
        while i < MAX_ITERATIONS {
            let squared = z.dot(z);
            if squared > ESCAPE_RADIUS_SQUARED {
                // Continuous count: subtract how far past the radius the last step went.
                return i as f32 + 1.0 - (0.5 * squared.ln()).ln() / LN_2;
            }
            z = Vec2::new(z.x * z.x - z.y * z.y, 2.0 * z.x * z.y) + c;
            i += 1;
        }
        MAX_ITERATIONS as f32
    }

    /// The colour of pixel (x, y) of a `width` x `height` image of the set of `c`.
    pub fn shade(x: u32, y: u32, width: u32, height: u32, c: Vec2) -> Vec4 {
        let size = Vec2::new(width as f32, height as f32);
        let uv = (Vec2::new(x as f32, y as f32) + 0.5) / size * 2.0 - 1.0;
        let z = Vec2::new(uv.x * 1.6 * size.x / size.y, uv.y * 1.6);
        let t = escape_time(z, c) / MAX_ITERATIONS as f32;
        if t >= 1.0 {
            return Vec4::new(0.0, 0.0, 0.0, 1.0);
        }
        // A cosine palette (Inigo Quilez's form).
        let phase = (Vec3::new(0.0, 0.33, 0.67) + Vec3::splat(t * 3.0)) * TAU;
        let colour = Vec3::splat(0.5) + Vec3::new(phase.x.cos(), phase.y.cos(), phase.z.cos()) * 0.5;
        colour.extend(1.0)
    }
}
