//! Irradiance at points, `E(x, n) = ∫_H L_i(x, ω) cos θ dω` (docs/math.md §1),
//! in W/m² per RGB channel.
//!
//! Two decompositions, both unbiased:
//! - [`IrradianceMethod::Hemisphere`]: every path length `1..=max_depth`
//!   through the hemisphere estimator. With cosine-weighted directions
//!   (`p = cos θ / π`) the Monte Carlo estimate is `E ≈ π · mean(L_i(ω_k))`.
//! - [`IrradianceMethod::Split`]: direct light (path length 1) by light
//!   sampling alone, `E_d ≈ mean(L_e cos θ / p_light)`, plus the rest
//!   (lengths `2..=max_depth`, [`PathLengths::Indirect`]) through the
//!   hemisphere estimator. Each path length is estimated by exactly one of
//!   the two parts, so nothing is counted twice; the hemisphere integrand no
//!   longer contains the light source's sharp edges, which is what makes it
//!   smooth enough for Bayesian quadrature.
//!
//! The hemisphere part is open to other estimators:
//! [`Transport::hemisphere_samples`] takes local-frame directions from the
//! caller and returns the radiance along each, so a BMC/QMC estimator can
//! choose the directions and combine the values with its own weights
//! (`E = π · Σ w_k L_k` for weights integrating `cos θ / π`).
//!
//! Reproducibility: point `i` draws all its random numbers from
//! [`point_rng`]`(seed, i)`, so results do not depend on the thread count.

use glam::DVec3;
use rand::{Rng, RngExt};
use rayon::prelude::*;

use super::cancel::Cancel;
use super::environment_prior::{EnvironmentPrior, PriorChoice};
use super::error::RenderError;
use super::lights::environment_radiance;
use super::mean::{MeanEstimate, StrataVariance};
use super::path::{
    AveragedPaths, FirstSegment, PathLengths, PathLimits, RadianceSample, TraceStats,
    power_heuristic,
};
use super::query::QueryPoint;
use super::seed::point_rng;
use super::strata::SharedStrata;
use super::transport::Transport;
use crate::color::Rgb;
use crate::optics::warp;
use crate::sphere::Frame;
use std::f64::consts::PI;

use super::path::PathDepth;

/// How the irradiance integral is split between estimators (module docs,
/// docs/math.md §14).
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
pub enum IrradianceMethod {
    /// Everything through the hemisphere estimator.
    Hemisphere,
    /// Direct light by light sampling + the rest through the hemisphere estimator.
    Split,
    /// Chosen per scene by [`Transport::decomposition`]: `hemisphere` for a
    /// scene lit only by a smooth environment, `split` otherwise.
    #[default]
    Auto,
}

/// A decomposition as run: [`IrradianceMethod`] with `auto` resolved.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Decomposition {
    Hemisphere,
    Split,
}

/// Largest relative variance `Var L / (E L)²` of the environment's radiance
/// over the sphere for which `auto` lets the hemisphere estimator integrate
/// it (docs/math.md §14): at 1, cosine-distributed directions estimate the
/// unoccluded irradiance about as well as light sampling would, and the
/// environment prior mean (§10.4) takes most of the rest.
pub const SMOOTH_ENVIRONMENT_RELATIVE_VARIANCE: f64 = 1.0;

impl Transport {
    /// The prior mean the hemisphere part uses for `choice` under
    /// `decomposition`: the environment prior where the hemisphere integrand
    /// contains the environment seen directly (the hemisphere decomposition
    /// of a scene with an environment), else none.
    pub fn hemisphere_prior(
        &self,
        choice: PriorChoice,
        decomposition: Decomposition,
    ) -> Option<&EnvironmentPrior> {
        match (choice, decomposition) {
            (PriorChoice::Environment, Decomposition::Hemisphere) => self.environment_prior(),
            _ => None,
        }
    }

