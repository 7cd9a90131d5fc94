//! Light sampling for next-event estimation: pick a light, pick a point or
//! direction on it, and evaluate the density of any direction that a
//! BSDF-sampled ray happened to find on a light (needed for MIS).
//!
//! Strategy (pbrt-v4 §12.6 "Light Sampling" and §12.5 "Infinite Lights"):
//! - Area emitters and delta lights are chosen together in proportion to
//!   their power: `π A lum(L_e)` for an area light, `4π lum(I)` for a point
//!   light, `2π (1 − cos θ_m) lum(I)` for a spot light (`θ_m` halfway between
//!   its beam width and cutoff angle), `π R² lum(E)` for a directional light
//!   (`R` the scene's bounding radius: the power crossing the scene).
//! - On an area light a point is drawn uniformly by area with
//!   `Scene::sample_shape_area` and converted to solid angle,
//!   `p_ω = p_A · d² / |cos θ_l|`. Emitters radiate on their front side only
//!   (as in Mitsuba 3).
//! - A delta light has one direction to offer: the sample's `pdf` is the
//!   probability of choosing it and its `radiance` is what arrives, so that
//!   `radiance / pdf` is the light's contribution over that choice
//!   (`I f(θ)/d²` for point and spot lights, `E` for a directional light).
//! - The environment, when present, is one more light. Its power cannot be
//!   compared with finite emitters without a scene radius, so it gets a fixed
//!   selection probability of ½ when area emitters exist (1 otherwise).
//! - A constant environment is sampled uniformly over the sphere; a lat-long
//!   map by its texel luminance (see [`super::environment_sampling`]).
//!
//! All densities returned are in solid angle at the shading point and already
//! include the probability of selecting the light.

use glam::DVec3;

use super::distribution::Distribution1D;
use super::environment_sampling::EnvironmentSampler;
use super::rgb::Rgb;
use super::trace_stats::TraceStats;
use crate::scene::{Emitter, Scene, SurfaceHit};

/// Probability of choosing the environment when both kinds of light exist.
const ENVIRONMENT_SELECTION: f64 = 0.5;

/// A direction towards a light with what it carries.
#[derive(Clone, Copy, Debug)]
pub struct LightSample {
    /// Unit world direction from the shading point towards the light.
    pub wi: DVec3,
    /// Emitted radiance arriving along `-wi` if nothing is in between, W/(m²·sr).
    pub radiance: Rgb,
    /// Solid-angle density including light selection, sr⁻¹.
    pub pdf: f64,
    /// The light's point (with its surface normal on an area light), for
    /// the shadow ray; `None` for light from infinitely far (the environment,
    /// a directional light), whose shadow ray is unbounded.
    pub target: Option<(DVec3, Option<DVec3>)>,
    /// Whether the light is a Dirac delta (point, spot, directional): no
    /// BSDF-sampled ray can find it, so it needs no MIS weight.
    pub delta: bool,
}

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

/// Mitsuba 3's spot falloff for a direction at angle `theta` from the
/// axis: 1 within `beam_width`, linear in angle down to 0 at `cutoff_angle`.
pub fn spot_falloff(theta: f64, cutoff_angle: f64, beam_width: f64) -> f64 {
    if theta >= cutoff_angle {
        0.0
    } else if theta <= beam_width {
        1.0
    } else {
        (cutoff_angle - theta) / (cutoff_angle - beam_width)
    }
}

/// The power by which a light is chosen (module docs); `radius` is the
/// scene's bounding radius.
fn selection_power(scene: &Scene, emitter: &Emitter, radius: f64) -> f64 {
    use std::f64::consts::{PI, TAU};
    let lum = |c: &[f64; 3]| Rgb::from_array(*c).luminance();
    match emitter {
        Emitter::Area { shape, radiance } => PI * scene.shape_area(*shape) * lum(&radiance.mean()),
        Emitter::Point { intensity, .. } => 2.0 * TAU * lum(intensity),
        Emitter::Spot {
            intensity,
            cutoff_angle,
            beam_width,
            ..
        } => TAU * (1.0 - (0.5 * (cutoff_angle + beam_width)).cos()) * lum(intensity),
        Emitter::Directional { irradiance, .. } => PI * radius * radius * lum(irradiance),
    }
}

/// Precomputed light-selection tables for one scene.
#[derive(Clone, Debug)]
pub struct LightSampler {
    /// Indices into `scene.emitters` of emitters with positive power.
    emitters: Vec<usize>,
    /// Selection among `emitters` by power.
    distribution: Option<Distribution1D>,
    /// Selection probability of each `scene.emitters` entry (0 for dark ones),
    /// conditional on choosing an emitter rather than the environment.
    probability: Vec<f64>,
    environment: Option<EnvironmentSampler>,
    /// Probability of sampling the environment rather than an area emitter.
    environment_probability: f64,
}

impl LightSampler {
    pub fn new(scene: &Scene) -> Self {
        let (lo, hi) = scene.bounds();
        let radius = if lo.is_finite() && hi.is_finite() {
            0.5 * (hi - lo).length()
        } else {
            0.0
        };
        let mut emitters = Vec::new();
        let mut powers = Vec::new();
        for (i, emitter) in scene.emitters.iter().enumerate() {
            let power = selection_power(scene, emitter, radius);
            if power > 0.0 && power.is_finite() {
                emitters.push(i);
                powers.push(power);
            }
        }
        let distribution = (!powers.is_empty()).then(|| Distribution1D::new(&powers));
        let mut probability = vec![0.0; scene.emitters.len()];
        if let Some(d) = &distribution {
            for (k, &i) in emitters.iter().enumerate() {
                probability[i] = d.probability(k);
            }
        }
        let environment = scene.environment.as_ref().map(EnvironmentSampler::new);
        let environment_probability = match (&environment, &distribution) {
            (None, _) => 0.0,
            (Some(_), None) => 1.0,
            (Some(_), Some(_)) => ENVIRONMENT_SELECTION,
        };
        Self {
            emitters,
            distribution,
            probability,
            environment,
            environment_probability,
        }
    }

