//! Outgoing radiance at a surface point through the irradiance cache: the
//! shading used by tiles and by single radiance queries.
//!
//! `L_o(x, ω_o) = L_e + L_direct + (k_d/π) E_ind + k_s I_glossy` where
//! - `L_e` is the surface's own emission;
//! - `L_direct` is light arriving straight from emitters, estimated by
//!   stratified light sampling (next-event estimation) through the whole
//!   BSDF, diffuse and Phong lobes (docs/math.md §1); in tiles the light
//!   samples of all a pixel's camera rays share one stratified pattern, so
//!   64 rays × 4 samples act as 256 jittered samples of the light rather
//!   than 64 independent groups of 4;
//! - `E_ind` is the indirect irradiance (path lengths ≥ 2,
//!   [`PathLengths::Indirect`]) interpolated from cache records (docs/math.md §9);
//! - `I_glossy = ∫ L_ind p dω` with the Phong density
//!   `p = (m+2)/(2π) cos^m α cos θ` is a BMC estimate ([`GlossyRule`]); so
//!   each path length is counted by exactly one term. Where the BMC sum
//!   comes out negative in a channel (the negative-weight guard,
//!   docs/math.md §3.6), the lobe is estimated by as many lobe-sampled
//!   paths instead, and the shading reports their variance
//!   (docs/math.md §13.3).
//!
//! # Ambient bounces: records gather through the cache
//! A record's `N` rays need the radiance leaving the surfaces they hit. A
//! path per ray ([`Gather::Paths`]) freezes that path's noise into the
//! record. With `ambient_bounces ≥ 1` (Radiance's `-ab`; Ward et al. 1988)
//! a record instead shades each hit `y` as a camera hit is shaded:
//! `L(y → x) = L_direct(y) + (k_d/π) E_ind(y) + k_s I_glossy(y)`, direct
//! light by one light sample (the `N` rays average those), `E_ind(y)` looked
//! up in the same cache at the relaxed accuracy `min(1, 2a)` and, where no
//! record covers `y`, a record created there one level deeper (levels
//! `≥ ambient_bounces` trace paths), and glossy lobes by one lobe-sampled
//! path. The cache's records count indirect paths of every length, so a
//! bounce through them replaces the truncation at `max_depth` by the
//! cache's own fixed point; records therefore gather this way only when
//! their paths' depth (counted from the record's point) is at least
//! [`AMBIENT_MIN_DEPTH`](super::config::AMBIENT_MIN_DEPTH), where the truncated tail is
//! negligible, and trace exact paths otherwise. In a reproducible
//! placement pass the bounces only read the private cache (a miss falls
//! back to one path), so every record of a batch sees the same cache.
//!

mod gather;
mod reflection;
mod traced_record;

use std::f64::consts::PI;

use glam::DVec3;
use rand::{Rng, RngExt};

use super::config::{
    AMBIENT_ACCURACY_FACTOR, CachedShading, MAX_BMC_EXPONENT, PlacementOptions, indirect_paths,
};
use super::dense::{DENSE_INDIRECT_PATHS, DENSE_LIGHT_FACTOR};
use super::direct_light::{Surface, direct_radiance, mis_weights};
use super::glossy::lobe_sampled;
use super::record_estimate::{GatheredRecord, PlacementPoint, finish_records, lookup};
use super::shade_point::{Bounce, OnMiss, ShadePoint};
use super::stats::ShadingStats;
use crate::cache::{Accuracy, CacheError, IrradianceCache, RadiusLimits, Record, RecordRule};
use crate::optics::warp;
use crate::render::lights::{emitted_radiance, environment_radiance};
use crate::render::{
    Evaluation, FirstSegment, PathLengths, PathLimits, QueryPoint, RadianceSample, RenderError,
    Rgb, TraceStats, Transport,
};
use crate::scene::{Ray, SurfaceHit};
use crate::sphere::Frame;
use crate::stats::RunningMean;
pub use gather::{Gather, RecordGather};
use reflection::Reflection;
pub use traced_record::{TracedRecord, trace_record};

