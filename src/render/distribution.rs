//! Piecewise-constant distributions in one and two dimensions, sampled by
//! inverting their cumulative distribution (pbrt-v4 §A.4.1 and §A.4.6:
//! `PiecewiseConstant1D`, `PiecewiseConstant2D`).
//!
//! Used to pick emitters in proportion to their power and to importance-sample
//! lat-long environment maps (texel luminance × sin θ).

/// Piecewise-constant density on `[0, 1)` with `n` equal bins.
///
/// Invariant: `cdf` has `n + 1` entries, starts at 0, ends at 1 and never
/// decreases. When every weight is zero the distribution falls back to
/// uniform so that sampling always succeeds.
#[derive(Clone, Debug)]
pub struct Distribution1D {
    /// Bin weights after clamping negatives and non-finite values to zero.
    weights: Vec<f64>,
    cdf: Vec<f64>,
    /// Sum of the weights divided by the bin count: the integral of the
    /// unnormalised step function over `[0, 1)`.
    integral: f64,
}

impl Distribution1D {
    /// `weights` must be non-empty; negative or non-finite weights count as 0.
    pub fn new(weights: &[f64]) -> Self {
        assert!(!weights.is_empty(), "a distribution needs at least one bin");
        let mut weights: Vec<f64> = weights
            .iter()
            .map(|&w| if w.is_finite() && w > 0.0 { w } else { 0.0 })
            .collect();
        let n = weights.len() as f64;
        let total: f64 = weights.iter().sum();
        let integral = total / n;
        if total <= 0.0 {
            weights.iter_mut().for_each(|w| *w = 1.0);
        }
        let total: f64 = weights.iter().sum();
        let mut cdf = Vec::with_capacity(weights.len() + 1);
        let mut acc = 0.0;
        cdf.push(0.0);
        for w in &weights {
            acc += w;
            cdf.push(acc / total);
        }
        if let Some(last) = cdf.last_mut() {
            *last = 1.0;
        }
        Self {
            weights,
            cdf,
            integral,
        }
    }

    fn len(&self) -> usize {
        self.weights.len()
    }

    /// Integral of the (unnormalised) step function over `[0, 1)`; zero when
    /// every weight was zero.
    pub fn integral(&self) -> f64 {
        self.integral
    }

    /// Probability of bin `i` under [`Distribution1D::sample_discrete`].
    pub fn probability(&self, i: usize) -> f64 {
        self.cdf[i + 1] - self.cdf[i]
    }

    /// Picks a bin with probability proportional to its weight.
    /// Returns `(bin, probability, u remapped to [0,1) within the bin)`.
    pub fn sample_discrete(&self, u: f64) -> (usize, f64, f64) {
        let i = self.find(u);
        let p = self.probability(i);
        let remapped = if p > 0.0 {
            ((u - self.cdf[i]) / p).clamp(0.0, 1.0 - f64::EPSILON)
        } else {
            0.0
        };
        (i, p, remapped)
    }

    /// Continuous sample `x ∈ [0, 1)` with its density `p(x) = n · P(bin)`.
    /// Returns `(x, pdf, bin)`.
    pub fn sample_continuous(&self, u: f64) -> (f64, f64, usize) {
        let (i, p, within) = self.sample_discrete(u);
        let n = self.len() as f64;
        ((i as f64 + within) / n, p * n, i)
    }

    /// Density of [`Distribution1D::sample_continuous`] at `x ∈ [0, 1]`.
    pub fn pdf(&self, x: f64) -> f64 {
        let n = self.len();
        let i = ((x * n as f64) as usize).min(n - 1);
        self.probability(i) * n as f64
    }

    /// Largest `i` with `cdf[i] ≤ u`, restricted to bins with non-zero mass.
    fn find(&self, u: f64) -> usize {
        let u = u.clamp(0.0, 1.0);
        let i = self.cdf.partition_point(|&c| c <= u).saturating_sub(1);
        let mut i = i.min(self.len() - 1);
        // Rounding can land on an empty bin at the top; step back to mass.
        while i > 0 && self.probability(i) == 0.0 {
            i -= 1;
        }
        i
    }
}

