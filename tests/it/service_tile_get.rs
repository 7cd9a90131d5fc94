//! `GET /v1/scenes/{id}/tiles/{tx}/{ty}.{format}` end to end: reproducible
//! bytes and ETags (across other requests and a restart, for the last pass
//! and an intermediate one), 304s, passes
//! without wasted work, the AOVs, denoised tiles, CORS and bad parameters.

use crate::common::{TestApp, error_of, spawn_app_in};
use reqwest::StatusCode;
use serde_json::{Value, json};

/// The bundled Cornell box with a 48×40 camera (a partial tile column and
/// row at size 32), in a scenes directory of its own.
fn scenes_dir() -> tempfile::TempDir {
    let dir = tempfile::tempdir().unwrap();
    let mut doc: Value =
        serde_json::from_str(include_str!("../../scenes/cornell-box.json")).unwrap();
    doc["camera"]["width"] = json!(48);
    doc["camera"]["height"] = json!(40);
    std::fs::write(dir.path().join("box.json"), doc.to_string()).unwrap();
    dir
}

async fn spawn() -> TestApp {
    spawn_app_in(scenes_dir(), |_| {}).await
}

/// Draft tiles of 32 pixels: cheap in a debug build.
const DRAFT: &str = "size=32&preset=draft";

async fn fetch(app: &TestApp, path: &str) -> (StatusCode, reqwest::header::HeaderMap, Vec<u8>) {
    let response = app.get(path).await;
    let status = response.status();
    let headers = response.headers().clone();
    (status, headers, response.bytes().await.unwrap().to_vec())
}

fn number(headers: &reqwest::header::HeaderMap, name: &str) -> u64 {
    headers[name].to_str().unwrap().parse().unwrap()
}

#[tokio::test]
async fn the_same_url_gives_the_same_bytes_across_requests_and_restarts() {
    let url = format!("/v1/scenes/box/tiles/1/0.png?{DRAFT}&exposure=1");
    let app = spawn().await;
    let (status, first_headers, first) = fetch(&app, &url).await;
    assert_eq!(status, StatusCode::OK);
    assert_eq!(first_headers["content-type"], "image/png");
    assert_eq!(first_headers["access-control-allow-origin"], "*");
    assert!(
        first_headers["cache-control"]
            .to_str()
            .unwrap()
            .contains("max-age")
    );
    let etag = first_headers["etag"].to_str().unwrap().to_owned();
    assert!(etag.starts_with('"') && etag.len() > 10, "{etag}");
    assert!(number(&first_headers, "x-records-created") > 0);
    // The scene's cache report counts them as content-keyed, and clearing the
    // shared caches leaves them (they would come back bit for bit).
    let report: Value = app.get("/v1/scenes/box/cache").await.json().await.unwrap();
    let held = &report["content_keyed"];
    assert_eq!(held["sets"], 1, "{report}");
    assert_eq!(
        held["records"],
        number(&first_headers, "x-records-created"),
        "{report}"
    );
    let cleared: Value = app
        .delete("/v1/scenes/box/cache")
        .await
        .json()
        .await
        .unwrap();
    assert_eq!(
        cleared["content_keyed"], report["content_keyed"],
        "{cleared}"
    );
    // The edge tile is clipped to the image: 16 of 32 columns.
    assert_eq!(&first[16..20], &16u32.to_be_bytes());
    // Other work in between: other tiles and seeds, a POST through the shared cache.
    for other in [
        format!("/v1/scenes/box/tiles/0/0.png?{DRAFT}"),
        format!("/v1/scenes/box/tiles/1/0.png?{DRAFT}&seed=4"),
    ] {
        assert_eq!(fetch(&app, &other).await.0, StatusCode::OK);
    }
    let post = app
        .post_json(
            "/v1/scenes/box/tiles",
            &json!({"x": 0, "y": 0, "width": 48, "height": 40, "preset": "draft",
                    "estimator": {"reproducible": false}}),
        )
        .await;
    assert_eq!(post.status(), StatusCode::OK);
    let (_, again_headers, again) = fetch(&app, &url).await;
    assert_eq!(again, first);
    assert_eq!(again_headers["etag"], etag.as_str());
    // A repeat costs no rays: the passes are kept.
    assert_eq!(number(&again_headers, "x-rays"), 0);
    // Revalidation.
    let response = app
        .client
        .get(app.url(&url))
        .header("if-none-match", &etag)
        .send()
        .await
        .unwrap();
    assert_eq!(response.status(), StatusCode::NOT_MODIFIED);
    assert_eq!(response.headers()["etag"], etag.as_str());
    assert!(response.bytes().await.unwrap().is_empty());
    // Another exposure is another entity.
    let (_, other_headers, _) = fetch(&app, &format!("/v1/scenes/box/tiles/1/0.png?{DRAFT}")).await;
    assert_ne!(other_headers["etag"], etag.as_str());
    // A pass of a progressive preset after its first (an adaptive one, docs/math.md
    // §16.5), as the viewer's ladder asks for it.
    let pass_url = "/v1/scenes/box/tiles/0/0.exr?size=32&preset=preview&pass=1";
    let (status, _, pass_bytes) = fetch(&app, pass_url).await;
    assert_eq!(status, StatusCode::OK);
    // After a restart (a new process state, the same scene files).
    let copy = tempfile::tempdir().unwrap();
    std::fs::copy(
        app.scenes_dir.path().join("box.json"),
        copy.path().join("box.json"),
    )
    .unwrap();
    drop(app);
    let restarted = spawn_app_in(copy, |_| {}).await;
    let (_, headers, bytes) = fetch(&restarted, &url).await;
    assert_eq!(headers["etag"], etag.as_str());
    assert_eq!(bytes, first);
    assert_eq!(fetch(&restarted, pass_url).await.2, pass_bytes);
}