/// Shading through one irradiance cache: the scene's transport, the cache
/// that is read and extended, and its rules and options. The methods carry
/// the mutual recursion of shading and records (a shading point may create a
/// record, whose rays may shade points through the cache again), so none of
/// them passes this context along.
#[derive(Clone, Copy)]
pub struct CachedIntegrator<'a> {
    pub transport: &'a Transport,
    pub cache: &'a IrradianceCache,
    pub shading: &'a CachedShading,
    /// The scene's secondary cache (`secondary`), if the records this
    /// integrator places for shading points gather through it
    /// ([`Gather::for_record`]); see `secondary::secondary_cache_of`.
    pub secondary: Option<&'a IrradianceCache>,
}

impl<'a> CachedIntegrator<'a> {
    /// Shading through `cache` with `shading`'s rules and options; records
    /// it places gather by paths or ambient bounces until a secondary cache
    /// is given.
    pub fn new(
        transport: &'a Transport,
        cache: &'a IrradianceCache,
        shading: &'a CachedShading,
    ) -> Self {
        CachedIntegrator {
            transport,
            cache,
            shading,
            secondary: None,
        }
    }
}

impl RecordGather<'_> {
    /// Incident radiance along each local direction of a record at `point`
    /// in `frame`, each the mean of `per_direction` estimates; rays and
    /// nested records are counted in `stats`.
    pub fn samples<R: Rng + ?Sized>(
        &self,
        transport: &Transport,
        point: &QueryPoint,
        frame: &Frame,
        local_dirs: &[DVec3],
        rng: &mut R,
        stats: &mut ShadingStats,
    ) -> Result<Vec<RadianceSample>, RenderError> {
        let (integrator, bounce) = match self.gather {
            Gather::Cache { integrator, bounce } => (integrator, bounce),
            Gather::Paths | Gather::Secondary { .. } => {
                let mut trace = TraceStats::default();
                let segments = transport
                    .hemisphere_first_segments(point, frame, local_dirs, self.paths, &mut trace);
                stats.rays += trace.rays;
                return self.continue_segments(transport, &segments, rng, stats);
            }
        };
        let gather = |rng: &mut R, stats: &mut ShadingStats| {
            integrator.gather_through_cache(point, frame, local_dirs, bounce, rng, stats)
        };
        // A running mean and spread per direction: the repeats are
        // independent estimates of each value, folded in as they come, so
        // memory stays one sample set whatever `per_direction` is.
        let mut samples = gather(rng, stats)?;
        if self.per_direction > 1 {
            let mut running: Vec<RunningMean<Rgb>> = samples
                .iter()
                .map(|s| {
                    let mut r = RunningMean::new();
                    r.push(s.radiance);
                    r
                })
                .collect();
            for _ in 1..self.per_direction {
                for (r, m) in running.iter_mut().zip(gather(rng, stats)?) {
                    r.push(m.radiance);
                }
            }
            for (s, r) in samples.iter_mut().zip(running) {
                s.radiance = r.mean();
                s.variance = r.variance_of_mean().unwrap_or(Rgb::BLACK);
            }
        }
        Ok(samples)
    }
}

impl RecordGather<'_> {
    /// The radiance along each of `segments` (traced by
    /// [`Transport::hemisphere_first_segments`] with `self.paths`): their
    /// paths continued, or their hits shaded through the secondary cache
    /// ([`Gather::Secondary`]). An ambient bounce ([`Gather::Cache`])
    /// retraces its rays and is not continued here: it is treated as paths.
    fn continue_segments<R: Rng + ?Sized>(
        &self,
        transport: &Transport,
        segments: &[FirstSegment],
        rng: &mut R,
        stats: &mut ShadingStats,
    ) -> Result<Vec<RadianceSample>, RenderError> {
        let Gather::Secondary { integrator } = self.gather else {
            let mut trace = TraceStats::default();
            let samples =
                transport.continue_hemisphere(segments, self.averaged_paths(), rng, &mut trace);
            stats.rays += trace.rays;
            return Ok(samples);
        };
        let placement = integrator.shading.placement(self.paths, 0);
        let reflection = Reflection {
            placement: &placement,
            light_samples: self.per_direction,
            level: 1,
            on_miss: OnMiss::PathTrace,
            sample: None,
            indirect: true,
            glossy_bmc: false,
            delta_chain: 0,
            fallback_paths: 1,
        };
        segments
            .iter()
            .map(|segment| {
                let mut sample = segment.sample();
                if let Some((hit, dir)) = segment.hit() {
                    let reflected =
                        integrator.reflected_radiance(&hit, -dir, &reflection, rng, stats)?;
                    sample.radiance += reflected.value;
                    sample.variance = reflected.variance;
                }
                Ok(sample)
            })
            .collect()
    }
}

