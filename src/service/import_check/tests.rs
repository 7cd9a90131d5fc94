use std::sync::Arc;

use super::*;
use crate::bmc::cache::QuadratureCache;
use crate::cache::{CacheConfig, IrradianceCache};
use crate::integrator::cached::{CacheShadingOptions, CachedIntegrator, CachedShading};
use crate::integrator::cached::{CachedTileReport, default_rule_spec};
use crate::integrator::progressive::TileRecords;
use crate::render::TileRequest;
use crate::service::tile_store::{DecodedImport, ImportError, TileStore};
use crate::testing::cornell;

/// The bound of docs/math.md §9.8 at the check's sizes: 19 of 64 refuse,
/// a count genuine records reach with a chance below 10⁻⁹ and 18 not.
#[test]
fn the_refusing_count_is_the_binomial_bound() {
    assert_eq!(refusing_count(0), None);
    assert_eq!(refusing_count(CHECKED_RECORDS), Some(19));
    let tail = |k: u64| binomial_upper_tail(64, GENUINE_DISAGREEMENT, k);
    assert!(tail(19) <= FALSE_REFUSAL && tail(18) > FALSE_REFUSAL);
    // Too few records for the bound: all of them must disagree.
    assert_eq!(refusing_count(1), Some(1));
    assert_eq!(refusing_count(6), Some(6));
    assert_eq!(refusing_count(10), Some(9));
}

/// Within a factor 4 of the fresh estimate's 3σ interval agrees, beyond
/// it (up or down) disagrees; near zero the slack decides.
#[test]
fn a_value_disagrees_beyond_a_factor_of_the_fresh_interval() {
    let fresh = Fresh {
        mean: Rgb::splat(1.0),
        variance: Rgb::splat(0.01),
    };
    let none = Rgb::BLACK;
    // The interval is [0.7, 1.3]; the factor reaches 5.2 and 0.175.
    for (value, disagrees_) in [
        (1.0, false),
        (5.1, false),
        (5.3, true),
        (0.18, false),
        (0.17, true),
        (1000.0, true),
        (0.001, true),
    ] {
        assert_eq!(
            disagrees(Rgb::splat(value), &fresh, none),
            disagrees_,
            "{value}"
        );
    }
    // One channel is enough.
    assert!(disagrees(Rgb::new(1.0, 1.0, 6.0), &fresh, none));
    // Nothing where nothing arrives, and a slack to be beyond near zero.
    let dark = Fresh {
        mean: Rgb::BLACK,
        variance: Rgb::BLACK,
    };
    assert!(!disagrees(Rgb::BLACK, &dark, none));
    assert!(disagrees(Rgb::splat(1e-9), &dark, none));
    assert!(!disagrees(Rgb::splat(0.02), &dark, Rgb::splat(0.01)));
    assert!(disagrees(Rgb::splat(0.04), &dark, Rgb::splat(0.01)));
}

/// A small, fast configuration: the default rule's 64 directions, two
/// paths each.
fn shading() -> CachedShading {
    let options = CacheShadingOptions {
        reproducible: true,
        light_samples: 2,
        paths_per_direction: 2,
        ..CacheShadingOptions::default()
    };
    CachedShading::new(
        default_rule_spec(),
        4,
        Arc::new(QuadratureCache::new(1 << 24)),
        options,
    )
    .unwrap()
}

/// The records of two 16-pixel tiles of the Cornell box (32² pixels) as
/// reproducible tiles place them, at depth 6 from the camera, each value
/// times `scale`, exported.
fn genuine_export(transport: &Transport, scale: f64) -> Vec<u8> {
    let shading = shading();
    let cache = IrradianceCache::new(CacheConfig::default()).unwrap();
    let integrator = CachedIntegrator::new(transport, &cache, &shading);
    let store = TileStore::new(1 << 24, 4096);
    let digest = *transport.scene().digest.as_bytes();
    for (key, x) in [(1u8, 0), (2, 16)] {
        let request = TileRequest {
            x,
            y: 8,
            width: 16,
            height: 16,
            samples_per_pixel: 1,
            max_depth: PathDepth::constant(6),
            seed: 7,
            pass: 0,
            passes: 1,
        };
        let (mut records, _) = integrator.tile_records(&request, &Cancel::never()).unwrap();
        for r in &mut records {
            r.irradiance *= scale;
            r.variance *= scale * scale;
            r.rotation_gradient = r.rotation_gradient.map(|g| g * scale);
            r.translation_gradient = r.translation_gradient.map(|g| g * scale);
        }
        store
            .records_or::<()>([key; 32], || {
                Ok(TileRecords {
                    scene: digest,
                    max_depth: request.max_depth,
                    records,
                    report: CachedTileReport::default(),
                })
            })
            .unwrap();
    }
    let mut image = crate::cache::log::MAGIC.to_vec();
    for key in store.export_keys(&digest) {
        image.extend(store.export_entry(&key).unwrap());
    }
    image
}

