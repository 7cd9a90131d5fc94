//! The mean of RGB samples with the variance of that mean.

use super::rgb::Rgb;
use crate::stats::RunningMean;

/// One estimate of an RGB quantity and the variances its estimator reports
/// for it (per channel, in the quantity's units squared; zero where the
/// estimator knows none, as for a single path).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Evaluation {
    pub value: Rgb,
    /// Variance of the evaluation's own noise, independent of other
    /// evaluations' (a glossy fallback's lobe-sampled paths).
    pub variance: Rgb,
    /// Variance of an error that every evaluation of the same quantity
    /// shares, so that it does not average out over them: that of the
    /// irradiance-cache records an evaluation interpolates (docs/math.md
    /// §16.3).
    pub shared: Rgb,
}

impl Evaluation {
    /// A value whose estimator reports no variance of its own.
    pub fn of(value: Rgb) -> Self {
        Self {
            value,
            variance: Rgb::BLACK,
            shared: Rgb::BLACK,
        }
    }
}

/// Sample mean of a quantity with the variance of that mean.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MeanEstimate {
    pub mean: Rgb,
    /// Unbiased sample variance divided by the sample count (0 for one
    /// sample), plus [`Self::shared`].
    pub variance_of_mean: Rgb,
    /// The part of `variance_of_mean` that the evaluations share (the mean
    /// of their [`Evaluation::shared`]), which more of them would not lower.
    pub shared: Rgb,
    /// Values averaged.
    pub count: u64,
}

impl MeanEstimate {
    /// The mean of `values` and its variance, per channel (`crate::stats`).
    pub fn of(values: impl IntoIterator<Item = Rgb>) -> Self {
        Self::of_evaluations(values.into_iter().map(Evaluation::of))
    }

    /// The mean of `evaluations` and, per channel, the larger of the
    /// variance of the mean from their spread (as [`Self::of`]) and the mean
    /// of the variances they report themselves over their count
    /// (docs/math.md §13.3): the spread of one evaluation is unknown, and an
    /// estimator's own variance (the glossy fallback's) is a floor the
    /// reported error should not fall below; plus the mean of their shared
    /// variances, which no count divides (docs/math.md §16.3). Where no
    /// evaluation reports a variance this is [`Self::of`] of their values,
    /// bit for bit.
    pub fn of_evaluations(evaluations: impl IntoIterator<Item = Evaluation>) -> Self {
        let mut running = RunningMean::new();
        let (mut own, mut shared) = (Rgb::BLACK, Rgb::BLACK);
        for e in evaluations {
            running.push(e.value);
            own += e.variance;
            shared += e.shared;
        }
        let n = running.count().max(1) as f64;
        let spread = running.variance_of_mean().unwrap_or(Rgb::BLACK).to_array();
        let own = (own * (1.0 / (n * n))).to_array();
        let variance = std::array::from_fn(|c| {
            if own[c] > spread[c] {
                own[c]
            } else {
                spread[c]
            }
        });
        let shared = shared * (1.0 / n);
        Self {
            mean: running.mean(),
            variance_of_mean: Rgb::from_array(variance) + shared,
            shared,
            count: running.count(),
        }
    }

    pub(crate) fn scaled(self, s: f64) -> Self {
        Self {
            mean: self.mean * s,
            variance_of_mean: self.variance_of_mean * (s * s),
            shared: self.shared * (s * s),
            count: self.count,
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

    /// Without own variances the spread alone, bit for bit; with them, the
    /// larger of spread and mean own variance over the count, per channel.
    #[test]
    fn evaluations_report_at_least_their_own_variance() {
        let values = [1.0, 2.0, 4.0, 7.0].map(|v| Rgb::new(v, 2.0 * v, 0.0));
        let plain = MeanEstimate::of_evaluations(values.map(Evaluation::of));
        assert_eq!(plain, MeanEstimate::of(values));
        let with_own = values.map(|value| Evaluation {
            value,
            variance: Rgb::new(0.0, 4.0, 8.0),
            shared: Rgb::BLACK,
        });
        let e = MeanEstimate::of_evaluations(with_own);
        assert_eq!(e.mean, plain.mean);
        // Spread 1.75 beats 0; spread 7 beats 4/4; own 8/4 beats spread 0.
        assert_eq!(e.variance_of_mean.r, plain.variance_of_mean.r);
        assert_eq!(e.variance_of_mean.g, plain.variance_of_mean.g);
        assert!((e.variance_of_mean.b - 2.0).abs() < 1e-12);
        // One evaluation: no spread, its own variance.
        let one = MeanEstimate::of_evaluations([Evaluation {
            value: Rgb::WHITE,
            variance: Rgb::new(0.5, 0.0, 0.0),
            shared: Rgb::BLACK,
        }]);
        assert_eq!(one.variance_of_mean, Rgb::new(0.5, 0.0, 0.0));
    }

    /// A shared variance is not divided by the count: four evaluations
    /// sharing a record's error of variance 2 report at least 2.
    #[test]
    fn shared_variances_do_not_average_out() {
        let values = [1.0, 2.0, 4.0, 7.0].map(|v| Rgb::new(v, 0.0, 0.0));
        let plain = MeanEstimate::of(values);
        let shared = MeanEstimate::of_evaluations(values.map(|value| Evaluation {
            shared: Rgb::new(2.0, 2.0, 0.0),
            ..Evaluation::of(value)
        }));
        assert_eq!(shared.mean, plain.mean);
        assert!((shared.variance_of_mean.r - (1.75 + 2.0)).abs() < 1e-12);
        assert_eq!(shared.shared, Rgb::new(2.0, 2.0, 0.0));
        assert!((shared.variance_of_mean.g - 2.0).abs() < 1e-12);
        assert_eq!(shared.variance_of_mean.b, 0.0);
    }
}
