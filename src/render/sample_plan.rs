//! Adaptive passes: how many camera rays each pixel of a tile takes in a
//! pass, from the standard errors of the passes before (docs/math.md §16.5).

/// The most rays one pixel takes in one adaptive pass, in multiples of the
/// pass's mean: bounds what one firefly pixel can draw from the others.
const MAX_SHARE: u32 = 4;

/// Camera rays per pixel of one pass of a tile, and where in each pixel's
/// pattern they start.
#[derive(Clone, Debug, PartialEq)]
pub struct SamplePlan {
    /// Rays of each pixel in this pass, row order.
    pub counts: Vec<u32>,
    /// Index of each pixel's first ray in its pattern: the rays of the
    /// passes before.
    pub firsts: Vec<u32>,
    /// Rays each pixel's pattern is laid out for (`SharedStrata`): at least
    /// any pixel's rays over all passes.
    pub pattern: u32,
}

impl SamplePlan {
    /// The pattern size of an adaptive ladder of `passes` passes of `spp`
    /// rays per pixel on average: room for every pass to take
    /// [`MAX_SHARE`] times its mean.
    pub fn pattern_size(spp: u32, passes: u32) -> u32 {
        spp.saturating_mul(passes).saturating_mul(MAX_SHARE)
    }

    /// `spp` rays for each of `pixels` pixels, the first pass of a ladder of
    /// `passes`.
    pub fn uniform(pixels: usize, spp: u32, passes: u32) -> Self {
        Self {
            counts: vec![spp; pixels],
            firsts: vec![0; pixels],
            pattern: Self::pattern_size(spp, passes),
        }
    }

