//! Stratified 2D samples shared by several estimates of one quantity: the
//! light samples of all camera rays of a pixel (or of all repeats of a
//! radiance query) are spread over one jittered grid instead of each ray
//! stratifying only its own few samples.
//!
//! Sample `j` of `M` uses cell `c(j) = (π(j) + o) mod s²` of an `s × s`
//! grid, `s = ⌊√M⌋`, jittered uniformly within the cell; samples `j ≥ s²`
//! are uniform on the square (padding, as in the camera-ray grid of
//! `render::tile`). `π` is a pseudo-random permutation of `0..s²` keyed per
//! pattern (so the order of the rays carries no structure into the cells)
//! and `o` a uniform random offset: for every fixed `j`, `c(j)` is uniform
//! over the cells whatever `π` is, so every sample is uniform on its own and
//! means of them stay unbiased, while distinct samples of a pattern never
//! share a cell (Owen 2013, *Monte Carlo theory, methods and examples*,
//! §10.2, for jittered sampling; the rotation by `o` is the Cranley–Patterson
//! trick applied to cell indices).

/// One pattern of `count` 2D samples (see the module docs). `Copy`, so a
/// pixel draws it once and hands it to each of its rays.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SharedStrata {
    /// Grid side `s = ⌊√M⌋`.
    side: u64,
    /// Key of the permutation `π`.
    key: u64,
    /// Cell offset `o ∈ 0..s²`.
    offset: u64,
}

impl SharedStrata {
    /// A pattern of `count ≥ 1` samples (0 is taken as 1) from two
    /// independent uniform words: the permutation key and the offset's.
    pub fn new(count: u64, seeds: [u64; 2]) -> Self {
        let count = count.max(1);
        let side = count.isqrt();
        let cells = side * side;
        // Multiply-high maps a uniform u64 onto 0..cells (bias < cells/2⁶⁴).
        let offset = ((u128::from(seeds[1]) * u128::from(cells)) >> 64) as u64;
        Self {
            side,
            key: seeds[0],
            offset,
        }
    }

    /// Sample `j` of the pattern from the uniform jitter `u ∈ [0, 1)²`:
    /// `u` moved into cell `c(j)` for `j < s²`, `u` itself otherwise.
    pub fn sample(&self, j: u64, u: [f64; 2]) -> [f64; 2] {
        let cells = self.side * self.side;
        if j >= cells {
            return u;
        }
        // Both terms are below `cells`, so one subtraction wraps the sum
        // (an integer division costs tens of cycles per camera ray).
        let cell = permute(j, cells, self.key) + self.offset;
        let cell = if cell >= cells { cell - cells } else { cell };
        let (row, column) = (cell / self.side, cell % self.side);
        let s = self.side as f64;
        [(column as f64 + u[0]) / s, (row as f64 + u[1]) / s]
    }
}

/// A near-square grid of `s_x × s_y = n` cells over the unit square
/// (`s_x` the largest divisor of `n` not above `√n`), for `n` samples
/// that each take one cell, in order.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct GridStrata {
    sx: u32,
    sy: u32,
}

impl GridStrata {
    /// A grid of `n ≥ 1` cells (0 is taken as 1).
    pub fn new(n: u32) -> Self {
        let n = n.max(1);
        let sx = (1..=n.isqrt())
            .rev()
            .find(|&d| n.is_multiple_of(d))
            .unwrap_or(1);
        Self { sx, sy: n / sx }
    }

    /// `u ∈ [0, 1)²` moved into cell `j mod n`.
    pub fn sample(&self, j: u32, u: [f64; 2]) -> [f64; 2] {
        let (x, y) = (j % self.sx, (j / self.sx) % self.sy);
        [
            (f64::from(x) + u[0]) / f64::from(self.sx),
            (f64::from(y) + u[1]) / f64::from(self.sy),
        ]
    }
}