impl CachedIntegrator<'_> {
    /// Radiance leaving the surface at `hit` towards the unit world direction
    /// `wo` (pointing away from the surface), W/(m²·sr), shaded as in the
    /// module docs and `how` says, with the variance the shading knows of
    /// for it: that of the glossy fallback times `k_s²` where it ran
    /// (docs/math.md §13.3), zero otherwise. With `how.sample`, this is ray
    /// `index` of `count` estimating one value (a pixel's camera rays) and
    /// its light samples are numbers `index·n ..< (index + 1)·n` of one
    /// shared stratified pattern (`SharedStrata`) of `count·n` samples seeded by
    /// `sample.pattern`; otherwise they are stratified among themselves only.
    pub fn outgoing_radiance<R: Rng + ?Sized>(
        &self,
        hit: &SurfaceHit,
        wo: DVec3,
        how: ShadePoint,
        rng: &mut R,
        stats: &mut ShadingStats,
    ) -> Result<Evaluation, RenderError> {
        let options = &self.shading.options;
        let radiance = emitted_radiance(self.transport.scene(), hit, -wo);
        // Paths leaving the point count their segments from it.
        let Some(from_point) = how.max_depth.after_first_segment() else {
            return Ok(Evaluation::of(radiance));
        };
        let placement = self.shading.placement(indirect_paths(from_point), 0);
        let (light_factor, fallback_paths) = match how.dense {
            true => (DENSE_LIGHT_FACTOR, DENSE_INDIRECT_PATHS),
            false => (1, 1),
        };
        let reflection = Reflection {
            placement: &placement,
            light_samples: options.light_samples.saturating_mul(light_factor),
            fallback_paths,
            level: 0,
            on_miss: how.on_miss,
            sample: how.sample,
            indirect: from_point.has_reflections(),
            glossy_bmc: true,
            delta_chain: 0,
        };
        let reflected = self.reflected_radiance(hit, wo, &reflection, rng, stats)?;
        Ok(Evaluation {
            value: radiance + reflected.value,
            ..reflected
        })
    }

    /// Radiance reflected at `hit` towards `wo` (no emission): direct light,
    /// and with `r.indirect` the diffuse and glossy indirect terms; with the
    /// variance of the glossy fallback (times `k_s²`) where it ran.
    fn reflected_radiance<R: Rng + ?Sized>(
        &self,
        hit: &SurfaceHit,
        wo: DVec3,
        r: &Reflection,
        rng: &mut R,
        stats: &mut ShadingStats,
    ) -> Result<Evaluation, RenderError> {
        let Some(bsdf) = self.transport.bsdf_at(hit) else {
            return Ok(Evaluation::of(Rgb::BLACK));
        };
        let frame = bsdf.frame_at(hit);
        let wo_local = frame.to_local(wo);
        if !bsdf.scatters_towards(wo_local) || bsdf.is_black() {
            return Ok(Evaluation::of(Rgb::BLACK));
        }
        let surface = Surface {
            hit,
            frame,
            bsdf: &bsdf,
            wo_local,
        };
        let mut trace = TraceStats::default();
        let flags = bsdf.flags();
        let mut radiance = Rgb::BLACK;
        // A glossy lobe other than Phong's reflects lights by light samples
        // and by the BSDF sample of `lambertian_and_rest`, weighted against
        // each other: light samples alone miss the highlight of a large
        // bright light (the sky) in a narrow lobe, and sparkle.
        let mis = flags.glossy && bsdf.phong().is_none();
        if flags.diffuse || flags.glossy {
            radiance += direct_radiance(
                self.transport,
                &surface,
                r.light_samples,
                r.sample,
                mis,
                rng,
                &mut trace,
            );
        }
        let (mut variance, mut shared) = (Rgb::BLACK, Rgb::BLACK);
        match bsdf.phong() {
            Some(phong) if r.indirect => {
                let point = QueryPoint::new(hit.position, hit.shading_normal)?;
                if !phong.diffuse.is_black() {
                    let (e, v) = self.indirect_irradiance(&point, r, rng, &mut trace, stats)?;
                    let kd = phong.diffuse * (1.0 / PI);
                    radiance += kd * e;
                    shared += kd * kd * v;
                }
                if !phong.specular.is_black() {
                    let i = self.glossy_indirect(&surface, &point, r, rng, &mut trace, stats)?;
                    radiance += phong.specular * i.value;
                    variance += phong.specular * phong.specular * i.variance;
                }
            }
            Some(_) => {}
            None => {
                let rest = self.lambertian_and_rest(&surface, r, mis, rng, &mut trace, stats)?;
                radiance += rest.value;
                variance += rest.variance;
                shared += rest.shared;
            }
        }
        stats.rays += trace.rays;
        Ok(Evaluation {
            value: radiance,
            variance,
            shared,
        })
    }

    /// The reflection of a BSDF other than Phong, direct light aside
    /// (docs/math.md §18.3): its Lambertian part `ρ(ω_o)` times the cached
    /// indirect irradiance `E/π` (on the side `ω_o` sees), plus the rest
    /// `f − ρ/π` by one BSDF sample: all the light arriving through a Dirac
    /// delta (which no light sample reaches), only its indirect part
    /// otherwise (light samples took the direct), except with `mis`, where
    /// the sample also brings the direct emission it finds through the
    /// whole BSDF, weighted against the light samples ([`direct_radiance`]).
    /// A camera path ([`Self::through_delta`]) follows deltas through the
    /// cache; every other sample's incident radiance is path traced.
    fn lambertian_and_rest<R: Rng + ?Sized>(
        &self,
        s: &Surface,
        r: &Reflection,
        mis: bool,
        rng: &mut R,
        trace: &mut TraceStats,
        stats: &mut ShadingStats,
    ) -> Result<Evaluation, RenderError> {
        let (mut radiance, mut shared) = (Rgb::BLACK, Rgb::BLACK);
        let rho = s.bsdf.lambertian(s.wo_local);
        if r.indirect && !rho.is_black() {
            let side = s.wo_local.z.signum();
            let point = QueryPoint::new(s.hit.position, s.hit.shading_normal * side)?;
            let (e, v) = self.indirect_irradiance(&point, r, rng, trace, stats)?;
            let kd = rho * (1.0 / PI);
            radiance += kd * e;
            shared = kd * kd * v;
        }
        // The records' error is in every return below; the rest's noise is
        // the ray's own.
        let done = |value| Evaluation {
            value,
            variance: Rgb::BLACK,
            shared,
        };
        let u = [rng.random(), rng.random()];
        let Some(sample) = s.bsdf.sample(s.wo_local, rng.random(), u) else {
            return Ok(done(radiance));
        };
        let mis = mis && !sample.delta;
        if !sample.delta && !r.indirect && !mis {
            return Ok(done(radiance));
        }
        let cos_over_pdf = sample.wi.z.abs() / sample.pdf;
        let mut f = sample.value;
        if !sample.delta && sample.wi.z * s.wo_local.z > 0.0 {
            f = f - rho * (1.0 / PI);
        }
        let throughput = f * cos_over_pdf;
        if throughput.is_black() && !mis {
            return Ok(done(radiance));
        }
        let scene = self.transport.scene();
        let ray = scene.spawn_ray(s.hit.position, s.hit.normal, s.frame.to_world(sample.wi));
        if mis {
            // Direct emission through the whole BSDF, at the weight the
            // light samples left it; then, if asked, the indirect light
            // through the rest `f − ρ/π` along the same first segment.
            let limits = PathLimits {
                max_depth: r.placement.paths.max_depth,
                lengths: PathLengths::All,
            };
            let traced = self
                .transport
                .paths()
                .trace_first_segment(ray, limits, trace);
            let light_pdf = self
                .transport
                .paths()
                .light_pdf_of(s.hit.position, &traced, ray.dir);
            let weight = mis_weights(r.light_samples, light_pdf, sample.pdf).1;
            radiance += sample.value * traced.sample().direct * (weight * cos_over_pdf);
            if r.indirect && !throughput.is_black() {
                let incident = self
                    .transport
                    .paths()
                    .continue_averaged(&traced, limits, 1, rng, trace);
                radiance += throughput * (incident.radiance - incident.direct);
            }
            return Ok(done(radiance));
        }
        if sample.delta && self.through_delta(r) {
            let arriving = self.arriving_through_delta(ray, r, rng, trace, stats)?;
            return Ok(Evaluation {
                value: radiance + throughput * arriving.value,
                variance: throughput * throughput * arriving.variance,
                shared: shared + throughput * throughput * arriving.shared,
            });
        }
        let limits = PathLimits {
            max_depth: r.placement.paths.max_depth,
            lengths: if sample.delta {
                PathLengths::All
            } else {
                PathLengths::Indirect
            },
        };
        let incident = self
            .transport
            .paths()
            .incident_radiance(ray, limits, rng, trace);
        Ok(done(radiance + throughput * incident.radiance))
    }

    /// Radiance arriving along `ray` from the surface it hits, shaded as a
    /// camera hit is (emission, direct light, the cache), or from the
    /// environment if it escapes.
    fn arriving_through_delta<R: Rng + ?Sized>(
        &self,
        ray: Ray,
        r: &Reflection,
        rng: &mut R,
        trace: &mut TraceStats,
        stats: &mut ShadingStats,
    ) -> Result<Evaluation, RenderError> {
        let scene = self.transport.scene();
        trace.rays += 1;
        let Some(next) = scene.intersect(&ray) else {
            return Ok(Evaluation::of(environment_radiance(scene, ray.dir)));
        };
        let emitted = emitted_radiance(scene, &next, ray.dir);
        let chained = Reflection {
            delta_chain: r.delta_chain + 1,
            ..*r
        };
        let reflected = self.reflected_radiance(&next, -ray.dir, &chained, rng, stats)?;
        Ok(Evaluation {
            value: emitted + reflected.value,
            ..reflected
        })
    }

    /// One estimate per direction by an ambient bounce ([`Gather::Cache`]).
    fn gather_through_cache<R: Rng + ?Sized>(
        &self,
        point: &QueryPoint,
        frame: &Frame,
        local_dirs: &[DVec3],
        bounce: Bounce,
        rng: &mut R,
        stats: &mut ShadingStats,
    ) -> Result<Vec<RadianceSample>, RenderError> {
        let options = &self.shading.options;
        let relaxed = PlacementOptions {
            accuracy: Accuracy::new((AMBIENT_ACCURACY_FACTOR * options.accuracy).min(1.0))?,
            ..self.shading.placement(bounce.paths, 0)
        };
        let reflection = Reflection {
            placement: &relaxed,
            light_samples: 1,
            level: bounce.level + 1,
            on_miss: bounce.on_miss,
            sample: None,
            indirect: true,
            glossy_bmc: false,
            delta_chain: 0,
            fallback_paths: 1,
        };
        let all = bounce.paths.lengths == PathLengths::All;
        let scene = self.transport.scene();
        local_dirs
            .iter()
            .map(|local| {
                let mut sample = RadianceSample::NONE;
                if local.z.is_nan() || local.z <= 0.0 || !local.is_finite() {
                    return Ok(sample);
                }
                let dir = frame.to_world(local.normalize());
                let ray = scene.spawn_ray(point.position(), point.normal(), dir);
                stats.rays += 1;
                let Some(hit) = scene.intersect(&ray) else {
                    if all {
                        sample.radiance = environment_radiance(scene, dir);
                    }
                    return Ok(sample);
                };
                sample.distance = hit.t;
                if all {
                    sample.radiance = emitted_radiance(scene, &hit, dir);
                }
                // Glossy lobes are path traced here (no BMC, no fallback),
                // so the reflection reports no variance of its own.
                sample.radiance += self
                    .reflected_radiance(&hit, -dir, &reflection, rng, stats)?
                    .value;
                Ok(sample)
            })
            .collect()
    }

    /// Indirect irradiance at `point` from the cache (module docs,
    /// [`OnMiss`]), W/m², and the variance of the records' error in it,
    /// (W/m²)² (their interpolated posterior variance,
    /// [`crate::cache::Interpolated::variance`]; zero where paths estimate
    /// it, whose noise is the ray's own).
    fn indirect_irradiance<R: Rng + ?Sized>(
        &self,
        point: &QueryPoint,
        r: &Reflection,
        rng: &mut R,
        trace: &mut TraceStats,
        stats: &mut ShadingStats,
    ) -> Result<(Rgb, Rgb), RenderError> {
        let (cache, placement) = (self.cache, r.placement);
        if let Some(found) = lookup(cache, self.transport, point, placement) {
            stats.cache_hits += 1;
            return Ok((found.irradiance, found.error_variance()));
        }
        match r.on_miss {
            OnMiss::Insert => {
                stats.cache_misses += 1;
                let target = PlacementPoint {
                    point: *point,
                    footprint: None,
                };
                let how = RecordGather {
                    paths: placement.paths,
                    per_direction: placement.paths_per_direction,
                    gather: Gather::for_record(*self, placement.paths, r.level, true),
                };
                let record = self
                    .record_at(&target, &how, rng, stats)
                    .and_then(|record| cache.insert(record))?;
                stats.records_created += 1;
                if r.level > 0 {
                    stats.ambient_records += 1;
                }
                Ok((record.irradiance, record.variance))
            }
            OnMiss::PathTrace => {
                let relaxed = PlacementOptions {
                    accuracy: Accuracy::new(1.0)?,
                    ..*placement
                };
                if let Some(found) = lookup(cache, self.transport, point, &relaxed) {
                    stats.cache_hits += 1;
                    stats.relaxed_hits += 1;
                    return Ok((found.irradiance, found.error_variance()));
                }
                stats.cache_misses += 1;
                stats.fallbacks += 1;
                // E ≈ π mean L_i(ω) over cosine-distributed ω.
                let frame = Frame::from_normal(point.normal());
                let dirs: Vec<DVec3> = (0..r.fallback_paths)
                    .map(|_| warp::cosine_hemisphere([rng.random(), rng.random()]))
                    .collect();
                let samples = self.transport.hemisphere_samples(
                    point,
                    &frame,
                    &dirs,
                    placement.paths,
                    rng,
                    trace,
                );
                let sum = samples.iter().fold(Rgb::BLACK, |a, s| a + s.radiance);
                Ok((sum * (PI / f64::from(r.fallback_paths)), Rgb::BLACK))
            }
        }
    }

    /// `∫ L_ind p dω` for the Phong density of the surface's BSDF at its
    /// `wo_local` (units of `L`): BMC with the interpolated glossy rule, or
    /// one lobe-sampled path above [`MAX_BMC_EXPONENT`] or without
    /// `r.glossy_bmc`; both report no variance (the BMC weights are fixed
    /// and one path has no spread). Where the BMC sum is negative in a
    /// channel (the negative-weight guard, docs/math.md §3.6), as many
    /// lobe-sampled paths as the rule has directions replace it, with their
    /// variance (docs/math.md §13.3).
    fn glossy_indirect<R: Rng + ?Sized>(
        &self,
        s: &Surface,
        point: &QueryPoint,
        r: &Reflection,
        rng: &mut R,
        trace: &mut TraceStats,
        stats: &mut ShadingStats,
    ) -> Result<Evaluation, RenderError> {
        let paths = r.placement.paths;
        let mirror = DVec3::new(-s.wo_local.x, -s.wo_local.y, s.wo_local.z);
        let m = s.bsdf.phong().map_or(0.0, |p| p.exponent);
        // Radiance of one path along a local direction of the surface's frame.
        let transport = self.transport;
        let path = |wi: DVec3, rng: &mut R, trace: &mut TraceStats| {
            transport.hemisphere_samples(point, &s.frame, &[wi], paths, rng, trace)[0].radiance
        };
        if !r.glossy_bmc || m > MAX_BMC_EXPONENT {
            stats.glossy_path_traced += 1;
            return Ok(lobe_sampled(m, mirror, 1, rng, |wi, rng| {
                path(wi, rng, trace)
            }));
        }
        stats.glossy_bmc += 1;
        let theta_r = mirror.z.clamp(-1.0, 1.0).acos();
        let turned = s.frame.rotated_about_normal(mirror.y.atan2(mirror.x));
        let rule = self.shading.glossy.weights(m, theta_r)?;
        let samples =
            self.transport
                .hemisphere_samples(point, &turned, &rule.directions, paths, rng, trace);
        if let Some(bmc) = rule.estimate(&samples) {
            return Ok(Evaluation::of(bmc));
        }
        stats.glossy_fallbacks += 1;
        let n = u32::try_from(rule.directions.len()).unwrap_or(u32::MAX);
        Ok(lobe_sampled(m, mirror, n.max(2), rng, |wi, rng| {
            path(wi, rng, trace)
        }))
    }
}

