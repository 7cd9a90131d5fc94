use super::*;
use crate::estimators::spec::{
    DEFAULT_SAMPLE_SET, DEFAULT_VARIANCE, EstimatorMethod, SampleSetChoice,
};
use crate::estimators::{KernelSpec, Lengthscale};
use crate::sphere::SampleSetKind;

fn spec(method: EstimatorMethod) -> EstimatorSpec {
    EstimatorSpec {
        method: Some(method),
        samples: Some(16),
        records_prior: RecordsPriorMode::Set(false),
        ..EstimatorSpec::default()
    }
}

fn field(result: Result<PointEstimator, EstimatorError>) -> String {
    match result {
        Err(EstimatorError::Invalid { field, .. }) => field,
        other => panic!("expected an invalid field, got {other:?}"),
    }
}

#[test]
fn options_are_checked_against_the_method() {
    assert!(matches!(
        spec(EstimatorMethod::Mc).resolve(),
        Ok(PointEstimator {
            rule: PointRule::Mc { count: 16 },
            prior: PriorChoice::None,
            calibrate: true,
            ..
        })
    ));
    let mc_with_set = EstimatorSpec {
        sample_set: Some(SampleSetChoice {
            kind: Some(SampleSetKind::Fibonacci),
            seed: None,
        }),
        ..spec(EstimatorMethod::Mc)
    };
    assert_eq!(field(mc_with_set.resolve()), "sample_set");
    let qmc_random = EstimatorSpec {
        sample_set: Some(SampleSetChoice {
            kind: Some(SampleSetKind::Uniform),
            seed: Some(3),
        }),
        ..spec(EstimatorMethod::Qmc)
    };
    assert_eq!(field(qmc_random.resolve()), "sample_set.kind");
    let qmc_kernel = EstimatorSpec {
        kernel: Some(KernelSpec::default()),
        ..spec(EstimatorMethod::Qmc)
    };
    assert_eq!(field(qmc_kernel.resolve()), "kernel");
    let zero = EstimatorSpec {
        samples: Some(0),
        ..spec(EstimatorMethod::Bmc)
    };
    assert_eq!(field(zero.resolve()), "samples");
}

#[test]
fn lengthscales_parse_from_text_and_json() {
    assert_eq!("auto".parse(), Ok(Lengthscale::Auto));
    assert_eq!("0.5".parse(), Ok(Lengthscale::Value(0.5)));
    assert!("short".parse::<Lengthscale>().is_err());
    let json: Lengthscale = serde_json::from_str("0.25").unwrap();
    assert_eq!(json, Lengthscale::Value(0.25));
    let json: Lengthscale = serde_json::from_str("\"auto\"").unwrap();
    assert_eq!(json, Lengthscale::Auto);
    assert!(serde_json::from_str::<Lengthscale>("\"long\"").is_err());
}

#[test]
fn bmc_kernel_numbers_are_checked_before_any_work() {
    let overflow = EstimatorSpec {
        kernel: Some(KernelSpec {
            variance: Some(1e308),
            noise: Some(1e308),
            ..KernelSpec::default()
        }),
        ..spec(EstimatorMethod::Bmc)
    };
    assert_eq!(field(overflow.resolve()), "kernel.variance");
    let Ok(PointEstimator {
        rule: PointRule::Bmc(setup),
        prior: PriorChoice::Environment,
        ..
    }) = spec(EstimatorMethod::Bmc).resolve()
    else {
        panic!("bmc resolves, with the environment prior by default");
    };
    // Defaults: Fibonacci-cosine set, the kernel family selected with
    // the "auto" lengthscale.
    assert_eq!(setup.sample_set.kind, DEFAULT_SAMPLE_SET);
    assert_eq!(setup.kind, None);
    assert_eq!(setup.lengthscale, None);
    assert_eq!(setup.variance, DEFAULT_VARIANCE);
}

/// A prior on the direct part that knows each point's irradiance (a
/// Monte Carlo reference of many samples), scaled by `bias`, and states
/// a relative standard deviation `stated`; on the half `x > 0` of the
/// scene only, if `half`.
struct ReferencePrior<'a> {
    transport: &'a Transport,
    bias: f64,
    stated: f64,
    half: bool,
}

