//! Irradiance at points with any [`HemisphereEstimator`] (MC, QMC or BMC;
//! docs/math.md §3, §6) over the incident radiance of a scene.
//!
//! Per point `i` (all random numbers from [`point_rng`]`(seed, i)`, so the
//! result does not depend on the thread count):
//! 1. a random rotation of the shading frame about the normal: it turns the
//!    structured error of a fixed sample set into noise and leaves the BMC
//!    weights exact, because `Q` and the Lambert kernel means are invariant
//!    under it (docs/math.md §5);
//! 2. the estimator's directions (fixed for QMC/BMC, fresh draws for MC) are
//!    traced with [`Transport::hemisphere_samples`];
//! 3. each RGB channel is combined by the estimator, which integrates against
//!    the Lambert density `cos θ/π`, so `E = π I` ([`irradiance_from_lambert`]).
//!
//! [`IrradianceMethod::Split`] adds light-sampled direct light
//! ([`Transport::direct_irradiance`], `options.light_samples()` of them) to the
//! hemisphere estimate of path lengths `2..=max_depth`; the two parts use
//! disjoint random numbers, so their variances add. The reported standard
//! deviation is the square root of the estimator's variance: for BMC the
//! GP posterior variance with the amplitude fitted per point and channel
//! (the caller chooses, see [`crate::bmc::estimator::BmcVariance`]), for
//! MC/QMC the sample variance of the mean. Where paths reflect, the estimate
//! also reports its indirect part (paths of 2 or more segments), for a prior
//! on it (docs/math.md §10.7), with its share of the variance: in split
//! mode the hemisphere rule's whole estimate, whose variance is the rule's
//! beside the light samples'; under the hemisphere decomposition, when
//! [`HemisphereRule::indirect_part`] asks, the rule over each value less the
//! emission its direction sees directly.

use rayon::prelude::*;

use super::integral_prior::share;
use crate::bmc::estimator::{HemisphereEstimator, irradiance_from_lambert};
use crate::render::Cancel;
use crate::render::QueryPoint;
use crate::render::RenderError;
use crate::render::Rgb;
use crate::render::Transport;
use crate::render::environment_prior::{EnvironmentPrior, PriorChoice};
use crate::render::nothing_seen;
use crate::render::seed::point_rng;
use crate::render::{Decomposition, IndirectPart, IrradianceEstimate, IrradianceOptions};
use crate::render::{PathLengths, PathLimits, TraceStats};

/// The rule of the hemisphere part, run by [`HemisphereRule::estimate`].
#[derive(Clone, Copy)]
pub struct HemisphereRule<'a> {
    /// The rule; it must integrate against the Lambert density `cos θ/π`.
    pub estimator: &'a dyn HemisphereEstimator,
    /// Subtracted from the hemisphere values, its exact integral added back
    /// ([`Transport::hemisphere_prior`] says where it applies).
    pub prior: PriorChoice,
    /// Also estimate the indirect part under the hemisphere decomposition
    /// (for a prior on it, docs/math.md §10.7), at three more evaluations of
    /// the rule per point; split estimates always report theirs (the rule's
    /// whole estimate).
    pub indirect_part: bool,
}

/// A [`HemisphereRule`] resolved for the scene: the prior that applies and
/// the decomposition.
#[derive(Clone, Copy)]
struct ResolvedRule<'a> {
    estimator: &'a dyn HemisphereEstimator,
    prior: Option<&'a EnvironmentPrior>,
    decomposition: Decomposition,
    indirect_part: bool,
}

impl HemisphereRule<'_> {
    /// Irradiance at every point of `transport`'s scene with this rule for the hemisphere part
    /// (module docs), in parallel on the current rayon pool.
    ///
    /// `options.light_samples()` is the number of light samples of the
    /// direct part in split mode; the hemisphere sample count is the
    /// estimator's. `on_done`
    /// is called once per finished point; stops between points once `cancel`
    /// is set.
    pub fn estimate(
        &self,
        transport: &Transport,
        points: &[QueryPoint],
        options: &IrradianceOptions,
        on_done: &(dyn Fn() + Sync),
        cancel: &Cancel,
    ) -> Result<Vec<IrradianceEstimate>, RenderError> {
        options.validate()?;
        let decomposition = transport.decomposition(options.method);
        let resolved = ResolvedRule {
            estimator: self.estimator,
            prior: transport.hemisphere_prior(self.prior, decomposition),
            decomposition,
            indirect_part: self.indirect_part,
        };
        points
            .par_iter()
            .enumerate()
            .map(|(i, point)| {
                cancel.check()?;
                let estimate = estimate_point(transport, point, i as u64, &resolved, options);
                on_done();
                estimate
            })
            .collect()
    }
}