/// Piecewise-constant density on `[0,1)²` over a `width × height` grid,
/// sampled as a marginal over rows (`v`) then a conditional within the row
/// (`u`).
#[derive(Clone, Debug)]
pub struct Distribution2D {
    rows: Vec<Distribution1D>,
    marginal: Distribution1D,
}

impl Distribution2D {
    /// `weights` is row-major, `weights[y * width + x]`, with `y` along `v`.
    pub fn new(weights: &[f64], width: usize, height: usize) -> Self {
        assert!(width > 0 && height > 0 && weights.len() == width * height);
        let rows: Vec<Distribution1D> = weights.chunks(width).map(Distribution1D::new).collect();
        let marginal = Distribution1D::new(&rows.iter().map(|r| r.integral()).collect::<Vec<_>>());
        Self { rows, marginal }
    }

    /// Point `(u, v)` with its density over `[0,1)²`.
    pub fn sample(&self, u: [f64; 2]) -> ((f64, f64), f64) {
        let (v, pdf_v, row) = self.marginal.sample_continuous(u[1]);
        let (x, pdf_u, _) = self.rows[row].sample_continuous(u[0]);
        ((x, v), pdf_v * pdf_u)
    }

    /// Density of [`Distribution2D::sample`] at `(u, v)`.
    pub fn pdf(&self, u: f64, v: f64) -> f64 {
        let h = self.rows.len();
        let row = ((v * h as f64) as usize).min(h - 1);
        self.marginal.pdf(v) * self.rows[row].pdf(u)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn discrete_sampling_follows_the_weights() {
        let d = Distribution1D::new(&[1.0, 0.0, 3.0, f64::NAN]);
        assert_eq!(d.probability(1), 0.0);
        assert_eq!(d.probability(3), 0.0);
        assert!((d.probability(2) - 0.75).abs() < 1e-15);
        let n = 10_000;
        let mut counts = [0usize; 4];
        for i in 0..n {
            let (bin, p, within) = d.sample_discrete((i as f64 + 0.5) / n as f64);
            assert!(p > 0.0 && (0.0..1.0).contains(&within));
            counts[bin] += 1;
        }
        assert_eq!(counts, [2500, 0, 7500, 0]);
        assert_eq!(d.sample_discrete(1.0).0, 2);
    }

    #[test]
    fn continuous_density_integrates_to_one_and_matches_samples() {
        let d = Distribution1D::new(&[0.5, 2.0, 0.0, 1.5]);
        let n = 4000;
        let integral: f64 = (0..n)
            .map(|i| d.pdf((i as f64 + 0.5) / n as f64))
            .sum::<f64>()
            / n as f64;
        assert!((integral - 1.0).abs() < 1e-12);
        for i in 0..100 {
            let (x, pdf, _) = d.sample_continuous((i as f64 + 0.5) / 100.0);
            assert!((pdf - d.pdf(x)).abs() < 1e-12);
            assert!(pdf > 0.0);
        }
    }

    #[test]
    fn all_zero_weights_fall_back_to_uniform() {
        let d = Distribution1D::new(&[0.0, 0.0]);
        assert_eq!(d.integral(), 0.0);
        assert_eq!(d.probability(0), 0.5);
    }

    #[test]
    fn two_dimensional_density_integrates_to_one_and_matches_samples() {
        let (w, h) = (5, 3);
        let weights: Vec<f64> = (0..w * h).map(|i| ((i * 7) % 5) as f64).collect();
        let d = Distribution2D::new(&weights, w, h);
        let n = 200;
        let mut integral = 0.0;
        for i in 0..n {
            for j in 0..n {
                integral += d.pdf((i as f64 + 0.5) / n as f64, (j as f64 + 0.5) / n as f64);
            }
        }
        assert!((integral / (n * n) as f64 - 1.0).abs() < 1e-12);
        let total: f64 = weights.iter().sum();
        for i in 0..50 {
            let ((u, v), pdf) = d.sample([(i as f64 * 0.618) % 1.0, (i as f64 + 0.5) / 50.0]);
            assert!((pdf - d.pdf(u, v)).abs() < 1e-9);
            let texel = weights[(v * h as f64) as usize * w + (u * w as f64) as usize];
            assert!((pdf - texel / total * (w * h) as f64).abs() < 1e-9);
        }
    }
}
