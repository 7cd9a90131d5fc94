//! `POST /v1/scenes/{id}/tiles` end to end: the three encodings agree and
//! tiles assemble into the whole image (bad tiles: `service_bad_inputs.rs`).

use std::path::Path;

use crate::common::{TINY_SCENE, spawn_app_in, spawn_app_with_scenes};
use bmc_irradiance::image::decode_exr;
use bmc_irradiance::scene::Scene;
use reqwest::StatusCode;
use serde_json::{Value, json};

fn tile(x: u32, y: u32, width: u32, height: u32, format: &str) -> Value {
    json!({"x": x, "y": y, "width": width, "height": height, "format": format,
           "samples_per_pixel": 4, "max_depth": 4, "seed": 5, "estimator": {"method": "path"}})
}

/// `(width, height, rgb)` of a JSON tile body.
fn json_pixels(body: &Value) -> (u64, u64, Vec<[f32; 3]>) {
    let rgb = body["rgb"]
        .as_array()
        .unwrap()
        .iter()
        .map(|p| {
            let c: Vec<f32> = p
                .as_array()
                .unwrap()
                .iter()
                .map(|v| v.as_f64().unwrap() as f32)
                .collect();
            [c[0], c[1], c[2]]
        })
        .collect();
    (
        body["width"].as_u64().unwrap(),
        body["height"].as_u64().unwrap(),
        rgb,
    )
}

#[tokio::test]
async fn encodings_agree_and_tiles_assemble_into_the_image() {
    let app = spawn_app_with_scenes(&[("tiny.json", TINY_SCENE)], |_| {}).await;
    let post = |body: Value| {
        let app = &app;
        async move {
            let response = app.post_json("/v1/scenes/tiny/tiles", &body).await;
            assert_eq!(response.status(), StatusCode::OK, "{body}");
            response
        }
    };

    let whole = post(tile(0, 0, 8, 8, "json")).await;
    assert_eq!(whole.headers()["content-type"], "application/json");
    assert_eq!(whole.headers()["x-tile-x"], "0");
    let rays: u64 = whole.headers()["x-rays"].to_str().unwrap().parse().unwrap();
    assert!(rays >= 8 * 8 * 4, "{rays}");
    let whole: Value = whole.json().await.unwrap();
    let (w, h, pixels) = json_pixels(&whole);
    assert_eq!((w, h, pixels.len()), (8, 8, 64));
    assert_eq!(whole["variance"].as_array().unwrap().len(), 64);
    // The lit rectangle fills the middle of the view; the sky (radiance 1) the rest.
    assert!(
        pixels
            .iter()
            .all(|p| p.iter().all(|c| c.is_finite() && *c >= 0.0))
    );
    assert!(pixels.iter().any(|p| p[0] > 0.0));

    // Two halves: the same pixels, whatever the tiling.
    for (y, rows) in [(0u32, 0..32usize), (4, 32..64)] {
        let half: Value = post(tile(0, y, 8, 4, "json")).await.json().await.unwrap();
        let (_, _, half_pixels) = json_pixels(&half);
        assert_eq!(half_pixels, pixels[rows]);
    }

    // EXR carries the same floats and the variance channel.
    let exr = post(tile(0, 0, 8, 8, "exr")).await;
    assert_eq!(exr.headers()["content-type"], "image/x-exr");
    let image = decode_exr(&exr.bytes().await.unwrap()).unwrap();
    assert_eq!((image.width(), image.height()), (8, 8));
    assert_eq!(image.rgb(), &pixels[..]);
    assert_eq!(image.variance().unwrap().len(), 64);

    // PNG: an 8-bit image of the tile's size.
    let png = post(tile(2, 2, 4, 3, "png")).await;
    assert_eq!(png.headers()["content-type"], "image/png");
    assert_eq!(png.headers()["x-tile-y"], "2");
    let decoded = image::load_from_memory(&png.bytes().await.unwrap()).unwrap();
    assert_eq!((decoded.width(), decoded.height()), (4, 3));

    let metrics = app.get("/metrics").await.text().await.unwrap();
    assert!(
        metrics.contains("/v1/scenes/{id}/tiles"),
        "per-route metrics: {metrics}"
    );
}

