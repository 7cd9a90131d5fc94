//! The film's reconstruction filter, Mitsuba 3's `rfilter`: how the
//! radiance around a pixel is weighted into its value. A pixel's value is
//! `∫ f(x − p) L(x) dx / ∫ f`, `p` its centre and `f(d) = f₁(d_x) f₁(d_y)`
//! separable, in pixel units. It is estimated by filter importance
//! sampling (Ernst, Stamminger & Greiner 2006, "Filter importance sampling";
//! docs/math.md §15.5): camera rays leave at offsets drawn from `f₁` itself,
//! so every sample has weight one and a pixel's samples stay its own (no
//! splatting into neighbours, which would correlate them and break a tile's
//! independence). Mitsuba splats instead; both estimate the same value.
//! Like Mitsuba's films (`sample_border` false), no sample leaves the
//! image: near its border a pixel's filter is cut at the image's edge.
//!
//! - `box`: `f₁ = 1` on `[−½, ½)`, the pixel's mean radiance.
//! - `gaussian`: `f₁(d) = max(0, e^(−d²/2σ²) − e^(−r²/2σ²))`, `r = 4σ`
//!   (Mitsuba's, σ = `stddev`, default 0.5 pixel).
//! - `tent`: `f₁(d) = max(0, 1 − |d|/r)` (Mitsuba's, `radius` default 1).

use std::f64::consts::{FRAC_1_SQRT_2, PI};

use super::error::SceneError;
use super::format::FilterDoc;
use crate::stats::solve_increasing;

/// Mitsuba's default `stddev` of a Gaussian filter, pixels.
pub const DEFAULT_STDDEV: f64 = 0.5;
/// Mitsuba's default `radius` of a tent filter, pixels.
pub const DEFAULT_TENT_RADIUS: f64 = 1.0;
/// Widest accepted filter support (radius), pixels: wider filters blur the
/// image into a few dozen pixels and are almost surely a mistake.
pub const MAX_RADIUS: f64 = 16.0;

/// A separable reconstruction filter (module docs).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub enum PixelFilter {
    #[default]
    Box,
    Gaussian {
        stddev: f64,
    },
    Tent {
        radius: f64,
    },
}

impl PixelFilter {
    /// The filter a scene's `filter` field describes; `field` names it in errors.
    pub(crate) fn from_doc(doc: &FilterDoc, field: &str) -> Result<Self, SceneError> {
        let width = |name: &str, value: f64, radius: f64| {
            if value > 0.0 && value.is_finite() && radius <= MAX_RADIUS {
                Ok(value)
            } else {
                Err(SceneError::invalid(
                    format!("{field}.{name}"),
                    format!(
                        "{value} is not a width in pixels with a support of at most {MAX_RADIUS}"
                    ),
                ))
            }
        };
        Ok(match *doc {
            FilterDoc::Box => PixelFilter::Box,
            FilterDoc::Gaussian { stddev } => {
                let stddev = stddev.unwrap_or(DEFAULT_STDDEV);
                PixelFilter::Gaussian {
                    stddev: width("stddev", stddev, 4.0 * stddev)?,
                }
            }
            FilterDoc::Tent { radius } => {
                let radius = radius.unwrap_or(DEFAULT_TENT_RADIUS);
                PixelFilter::Tent {
                    radius: width("radius", radius, radius)?,
                }
            }
        })
    }

    /// The position in an image of `size` pixels, in pixels, of a camera
    /// sample of pixel `(px, py)` drawn with `u ∈ [0, 1)²`: uniform over
    /// the pixel for a box (`px + u`, as before filters existed), else the
    /// pixel's centre plus offsets distributed as `f₁` along each axis, cut
    /// at the image's edges (module docs).
    pub fn position(&self, (px, py): (u32, u32), size: (u32, u32), u: [f64; 2]) -> (f64, f64) {
        let (x, y) = (f64::from(px), f64::from(py));
        match self {
            PixelFilter::Box => (x + u[0], y + u[1]),
            _ => (
                x + 0.5 + self.offset(u[0], x + 0.5, f64::from(size.0)),
                y + 0.5 + self.offset(u[1], y + 0.5, f64::from(size.1)),
            ),
        }
    }

