//! Small scene uploads that used to crash or exhaust the service: XML
//! expansion, huge element counts, meshes repeated across shapes, special
//! files in the scenes directory, huge PNG textures, duplicate JSON keys.
//! Each is answered quickly with its status and JSON error body, and the
//! service keeps serving the bundled scenes afterwards.

use std::path::Path;
use std::time::Duration;

use crate::common::{TestApp, error_json, spawn_app_in};
use reqwest::StatusCode;
use serde_json::{Value, json};
use tempfile::TempDir;

/// Ids of the scenes bundled in `scenes/`, loaded from a copy at startup.
const BUNDLED: [&str; 6] = [
    "cornell-box",
    "cornell-box-xml",
    "mesh",
    "overcast",
    "sky",
    "studio",
];

/// A generous bound for "answers promptly": the attacks took minutes or
/// never returned.
const PROMPT: Duration = Duration::from_secs(10);

/// A copy of the bundled scenes directory.
fn bundled_dir() -> TempDir {
    fn copy(from: &Path, to: &Path) {
        std::fs::create_dir_all(to).unwrap();
        for entry in std::fs::read_dir(from).unwrap() {
            let entry = entry.unwrap();
            let target = to.join(entry.file_name());
            if entry.file_type().unwrap().is_dir() {
                copy(&entry.path(), &target);
            } else {
                std::fs::copy(entry.path(), target).unwrap();
            }
        }
    }
    let dir = tempfile::tempdir().unwrap();
    copy(
        &Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes"),
        dir.path(),
    );
    dir
}

/// Starts the service, failing (instead of hanging) if startup blocks.
async fn start(dir: TempDir, adjust: impl FnOnce(&mut bmc_irradiance::service::Config)) -> TestApp {
    tokio::time::timeout(Duration::from_secs(60), spawn_app_in(dir, adjust))
        .await
        .expect("the service starts listening")
}

fn client() -> reqwest::Client {
    reqwest::Client::builder().timeout(PROMPT).build().unwrap()
}

async fn post(app: &TestApp, path: &str, content_type: &str, body: Vec<u8>) -> reqwest::Response {
    client()
        .post(app.url(path))
        .header("content-type", content_type)
        .body(body)
        .send()
        .await
        .expect("the service answers promptly")
}

async fn post_json(app: &TestApp, body: &Value) -> reqwest::Response {
    post(
        app,
        "/v1/scenes",
        "application/json",
        body.to_string().into_bytes(),
    )
    .await
}

async fn post_xml(app: &TestApp, query: &str, xml: &str) -> reqwest::Response {
    let path = format!("/v1/scenes?{query}");
    post(app, &path, "application/xml", xml.as_bytes().to_vec()).await
}

/// Asserts the status and the error body; returns `(code, field, message)`.
async fn expect_error(response: reqwest::Response, status: StatusCode) -> (String, String, String) {
    assert_eq!(response.status(), status);
    let (body, len) = error_json(response).await;
    // Errors never echo huge values back.
    assert!(len < 4096, "{len} bytes of error body");
    let error = &body["error"];
    (
        error["code"].as_str().unwrap().to_owned(),
        error["field"].as_str().unwrap_or_default().to_owned(),
        error["message"].as_str().unwrap().to_owned(),
    )
}

/// `GET path` as JSON, within the tests' client timeout.
async fn get_json(app: &TestApp, path: &str) -> Value {
    client()
        .get(app.url(path))
        .send()
        .await
        .unwrap()
        .json()
        .await
        .unwrap()
}

/// `/health` is ok and every bundled scene is still listed.
async fn still_serving(app: &TestApp) {
    let health: Value = get_json(app, "/health").await;
    assert_eq!(health["status"], "ok");
    let list: Value = get_json(app, "/v1/scenes").await;
    let ids: Vec<&str> = list
        .as_array()
        .unwrap()
        .iter()
        .map(|s| s["id"].as_str().unwrap())
        .collect();
    for id in BUNDLED {
        assert!(ids.contains(&id), "{id} missing from {ids:?}");
    }
}

/// A scene document named `name` with `shapes`, lit by a constant sky.
fn scene(name: &str, shapes: Value) -> Value {
    json!({
        "name": name,
        "materials": [{"id": "white", "type": "diffuse", "reflectance": [0.5, 0.5, 0.5]}],
        "shapes": shapes,
        "environment": {"type": "constant", "radiance": [1, 1, 1]},
        "camera": {"type": "perspective", "fov": 40, "origin": [0, 0, 3], "target": [0, 0, 0],
                   "up": [0, 1, 0], "width": 8, "height": 8}
    })
}

