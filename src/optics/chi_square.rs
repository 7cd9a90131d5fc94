//! Pearson's χ² test of sampled counts against the counts a density
//! predicts, for the sampling tests of the microfacet distributions and
//! the BSDFs (as Mitsuba 3's and pbrt's test suites do).

/// Cells expecting fewer samples than this are pooled into one.
const MIN_EXPECTED: f64 = 5.0;

/// The test's threshold, in standard deviations of the χ² distribution
/// (one-sided p ≈ 1e-4, so a correct sampler fails about once in 10⁴ runs).
const Z: f64 = 3.719;

/// The statistic of one test and the limit it must stay below.
#[derive(Clone, Copy, Debug)]
pub struct ChiSquare {
    pub chi2: f64,
    /// Cells counted (the pooled one included).
    pub cells: f64,
    /// The χ² quantile at [`Z`] for `cells − 1` degrees of freedom.
    pub limit: f64,
    /// Observed and expected counts of the cells that expect too few to
    /// count on their own, when they do not add up to a cell either.
    pub left_out: (f64, f64),
}

impl ChiSquare {
    /// The statistic of `observed` counts against `expected` ones (same
    /// cells, same order).
    pub fn of(observed: &[f64], expected: &[f64]) -> Self {
        let (mut chi2, mut cells) = (0.0, 0.0);
        let (mut pooled_o, mut pooled_e) = (0.0, 0.0);
        for (o, e) in observed.iter().zip(expected) {
            if *e < MIN_EXPECTED {
                pooled_o += o;
                pooled_e += e;
            } else {
                chi2 += (o - e) * (o - e) / e;
                cells += 1.0;
            }
        }
        let mut left_out = (0.0, 0.0);
        if pooled_e >= MIN_EXPECTED {
            chi2 += (pooled_o - pooled_e).powi(2) / pooled_e;
            cells += 1.0;
        } else {
            left_out = (pooled_o, pooled_e);
        }
        Self {
            chi2,
            cells,
            limit: quantile(cells - 1.0, Z),
            left_out,
        }
    }

    pub fn passes(&self) -> bool {
        self.chi2 < self.limit
    }
}

impl std::fmt::Display for ChiSquare {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "χ² = {} over {} cells (limit {})",
            self.chi2, self.cells, self.limit
        )
    }
}

/// χ² quantile by the Wilson–Hilferty approximation at `z` standard deviations.
fn quantile(df: f64, z: f64) -> f64 {
    let h = 2.0 / (9.0 * df);
    df * (1.0 - h + z * h.sqrt()).powi(3)
}