/// One point's estimate (module docs).
fn estimate_point(
    transport: &Transport,
    point: &QueryPoint,
    index: u64,
    rule: &ResolvedRule,
    options: &IrradianceOptions,
) -> Result<IrradianceEstimate, RenderError> {
    let ResolvedRule {
        estimator,
        prior,
        decomposition,
        indirect_part,
    } = *rule;
    let mut rng = point_rng(options.seed, index);
    let mut stats = TraceStats::default();
    let depth = options.effective_max_depth();
    let frame = point.turned_frame(&mut rng);
    let lengths = match decomposition {
        Decomposition::Hemisphere => Some(PathLengths::All),
        Decomposition::Split => depth.has_reflections().then_some(PathLengths::Indirect),
    };
    let (mut irradiance, mut variance) = (Rgb::BLACK, Rgb::BLACK);
    let mut indirect = None;
    let mut unseen_light = [1.0; 3];
    let mut direct_strata = None;
    if let Some(lengths) = lengths {
        let directions = estimator.directions(&mut rng);
        let limits = PathLimits {
            max_depth: depth,
            lengths,
        };
        let samples =
            transport.hemisphere_samples(point, &frame, &directions, limits, &mut rng, &mut stats);
        // The prior at each direction (zero where a direction carries
        // nothing) and its exact Lambert integral (docs/math.md §10.4).
        let (prior_values, prior_integral) = match prior {
            Some(prior) => (
                directions
                    .iter()
                    .map(|d| {
                        if d.z > 0.0 && d.is_finite() {
                            prior.radiance(frame.to_world(d.normalize()))
                        } else {
                            Rgb::BLACK
                        }
                    })
                    .collect(),
                prior.lambert_integral(point.normal()),
            ),
            None => (vec![Rgb::BLACK; directions.len()], Rgb::BLACK),
        };
        let estimate = |values: &[f64]| {
            estimator
                .estimate(&directions, values)
                .map_err(|err| RenderError::InvalidOption {
                    field: "estimator",
                    reason: err.to_string(),
                })
        };
        // Only paths that reflect have an indirect part (at depth 1 it
        // is zero by definition, and no prior may move it). Under the
        // hemisphere decomposition it is the same rule over each value
        // less the emission its direction sees directly (docs/math.md
        // §10.7), with the share of the variance that is the part's.
        let hemisphere_part =
            indirect_part && lengths == PathLengths::All && depth.has_reflections();
        let mut value = [0.0; 3];
        let mut var = [0.0; 3];
        let mut part = [0.0; 3];
        let mut share = [1.0; 3];
        for c in 0..3 {
            let channel: Vec<f64> = samples
                .iter()
                .zip(&prior_values)
                .map(|(s, m)| s.radiance.to_array()[c] - m.to_array()[c])
                .collect();
            let mut e = estimate(&channel)?;
            e.value += prior_integral.to_array()[c];
            if e.value < 0.0 && prior.is_some() {
                // A negative total of a non-negative integral: the rule
                // without the prior on the same samples, which the
                // negative-weight guard covers (docs/math.md §3.6).
                let raw: Vec<f64> = samples.iter().map(|s| s.radiance.to_array()[c]).collect();
                e = estimate(&raw)?;
            }
            let e = irradiance_from_lambert(e);
            value[c] = e.value;
            var[c] = e.variance;
            if hemisphere_part {
                let channel: Vec<f64> = samples
                    .iter()
                    .map(|s| s.radiance.to_array()[c] - s.direct.to_array()[c])
                    .collect();
                let p = irradiance_from_lambert(estimate(&channel)?);
                part[c] = p.value;
                if e.variance > 0.0 {
                    share[c] = (p.variance / e.variance).clamp(0.0, 1.0);
                }
            }
        }
        irradiance = Rgb::from_array(value);
        variance = Rgb::from_array(var);
        indirect = if lengths == PathLengths::Indirect {
            Some(IndirectPart::whole(irradiance))
        } else if hemisphere_part {
            Some(IndirectPart {
                irradiance: Rgb::from_array(part),
                variance_share: Rgb::from_array(share),
            })
        } else {
            None
        };
    }
    if decomposition == Decomposition::Split {
        let (direct, strata) =
            transport.direct_irradiance(point, options.light_samples(), &mut rng, &mut stats);
        direct_strata = strata;
        irradiance += direct.mean;
        unseen_light = nothing_seen(direct.mean);
        let indirect_variance = variance;
        variance += direct.variance_of_mean;
        // The indirect part's share is its own variance over the
        // whole's (docs/math.md §10.7): a prior on it must not take
        // away the light samples' variance.
        if let Some(part) = indirect.as_mut() {
            part.variance_share = share(indirect_variance, variance);
        }
    }
    Ok(IrradianceEstimate {
        irradiance,
        std_error: variance.map(f64::sqrt),
        rays: stats.rays,
        indirect,
        unseen_light,
        direct_strata,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bmc::cache::QuadratureCache;
    use crate::bmc::estimator::{BayesianEstimator, BmcVariance, SampleMeanEstimator, SamplingPdf};
    use crate::bmc::{Density, Kernel, KernelKind, KernelMeanMethod, PriorMean};
    use crate::render::IrradianceMethod;
    use crate::sphere::{SampleSetKind, SampleSetSpec};
    use crate::testing::cornell;
    use glam::DVec3;

    /// BMC on cosine Fibonacci points; the noise ratio 1e-3 regularises the
    /// weights of the smooth SE kernel (with 1e-8 they oscillate).
    fn bmc(count: usize, lengthscale: f64) -> BayesianEstimator {
        let noise = 1e-3;
        let kernel = Kernel::new(KernelKind::SquaredExponential, lengthscale, 1.0, noise).unwrap();
        let spec = SampleSetSpec {
            kind: SampleSetKind::FibonacciCosine,
            count,
            seed: 0,
        };
        let (q, _) = QuadratureCache::new(1 << 24)
            .quadrature(
                spec,
                &kernel,
                &Density::Lambert,
                PriorMean::Gls,
                KernelMeanMethod::Exact,
            )
            .unwrap();
        BayesianEstimator::new(q, BmcVariance::AmplitudeFit)
    }

    fn options(light_samples: u32, seed: u64) -> IrradianceOptions {
        IrradianceOptions {
            samples: light_samples,
            light_samples: Some(light_samples),
            max_depth: crate::render::PathDepth::constant(3),
            direct_only: false,
            method: IrradianceMethod::Split,
            seed,
        }
    }

    /// A point on the Cornell box's back wall, facing into the box.
    fn wall_point() -> QueryPoint {
        QueryPoint::new(DVec3::new(0.2, 0.4, -0.999), DVec3::Z).unwrap()
    }

    /// The estimate at [`wall_point`] by BMC on 64 directions, reporting
    /// its indirect part.
    fn wall_estimate(options: IrradianceOptions) -> IrradianceEstimate {
        let estimator = bmc(64, 0.5);
        let rule = HemisphereRule {
            estimator: &estimator,
            prior: PriorChoice::None,
            indirect_part: true,
        };
        rule.estimate(
            &cornell(8),
            &[wall_point()],
            &options,
            &|| {},
            &Cancel::never(),
        )
        .unwrap()[0]
    }

    #[test]
    fn bmc_agrees_with_the_mc_reference_and_beats_mc_at_equal_samples() {
        let transport = cornell(8);
        let point = [wall_point()];
        // The reference comes from the independent MC path of `irradiance.rs`.
        let reference = transport
            .irradiance_at_points(&point, &options(65536, 99), &|| {}, &Cancel::never())
            .unwrap()[0];
        let bmc = bmc(64, 0.5);
        let mc =
            SampleMeanEstimator::monte_carlo(Density::Lambert, SamplingPdf::Cosine, 64).unwrap();
        // Many light samples make the direct part nearly exact for both, so
        // the comparison is about the hemisphere estimators at N = 64.
        let (mut bmc_sq, mut mc_sq, mut within) = (0.0, 0.0, 0);
        let runs = 32;
        for seed in 0..runs {
            let b = HemisphereRule {
                estimator: &bmc,
                prior: PriorChoice::None,
                indirect_part: false,
            }
            .estimate(
                &transport,
                &point,
                &options(4096, seed),
                &|| {},
                &Cancel::never(),
            )
            .unwrap()[0];
            let m = HemisphereRule {
                estimator: &mc,
                prior: PriorChoice::None,
                indirect_part: false,
            }
            .estimate(
                &transport,
                &point,
                &options(4096, seed),
                &|| {},
                &Cancel::never(),
            )
            .unwrap()[0];
            let (e_b, e_m, e_r) = (
                b.irradiance.luminance(),
                m.irradiance.luminance(),
                reference.irradiance.luminance(),
            );
            bmc_sq += (e_b - e_r).powi(2);
            mc_sq += (e_m - e_r).powi(2);
            let sigma =
                (b.std_error.luminance().powi(2) + reference.std_error.luminance().powi(2)).sqrt();
            within += usize::from((e_b - e_r).abs() <= 3.0 * sigma);
        }
        assert!(
            within >= 27,
            "{within}/{runs} BMC estimates within 3σ of the reference"
        );
        // Measured RMS errors: BMC 0.029, MC 0.046 (QMC 0.033). With one
        // path-traced sample per direction the path noise bounds what any rule
        // can gain; at other points (e.g. on the floor near the open front)
        // the three are within a few per cent of each other.
        assert!(
            bmc_sq < mc_sq,
            "BMC {bmc_sq} vs MC {mc_sq} (sums of squared errors)"
        );
    }

    /// Under the hemisphere decomposition the indirect part is the rule over
    /// the values less what each direction sees directly: the whole less the
    /// part is then the depth-1 estimate on the same directions (the light
    /// is seen directly from the wall), and there is no part at depth 1.
    #[test]
    fn the_hemisphere_indirect_part_is_the_whole_less_the_direct_light() {
        let run = |max_depth: u32| {
            wall_estimate(IrradianceOptions {
                max_depth: crate::render::PathDepth::constant(max_depth),
                method: IrradianceMethod::Hemisphere,
                light_samples: None,
                ..options(1, 17)
            })
        };
        let (whole, direct) = (run(8), run(1));
        assert_eq!(direct.indirect, None);
        let part = whole.indirect.expect("an indirect part at depth 8");
        for c in 0..3 {
            let (w, p, d) = (
                whole.irradiance.to_array()[c],
                part.irradiance.to_array()[c],
                direct.irradiance.to_array()[c],
            );
            assert!(d > 0.0 && p > 0.0, "direct {d}, indirect {p}");
            assert!((w - p - d).abs() <= 1e-12 * w, "{w} − {p} vs {d}");
            let share = part.variance_share.to_array()[c];
            assert!((0.0..=1.0).contains(&share), "share {share}");
        }
    }

    /// In split mode the indirect part carries the rule's variance, not the
    /// light samples' (docs/math.md §10.7): a prior on it as good as
    /// certain leaves the direct part's variance in the error bar.
    #[test]
    fn a_split_prior_on_the_indirect_part_keeps_the_light_samples_variance() {
        let run = |max_depth: u32| {
            wall_estimate(IrradianceOptions {
                max_depth: crate::render::PathDepth::constant(max_depth),
                ..options(16, 23)
            })
        };
        let (mut whole, direct) = (run(8), run(1));
        let part = whole.indirect.expect("an indirect part in split mode");
        let total = whole.std_error * whole.std_error;
        let certain = (part.irradiance, Rgb::splat(1e-30));
        assert!(super::super::integral_prior::combine_part(
            &mut whole, certain
        ));
        let kept = whole.std_error * whole.std_error;
        // The depth-1 run's variance is the light samples' alone (other
        // samples of the same light, so the same size within noise).
        let direct_variance = direct.std_error * direct.std_error;
        for c in 0..3 {
            let share = part.variance_share.to_array()[c];
            let (t, k, d) = (
                total.to_array()[c],
                kept.to_array()[c],
                direct_variance.to_array()[c],
            );
            assert!(share > 0.0 && share < 1.0, "share {share}");
            assert!((k - (1.0 - share) * t).abs() <= 1e-9 * t, "kept {k} of {t}");
            assert!(k > d / 3.0 && k < 3.0 * d, "kept {k}, light samples' {d}");
        }
    }

    #[test]
    fn results_do_not_depend_on_the_thread_count() {
        let transport = cornell(8);
        let points: Vec<_> = (0..12)
            .map(|i| {
                QueryPoint::new(DVec3::new(-0.999, -0.5 + 0.08 * i as f64, 0.1), DVec3::X).unwrap()
            })
            .collect();
        let estimator = bmc(16, 0.6);
        let run = |threads| {
            rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap()
                .install(|| {
                    HemisphereRule {
                        estimator: &estimator,
                        prior: PriorChoice::None,
                        indirect_part: false,
                    }
                    .estimate(
                        &transport,
                        &points,
                        &options(4, 5),
                        &|| {},
                        &Cancel::never(),
                    )
                })
                .unwrap()
        };
        assert_eq!(run(1), run(3));
    }
}
