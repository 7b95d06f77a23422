//! Statistics for comparing renders: estimates with standard errors, so that tests and charts
//! compare images with confidence intervals rather than exact pixels.

/// A mean with its standard error.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Estimate {
    pub mean: f64,
    pub std_err: f64,
}

impl Estimate {
    /// From independent samples (e.g. the mean of each frame of a render).
    pub fn from_samples(samples: &[f64]) -> Estimate {
        let n = samples.len() as f64;
        if n < 2.0 {
            return Estimate { mean: samples.first().copied().unwrap_or(0.0), std_err: f64::INFINITY };
        }
        let mean = samples.iter().sum::<f64>() / n;
        let var = samples.iter().map(|s| (s - mean) * (s - mean)).sum::<f64>() / (n - 1.0);
        Estimate { mean, std_err: (var / n).sqrt() }
    }

    /// How many combined standard errors separate two estimates.
    pub fn z_score(&self, other: &Estimate) -> f64 {
        let se = (self.std_err * self.std_err + other.std_err * other.std_err).sqrt();
        if se == 0.0 {
            if self.mean == other.mean {
                0.0
            } else {
                f64::INFINITY
            }
        } else {
            (self.mean - other.mean).abs() / se
        }
    }

    /// How many standard errors this estimate lies from an exact value.
    pub fn z_score_to(&self, exact: f64) -> f64 {
        self.z_score(&Estimate { mean: exact, std_err: 0.0 })
    }
}

/// Root mean squared error between two images (per channel, over all pixels).
pub fn rmse(a: &[glam::Vec3], b: &[glam::Vec3]) -> f64 {
    let n = (a.len().min(b.len()) * 3).max(1) as f64;
    let sum: f64 = a.iter().zip(b).map(|(x, y)| (*x - *y).as_dvec3().length_squared()).sum();
    (sum / n).sqrt()
}

/// Relative mean squared error: mean of (a - b)² / (b² + eps) over channels.
pub fn rel_mse(a: &[glam::Vec3], reference: &[glam::Vec3]) -> f64 {
    let n = (a.len().min(reference.len()) * 3).max(1) as f64;
    let eps = 1e-2;
    let sum: f64 = a
        .iter()
        .zip(reference)
        .map(|(x, r)| {
            let d = (*x - *r).as_dvec3();
            let r = r.as_dvec3();
            d.x * d.x / (r.x * r.x + eps) + d.y * d.y / (r.y * r.y + eps) + d.z * d.z / (r.z * r.z + eps)
        })
        .sum();
    sum / n
}
