//! `POST /v1/scenes` as `multipart/form-data`: a scene with its OBJ mesh and
//! EXR map renders; names that would escape, documents that reach outside
//! the upload, and uploads over the limit are refused with the field named.

use std::path::Path;

use crate::common::{TestApp, spawn_app_with};
use bmc_irradiance::testing::{BOUNDARY, multipart};
use reqwest::StatusCode;
use serde_json::{Value, json};

/// A document with a mesh under `meshes/` and the bundled sky map.
fn document(mesh: &str) -> String {
    json!({
        "name": "uploaded",
        "materials": [{"id": "m", "type": "diffuse", "reflectance": [0.6, 0.5, 0.4]}],
        "shapes": [{"type": "obj", "filename": mesh, "material": "m"}],
        "environment": {"type": "envmap", "filename": "sky.exr"},
        "camera": {"type": "perspective", "fov": 40, "width": 16, "height": 16,
                   "origin": [0, 0.5, 3], "target": [0, 0.3, 0], "up": [0, 1, 0]}
    })
    .to_string()
}

const OBJ: &str = "v -1 0 -1\nv 1 0 -1\nv 1 0 1\nv -1 0 1\nv 0 1 0\n\
                   f 1 2 3\nf 1 3 4\nf 1 2 5\nf 2 3 5\n";

/// The scene `uploaded` with its mesh under `meshes/` and the sky map, as
/// one multipart body.
pub(crate) fn with_mesh_and_map() -> Vec<u8> {
    multipart(&[
        (
            "scene",
            Some("scene.json"),
            "application/json",
            document("meshes/pyramid.obj").into_bytes(),
        ),
        (
            "asset",
            Some("meshes/pyramid.obj"),
            "text/plain",
            OBJ.as_bytes().to_vec(),
        ),
        ("asset", Some("sky.exr"), "image/x-exr", sky()),
    ])
}

