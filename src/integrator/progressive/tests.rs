//! Progressive tiles' jobs, pass means and sample plans.

use super::*;
use crate::scene::SceneError;

/// The Cornell box, with `max_depth` in its document when given.
fn cornell(max_depth: Option<u32>) -> Result<Scene, SceneError> {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes");
    let text = std::fs::read_to_string(dir.join("cornell-box.json")).expect("bundled scene");
    let mut doc: serde_json::Value = serde_json::from_str(&text).expect("JSON");
    if let Some(d) = max_depth {
        doc["max_depth"] = d.into();
    }
    Scene::from_json_str(&doc.to_string(), &dir, &dir)
}

#[test]
fn the_depth_is_the_requests_else_the_scenes_else_the_presets() {
    let depth = |scene: &Scene, max_depth| {
        let params = TileParams {
            x: 0,
            y: 0,
            width: 8,
            height: 8,
            preset: Preset::Draft,
            samples_per_pixel: None,
            pass: None,
            max_depth,
            seed: 1,
            estimator: IntegratorSpec::default(),
            denoise: None,
        };
        params.job(scene).expect("valid").request.max_depth.get()
    };
    let (plain, deep) = (cornell(None).unwrap(), cornell(Some(3)).unwrap());
    assert_eq!(
        depth(&plain, None),
        Preset::Draft.settings().max_depth.get()
    );
    assert_eq!(depth(&deep, None), 3);
    assert_eq!(depth(&deep, Some(5)), 5);
    let refused = cornell(Some(0)).err().expect("depth 0 refused");
    assert_eq!(refused.field(), Some("max_depth"));
}

/// Two passes of one pixel, each of variance 3 of which 2 is shared:
/// with equal rays the mean's own part halves (1 → 0.5) and the shared
/// part stays 2; with 1 and 3 rays the values weigh 1 : 3, the own part
/// is (1 + 9) / 16 and the shared part still 2.
#[test]
fn passes_average_their_own_noise_but_not_the_records_error() {
    let pass = |value: f32, counts: Vec<u32>| {
        Arc::new(RenderedPass {
            image: Image::from_parts(1, 1, vec![[value; 3]], Some(vec![3.0])).unwrap(),
            shared: vec![2.0],
            counts,
            rays: 1,
            cache_hits: 0,
        })
    };
    let mean = mean_of_passes(&[pass(1.0, vec![]), pass(3.0, vec![])], 4).unwrap();
    assert_eq!(mean.image.pixel(0, 0), Some([2.0; 3]));
    assert_eq!(mean.image.variance(), Some(&[2.5][..]));
    assert_eq!((mean.own_variance, mean.rays), (vec![0.5], vec![8]));
    let one = mean_of_passes(&[pass(1.0, vec![])], 4).unwrap();
    assert_eq!(one.image.variance(), Some(&[3.0][..]));
    let weighted = mean_of_passes(&[pass(1.0, vec![1]), pass(3.0, vec![3])], 4).unwrap();
    assert_eq!(weighted.image.pixel(0, 0), Some([2.5; 3]));
    // Own: (1 + 9) / 16 = 0.625 against the 3-ray pass's per-ray 3 over
    // 4 rays, 0.75; plus the shared 2.
    assert_eq!(weighted.image.variance(), Some(&[2.75][..]));
    assert_eq!(weighted.rays, [4]);
}