/// The bundled Cornell box with a `side`² camera, as a scenes-directory file.
fn small_cornell(side: u32) -> String {
    let mut doc: Value =
        serde_json::from_str(include_str!("../../scenes/cornell-box.json")).unwrap();
    doc["camera"]["width"] = json!(side);
    doc["camera"]["height"] = json!(side);
    doc.to_string()
}

/// A cheap `bmc` tile of the small Cornell box.
fn bmc_tile(x: u32, y: u32, side: u32, extra: Value) -> Value {
    let mut estimator = json!({"method": "cache", "samples": 16, "light_samples": 2, "accuracy": 0.5,
               "reproducible": false});
    for (key, value) in extra.as_object().unwrap() {
        estimator[key] = value.clone();
    }
    json!({"x": x, "y": y, "width": side, "height": side, "format": "json",
           "max_depth": 3, "seed": 9, "samples_per_pixel": 1, "pass": 0, "estimator": estimator})
}

/// `"denoise": true` on a path-traced tile: the same tile filtered, every
/// channel within its pixel's standard error, the error bars kept, and the
/// guides' four rays per pixel counted.
#[tokio::test]
async fn a_posted_tile_can_be_denoised_within_its_error_bars() {
    let app = spawn_app_with_scenes(&[("box.json", &small_cornell(24))], |_| {}).await;
    let body = |denoise: bool| {
        json!({"x": 0, "y": 0, "width": 24, "height": 24, "format": "json", "samples_per_pixel": 8,
               "seed": 3, "estimator": {"method": "path"}, "denoise": denoise})
    };
    let plain = app.post_json("/v1/scenes/box/tiles", &body(false)).await;
    let denoised = app.post_json("/v1/scenes/box/tiles", &body(true)).await;
    assert_eq!(denoised.status(), StatusCode::OK);
    // The pass is memoised (a reproducible tile): only the guides are new.
    assert!(header(&plain, "x-rays") > 24 * 24 * 8);
    assert_eq!(header(&denoised, "x-rays"), 4 * 24 * 24);
    let (plain, denoised): (Value, Value) =
        (plain.json().await.unwrap(), denoised.json().await.unwrap());
    assert_eq!(plain["variance"], denoised["variance"]);
    let (_, _, a) = json_pixels(&plain);
    let (_, _, b) = json_pixels(&denoised);
    let mut moved = 0;
    for (i, (a, b)) in a.iter().zip(&b).enumerate() {
        let sigma = plain["variance"][i].as_f64().unwrap().sqrt() as f32;
        for c in 0..3 {
            assert!(
                (a[c] - b[c]).abs() <= sigma * 1.00001 + 1e-6,
                "pixel {i}: {a:?} -> {b:?}"
            );
            moved += usize::from(a[c] != b[c]);
        }
    }
    assert!(moved > 24 * 24, "{moved} channels moved");
}

fn header(response: &reqwest::Response, name: &str) -> u64 {
    response.headers()[name].to_str().unwrap().parse().unwrap()
}

async fn cache_stats(app: &crate::common::TestApp) -> Value {
    let report: Value = app.get("/v1/scenes/box/cache").await.json().await.unwrap();
    report
}

/// `DELETE /v1/scenes/box/cache`: the stats after clearing.
async fn clear_cache(app: &crate::common::TestApp) -> Value {
    app.delete("/v1/scenes/box/cache")
        .await
        .json()
        .await
        .unwrap()
}