/// [`pick`] from the tiles `decoded` would add.
fn picked(decoded: &DecodedImport, export: &[u8], key: &[u8; 32]) -> Vec<Picked> {
    let tiles = decoded
        .new_tiles()
        .map(|(i, t)| (i, t.records.as_slice(), t.max_depth));
    pick(tiles, export, key).unwrap()
}

/// `export` decoded by `store` for `transport`'s scene.
fn decoded_by(store: &TileStore, transport: &Transport, export: &[u8]) -> DecodedImport {
    let digest = *transport.scene().digest.as_bytes();
    store
        .decode_import(&digest, transport.scene().bounds(), export)
        .unwrap()
}

/// `export` decoded by a store that holds nothing.
fn decoded(transport: &Transport, export: &[u8]) -> DecodedImport {
    decoded_by(&TileStore::new(1 << 24, 4096), transport, export)
}

fn verdict_of(transport: &Transport, export: &[u8], key: &[u8; 32]) -> Verdict {
    let decoded = decoded(transport, export);
    check(transport, &picked(&decoded, export, key), &Cancel::never()).unwrap()
}

/// Genuine records pass; the same records scaled by 1,000 (their
/// variances and gradients with them, so every per-record check passes) or
/// by 1/1,000 are refused, naming the first that disagrees.
#[test]
fn genuine_records_pass_and_scaled_ones_are_refused() {
    let transport = cornell(32);
    let genuine = genuine_export(&transport, 1.0);
    let verdict = verdict_of(&transport, &genuine, &[3; 32]);
    assert_eq!(verdict.checked, CHECKED_RECORDS, "{verdict:?}");
    assert!(verdict.refusal().is_none(), "{verdict:?}");
    assert!(verdict.disagreeing <= 2, "{verdict:?}");
    for scale in [1000.0, 1e-3] {
        let forged = genuine_export(&transport, scale);
        let verdict = verdict_of(&transport, &forged, &[3; 32]);
        let refusal = verdict.refusal().expect("refused");
        assert!(verdict.disagreeing > 19, "{scale}: {verdict:?}");
        let first = verdict.first.unwrap();
        assert_eq!(
            (
                refusal.entry,
                refusal.record,
                refusal.checked,
                refusal.allowed
            ),
            (first.entry, first.record, 64, 18)
        );
        let error = ImportError::from(refusal);
        assert!(error.to_string().contains("fresh paths give"), "{error}");
    }
}

/// The records checked are a function of the body and the key: distinct,
/// in the import's order, the same again for the same pair, others for
/// another key; all of them in an import of at most [`CHECKED_RECORDS`].
#[test]
fn the_records_checked_are_keyed_by_the_import() {
    let transport = cornell(32);
    let export = genuine_export(&transport, 1.0);
    let decoded = decoded(&transport, &export);
    let places = |key: &[u8; 32]| -> Vec<(usize, usize)> {
        picked(&decoded, &export, key)
            .iter()
            .map(|p| (p.entry, p.record))
            .collect()
    };
    let total: usize = decoded.new_tiles().map(|(_, t)| t.records.len()).sum();
    assert!(total > CHECKED_RECORDS, "{total}");
    let a = places(&[1; 32]);
    assert_eq!(a.len(), CHECKED_RECORDS);
    assert!(a.windows(2).all(|w| w[0] < w[1]), "{a:?}");
    assert_eq!(places(&[1; 32]), a);
    assert_ne!(places(&[2; 32]), a);
    for p in picked(&decoded, &export, &[1; 32]) {
        let tile = decoded.new_tiles().find(|(i, _)| *i == p.entry).unwrap().1;
        assert_eq!(tile.records[p.record], p.value);
        assert_eq!(p.camera_depth, PathDepth::constant(6));
    }
    // A held tile is not checked: its records would not be added.
    let holder = TileStore::new(1 << 24, 4096);
    let first = decoded_by(&holder, &transport, &export);
    let verdict = check(
        &transport,
        &picked(&first, &export, &[1; 32]),
        &Cancel::never(),
    )
    .unwrap();
    let report = holder.add_import(first.accept(&verdict).unwrap());
    assert_eq!((report.imported, report.checked), (2, 64));
    let again = decoded_by(&holder, &transport, &export);
    assert!(picked(&again, &export, &[1; 32]).is_empty());
}

/// The check stops once its request is gone.
#[test]
fn a_cancelled_check_stops() {
    let transport = cornell(32);
    let export = genuine_export(&transport, 1.0);
    let decoded = decoded(&transport, &export);
    let cancel = Cancel::new();
    cancel.cancel();
    assert!(check(&transport, &picked(&decoded, &export, &[1; 32]), &cancel).is_err());
}
