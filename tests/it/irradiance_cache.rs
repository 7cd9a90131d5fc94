//! End-to-end tests of the Bayesian irradiance cache on the bundled Cornell
//! box: reproducible two-pass placement, variance-driven placement, the
//! occlusion check, and agreement of BMC records with Monte Carlo.

use std::f64::consts::PI;
use std::path::Path;
use std::sync::Arc;

use bmc_irradiance::bmc::{Kernel, KernelKind, PriorMean};
use bmc_irradiance::cache::{
    Accuracy, CacheConfig, Interpolated, IrradianceCache, RECORD_BYTES, Record, RecordRule,
    RecordRuleSpec,
};
use bmc_irradiance::integrator::cached::{
    CacheShadingOptions, Gather, PlacementCache, PlacementOptions, PlacementPoint, RecordGather,
    ShadingStats, compute_record, lookup, place_and_shade, place_records,
};
use bmc_irradiance::optics::warp;
use bmc_irradiance::render::Cancel;
use bmc_irradiance::render::MeanEstimate;
use bmc_irradiance::render::seed::point_rng;
use bmc_irradiance::render::{
    PathDepth, PathLengths, PathLimits, QueryPoint, Rgb, TraceStats, Transport,
};
use bmc_irradiance::scene::Scene;
use bmc_irradiance::sphere::{Frame, SampleSetKind, SampleSetSpec};
use bmc_irradiance::testing::{agrees, flat_record};
use glam::DVec3;
use rand::RngExt;

fn cornell() -> Transport {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes");
    let scene = Scene::load(&dir.join("cornell-box.json"), &dir).expect("bundled scene");
    Transport::new(Arc::new(scene))
}

fn rule(count: usize) -> RecordRule {
    RecordRule::new(RecordRuleSpec {
        samples: SampleSetSpec {
            kind: SampleSetKind::Fibonacci,
            count,
            seed: 0,
        },
        kernel: Kernel::new(KernelKind::SquaredExponential, 0.5, 1.0, 1e-3).unwrap(),
        prior_mean: PriorMean::Gls,
    })
    .unwrap()
}

fn config() -> CacheConfig {
    CacheConfig {
        min_radius: 0.02,
        max_radius: 0.5,
        ..CacheConfig::default()
    }
}

fn options(seed: u64) -> PlacementOptions {
    PlacementOptions {
        paths: PathLimits {
            max_depth: PathDepth::constant(3),
            lengths: PathLengths::Indirect,
        },
        accuracy: Accuracy::new(0.5).unwrap(),
        relative_error_target: None,
        occlusion_check: false,
        paths_per_direction: 1,
        seed,
        batch_size: 16,
    }
}

/// A `k × k` grid on the back wall (z = −1, facing +z), in pixel order.
fn back_wall(k: usize) -> Vec<PlacementPoint> {
    let mut out = Vec::new();
    for j in 0..k {
        for i in 0..k {
            let u = |t: usize| -0.9 + 1.8 * (t as f64 + 0.5) / k as f64;
            out.push(PlacementPoint {
                point: QueryPoint::new(DVec3::new(u(i), u(j), -1.0), DVec3::Z).unwrap(),
                footprint: None,
            });
        }
    }
    out
}

fn bits(values: &[Option<Interpolated>]) -> Vec<Option<([u64; 6], usize)>> {
    values
        .iter()
        .map(|v| {
            v.map(|v| {
                let (e, var) = (v.irradiance.to_array(), v.variance.to_array());
                (
                    [e[0], e[1], e[2], var[0], var[1], var[2]].map(f64::to_bits),
                    v.records_used,
                )
            })
        })
        .collect()
}

fn with_threads<T: Send>(n: usize, f: impl FnOnce() -> T + Send) -> T {
    rayon::ThreadPoolBuilder::new()
        .num_threads(n)
        .build()
        .unwrap()
        .install(f)
}