    /// The decomposition `method` stands for in this scene: itself, or for
    /// `auto` `hemisphere` when the scene has no emitting surface and an
    /// environment whose relative variance is at most
    /// [`SMOOTH_ENVIRONMENT_RELATIVE_VARIANCE`], else `split`. A scene with
    /// point, spot or directional lights is always split, whatever is asked:
    /// no hemisphere direction can find a delta light, only light samples
    /// can (the response says which decomposition ran).
    pub fn decomposition(&self, method: IrradianceMethod) -> Decomposition {
        if self.scene().emitters.iter().any(|e| e.is_delta()) {
            return Decomposition::Split;
        }
        match method {
            IrradianceMethod::Auto => {
                let smooth_environment_only = !self.lights().has_finite_lights()
                    && self
                        .environment_relative_variance()
                        .is_some_and(|v| v <= SMOOTH_ENVIRONMENT_RELATIVE_VARIANCE);
                if smooth_environment_only {
                    Decomposition::Hemisphere
                } else {
                    Decomposition::Split
                }
            }
            IrradianceMethod::Hemisphere => Decomposition::Hemisphere,
            IrradianceMethod::Split => Decomposition::Split,
        }
    }
}

/// What to estimate and with how much work.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct IrradianceOptions {
    /// Hemisphere directions per point. At least 1 (2 for a standard error).
    pub samples: u32,
    /// Light samples of the direct part in split mode; `None`: `samples`.
    /// Each is one shadow ray, against a path per hemisphere direction, so a
    /// query whose error is in the direct light (penumbrae, a sun) can take
    /// many more of them than directions. At least 1 when given.
    pub light_samples: Option<u32>,
    /// Longest path counted, in segments from the point (1 = direct light only).
    pub max_depth: PathDepth,
    /// Direct light only; the same as `max_depth = 1`.
    pub direct_only: bool,
    pub method: IrradianceMethod,
    /// Seed of every random stream of the request.
    pub seed: u64,
}

/// Seed of every random stream of a query or command that names none.
pub const DEFAULT_SEED: u64 = 1;

impl Default for IrradianceOptions {
    fn default() -> Self {
        Self {
            samples: 256,
            light_samples: None,
            max_depth: PathDepth::default(),
            direct_only: false,
            method: IrradianceMethod::Split,
            seed: DEFAULT_SEED,
        }
    }
}

impl IrradianceOptions {
    /// Reference mode: enough samples and depth for a converged answer
    /// (relative standard error 0.04–0.8 % at the Cornell-box validation
    /// points of docs/VALIDATION.md).
    pub fn reference(seed: u64) -> Self {
        Self {
            samples: 65_536,
            light_samples: None,
            max_depth: PathDepth::constant(64),
            direct_only: false,
            method: IrradianceMethod::Split,
            seed,
        }
    }

    /// Path-length bound after applying `direct_only`.
    pub fn effective_max_depth(&self) -> PathDepth {
        if self.direct_only {
            PathDepth::DIRECT
        } else {
            self.max_depth
        }
    }

    /// Light samples of the split direct part (`light_samples`, else
    /// `samples`).
    pub fn light_samples(&self) -> u32 {
        self.light_samples.unwrap_or(self.samples)
    }

    /// Checks the sample counts (the depth is valid by construction), and
    /// that light samples come with a decomposition that takes them: the
    /// hemisphere decomposition has no light-sampled part (`auto` may
    /// resolve to it, and then ignores them).
    pub fn validate(&self) -> Result<(), RenderError> {
        if self.method == IrradianceMethod::Hemisphere && self.light_samples.is_some() {
            return Err(RenderError::InvalidOption {
                field: "light_samples",
                reason: "the hemisphere decomposition takes no light samples".into(),
            });
        }
        for (field, count) in [
            ("samples", self.samples),
            ("light_samples", self.light_samples()),
        ] {
            if count == 0 {
                return Err(RenderError::InvalidOption {
                    field,
                    reason: "must be at least 1".into(),
                });
            }
        }
        Ok(())
    }
}

