//! Light sampling for next-event estimation: pick a light, pick a point or
//! direction on it, and evaluate the density of any direction that a
//! BSDF-sampled ray happened to find on a light (needed for MIS).
//!
//! Strategy (pbrt-v4 §12.6 "Light Sampling" and §12.5 "Infinite Lights"):
//! - Every light, the environment included, is chosen at the shading point
//!   `x` in proportion to an estimate of the irradiance it can bring there
//!   ([`Reach::at`], docs/math.md §15.2; each light's file in
//!   `scene::emitter` says what its reach is): the importance of pbrt-v4's light
//!   BVH without its orientation bounds, evaluated for every light, so a
//!   sample costs a pass over the lights (one per emitting shape, few in
//!   the scenes seen). Choosing by power alone, as before, gave the studio
//!   scene's spot light 7 % of the samples where it outshines the others.
//! - On an area light a point is drawn uniformly by area with
//!   `Scene::sample_shape_area` and converted to solid angle,
//!   `p_ω = p_A · d² / |cos θ_l|`. Emitters radiate on their front side only
//!   (as in Mitsuba 3).
//! - A delta light has one direction to offer: the sample's `pdf` is the
//!   probability of choosing it and its `radiance` is what arrives, so that
//!   `radiance / pdf` is the light's contribution over that choice
//!   (`I f(θ)/d²` for point and spot lights, `E` for a directional light).
//! - A constant environment is sampled uniformly over the sphere; a lat-long
//!   map by its texel luminance (see [`super::environment_sampling`]).
//!
//! All densities returned are in solid angle at the shading point and already
//! include the probability of selecting the light.

use glam::DVec3;

use super::environment_sampling::{EnvironmentSampler, environment_mean_luminance};
use super::trace_stats::TraceStats;
use crate::color::Rgb;
use crate::scene::emitter::{LightSample, Reach};
use crate::scene::{Emitter, Scene, SurfaceHit};

impl LightSample {
    /// Whether nothing blocks this light from the surface point `x` with
    /// geometric normal `n` (the shadow ray starts offset along it): one
    /// shadow ray, counted in `stats`. The one place next-event estimation
    /// traces its shadow rays.
    pub fn visible_from(&self, scene: &Scene, x: DVec3, n: DVec3, stats: &mut TraceStats) -> bool {
        let shadow = match self.target {
            Some((p, pn)) => scene.spawn_ray_to(x, n, p, pn),
            None => scene.spawn_ray(x, n, self.wi),
        };
        stats.rays += 1;
        !scene.occluded(&shadow)
    }

    /// Whether the sample came from the environment (which a ray that
    /// escapes the scene also finds).
    pub fn is_environment(&self) -> bool {
        self.target.is_none() && !self.delta
    }
}

/// A light that can be chosen: an entry of `scene.emitters`, or the
/// environment.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Light {
    Emitter(usize),
    Environment,
}

/// Precomputed light-selection data for one scene.
#[derive(Clone, Debug)]
pub struct LightSampler {
    /// Every light that can bring light, with its reach: the emitters
    /// whose strength is positive and finite, then the environment.
    lights: Vec<(Light, Reach)>,
    /// Position in `lights` of each `scene.emitters` entry (`None` for dark ones).
    index: Vec<Option<usize>>,
    environment: Option<EnvironmentSampler>,
}

impl LightSampler {
    pub fn new(scene: &Scene) -> Self {
        let mut lights = Vec::new();
        let mut index = vec![None; scene.emitters.len()];
        for (i, emitter) in scene.emitters.iter().enumerate() {
            let reach = emitter.reach(scene);
            let strength = match reach {
                Reach::Surface { strength, .. } => strength,
                Reach::Point { intensity, .. } => intensity,
                Reach::Distant(e) => e,
            };
            if strength > 0.0 && strength.is_finite() {
                index[i] = Some(lights.len());
                lights.push((Light::Emitter(i), reach));
            }
        }
        let environment = scene.environment.as_ref().map(|env| {
            // A black map brings nothing and is never chosen.
            let irradiance = std::f64::consts::PI * environment_mean_luminance(env);
            if irradiance > 0.0 && irradiance.is_finite() {
                lights.push((Light::Environment, Reach::Distant(irradiance)));
            }
            EnvironmentSampler::new(env)
        });
        Self {
            lights,
            index,
            environment,
        }
    }

    /// The sum of the lights' reach at `x`.
    fn total_reach(&self, x: DVec3) -> f64 {
        self.lights.iter().map(|(_, r)| r.at(x)).sum()
    }

