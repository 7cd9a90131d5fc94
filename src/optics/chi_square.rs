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

/// The statistic of `samples` draws of a direction (`None` where a draw
/// gives none, which the density's missing mass accounts for) against the
/// solid-angle density `pdf`, over `z_bins × phi_bins` cells of equal
/// solid angle on the whole sphere, the expected counts integrated by
/// 16 × 16 midpoints per cell.
#[cfg(test)]
pub(crate) fn of_directions(
    mut draw: impl FnMut() -> Option<glam::DVec3>,
    pdf: impl Fn(glam::DVec3) -> f64,
    samples: usize,
    (z_bins, phi_bins): (usize, usize),
) -> ChiSquare {
    use std::f64::consts::TAU;
    let cell = |w: glam::DVec3| {
        let i = (((w.z + 1.0) / 2.0 * z_bins as f64) as usize).min(z_bins - 1);
        let phi = w.y.atan2(w.x).rem_euclid(TAU);
        let j = ((phi / TAU * phi_bins as f64) as usize).min(phi_bins - 1);
        i * phi_bins + j
    };
    let mut counts = vec![0.0; z_bins * phi_bins];
    for _ in 0..samples {
        if let Some(w) = draw() {
            counts[cell(w)] += 1.0;
        }
    }
    let sub = 16;
    let (dz, dphi) = (2.0 / (z_bins * sub) as f64, TAU / (phi_bins * sub) as f64);
    let mut expected = vec![0.0; z_bins * phi_bins];
    for a in 0..z_bins * sub {
        let z = -1.0 + (a as f64 + 0.5) * dz;
        let r = (1.0 - z * z).sqrt();
        for b in 0..phi_bins * sub {
            let phi = (b as f64 + 0.5) * dphi;
            let w = glam::DVec3::new(r * phi.cos(), r * phi.sin(), z);
            expected[cell(w)] += pdf(w) * dz * dphi * samples as f64;
        }
    }
    ChiSquare::of(&counts, &expected)
}

/// χ² quantile by the Wilson–Hilferty approximation at `z` standard deviations.
fn quantile(df: f64, z: f64) -> f64 {
    let h = 2.0 / (9.0 * df);
    df * (1.0 - h + z * h.sqrt()).powi(3)
}
