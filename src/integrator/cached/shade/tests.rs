use super::*;
use crate::bmc::cache::QuadratureCache;
use crate::cache::RecordRuleSpec;
use crate::integrator::cached::{CacheShadingOptions, default_rule_spec};
use crate::render::{MeanEstimate, PathDepth};
use crate::scene::Ray;
use crate::testing::{agrees, cornell};
use rand::SeedableRng;
use rand_pcg::Pcg64;
use std::sync::Arc;

/// Rules for `spec` with 4 glossy nodes and a private quadrature cache.
fn test_shading(spec: RecordRuleSpec, options: CacheShadingOptions) -> CachedShading {
    let quadratures = Arc::new(QuadratureCache::new(1 << 24));
    CachedShading::new(spec, 4, quadratures, options).unwrap()
}

fn small_spec() -> RecordRuleSpec {
    let mut spec = default_rule_spec();
    spec.samples.count = 16;
    spec
}

/// Asserts that 24 records on the Cornell box's back wall whose rays
/// gather as `gathered` says agree with 24 gathered by paths, per
/// channel within 4 standard errors plus `rel` of the paths' mean;
/// returns the counters of the former.
pub(crate) fn assert_records_agree(
    transport: &Transport,
    shading: &CachedShading,
    paths: PathLimits,
    per_direction: u32,
    gathered: Gather,
    rel: f64,
) -> ShadingStats {
    // The back wall above the boxes.
    let target = PlacementPoint {
        point: QueryPoint::new(DVec3::new(0.2, 0.3, -1.0), DVec3::Z).unwrap(),
        footprint: None,
    };
    let limits = IrradianceCache::new(Default::default())
        .unwrap()
        .radius_limits();
    let mut rng = Pcg64::seed_from_u64(21);
    let mut record = |gather: Gather, stats: &mut ShadingStats| {
        let how = RecordGather {
            paths,
            per_direction,
            gather,
        };
        compute_record(
            transport,
            &shading.rule,
            &target,
            limits,
            &how,
            &mut rng,
            stats,
        )
        .unwrap()
        .irradiance
    };
    let mut stats = ShadingStats::default();
    let other = MeanEstimate::of((0..24).map(|_| record(gathered, &mut stats)));
    let traced =
        MeanEstimate::of((0..24).map(|_| record(Gather::Paths, &mut ShadingStats::default())));
    let (c, t) = (other.mean.to_array(), traced.mean.to_array());
    let (vc, vt) = (
        other.variance_of_mean.to_array(),
        traced.variance_of_mean.to_array(),
    );
    for k in 0..3 {
        let se = (vc[k] + vt[k]).sqrt();
        assert!(
            agrees(c[k], t[k], se, 4.0, rel),
            "channel {k}: {c:?} vs paths {t:?}"
        );
    }
    stats
}

/// A record gathered through the cache (ambient bounces, nested records
/// created on demand) agrees with records gathered by paths, and every
/// nested record is counted and stored.
#[test]
fn records_gathered_through_the_cache_agree_with_path_traced_records() {
    let transport = cornell(8);
    let shading = test_shading(
        small_spec(),
        CacheShadingOptions {
            ambient_bounces: 2,
            ..Default::default()
        },
    );
    let cache = IrradianceCache::new(Default::default()).unwrap();
    let paths = indirect_paths(PathDepth::constant(32));
    let integrator = CachedIntegrator::new(&transport, &cache, &shading);
    let gathered = Gather::for_record(integrator, paths, 0, true);
    assert!(matches!(
        gathered,
        Gather::Cache {
            bounce: Bounce { level: 0, .. },
            ..
        }
    ));
    // 3 %: records from the cache see cached (interpolated) light at their bounces.
    let stats = assert_records_agree(&transport, &shading, paths, 1, gathered, 0.03);
    assert!(
        stats.records_created > 0 && stats.ambient_records > 0,
        "{stats:?}"
    );
    assert_eq!(cache.stats().records, stats.records_created);
    // Short paths, or no ambient bounces, gather by paths.
    assert!(matches!(
        Gather::for_record(integrator, indirect_paths(PathDepth::constant(4)), 0, true),
        Gather::Paths
    ));
    assert!(matches!(
        Gather::for_record(integrator, paths, 2, true),
        Gather::Paths
    ));
}

#[test]
fn radiance_queries_insert_records_on_a_miss_and_reuse_them() {
    let transport = cornell(8);
    let shading = test_shading(small_spec(), CacheShadingOptions::default());
    let cache = IrradianceCache::new(Default::default()).unwrap();
    // The floor's centre seen from above.
    let ray = Ray {
        origin: DVec3::new(0.0, 0.5, 0.3),
        dir: DVec3::new(0.0, -1.0, 0.0),
        t_max: f64::INFINITY,
    };
    let hit = transport.scene().intersect(&ray).unwrap();
    let mut rng = Pcg64::seed_from_u64(3);
    let mut stats = ShadingStats::default();
    let integrator = CachedIntegrator::new(&transport, &cache, &shading);
    // Depths counted from the viewer, whose segment reaches the floor.
    let mut shade = |max_depth: u32, stats: &mut ShadingStats| {
        let how = ShadePoint {
            max_depth: PathDepth::constant(max_depth),
            on_miss: OnMiss::Insert,
            sample: None,
            dense: false,
        };
        integrator
            .outgoing_radiance(&hit, -ray.dir, how, &mut rng, stats)
            .unwrap()
            .value
    };
    let full = shade(9, &mut stats);
    assert_eq!((stats.cache_misses, stats.records_created), (1, 1));
    assert_eq!(cache.stats().records, 1);
    let again = shade(9, &mut stats);
    assert_eq!((stats.cache_hits, stats.records_created), (1, 1));
    let direct = shade(2, &mut ShadingStats::default());
    // Indirect light adds to direct light; nothing is emitted here.
    assert!(full.g > direct.g && again.g > direct.g && direct.g > 0.0);
    assert_eq!(shade(1, &mut ShadingStats::default()), Rgb::BLACK);
}

