//! The mean of RGB samples with the variance of that mean.

use crate::color::Rgb;
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

/// Fewest full 2 × 2 blocks of cells from which [`MeanEstimate::of_strata`]
/// estimates a variance: each contrast is one degree of freedom.
pub const MIN_STRATA_BLOCKS: usize = 16;

/// The two variances of a stratified mean ([`MeanEstimate::of_strata`]),
/// per channel, of the mean, in the value's units squared.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StrataVariance {
    /// From the contrasts of the full blocks: unbiased or conservative, but
    /// with `blocks` degrees of freedom at most, and fewer where a few
    /// blocks hold all the variance (a shadow's edge, a small bright light).
    pub stratified: Rgb,
    /// `s²/N` of the same values as if they were independent: a bound with
    /// `N − 1` degrees of freedom, by as much as the stratification gains.
    pub independent: Rgb,
    /// Full 2 × 2 blocks, each one contrast.
    pub blocks: u32,
}

impl StrataVariance {
    /// The stratified variance moderated towards `ratio` times the
    /// independent one, as if that prior were worth `prior_blocks` blocks:
    /// `(d v_s + d₀ c v_i)/(d + d₀)` (Smyth 2004), with `c` pooled by the
    /// calibration on the scene and `d₀` fixed there (docs/math.md §10.5).
    pub fn moderated(&self, ratio: f64, prior_blocks: f64) -> Rgb {
        let d = f64::from(self.blocks);
        (self.stratified * d + self.independent * (ratio * prior_blocks))
            * (1.0 / (d + prior_blocks))
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

    /// The mean of `values`, each drawn in the cell `cells[i]` of a
    /// stratified pattern at most one per cell (`None`: not stratified), and
    /// the variance of that mean from the contrasts of 2 × 2 blocks of cells
    /// (docs/math.md §14): the cells whose codes share all bits but the
    /// lowest two form a block, and `(f₀₀ − f₀₁ − f₁₀ + f₁₁)²` has the sum of
    /// the four values' variances within their cells as its expectation,
    /// plus the square of the same contrast of the cells' means, which a
    /// trend linear across the block cancels. A value outside a full block
    /// adds the plain sample variance of all the values; with fewer than
    /// [`MIN_STRATA_BLOCKS`] full blocks, too few to estimate a variance,
    /// this is [`Self::of`] and there is no [`StrataVariance`].
    pub fn of_strata(values: &[Rgb], cells: &[Option<u32>]) -> (Self, Option<StrataVariance>) {
        let plain = Self::of(values.iter().copied());
        let mut by_cell: Vec<(u32, usize)> = cells
            .iter()
            .enumerate()
            .filter_map(|(i, c)| c.map(|c| (c, i)))
            .collect();
        by_cell.sort_unstable();
        let (mut contrasts, mut blocks) = (Rgb::BLACK, 0);
        for block in by_cell.chunk_by(|a, b| a.0 >> 2 == b.0 >> 2) {
            if block.len() == 4 {
                let sign = |c: u32| if (c ^ (c >> 1)) & 1 == 0 { 1.0 } else { -1.0 };
                let contrast = block
                    .iter()
                    .fold(Rgb::BLACK, |sum, &(c, i)| sum + values[i] * sign(c));
                contrasts += contrast * contrast;
                blocks += 1;
            }
        }
        if blocks < MIN_STRATA_BLOCKS {
            return (plain, None);
        }
        let n = values.len() as f64;
        // `variance_of_mean` is `s²/n`; `s²` for each value outside a block.
        let rest = plain.variance_of_mean * ((n - 4.0 * blocks as f64) * n);
        let stratified = (contrasts + rest) * (1.0 / (n * n));
        let strata = StrataVariance {
            stratified,
            independent: plain.variance_of_mean,
            blocks: blocks as u32,
        };
        (
            Self {
                variance_of_mean: stratified,
                ..plain
            },
            Some(strata),
        )
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

    /// Full 2 × 2 blocks count their squared contrasts, which a linear
    /// trend leaves at zero; values outside them, the sample variance of
    /// all; too few blocks, the plain formula.
    #[test]
    fn strata_take_the_contrasts_of_full_blocks() {
        // A linear trend over 18 blocks, stored in another order: value
        // `c + 10 (c >> 2)` in cell `c`; every contrast is zero.
        let cells: Vec<u32> = (0..72).map(|c| (c * 7) % 72).collect();
        let values: Vec<Rgb> = cells
            .iter()
            .map(|&c| Rgb::new(f64::from(c + 10 * (c >> 2)), 0.0, 0.0))
            .collect();
        let codes: Vec<Option<u32>> = cells.iter().map(|&c| Some(c)).collect();
        let plain = MeanEstimate::of(values.iter().copied());
        let (linear, strata) = MeanEstimate::of_strata(&values, &codes);
        assert_eq!(linear.mean, plain.mean);
        let strata = strata.unwrap();
        assert_eq!(strata.blocks, 18);
        assert_eq!(strata.independent, plain.variance_of_mean);
        assert_eq!(linear.variance_of_mean.r, 0.0);
        // The value in cell 0 off the trend by 4: its block's contrast is 4.
        let mut bumped = values.clone();
        bumped[0].r += 4.0;
        let n2 = 72.0 * 72.0;
        let (one, strata) = MeanEstimate::of_strata(&bumped, &codes);
        assert!((one.variance_of_mean.r - 16.0 / n2).abs() < 1e-12);
        // Moderated: no prior weight leaves it; equal weight, the midpoint
        // with the scaled independent variance.
        let strata = strata.unwrap();
        assert_eq!(strata.moderated(0.5, 0.0), one.variance_of_mean);
        let midpoint = (strata.stratified.r + 0.5 * strata.independent.r) / 2.0;
        assert!((strata.moderated(0.5, 18.0).r - midpoint).abs() < 1e-12);
        // The value in cell 35 not stratified: its block (32…35) is not
        // full, and its four values each add the sample variance.
        let mut loose = codes.clone();
        loose[5] = None;
        let (partial, _) = MeanEstimate::of_strata(&bumped, &loose);
        let s2 = MeanEstimate::of(bumped.iter().copied()).variance_of_mean.r * 72.0;
        assert!((partial.variance_of_mean.r - (16.0 + 4.0 * s2) / n2).abs() < 1e-12);
        // Fifteen blocks are too few: the plain formula.
        let (few, few_codes) = (&bumped[..60], &(0..60).map(Some).collect::<Vec<_>>());
        assert_eq!(
            MeanEstimate::of_strata(few, few_codes),
            (MeanEstimate::of(few.iter().copied()), None)
        );
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