/// A pseudo-random permutation of `0..n` keyed by `key`: a bijection on the
/// `b`-bit integers (`2^b ≥ n`, the smallest such) iterated until it lands
/// below `n` ("cycle walking": the walk stays on `i`'s cycle, which returns
/// below `n`, and takes fewer than two steps on average as `2^b < 2n`).
/// Each round xors a key, multiplies by an odd constant and xor-shifts
/// right, each a bijection modulo `2^b`.
fn permute(i: u64, n: u64, key: u64) -> u64 {
    debug_assert!(i < n);
    if n <= 1 {
        return 0;
    }
    let bits = 64 - (n - 1).leading_zeros();
    let mask = if bits == 64 {
        u64::MAX
    } else {
        (1 << bits) - 1
    };
    let shift = (bits / 2).max(1);
    let round_keys = [key, key.rotate_left(21), key.rotate_left(42)];
    const ODD: [u64; 3] = [
        0x9E37_79B9_7F4A_7C15,
        0xBF58_476D_1CE4_E5B9,
        0x94D0_49BB_1331_11EB,
    ];
    let mut x = i;
    loop {
        for (k, m) in round_keys.iter().zip(ODD) {
            x = (x ^ k) & mask;
            x = x.wrapping_mul(m) & mask;
            x ^= x >> shift;
        }
        if x < n {
            return x;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{RngExt, SeedableRng};
    use rand_pcg::Pcg64;

    /// A pattern of `count` samples with seeds drawn from `rng`.
    fn random_strata(count: u64, rng: &mut Pcg64) -> SharedStrata {
        SharedStrata::new(count, [rng.random(), rng.random()])
    }

    #[test]
    fn grids_are_near_square_and_cover_the_square() {
        assert_eq!(GridStrata::new(8), GridStrata { sx: 2, sy: 4 });
        assert_eq!(GridStrata::new(9), GridStrata { sx: 3, sy: 3 });
        assert_eq!(GridStrata::new(7), GridStrata { sx: 1, sy: 7 });
        assert_eq!(GridStrata::new(0), GridStrata { sx: 1, sy: 1 });
        let grid = GridStrata::new(8);
        let cells: Vec<[f64; 2]> = (0..8).map(|j| grid.sample(j, [0.5, 0.5])).collect();
        for (j, c) in cells.iter().enumerate() {
            assert!(cells[..j].iter().all(|d| d != c), "cell {j} repeated");
        }
        assert_eq!(grid.sample(3, [0.0, 0.0]), [0.5, 0.25]);
    }

    #[test]
    fn permutations_are_bijections() {
        for n in [1, 2, 3, 7, 64, 100, 1000, 4097] {
            for key in [0, 1, 0xDEAD_BEEF, u64::MAX] {
                let mut seen = vec![false; n as usize];
                for i in 0..n {
                    let p = permute(i, n, key);
                    assert!(p < n && !seen[p as usize], "n {n} key {key}: {i} → {p}");
                    seen[p as usize] = true;
                }
            }
        }
    }

    #[test]
    fn a_pattern_puts_one_sample_in_each_cell() {
        let mut rng = Pcg64::seed_from_u64(1);
        for count in [1, 4, 10, 64, 256] {
            let strata = random_strata(count, &mut rng);
            let side = count.isqrt();
            let mut hits = vec![0; (side * side) as usize];
            for j in 0..count {
                let [x, y] = strata.sample(j, [rng.random(), rng.random()]);
                assert!((0.0..1.0).contains(&x) && (0.0..1.0).contains(&y));
                if j < side * side {
                    let cell = (y * side as f64) as u64 * side + (x * side as f64) as u64;
                    hits[cell as usize] += 1;
                }
            }
            assert!(hits.iter().all(|&h| h == 1), "count {count}: {hits:?}");
        }
    }

    /// Every sample is uniform on its own: over many patterns, sample `j`
    /// falls in each quarter of the square equally often (χ² test).
    #[test]
    fn each_sample_is_uniform_over_patterns() {
        let mut rng = Pcg64::seed_from_u64(2);
        let patterns = 40_000;
        for j in [0, 5, 15] {
            let mut counts = [0.0f64; 4];
            for _ in 0..patterns {
                let strata = random_strata(16, &mut rng);
                let [x, y] = strata.sample(j, [rng.random(), rng.random()]);
                counts[usize::from(x >= 0.5) + 2 * usize::from(y >= 0.5)] += 1.0;
            }
            let expected = patterns as f64 / 4.0;
            let chi2: f64 = counts
                .iter()
                .map(|c| (c - expected).powi(2) / expected)
                .sum();
            // 3 degrees of freedom: P(χ² > 16.27) = 0.001.
            assert!(chi2 < 16.27, "sample {j}: {counts:?}");
        }
    }
}