impl IntegralPrior for ReferencePrior<'_> {
    fn at(&self, point: &QueryPoint) -> Option<PriorAt> {
        if self.half && point.position().x <= 0.0 {
            return None;
        }
        let options = IrradianceOptions {
            samples: 4096,
            max_depth: crate::render::PathDepth::new(1).unwrap(),
            method: crate::render::IrradianceMethod::Split,
            seed: 99,
            ..IrradianceOptions::default()
        };
        let reference = self
            .transport
            .irradiance_at_points(&[*point], &options, &|| {}, &Cancel::never())
            .unwrap();
        let e = reference[0].irradiance;
        Some(PriorAt {
            mean: e * self.bias,
            variance: crate::render::Rgb::BLACK,
            modelled: e * e * (self.stated * self.stated),
            rays: 0,
        })
    }

    fn state(&self) -> u64 {
        0
    }
}

/// A ground under a constant sky, partly shaded by a square above it.
fn shaded_ground() -> Transport {
    let doc = r#"{
        "materials": [{"id": "grey", "type": "diffuse", "reflectance": [0.5, 0.5, 0.5]}],
        "shapes": [
            {"type": "rectangle", "material": "grey",
             "to_world": [{"scale": [3, 3, 1]}]},
            {"type": "rectangle", "material": "grey",
             "to_world": [{"scale": [0.6, 0.6, 1]}, {"translate": [0, 0, 0.4]}]}
        ],
        "environment": {"type": "constant", "radiance": [1, 1, 1]},
        "camera": {"type": "perspective", "fov": 50, "origin": [0.3, -0.2, 4],
                   "target": [0, 0, 0], "up": [0, 1, 0], "width": 16, "height": 16}
    }"#;
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
    let scene = crate::scene::Scene::from_json_str(doc, dir, dir).unwrap();
    Transport::new(Arc::new(scene))
}

/// `spec`'s estimates at `points` at depth 1, 16 samples and seed 5 under
/// `method`, calibrated with `calibrations`, `direct` its prior on the
/// direct part.
fn estimate_at(
    transport: &Transport,
    points: &[QueryPoint],
    spec: EstimatorSpec,
    method: crate::render::IrradianceMethod,
    calibrations: &Calibrations,
    direct: Option<&dyn IntegralPrior>,
) -> Estimates {
    let options = IrradianceOptions {
        samples: 16,
        max_depth: crate::render::PathDepth::new(1).unwrap(),
        method,
        seed: 5,
        ..IrradianceOptions::default()
    };
    let caches = EstimatorCaches {
        kernels: &FittedKernels::default(),
        quadratures: &QuadratureCache::new(16 << 20),
        calibrations,
        records: None,
        direct,
        amortised: &AmortisedRays::default(),
    };
    spec.resolve()
        .unwrap()
        .estimate(
            transport,
            caches,
            points,
            &options,
            &|| {},
            &Cancel::never(),
        )
        .unwrap()
}

/// On [`shaded_ground`], 16 directions see the square's edges badly, a
/// prior that knows the answer and says it knows it poorly is trusted more
/// than it says, and a wrong prior that says it is sure is trusted less
/// (docs/math.md §10.9); where the prior says nothing, the estimate and its
/// error bar are the rule's.
#[test]
fn the_priors_variance_is_scaled_by_what_the_training_points_show() {
    let transport = shaded_ground();
    let points = super::super::sample_points::camera_points(&transport, 12, 3);
    let run = |records_prior: bool, prior: Option<&ReferencePrior>| {
        let spec = EstimatorSpec {
            records_prior: RecordsPriorMode::Set(records_prior),
            ..spec(EstimatorMethod::Qmc)
        };
        // Each prior is fitted apart (its state says nothing of it).
        estimate_at(
            &transport,
            &points,
            spec,
            crate::render::IrradianceMethod::Hemisphere,
            &Calibrations::default(),
            prior.map(|p| p as &dyn IntegralPrior),
        )
    };
    let prior = |bias, stated, half| ReferencePrior {
        transport: &transport,
        bias,
        stated,
        half,
    };
    let scales = |estimates: &Estimates| estimates.calibration.unwrap().prior_scales.unwrap();
    let trusted = scales(&run(true, Some(&prior(1.0, 0.5, false))));
    assert!(trusted.direct <= 1.0 / 16.0, "{trusted:?}");
    assert_eq!(trusted.records, 1.0, "no records prior");
    let wrong = scales(&run(true, Some(&prior(0.7, 0.01, false))));
    assert!(wrong.direct >= 1.0, "{wrong:?}");
    let rule = run(false, None);
    let half = run(true, Some(&prior(1.0, 0.5, true)));
    let (mut moved, mut kept) = (0, 0);
    for ((with, without), point) in half.estimates.iter().zip(&rule.estimates).zip(&points) {
        if point.position().x <= 0.0 {
            kept += 1;
            assert_eq!(
                (with.irradiance, with.std_error),
                (without.irradiance, without.std_error)
            );
        } else {
            moved += usize::from(with.irradiance != without.irradiance);
        }
    }
    assert!(moved > 0 && kept > 0, "{moved} moved, {kept} kept");
}

