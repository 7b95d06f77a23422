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

/// Why two images cannot be compared.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum CompareError {
    #[error("images differ in size: {0} pixels against a reference of {1}")]
    SizeMismatch(usize, usize),
    #[error("the images are empty")]
    Empty,
}

/// The ε of [`rel_mse`]: keeps dark reference pixels from dominating (Rousselle et al. 2011 use
/// 0.01 for radiance around 1).
pub const REL_MSE_EPSILON: f64 = 1e-2;

fn check_sizes(image: &[glam::Vec3], reference: &[glam::Vec3]) -> Result<(), CompareError> {
    if image.len() != reference.len() {
        return Err(CompareError::SizeMismatch(image.len(), reference.len()));
    }
    if image.is_empty() {
        return Err(CompareError::Empty);
    }
    Ok(())
}

/// Mean squared error over every pixel and channel, in f64. A non-finite pixel makes the
/// result non-finite (the error is then unknown, not small).
pub fn mse(image: &[glam::Vec3], reference: &[glam::Vec3]) -> Result<f64, CompareError> {
    check_sizes(image, reference)?;
    let sum: f64 = image
        .iter()
        .zip(reference)
        .map(|(a, b)| {
            let d = a.as_dvec3() - b.as_dvec3();
            d.dot(d)
        })
        .sum();
    Ok(sum / (3 * image.len()) as f64)
}

/// Root mean squared error over every pixel and channel (same units as the radiance).
pub fn rmse(image: &[glam::Vec3], reference: &[glam::Vec3]) -> Result<f64, CompareError> {
    mse(image, reference).map(f64::sqrt)
}

/// Relative mean squared error: the mean over pixels and channels of
/// `(x - ref)² / (ref² + ε)` with ε = [`REL_MSE_EPSILON`]. Unlike [`rmse`] it weighs dark and
/// bright regions alike, so it does not only measure the brightest pixels.
pub fn rel_mse(image: &[glam::Vec3], reference: &[glam::Vec3]) -> Result<f64, CompareError> {
    check_sizes(image, reference)?;
    let sum: f64 = image
        .iter()
        .zip(reference)
        .map(|(a, b)| {
            let (a, b) = (a.as_dvec3(), b.as_dvec3());
            let d = a - b;
            (d * d / (b * b + REL_MSE_EPSILON)).element_sum()
        })
        .sum();
    Ok(sum / (3 * image.len()) as f64)
}

/// Slope of the least-squares line through `(ln x, ln y)`: the convergence rate of an error
/// measured at several times (−½ for the RMSE of an unbiased Monte Carlo estimator, −1 for
/// its MSE). `None` with fewer than two usable points (non-positive or non-finite values are
/// skipped) or when every x is the same.
pub fn log_log_slope(points: &[(f64, f64)]) -> Option<f64> {
    let logs: Vec<(f64, f64)> = points
        .iter()
        .filter(|(x, y)| *x > 0.0 && *y > 0.0 && x.is_finite() && y.is_finite())
        .map(|(x, y)| (x.ln(), y.ln()))
        .collect();
    if logs.len() < 2 {
        return None;
    }
    let n = logs.len() as f64;
    let mx = logs.iter().map(|p| p.0).sum::<f64>() / n;
    let my = logs.iter().map(|p| p.1).sum::<f64>() / n;
    let sxx: f64 = logs.iter().map(|p| (p.0 - mx) * (p.0 - mx)).sum();
    let sxy: f64 = logs.iter().map(|p| (p.0 - mx) * (p.1 - my)).sum();
    (sxx > 0.0).then(|| sxy / sxx)
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;

    #[test]
    fn errors_of_a_known_difference() {
        let reference = vec![Vec3::ONE; 4];
        let mut image = reference.clone();
        image[0] = Vec3::new(3.0, 1.0, 1.0); // one channel off by 2 out of 12
        assert!((mse(&image, &reference).unwrap() - 4.0 / 12.0).abs() < 1e-12);
        assert!((rmse(&image, &reference).unwrap() - (4.0f64 / 12.0).sqrt()).abs() < 1e-12);
        let expected = 4.0 / (1.0 + REL_MSE_EPSILON) / 12.0;
        assert!((rel_mse(&image, &reference).unwrap() - expected).abs() < 1e-12);
        assert_eq!(rmse(&reference, &reference).unwrap(), 0.0);
    }

    #[test]
    fn rel_mse_weighs_dark_pixels_like_bright_ones() {
        // The same 10% error on a dark and on a bright reference gives (nearly) the same relMSE.
        let dark = rel_mse(&[Vec3::splat(1.1)], &[Vec3::splat(1.0)]).unwrap();
        let bright = rel_mse(&[Vec3::splat(110.0)], &[Vec3::splat(100.0)]).unwrap();
        assert!((dark / bright - 1.0).abs() < 0.02, "{dark} vs {bright}");
        assert!(rmse(&[Vec3::splat(110.0)], &[Vec3::splat(100.0)]).unwrap() > 50.0 * 0.1);
    }

    #[test]
    fn mismatched_or_empty_images_are_errors() {
        assert_eq!(rmse(&[Vec3::ONE], &[Vec3::ONE, Vec3::ONE]), Err(CompareError::SizeMismatch(1, 2)));
        assert_eq!(rel_mse(&[], &[]), Err(CompareError::Empty));
        assert!(mse(&[Vec3::NAN], &[Vec3::ONE]).unwrap().is_nan());
    }

    #[test]
    fn slope_of_a_power_law() {
        let points: Vec<(f64, f64)> = (1..=8).map(|i| (i as f64, 3.0 / (i as f64).sqrt())).collect();
        assert!((log_log_slope(&points).unwrap() + 0.5).abs() < 1e-12);
        assert_eq!(log_log_slope(&[(1.0, 1.0)]), None);
        assert_eq!(log_log_slope(&[(1.0, 1.0), (1.0, 2.0)]), None);
    }
}
