//! The variance a tile reports for each pixel's value: its own rays' sample
//! variance pooled with its neighbours', plus what its rays share
//! (docs/math.md §16.4).

use super::mean::MeanEstimate;

/// Per pixel of a tile, mean over RGB ((W/(m²·sr))²): the variance its
/// image reports, and the part of it that the pixel's rays share.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct PixelVariances {
    /// The larger of the pixel's own noise (its variance of the mean less
    /// the shared part) and the mean over its 3×3 neighbourhood within the
    /// tile of the neighbours' per-ray variance (own noise × rays) divided
    /// by its own rays, plus [`Self::shared`].
    pub variance: Vec<f32>,
    /// [`MeanEstimate::shared`]: the records' error, which more rays or
    /// passes over the same records do not lower (docs/math.md §16.3).
    pub shared: Vec<f32>,
}

impl PixelVariances {
    /// The variances of a `width`-pixel-wide tile whose estimates are
    /// `pixels` in row order.
    ///
    /// Why pool: a pixel's sample variance over `K` rays has `K − 1`
    /// degrees of freedom, so with few rays it is often far too small (with
    /// `K = 2`, ±2 of it covers 70 % of errors, a Student t with one degree
    /// of freedom); the neighbourhood's mean has about nine times the
    /// degrees of freedom, and the larger of the two keeps a pixel noisier
    /// than its neighbours (an edge, a highlight) from being under-reported
    /// (docs/math.md §16.4). Only pixels of the tile pool, so a tile's
    /// output depends on the tile alone.
    pub fn of_tile(width: usize, pixels: &[MeanEstimate]) -> Self {
        let mean_rgb = |v: crate::color::Rgb| (v.r + v.g + v.b) / 3.0;
        let own: Vec<f64> = pixels
            .iter()
            .map(|e| mean_rgb(e.variance_of_mean - e.shared).max(0.0))
            .collect();
        let shared: Vec<f64> = pixels.iter().map(|e| mean_rgb(e.shared)).collect();
        // Pixels of one pass may take different numbers of rays (an
        // adaptive pass), so neighbours pool their per-ray variances.
        let rays: Vec<f64> = pixels.iter().map(|e| e.count.max(1) as f64).collect();
        let height = pixels.len().checked_div(width).unwrap_or(0);
        let variance = (0..pixels.len())
            .map(|i| {
                let (x, y) = (i % width, i / width);
                let (mut sum, mut count) = (0.0, 0.0);
                for ny in y.saturating_sub(1)..=(y + 1).min(height - 1) {
                    for nx in x.saturating_sub(1)..=(x + 1).min(width - 1) {
                        let q = ny * width + nx;
                        sum += own[q] * rays[q];
                        count += 1.0;
                    }
                }
                (own[i].max(sum / count / rays[i]) + shared[i]) as f32
            })
            .collect();
        Self {
            variance,
            shared: shared.into_iter().map(|s| s as f32).collect(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::color::Rgb;

    fn estimate(own: f64, shared: f64) -> MeanEstimate {
        MeanEstimate {
            mean: Rgb::BLACK,
            variance_of_mean: Rgb::splat(own + shared),
            shared: Rgb::splat(shared),
            count: 2,
        }
    }

    /// A 3×2 tile: the corner pools over its 4 neighbours in the tile, a
    /// pixel noisier than its neighbourhood keeps its own, and the shared
    /// part is added after pooling, never pooled.
    #[test]
    fn pixels_take_the_larger_of_their_own_and_their_neighbourhoods_noise() {
        let pixels = [
            estimate(0.0, 0.0),
            estimate(6.0, 1.0),
            estimate(0.0, 0.0),
            estimate(2.0, 0.0),
            estimate(0.0, 5.0),
            estimate(4.0, 0.0),
        ];
        let PixelVariances {
            variance: v,
            shared,
        } = PixelVariances::of_tile(3, &pixels);
        // Pixel (0, 0): mean of 0, 6, 2, 0 over its 4 neighbours in the tile.
        assert_eq!(v[0], 2.0);
        // Pixel (1, 0): its own 6 beats the mean of all six, 2; plus its 1 shared.
        assert_eq!(v[1], 7.0);
        // Pixel (1, 1): the neighbourhood's 2 plus its own 5 shared.
        assert_eq!(v[4], 7.0);
        // Pixel (2, 1): own 4 beats (6 + 0 + 0 + 4) / 4.
        assert_eq!(v[5], 4.0);
        assert_eq!(shared, [0.0, 1.0, 0.0, 0.0, 5.0, 0.0]);
        // A pixel of one ray (own 8) beside one of four (own 1): per-ray
        // variances 8 and 4 pool to 6, which is 6 for the first (its own 8
        // is larger) and 6 / 4 = 1.5 for the second.
        let pair = [
            MeanEstimate {
                count: 1,
                ..estimate(8.0, 0.0)
            },
            MeanEstimate {
                count: 4,
                ..estimate(1.0, 0.0)
            },
        ];
        assert_eq!(PixelVariances::of_tile(2, &pair).variance, [8.0, 1.5]);
        assert_eq!(PixelVariances::of_tile(3, &[]), PixelVariances::default());
    }

    /// Two rays per pixel of a uniform noise field: ±2 standard errors of
    /// the pooled variance cover close to the normal 95 %, where the
    /// pixels' own variances cover about 70 %.
    #[test]
    fn pooling_restores_the_coverage_of_two_ray_pixels() {
        use rand::SeedableRng;
        let mut rng = rand_pcg::Pcg64::seed_from_u64(7);
        let (width, height) = (64, 64);
        let normal = crate::testing::standard_normal::<rand_pcg::Pcg64>;
        let pixels: Vec<MeanEstimate> = (0..width * height)
            .map(|_| MeanEstimate::of((0..2).map(|_| Rgb::splat(normal(&mut rng)))))
            .collect();
        let coverage = |variances: &[f64]| {
            let within = pixels
                .iter()
                .zip(variances)
                .filter(|(e, v)| e.mean.r.abs() <= 2.0 * v.sqrt())
                .count();
            within as f64 / pixels.len() as f64
        };
        let own: Vec<f64> = pixels.iter().map(|e| e.variance_of_mean.r).collect();
        let pooled: Vec<f64> = PixelVariances::of_tile(width, &pixels)
            .variance
            .into_iter()
            .map(f64::from)
            .collect();
        let (own, pooled) = (coverage(&own), coverage(&pooled));
        assert!((0.65..0.76).contains(&own), "own {own}");
        assert!((0.92..0.99).contains(&pooled), "pooled {pooled}");
    }
}