#[tokio::test]
async fn passes_refine_without_redoing_earlier_work() {
    let app = spawn().await;
    let pass = |k: u32| format!("/v1/scenes/box/tiles/0/0.json?size=32&preset=preview&pass={k}");
    let (status, h0, p0) = fetch(&app, &pass(0)).await;
    assert_eq!(status, StatusCode::OK);
    let passes = number(&h0, "x-passes");
    assert!(passes >= 2);
    assert_eq!(number(&h0, "x-passes-rendered"), 1);
    assert_eq!(number(&h0, "x-denoised"), 0);
    let (_, h1, p1) = fetch(&app, &pass(1)).await;
    // Pass 1 reuses pass 0 and the records: one more pass, no records.
    assert_eq!(number(&h1, "x-passes-rendered"), 1);
    assert_eq!(number(&h1, "x-records-created"), 0);
    let (p0, p1): (Value, Value) = (
        serde_json::from_slice(&p0).unwrap(),
        serde_json::from_slice(&p1).unwrap(),
    );
    assert_ne!(p0["rgb"], p1["rgb"]);
    // The mean of two passes has less variance than one.
    let mean_variance = |v: &Value| {
        let v = v["variance"].as_array().unwrap();
        v.iter().map(|x| x.as_f64().unwrap()).sum::<f64>() / v.len() as f64
    };
    assert!(mean_variance(&p1) < mean_variance(&p0));
    // The default is the last pass: the final image.
    let last = format!(
        "/v1/scenes/box/tiles/0/0.json?size=32&preset=preview&pass={}",
        passes - 1
    );
    let (_, _, final_bytes) = fetch(&app, &last).await;
    let (_, _, default_bytes) = fetch(&app, "/v1/scenes/box/tiles/0/0.json?size=32").await;
    assert_eq!(final_bytes, default_bytes);
    // POST of the same rectangle, preset and seed: the same image.
    let post = app
        .post_json(
            "/v1/scenes/box/tiles",
            &json!({"x": 0, "y": 0, "width": 32, "height": 32, "format": "json"}),
        )
        .await;
    assert_eq!(post.status(), StatusCode::OK);
    assert_eq!(post.bytes().await.unwrap().to_vec(), default_bytes);
}

