use super::*;
use crate::service::import_check::Verdict;

fn pass(seed: f32) -> RenderedPass {
    let rgb = (0..6).map(|i| [i as f32 * seed, 1.0, 2.0]).collect();
    RenderedPass {
        image: Image::from_parts(3, 2, rgb, Some(vec![0.5; 6])).unwrap(),
        shared: vec![0.25; 6],
        counts: vec![1, 2, 3, 4, 5, 6],
        rays: 99,
        cache_hits: 7,
    }
}

#[test]
fn parts_survive_a_restart_through_the_log() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("tiles.log");
    let record = Record::from_le_bytes(&[0u8; Record::ENCODED_BYTES]);
    assert!(record.is_none(), "a zero normal is not a record");
    let store = TileStore::open(1 << 20, 4096, &path).unwrap();
    let p = store.pass_or::<()>([1; 32], || Ok(pass(1.5))).unwrap();
    // Cached: the closure is not called again.
    let again = store
        .pass_or::<()>([1; 32], || panic!("recomputed"))
        .unwrap();
    assert_eq!(again.image, p.image);
    drop(store);
    let reopened = TileStore::open(1 << 20, 4096, &path).unwrap();
    assert_eq!(reopened.stats().loaded_entries, 1);
    let back = reopened
        .pass_or::<()>([1; 32], || panic!("not loaded"))
        .unwrap();
    assert_eq!(
        (back.image.clone(), &back.shared, &back.counts, back.rays),
        (p.image.clone(), &p.shared, &p.counts, 99)
    );
    assert!(decode_pass(&encode_pass(&p)[..30], 4096).is_none());
}

/// A box around the records of [`tile`].
const BOUNDS: (glam::DVec3, glam::DVec3) = (glam::DVec3::splat(-1.0), glam::DVec3::splat(1.0));

fn tile(scene: u8) -> TileRecords {
    use glam::DVec3;
    let valid = Record {
        position: DVec3::ZERO,
        normal: DVec3::Z,
        irradiance: crate::render::Rgb::new(1.0, 2.0, 3.0),
        variance: crate::render::Rgb::new(0.1, 0.1, 0.1),
        radius: 0.5,
        rotation_gradient: [DVec3::ZERO; 3],
        translation_gradient: [DVec3::ZERO; 3],
    };
    TileRecords {
        scene: [scene; 32],
        max_depth: PathDepth::new(5).unwrap(),
        records: (0..3)
            .map(|i| Record {
                position: DVec3::new(0.1 * f64::from(i), 0.0, 0.0),
                ..valid
            })
            .collect(),
        report: CachedTileReport::default(),
    }
}

#[test]
fn a_scene_s_records_export_and_import_and_nothing_else() {
    let store = TileStore::new(1 << 20, 4096);
    store.records_or::<()>([1; 32], || Ok(tile(7))).unwrap();
    store.records_or::<()>([2; 32], || Ok(tile(7))).unwrap();
    store.records_or::<()>([3; 32], || Ok(tile(8))).unwrap();
    store.pass_or::<()>([4; 32], || Ok(pass(1.0))).unwrap();
    let export = store.export(&[7; 32]);
    assert_eq!(log::decode_log(&export).unwrap().len(), 2);

    let other = TileStore::new(1 << 20, 4096);
    let decoded = other.decode_import(&[7; 32], BOUNDS, &export).unwrap();
    assert_eq!(
        decoded
            .new_tiles()
            .map(|(i, t)| (i, t.records.len()))
            .collect::<Vec<_>>(),
        [(0, 3), (1, 3)]
    );
    // Decoding adds nothing.
    assert_eq!(other.stats().tiles, 0);
    let report = other.add_import(decoded.accept(&Verdict::nothing_checked()).unwrap());
    assert_eq!(
        (report.imported, report.already_held, report.records),
        (2, 0, 6)
    );
    let back = other
        .records_or::<()>([2; 32], || panic!("not imported"))
        .unwrap();
    assert_eq!(back.records, tile(7).records);
    let again = other.decode_import(&[7; 32], BOUNDS, &export).unwrap();
    assert_eq!(again.new_tiles().count(), 0, "held tiles are not new");
    assert_eq!(
        other
            .add_import(again.accept(&Verdict::nothing_checked()).unwrap())
            .already_held,
        2
    );
    // A tile held when the import was decoded was not checked with it: it
    // stays out even if evicted before the import is added.
    let stale = other.decode_import(&[7; 32], BOUNDS, &export).unwrap();
    other.records.invalidate(&[1; 32]);
    let report = other.add_import(stale.accept(&Verdict::nothing_checked()).unwrap());
    assert_eq!((report.imported, report.already_held), (0, 2));
    assert!(other.records.get(&[1; 32]).is_none());
    // Refused whole: another scene's content, damage, not an export.
    let fresh = TileStore::new(1 << 20, 4096);
    assert!(matches!(
        fresh.decode_import(&[8; 32], BOUNDS, &export),
        Err(ImportError::OtherScene { entry: 0, .. })
    ));
    assert_eq!(
        fresh
            .decode_import(&[7; 32], BOUNDS, &export[..export.len() - 3])
            .err(),
        Some(ImportError::Damaged { entry: 1 })
    );
    assert_eq!(
        fresh.decode_import(&[7; 32], BOUNDS, b"{}").err(),
        Some(ImportError::NotALog)
    );
    assert_eq!(fresh.stats().tiles, 0);
}