impl CachedIntegrator<'_> {
    /// Record at the point of `target`, its rays gathered by `how` (see
    /// [`compute_record`]), with this integrator's rule and cache limits.
    fn record_at<R: Rng + ?Sized>(
        &self,
        target: &PlacementPoint,
        how: &RecordGather,
        rng: &mut R,
        stats: &mut ShadingStats,
    ) -> Result<Record, CacheError> {
        let limits = self.cache.radius_limits();
        compute_record(
            self.transport,
            &self.shading.rule,
            target,
            limits,
            how,
            rng,
            stats,
        )
    }
}

/// BMC record at `point`: the rule's directions turned about the normal by a
/// random angle from `rng`, the mean of `how.per_direction` radiance
/// samples each (gathered as `how.gather` says), `E = π Σ w_i L_i`
/// (see [`RecordRule::estimate`]) and the harmonic-mean radius within
/// `limits` (tightened by the point's footprint). `stats` counts the rays
/// and any records created at the rays' bounces.
pub fn compute_record<R: Rng + ?Sized>(
    transport: &Transport,
    rule: &RecordRule,
    target: &PlacementPoint,
    limits: RadiusLimits,
    how: &RecordGather,
    rng: &mut R,
    stats: &mut ShadingStats,
) -> Result<Record, CacheError> {
    let rays = gather_record(transport, rule, target, how, rng, stats)?;
    let mut one = finish_records(rule, &[(target, rays)], limits);
    one.pop().expect("one record per gathered record")
}

/// The rays of [`compute_record`]: the frame turned by a random angle from
/// `rng`, then the samples.
pub fn gather_record<R: Rng + ?Sized>(
    transport: &Transport,
    rule: &RecordRule,
    target: &PlacementPoint,
    how: &RecordGather,
    rng: &mut R,
    stats: &mut ShadingStats,
) -> Result<GatheredRecord, CacheError> {
    let point = &target.point;
    let frame = point.turned_frame(rng);
    let samples = how.samples(transport, point, &frame, rule.directions(), rng, stats)?;
    Ok(GatheredRecord { frame, samples })
}

#[cfg(test)]
pub(crate) mod tests;
