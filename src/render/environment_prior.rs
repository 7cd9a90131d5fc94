//! The environment prior mean: what the incident radiance would be if
//! nothing occluded the environment (docs/math.md §10.1, §10.4).
//!
//! The prior mean `m̄(ω)` is the scene environment's real spherical-harmonic
//! expansion up to band [`PRIOR_BANDS`]` − 1`, in the **world frame**. Two
//! properties make it a good prior for an estimator over the hemisphere of a
//! normal `n`:
//! - evaluated at a sample direction it costs `O(bands²)` and no ray;
//! - its Lambert integral `∫_H m̄(ω) (n·ω)/π dω` is exact in closed form for
//!   every normal by the Funk–Hecke theorem: each band `l` is scaled by the
//!   clamped-cosine coefficient `Â_l` (Ramamoorthi & Hanrahan 2001).
//!
//! Whatever the coefficients are (the projection of the map is numerical),
//! the prior mean is *this* expansion, so the estimate `∫ m̄ p + rule(Y − m̄)`
//! stays consistent; a better projection only makes the residual smaller.

use std::f64::consts::PI;

use glam::DVec3;

use crate::color::Rgb;
use crate::scene::Environment;

/// Number of spherical-harmonic bands (`l = 0..PRIOR_BANDS`). Eight bands
/// hold features down to about 180°/8 ≈ 22° (a broad sky gradient, a soft
/// window glow); sharper features (a sun) stay in the residual, which is
/// why such maps are sampled by light sampling instead (docs/math.md §14).
pub const PRIOR_BANDS: usize = 8;
const COEFFICIENTS: usize = PRIOR_BANDS * PRIOR_BANDS;

/// Longest side of the grid the map is averaged onto before projecting:
/// the projection costs one basis evaluation per grid cell, and bands below
/// eight need nothing finer.
const PROJECTION_GRID: usize = 256;

/// Which prior mean a hemisphere estimator subtracts from its values.
#[derive(
    Clone,
    Copy,
    Debug,
    Default,
    PartialEq,
    Eq,
    Hash,
    serde::Serialize,
    serde::Deserialize,
    clap::ValueEnum,
)]
#[serde(rename_all = "snake_case")]
pub enum PriorChoice {
    /// None: the estimator integrates the values as they are.
    #[default]
    None,
    /// The unoccluded environment ([`EnvironmentPrior`]), where the hemisphere
    /// integrand contains the environment seen directly.
    Environment,
}

/// The unoccluded-environment prior mean of one scene (module docs).
#[derive(Clone, Debug, PartialEq)]
pub struct EnvironmentPrior {
    /// `c[l² + l + m]`, per RGB channel, in W/(m²·sr).
    coefficients: Vec<Rgb>,
}

impl EnvironmentPrior {
    /// Projects `environment` onto the first [`PRIOR_BANDS`] bands.
    pub fn new(environment: &Environment) -> Self {
        let mut coefficients = vec![Rgb::BLACK; COEFFICIENTS];
        let mut basis = [0.0; COEFFICIENTS];
        match environment {
            Environment::Constant { radiance } => {
                // Only band 0: `Y₀₀ = 1/(2√π)`, so `c₀₀ = 4π L Y₀₀ = 2√π L`.
                coefficients[0] = Rgb::from_array(*radiance) * (2.0 * PI.sqrt());
            }
            Environment::Map(map) => {
                let (w, h) = (map.width(), map.height());
                if w == 0 || h == 0 {
                    return Self { coefficients };
                }
                // Average blocks of texels onto a grid of at most
                // PROJECTION_GRID columns; each grid cell is a lat-long cell
                // whose exact solid angle weighs its mean radiance.
                let (bx, by) = (w.div_ceil(PROJECTION_GRID), h.div_ceil(PROJECTION_GRID / 2));
                let (gw, gh) = (w.div_ceil(bx), h.div_ceil(by));
                for gy in 0..gh {
                    let (y0, y1) = (gy * by, ((gy + 1) * by).min(h));
                    let (v0, v1) = (y0 as f64 / h as f64, y1 as f64 / h as f64);
                    for gx in 0..gw {
                        let (x0, x1) = (gx * bx, ((gx + 1) * bx).min(w));
                        let (u0, u1) = (x0 as f64 / w as f64, x1 as f64 / w as f64);
                        let solid_angle =
                            2.0 * PI * (u1 - u0) * ((PI * v0).cos() - (PI * v1).cos());
                        // Texels in a row block cover nearly equal solid angles.
                        let mut sum = Rgb::BLACK;
                        for y in y0..y1 {
                            for x in x0..x1 {
                                sum += Rgb::from_array(map.texel(x, y));
                            }
                        }
                        let mean = sum * (1.0 / ((x1 - x0) * (y1 - y0)) as f64);
                        let dir = map.uv_to_direction(0.5 * (u0 + u1), 0.5 * (v0 + v1));
                        real_sh(dir, &mut basis);
                        for (c, y) in coefficients.iter_mut().zip(&basis) {
                            *c += mean * (y * solid_angle);
                        }
                    }
                }
            }
        }
        Self { coefficients }
    }