#[tokio::test]
async fn cache_tiles_fill_the_shared_cache_and_reuse_it() {
    let app = spawn_app_with_scenes(&[("box.json", &small_cornell(16))], |_| {}).await;
    assert!(
        cache_stats(&app).await["caches"]
            .as_array()
            .unwrap()
            .is_empty()
    );

    let first = app
        .post_json("/v1/scenes/box/tiles", &bmc_tile(0, 0, 16, json!({})))
        .await;
    assert_eq!(first.status(), StatusCode::OK);
    let created = header(&first, "x-records-created");
    let first_rays = header(&first, "x-rays");
    assert!(created > 0);
    let pixels: Value = first.json().await.unwrap();
    assert!(
        json_pixels(&pixels)
            .2
            .iter()
            .all(|p| p.iter().all(|c| c.is_finite() && *c >= 0.0))
    );

    let report = cache_stats(&app).await;
    let caches = report["caches"].as_array().unwrap();
    assert_eq!(caches.len(), 1, "{report}");
    assert_eq!(caches[0]["stats"]["records"], created);
    assert_eq!(caches[0]["configuration"]["max_depth"], 3);

    // The same tile again finds every record it needs.
    let second = app
        .post_json("/v1/scenes/box/tiles", &bmc_tile(0, 0, 16, json!({})))
        .await;
    assert_eq!(header(&second, "x-records-created"), 0);
    assert!(header(&second, "x-cache-hits") > 0);
    assert!(header(&second, "x-rays") < first_rays);

    // A request may keep the shared cache out of it.
    let alone = app
        .post_json(
            "/v1/scenes/box/tiles",
            &bmc_tile(0, 0, 16, json!({"cache": false})),
        )
        .await;
    assert_eq!(alone.status(), StatusCode::OK);
    assert!(header(&alone, "x-records-created") > 0);
    assert_eq!(
        cache_stats(&app).await["caches"][0]["stats"]["records"],
        created
    );

    // DELETE empties it; replacing the scene retires its caches.
    let cleared = clear_cache(&app).await;
    assert_eq!(cleared["cleared_records"], created);
    assert_eq!(cleared["caches"][0]["stats"]["records"], 0);
    app.post_json("/v1/scenes/box/tiles", &bmc_tile(0, 0, 16, json!({})))
        .await;
    let mut doc: Value = serde_json::from_str(&small_cornell(16)).unwrap();
    doc["name"] = json!("box");
    assert_eq!(
        app.post_json("/v1/scenes?replace=true", &doc)
            .await
            .status(),
        StatusCode::OK
    );
    assert!(
        cache_stats(&app).await["caches"]
            .as_array()
            .unwrap()
            .is_empty()
    );
}

#[tokio::test]
async fn reproducible_cache_tiles_ignore_what_ran_before() {
    let app = spawn_app_with_scenes(&[("box.json", &small_cornell(16))], |_| {}).await;
    let request = bmc_tile(4, 4, 8, json!({"reproducible": true}));
    let cold = app.post_json("/v1/scenes/box/tiles", &request).await;
    assert_eq!(cold.status(), StatusCode::OK);
    let cold = cold.bytes().await.unwrap();
    // Fill the shared cache with records from other tiles and seeds.
    for (x, seed) in [(0, 1), (8, 2)] {
        let mut other = bmc_tile(x, 0, 8, json!({}));
        other["seed"] = json!(seed);
        assert_eq!(
            app.post_json("/v1/scenes/box/tiles", &other).await.status(),
            StatusCode::OK
        );
    }
    let warm = app
        .post_json("/v1/scenes/box/tiles", &request)
        .await
        .bytes()
        .await
        .unwrap();
    assert_eq!(cold, warm);
}