/// Irradiance at one point with its Monte Carlo uncertainty.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct IrradianceEstimate {
    /// Estimated irradiance, W/m².
    pub irradiance: Rgb,
    /// Standard error of `irradiance` (sample standard deviation / √N,
    /// combined over the parts in split mode), W/m².
    pub std_error: Rgb,
    /// Rays traced for this point (closest-hit and shadow).
    pub rays: u64,
    /// The indirect part of `irradiance` (paths of 2 or more segments), the
    /// part a prior on the integral concerns (docs/math.md §10.7), where a
    /// hemisphere rule estimated it; `None` otherwise.
    pub indirect: Option<IndirectPart>,
    /// Per channel, in `[0, 1]`, the weight in the estimate of samples that
    /// may all have missed light at the scene's scale, for which the
    /// calibration adds a term in proportion (docs/math.md §10.5): 1 for
    /// directions drawn without regard to the lights (a hemisphere rule's);
    /// for light samples (split mode) 1 only where none of them carried
    /// light, else 0, since they reach every light the scene has, so that
    /// once one has seen light what they missed is a share of the light they
    /// saw (an occluder or a gap), which the model variance and the
    /// calibration's floor hold; less than 1 once a prior took over part of
    /// the direct light (the rule's weight there, §10.8).
    pub unseen_light: [f64; 3],
    /// Where the direct part is the mean of stratified light samples
    /// (split mode), its two variances; `std_error` holds the stratified
    /// one, which the calibration moderates (docs/math.md §10.5, §14).
    pub direct_strata: Option<StrataVariance>,
}

/// [`IrradianceEstimate::unseen_light`] of light samples whose mean is
/// `direct`: 1 in the channels where none carried light, else 0.
pub fn nothing_seen(direct: Rgb) -> [f64; 3] {
    direct.to_array().map(|v| if v == 0.0 { 1.0 } else { 0.0 })
}

/// The indirect part of an [`IrradianceEstimate`] (docs/math.md §10.7).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct IndirectPart {
    /// Indirect irradiance, W/m².
    pub irradiance: Rgb,
    /// The share of the estimate's variance that is the part's, per channel,
    /// in `[0, 1]`: the rule's own variance of the part over that of the
    /// whole (in split mode the hemisphere rule's over the rule's plus the
    /// light samples'; docs/math.md §10.7).
    pub variance_share: Rgb,
}

impl IndirectPart {
    /// A part that carries the estimate's whole variance.
    pub fn whole(irradiance: Rgb) -> Self {
        Self {
            irradiance,
            variance_share: Rgb::WHITE,
        }
    }
}

impl Transport {
    /// Radiance along each local-frame direction of `local_dirs` (z = the
    /// frame's normal, which should be the point's normal, possibly rotated
    /// about it). Directions with `z ≤ 0` (or not finite) carry nothing and
    /// trace no ray; the others need not be normalised.
    pub fn hemisphere_samples<R: Rng + ?Sized>(
        &self,
        point: &QueryPoint,
        frame: &Frame,
        local_dirs: &[DVec3],
        limits: PathLimits,
        rng: &mut R,
        stats: &mut TraceStats,
    ) -> Vec<RadianceSample> {
        let paths = AveragedPaths {
            limits,
            per_direction: 1,
        };
        self.hemisphere_samples_averaged(point, frame, local_dirs, paths, rng, stats)
    }

    /// [`Self::hemisphere_samples`] with each direction's radiance the mean
    /// of `paths.per_direction` paths sharing their first segment
    /// ([`Self::incident_radiance_averaged`]).
    pub fn hemisphere_samples_averaged<R: Rng + ?Sized>(
        &self,
        point: &QueryPoint,
        frame: &Frame,
        local_dirs: &[DVec3],
        paths: AveragedPaths,
        rng: &mut R,
        stats: &mut TraceStats,
    ) -> Vec<RadianceSample> {
        let traced = self.hemisphere_first_segments(point, frame, local_dirs, paths.limits, stats);
        self.continue_hemisphere(&traced, paths, rng, stats)
    }