/// The glossy BMC lobe is turned towards the mirror direction: on a
/// glossy floor next to the red wall, seen from the green side, BMC
/// agrees with a lobe-sampled Monte Carlo estimate of the same
/// integral `∫ L_ind p dω`, reddish as the wall it mirrors.
#[test]
fn glossy_bmc_agrees_with_lobe_sampling() {
    use crate::scene::Scene;
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes");
    let text = std::fs::read_to_string(root.join("cornell-box.json")).unwrap();
    let mut doc: serde_json::Value = serde_json::from_str(&text).unwrap();
    let m = 30.0;
    doc["materials"]
        .as_array_mut()
        .unwrap()
        .push(serde_json::json!({
            "id": "shiny", "type": "glossy", "diffuse": [0.1, 0.1, 0.1],
            "specular": [0.8, 0.8, 0.8], "exponent": m
        }));
    assert_eq!(doc["shapes"][0]["id"], "floor");
    doc["shapes"][0]["material"] = "shiny".into();
    let scene = Scene::from_json_str(&doc.to_string(), &root, &root).unwrap();
    let transport = Transport::new(Arc::new(scene));
    let down = Ray {
        origin: DVec3::new(-0.75, -0.5, 0.6),
        dir: -DVec3::Y,
        t_max: f64::INFINITY,
    };
    let hit = transport.scene().intersect(&down).unwrap();
    assert!((hit.position.y + 1.0).abs() < 1e-6, "{hit:?}");
    let bsdf = transport.bsdf(hit.material).unwrap().clone();
    assert_eq!(bsdf.phong().unwrap().exponent, m);
    let frame = Frame::from_normal(hit.shading_normal);
    // Viewed from +x above: the mirror direction points at the red wall.
    let wo_local = frame.to_local(DVec3::new(1.0, 1.0, 0.0).normalize());
    let point = QueryPoint::new(hit.position, hit.shading_normal).unwrap();
    let paths = indirect_paths(PathDepth::constant(4));
    let shading = test_shading(default_rule_spec(), CacheShadingOptions::default());
    let cache = IrradianceCache::new(Default::default()).unwrap();
    let integrator = CachedIntegrator::new(&transport, &cache, &shading);
    let surface = Surface {
        hit: &hit,
        frame,
        bsdf: &bsdf,
        wo_local,
    };
    let placement = shading.placement(paths, 0);
    let reflection = Reflection {
        placement: &placement,
        light_samples: 1,
        level: 0,
        on_miss: OnMiss::PathTrace,
        sample: None,
        indirect: true,
        glossy_bmc: true,
        delta_chain: 0,
        fallback_paths: 1,
    };
    let mut rng = Pcg64::seed_from_u64(5);
    let (mut trace, mut stats) = (TraceStats::default(), ShadingStats::default());
    let bmc: Rgb = (0..16)
        .map(|_| {
            integrator
                .glossy_indirect(
                    &surface,
                    &point,
                    &reflection,
                    &mut rng,
                    &mut trace,
                    &mut stats,
                )
                .unwrap()
                .value
        })
        .sum::<Rgb>()
        * (1.0 / 16.0);
    assert_eq!(stats.glossy_bmc, 16);
    let lobe = Frame::from_normal(DVec3::new(-wo_local.x, -wo_local.y, wo_local.z));
    let mc = crate::render::MeanEstimate::of((0..6000).map(|_| {
        let wi = lobe.to_world(warp::power_cosine([rng.random(), rng.random()], m));
        if wi.z <= 0.0 {
            return Rgb::BLACK;
        }
        let l = transport.hemisphere_samples(&point, &frame, &[wi], paths, &mut rng, &mut trace)[0]
            .radiance;
        l * ((m + 2.0) / (m + 1.0) * wi.z)
    }));
    let (b, e, se) = (
        bmc.to_array(),
        mc.mean.to_array(),
        mc.variance_of_mean.to_array(),
    );
    for c in 0..3 {
        assert!(
            // 15 %: the θ_r interpolation of the glossy weights (module docs).
            agrees(b[c], e[c], se[c].sqrt(), 4.0, 0.15),
            "channel {c}: BMC {b:?} vs MC {e:?} ± {se:?}"
        );
    }
    assert!(e[0] > 1.5 * e[1] && b[0] > 1.5 * b[1], "{b:?} {e:?}");
}

#[test]
fn bad_options_name_the_field() {
    let bad = |o: CacheShadingOptions| o.validate().unwrap_err().field().map(String::from);
    let d = CacheShadingOptions::default();
    assert_eq!(
        bad(CacheShadingOptions { accuracy: 0.0, ..d }).as_deref(),
        Some("accuracy")
    );
    assert_eq!(
        bad(CacheShadingOptions {
            light_samples: 0,
            ..d
        })
        .as_deref(),
        Some("light_samples")
    );
    assert_eq!(
        bad(CacheShadingOptions {
            min_pixels: f64::NAN,
            ..d
        })
        .as_deref(),
        Some("min_pixels")
    );
    let parsed: CacheShadingOptions =
        serde_json::from_str(r#"{"accuracy": 0.3, "reproducible": true}"#).unwrap();
    assert_eq!((parsed.accuracy, parsed.reproducible), (0.3, true));
    assert!(serde_json::from_str::<CacheShadingOptions>(r#"{"acuracy": 1}"#).is_err());
}