    /// Probability of choosing the `k`-th of `lights` at `x`.
    fn probability(&self, k: usize, x: DVec3) -> f64 {
        let total = self.total_reach(x);
        if total > 0.0 {
            self.lights[k].1.at(x) / total
        } else {
            0.0
        }
    }

    /// Chooses a light at `x` with `u ∈ [0, 1)`: its position in `lights`
    /// and probability.
    fn choose(&self, x: DVec3, u: f64) -> Option<(usize, f64)> {
        let total = self.total_reach(x);
        if !(total > 0.0 && total.is_finite()) {
            return None;
        }
        let target = u * total;
        let mut sum = 0.0;
        let mut last = None;
        for (k, (_, reach)) in self.lights.iter().enumerate() {
            let w = reach.at(x);
            if w <= 0.0 {
                continue;
            }
            sum += w;
            last = Some((k, w / total));
            if target < sum {
                break;
            }
        }
        last
    }

    /// Samples a light as seen from `x`. `u_select` chooses the light, `u`
    /// the point on it. `None` when the sample carries nothing (the back of
    /// an emitter faces `x`, or no light reaches `x`).
    pub fn sample(
        &self,
        scene: &Scene,
        x: DVec3,
        u_select: f64,
        u: [f64; 2],
    ) -> Option<LightSample> {
        let (k, p_select) = self.choose(x, u_select)?;
        let i = match self.lights[k].0 {
            Light::Environment => {
                let (sampler, env) = self.environment.as_ref().zip(scene.environment.as_ref())?;
                let (wi, radiance, pdf) = sampler.sample(env, u)?;
                return Some(LightSample {
                    wi,
                    radiance,
                    pdf: pdf * p_select,
                    target: None,
                    delta: false,
                });
            }
            Light::Emitter(i) => i,
        };
        scene.emitters[i].sample(scene, x, p_select, u)
    }

    /// Whether the scene has a light other than the environment (an
    /// emitting surface or a delta light) with positive power.
    pub fn has_finite_lights(&self) -> bool {
        self.lights
            .iter()
            .any(|(light, _)| matches!(light, Light::Emitter(_)))
    }

    /// Whether the scene has an environment to sample.
    pub fn has_environment(&self) -> bool {
        self.environment.is_some()
    }

    /// Solid-angle density with which [`LightSampler::sample`] would produce
    /// the direction of a ray from `x` that hit emitter surface `hit`.
    pub fn pdf_area_hit(&self, scene: &Scene, x: DVec3, hit: &SurfaceHit) -> f64 {
        let Some(k) = hit
            .emitter
            .and_then(|e| self.index.get(e).copied().flatten())
        else {
            return 0.0;
        };
        let d = hit.position - x;
        let dist2 = d.length_squared();
        let cos_light = hit.normal.dot(-d.normalize_or_zero());
        if cos_light <= 0.0 {
            return 0.0;
        }
        // Uniform area sampling: p_A = 1 / A (checked in the tests).
        let pdf_area = 1.0 / scene.shape_area(hit.shape);
        self.probability(k, x) * pdf_area * dist2 / cos_light
    }

    /// Solid-angle density with which [`LightSampler::sample`] at `x` would
    /// produce the environment in world direction `dir`.
    pub fn pdf_environment(&self, scene: &Scene, x: DVec3, dir: DVec3) -> f64 {
        let Some(k) = self
            .lights
            .iter()
            .position(|(l, _)| *l == Light::Environment)
        else {
            return 0.0;
        };
        match (&self.environment, &scene.environment) {
            (Some(sampler), Some(env)) => self.probability(k, x) * sampler.pdf(env, dir),
            _ => 0.0,
        }
    }
}

/// Radiance of the environment along world direction `dir` (zero without one).
pub fn environment_radiance(scene: &Scene, dir: DVec3) -> Rgb {
    scene
        .environment
        .as_ref()
        .map_or(Rgb::BLACK, |env| Rgb::from_array(env.radiance(dir)))
}

/// Radiance emitted by the surface at `hit` towards `-dir` (front side only).
pub fn emitted_radiance(scene: &Scene, hit: &SurfaceHit, dir: DVec3) -> Rgb {
    match hit.emitter.and_then(|e| scene.emitters.get(e)) {
        Some(Emitter::Area(area)) if hit.normal.dot(dir) < 0.0 => {
            Rgb::from_array(area.radiance.eval(hit.uv))
        }
        _ => Rgb::BLACK,
    }
}

#[cfg(test)]
mod tests;