    /// A later pass of `spp` rays per pixel on average, for a tile
    /// `width` pixels wide whose first pass had, per pixel, `own_variance`
    /// (the variance of its mean's own noise, which more rays lower: the
    /// shared part left out, (W/(m²·sr))², from `spp` rays) and whose
    /// pixels have taken `rays` rays so far.
    ///
    /// Each pixel takes one ray, and the rest of the tile's `spp · pixels`
    /// go in proportion to per-ray standard deviations `σ_p`, at most
    /// [`MAX_SHARE`]` · spp` each: for a sum of squared errors `Σ σ_p² / n_p`
    /// under a fixed total the optimal `n_p` is proportional to `σ_p`
    /// (docs/math.md §16.5). `σ_p` is estimated from the first pass of the
    /// pixels two away from `p` (the ring around its 3×3 neighbourhood), so
    /// that no pixel's rays depend on its own values, nor on a variance
    /// pooled with them (§16.4): the mean weighted by rays stays unbiased.
    /// Counts are rounded cumulatively in row order, so they add up
    /// exactly; with no noise anywhere, or `spp < 2`, the pass is uniform.
    pub fn adaptive(
        spp: u32,
        passes: u32,
        width: usize,
        own_variance: &[f32],
        rays: &[u32],
    ) -> Self {
        let pixels = own_variance.len();
        let pattern = Self::pattern_size(spp, passes);
        let height = pixels.checked_div(width).unwrap_or(0);
        let per_ray: Vec<f64> = own_variance
            .iter()
            .map(|&v| f64::from(v.max(0.0)) * f64::from(spp))
            .map(|v| if v.is_finite() { v } else { 0.0 })
            .collect();
        let tile_mean = per_ray.iter().sum::<f64>() / pixels.max(1) as f64;
        let sigma: Vec<f64> = (0..pixels)
            .map(|i| {
                let (x, y) = ((i % width) as i64, (i / width) as i64);
                let (mut sum, mut count) = (0.0, 0u32);
                for dy in -2..=2i64 {
                    for dx in -2..=2i64 {
                        let (nx, ny) = (x + dx, y + dy);
                        let ring = dx.abs() == 2 || dy.abs() == 2;
                        if ring
                            && (0..width as i64).contains(&nx)
                            && (0..height as i64).contains(&ny)
                        {
                            sum += per_ray[ny as usize * width + nx as usize];
                            count += 1;
                        }
                    }
                }
                match count {
                    0 => tile_mean.sqrt(),
                    n => (sum / f64::from(n)).sqrt(),
                }
            })
            .collect();
        let total_sigma: f64 = sigma.iter().sum();
        if spp < 2 || total_sigma <= 0.0 {
            return Self {
                counts: vec![spp; pixels],
                firsts: rays.to_vec(),
                pattern,
            };
        }
        // Water-filling: pixels whose share passes the cap take the cap, and
        // the others share what is left in proportion to σ.
        let cap = f64::from(MAX_SHARE * spp - 1);
        let mut extra = vec![0.0; pixels];
        let mut capped = vec![false; pixels];
        let mut left = f64::from(spp - 1) * pixels as f64;
        loop {
            let free: f64 = (0..pixels).filter(|&p| !capped[p]).map(|p| sigma[p]).sum();
            if free <= 0.0 {
                // Only noiseless pixels are left below the cap: they share
                // the rest evenly, so the pass keeps its rays.
                let open = capped.iter().filter(|&&c| !c).count().max(1) as f64;
                for p in (0..pixels).filter(|&p| !capped[p]) {
                    extra[p] = left / open;
                }
                break;
            }
            let mut newly = false;
            for p in 0..pixels {
                if capped[p] {
                    continue;
                }
                extra[p] = left * sigma[p] / free;
                if extra[p] > cap {
                    extra[p] = cap;
                    capped[p] = true;
                    left -= cap;
                    newly = true;
                }
            }
            if !newly {
                break;
            }
        }
        let (mut cumulative, mut given) = (0.0, 0u64);
        let counts = extra
            .iter()
            .map(|e| {
                cumulative += e;
                let upto = cumulative.round() as u64;
                let n = upto - given;
                given = upto;
                1 + n as u32
            })
            .collect();
        Self {
            counts,
            firsts: rays.to_vec(),
            pattern,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A 5×1 tile: each pixel's σ is that of the pixels two away (per ray
    /// `v · spp`), never its own; the tile's rays add up to `spp` per pixel,
    /// each pixel takes one at least, and the rest follow σ.
    #[test]
    fn rays_follow_the_standard_deviation_two_pixels_away() {
        // Per-ray variances 4 v: 0, 0, 1, 4, 9 at x = 0..4.
        let own = [0.0, 0.0, 0.25, 1.0, 2.25];
        let plan = SamplePlan::adaptive(4, 3, 5, &own, &[4; 5]);
        // σ from x ± 2: x0 ← x2: 1; x1 ← x3: 2; x2 ← x0, x4: √4.5;
        // x3 ← x1: 0; x4 ← x2: 1. 15 extra rays in proportion, rounded
        // cumulatively.
        let sigma = [1.0, 2.0, 4.5_f64.sqrt(), 0.0, 1.0];
        let total: f64 = sigma.iter().sum();
        let mut cumulative = 0.0;
        let mut given = 0;
        let expected: Vec<u32> = sigma
            .iter()
            .map(|s| {
                cumulative += 15.0 * s / total;
                let upto = cumulative.round() as u32;
                let n = upto - given;
                given = upto;
                1 + n
            })
            .collect();
        assert_eq!(plan.counts, expected);
        assert_eq!(plan.counts.iter().sum::<u32>(), 20);
        assert_eq!(plan.counts[3], 1);
        assert_eq!(plan.firsts, [4; 5]);
        assert_eq!(plan.pattern, 48);
    }

    /// Pixels beside a firefly take at most `MAX_SHARE` times the mean,
    /// and the others share the rest; the total still adds up.
    #[test]
    fn noisy_neighbourhoods_take_at_most_their_cap() {
        let mut own = vec![1e-4_f32; 16];
        own[7] = 1e6;
        let plan = SamplePlan::adaptive(4, 2, 16, &own, &[4; 16]);
        assert_eq!(plan.counts[5], MAX_SHARE * 4);
        assert_eq!(plan.counts[9], MAX_SHARE * 4);
        assert!(plan.counts[7] < 4);
        assert_eq!(plan.counts.iter().sum::<u32>(), 64);
        assert!(plan.counts.iter().all(|&n| n >= 1));
        // Noise that only two pixels' rings see: they take the cap, and the
        // noiseless rest share what is left evenly.
        let mut own = vec![0.0_f32; 16];
        own[7] = 1.0;
        let plan = SamplePlan::adaptive(4, 2, 16, &own, &[4; 16]);
        assert_eq!((plan.counts[5], plan.counts[9]), (16, 16));
        assert_eq!(plan.counts.iter().sum::<u32>(), 64);
    }

    /// No noise anywhere (or one ray per pixel): a uniform pass.
    #[test]
    fn without_noise_the_pass_is_uniform() {
        assert_eq!(
            SamplePlan::adaptive(4, 2, 3, &[0.0; 3], &[4; 3]).counts,
            [4; 3]
        );
        assert_eq!(
            SamplePlan::adaptive(1, 2, 3, &[1.0; 3], &[1; 3]).counts,
            [1; 3]
        );
        let first = SamplePlan::uniform(3, 4, 2);
        assert_eq!((first.counts, first.firsts), (vec![4; 3], vec![0; 3]));
    }
}