/// `count` shapes that each place the OBJ `filename`.
fn obj_shapes(filename: &str, count: usize) -> Value {
    (0..count)
        .map(|i| {
            json!({"type": "obj", "filename": filename, "material": "white",
                   "to_world": [{"translate": [i as f64, 0, 0]}]})
        })
        .collect()
}

/// A Mitsuba scene around `body`.
fn mitsuba(body: &str) -> String {
    format!("<scene version=\"3.0.0\">{body}</scene>")
}

/// `<default>` chain `a0 = "x"`, `aK = 10 × $a(K-1)`, up to `a{levels}`.
fn expansion_chain(levels: usize) -> String {
    let mut xml = String::from("<default name=\"a0\" value=\"x\"/>");
    for k in 1..=levels {
        let value = format!("$a{}", k - 1).repeat(10);
        xml.push_str(&format!("<default name=\"a{k}\" value=\"{value}\"/>"));
    }
    xml
}

#[tokio::test]
async fn xml_that_expands_or_repeats_is_refused_or_read_promptly() {
    let app = start(bundled_dir(), |_| {}).await;

    // 10⁹ bytes from 655: refused where a value passes 64 KiB (a5 = 10⁵ bytes).
    let bomb = mitsuba(&format!(
        "{}<integer name=\"n\" value=\"$a9\"/>",
        expansion_chain(9)
    ));
    assert!(bomb.len() < 700);
    let (code, field, message) = expect_error(
        post_xml(&app, "id=bomb", &bomb).await,
        StatusCode::UNPROCESSABLE_ENTITY,
    )
    .await;
    assert_eq!(code, "invalid_field");
    assert_eq!(field, "<default name=\"a5\">.value");
    assert!(message.contains("65536 bytes"), "{message}");

    // Values under the per-value cap that add up: refused at the use that
    // passes the per-document cap (10 KB × 420 > 4 MiB), naming it.
    let uses = "<float name=\"f\" value=\"$a4\"/>".repeat(420);
    let wide = mitsuba(&format!("{}{uses}", expansion_chain(4)));
    let (_, field, message) = expect_error(
        post_xml(&app, "id=wide", &wide).await,
        StatusCode::UNPROCESSABLE_ENTITY,
    )
    .await;
    assert_eq!(field, "<float name=\"f\">.value");
    assert!(message.contains("in this document"), "{message}");

    // A long value that is not a number is quoted cut short.
    let long = mitsuba(&format!(
        "{}<sensor type=\"perspective\"><float name=\"fov\" value=\"$a4\"/></sensor>",
        expansion_chain(4)
    ));
    let (_, field, message) = expect_error(
        post_xml(&app, "id=long", &long).await,
        StatusCode::UNPROCESSABLE_ENTITY,
    )
    .await;
    assert_eq!(field, "<float name=\"fov\">.value");
    assert!(message.contains("…"), "{message}");

    // 80 000 elements on one line, all unsupported: read in linear time and
    // accepted in lenient mode (the warnings are counted, not all kept).
    let many = mitsuba(&"<foo/>".repeat(80_000));
    let response = post_xml(&app, "id=many&lenient=true", &many).await;
    assert_eq!(response.status(), StatusCode::CREATED);
    let summary: Value = response.json().await.unwrap();
    // An XML document has no name of its own: the id names it.
    assert_eq!(summary["name"], "many");
    // The answer says what was approximated (the first ones, and how many),
    // and so does the scene's summary afterwards.
    let total = summary["approximations"].as_u64().unwrap();
    assert!(total >= 80_000, "{total}");
    let approximated = summary["approximated"].as_array().unwrap();
    assert!(!approximated.is_empty() && approximated.len() < 1000);
    assert!(
        approximated[0].as_str().unwrap().contains("<foo>"),
        "{summary}"
    );
    let again: Value = app.get("/v1/scenes/many").await.json().await.unwrap();
    assert_eq!(again["approximations"], total);

    still_serving(&app).await;
}

