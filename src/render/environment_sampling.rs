//! Importance sampling of environment lighting.
//!
//! A lat-long map is sampled texel by texel in proportion to
//! `lum(texel) · sin θ` (the solid angle a texel row covers), then uniformly
//! within the texel; the density converts from the map's `(u, v)` square to
//! solid angle with the lat-long Jacobian `dω = 2π² sin θ du dv`, `θ = π v`
//! (pbrt-v4 §12.5.3; Pharr & Humphreys 2004). A small floor keeps the density
//! positive wherever a filtered lookup could return light next to a black
//! texel, so no radiance is ever unreachable.
//!
//! A constant environment is sampled uniformly over the sphere.

use std::f64::consts::PI;

use glam::DVec3;

use super::distribution::Distribution2D;
use super::rgb::Rgb;
use super::warp;
use crate::scene::{Environment, EnvironmentMap};

/// Fraction of the mean texel weight added to every texel's weight.
const DENSITY_FLOOR: f64 = 0.01;

/// Sampling tables for one scene environment; the environment itself stays
/// in the scene and is passed to every call.
///
/// Invariant: `distribution` is `Some` exactly when built from a non-empty map.
#[derive(Clone, Debug)]
pub struct EnvironmentSampler {
    distribution: Option<Distribution2D>,
}

impl EnvironmentSampler {
    pub fn new(environment: &Environment) -> Self {
        let distribution = match environment {
            Environment::Constant { .. } => None,
            // An empty map cannot be tabulated; uniform sampling still works.
            Environment::Map(map) if map.width() > 0 && map.height() > 0 => {
                Some(map_distribution(map))
            }
            Environment::Map(_) => None,
        };
        Self { distribution }
    }

    /// `(world direction, radiance, solid-angle density)`.
    pub fn sample(&self, environment: &Environment, u: [f64; 2]) -> Option<(DVec3, Rgb, f64)> {
        match (environment, &self.distribution) {
            (Environment::Map(map), Some(distribution)) => {
                let ((su, sv), pdf_uv) = distribution.sample(u);
                let sin_theta = (PI * sv).sin();
                if pdf_uv <= 0.0 || sin_theta <= 0.0 {
                    return None;
                }
                let dir = map.uv_to_direction(su, sv);
                let pdf = pdf_uv / (2.0 * PI * PI * sin_theta);
                Some((dir, Rgb::from_array(map.radiance(dir)), pdf))
            }
            _ => {
                let dir = warp::uniform_sphere(u);
                let radiance = Rgb::from_array(environment.radiance(dir));
                Some((dir, radiance, warp::UNIFORM_SPHERE_PDF))
            }
        }
    }

    /// Solid-angle density of [`EnvironmentSampler::sample`] at world `dir`.
    pub fn pdf(&self, environment: &Environment, dir: DVec3) -> f64 {
        match (environment, &self.distribution) {
            (Environment::Map(map), Some(distribution)) => {
                let (u, v) = map.direction_to_uv(dir);
                let sin_theta = (PI * v).sin();
                if sin_theta <= 0.0 {
                    return 0.0;
                }
                distribution.pdf(u, v) / (2.0 * PI * PI * sin_theta)
            }
            _ => warp::UNIFORM_SPHERE_PDF,
        }
    }
}

/// `Var L / (E L)²` of the environment's luminance over the sphere (uniform
/// solid-angle measure): the relative variance of a one-sample estimate of
/// its mean radiance by uniform directions. Zero for a constant environment;
/// a sun of a few degrees makes it hundreds or more.
pub fn environment_relative_variance(environment: &Environment) -> f64 {
    let Environment::Map(map) = environment else {
        return 0.0;
    };
    let (w, h) = (map.width(), map.height());
    let (mut total, mut mean, mut square) = (0.0, 0.0, 0.0);
    for y in 0..h {
        // Solid angle of a texel in row y, up to the constant 2π²/(w h).
        let weight = (PI * (y as f64 + 0.5) / h as f64).sin();
        for x in 0..w {
            let lum = Rgb::from_array(map.texel(x, y)).luminance();
            total += weight;
            mean += weight * lum;
            square += weight * lum * lum;
        }
    }
    if total <= 0.0 || mean <= 0.0 {
        return 0.0;
    }
    let (mean, square) = (mean / total, square / total);
    (square / (mean * mean) - 1.0).max(0.0)
}

