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
