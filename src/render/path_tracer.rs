//! Incident radiance `L_i(x, ω)` along one ray by unidirectional path tracing
//! with next-event estimation, multiple importance sampling and Russian
//! roulette (pbrt-v4 §13.4 `PathIntegrator`; Veach 1997 ch. 9 for the power
//! heuristic).
//!
//! The first direction is chosen by the caller (a hemisphere estimator), so
//! emission found by the first segment is taken at full weight. At later
//! vertices light is gathered twice — by a light sample and by the BSDF-sampled
//! continuation — and the two are weighted by the power heuristic so nothing is
//! counted twice.

use glam::DVec3;
use rand::{Rng, RngExt};

use super::lights::{emitted_radiance, environment_radiance};
use super::mean::MeanEstimate;
use super::path::{
    FirstSegment, PathDepth, PathLengths, PathLimits, RadianceSample, SharedFirstVertex,
    power_heuristic,
};
use super::strata::GridStrata;
use super::trace_stats::TraceStats;
use super::transport::Transport;
use crate::color::Rgb;
use crate::scene::{Ray, SurfaceHit};

/// Russian roulette starts once a path has this many segments: the first
/// bounces carry most of the energy and are never cut (pbrt-v4 uses `depth > 1`).
const ROULETTE_START: u32 = 2;

/// The path kernel of a scene's [`Transport`]: incident radiance along rays
/// (module docs), made by [`Transport::paths`]; it holds nothing else.
#[derive(Clone, Copy)]
pub struct PathTracer<'a> {
    transport: &'a Transport,
}

impl Transport {
    /// The path kernel: incident radiance along rays of this scene.
    pub fn paths(&self) -> PathTracer<'_> {
        PathTracer { transport: self }
    }
}

