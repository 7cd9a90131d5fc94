//! One-dimensional numerical integration: Gauss–Legendre rules and a
//! globally adaptive bisection driver, the building blocks of the exact
//! kernel means.
//!
//! The adaptive scheme values each panel by a 12-point Gauss–Legendre rule on
//! its two halves, `L + R`, and takes `|L + R − W|` (`W`: the rule on the
//! whole panel) as its error estimate. That estimates the error of the
//! *coarser* `W`, so the returned sums are in practice many orders more
//! accurate than the requested tolerance for the smooth integrands used here
//! (Davis & Rabinowitz, *Methods of Numerical Integration*, 2nd ed., §6.2).

use std::collections::BinaryHeap;
use std::f64::consts::PI;
use std::sync::OnceLock;

/// Nodes and weights of an `n`-point Gauss–Legendre rule on `[-1, 1]`.
#[derive(Clone, Debug)]
pub(crate) struct GaussLegendre {
    pub nodes: Vec<f64>,
    pub weights: Vec<f64>,
}

impl GaussLegendre {
    /// Rule with `n ≥ 1` nodes, computed by Newton's method on the three-term
    /// recurrence of the Legendre polynomials (Press et al., *Numerical
    /// Recipes*, 3rd ed., §4.6), converged to machine precision.
    pub fn new(n: usize) -> GaussLegendre {
        let n = n.max(1);
        let mut nodes = vec![0.0; n];
        let mut weights = vec![0.0; n];
        for i in 0..n.div_ceil(2) {
            // Standard asymptotic initial guess for the i-th largest root.
            let mut x = (PI * (i as f64 + 0.75) / (n as f64 + 0.5)).cos();
            for _ in 0..100 {
                let (p, d) = legendre_with_derivative(n, x);
                let dx = p / d;
                x -= dx;
                if dx.abs() < 1e-16 {
                    break;
                }
            }
            let (_, dp) = legendre_with_derivative(n, x);
            let w = 2.0 / ((1.0 - x * x) * dp * dp);
            nodes[i] = -x;
            nodes[n - 1 - i] = x;
            weights[i] = w;
            weights[n - 1 - i] = w;
        }
        GaussLegendre { nodes, weights }
    }

    /// `∫_a^b f` by this rule mapped onto `[a, b]`.
    #[inline]
    pub fn integrate(&self, f: &dyn Fn(f64) -> f64, a: f64, b: f64) -> f64 {
        let half = 0.5 * (b - a);
        let mid = 0.5 * (a + b);
        let mut sum = 0.0;
        for (x, w) in self.nodes.iter().zip(&self.weights) {
            sum += w * f(mid + half * x);
        }
        sum * half
    }
}

/// `(P_n(x), P_n'(x))` by Bonnet's recurrence.
fn legendre_with_derivative(n: usize, x: f64) -> (f64, f64) {
    let (mut p0, mut p1) = (1.0, x);
    for k in 2..=n {
        let k = k as f64;
        let p2 = ((2.0 * k - 1.0) * x * p1 - (k - 1.0) * p0) / k;
        p0 = p1;
        p1 = p2;
    }
    if n == 0 {
        return (1.0, 0.0);
    }
    let d = n as f64 * (x * p1 - p0) / (x * x - 1.0);
    (p1, d)
}

/// Panel rule of the adaptive driver.
fn panel_rule() -> &'static GaussLegendre {
    static RULE: OnceLock<GaussLegendre> = OnceLock::new();
    RULE.get_or_init(|| GaussLegendre::new(12))
}

/// Accuracy request for [`adaptive`]: stop when the error estimate is below
/// `max(abs, rel·|value|)`.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Tolerance {
    pub rel: f64,
    pub abs: f64,
}

impl Tolerance {
    /// Tolerance for an integral that is multiplied by `factor` afterwards.
    pub fn scaled(self, factor: f64) -> Tolerance {
        Tolerance {
            rel: self.rel,
            abs: self.abs / factor.abs().max(1e-300),
        }
    }
}

/// Most panels one integral may use; reached only by integrands with
/// singularities, where the value is then returned at the accuracy reached.
const MAX_PANELS: usize = 2000;

/// A panel `[a, b]` with its two-half value and the error estimate of its
/// one-panel value `whole`.
struct Panel {
    a: f64,
    b: f64,
    left: f64,
    right: f64,
    error: f64,
}

impl Panel {
    fn new(f: &dyn Fn(f64) -> f64, rule: &GaussLegendre, a: f64, b: f64, whole: f64) -> Panel {
        let m = 0.5 * (a + b);
        let left = rule.integrate(f, a, m);
        let right = rule.integrate(f, m, b);
        Panel {
            a,
            b,
            left,
            right,
            error: (left + right - whole).abs(),
        }
    }
}