/// A preset's ladder: the first pass uniform, the next one's rays where
/// the first pass was noisy two pixels away, adding up to the pass's
/// rays; a single pass has no plan.
#[test]
fn a_ladder_plans_its_passes_from_the_first() {
    let scene = cornell(None).unwrap();
    let params = TileParams {
        x: 0,
        y: 0,
        width: 8,
        height: 8,
        preset: Preset::Preview,
        samples_per_pixel: None,
        pass: None,
        max_depth: None,
        seed: 1,
        estimator: IntegratorSpec::default(),
        denoise: None,
    };
    let job = params.job(&scene).unwrap();
    let spp = job.request.samples_per_pixel;
    let first = job.plan(&job.request, &[]).unwrap().expect("a ladder");
    assert_eq!(first.counts, vec![spp; 64]);
    // Noise only in columns 6 and 7.
    let variance = (0..64)
        .map(|i| if i % 8 >= 6 { 1.0 } else { 0.0 })
        .collect();
    let pass = Arc::new(RenderedPass {
        image: Image::from_parts(8, 8, vec![[1.0; 3]; 64], Some(variance)).unwrap(),
        shared: vec![],
        counts: vec![],
        rays: 0,
        cache_hits: 0,
    });
    let next = job.plan(&job.request, &[pass]).unwrap().expect("a ladder");
    assert_eq!(next.counts.iter().sum::<u32>(), 64 * spp);
    assert_eq!(next.firsts, vec![spp; 64]);
    for (i, &n) in next.counts.iter().enumerate() {
        match i % 8 {
            // Two or more columns from the noise: one ray.
            0..=3 => assert_eq!(n, 1, "pixel {i}"),
            _ => assert!(n > spp && n <= 4 * spp, "pixel {i}: {n}"),
        }
    }
    let single = TileParams {
        samples_per_pixel: Some(4),
        ..params
    };
    assert!(
        single
            .job(&scene)
            .unwrap()
            .plan(&single.job(&scene).unwrap().request, &[])
            .unwrap()
            .is_none()
    );
}

/// With record blocks (`integrator::cached::tiles`), a pixel of a preset's
/// image is the same whichever tile it is rendered in: two 64-pixel tiles
/// and the 128-pixel tile holding both, and an unaligned tile across
/// their edge, agree bit for bit, each tiling placing its blocks afresh.
#[test]
fn a_pixel_is_the_same_whatever_tile_renders_it() {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes");
    let text = std::fs::read_to_string(dir.join("cornell-box.json")).expect("bundled scene");
    let mut doc: serde_json::Value = serde_json::from_str(&text).expect("JSON");
    // Small, so every block is placed quickly; 3 × 2 blocks.
    doc["camera"]["width"] = 192.into();
    doc["camera"]["height"] = 128.into();
    let scene = Scene::from_json_str(&doc.to_string(), &dir, &dir).unwrap();
    let transport = Transport::new(Arc::new(scene));
    let params = |x, y, width, height| TileParams {
        x,
        y,
        width,
        height,
        preset: Preset::Draft,
        samples_per_pixel: Some(2),
        pass: None,
        max_depth: None,
        seed: 7,
        estimator: IntegratorSpec::default(),
        denoise: None,
    };
    let integrator = params(0, 0, 1, 1)
        .job(transport.scene())
        .unwrap()
        .integrator;
    let config = integrator.cached().expect("presets use the cache");
    let quadratures = Arc::new(crate::bmc::cache::QuadratureCache::new(64 << 20));
    let shading = config.shading(quadratures).unwrap();
    let cache = crate::cache::IrradianceCache::new(crate::cache::CacheConfig::default()).unwrap();
    let bound = integrator
        .bind(&transport, Some((&cache, &shading)))
        .unwrap();
    let render = |memo: &HeldBlocks, p: TileParams| {
        let job = p.job(transport.scene()).unwrap();
        render_progressive(&transport, &bound, &job, memo, &Cancel::never()).unwrap()
    };
    let (apart, whole) = (HeldBlocks::default(), HeldBlocks::default());
    let left = render(&apart, params(0, 64, 64, 64));
    let right = render(&apart, params(64, 64, 64, 64));
    let both = render(&whole, params(0, 64, 128, 64));
    let across = render(&HeldBlocks::default(), params(50, 70, 30, 20));
    for y in 0..64 {
        for x in 0..128 {
            let (tile, tx) = if x < 64 { (&left, x) } else { (&right, x - 64) };
            assert_eq!(
                tile.image.pixel(tx, y),
                both.image.pixel(x, y),
                "({x}, {y})"
            );
        }
    }
    for y in 0..20 {
        for x in 0..30 {
            let expected = both.image.pixel(50 + x, 6 + y);
            assert_eq!(across.image.pixel(x, y), expected, "({x}, {y})");
        }
    }
    // All six blocks (the margin reaches the whole image), each placed
    // once for every tile of a tiling.
    assert!(both.records_created > 0 && both.records.len() == 6);
    assert_eq!(
        apart.report().placement.records_created,
        both.records_created
    );
}