    /// An offset from a pixel centred at `centre` on an axis of `size`
    /// pixels, distributed as `f₁` on its part inside the image: its CDF
    /// inverted at `u` taken into the CDF's range there.
    fn offset(&self, u: f64, centre: f64, size: f64) -> f64 {
        let profile = match *self {
            PixelFilter::Box => Profile::Box,
            PixelFilter::Tent { radius } => Profile::Tent(radius),
            PixelFilter::Gaussian { stddev } => Profile::Gaussian(Gaussian::new(stddev)),
        };
        let r = profile.radius();
        let (lo, hi) = ((-centre).max(-r), (size - centre).min(r));
        let (c_lo, c_hi) = (profile.cdf(lo), profile.cdf(hi));
        profile.inverse_cdf(c_lo + u * (c_hi - c_lo)).clamp(lo, hi)
    }
}

/// A filter's `f₁` with what its CDF needs, built once per offset.
enum Profile {
    Box,
    Tent(f64),
    Gaussian(Gaussian),
}

impl Profile {
    /// Half the filter's support, pixels.
    fn radius(&self) -> f64 {
        match self {
            Profile::Box => 0.5,
            Profile::Tent(radius) => *radius,
            Profile::Gaussian(g) => g.r,
        }
    }

    /// `∫ f₁` from `−r` to `d`, over its total: 0 at `−r`, 1 at `r`.
    fn cdf(&self, d: f64) -> f64 {
        match self {
            Profile::Box => (d + 0.5).clamp(0.0, 1.0),
            Profile::Tent(radius) => {
                let t = (d / radius).clamp(-1.0, 1.0);
                if t < 0.0 {
                    0.5 * (1.0 + t) * (1.0 + t)
                } else {
                    1.0 - 0.5 * (1.0 - t) * (1.0 - t)
                }
            }
            Profile::Gaussian(g) => g.integral(d) / g.total,
        }
    }

    /// The offset where [`Self::cdf`] is `t ∈ [0, 1]`.
    fn inverse_cdf(&self, t: f64) -> f64 {
        match self {
            Profile::Box => t - 0.5,
            Profile::Tent(radius) => {
                if t < 0.5 {
                    radius * ((2.0 * t).sqrt() - 1.0)
                } else {
                    radius * (1.0 - (2.0 * (1.0 - t)).sqrt())
                }
            }
            Profile::Gaussian(g) => g.inverse_cdf(t),
        }
    }
}

/// Mitsuba's truncated Gaussian of standard deviation `σ` (module docs):
/// `C(d) = σ√(π/2) (erf(d/σ√2) + erf(r/σ√2)) − b (d + r)`, the integral of
/// `f₁` from `−r`, with `b = e^(−r²/2σ²)` and `r = 4σ`.
struct Gaussian {
    stddev: f64,
    r: f64,
    bias: f64,
    total: f64,
}

impl Gaussian {
    fn new(stddev: f64) -> Self {
        let r = 4.0 * stddev;
        let mut g = Self {
            stddev,
            r,
            bias: (-8.0f64).exp(),
            total: 1.0,
        };
        g.total = g.integral(r);
        g
    }

    fn integral(&self, d: f64) -> f64 {
        let scale = FRAC_1_SQRT_2 / self.stddev;
        let d = d.clamp(-self.r, self.r);
        self.stddev * (0.5 * PI).sqrt() * (libm::erf(d * scale) + libm::erf(self.r * scale))
            - self.bias * (d + self.r)
    }

    /// The `d` where `C(d) = t C(r)`, by [`solve_increasing`] (`C` is
    /// increasing, its derivative the filter).
    fn inverse_cdf(&self, t: f64) -> f64 {
        solve_increasing(
            |d| self.integral(d),
            |d| ((-0.5 * (d / self.stddev).powi(2)).exp() - self.bias).max(0.0),
            t.clamp(0.0, 1.0) * self.total,
            (-self.r, self.r),
            (t - 0.5) * 2.0 * self.stddev,
            1e-15 * self.total,
        )
    }
}

#[cfg(test)]
mod tests {
    use rand::{RngExt, SeedableRng};
    use rand_pcg::Pcg64;

    use super::*;
    use crate::optics::chi_square::ChiSquare;

    /// `∫ f₁` over `[a, b]` by the midpoint rule.
    fn mass(f: &dyn Fn(f64) -> f64, a: f64, b: f64) -> f64 {
        let n = 200;
        let h = (b - a) / n as f64;
        (0..n).map(|i| f(a + (i as f64 + 0.5) * h)).sum::<f64>() * h
    }