fn sky() -> Vec<u8> {
    std::fs::read(Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/sky.exr")).unwrap()
}

async fn upload(app: &TestApp, query: &str, body: Vec<u8>) -> reqwest::Response {
    app.client
        .post(app.url(&format!("/v1/scenes{query}")))
        .header(
            "content-type",
            format!("multipart/form-data; boundary={BOUNDARY}"),
        )
        .body(body)
        .send()
        .await
        .unwrap()
}

#[tokio::test]
async fn a_scene_uploaded_with_its_mesh_and_map_renders() {
    let app = spawn_app_with(|_| {}).await;
    let body = with_mesh_and_map();
    let response = upload(&app, "", body.clone()).await;
    assert_eq!(response.status(), StatusCode::CREATED);
    let summary: Value = response.json().await.unwrap();
    assert_eq!(summary["id"], "uploaded");
    assert_eq!(summary["triangles"], 4);
    assert_eq!(summary["environment"], true);
    let digest = summary["digest"].as_str().unwrap().to_owned();
    // It renders: the map lights the mesh.
    let tile: Value = app
        .get("/v1/scenes/uploaded/tiles/0/0.json?preset=draft&size=16")
        .await
        .json()
        .await
        .unwrap();
    let lit = tile["rgb"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|p| p[0].as_f64().unwrap() > 0.0)
        .count();
    assert!(lit > 100, "{lit} of 256 pixels lit");
    // The same upload again, replacing it: the same content digest (200).
    let again = upload(&app, "?replace=true", body).await;
    assert_eq!(again.status(), StatusCode::OK);
    let again: Value = again.json().await.unwrap();
    assert_eq!(again["digest"], digest.as_str());
}

#[tokio::test]
async fn escaping_and_oversized_uploads_are_refused() {
    let app = spawn_app_with(|config| config.limits.max_upload_bytes = 64 * 1024).await;
    let scene = |mesh: &str| {
        (
            "scene",
            Some("scene.json"),
            "application/json",
            document(mesh).into_bytes(),
        )
    };
    let cases: Vec<(Vec<u8>, &str)> = vec![
        (
            multipart(&[
                scene("x.obj"),
                ("asset", Some("../x.obj"), "text/plain", OBJ.into()),
            ]),
            "assets[0]",
        ),
        (
            multipart(&[
                scene("x.obj"),
                ("asset", Some("/tmp/x.obj"), "text/plain", OBJ.into()),
            ]),
            "assets[0]",
        ),
        (
            multipart(&[
                scene("x.obj"),
                ("asset", Some("x.obj"), "text/plain", OBJ.into()),
                ("asset", Some("a/../x.obj"), "text/plain", OBJ.into()),
            ]),
            "assets[1]",
        ),
        // The document itself reaching outside the upload.
        (
            multipart(&[
                scene("../../../../etc/hostname"),
                ("asset", Some("sky.exr"), "image/x-exr", sky()),
            ]),
            "shapes[0].filename",
        ),
        // A referenced file that was not uploaded.
        (
            multipart(&[
                scene("meshes/missing.obj"),
                ("asset", Some("sky.exr"), "image/x-exr", sky()),
            ]),
            "shapes[0].filename",
        ),
        (
            multipart(&[("asset", Some("x.obj"), "text/plain", OBJ.into())]),
            "scene",
        ),
        (
            multipart(&[
                scene("x.obj"),
                (
                    "asset",
                    Some("big.bin"),
                    "application/octet-stream",
                    vec![7; 80 * 1024],
                ),
            ]),
            "limits.max_upload_bytes",
        ),
    ];
    for (body, field) in cases {
        let response = upload(&app, "", body).await;
        assert!(
            response.status().is_client_error(),
            "{field}: {}",
            response.status()
        );
        let (body, _) = crate::common::error_json(response).await;
        assert_eq!(body["error"]["field"].as_str(), Some(field), "{body}");
        if field == "limits.max_upload_bytes" {
            // The limit as configured, not a made-up length one above it.
            let message = body["error"]["message"].as_str().unwrap();
            assert!(message.contains(" 65536 bytes"), "{message}");
            assert!(!message.contains("65537"), "{message}");
        }
    }
    // Nothing was added, and the service is fine.
    let scenes: Value = app.get("/v1/scenes").await.json().await.unwrap();
    assert_eq!(scenes, json!([]));
    let health: Value = app.get("/health").await.json().await.unwrap();
    assert_eq!(health["status"], "ok");
}

/// Uploads read at once are bounded (`limits.max_concurrent_uploads`): one
/// more gets 503 with `Retry-After`, naming the limit, while the others are
/// read; and the posted scenes kept on disk have a budget
/// (`cache.posted_scene_bytes`): a POST beyond it gets 507 naming it and
/// changes nothing.
#[tokio::test]
async fn uploads_at_once_and_the_disk_they_take_are_bounded() {
    use tokio::io::AsyncWriteExt;
    let data = tempfile::tempdir().unwrap();
    let kept = data.path().to_owned();
    let body = with_mesh_and_map();
    // Room for the scene and a copy or two, not for ten.
    let budget = 3 * body.len() as u64;
    let app = spawn_app_with(move |config| {
        config.limits.max_concurrent_uploads = 1;
        config.server.header_read_timeout_secs = 5;
        config.cache.data_dir = kept;
        config.cache.posted_scene_bytes = budget;
    })
    .await;
    // An upload that has sent its head and half its body holds the slot.
    let addr = app.base.trim_start_matches("http://").to_owned();
    let mut slow = tokio::net::TcpStream::connect(&addr).await.unwrap();
    let head = format!(
        "POST /v1/scenes HTTP/1.1\r\nHost: x\r\nContent-Type: multipart/form-data; boundary={BOUNDARY}\r\nContent-Length: {}\r\n\r\n",
        body.len()
    );
    slow.write_all(head.as_bytes()).await.unwrap();
    slow.write_all(&body[..body.len() / 2]).await.unwrap();
    tokio::time::sleep(std::time::Duration::from_millis(300)).await;
    let busy = upload(&app, "", body.clone()).await;
    assert_eq!(busy.status(), StatusCode::SERVICE_UNAVAILABLE);
    assert_eq!(busy.headers()["retry-after"], "1");
    let (body_json, _) = crate::common::error_json(busy).await;
    assert_eq!(body_json["error"]["field"], "limits.max_concurrent_uploads");
    drop(slow);
    tokio::time::sleep(std::time::Duration::from_millis(300)).await;

    // The mesh scene with its map fits; copies under other names do not.
    assert_eq!(
        upload(&app, "", body.clone()).await.status(),
        StatusCode::CREATED
    );
    let mut refused = None;
    for i in 0..10 {
        let name: &[u8] = b"\"uploaded\"";
        let at = body.windows(name.len()).position(|w| w == name).unwrap();
        let renamed = [
            &body[..at],
            format!("\"copy-{i}\"").as_bytes(),
            &body[at + name.len()..],
        ]
        .concat();
        let response = upload(&app, "", renamed).await;
        if response.status() != StatusCode::CREATED {
            refused = Some((i, response));
            break;
        }
    }
    let (i, response) = refused.expect("the disk budget never refused a copy");
    assert_eq!(response.status(), StatusCode::INSUFFICIENT_STORAGE);
    let (body_json, _) = crate::common::error_json(response).await;
    assert_eq!(
        body_json["error"]["field"], "cache.posted_scene_bytes",
        "{body_json}"
    );
    assert_eq!(app.get(&format!("/v1/scenes/copy-{i}")).await.status(), 404);
    assert_eq!(app.get("/v1/scenes/uploaded").await.status(), 200);
}