    /// `m̄(ω)`: the prior radiance seen looking towards world `dir` (unit).
    pub fn radiance(&self, dir: DVec3) -> Rgb {
        let mut basis = [0.0; COEFFICIENTS];
        real_sh(dir, &mut basis);
        self.coefficients
            .iter()
            .zip(&basis)
            .map(|(c, y)| *c * *y)
            .sum()
    }

    /// `∫_H m̄(ω) max(0, n·ω)/π dω` for world unit normal `n`, exactly
    /// (module docs); multiply by π for the prior's irradiance in W/m².
    pub fn lambert_integral(&self, n: DVec3) -> Rgb {
        let mut basis = [0.0; COEFFICIENTS];
        real_sh(n, &mut basis);
        let mut sum = Rgb::BLACK;
        for l in 0..PRIOR_BANDS {
            let a = clamped_cosine_coefficient(l);
            if a == 0.0 {
                continue;
            }
            let band = l * l..(l + 1) * (l + 1);
            for (c, y) in self.coefficients[band.clone()].iter().zip(&basis[band]) {
                sum += *c * (a * y);
            }
        }
        sum * (1.0 / PI)
    }
}

/// `Â_l`, with `∫_{S²} Y_lm(ω) max(0, n·ω) dω = Â_l Y_lm(n)`
/// (Funk–Hecke; docs/math.md §10.4): `π`, `2π/3`, zero for odd `l ≥ 3`, and
/// `2π (−1)^{l/2−1} / ((l+2)(l−1)) · l! / (2^l ((l/2)!)²)` for even `l ≥ 2`.
fn clamped_cosine_coefficient(l: usize) -> f64 {
    match l {
        0 => PI,
        1 => 2.0 * PI / 3.0,
        _ if l % 2 == 1 => 0.0,
        _ => {
            let half = l / 2;
            // l! / (2^l (l/2)!²) = C(l, l/2) / 2^l.
            let mut binomial = 1.0;
            for k in 0..half {
                binomial *= (l - k) as f64 / (k + 1) as f64;
            }
            let sign = if half % 2 == 1 { 1.0 } else { -1.0 };
            2.0 * PI * sign / ((l + 2) as f64 * (l - 1) as f64) * binomial / 2f64.powi(l as i32)
        }
    }
}

/// Orthonormal real spherical harmonics `Y_lm(d)` for `l < PRIOR_BANDS` at
/// unit `d`, index `l² + l + m`, polar axis +Z. Written in Cartesian form,
/// `Y_lm ∝ P̃_l^|m|(z) · Re/Im (x + iy)^|m|` with `P̃_l^m = P_l^m / sin^m θ`,
/// a polynomial in `z`, so no angle is computed and the poles are regular.
fn real_sh(d: DVec3, out: &mut [f64; COEFFICIENTS]) {
    let z = d.z;
    // (x + iy)^m, m = 0..bands.
    let mut re = [0.0; PRIOR_BANDS];
    let mut im = [0.0; PRIOR_BANDS];
    (re[0], im[0]) = (1.0, 0.0);
    for m in 1..PRIOR_BANDS {
        re[m] = re[m - 1] * d.x - im[m - 1] * d.y;
        im[m] = re[m - 1] * d.y + im[m - 1] * d.x;
    }
    let mut double_factorial = 1.0; // (2m − 1)!!
    for m in 0..PRIOR_BANDS {
        if m > 0 {
            double_factorial *= (2 * m - 1) as f64;
        }
        // P̃_m^m, then upwards in l by the three-term recurrence.
        let (mut p_prev, mut p) = (0.0, double_factorial);
        for l in m..PRIOR_BANDS {
            if l == m + 1 {
                (p_prev, p) = (p, z * (2 * m + 1) as f64 * p);
            } else if l > m + 1 {
                let next =
                    ((2 * l - 1) as f64 * z * p - (l + m - 1) as f64 * p_prev) / (l - m) as f64;
                (p_prev, p) = (p, next);
            }
            let norm = normalisation(l, m);
            if m == 0 {
                out[l * l + l] = norm * p;
            } else {
                out[l * l + l + m] = std::f64::consts::SQRT_2 * norm * p * re[m];
                out[l * l + l - m] = std::f64::consts::SQRT_2 * norm * p * im[m];
            }
        }
    }
}