    /// The first step of [`Self::hemisphere_samples_averaged`]: each
    /// direction's first segment ([`Self::trace_first_segment`]), no random
    /// number drawn.
    pub fn hemisphere_first_segments(
        &self,
        point: &QueryPoint,
        frame: &Frame,
        local_dirs: &[DVec3],
        limits: PathLimits,
        stats: &mut TraceStats,
    ) -> Vec<FirstSegment> {
        local_dirs
            .iter()
            .map(|local| {
                if local.z.is_nan() || local.z <= 0.0 || !local.is_finite() {
                    return FirstSegment::NONE;
                }
                let dir = frame.to_world(local.normalize());
                let ray = self
                    .scene()
                    .spawn_ray(point.position(), point.normal(), dir);
                self.paths().trace_first_segment(ray, limits, stats)
            })
            .collect()
    }

    /// The second step of [`Self::hemisphere_samples_averaged`]: the
    /// continuations of `traced` in order, drawn from `rng`.
    pub fn continue_hemisphere<R: Rng + ?Sized>(
        &self,
        traced: &[FirstSegment],
        paths: AveragedPaths,
        rng: &mut R,
        stats: &mut TraceStats,
    ) -> Vec<RadianceSample> {
        traced
            .iter()
            .map(|t| {
                self.paths()
                    .continue_averaged(t, paths.limits, paths.per_direction, rng, stats)
            })
            .collect()
    }

    /// Direct irradiance (path length 1) by `samples` light samples, W/m².
    ///
    /// With an environment, each sample also traces one cosine-distributed
    /// direction, and environment light found by either strategy is weighted
    /// by the power heuristic (docs/math.md §14, §15.2): light sampling alone
    /// wastes most samples on a smooth environment that the cosine lobe
    /// would find, and cosine sampling alone misses a sun. The samples are
    /// stratified; with enough of them, both variances of their mean.
    pub fn direct_irradiance<R: Rng + ?Sized>(
        &self,
        point: &QueryPoint,
        samples: u32,
        rng: &mut R,
        stats: &mut TraceStats,
    ) -> (MeanEstimate, Option<StrataVariance>) {
        let strata = direct_strata(samples, rng);
        let values: Vec<Rgb> = (0..samples)
            .map(|j| self.direct_sample(point, (&strata, j), rng, stats).0)
            .collect();
        direct_mean(&strata, &values)
    }

    /// [`Self::direct_irradiance`] and, from the same samples, its gradient
    /// with respect to the normal per channel (W/m² per unit of normal,
    /// docs/math.md §10.8): `∂E/∂n = ∫ L(ω) ω dω` over the unoccluded
    /// directions in front, each sample's `L w ω / p`.
    pub fn direct_irradiance_and_normal_gradient<R: Rng + ?Sized>(
        &self,
        point: &QueryPoint,
        samples: u32,
        rng: &mut R,
        stats: &mut TraceStats,
    ) -> (MeanEstimate, [DVec3; 3]) {
        let mut gradient = [DVec3::ZERO; 3];
        let strata = direct_strata(samples, rng);
        let values: Vec<Rgb> = (0..samples)
            .map(|j| {
                let (value, g) = self.direct_sample(point, (&strata, j), rng, stats);
                for (sum, g) in gradient.iter_mut().zip(g) {
                    *sum += g;
                }
                value
            })
            .collect();
        let count = f64::from(samples.max(1));
        (direct_mean(&strata, &values).0, gradient.map(|g| g / count))
    }