#[test]
fn two_pass_placement_is_bit_identical_across_thread_counts_and_history() {
    let transport = cornell();
    let rule = rule(48);
    let points = back_wall(12);
    let run = || place_and_shade(&transport, &rule, config(), &points, &options(7)).unwrap();
    let (one, cache_one, report) = with_threads(1, run);
    // An unrelated request on a shared cache first, then the same request.
    let shared = IrradianceCache::new(config()).unwrap();
    with_threads(2, || {
        place_records(
            PlacementCache::Shared(&shared),
            &transport,
            &rule,
            &back_wall(5),
            &options(99),
            Gather::Paths,
            &Cancel::never(),
        )
        .unwrap()
    });
    let (two, cache_two, _) = with_threads(2, run);
    assert_eq!(bits(&one), bits(&two));
    assert_eq!(cache_one.records(), cache_two.records());
    // Every point was covered and records were reused.
    assert!(one.iter().all(Option::is_some));
    let records = cache_one.stats().records;
    assert_eq!(records, report.records_created);
    assert!(records < points.len() as u64 * 3 / 4, "{records} records");
    assert!(one.iter().any(|v| v.is_some_and(|v| v.records_used > 1)));
    // A different seed gives different values.
    let (other, _, _) = place_and_shade(&transport, &rule, config(), &points, &options(8)).unwrap();
    assert_ne!(bits(&one), bits(&other));
}

/// A pass over a cache only it reads inserts records once their first
/// segments are traced, then traces their paths and estimates them in
/// batches; the cache must end as if each record had gone in finished:
/// same records, values, radii (neighbour clamp), evictions and rays, bit
/// for bit, with several held-back batches in one pass and with paths
/// averaged per direction (their first-vertex strata).
#[test]
fn held_back_estimates_leave_the_cache_as_finished_inserts() {
    let transport = cornell();
    let rule = rule(32);
    let points = back_wall(20);
    let place = |config: CacheConfig, private: bool, paths_per_direction: u32| {
        let cache = IrradianceCache::new(config).unwrap();
        let into = if private {
            PlacementCache::Private(&cache)
        } else {
            PlacementCache::Shared(&cache)
        };
        let report = with_threads(1, || {
            place_records(
                into,
                &transport,
                &rule,
                &points,
                &PlacementOptions {
                    paths_per_direction,
                    ..options(5)
                },
                Gather::Paths,
                &Cancel::never(),
            )
            .unwrap()
        });
        (cache.records(), report, cache.stats().evictions)
    };
    let tight = CacheConfig {
        byte_budget: 40 * RECORD_BYTES,
        ..config()
    };
    for (config, paths) in [(config(), 1), (tight, 1), (config(), 3)] {
        let (held, held_report, held_evictions) = place(config, true, paths);
        let (finished, report, evictions) = place(config, false, paths);
        assert_eq!(held, finished);
        assert_eq!(held_report, report);
        assert_eq!(held_evictions, evictions);
        // More than one held-back batch of 32 (one thread), values filled in.
        assert!(report.records_created > 64, "{report:?}");
        assert!(
            held.iter()
                .all(|r| r.irradiance.to_array().iter().all(|&e| e > 0.0))
        );
    }
}

#[test]
fn a_variance_target_places_more_records() {
    let transport = cornell();
    let rule = rule(32);
    let points = back_wall(8);
    let plain = options(3);
    let (_, _, base) = place_and_shade(&transport, &rule, config(), &points, &plain).unwrap();
    let strict = PlacementOptions {
        relative_error_target: Some(1e-4),
        ..plain
    };
    let (values, _, more) = place_and_shade(&transport, &rule, config(), &points, &strict).unwrap();
    assert_eq!(base.records_for_variance, 0);
    assert!(more.records_for_variance > 0);
    assert!(more.records_created > base.records_created);
    assert!(values.iter().all(Option::is_some));
    // Options are checked once, where they are resolved; placement trusts them.
    let bad = CacheShadingOptions {
        batch_size: 0,
        ..CacheShadingOptions::default()
    };
    assert_eq!(bad.validate().unwrap_err().field(), Some("batch_size"));
}

/// The small box stands on the floor around (0.335, −1, 0.38); a record on
/// one side must not light a floor point on the other side when the
/// occlusion check is on.
#[test]
fn occlusion_check_stops_records_leaking_through_a_box() {
    let transport = cornell();
    let cache = IrradianceCache::new(CacheConfig {
        max_radius: 1.0,
        ..config()
    })
    .unwrap();
    cache
        .insert(flat_record(
            DVec3::new(0.335, -1.0, -0.1),
            DVec3::Y,
            Rgb::WHITE,
            1.0,
        ))
        .unwrap();
    let behind_box = QueryPoint::new(DVec3::new(0.335, -1.0, 0.86), DVec3::Y).unwrap();
    let beside = QueryPoint::new(DVec3::new(0.335, -1.0, -0.5), DVec3::Y).unwrap();
    let mut o = options(1);
    o.accuracy = Accuracy::new(1.0).unwrap();
    assert!(lookup(&cache, &transport, &behind_box, &o).is_some());
    o.occlusion_check = true;
    assert!(lookup(&cache, &transport, &behind_box, &o).is_none());
    assert!(lookup(&cache, &transport, &beside, &o).is_some());
}

