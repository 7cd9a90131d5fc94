//! Running mean and spread by Welford's update (Welford 1962): the one place
//! the project computes a sample mean and the variance of that mean, for
//! scalars (`bmc::estimator`) and RGB values (`render`) alike.

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

#[cfg(test)]
mod tests {
    use super::*;

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
}
