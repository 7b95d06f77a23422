#[kernel_dsl::kernel]
pub mod sampling {
    //! Direction sampling: an orthonormal basis around a normal and cosine-weighted
    //! hemisphere sampling (the Lambert BSDF's importance sampling).

    use glam::{Vec2, Vec3};

    pub const PI: f32 = core::f32::consts::PI;
    pub const INV_PI: f32 = core::f32::consts::FRAC_1_PI;

    /// An orthonormal basis; `normal` is the local +Z axis.
    #[derive(Clone, Copy, Debug, PartialEq)]
    pub struct Onb {
        pub tangent: Vec3,
        pub bitangent: Vec3,
        pub normal: Vec3,
    }

    /// Duff et al. 2017, "Building an Orthonormal Basis, Revisited": branch-light and
    /// continuous except across z = 0. `n` must be unit length.
    pub fn onb_from_normal(n: Vec3) -> Onb {
        let sign = if n.z >= 0.0 { 1.0 } else { -1.0 };
        let a = -1.0 / (sign + n.z);
        let b = n.x * n.y * a;
        Onb {
            tangent: Vec3::new(1.0 + sign * n.x * n.x * a, sign * b, -sign * n.x),
            bitangent: Vec3::new(b, sign + n.y * n.y * a, -n.y),
            normal: n,
        }
    }

    /// Local (tangent, bitangent, normal) coordinates to world space.
    pub fn onb_to_world(onb: Onb, v: Vec3) -> Vec3 {
        onb.tangent * v.x + onb.bitangent * v.y + onb.normal * v.z
    }

    /// A cosine-weighted direction on the +Z hemisphere from two uniforms in [0, 1)
    /// (Malley's method on the polar disk mapping). Its pdf is `cos_theta / PI`.
    pub fn cosine_sample_hemisphere(u1: f32, u2: f32) -> Vec3 {
        let r = u1.sqrt();
        let cs = cos_sin_turns(u2);
        let z = (1.0 - u1).max(0.0).sqrt();
        Vec3::new(r * cs.x, r * cs.y, z)
    }

    /// (cos, sin) of the angle `2π t` for t in [0, 1], within 2e-7: the quarter turn nearest
    /// to t, then Taylor polynomials (to degree 8 and 9) on the remaining eighth of a turn at
    /// most, rotated by the quarter turns. The same arithmetic on every target, with no call:
    /// on a CPU, `sin`/`cos` are a library call that took 4 % of a Cornell box sample's time.
    pub fn cos_sin_turns(t: f32) -> Vec2 {
        let quarters = (t * 4.0).round();
        let x = (t * 4.0 - quarters) * (0.5 * PI);
        let x2 = x * x;
        let s = x * (1.0 + x2 * (-1.0 / 6.0 + x2 * (1.0 / 120.0 + x2 * (-1.0 / 5040.0 + x2 * (1.0 / 362880.0)))));
        let c = 1.0 + x2 * (-0.5 + x2 * (1.0 / 24.0 + x2 * (-1.0 / 720.0 + x2 * (1.0 / 40320.0))));
        // Quarter turns 0 to 4 (4 is a whole turn): rotate (c, s) by 90 degrees each.
        let q = (quarters as u32) & 3;
        if q == 0 {
            Vec2::new(c, s)
        } else if q == 1 {
            Vec2::new(-s, c)
        } else if q == 2 {
            Vec2::new(-c, -s)
        } else {
            Vec2::new(s, -c)
        }
    }

    /// The solid-angle pdf of `cosine_sample_hemisphere` for a direction at `cos_theta`.
    pub fn cosine_hemisphere_pdf(cos_theta: f32) -> f32 {
        cos_theta.max(0.0) * INV_PI
    }

    /// A cosine-weighted direction around the unit normal `n`.
    pub fn sample_cosine_around(n: Vec3, u1: f32, u2: f32) -> Vec3 {
        onb_to_world(onb_from_normal(n), cosine_sample_hemisphere(u1, u2))
    }

    /// Uniform barycentrics (u, v) on a triangle from two uniforms (Shirley's square-root
    /// mapping): the point is `(1 - u - v) * p0 + u * p1 + v * p2`.
    pub fn uniform_sample_triangle(u1: f32, u2: f32) -> Vec2 {
        let s = u1.sqrt();
        Vec2::new(s * (1.0 - u2), s * u2)
    }

    /// World coordinates to the basis' local (tangent, bitangent, normal) ones: the inverse of
    /// [`onb_to_world`] (the basis is orthonormal).
    pub fn onb_to_local(onb: Onb, v: Vec3) -> Vec3 {
        Vec3::new(v.dot(onb.tangent), v.dot(onb.bitangent), v.dot(onb.normal))
    }
}