/// Which priors moved an estimate is what was combined: a direct part its
/// own samples contradict keeps its value and is not counted, and a point
/// outside the records is left alone.
#[test]
fn only_the_priors_combined_are_reported() {
    use crate::render::{IndirectPart, IrradianceEstimate, Rgb};
    let estimate = IrradianceEstimate {
        irradiance: Rgb::splat(5.0),
        std_error: Rgb::splat(0.5),
        rays: 64,
        indirect: Some(IndirectPart {
            irradiance: Rgb::splat(1.0),
            variance_share: Rgb::splat(0.5),
        }),
        unseen_light: [0.0; 3],
        direct_strata: None,
    };
    let prior = |mean: f64| PriorAt {
        mean: Rgb::splat(mean),
        variance: Rgb::splat(0.01),
        modelled: Rgb::BLACK,
        rays: 0,
    };
    let known = [
        // Records and twins that agree with the estimate (direct part 4).
        KnownPriors {
            records: Some(prior(1.1)),
            direct: Some(prior(4.1)),
        },
        // Twins in shadow where the point is lit.
        KnownPriors {
            records: Some(prior(1.1)),
            direct: Some(prior(0.5)),
        },
        KnownPriors {
            records: None,
            direct: None,
        },
    ];
    let mut estimates = [estimate; 3];
    let combined = combine_priors(&mut estimates, &known, PriorScales::ONE);
    let both = PriorsCombined {
        records: true,
        direct: true,
    };
    let records_only = PriorsCombined {
        records: true,
        direct: false,
    };
    assert_eq!(combined, [both, records_only, PriorsCombined::default()]);
    assert_eq!(estimates[2], estimate);
    // The lit point's direct part kept its own value: the total moved only
    // by what the indirect part moved.
    let indirect_moved = estimates[1].indirect.unwrap().irradiance.r - 1.0;
    assert!((estimates[1].irradiance.r - 5.0 - indirect_moved).abs() < 1e-12);
}

/// A combination keeps the share `w = v / (s² + v)` of the rule's
/// estimate, so at least `w s` of its standard error: with a wide prior
/// almost all of the rule's, with a narrow one little (docs/math.md §10.9).
#[test]
fn combined_bars_keep_the_rule_noise_they_carry() {
    let s = 0.4;
    for v in [100.0, 1.0, 0.01] {
        let (_, posterior) = crate::estimators::integral_prior::combine(
            (Rgb::splat(1.0), Rgb::splat(s * s)),
            (Rgb::splat(2.0), Rgb::splat(v)),
        );
        let least = rule_noise_carried(Rgb::splat(s), posterior.map(f64::sqrt));
        let w = v / (s * s + v);
        assert!((least.g - w * s).abs() < 1e-12, "v = {v}: {least:?}");
    }
    assert_eq!(rule_noise_carried(Rgb::BLACK, Rgb::splat(0.1)), Rgb::BLACK);
}

/// Split direct light is the light samples' mean whatever the rule, so at
/// depth 1 BMC's estimates are QMC's and must be calibrated alike, with
/// the term for light every sample missed (docs/math.md §10.5).
#[test]
fn split_direct_light_is_calibrated_alike_for_every_rule() {
    let transport = shaded_ground();
    let points = super::super::sample_points::camera_points(&transport, 12, 3);
    let calibrations = Calibrations::default();
    let run = |method| {
        let split = crate::render::IrradianceMethod::Split;
        estimate_at(
            &transport,
            &points,
            spec(method),
            split,
            &calibrations,
            None,
        )
    };
    let (qmc, bmc) = (run(EstimatorMethod::Qmc), run(EstimatorMethod::Bmc));
    let unseen = |e: &Estimates| e.calibration.unwrap().unseen;
    assert!(unseen(&bmc) > 0.0);
    assert_eq!(unseen(&bmc), unseen(&qmc));
    assert_eq!(bmc.estimates, qmc.estimates);
}
