//! Stratified 2D samples shared by several estimates of one quantity: the
//! camera positions and light samples of all camera rays of a pixel (or of
//! all repeats of a radiance query) are spread over one pattern instead of
//! each ray stratifying only its own few samples.
//!
//! The pattern is progressive (docs/math.md §16): sample `j` of `M` takes
//! cell `D(σ(R(τ(j))))` of a `2^⌈k/2⌉ × 2^⌊k/2⌋` grid, `k = ⌈log₂ M⌉`,
//! jittered uniformly within the cell, where `τ` and `σ` are nested uniform
//! (Owen) scrambles of `k` bits keyed per pattern (hash-based, Burley 2020),
//! `R` reverses the bits, and `D` de-interleaves them into a column (the
//! even bits from the top) and a row (the odd ones); with `M` not a power of
//! two, some cells stay empty. Samples `j ≥ 2^k` (past a 32-bit pattern)
//! are uniform on the square. Any aligned block of `2^m` consecutive
//! samples (`j` from `a·2^m`) then puts one sample in each cell of the
//! coarser `2^⌈m/2⌉ × 2^⌊m/2⌋` grid: a pass of `spp` rays is stratified on
//! its own and so is every aligned run of passes of a power-of-two length,
//! while every sample is uniform on its own (each scrambled word is) and
//! samples in distinct cells are nearly independent within them, so means
//! stay unbiased with at most about the variance of independent samples
//! (Owen 1997, "Monte Carlo variance of scrambled net quadrature"; the
//! bit-reversed Morton order is the base-2 van der Corput idea in 2D). `τ`
//! shuffles the order within blocks, so two patterns with different seeds
//! used by the same rays (a ray's camera position and its light sample) are
//! not coupled through their shared index.

use super::seed::mix;

/// One pattern of `count` 2D samples (see the module docs). `Copy`, so a
/// pixel draws it once and hands it to each of its rays.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SharedStrata {
    /// `k = ⌈log₂ count⌉` (at most 32): the pattern has `2^k` cells.
    bits: u32,
    /// Seeds of the index shuffle `τ` and of the scramble `σ`.
    seeds: [u32; 2],
    /// `1 / columns`, `1 / rows`: powers of two, so multiplying is exact.
    cell: [f64; 2],
}

impl SharedStrata {
    /// A pattern of `count ≥ 1` samples (0 is taken as 1) from two
    /// independent uniform words.
    pub fn new(count: u64, seeds: [u64; 2]) -> Self {
        let key = mix(seeds[0] ^ mix(seeds[1]));
        let bits = count.max(1).next_power_of_two().ilog2().min(32);
        Self {
            bits,
            seeds: [key as u32, (key >> 32) as u32],
            cell: [
                1.0 / (1u64 << bits.div_ceil(2)) as f64,
                1.0 / (1u64 << (bits / 2)) as f64,
            ],
        }
    }

    /// Sample `j` of the pattern from the uniform jitter `u ∈ [0, 1)²`:
    /// `u` moved into cell `D(σ(R(τ(j))))` for `j < 2^k`, `u` itself
    /// otherwise.
    pub fn sample(&self, j: u64, u: [f64; 2]) -> [f64; 2] {
        let k = self.bits;
        let Some(code) = self.cell_code(j) else {
            return u;
        };
        // De-interleave from the top bit: column, row, column, … With a zero
        // appended when `k` is odd, the column holds the odd bits and the
        // row the even ones (the row then one zero too many at the bottom).
        let even = u64::from(code) << (k & 1);
        let column = compact_even_bits(even >> 1);
        let row = compact_even_bits(even) >> (k & 1);
        [
            (column as f64 + u[0]) * self.cell[0],
            (row as f64 + u[1]) * self.cell[1],
        ]
    }

    /// The code `σ(R(τ(j)))` of sample `j`'s cell (module docs), `k` bits;
    /// `None` where the sample is not stratified (`k = 0` or `j ≥ 2^k`).
    /// Codes `2m` and `2m + 1` are neighbouring cells: they differ only in
    /// the lowest bit, the finest column or row.
    pub fn cell_code(&self, j: u64) -> Option<u32> {
        let k = self.bits;
        if k == 0 || j >> k != 0 {
            return None;
        }
        // `R(τ(j))` is the hash of `R(j)` itself: `τ`'s outer reversal and
        // `R` cancel, so neither is computed.
        let shuffled = laine_karras(reverse(j as u32, k), self.seeds[0]);
        Some(owen_scramble(shuffled, k, self.seeds[1]))
    }
}

/// The low `k ∈ 1..=32` bits of `v` in reverse order.
fn reverse(v: u32, k: u32) -> u32 {
    v.reverse_bits() >> (32 - k)
}