#[tokio::test]
async fn uncertainty_and_record_aovs_show_what_they_promise() {
    let app = spawn().await;
    let base = "/v1/scenes/box/tiles/0/0";
    let (_, _, radiance) = fetch(&app, &format!("{base}.png?{DRAFT}")).await;
    let (status, headers, std_dev) = fetch(&app, &format!("{base}.png?{DRAFT}&aov=std_dev")).await;
    assert_eq!(status, StatusCode::OK);
    assert_eq!(headers["x-std-dev-scale"], "0.2");
    assert_ne!(std_dev, radiance);
    let (_, headers, _) = fetch(&app, &format!("{base}.png?{DRAFT}&aov=std_dev&scale=0.05")).await;
    assert_eq!(headers["x-std-dev-scale"], "0.05");
    // Absolute standard errors as JSON: √variance of the radiance tile.
    let (_, _, tile) = fetch(&app, &format!("{base}.json?{DRAFT}")).await;
    let (_, _, sd) = fetch(&app, &format!("{base}.json?{DRAFT}&aov=std_dev")).await;
    let (tile, sd): (Value, Value) = (
        serde_json::from_slice(&tile).unwrap(),
        serde_json::from_slice(&sd).unwrap(),
    );
    let variance = tile["variance"][5].as_f64().unwrap();
    let sigma = sd["rgb"][5][0].as_f64().unwrap();
    assert!(
        (sigma - variance.sqrt()).abs() <= 1e-6 * (1.0 + sigma),
        "{sigma} {variance}"
    );
    assert!(
        tile["variance"]
            .as_array()
            .unwrap()
            .iter()
            .any(|v| v.as_f64().unwrap() > 0.0)
    );
    // Records: inside the tile, with radii, and drawn on a transparent overlay.
    let (status, headers, records) = fetch(&app, &format!("{base}.json?{DRAFT}&aov=records")).await;
    assert_eq!(status, StatusCode::OK);
    let records: Value = serde_json::from_slice(&records).unwrap();
    let list = records["records"].as_array().unwrap();
    assert!(!list.is_empty());
    assert_eq!(number(&headers, "x-records"), list.len() as u64);
    for r in list {
        let [px, py] = [
            r["pixel"][0].as_f64().unwrap(),
            r["pixel"][1].as_f64().unwrap(),
        ];
        assert!(
            (0.0..32.0).contains(&px) && (0.0..32.0).contains(&py),
            "{r}"
        );
        assert!(r["radius"].as_f64().unwrap() > 0.0);
    }
    let (_, headers, overlay) = fetch(&app, &format!("{base}.png?{DRAFT}&aov=records")).await;
    assert_eq!(headers["content-type"], "image/png");
    // Colour type 6: RGBA.
    assert_eq!(overlay[25], 6);
}

/// `denoise=true`: the same bytes on every request, its own ETag, each
/// pixel within one of its standard errors of the plain tile's value with
/// the same error bar, closer to the `final` preset's tile, and the guide
/// rays counted in `x-rays`.
#[tokio::test]
async fn denoised_tiles_stay_within_their_error_bars() {
    let app = spawn().await;
    let base = "/v1/scenes/box/tiles/0/0.json?size=32&preset=preview";
    let (_, plain_headers, plain) = fetch(&app, base).await;
    let (_, _, converged) = fetch(&app, &base.replace("preview", "final")).await;
    let denoised_url = format!("{base}&denoise=true");
    let (status, headers, denoised) = fetch(&app, &denoised_url).await;
    assert_eq!(status, StatusCode::OK);
    assert_ne!(headers["etag"], plain_headers["etag"]);
    // The passes are memoised: only the guides' four rays per pixel are new.
    assert_eq!(number(&headers, "x-rays"), 4 * 32 * 32);
    let (_, again_headers, again) = fetch(&app, &denoised_url).await;
    assert_eq!(
        (again, &again_headers["etag"]),
        (denoised.clone(), &headers["etag"])
    );
    let [plain, denoised, converged]: [Value; 3] =
        [plain, denoised, converged].map(|b| serde_json::from_slice(&b).unwrap());
    assert_eq!(plain["variance"], denoised["variance"]);
    let rgb = |tile: &Value, i: usize, k: usize| tile["rgb"][i][k].as_f64().unwrap();
    let (mut moved, mut squared_error) = (0, [0.0; 2]);
    for i in 0..32 * 32 {
        let sigma = plain["variance"][i].as_f64().unwrap().sqrt();
        for k in 0..3 {
            let (a, b) = (rgb(&plain, i, k), rgb(&denoised, i, k));
            assert!(
                (a - b).abs() <= sigma * (1.0 + 1e-5) + 1e-6,
                "pixel {i}: {a} -> {b} (σ {sigma})"
            );
            moved += usize::from(a != b);
            for (e, tile) in squared_error.iter_mut().zip([&plain, &denoised]) {
                *e += (rgb(tile, i, k) - rgb(&converged, i, k)).powi(2);
            }
        }
    }
    assert!(moved > 32 * 32, "{moved} channels moved");
    assert!(
        squared_error[1] < 0.9 * squared_error[0],
        "{squared_error:?}"
    );
}