    /// Samples a light as seen from `x`. `u_select` chooses the light, `u`
    /// the point on it. `None` when the sample carries nothing (the back of
    /// an emitter faces `x`, or the scene has no light).
    pub fn sample(
        &self,
        scene: &Scene,
        x: DVec3,
        u_select: f64,
        u: [f64; 2],
    ) -> Option<LightSample> {
        let pe = self.environment_probability;
        if u_select < pe {
            let (sampler, env) = self.environment.as_ref().zip(scene.environment.as_ref())?;
            let (wi, radiance, pdf) = sampler.sample(env, u)?;
            return Some(LightSample {
                wi,
                radiance,
                pdf: pdf * pe,
                target: None,
                delta: false,
            });
        }
        let dist = self.distribution.as_ref()?;
        let (k, p_select, _) = dist.sample_discrete(((u_select - pe) / (1.0 - pe)).min(1.0));
        let p_select = (1.0 - pe) * p_select;
        let point_light = |position: &[f64; 3], intensity: Rgb| {
            let p = DVec3::from_array(*position);
            let d = p - x;
            let dist2 = d.length_squared();
            (dist2 > 0.0).then(|| LightSample {
                wi: d / dist2.sqrt(),
                radiance: intensity * (1.0 / dist2),
                pdf: p_select,
                target: Some((p, None)),
                delta: true,
            })
        };
        match &scene.emitters[self.emitters[k]] {
            Emitter::Area { shape, radiance } => {
                let (point, normal, pdf_area, uv) = scene.sample_shape_area_uv(*shape, u);
                let d = point - x;
                let dist2 = d.length_squared();
                if dist2 <= 0.0 || pdf_area <= 0.0 {
                    return None;
                }
                let wi = d / dist2.sqrt();
                let cos_light = -normal.dot(wi);
                if cos_light <= 0.0 {
                    return None;
                }
                Some(LightSample {
                    wi,
                    radiance: Rgb::from_array(radiance.eval(uv)),
                    pdf: p_select * pdf_area * dist2 / cos_light,
                    target: Some((point, Some(normal))),
                    delta: false,
                })
            }
            Emitter::Point {
                position,
                intensity,
            } => point_light(position, Rgb::from_array(*intensity)),
            Emitter::Spot {
                position,
                direction,
                intensity,
                cutoff_angle,
                beam_width,
            } => {
                let axis = DVec3::from_array(*direction);
                let towards_x = (x - DVec3::from_array(*position)).normalize_or_zero();
                let theta = axis.dot(towards_x).clamp(-1.0, 1.0).acos();
                let falloff = spot_falloff(theta, *cutoff_angle, *beam_width);
                if falloff <= 0.0 {
                    return None;
                }
                point_light(position, Rgb::from_array(*intensity) * falloff)
            }
            Emitter::Directional {
                direction,
                irradiance,
            } => Some(LightSample {
                wi: -DVec3::from_array(*direction),
                radiance: Rgb::from_array(*irradiance),
                pdf: p_select,
                target: None,
                delta: true,
            }),
        }
    }

    /// Whether the scene has a light other than the environment (an
    /// emitting surface or a delta light) with positive power.
    pub fn has_finite_lights(&self) -> bool {
        self.distribution.is_some()
    }

    /// Whether the scene has an environment to sample.
    pub fn has_environment(&self) -> bool {
        self.environment.is_some()
    }

    /// Solid-angle density with which [`LightSampler::sample`] would produce
    /// the direction of a ray from `x` that hit emitter surface `hit`.
    pub fn pdf_area_hit(&self, scene: &Scene, x: DVec3, hit: &SurfaceHit) -> f64 {
        let Some(emitter) = hit.emitter else {
            return 0.0;
        };
        let p_select = self.probability.get(emitter).copied().unwrap_or(0.0);
        if p_select == 0.0 {
            return 0.0;
        }
        let d = hit.position - x;
        let dist2 = d.length_squared();
        let cos_light = hit.normal.dot(-d.normalize_or_zero());
        if cos_light <= 0.0 {
            return 0.0;
        }
        // Uniform area sampling: p_A = 1 / A (checked in the tests).
        let pdf_area = 1.0 / scene.shape_area(hit.shape);
        (1.0 - self.environment_probability) * p_select * pdf_area * dist2 / cos_light
    }

    /// Solid-angle density of sampling the environment in world direction `dir`.
    pub fn pdf_environment(&self, scene: &Scene, dir: DVec3) -> f64 {
        match (&self.environment, &scene.environment) {
            (Some(sampler), Some(env)) => self.environment_probability * sampler.pdf(env, dir),
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
        Some(Emitter::Area { radiance, .. }) if hit.normal.dot(dir) < 0.0 => {
            Rgb::from_array(radiance.eval(hit.uv))
        }
        _ => Rgb::BLACK,
    }
}

#[cfg(test)]
mod tests;