impl PartialEq for Panel {
    fn eq(&self, other: &Self) -> bool {
        self.error.total_cmp(&other.error).is_eq()
    }
}
impl Eq for Panel {}
impl PartialOrd for Panel {
    fn partial_cmp(&self, other: &Self) -> Option<std::cmp::Ordering> {
        Some(self.cmp(other))
    }
}
impl Ord for Panel {
    fn cmp(&self, other: &Self) -> std::cmp::Ordering {
        self.error.total_cmp(&other.error)
    }
}

/// Adaptive `∫_a^b f`, see the module documentation.
pub(crate) fn adaptive(f: &dyn Fn(f64) -> f64, a: f64, b: f64, tol: Tolerance) -> f64 {
    adaptive_split(f, a, b, &[], tol)
}

/// Adaptive `∫ f` over `[lo, hi]` split at the given interior `breaks` (kinks,
/// peaks, clipping boundaries), so that no feature hides inside one panel.
/// Breaks outside `(lo, hi)` are ignored.
///
/// Globally adaptive (QUADPACK's QAG strategy, Piessens et al. 1983): the
/// panel with the largest error estimate is bisected until the summed
/// estimate is below `max(abs, rel·|total|)`.
pub(crate) fn adaptive_split(
    f: &dyn Fn(f64) -> f64,
    lo: f64,
    hi: f64,
    breaks: &[f64],
    tol: Tolerance,
) -> f64 {
    if hi <= lo {
        return 0.0;
    }
    let rule = panel_rule();
    let mut points: Vec<f64> = breaks
        .iter()
        .copied()
        .filter(|x| x.is_finite() && *x > lo && *x < hi)
        .collect();
    points.push(lo);
    points.push(hi);
    points.sort_by(f64::total_cmp);
    points.dedup_by(|a, b| (*a - *b).abs() <= 1e-15 * (hi - lo));
    let mut heap: BinaryHeap<Panel> = points
        .windows(2)
        .map(|w| Panel::new(f, rule, w[0], w[1], rule.integrate(f, w[0], w[1])))
        .collect();
    let sums = |heap: &BinaryHeap<Panel>| {
        heap.iter()
            .fold((0.0, 0.0), |(t, e), p| (t + p.left + p.right, e + p.error))
    };
    let (mut total, mut error) = sums(&heap);
    loop {
        if error <= tol.abs.max(tol.rel * total.abs()) || heap.len() >= MAX_PANELS {
            // Running sums drift by rounding; confirm with exact ones.
            let (t, e) = sums(&heap);
            if e <= tol.abs.max(tol.rel * t.abs()) || heap.len() >= MAX_PANELS {
                return t;
            }
            (total, error) = (t, e);
        }
        let Some(worst) = heap.pop() else {
            return total;
        };
        let m = 0.5 * (worst.a + worst.b);
        let left = Panel::new(f, rule, worst.a, m, worst.left);
        let right = Panel::new(f, rule, m, worst.b, worst.right);
        total += left.left + left.right + right.left + right.right - worst.left - worst.right;
        error += left.error + right.error - worst.error;
        heap.push(left);
        heap.push(right);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn gauss_legendre_is_exact_for_polynomials_of_degree_2n_minus_1() {
        for n in [1, 2, 5, 12, 33] {
            let rule = GaussLegendre::new(n);
            let wsum: f64 = rule.weights.iter().sum();
            assert!((wsum - 2.0).abs() < 1e-14, "n={n}");
            let deg = 2 * n - 1;
            // ∫_0^1 x^deg = 1/(deg+1)
            let got = rule.integrate(&|x| x.powi(deg as i32), 0.0, 1.0);
            assert!((got - 1.0 / (deg as f64 + 1.0)).abs() < 1e-14, "n={n}");
        }
    }

    #[test]
    fn adaptive_handles_peaks_and_kinks() {
        let tol = Tolerance {
            rel: 1e-12,
            abs: 0.0,
        };
        // Narrow Gaussian at an interior break: ∫ = sqrt(π)·s·erf-ish ≈ sqrt(π)·s.
        let s = 1e-3;
        let got = adaptive_split(&|x| (-((x - 0.3) / s).powi(2)).exp(), 0.0, 1.0, &[0.3], tol);
        assert!((got / (PI.sqrt() * s) - 1.0).abs() < 1e-12);
        // |x − 1/3| has a kink; with the break it is integrated exactly.
        let got = adaptive_split(&|x| (x - 1.0 / 3.0).abs(), 0.0, 1.0, &[1.0 / 3.0], tol);
        assert!((got - (1.0 / 18.0 + 2.0 / 9.0)).abs() < 1e-15);
        // sqrt endpoint singularity converges by bisection.
        let got = adaptive(&|x: f64| x.sqrt(), 0.0, 1.0, tol);
        assert!((got - 2.0 / 3.0).abs() < 1e-11);
    }
}