#[test]
fn parts_from_another_replica_merge_once() {
    let store = TileStore::new(1 << 20, 4096);
    let framed = log::encode_entry(PASS, &[5; 32], &encode_pass(&pass(2.0))).unwrap();
    assert!(store.merge(&framed));
    assert!(!store.merge(&framed), "held already");
    assert!(!store.merge(&framed[..framed.len() - 1]), "damaged");
    let merged = store
        .pass_or::<()>([5; 32], || panic!("not merged"))
        .unwrap();
    assert_eq!(merged.image, pass(2.0).image);
}

/// Another replica's part (or the log's) that no rendering could have
/// made is not taken: non-finite, negative or huge values, or more
/// pixels than the largest tile.
#[test]
fn poisoned_parts_are_not_merged() {
    let store = TileStore::new(1 << 20, 4);
    for (i, value) in [f32::NAN, f32::INFINITY, -1.0, 1e30]
        .into_iter()
        .enumerate()
    {
        let mut poisoned = pass(1.0);
        let mut rgb = poisoned.image.rgb().to_vec();
        rgb[1][2] = value;
        poisoned.image = Image::from_parts(3, 2, rgb, Some(vec![0.5; 6])).unwrap_or_else(|_| {
            // Images refuse some values themselves; forge the bytes then.
            pass(1.0).image
        });
        let mut payload = encode_pass(&poisoned);
        // rgb starts after 25 bytes of header: pixel 1, channel 2.
        payload[25 + 4 * 5..25 + 4 * 6].copy_from_slice(&value.to_le_bytes());
        let framed = log::encode_entry(PASS, &[i as u8; 32], &payload).unwrap();
        assert!(!store.merge(&framed), "{value}");
    }
    // Six pixels, more than a largest tile of four.
    let framed = log::encode_entry(PASS, &[9; 32], &encode_pass(&pass(1.0))).unwrap();
    assert!(!store.merge(&framed));
    assert!(TileStore::new(1 << 20, 6).merge(&framed));
}

#[test]
fn the_log_is_compacted_to_what_memory_holds() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("tiles.log");
    // A budget of a few passes: the log is rewritten many times.
    let store = TileStore::open(4096, 4096, &path).unwrap();
    for i in 0..200u8 {
        store
            .pass_or::<()>([i; 32], || Ok(pass(f32::from(i))))
            .unwrap();
    }
    assert!(
        store.stats().log_bytes <= 2 * 4096 + 512,
        "{:?}",
        store.stats()
    );
    drop(store);
    let reopened = TileStore::open(4096, 4096, &path).unwrap();
    assert!(reopened.stats().loaded_entries > 0);
}