/// Nested uniform scramble of the `k`-bit word `v` (Owen 1995): bit
/// `k − 1 − l` (level `l` from the top) is flipped by a coin that depends on
/// the seed and on `v`'s bits above it only. So it maps every aligned block
/// of `2^m` words onto an aligned block of the same size and permutes within
/// blocks, exactly. The coins come from a hash whose bit `i` depends only on
/// bits `0..=i` of its input (a Laine–Karras permutation, here with
/// Vegdahl's 2021 constants) applied to the reversed word, as in Burley
/// 2020, "Practical hash-based Owen scrambling" (JCGT 9(4)): every output
/// word is uniform when the seed is (its first step adds the seed), and the
/// coins of distinct nodes are close to independent.
fn owen_scramble(v: u32, k: u32, seed: u32) -> u32 {
    reverse(laine_karras(reverse(v, k), seed), k)
}

/// The hash of [`owen_scramble`]: a bijection of 32-bit words whose bit `i`
/// depends only on bits `0..=i` of `x` and on the seed.
fn laine_karras(mut x: u32, seed: u32) -> u32 {
    x ^= x.wrapping_mul(0x3D20_ADEA);
    x = x.wrapping_add(seed);
    x = x.wrapping_mul((seed >> 16) | 1);
    x ^= x.wrapping_mul(0x0552_6C56);
    x ^= x.wrapping_mul(0x53A2_2864);
    x
}

/// Bits 0, 2, 4, … of `x` packed into its low half (bit `2i` to bit `i`).
fn compact_even_bits(x: u64) -> u64 {
    let mut x = x & 0x5555_5555_5555_5555;
    x = (x | (x >> 1)) & 0x3333_3333_3333_3333;
    x = (x | (x >> 2)) & 0x0F0F_0F0F_0F0F_0F0F;
    x = (x | (x >> 4)) & 0x00FF_00FF_00FF_00FF;
    x = (x | (x >> 8)) & 0x0000_FFFF_0000_FFFF;
    (x | (x >> 16)) & 0x0000_0000_FFFF_FFFF
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
    fn scrambles_are_bijections() {
        let mut rng = Pcg64::seed_from_u64(3);
        for count in [2, 8, 64, 1000, 4096] {
            let strata = random_strata(count, &mut rng);
            let cells = 1u32 << strata.bits;
            let mut seen = vec![false; cells as usize];
            for code in 0..cells {
                let s = owen_scramble(code, strata.bits, strata.seeds[1]);
                assert!(
                    s < cells && !seen[s as usize],
                    "count {count}: {code} → {s}"
                );
                seen[s as usize] = true;
            }
        }
    }

    /// Every aligned block of `2^m` samples puts one in each cell of the
    /// `2^⌈m/2⌉ × 2^⌊m/2⌋` grid: each pass of a power-of-two size, and the
    /// whole pattern, are stratified.
    #[test]
    fn every_aligned_block_puts_one_sample_in_each_cell() {
        let mut rng = Pcg64::seed_from_u64(1);
        for count in [1, 2, 8, 10, 16, 64, 256] {
            let strata = random_strata(count, &mut rng);
            for m in 0..=strata.bits {
                let (columns, rows) = (1u64 << m.div_ceil(2), 1u64 << (m / 2));
                for block in 0..(1u64 << (strata.bits - m)) {
                    let mut hits = vec![0; (columns * rows) as usize];
                    for j in block << m..(block + 1) << m {
                        let [x, y] = strata.sample(j, [rng.random(), rng.random()]);
                        assert!((0.0..1.0).contains(&x) && (0.0..1.0).contains(&y));
                        let cell = (y * rows as f64) as u64 * columns + (x * columns as f64) as u64;
                        hits[cell as usize] += 1;
                    }
                    assert!(
                        hits.iter().all(|&h| h == 1),
                        "count {count} m {m}: {hits:?}"
                    );
                }
            }
            // Padding past the 2^k cells is the jitter itself.
            assert_eq!(strata.sample(1 << strata.bits, [0.25, 0.75]), [0.25, 0.75]);
        }
    }

    /// Two patterns used by the same rays (a camera position and a light
    /// sample of ray `j`) are not coupled through the index: whether both
    /// samples of a ray fall in the left half agrees for about half the
    /// rays, where without the shuffle `τ` it agrees for all or none.
    #[test]
    fn patterns_sharing_an_index_are_not_coupled() {
        let mut rng = Pcg64::seed_from_u64(4);
        for _ in 0..50 {
            let (a, b) = (random_strata(256, &mut rng), random_strata(256, &mut rng));
            let agree = (0..256)
                .filter(|&j| (a.sample(j, [0.5; 2])[0] < 0.5) == (b.sample(j, [0.5; 2])[0] < 0.5))
                .count();
            assert!((64..=192).contains(&agree), "{agree} of 256");
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