/// Indirect light (path lengths 2..=6) of the back-wall record tests.
const INDIRECT: PathLimits = PathLimits {
    max_depth: PathDepth::constant(6),
    lengths: PathLengths::Indirect,
};

fn back_wall_point() -> PlacementPoint {
    PlacementPoint {
        point: QueryPoint::new(DVec3::new(0.2, 0.3, -1.0), DVec3::Z).unwrap(),
        footprint: None,
    }
}

/// `count` independent records (rotations and paths from `point_rng(seed, i)`)
/// at [`back_wall_point`], each direction averaging `per_direction` paths.
fn back_wall_records(rule: &RecordRule, count: u64, seed: u64, per_direction: u32) -> Vec<Record> {
    let transport = cornell();
    let limits = config().validate().unwrap();
    (0..count)
        .map(|i| {
            let mut rng = point_rng(seed, i);
            let mut stats = ShadingStats::default();
            let how = RecordGather {
                paths: INDIRECT,
                per_direction,
                gather: Gather::Paths,
            };
            let point = back_wall_point();
            compute_record(&transport, rule, &point, limits, &how, &mut rng, &mut stats).unwrap()
        })
        .collect()
}

/// Indirect irradiance (path lengths 2..=6) at a back-wall point: the mean of
/// 8 BMC records (independent rotations and paths) against 8192-sample
/// cosine-weighted Monte Carlo, within 4 combined standard errors.
#[test]
fn bmc_record_agrees_with_monte_carlo_indirect_irradiance() {
    let transport = cornell();
    let (paths, target) = (INDIRECT, back_wall_point());
    let limits = config().validate().unwrap();
    let records = back_wall_records(&rule(128), 8, 11, 1);
    let bmc = MeanEstimate::of(records.iter().map(|r| r.irradiance));

    let mut rng = point_rng(12, 0);
    let dirs: Vec<DVec3> = (0..8192)
        .map(|_| warp::cosine_hemisphere([rng.random(), rng.random()]))
        .collect();
    let frame = Frame::from_normal(DVec3::Z);
    let mut stats = TraceStats::default();
    let samples =
        transport.hemisphere_samples(&target.point, &frame, &dirs, paths, &mut rng, &mut stats);
    let mc = MeanEstimate::of(samples.iter().map(|s| s.radiance * PI));

    for c in 0..3 {
        let (b, m) = (bmc.mean.to_array()[c], mc.mean.to_array()[c]);
        let se = (bmc.variance_of_mean.to_array()[c] + mc.variance_of_mean.to_array()[c]).sqrt();
        assert!(m > 0.0);
        assert!(
            agrees(b, m, se, 4.0, 0.0),
            "channel {c}: BMC {b} vs MC {m} (se {se})"
        );
    }
    for r in &records {
        assert!(r.radius >= limits.min && r.radius <= limits.max);
        assert!(r.variance.to_array().iter().all(|v| *v > 0.0));
    }
}

/// A record's variance covers its error: with several paths per direction
/// it adds the values' Monte Carlo noise (`π² Σ w_i² Var(L_i)`, from the
/// paths' spread) to the rule's posterior variance, and over 40 independent
/// records at one point (new rotations and paths) the spread of `E` is then
/// within a small factor of the mean reported variance.
#[test]
fn record_variance_covers_the_spread_of_records() {
    let records = back_wall_records(&rule(64), 40, 21, 4);
    let spread = MeanEstimate::of(records.iter().map(|r| r.irradiance));
    let reported = MeanEstimate::of(records.iter().map(|r| r.variance)).mean;
    for c in 0..3 {
        // Sample variance of E over the records.
        let empirical = spread.variance_of_mean.to_array()[c] * records.len() as f64;
        let reported = reported.to_array()[c];
        // Measured: 1.4–1.8 (the rule's posterior alone gives 4.6, at
        // one path per direction 3.6: the values' noise was missing).
        assert!(
            empirical < 2.5 * reported && empirical > 0.25 * reported,
            "channel {c}: spread {empirical} vs reported {reported}"
        );
    }
}