/// A mirror makes caustics, which records sample badly: the same preset
/// path traces the scene and denoises its tiles unless a tile says not to
/// (docs/math.md §16.7).
#[tokio::test]
async fn a_scene_with_a_mirror_is_path_traced_and_denoised_by_default() {
    let dir = scenes_dir();
    let path = dir.path().join("box.json");
    let mut doc: Value = serde_json::from_str(&std::fs::read_to_string(&path).unwrap()).unwrap();
    let white = doc["materials"][0]["id"].clone();
    doc["materials"][0] = json!({"id": white, "type": "conductor"});
    std::fs::write(&path, doc.to_string()).unwrap();
    let app = spawn_app_in(dir, |_| {}).await;
    let url = format!("/v1/scenes/box/tiles/0/0.exr?{DRAFT}");
    let (status, headers, _) = fetch(&app, &url).await;
    assert_eq!(status, StatusCode::OK);
    assert_eq!(number(&headers, "x-denoised"), 1);
    assert_eq!(number(&headers, "x-records-created"), 0);
    assert_eq!(number(&headers, "x-cache-hits"), 0);
    let (_, raw_headers, _) = fetch(&app, &format!("{url}&denoise=false")).await;
    assert_eq!(number(&raw_headers, "x-denoised"), 0);
    assert_ne!(raw_headers["etag"], headers["etag"]);
    // Naming the cache's knobs asks for the cache.
    let body = json!({"x": 0, "y": 0, "width": 16, "height": 16, "preset": "draft",
        "estimator": {"method": "cache", "samples": 32}, "format": "json"});
    let response = app.post_json("/v1/scenes/box/tiles", &body).await;
    assert_eq!(response.status(), StatusCode::OK);
    assert!(number(response.headers(), "x-records-created") > 0);
}