    /// One sample of [`Self::direct_irradiance`] (its light sample and, with
    /// an environment, its cosine direction) and its contribution to the
    /// normal gradient per channel: a direction `ω` of weight `L w / p`
    /// adds `L w cos θ / p` to the value and `L w ω / p` to the gradient.
    fn direct_sample<R: Rng + ?Sized>(
        &self,
        point: &QueryPoint,
        (strata, j): (&SharedStrata, u32),
        rng: &mut R,
        stats: &mut TraceStats,
    ) -> (Rgb, [DVec3; 3]) {
        let scene = self.scene();
        let (x, n) = (point.position(), point.normal());
        let mut value = Rgb::BLACK;
        let mut gradient = [DVec3::ZERO; 3];
        // `L` times `w cos θ / p` into the value, `w / p` along `ω` into the
        // gradient (each factor written as the estimate always wrote it).
        let mut add = |radiance: Rgb, value_factor: f64, weight_over_pdf: f64, dir: DVec3| {
            value += radiance * value_factor;
            for (g, l) in gradient.iter_mut().zip(radiance.to_array()) {
                *g += dir * (l * weight_over_pdf);
            }
        };
        let u_select = rng.random();
        let u = strata.sample(u64::from(j), [rng.random(), rng.random()]);
        if let Some(light) = self.lights().sample(scene, x, u_select, u) {
            let cos = n.dot(light.wi);
            if cos > 0.0 && !light.radiance.is_black() && light.visible_from(scene, x, n, stats) {
                // Only environment light is also reachable by the cosine strategy.
                let weight = if light.is_environment() {
                    power_heuristic(light.pdf, cos / PI)
                } else {
                    1.0
                };
                let value_factor = weight * cos / light.pdf;
                add(light.radiance, value_factor, weight / light.pdf, light.wi);
            }
        }
        if self.lights().has_environment() {
            let u = strata.sample(u64::from(j), [rng.random(), rng.random()]);
            let local = warp::cosine_hemisphere(u);
            let dir = Frame::from_normal(n).to_world(local);
            stats.rays += 1;
            if local.z > 0.0 && scene.intersect(&scene.spawn_ray(x, n, dir)).is_none() {
                let pdf = local.z / PI;
                let weight = power_heuristic(pdf, self.lights().pdf_environment(scene, x, dir));
                // L cos θ / p = π L for cosine-distributed directions.
                add(
                    environment_radiance(scene, dir),
                    weight * PI,
                    weight / pdf,
                    dir,
                );
            }
        }
        (value, gradient)
    }

    /// Hemisphere estimate of `∫_H L cos θ dω` with `samples` cosine-weighted
    /// random directions: `π · mean(L)` (docs/math.md §1), the paths along
    /// them summing `limits`, with the unbiased variance of that mean
    /// (`crate::stats::RunningMean`). Independent directions, so the
    /// variance is estimated from their spread; the plain Monte Carlo
    /// estimate that checks imported records (`service::import_check`).
    pub fn cosine_hemisphere_irradiance<R: Rng + ?Sized>(
        &self,
        point: &QueryPoint,
        samples: u32,
        limits: PathLimits,
        rng: &mut R,
        stats: &mut TraceStats,
    ) -> MeanEstimate {
        let frame = Frame::from_normal(point.normal());
        let dirs: Vec<DVec3> = (0..samples)
            .map(|_| warp::cosine_hemisphere([rng.random(), rng.random()]))
            .collect();
        let values = self.hemisphere_samples(point, &frame, &dirs, limits, rng, stats);
        MeanEstimate::of(values.iter().map(|s| s.radiance)).scaled(PI)
    }