/// Tiles whose records read the scene's secondary cache: the request that
/// builds the cache traces its rays, and a tile is the same bytes whichever
/// request built it; records that trace paths instead give another image.
#[tokio::test]
async fn secondary_cache_tiles_are_the_same_whichever_request_built_the_cache() {
    let scene = small_cornell(16);
    let scenes = [("box.json", scene.as_str())];
    // The image is one record block: a tile of another seed places its
    // records afresh (the seed is part of their key), a tile of the same
    // seed finds them.
    let tile = |x, y, seed: u64, secondary: bool| {
        let extra = json!({"reproducible": true, "secondary_cache": secondary});
        let mut t = bmc_tile(x, y, 8, extra);
        // Long enough paths for a cached bounce (AMBIENT_MIN_DEPTH from the hit).
        t["max_depth"] = json!(17);
        t["seed"] = json!(seed);
        t
    };
    let first_app = spawn_app_with_scenes(&scenes, |_| {}).await;
    let building = first_app
        .post_json("/v1/scenes/box/tiles", &tile(4, 4, 9, true))
        .await;
    assert_eq!(building.status(), StatusCode::OK);
    let rays_building = header(&building, "x-rays");
    let building = building.bytes().await.unwrap();

    let second_app = spawn_app_with_scenes(&scenes, |_| {}).await;
    let other = second_app
        .post_json("/v1/scenes/box/tiles", &tile(8, 8, 10, true))
        .await;
    assert_eq!(other.status(), StatusCode::OK);
    let rays_other = header(&other, "x-rays");
    let other = other.bytes().await.unwrap();
    let reading = second_app
        .post_json("/v1/scenes/box/tiles", &tile(4, 4, 9, true))
        .await;
    assert_eq!(reading.status(), StatusCode::OK);
    assert!(header(&reading, "x-rays") < rays_building);
    assert_eq!(reading.bytes().await.unwrap(), building);

    // DELETE drops the secondary cache with the records; a request whose
    // records are not placed yet on this server builds both again, as the
    // first request on the other server did.
    let before = cache_stats(&first_app).await;
    let (records, secondary) = (
        &before["caches"][0]["stats"]["records"],
        &before["caches"][0]["secondary_records"],
    );
    assert!(secondary.as_u64().unwrap() > 0, "{before}");
    let cleared = clear_cache(&first_app).await;
    assert_eq!(
        cleared["cleared_records"].as_u64(),
        Some(records.as_u64().unwrap() + secondary.as_u64().unwrap())
    );
    assert_eq!(cleared["caches"][0]["secondary_records"], 0);
    let rebuilt = first_app
        .post_json("/v1/scenes/box/tiles", &tile(8, 8, 10, true))
        .await;
    assert_eq!(header(&rebuilt, "x-rays"), rays_other);
    assert_eq!(rebuilt.bytes().await.unwrap(), other);

    let by_paths = first_app
        .post_json("/v1/scenes/box/tiles", &tile(4, 4, 9, false))
        .await;
    assert_eq!(by_paths.status(), StatusCode::OK);
    assert_ne!(by_paths.bytes().await.unwrap(), building);
}

#[tokio::test]
async fn eight_concurrent_clients_leave_a_consistent_cache() {
    eight_concurrent_clients(json!({}), 3).await;
}

/// Records gathering through the shared cache create nested records while
/// other requests read and extend it; they are counted all the same.
#[tokio::test]
async fn eight_concurrent_clients_with_ambient_bounces_leave_a_consistent_cache() {
    eight_concurrent_clients(json!({"ambient_bounces": 2}), 16).await;
}

async fn eight_concurrent_clients(extra: Value, max_depth: u32) {
    let app = spawn_app_with_scenes(&[("box.json", &small_cornell(16))], |config| {
        config.server.worker_threads = 2;
    })
    .await;
    let mut clients = tokio::task::JoinSet::new();
    for i in 0..8u32 {
        let mut body = bmc_tile((i % 4) * 4, (i / 4) * 8, 4, extra.clone());
        body["max_depth"] = json!(max_depth);
        let (client, url) = (app.client.clone(), app.url("/v1/scenes/box/tiles"));
        clients.spawn(async move {
            let response = client.post(url).json(&body).send().await.unwrap();
            assert_eq!(response.status(), StatusCode::OK);
            header(&response, "x-records-created")
        });
    }
    let created: u64 = clients.join_all().await.into_iter().sum();
    let stats = &cache_stats(&app).await["caches"][0]["stats"];
    assert!(created > 0);
    assert_eq!(stats["inserts"], created, "{stats}");
    assert_eq!(stats["evictions"], 0);
    assert_eq!(stats["records"], created, "no record lost");
    let (lookups, hits, misses) = (
        stats["lookups"].as_u64().unwrap(),
        stats["hits"].as_u64().unwrap(),
        stats["misses"].as_u64().unwrap(),
    );
    assert_eq!(hits + misses, lookups);
}