#[tokio::test]
async fn meshes_are_shared_and_scenes_are_budgeted() {
    // Room for the bundled scenes (the blob's 101 760 triangles in `mesh`
    // and in `studio`, a few dozen elsewhere) and two more copies of the
    // blob, not three.
    let app = start(bundled_dir(), |config| {
        config.scenes.max_triangles = 420_000;
        config.scenes.max_scenes = BUNDLED.len() + 2;
    })
    .await;

    // One scene placing the blob many times is refused before it is built.
    let (code, field, message) = expect_error(
        post_json(&app, &scene("blobs", obj_shapes("meshes/blob.obj", 40))).await,
        StatusCode::UNPROCESSABLE_ENTITY,
    )
    .await;
    assert_eq!(code, "invalid_field");
    assert!(field.starts_with("shapes["), "{field}");
    assert!(message.contains("MAX_SCENE_MEMORY_BYTES"), "{message}");

    let two = scene("two", obj_shapes("meshes/blob.obj", 2));
    assert_eq!(post_json(&app, &two).await.status(), StatusCode::CREATED);
    // Over the service-wide triangle budget: 507, nothing lost.
    let one = scene("one", obj_shapes("meshes/blob.obj", 1));
    let (code, field, _) = expect_error(
        post_json(&app, &one).await,
        StatusCode::INSUFFICIENT_STORAGE,
    )
    .await;
    assert_eq!(code, "insufficient_storage");
    assert_eq!(field, "scenes.max_triangles");
    // Replacing a scene counts the budget net of the scene it replaces.
    let replace = post(
        &app,
        "/v1/scenes?replace=true",
        "application/json",
        two.to_string().into_bytes(),
    );
    assert_eq!(replace.await.status(), StatusCode::OK);

    // Over the scene count.
    let tiny = |name: &str| scene(name, json!([{"type": "rectangle", "material": "white"}]));
    assert_eq!(
        post_json(&app, &tiny("t1")).await.status(),
        StatusCode::CREATED
    );
    let (_, field, _) = expect_error(
        post_json(&app, &tiny("t2")).await,
        StatusCode::INSUFFICIENT_STORAGE,
    )
    .await;
    assert_eq!(field, "scenes.max_scenes");

    still_serving(&app).await;
    let two = client()
        .get(app.url("/v1/scenes/two"))
        .send()
        .await
        .unwrap();
    assert_eq!(two.status(), StatusCode::OK);
}

/// Makes a FIFO at `path`; false if `mkfifo` is unavailable.
fn mkfifo(path: &Path) -> bool {
    std::process::Command::new("mkfifo")
        .arg(path)
        .status()
        .is_ok_and(|s| s.success())
}

#[tokio::test]
async fn special_files_never_block_or_exhaust_the_service() {
    let dir = bundled_dir();
    let root = dir.path().to_owned();
    // A FIFO named like a scene would block startup forever if opened.
    assert!(
        mkfifo(&root.join("x.json")),
        "mkfifo is needed for this test"
    );
    assert!(mkfifo(&root.join("meshes/fifo.obj")));
    assert!(mkfifo(&root.join("meshes/fifo.ply")));
    assert!(mkfifo(&root.join("fifo.exr")));
    assert!(mkfifo(&root.join("fifo.png")));
    // A twin of /dev/zero needs root; skip that case where mknod fails.
    let zero = std::process::Command::new("mknod")
        .arg(root.join("meshes/zero.obj"))
        .args(["c", "1", "5"])
        .status()
        .is_ok_and(|s| s.success());
    let app = start(dir, |_| {}).await;

    let mut cases = vec![
        (
            scene("fifo-obj", obj_shapes("meshes/fifo.obj", 1)),
            "shapes[0].filename",
        ),
        (
            {
                let mut doc = scene(
                    "fifo-exr",
                    json!([{"type": "rectangle", "material": "white"}]),
                );
                doc["environment"] = json!({"type": "envmap", "filename": "fifo.exr"});
                doc
            },
            "environment.filename",
        ),
    ];
    if zero {
        cases.push((
            scene("zero-obj", obj_shapes("meshes/zero.obj", 1)),
            "shapes[0].filename",
        ));
    } else {
        eprintln!("mknod failed (not root?): skipping the character-device case");
    }
    for (doc, expected) in cases {
        let (code, field, message) = expect_error(
            post_json(&app, &doc).await,
            StatusCode::UNPROCESSABLE_ENTITY,
        )
        .await;
        assert_eq!(code, "invalid_field");
        assert_eq!(field, expected, "{doc}");
        assert!(message.contains("not a regular file"), "{message}");
    }

    let ply = mitsuba(
        "<shape type=\"ply\"><string name=\"filename\" value=\"meshes/fifo.ply\"/></shape>",
    );
    let (_, field, message) = expect_error(
        // Lenient: the missing sensor is not the error; the mesh file is.
        post_xml(&app, "id=ply&lenient=true", &ply).await,
        StatusCode::UNPROCESSABLE_ENTITY,
    )
    .await;
    assert!(
        field.contains("<shape type=\"ply\">"),
        "{field} / {message}"
    );
    assert!(message.contains("not a regular file"), "{message}");

    let png = mitsuba(
        "<bsdf type=\"diffuse\" id=\"b\"><texture type=\"bitmap\" name=\"reflectance\">\
         <string name=\"filename\" value=\"fifo.png\"/></texture></bsdf>",
    );
    let (_, field, message) = expect_error(
        post_xml(&app, "id=png&lenient=true", &png).await,
        StatusCode::UNPROCESSABLE_ENTITY,
    )
    .await;
    assert!(field.contains("filename"), "{field}");
    assert!(message.contains("not a regular file"), "{message}");

    still_serving(&app).await;
}

