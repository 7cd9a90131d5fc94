//! The mean of RGB samples with the variance of that mean.

use super::rgb::Rgb;
use crate::stats::RunningMean;

/// Sample mean of a quantity with the variance of that mean.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MeanEstimate {
    pub mean: Rgb,
    /// Unbiased sample variance divided by the sample count (0 for one sample).
    pub variance_of_mean: Rgb,
}

impl MeanEstimate {
    /// The mean of `values` and its variance, per channel (`crate::stats`).
    pub fn of(values: impl IntoIterator<Item = Rgb>) -> Self {
        let mut running = RunningMean::new();
        values.into_iter().for_each(|v| running.push(v));
        Self {
            mean: running.mean(),
            variance_of_mean: running.variance_of_mean().unwrap_or(Rgb::BLACK),
        }
    }

    pub(crate) fn scaled(self, s: f64) -> Self {
        Self {
            mean: self.mean * s,
            variance_of_mean: self.variance_of_mean * (s * s),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn mean_estimate_matches_the_textbook_formulas() {
        let values = [1.0, 2.0, 4.0, 7.0].map(|v| Rgb::new(v, 2.0 * v, 0.0));
        let e = MeanEstimate::of(values);
        // mean 3.5, sample variance ((2.5² + 1.5² + 0.5² + 3.5²) / 3) = 7, / 4.
        assert!((e.mean.r - 3.5).abs() < 1e-12);
        assert!((e.variance_of_mean.r - 1.75).abs() < 1e-12);
        assert!((e.variance_of_mean.g - 7.0).abs() < 1e-12);
        assert_eq!(e.variance_of_mean.b, 0.0);
        assert_eq!(MeanEstimate::of([Rgb::WHITE]).variance_of_mean, Rgb::BLACK);
    }
}