/// Issue 14, point 4: on the bundled sky scene at default tile options, the
/// BMC glossy estimate of the gold box (`m = 400`) met the sun, reflected
/// by the red sphere, on a negatively weighted direction and came out
/// negative: a black hole of about 6×7 pixels down to −0.9. The tiles
/// covering both glossy objects now have no negative channel and no pixel
/// of a glossy object far darker than the same surface around it; and as
/// one camera ray per pixel has no spread, the pixels where the guard fell
/// back to lobe sampling are the ones that report a variance (its own,
/// docs/math.md §13.3).
#[tokio::test]
async fn glossy_objects_of_the_sky_scene_have_no_negative_or_black_pixels() {
    const TILE: u32 = 32;
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes");
    let dir = tempfile::tempdir().unwrap();
    for name in ["sky.json", "sky.exr"] {
        std::fs::copy(root.join(name), dir.path().join(name)).unwrap();
    }
    let app = spawn_app_in(dir, |_| {}).await;

    // What each pixel centre shows: the material and shading normal of the
    // camera ray's first hit.
    let scene = Scene::load(&root.join("sky.json"), &root).unwrap();
    let material = |id: &str| scene.material_ids.iter().position(|m| m == id).unwrap();
    let (gold, red) = (material("gold"), material("red-glossy"));
    let (width, height) = scene.camera.resolution();
    let seen: Vec<Option<(usize, glam::DVec3)>> = (0..height)
        .flat_map(|y| (0..width).map(move |x| (x, y)))
        .map(|(x, y)| {
            let ray = scene
                .camera
                .generate_ray(f64::from(x) + 0.5, f64::from(y) + 0.5);
            scene
                .intersect(&ray)
                .map(|hit| (hit.material, hit.shading_normal))
        })
        .collect();
    let at = |x: u32, y: u32| seen[(y * width + x) as usize];
    let glossy = |x: u32, y: u32| at(x, y).is_some_and(|(m, _)| m == gold || m == red);

    // The tiles (aligned to TILE) holding a pixel of either glossy object.
    let mut tiles: Vec<(u32, u32)> = (0..height.div_ceil(TILE))
        .flat_map(|ty| (0..width.div_ceil(TILE)).map(move |tx| (tx * TILE, ty * TILE)))
        .filter(|&(x0, y0)| {
            (y0..(y0 + TILE).min(height))
                .any(|y| (x0..(x0 + TILE).min(width)).any(|x| glossy(x, y)))
        })
        .collect();
    tiles.sort_unstable();
    assert!(tiles.len() >= 9, "{tiles:?}");

    // The tile options that were the defaults when the hole was found:
    // one camera ray per pixel, 64 directions per glossy estimate, 16 light
    // samples, the shared cache.
    let mut rgb = vec![[f32::NAN; 3]; (width * height) as usize];
    let mut variance = vec![f32::NAN; (width * height) as usize];
    for &(x0, y0) in &tiles {
        let (w, h) = (TILE.min(width - x0), TILE.min(height - y0));
        let body = json!({"x": x0, "y": y0, "width": w, "height": h, "format": "json",
            "samples_per_pixel": 1, "pass": 0, "max_depth": 16,
            "estimator": {"samples": 64, "glossy_samples": 64, "light_samples": 16,
                          "accuracy": 0.5, "paths_per_direction": 1, "reproducible": false}});
        let response = app.post_json("/v1/scenes/sky/tiles", &body).await;
        assert_eq!(response.status(), StatusCode::OK, "{body}");
        let tile: Value = response.json().await.unwrap();
        let (_, _, pixels) = json_pixels(&tile);
        let spread = tile["variance"].as_array().unwrap();
        for (i, (p, v)) in pixels.iter().zip(spread).enumerate() {
            let (x, y) = (x0 + i as u32 % w, y0 + i as u32 / w);
            assert!(
                p.iter().all(|c| c.is_finite() && *c >= 0.0),
                "pixel ({x}, {y}) = {p:?}"
            );
            rgb[(y * width + x) as usize] = *p;
            variance[(y * width + x) as usize] = v.as_f64().unwrap() as f32;
        }
    }

    // No hole: every glossy pixel keeps at least a tenth of the median of
    // the pixels within 4 of it on the same surface facing the same way.
    let luminance = |x: u32, y: u32| rgb[(y * width + x) as usize].iter().sum::<f32>() / 3.0;
    let mut darkest = (f32::INFINITY, 0, 0);
    let mut checked = 0;
    for &(x0, y0) in &tiles {
        for y in y0..(y0 + TILE).min(height) {
            for x in x0..(x0 + TILE).min(width) {
                let Some((m, n)) = at(x, y).filter(|_| glossy(x, y)) else {
                    continue;
                };
                // Inside the object: its jittered ray cannot miss it.
                let interior = (y.saturating_sub(1)..(y + 2).min(height)).all(|v| {
                    (x.saturating_sub(1)..(x + 2).min(width))
                        .all(|u| at(u, v).is_some_and(|(mu, _)| mu == m))
                });
                if !interior {
                    continue;
                }
                let mut around: Vec<f32> = (y.saturating_sub(4)..(y + 5).min(height))
                    .flat_map(|v| (x.saturating_sub(4)..(x + 5).min(width)).map(move |u| (u, v)))
                    .filter(|&(u, v)| {
                        at(u, v).is_some_and(|(mu, nu)| mu == m && nu.dot(n) > 0.95)
                            && !luminance(u, v).is_nan()
                    })
                    .map(|(u, v)| luminance(u, v))
                    .collect();
                if around.len() < 15 {
                    continue;
                }
                around.sort_by(f32::total_cmp);
                let ratio = luminance(x, y) / around[around.len() / 2];
                if ratio < darkest.0 {
                    darkest = (ratio, x, y);
                }
                checked += 1;
            }
        }
    }
    assert!(checked > 10_000, "{checked}");
    assert!(
        darkest.0 > 0.1,
        "darkest glossy pixel relative to its surroundings: {darkest:?}"
    );

    // One ray per pixel (jittered within it): there is no spread, so a
    // pixel reports what its shading knows of its error: the glossy
    // fallback's paths on the glossy objects, the interpolated records'
    // posterior variance elsewhere (docs/math.md §16.3), where most pixels
    // are served by records and the sky's direct light, which no record
    // carries, keeps it small against the value (0.02 % at the median).
    let reported = |x: u32, y: u32| variance[(y * width + x) as usize];
    let touches_glossy = |x: u32, y: u32| {
        (y.saturating_sub(1)..(y + 2).min(height))
            .any(|v| (x.saturating_sub(1)..(x + 2).min(width)).any(|u| glossy(u, v)))
    };
    let (mut fell_back, mut diffuse) = (0, Vec::new());
    for &(x0, y0) in &tiles {
        for y in y0..(y0 + TILE).min(height) {
            for x in x0..(x0 + TILE).min(width) {
                if glossy(x, y) {
                    fell_back += usize::from(reported(x, y) > 0.0);
                } else if !touches_glossy(x, y) && luminance(x, y) > 0.0 {
                    diffuse.push(reported(x, y).sqrt() / luminance(x, y));
                }
            }
        }
    }
    assert!(fell_back > 0);
    diffuse.sort_by(f32::total_cmp);
    let served = diffuse.iter().filter(|&&r| r > 0.0).count();
    assert!(served > diffuse.len() / 2, "{served} of {}", diffuse.len());
    let median = diffuse[diffuse.len() / 2];
    assert!(
        median > 0.0 && median < 0.1,
        "median relative error {median}"
    );
}