#[tokio::test]
async fn bad_tile_parameters_are_named() {
    let app = spawn().await;
    let cases = [
        ("/v1/scenes/box/tiles/2/0.png?size=32", "tx"),
        ("/v1/scenes/box/tiles/0/2.png?size=32", "ty"),
        ("/v1/scenes/box/tiles/0/0.png?size=4096", "size"),
        ("/v1/scenes/box/tiles/0/0.png?size=0", "size"),
        ("/v1/scenes/box/tiles/0/0.png?preset=best", "preset"),
        ("/v1/scenes/box/tiles/0/0.png?aov=albedo", "aov"),
        ("/v1/scenes/box/tiles/0/0.png?pass=99", "pass"),
        ("/v1/scenes/box/tiles/0/0.png?seed=-1", "seed"),
        ("/v1/scenes/box/tiles/0/0.png?colour=1", "colour"),
        ("/v1/scenes/box/tiles/0/0.png?aov=std_dev&scale=0", "scale"),
        ("/v1/scenes/box/tiles/0/0.exr?aov=records", "format"),
        ("/v1/scenes/box/tiles/0/0.gif", "format"),
        ("/v1/scenes/box/tiles/0/0", "format"),
        ("/v1/scenes/box/tiles/x/0.png", "tx"),
        ("/v1/scenes/box/tiles/0/0.png?denoise=maybe", "denoise"),
    ];
    for (url, field) in cases {
        let response = app.get(url).await;
        assert_eq!(response.status(), StatusCode::UNPROCESSABLE_ENTITY, "{url}");
        let (code, got) = error_of(response).await;
        assert_eq!(code, "invalid_field", "{url}");
        assert_eq!(got.as_deref(), Some(field), "{url}");
    }
    // A number the parser cannot read is quoted, with what was wanted.
    let response = app.get("/v1/scenes/box/tiles/0/0.png?pass=-1").await;
    let (error, _) = crate::common::error_json(response).await;
    let message = error["error"]["message"].as_str().unwrap();
    assert!(
        message.starts_with(r#""-1" is not a pass: expected a whole number"#),
        "{message}"
    );
    let response = app.get("/v1/scenes/nope/tiles/0/0.png").await;
    assert_eq!(response.status(), StatusCode::NOT_FOUND);
    let health: Value = app.get("/health").await.json().await.unwrap();
    assert_eq!(health["status"], "ok");
}

/// `render --preset final` on the command line renders every tile as the
/// service's GET tiles of that preset do: with `--tile` equal to the
/// tiles' `size`, the same values and variances, bit for bit.
#[tokio::test]
async fn the_cli_renders_a_preset_as_the_get_tiles_do() {
    let app = spawn().await;
    let out = tempfile::tempdir().unwrap();
    let exr = out.path().join("final.exr");
    let scene = app.scenes_dir.path().join("box.json");
    let rendered = tokio::task::spawn_blocking({
        let (scene, exr) = (scene.clone(), exr.clone());
        move || {
            std::process::Command::new(env!("CARGO_BIN_EXE_bmc-irradiance"))
                .args([
                    "render",
                    "--preset",
                    "final",
                    "--tile",
                    "32",
                    "--threads",
                    "2",
                ])
                .arg("--scene")
                .arg(&scene)
                .arg("--out")
                .arg(&exr)
                .output()
                .unwrap()
        }
    })
    .await
    .unwrap();
    assert!(
        rendered.status.success(),
        "{}",
        String::from_utf8_lossy(&rendered.stderr)
    );
    let cli = bmc_irradiance::image::read_exr(&exr).unwrap();
    assert_eq!((cli.width(), cli.height()), (48, 40));
    let cli_variance = cli.variance().expect("the mean's variance");
    for (tx, ty) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
        let url = format!("/v1/scenes/box/tiles/{tx}/{ty}.exr?size=32&preset=final");
        let (status, _, bytes) = fetch(&app, &url).await;
        assert_eq!(status, StatusCode::OK, "{url}");
        let tile = bmc_irradiance::image::decode_exr(&bytes).unwrap();
        let tile_variance = tile.variance().expect("the tile's variance");
        for y in 0..tile.height() {
            for x in 0..tile.width() {
                let (cx, cy) = (32 * tx + x, 32 * ty + y);
                let (i, j) = ((y * tile.width() + x) as usize, (cy * 48 + cx) as usize);
                assert_eq!(tile.rgb()[i], cli.rgb()[j], "pixel ({cx}, {cy})");
                assert_eq!(tile_variance[i], cli_variance[j], "pixel ({cx}, {cy})");
            }
        }
    }
}

/// No tile seams (issue 67): two adjacent GET tiles and the one tile
/// holding both give every pixel the same value, so their shared edge is
/// the image's own (each tile is shaded by the records of the blocks
/// around it, not by its own records only). The first pass of the ladder
/// is uniform, so nothing else of a pixel depends on its tile.
#[tokio::test]
async fn adjacent_tiles_share_their_edge_with_the_tile_holding_both() {
    let app = spawn().await;
    let app = &app;
    let tile = |tx: u32, size: u32| async move {
        let url = format!("/v1/scenes/box/tiles/{tx}/0.json?size={size}&preset=draft&pass=0");
        let (status, _, body) = fetch(app, &url).await;
        assert_eq!(status, StatusCode::OK, "{url}");
        serde_json::from_slice::<Value>(&body).unwrap()
    };
    let (left, right, both) = (tile(0, 32).await, tile(1, 32).await, tile(0, 48).await);
    let pixel = |t: &Value, width: usize, x: usize, y: usize| t["rgb"][y * width + x].clone();
    for y in 0..32 {
        for x in 0..48 {
            let apart = match x < 32 {
                true => pixel(&left, 32, x, y),
                false => pixel(&right, 16, x - 32, y),
            };
            assert_eq!(apart, pixel(&both, 48, x, y), "({x}, {y})");
        }
    }
}