impl PathTracer<'_> {
    /// Incident radiance at `ray.origin` from direction `ray.dir` (world),
    /// summed over the paths `limits` allows.
    ///
    /// Spawn the ray with [`crate::scene::Scene::spawn_ray`] so it leaves the query surface
    /// cleanly.
    pub fn incident_radiance<R: Rng + ?Sized>(
        &self,
        ray: Ray,
        limits: PathLimits,
        rng: &mut R,
        stats: &mut TraceStats,
    ) -> RadianceSample {
        self.incident_radiance_averaged(ray, limits, 1, rng, stats)
    }

    /// The mean of `paths ≥ 1` path estimates of [`Self::incident_radiance`]
    /// that share their first segment: the ray is traced once and `paths`
    /// independent continuations leave its hit. Every continuation is an
    /// unbiased path sample, so the mean is unbiased; it saves `paths − 1`
    /// closest-hit rays, and the continuations' light samples at the first
    /// hit are stratified over the light's unit square (stratum `j` of a
    /// near-square `s_x × s_y = paths` grid), which lowers the variance of
    /// the one-bounce term that dominates indirect light. The sample's
    /// `variance` is the continuations' sample variance over `paths`.
    pub fn incident_radiance_averaged<R: Rng + ?Sized>(
        &self,
        ray: Ray,
        limits: PathLimits,
        paths: u32,
        rng: &mut R,
        stats: &mut TraceStats,
    ) -> RadianceSample {
        let traced = self.trace_first_segment(ray, limits, stats);
        self.continue_averaged(&traced, limits, paths, rng, stats)
    }

    /// [`Self::incident_radiance`] for ray `first.index` of a group of
    /// rays (a pixel's) whose first-vertex light and BSDF samples are
    /// spread over the group's shared patterns (`render::strata`): each
    /// sample stays uniform on its own, so the estimate stays unbiased, and
    /// the group's mean gets the stratification's lower variance.
    pub fn incident_radiance_stratified<R: Rng + ?Sized>(
        &self,
        ray: Ray,
        limits: PathLimits,
        first: SharedFirstVertex,
        rng: &mut R,
        stats: &mut TraceStats,
    ) -> RadianceSample {
        let traced = self.trace_first_segment(ray, limits, stats);
        let first = |_| FirstVertex::Shared(first);
        self.continue_first_segment(&traced, limits, 1, first, rng, stats)
    }

    /// The first step of [`Self::incident_radiance_averaged`]: `ray` traced
    /// and what it sees directly, with no random number drawn, so the
    /// continuations may follow later ([`Self::continue_averaged`]) and give
    /// the same bits as the one-step call with the same generator.
    pub fn trace_first_segment(
        &self,
        ray: Ray,
        limits: PathLimits,
        stats: &mut TraceStats,
    ) -> FirstSegment {
        let scene = self.transport.scene();
        let mut sample = RadianceSample::NONE;
        // The first segment's direction came from the caller, so emission
        // found by it is taken at full weight.
        let direct = limits.lengths == PathLengths::All;
        stats.rays += 1;
        let Some(hit) = scene.intersect(&ray) else {
            if direct {
                sample.direct = environment_radiance(scene, ray.dir);
                sample.radiance = sample.direct;
            }
            return FirstSegment { sample, hit: None };
        };
        sample.distance = hit.t;
        if direct {
            sample.direct = emitted_radiance(scene, &hit, ray.dir);
            sample.radiance = sample.direct;
        }
        FirstSegment {
            sample,
            hit: Some((hit, ray.dir)),
        }
    }

    /// The solid-angle density with which a light sample from `origin`
    /// (where `traced` started) would have chosen the emission `traced`
    /// found directly (its `direct`): the environment's where it escaped, the
    /// area emitter's where it hit one; the weight of that emission against
    /// light samples in multiple importance sampling.
    pub fn light_pdf_of(&self, origin: DVec3, traced: &FirstSegment, dir: DVec3) -> f64 {
        let scene = self.transport.scene();
        match &traced.hit {
            None => self.transport.lights().pdf_environment(scene, origin, dir),
            Some((hit, _)) => self.transport.lights().pdf_area_hit(scene, origin, hit),
        }
    }

    /// The second step of [`Self::incident_radiance_averaged`]: the mean of
    /// `paths` continuations from the hit of `traced`.
    pub fn continue_averaged<R: Rng + ?Sized>(
        &self,
        traced: &FirstSegment,
        limits: PathLimits,
        paths: u32,
        rng: &mut R,
        stats: &mut TraceStats,
    ) -> RadianceSample {
        let strata = GridStrata::new(paths);
        let first = |j| FirstVertex::Grid(strata, j);
        self.continue_first_segment(traced, limits, paths, first, rng, stats)
    }

    /// `paths` continuations from the hit of `traced`, the `j`-th drawing
    /// its first-vertex samples as `first(j)` says, averaged.
    fn continue_first_segment<R: Rng + ?Sized>(
        &self,
        traced: &FirstSegment,
        limits: PathLimits,
        paths: u32,
        first: impl Fn(u32) -> FirstVertex,
        rng: &mut R,
        stats: &mut TraceStats,
    ) -> RadianceSample {
        let mut sample = traced.sample;
        let Some((hit, dir)) = traced.hit else {
            return sample;
        };
        let paths = paths.max(1);
        // Given the shared hit the continuations are independent, so their
        // spread estimates the variance of their mean (an upper bound, as
        // their first light samples are stratified).
        let continuations = MeanEstimate::of(
            (0..paths)
                .map(|j| self.continue_path(hit, dir, limits.max_depth, first(j), rng, stats)),
        );
        sample.radiance += continuations.mean;
        sample.variance = continuations.variance_of_mean;
        sample
    }

    /// Radiance of path lengths `2..=max_depth` arriving along `dir` from
    /// the first hit `hit` (its emission excluded): NEE at every vertex,
    /// the first one's samples drawn as `first` says.
    fn continue_path<R: Rng + ?Sized>(
        &self,
        hit: SurfaceHit,
        dir: DVec3,
        max_depth: PathDepth,
        first: FirstVertex,
        rng: &mut R,
        stats: &mut TraceStats,
    ) -> Rgb {
        let scene = self.transport.scene();
        let mut radiance = Rgb::BLACK;
        let mut beta = Rgb::WHITE;
        let (mut hit, mut dir) = (hit, dir);
        // `hit` was reached by segment `depth`.
        for depth in 1..max_depth.get() {
            let Some(bsdf) = self.transport.bsdf_at(&hit) else {
                break;
            };
            // Reflection happens in the shading frame (interpolated mesh
            // normals where present), as in Mitsuba 3; rays still leave
            // from the geometric surface, on the side of their direction.
            let frame = bsdf.frame_at(&hit);
            let wo = frame.to_local(-dir);
            if !bsdf.scatters_towards(wo) || bsdf.is_black() {
                // Back faces of one-sided BSDFs are black, as in Mitsuba 3.
                break;
            }
            let flags = bsdf.flags();

            // Next-event estimation: a path of length depth + 1 ending on a
            // light, for the parts a light sample can reach (not deltas).
            if flags.diffuse || flags.glossy {
                let u_select = rng.random();
                let mut u = [rng.random(), rng.random()];
                if depth == 1 {
                    u = first.light(u);
                }
                if let Some(light) =
                    self.transport
                        .lights()
                        .sample(scene, hit.position, u_select, u)
                {
                    let wi = frame.to_local(light.wi);
                    let f = bsdf.eval(wo, wi);
                    if !f.is_black() && light.visible_from(scene, hit.position, hit.normal, stats) {
                        // A delta light is out of the BSDF sample's reach.
                        let weight = if light.delta {
                            1.0
                        } else {
                            power_heuristic(light.pdf, bsdf.pdf(wo, wi))
                        };
                        radiance += beta * f * light.radiance * (wi.z.abs() * weight / light.pdf);
                    }
                }
            }

            // Continue the path by sampling the BSDF.
            let lobe = rng.random();
            let mut u = [rng.random(), rng.random()];
            if depth == 1 {
                u = first.bsdf(u);
            }
            let Some(sample) = bsdf.sample(wo, lobe, u) else {
                break;
            };
            beta *= sample.value * (sample.wi.z.abs() / sample.pdf);
            if depth >= ROULETTE_START {
                let max = beta.max_component();
                if max < 1.0 {
                    let q = (1.0 - max).max(0.0);
                    if rng.random::<f64>() < q {
                        break;
                    }
                    beta *= 1.0 / (1.0 - q);
                }
            }
            let origin = hit.position;
            let ray = scene.spawn_ray(origin, hit.normal, frame.to_world(sample.wi));
            dir = ray.dir;
            // Segment depth + 1: light it finds was also reachable by the
            // light sample above, so both are weighted by the power
            // heuristic, unless a delta chose it, which no light sample can.
            let mis = |light_pdf: f64| {
                if sample.delta {
                    1.0
                } else {
                    power_heuristic(sample.pdf, light_pdf)
                }
            };
            stats.rays += 1;
            let Some(next) = scene.intersect(&ray) else {
                let le = environment_radiance(scene, dir);
                if !le.is_black() {
                    let weight = mis(self.transport.lights().pdf_environment(scene, origin, dir));
                    radiance += beta * le * weight;
                }
                break;
            };
            let le = emitted_radiance(scene, &next, dir);
            if !le.is_black() {
                let weight = mis(self.transport.lights().pdf_area_hit(scene, origin, &next));
                radiance += beta * le * weight;
            }
            hit = next;
        }
        radiance
    }
}

/// How a path's first-vertex samples (at the hit of its first segment)
/// are drawn from their uniform numbers.
#[derive(Clone, Copy, Debug)]
enum FirstVertex {
    /// The light sample within cell `j` of a grid (the continuations of
    /// one first segment); the BSDF sample as drawn.
    Grid(GridStrata, u32),
    /// Both within the cells of a group's shared patterns.
    Shared(SharedFirstVertex),
}

impl FirstVertex {
    fn light(&self, u: [f64; 2]) -> [f64; 2] {
        match self {
            FirstVertex::Grid(strata, j) => strata.sample(*j, u),
            FirstVertex::Shared(s) => s.light.sample(s.index, u),
        }
    }

    fn bsdf(&self, u: [f64; 2]) -> [f64; 2] {
        match self {
            FirstVertex::Grid(..) => u,
            FirstVertex::Shared(s) => s.bsdf.sample(s.index, u),
        }
    }
}