/// Each preset's `estimator` from `GET /v1/presets` posts back as a tile
/// request's estimator unchanged: accepted, and resolved to the very
/// configuration the preset names (the second tile is the first one's
/// memoised passes, the same bytes with nothing rendered).
#[tokio::test]
async fn every_preset_estimator_posts_back_unchanged() {
    let app = spawn_app_with_scenes(&[("tiny.json", TINY_SCENE)], |_| {}).await;
    let presets: Value = app.get("/v1/presets").await.json().await.unwrap();
    let presets = presets.as_array().expect("a list");
    assert_eq!(presets.len(), 5);
    for preset in presets {
        let name = preset["name"].as_str().unwrap();
        let estimator = &preset["estimator"];
        assert_eq!(estimator["method"], "cache", "{name}");
        assert!(estimator["min_pixels"].is_number(), "{name}: {estimator}");
        let body = json!({"x": 0, "y": 0, "width": 4, "height": 4,
                          "format": "json", "preset": name});
        let mut with_estimator = body.clone();
        with_estimator["estimator"] = estimator.clone();
        let named = app.post_json("/v1/scenes/tiny/tiles", &body).await;
        assert_eq!(named.status(), StatusCode::OK, "{name}");
        let named = named.bytes().await.unwrap();
        let posted_back = app
            .post_json("/v1/scenes/tiny/tiles", &with_estimator)
            .await;
        assert_eq!(posted_back.status(), StatusCode::OK, "{name}: {estimator}");
        assert_eq!(posted_back.headers()["x-passes-rendered"], "0", "{name}");
        assert_eq!(posted_back.bytes().await.unwrap(), named, "{name}");
    }
}
