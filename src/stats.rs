//! Running mean and spread by Welford's update (Welford 1962): the one place
//! the project computes a sample mean and the variance of that mean, for
//! scalars (`bmc::estimator`) and RGB values (`render`) alike; and the
//! standard normal quantile that turns a confidence into a number of
//! standard deviations (docs/math.md §10.6); the inverse error function and
//! the root finder the samplers invert their CDFs with; and the binomial
//! upper tail that bounds how many genuine imported records may disagree
//! with fresh estimates (docs/math.md §9.8).

use std::f64::consts::PI;
use std::ops::{Add, Div, Mul, Sub};

/// Mean and sum of squared deviations of the values pushed so far.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct RunningMean<T> {
    count: u64,
    mean: T,
    m2: T,
}

impl<T> RunningMean<T>
where
    T: Copy + Default + Add<Output = T> + Sub<Output = T> + Mul<Output = T> + Div<f64, Output = T>,
{
    /// No values yet.
    pub fn new() -> Self {
        Self::default()
    }

    /// Adds one value (products are per component for RGB).
    pub fn push(&mut self, value: T) {
        self.count += 1;
        let delta = value - self.mean;
        self.mean = self.mean + delta / self.count as f64;
        self.m2 = self.m2 + delta * (value - self.mean);
    }

    /// The running mean (zero before any value).
    pub fn mean(&self) -> T {
        self.mean
    }

    /// Values pushed.
    pub fn count(&self) -> u64 {
        self.count
    }

    /// The variance of the mean: the unbiased sample variance (dividing by
    /// `n − 1`, as the mean is estimated from the same values) over `n`;
    /// `None` for fewer than two values, where no spread is known.
    pub fn variance_of_mean(&self) -> Option<T> {
        let n = self.count;
        (n > 1).then(|| self.m2 / ((n - 1) * n) as f64)
    }
}

/// `z = error / sqrt(σ² + r²)` of docs/math.md §10.3, from the variances
/// `σ²` of the estimate and `r²` of the reference: the error in units of
/// their combined standard deviation; zero for an exact estimate with no
/// spread, infinite for a wrong one.
pub fn standard_score(error: f64, variance: f64, reference_variance: f64) -> f64 {
    let scale = (variance + reference_variance).sqrt();
    if scale > 0.0 {
        error / scale
    } else if error == 0.0 {
        0.0
    } else {
        f64::INFINITY
    }
}

/// `erfc(x)` with fractional error below 1.2e-7 everywhere (the Chebyshev
/// fit of Press et al., *Numerical Recipes*, 2nd ed., §6.2).
pub fn erfc(x: f64) -> f64 {
    let t = 1.0 / (1.0 + 0.5 * x.abs());
    let poly = -1.265_512_23
        + t * (1.000_023_68
            + t * (0.374_091_96
                + t * (0.096_784_18
                    + t * (-0.186_288_06
                        + t * (0.278_868_07
                            + t * (-1.135_203_98
                                + t * (1.488_515_87 + t * (-0.822_152_23 + t * 0.170_872_77))))))));
    let tail = t * (-x * x + poly).exp();
    if x >= 0.0 { tail } else { 2.0 - tail }
}

/// `erf⁻¹(p)` for `p ∈ (−1, 1)` (clamped just inside): Giles' (2010)
/// single-precision approximation refined by two Newton steps on
/// `libm::erf`.
pub fn inverse_erf(p: f64) -> f64 {
    let p = p.clamp(-1.0 + 1e-15, 1.0 - 1e-15);
    let w = -((1.0 - p) * (1.0 + p)).ln();
    let mut x = if w < 5.0 {
        let w = w - 2.5;
        let mut q = 2.810_226_36e-08;
        for c in [
            3.432_739_39e-07,
            -3.523_387_7e-06,
            -4.391_506_54e-06,
            0.000_218_580_87,
            -0.001_253_725_03,
            -0.004_177_681_64,
            0.246_640_727,
            1.501_409_41,
        ] {
            q = c + q * w;
        }
        q * p
    } else {
        let w = w.sqrt() - 3.0;
        let mut q = -0.000_200_214_257;
        for c in [
            0.000_100_950_558,
            0.001_349_343_22,
            -0.003_673_428_44,
            0.005_739_507_73,
            -0.007_622_461_3,
            0.009_438_870_47,
            1.001_674_06,
            2.832_976_82,
        ] {
            q = c + q * w;
        }
        q * p
    };
    let two_over_sqrt_pi = 2.0 / PI.sqrt();
    for _ in 0..2 {
        let e = libm::erf(x) - p;
        x -= e / (two_over_sqrt_pi * (-x * x).exp());
    }
    x
}