    /// Irradiance at one point, drawing random numbers from `rng`.
    pub fn irradiance<R: Rng + ?Sized>(
        &self,
        point: &QueryPoint,
        options: &IrradianceOptions,
        rng: &mut R,
    ) -> IrradianceEstimate {
        let mut stats = TraceStats::default();
        let depth = options.effective_max_depth();
        let decomposition = self.decomposition(options.method);
        let mut direct_strata = None;
        let parts = match decomposition {
            Decomposition::Hemisphere => vec![self.cosine_hemisphere_irradiance(
                point,
                options.samples,
                PathLimits {
                    max_depth: depth,
                    lengths: PathLengths::All,
                },
                rng,
                &mut stats,
            )],
            Decomposition::Split => {
                let (direct, strata) =
                    self.direct_irradiance(point, options.light_samples(), rng, &mut stats);
                direct_strata = strata;
                let mut parts = vec![direct];
                if depth.has_reflections() {
                    parts.push(self.cosine_hemisphere_irradiance(
                        point,
                        options.samples,
                        PathLimits {
                            max_depth: depth,
                            lengths: PathLengths::Indirect,
                        },
                        rng,
                        &mut stats,
                    ));
                }
                parts
            }
        };
        // The parts use disjoint random numbers, so their variances add.
        let irradiance = parts.iter().map(|p| p.mean).sum();
        let variance: Rgb = parts.iter().map(|p| p.variance_of_mean).sum();
        IrradianceEstimate {
            irradiance,
            std_error: variance.map(f64::sqrt),
            rays: stats.rays,
            indirect: None,
            unseen_light: match decomposition {
                Decomposition::Hemisphere => [1.0; 3],
                Decomposition::Split => nothing_seen(parts[0].mean),
            },
            direct_strata,
        }
    }

    /// Irradiance at every point, in parallel on the current rayon pool.
    /// `on_done` is called once per finished point (e.g. to advance a
    /// progress bar). Point `i` uses the stream `point_rng(seed, i)`.
    /// Stops between points once `cancel` is set.
    pub fn irradiance_at_points(
        &self,
        points: &[QueryPoint],
        options: &IrradianceOptions,
        on_done: &(dyn Fn() + Sync),
        cancel: &Cancel,
    ) -> Result<Vec<IrradianceEstimate>, RenderError> {
        options.validate()?;
        points
            .par_iter()
            .enumerate()
            .map(|(i, point)| {
                cancel.check()?;
                let mut rng = point_rng(options.seed, i as u64);
                let estimate = self.irradiance(point, options, &mut rng);
                on_done();
                Ok(estimate)
            })
            .collect()
    }
}

/// The pattern the direct light's `samples` samples at a point are spread
/// over (docs/math.md §14): sample `j` takes cell `j`'s place on the lights
/// and, with an environment, its cosine direction in the same cell of the
/// direction's square, each jittered independently.
fn direct_strata<R: Rng + ?Sized>(samples: u32, rng: &mut R) -> SharedStrata {
    SharedStrata::new(u64::from(samples), [rng.random(), rng.random()])
}

/// The mean of the direct light's samples and its collapsed-strata
/// variance ([`MeanEstimate::of_strata`]).
fn direct_mean(strata: &SharedStrata, values: &[Rgb]) -> (MeanEstimate, Option<StrataVariance>) {
    let cells: Vec<Option<u32>> = (0..values.len() as u64)
        .map(|j| strata.cell_code(j))
        .collect();
    MeanEstimate::of_strata(values, &cells)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn options_are_validated() {
        let mut o = IrradianceOptions::default();
        assert!(o.validate().is_ok());
        o.samples = 0;
        assert!(matches!(
            o.validate(),
            Err(RenderError::InvalidOption {
                field: "samples",
                ..
            })
        ));
        o.samples = 8;
        o.light_samples = Some(0);
        assert!(matches!(
            o.validate(),
            Err(RenderError::InvalidOption {
                field: "light_samples",
                ..
            })
        ));
        o.light_samples = None;
        assert_eq!(o.light_samples(), 8);
        o.direct_only = true;
        o.max_depth = PathDepth::constant(9);
        assert_eq!(o.effective_max_depth(), PathDepth::DIRECT);
    }
}