    #[test]
    fn offsets_follow_each_filter() {
        const BINS: usize = 40;
        const SAMPLES: usize = 200_000;
        // Each filter's f₁ (module docs), written out again.
        let density = |filter: &PixelFilter, d: f64| match *filter {
            PixelFilter::Gaussian { stddev } => {
                ((-0.5 * (d / stddev).powi(2)).exp() - (-8.0f64).exp()).max(0.0)
            }
            PixelFilter::Tent { radius } => (1.0 - d.abs() / radius).max(0.0),
            PixelFilter::Box => 1.0,
        };
        let cases = [
            (PixelFilter::Gaussian { stddev: 0.5 }, 2.0),
            (PixelFilter::Gaussian { stddev: 1.3 }, 5.2),
            (PixelFilter::Tent { radius: 1.0 }, 1.0),
            (PixelFilter::Tent { radius: 2.5 }, 2.5),
        ];
        let mut rng = Pcg64::seed_from_u64(7);
        for (filter, radius) in &cases {
            let f = |d: f64| density(filter, d);
            let mut counts = vec![0.0; BINS];
            for _ in 0..SAMPLES {
                let d = filter.offset(rng.random(), 1000.0, 2000.0);
                assert!(d.abs() <= *radius, "{filter:?}: {d}");
                let bin = ((d + radius) / (2.0 * radius) * BINS as f64) as usize;
                counts[bin.min(BINS - 1)] += 1.0;
            }
            let total = mass(&f, -radius, *radius);
            let expected: Vec<f64> = (0..BINS)
                .map(|i| {
                    let a = -radius + 2.0 * radius * i as f64 / BINS as f64;
                    let b = a + 2.0 * radius / BINS as f64;
                    SAMPLES as f64 * mass(&f, a, b) / total
                })
                .collect();
            let test = ChiSquare::of(&counts, &expected);
            assert!(test.passes(), "{filter:?}: {test}");
        }
    }

    #[test]
    fn a_box_keeps_uniform_positions_in_the_pixel_and_others_centre_on_it() {
        let size = (64, 48);
        assert_eq!(
            PixelFilter::Box.position((3, 7), size, [0.25, 0.75]),
            (3.25, 7.75)
        );
        let g = PixelFilter::Gaussian { stddev: 0.5 };
        let (x, y) = g.position((3, 7), size, [0.5, 0.5]);
        assert!(
            (x - 3.5).abs() < 1e-12 && (y - 7.5).abs() < 1e-12,
            "{x} {y}"
        );
        let t = PixelFilter::Tent { radius: 1.0 };
        let (x, y) = t.position((5, 5), size, [0.0, 0.5]);
        assert!(
            (x - 4.5).abs() < 1e-12 && (y - 5.5).abs() < 1e-12,
            "{x} {y}"
        );
    }

    #[test]
    fn samples_stay_in_the_image_with_the_filter_cut_at_its_edge() {
        // Pixel 0 of a tent of radius 1: the offset's density on [−½, 1]
        // is the tent's, renormalised there.
        let t = PixelFilter::Tent { radius: 1.0 };
        let mut rng = Pcg64::seed_from_u64(9);
        let (mut inside_left, n) = (0, 100_000);
        for _ in 0..n {
            let (x, y) = t.position((0, 2), (4, 4), [rng.random(), rng.random()]);
            assert!(
                (0.0..=4.0).contains(&x) && (0.0..=4.0).contains(&y),
                "{x} {y}"
            );
            inside_left += usize::from(x < 0.5);
        }
        // Mass of the tent on [−½, 0] over its mass on [−½, 1]: 3/8 / 7/8.
        let share = inside_left as f64 / n as f64;
        assert!((share - 3.0 / 7.0).abs() < 0.01, "{share}");
        let g = PixelFilter::Gaussian { stddev: 1.0 };
        for u in [0.0, 0.3, 0.999_999] {
            let (x, _) = g.position((63, 0), (64, 64), [u, 0.5]);
            assert!((0.0..=64.0).contains(&x), "{u}: {x}");
        }
    }

    #[test]
    fn widths_are_checked_and_named() {
        let bad = [
            FilterDoc::Gaussian { stddev: Some(0.0) },
            FilterDoc::Gaussian { stddev: Some(5.0) },
            FilterDoc::Tent {
                radius: Some(f64::NAN),
            },
        ];
        for doc in bad {
            let e = PixelFilter::from_doc(&doc, "camera.filter").unwrap_err();
            assert!(e.to_string().contains("camera.filter."), "{e}");
        }
        let doc = FilterDoc::Gaussian { stddev: None };
        assert_eq!(
            PixelFilter::from_doc(&doc, "f").unwrap(),
            PixelFilter::Gaussian { stddev: 0.5 }
        );
    }
}