/// The `x` in `[lo, hi]` where the increasing function `f` reaches
/// `target`, by Newton's method with `slope`, `f`'s derivative, from
/// `start`: a step that would leave the bracket, which shrinks around the
/// root at every evaluation, is a bisection instead. Stops when
/// `|f(x) − target| ≤ tolerance` or neither the step nor the bracket can
/// shrink further. The inverse CDFs of samplers (`optics::microfacet`,
/// `scene::pixel_filter`) are found this way.
pub fn solve_increasing(
    f: impl Fn(f64) -> f64,
    slope: impl Fn(f64) -> f64,
    target: f64,
    (mut lo, mut hi): (f64, f64),
    start: f64,
    tolerance: f64,
) -> f64 {
    let mut x = start;
    for _ in 0..100 {
        let g = f(x) - target;
        if g.abs() <= tolerance {
            break;
        }
        if g > 0.0 {
            hi = x;
        } else {
            lo = x;
        }
        let newton = x - g / slope(x);
        let next = if newton > lo && newton < hi {
            newton
        } else {
            0.5 * (lo + hi)
        };
        if next == x || hi - lo <= 1e-15 * (1.0 + x.abs()) {
            break;
        }
        x = next;
    }
    x
}

/// The `z` with `P(|Z| ≤ z) = confidence` for a standard normal `Z`, by
/// bisection on `erfc(z/√2) = 1 − confidence`; `confidence` in `(0, 1)`.
pub fn two_sided_normal_quantile(confidence: f64) -> f64 {
    let tail = 1.0 - confidence;
    let (mut lo, mut hi) = (0.0f64, 40.0f64);
    for _ in 0..100 {
        let mid = 0.5 * (lo + hi);
        if erfc(mid / std::f64::consts::SQRT_2) > tail {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    0.5 * (lo + hi)
}

/// `P(X ≥ k)` for `X ~ Binomial(n, p)`, `p` in `[0, 1]`: the sum over
/// `j ≥ k` of `C(n, j) p^j (1 − p)^(n − j)`, each term's logarithm built from
/// the previous one's by `ln((n − j)/(j + 1)) + ln(p/(1 − p))`, so no
/// binomial coefficient overflows (docs/math.md §9.8 bounds a count of
/// disagreeing records with it). 1 for `k = 0`, 0 for `k > n`.
pub fn binomial_upper_tail(n: u64, p: f64, k: u64) -> f64 {
    if k == 0 {
        return 1.0;
    }
    if k > n || p <= 0.0 {
        return 0.0;
    }
    if p >= 1.0 {
        return 1.0;
    }
    let odds = (p / (1.0 - p)).ln();
    // ln of the term j = 0, then up to j = k − 1.
    let mut log_term = n as f64 * (-p).ln_1p();
    for j in 0..k {
        log_term += ((n - j) as f64 / (j + 1) as f64).ln() + odds;
    }
    let mut tail = 0.0;
    for j in k..=n {
        tail += log_term.exp();
        if j < n {
            log_term += ((n - j) as f64 / (j + 1) as f64).ln() + odds;
        }
    }
    tail.min(1.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Against sums of exact binomial coefficients.
    #[test]
    fn binomial_tails_match_their_definition() {
        let exact = |n: u64, p: f64, k: u64| -> f64 {
            (k..=n)
                .map(|j| {
                    let c = (0..j).fold(1.0, |c, i| c * (n - i) as f64 / (i + 1) as f64);
                    c * p.powi(j as i32) * (1.0 - p).powi((n - j) as i32)
                })
                .sum()
        };
        for (n, p, k) in [
            (10, 0.05, 8),
            (64, 0.05, 19),
            (64, 0.5, 32),
            (5, 0.3, 1),
            (1, 0.05, 1),
        ] {
            let (got, want) = (binomial_upper_tail(n, p, k), exact(n, p, k));
            assert!(
                (got - want).abs() <= 1e-12 * want,
                "{n} {p} {k}: {got} vs {want}"
            );
        }
        assert_eq!(binomial_upper_tail(64, 0.05, 0), 1.0);
        assert_eq!(binomial_upper_tail(64, 0.05, 65), 0.0);
        assert_eq!(binomial_upper_tail(3, 0.0, 1), 0.0);
        // All of n: p^n.
        assert!((binomial_upper_tail(7, 0.05, 7) - 0.05f64.powi(7)).abs() < 1e-22);
    }

    #[test]
    fn matches_the_textbook_formulas() {
        let mut running = RunningMean::new();
        assert_eq!(running.variance_of_mean(), None);
        for v in [1.0, 2.0, 4.0, 7.0] {
            running.push(v);
        }
        // Mean 3.5; sample variance (2.5² + 1.5² + 0.5² + 3.5²)/3 = 7; over 4.
        assert_eq!(running.count(), 4);
        assert!((running.mean() - 3.5).abs() < 1e-12);
        assert!((running.variance_of_mean().unwrap() - 1.75).abs() < 1e-12);
    }

    #[test]
    fn normal_quantiles_match_the_tables() {
        for (confidence, z) in [(0.6827, 1.0), (0.95, 1.959_964), (0.99, 2.575_829)] {
            let got = two_sided_normal_quantile(confidence);
            assert!((got - z).abs() < 2e-4, "{confidence}: {got}");
        }
        assert!((erfc(0.0) - 1.0).abs() < 1e-7);
        assert!((erfc(-1.0) - 1.842_700_79).abs() < 1e-6);
    }

    #[test]
    fn the_inverse_error_function_inverts_erf_into_the_tails() {
        for p in [-0.999_999_9, -0.9, -0.3, 0.0, 1e-9, 0.5, 0.99, 0.999_999] {
            let x = inverse_erf(p);
            assert!(
                (libm::erf(x) - p).abs() < 1e-14,
                "{p}: erf({x}) = {}",
                libm::erf(x)
            );
        }
    }
}