/// `K_l^m = sqrt((2l+1)/(4π) · (l−m)!/(l+m)!)`.
fn normalisation(l: usize, m: usize) -> f64 {
    let ratio: f64 = (l - m + 1..=l + m).map(|k| 1.0 / k as f64).product();
    ((2 * l + 1) as f64 / (4.0 * PI) * ratio).sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::EnvironmentMap;
    use glam::DMat3;

    /// `count` uniform-area directions over the whole sphere (spherical
    /// Fibonacci, docs/math.md §5.1).
    fn sphere_points(count: usize) -> Vec<DVec3> {
        let golden = (1.0 + 5f64.sqrt()) / 2.0;
        (0..count)
            .map(|i| {
                let z = 1.0 - (2 * i + 1) as f64 / count as f64;
                let r = (1.0 - z * z).max(0.0).sqrt();
                let phi = 2.0 * PI * i as f64 / golden;
                DVec3::new(r * phi.cos(), r * phi.sin(), z)
            })
            .collect()
    }

    #[test]
    fn the_basis_is_orthonormal() {
        let points = sphere_points(40_000);
        let weight = 4.0 * PI / points.len() as f64;
        let mut gram = vec![0.0; COEFFICIENTS * COEFFICIENTS];
        let mut basis = [0.0; COEFFICIENTS];
        for d in &points {
            real_sh(*d, &mut basis);
            for i in 0..COEFFICIENTS {
                for j in 0..COEFFICIENTS {
                    gram[i * COEFFICIENTS + j] += weight * basis[i] * basis[j];
                }
            }
        }
        for i in 0..COEFFICIENTS {
            for j in 0..COEFFICIENTS {
                let expected = if i == j { 1.0 } else { 0.0 };
                let got = gram[i * COEFFICIENTS + j];
                assert!((got - expected).abs() < 2e-3, "<Y{i}, Y{j}> = {got}");
            }
        }
    }

    /// A smooth, coloured map (a broad glow and a gradient), rotated so its
    /// frame is not the world's.
    fn smooth_map() -> Environment {
        let (w, h) = (96, 48);
        let frame = EnvironmentMap::new(w, h, vec![[0.0; 3]; w * h], 1.0, DMat3::IDENTITY);
        let glow_at = DVec3::new(0.3, 0.5, -0.8).normalize();
        let mut texels = Vec::with_capacity(w * h);
        for y in 0..h {
            for x in 0..w {
                let d =
                    frame.uv_to_direction((x as f64 + 0.5) / w as f64, (y as f64 + 0.5) / h as f64);
                let glow = (2.0 * (d.dot(glow_at) - 1.0)).exp();
                texels.push([
                    (0.5 + glow) as f32,
                    (0.4 + 0.6 * glow) as f32,
                    (0.4 + 0.2 * d.y) as f32,
                ]);
            }
        }
        let rotation = DMat3::from_axis_angle(DVec3::new(1.0, 2.0, 0.5).normalize(), 0.7);
        Environment::Map(EnvironmentMap::new(w, h, texels, 1.5, rotation))
    }

    #[test]
    fn the_lambert_integral_of_the_prior_is_exact_for_any_normal() {
        // Funk–Hecke against brute-force quadrature of the prior itself.
        let prior = EnvironmentPrior::new(&smooth_map());
        let points = sphere_points(200_000);
        let weight = 4.0 * PI / points.len() as f64;
        let values: Vec<Rgb> = points.iter().map(|d| prior.radiance(*d)).collect();
        for n in [
            DVec3::Z,
            -DVec3::Z,
            DVec3::X,
            DVec3::new(0.3, -0.5, 0.8).normalize(),
            DVec3::new(-0.9, 0.1, -0.2).normalize(),
        ] {
            let brute: Rgb = points
                .iter()
                .zip(&values)
                .map(|(d, v)| *v * (weight * d.dot(n).max(0.0) / PI))
                .sum();
            let exact = prior.lambert_integral(n);
            for (b, e) in brute.to_array().iter().zip(exact.to_array()) {
                assert!((b - e).abs() < 2e-3 * e.abs().max(0.1), "{n}: {b} vs {e}");
            }
        }
    }

    #[test]
    fn a_smooth_map_is_reproduced_closely_and_a_constant_exactly() {
        let env = smooth_map();
        let prior = EnvironmentPrior::new(&env);
        let mut worst: f64 = 0.0;
        for d in sphere_points(2_000) {
            let truth = Rgb::from_array(env.radiance(d)).luminance();
            worst = worst.max((prior.radiance(d).luminance() - truth).abs() / truth);
        }
        assert!(worst < 0.08, "worst relative deviation {worst}");
        let constant = EnvironmentPrior::new(&Environment::Constant {
            radiance: [0.5, 1.0, 2.0],
        });
        let d = DVec3::new(0.2, -0.7, 0.3).normalize();
        assert!((constant.radiance(d).g - 1.0).abs() < 1e-12);
        assert!((constant.lambert_integral(d).b - 2.0).abs() < 1e-12);
    }

    #[test]
    fn clamped_cosine_coefficients_match_the_known_values() {
        assert!((clamped_cosine_coefficient(2) - PI / 4.0).abs() < 1e-15);
        assert!((clamped_cosine_coefficient(4) + PI / 24.0).abs() < 1e-15);
        assert!((clamped_cosine_coefficient(6) - PI / 64.0).abs() < 1e-15);
        assert_eq!(clamped_cosine_coefficient(5), 0.0);
    }
}
