//! The point query end to end in the library: records placed among a
//! query's points are held and reused, and the answer says what moved.

use super::*;
use crate::estimators::EstimatorSpec;
use crate::render::{PathDepth, PointDoc};

/// A grid of `n` points on the Cornell box's floor, facing up.
fn floor_points(n: usize) -> Vec<PointDoc> {
    let side = (n as f64).sqrt().ceil() as usize;
    (0..n)
        .map(|i| {
            let (u, v) = ((i % side) as f64, (i / side) as f64);
            let at = |t: f64| -0.8 + 1.6 * (t + 0.5) / side as f64;
            PointDoc {
                position: [at(u), -0.999, at(v)],
                normal: [0.0, 1.0, 0.0],
            }
        })
        .collect()
}

fn run(
    transport: &Transport,
    spec: &PointQuerySpec,
    kept: (&FittedKernels, &Calibrations, &HeldRecords, &PointRecords),
) -> PointAnswer {
    let (kernels, calibrations, store, gatherings) = kept;
    let query = spec.resolve(transport.scene(), 4096).expect("valid");
    let quadratures = Arc::new(QuadratureCache::new(64 << 20));
    let state = QueryState {
        kernels,
        calibrations,
        quadratures: &quadratures,
        store,
        gatherings,
        shared: Vec::new(),
        max_records: 1 << 16,
    };
    query
        .estimate(transport, state, &|| {}, &Cancel::never())
        .expect("estimates")
}

/// A query of many points places records among them once, keeps them,
/// and leans on them: the answer counts the points they moved, a repeated
/// query finds them held (no amortised rays) and answers the same.
#[test]
fn records_placed_among_points_are_kept_and_used() {
    let transport = crate::testing::cornell(8);
    let spec = PointQuerySpec {
        points: floor_points(MIN_POINTS_FOR_RECORDS),
        estimator: EstimatorSpec {
            samples: Some(16),
            calibrate: Some(false),
            ..EstimatorSpec::default()
        },
        max_depth: Some(PathDepth::new(2).unwrap()),
        ..PointQuerySpec::default()
    };
    let kept = (
        &FittedKernels::default(),
        &Calibrations::default(),
        &HeldRecords::default(),
        &PointRecords::new(1 << 24, 1 << 26),
    );
    let first = run(&transport, &spec, kept);
    assert!(
        first.amortised_rays > 0,
        "records placed and a kernel fitted"
    );
    let moved = first.records_prior_points.expect("bmc uses the records");
    assert!(moved > 0, "records cover the floor");
    assert_eq!(
        first.prior_used.as_ref().map(Vec::len),
        Some(spec.points.len())
    );
    let again = run(&transport, &spec, kept);
    assert_eq!(again.amortised_rays, 0, "everything kept");
    assert_eq!(again.irradiance, first.irradiance);
    // Fewer points than records need: none placed, nothing to lean on.
    let few = PointQuerySpec {
        points: floor_points(3),
        ..spec.clone()
    };
    let fresh = (
        &FittedKernels::default(),
        &Calibrations::default(),
        &HeldRecords::default(),
        &PointRecords::new(1 << 24, 1 << 26),
    );
    assert_eq!(run(&transport, &few, fresh).records_prior_points, Some(0));
}

/// The query's budget is its points times the larger of its paths and its
/// light samples, a target's cap replacing the per-point samples.
#[test]
fn estimated_paths_count_the_target_and_light_samples() {
    let transport = crate::testing::cornell(8);
    let mut spec = PointQuerySpec {
        points: floor_points(10),
        ..PointQuerySpec::default()
    };
    let paths = |spec: &PointQuerySpec| {
        spec.resolve(transport.scene(), 4096)
            .unwrap()
            .estimated_paths()
    };
    assert_eq!(paths(&spec), 10 * 64);
    spec.estimator.light_samples = Some(256);
    assert_eq!(paths(&spec), 10 * 256);
    spec.target = Some(crate::estimators::error_target::TargetSpec {
        relative_error: 0.05,
        confidence: None,
        max_samples: None,
    });
    assert_eq!(paths(&spec), 10 * 4096 * 4);
}

/// Errors name the field below the query.
#[test]
fn bad_points_and_options_name_their_field() {
    let transport = crate::testing::cornell(8);
    let mut spec = PointQuerySpec {
        points: floor_points(2),
        ..PointQuerySpec::default()
    };
    spec.points[1].normal = [0.0; 3];
    match spec.resolve(transport.scene(), 4096) {
        Err(EstimatorError::InvalidQuery { field, .. }) => assert_eq!(field, "points[1].normal"),
        other => panic!("{other:?}"),
    }
    spec.points[1].normal = [0.0, 1.0, 0.0];
    spec.estimator.samples = Some(0);
    match spec.resolve(transport.scene(), 4096) {
        Err(EstimatorError::Invalid { field, .. }) => assert_eq!(field, "samples"),
        other => panic!("{other:?}"),
    }
}
