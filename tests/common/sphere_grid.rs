//! A sphere grid for chi-square tests of direction samplers (cells fine around one axis),
//! with the chi-square p-value: shared by `metal_rough.rs` and `glass.rs`.

use std::f64::consts::PI;

use glam::{DVec3, Vec3};
use tracer::kernel::sampling::{onb_from_normal, onb_to_local, onb_to_world, Onb};

/// The cells of a sphere grid centred on the mirror direction of `wo`: polar angle from it
/// `θ = π t⁴` (fine near the specular peak, which at the roughness clamp is a few milliradians
/// wide), `T` cells in t and `P` in the azimuth.
pub struct Grid {
    frame: Onb,
}

pub const T: usize = 12;
pub const P: usize = 12;
/// Quadrature points per cell (midpoint rule in t and azimuth). Seen from a grazing angle the
/// reflected lobe at the roughness clamp is ~1e-4 rad wide across the plane of incidence
/// (2 cos θd times the half vector's spread): 64 azimuths per cell resolve it.
pub const QT: usize = 32;
pub const QP: usize = 64;

impl Grid {
    pub fn new(wo: Vec3) -> Grid {
        Grid::around(Vec3::new(-wo.x, -wo.y, wo.z))
    }

    /// The same grid centred on the unit direction `axis` (a refracted lobe's, say).
    pub fn around(axis: Vec3) -> Grid {
        Grid { frame: onb_from_normal(axis) }
    }

    pub fn cell(&self, wi: Vec3) -> usize {
        // From the tangential components: `acos` of an f32 cosine cannot resolve the angles of
        // the narrowest lobes (cos θ rounds to 1 below θ ~ 3e-4).
        let l = onb_to_local(self.frame, wi).as_dvec3();
        let theta = l.x.hypot(l.y).atan2(l.z);
        let t = (theta / PI).powf(0.25);
        let phi = l.y.atan2(l.x) + PI;
        let ti = ((t * T as f64) as usize).min(T - 1);
        let pi = ((phi / (2.0 * PI) * P as f64) as usize).min(P - 1);
        ti * P + pi
    }

    /// ∫ over each cell of `g(wi)` dω.
    pub fn integrate(&self, g: impl Fn(Vec3) -> f64) -> Vec<f64> {
        let mut cells = vec![0.0; T * P];
        for ti in 0..T {
            for qt in 0..QT {
                let t = (ti as f64 + (qt as f64 + 0.5) / QT as f64) / T as f64;
                let theta = PI * t.powi(4);
                // dω = sin θ dθ dφ, dθ = 4π t³ dt.
                let jacobian = theta.sin() * 4.0 * PI * t.powi(3) / (T * QT) as f64 * (2.0 * PI / (P * QP) as f64);
                for pi in 0..P {
                    for qp in 0..QP {
                        let phi = (pi as f64 + (qp as f64 + 0.5) / QP as f64) / P as f64 * 2.0 * PI - PI;
                        let l = DVec3::new(theta.sin() * phi.cos(), theta.sin() * phi.sin(), theta.cos());
                        let wi = onb_to_world(self.frame, l.as_vec3()).normalize();
                        cells[ti * P + pi] += g(wi) * jacobian;
                    }
                }
            }
        }
        cells
    }
}

/// Upper regularised gamma tail of the chi-square distribution by the Wilson–Hilferty normal
/// approximation (within about 1 % of the tail for dof >= 10).
pub fn chi_square_p_value(chi2: f64, dof: usize) -> f64 {
    let k = dof as f64;
    let c = 2.0 / (9.0 * k);
    let z = ((chi2 / k).cbrt() - (1.0 - c)) / c.sqrt();
    0.5 * erfc(z / std::f64::consts::SQRT_2)
}

/// Complementary error function (Numerical Recipes' Chebyshev fit, relative error < 1.2e-7).
fn erfc(x: f64) -> f64 {
    let z = x.abs();
    let t = 1.0 / (1.0 + 0.5 * z);
    let r = t
        * (-z * z - 1.26551223
            + t * (1.00002368
                + t * (0.37409196
                    + t * (0.09678418
                        + t * (-0.18628806
                            + t * (0.27886807
                                + t * (-1.13520398 + t * (1.48851587 + t * (-0.82215223 + t * 0.17087277)))))))))
            .exp();
    if x >= 0.0 {
        r
    } else {
        2.0 - r
    }
}