/// Writes a `side`² 8-bit grey PNG of zeros, row by row (never the whole
/// image in memory).
fn write_grey_png(path: &Path, side: u32) {
    let file = std::io::BufWriter::new(std::fs::File::create(path).unwrap());
    let mut encoder = png::Encoder::new(file, side, side);
    encoder.set_color(png::ColorType::Grayscale);
    encoder.set_depth(png::BitDepth::Eight);
    encoder.set_compression(png::Compression::Fast);
    let mut writer = encoder.write_header().unwrap();
    let mut stream = writer.stream_writer().unwrap();
    let row = vec![0u8; side as usize];
    for _ in 0..side {
        std::io::Write::write_all(&mut stream, &row).unwrap();
    }
    stream.finish().unwrap();
}

#[tokio::test]
async fn huge_png_textures_are_refused_before_decoding() {
    let dir = bundled_dir();
    write_grey_png(&dir.path().join("huge.png"), 16384);
    let app = start(dir, |_| {}).await;
    let xml = mitsuba(
        "<bsdf type=\"diffuse\" id=\"b\"><texture type=\"bitmap\" name=\"reflectance\">\
         <string name=\"filename\" value=\"huge.png\"/></texture></bsdf>",
    );
    let (code, field, message) = expect_error(
        post_xml(&app, "id=huge&lenient=true", &xml).await,
        StatusCode::UNPROCESSABLE_ENTITY,
    )
    .await;
    assert_eq!(code, "invalid_field");
    assert!(field.contains("<texture type=\"bitmap\""), "{field}");
    assert!(message.contains("16384×16384"), "{message}");
    still_serving(&app).await;
}

#[tokio::test]
async fn posted_json_is_read_as_strictly_as_other_routes() {
    let app = start(bundled_dir(), |_| {}).await;
    let tiny = scene("dup", json!([{"type": "rectangle", "material": "white"}]));
    let text = tiny.to_string();

    // Duplicate keys, at the top (the id itself) and deeper down.
    let duplicate_name = text.replacen("\"name\":\"dup\"", "\"name\":\"dup\",\"name\":\"sky\"", 1);
    assert_ne!(duplicate_name, text);
    let (code, _, message) = expect_error(
        post(
            &app,
            "/v1/scenes",
            "application/json",
            duplicate_name.into_bytes(),
        )
        .await,
        StatusCode::UNPROCESSABLE_ENTITY,
    )
    .await;
    assert_eq!(code, "invalid_field");
    assert!(message.contains("duplicate field `name`"), "{message}");
    let duplicate_fov = text.replacen("\"fov\":40", "\"fov\":40,\"fov\":10", 1);
    assert_ne!(duplicate_fov, text);
    let (_, field, message) = expect_error(
        post(
            &app,
            "/v1/scenes",
            "application/json",
            duplicate_fov.into_bytes(),
        )
        .await,
        StatusCode::UNPROCESSABLE_ENTITY,
    )
    .await;
    assert!(field.starts_with("camera"), "{field}");
    assert!(message.contains("duplicate field `fov`"), "{message}");

    // `?id=` belongs to XML uploads; with JSON it would silently not apply.
    let (_, field, _) = expect_error(
        post(
            &app,
            "/v1/scenes?id=sky",
            "application/json",
            text.clone().into_bytes(),
        )
        .await,
        StatusCode::UNPROCESSABLE_ENTITY,
    )
    .await;
    assert_eq!(field, "id");

    let (code, _, message) = expect_error(
        post(&app, "/v1/scenes", "text/plain", text.into_bytes()).await,
        StatusCode::UNSUPPORTED_MEDIA_TYPE,
    )
    .await;
    assert_eq!(code, "unsupported_media_type");
    assert!(
        message.contains("application/json") && message.contains("application/xml"),
        "{message}"
    );

    // Nothing was replaced: `sky` is still the bundled one.
    let sky: Value = get_json(&app, "/v1/scenes/sky").await;
    assert_eq!(sky["source"], "file");
    still_serving(&app).await;
}
