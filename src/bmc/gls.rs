//! The constant prior mean estimated by generalised least squares
//! (docs/math.md §3.3) and the residual it leaves for amplitude fits (§7.2,
//! §7.3): with `u = Q⁻¹1` and `s = 1ᵀu`, the mean is `m̂ = uᵀY/s` and the
//! residual quadratic form `(Y − m̂1)ᵀQ⁻¹(Y − m̂1) = YᵀQ⁻¹Y − (uᵀY)²/s`.
//! The one home of `Q⁻¹1`: the weights, the amplitude fits of estimates and
//! records, and the marginal likelihood all use it.

use super::dense::dot;
use super::factorisation::Factorisation;

/// `u = Q⁻¹1` and `s = 1ᵀQ⁻¹1` of one factorisation.
#[derive(Clone, Debug, PartialEq)]
pub struct Gls {
    ones_solved: Vec<f64>,
    ones_sum: f64,
}

impl Gls {
    /// Solves `Q u = 1` once.
    pub fn new(factorisation: &Factorisation) -> Self {
        let ones_solved = factorisation.solve(&vec![1.0; factorisation.len()]);
        let ones_sum = ones_solved.iter().sum();
        Gls {
            ones_solved,
            ones_sum,
        }
    }

    /// `u = Q⁻¹1`.
    pub fn ones_solved(&self) -> &[f64] {
        &self.ones_solved
    }

    /// `s = 1ᵀQ⁻¹1`.
    pub fn ones_sum(&self) -> f64 {
        self.ones_sum
    }

    /// The GLS mean `m̂ = uᵀY/s` of the values `Y`.
    pub fn mean(&self, values: &[f64]) -> f64 {
        dot(&self.ones_solved, values) / self.ones_sum
    }

    /// `(Y − m̂1)ᵀQ⁻¹(Y − m̂1)` from `Y` and `Q⁻¹Y`, clamped at 0 against
    /// rounding. Divided by the number of values it is the maximum-likelihood
    /// amplitude `σ̂²`; by one less, the unbiased one (one degree of freedom
    /// went into `m̂`). Callers say which they use and why.
    pub fn residual(&self, values: &[f64], solved: &[f64]) -> f64 {
        let cross = dot(&self.ones_solved, values);
        (dot(values, solved) - cross * cross / self.ones_sum).max(0.0)
    }

    /// Heap bytes held.
    pub fn size_bytes(&self) -> usize {
        self.ones_solved.len() * std::mem::size_of::<f64>()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bmc::{Kernel, KernelKind};
    use crate::sphere::{SampleSet, SampleSetKind, SampleSetSpec};

    #[test]
    fn a_constant_is_its_own_mean_and_leaves_no_residual() {
        let set = SampleSet::generate(SampleSetSpec {
            kind: SampleSetKind::Fibonacci,
            count: 16,
            seed: 0,
        })
        .unwrap();
        let kernel = Kernel::new(KernelKind::SquaredExponential, 0.5, 1.0, 1e-6).unwrap();
        let factorisation = Factorisation::new(&set, &kernel).unwrap();
        let gls = Gls::new(&factorisation);
        let constant = vec![2.5; 16];
        let mean = gls.mean(&constant);
        assert!((mean - 2.5).abs() < 1e-9);
        let residual = gls.residual(&constant, &factorisation.solve(&constant));
        assert!(residual.abs() < 1e-6, "{residual}");
        // A varying field leaves a positive residual.
        let field: Vec<f64> = set.directions.iter().map(|d| 1.0 + d.x).collect();
        assert!(gls.residual(&field, &factorisation.solve(&field)) > 1e-3);
    }
}
