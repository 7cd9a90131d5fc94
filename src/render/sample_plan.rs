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

    /// The next pass of `spp` rays per pixel on average after passes whose
    /// mean has, per pixel, `own_variance` (the variance of its own noise,
    /// which more rays lower: the shared part left out, (W/(m²·sr))²) from
    /// `rays` rays. Each pixel takes one ray, and the rest of the tile's
    /// `spp · pixels` go in proportion to the pixels' per-ray standard
    /// deviations `σ_p = √(v_p · n_p)`, at most [`MAX_SHARE`]` · spp` each:
    /// for a sum of squared errors `Σ σ_p² / n_p` under a fixed total, the
    /// optimal `n_p` is proportional to `σ_p` (docs/math.md §16.5). Counts
    /// are rounded cumulatively in row order, so they add up exactly; with
    /// no noise anywhere, or `spp < 2`, the pass is uniform.
    pub fn adaptive(spp: u32, passes: u32, own_variance: &[f32], rays: &[u32]) -> Self {
        let pixels = own_variance.len();
        let pattern = Self::pattern_size(spp, passes);
        let sigma: Vec<f64> = own_variance
            .iter()
            .zip(rays)
            .map(|(&v, &n)| (f64::from(v.max(0.0)) * f64::from(n)).sqrt())
            .map(|s| if s.is_finite() { s } else { 0.0 })
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

    /// The tile's rays add up to `spp` per pixel, every pixel takes one at
    /// least, and the rest follow the per-ray standard deviations.
    #[test]
    fn rays_follow_the_per_ray_standard_deviation() {
        // Per-ray σ: √(v n) = 0, 1, 2, 3 (with n = 4 rays so far).
        let own = [0.0, 0.25, 1.0, 2.25];
        let plan = SamplePlan::adaptive(4, 3, &own, &[4; 4]);
        assert_eq!(plan.counts.iter().sum::<u32>(), 16);
        // 12 extra rays over σ 0, 1, 2, 3: 0, 2, 4, 6.
        assert_eq!(plan.counts, [1, 3, 5, 7]);
        assert_eq!(plan.firsts, [4; 4]);
        assert_eq!(plan.pattern, 48);
    }

    /// A firefly takes at most `MAX_SHARE` times the mean, and the others
    /// share the rest; the total still adds up.
    #[test]
    fn one_noisy_pixel_takes_at_most_its_cap() {
        let mut own = vec![1e-4_f32; 8];
        own[3] = 1e6;
        let plan = SamplePlan::adaptive(4, 2, &own, &[4; 8]);
        assert_eq!(plan.counts[3], MAX_SHARE * 4);
        assert_eq!(plan.counts.iter().sum::<u32>(), 32);
        assert!(plan.counts.iter().all(|&n| n >= 1));
    }

    /// No noise anywhere (or one ray per pixel): a uniform pass.
    #[test]
    fn without_noise_the_pass_is_uniform() {
        assert_eq!(SamplePlan::adaptive(4, 2, &[0.0; 3], &[4; 3]).counts, [4; 3]);
        assert_eq!(SamplePlan::adaptive(1, 2, &[1.0; 3], &[1; 3]).counts, [1; 3]);
        let first = SamplePlan::uniform(3, 4, 2);
        assert_eq!((first.counts, first.firsts), (vec![4; 3], vec![0; 3]));
    }
}