/// Texel weights `lum · sin θ` plus the floor, as a 2-D distribution over `(u, v)`.
fn map_distribution(map: &EnvironmentMap) -> Distribution2D {
    let (w, h) = (map.width(), map.height());
    let row_sin = |y: usize| (PI * (y as f64 + 0.5) / h as f64).sin();
    let mut weights = Vec::with_capacity(w * h);
    for y in 0..h {
        for x in 0..w {
            let lum = Rgb::from_array(map.texel(x, y)).luminance();
            weights.push(lum.max(0.0) * row_sin(y));
        }
    }
    let mean = weights.iter().sum::<f64>() / weights.len().max(1) as f64;
    let floor = DENSITY_FLOOR * mean.max(f64::MIN_POSITIVE);
    for (i, weight) in weights.iter_mut().enumerate() {
        *weight += floor * row_sin(i / w);
    }
    Distribution2D::new(&weights, w, h)
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DMat3;

    /// A 16 × 8 map with one bright texel and a rotation, so the density is
    /// far from uniform and the map's pole is not the world's.
    fn sky() -> Environment {
        let (w, h) = (16, 8);
        let texels = (0..w * h)
            .map(|i| {
                if i == 2 * w + 5 {
                    [50.0, 40.0, 30.0]
                } else {
                    [0.2, 0.3, (i % 3) as f32]
                }
            })
            .collect();
        let rotation = DMat3::from_axis_angle(DVec3::new(1.0, 2.0, 0.5).normalize(), 0.7);
        Environment::Map(EnvironmentMap::new(w, h, texels, 1.5, rotation))
    }

    #[test]
    fn map_density_integrates_to_one_over_the_sphere() {
        let env = sky();
        let sampler = EnvironmentSampler::new(&env);
        let total = warp::integrate_directions(|w| sampler.pdf(&env, w), -1.0, 1000, 1000);
        assert!((total - 1.0).abs() < 2e-3, "{total}");
    }

    #[test]
    fn samples_carry_their_own_density_and_favour_the_bright_texel() {
        let env = sky();
        let sampler = EnvironmentSampler::new(&env);
        let Environment::Map(map) = &env else {
            unreachable!()
        };
        let n = 64;
        let mut bright = 0;
        for i in 0..n {
            for j in 0..n {
                let u = [(i as f64 + 0.5) / n as f64, (j as f64 + 0.5) / n as f64];
                let (dir, radiance, pdf) = sampler.sample(&env, u).expect("map has light");
                assert!((dir.length() - 1.0).abs() < 1e-12);
                assert!((pdf - sampler.pdf(&env, dir)).abs() < 1e-9 * pdf, "{pdf}");
                assert_eq!(radiance, Rgb::from_array(map.radiance(dir)));
                bright += usize::from(radiance.r > 10.0);
            }
        }
        // One texel of 128 holds most of the luminance.
        assert!(bright > n * n / 2, "{bright}");
    }

    #[test]
    fn constant_environment_is_sampled_uniformly() {
        let env = Environment::Constant {
            radiance: [1.0, 2.0, 3.0],
        };
        let sampler = EnvironmentSampler::new(&env);
        let (dir, radiance, pdf) = sampler.sample(&env, [0.3, 0.9]).expect("sample");
        assert_eq!(radiance, Rgb::new(1.0, 2.0, 3.0));
        assert_eq!(pdf, warp::UNIFORM_SPHERE_PDF);
        assert_eq!(sampler.pdf(&env, dir), pdf);
    }
}
