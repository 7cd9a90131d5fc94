//! Small files that claim large payloads, against the real binary with its
//! memory measured: each upload of a few kilobytes is refused with a 4xx
//! naming the field, before the memory it claims is taken; the service
//! stays healthy, keeps what it held, and its peak memory stays far below
//! any of the claims. Before these held, a 100 KB EXR aborted the process
//! (480 GB allocation), a 244-byte PLY grew memory without bound, a 1.9 MB
//! serialized mesh took 3.7 GB, 2 kB of `<ref>` doubling held a worker
//! past its deadline at 2.9 GB, and a 631-byte JPEG cost 1.17 GB.

use reqwest::StatusCode;
use serde_json::{Value, json};

use crate::common::{TINY_SCENE, get_json_at, peak_rss, scene_ids_at, serve_with};
use bmc_irradiance::testing::{
    BOUNDARY, jpeg_claiming, ref_doubling_xml, scene_upload as upload, two_part_exr,
};

fn rectangle() -> Value {
    json!({"type": "rectangle", "material": "m"})
}

#[tokio::test]
async fn small_files_claiming_large_payloads_are_refused_in_bounded_memory() {
    let scenes = tempfile::tempdir().unwrap();
    std::fs::write(scenes.path().join("tiny.json"), TINY_SCENE).unwrap();
    let data = tempfile::tempdir().unwrap();
    // A scenes budget of 32 MiB: a 1024² emitter texture fits (12 MiB
    // kept, 15 MiB more while it is decoded), a second beside it does not.
    let budget = (32u64 << 20).to_string();
    let (service, addr) = serve_with(
        scenes.path(),
        data.path(),
        &[("BMC_SCENES__MAX_SCENE_BYTES", budget.as_str())],
    );
    // Only turns a hang into a failure; nothing here is timed.
    let client = reqwest::Client::builder()
        .timeout(std::time::Duration::from_secs(300))
        .build()
        .unwrap();
    let url = |path: &str| format!("http://{addr}{path}");
    let ascii_junk = "ply\nformat ascii 1.0\nelement junk 100000000000\nelement vertex 3\n\
        property float x\nproperty float y\nproperty float z\nelement face 1\n\
        property list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n";
    let glow = {
        let mut png = Vec::new();
        image::RgbImage::from_pixel(1024, 1024, image::Rgb([200, 150, 100]))
            .write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png)
            .unwrap();
        png
    };
    let glowing = |file: &str| {
        json!({"type": "rectangle", "material": "m",
               "emitter": {"type": "area", "radiance": {"type": "bitmap", "filename": file}}})
    };
    let exr = two_part_exr(200_000);
    let cases: Vec<(&str, Vec<u8>, StatusCode, &str, &str)> = vec![
        (
            "a 1×1 EXR part in front of a 200000² one, as an environment map",
            upload(
                rectangle(),
                json!({"environment": {"type": "envmap", "filename": "sky.exr"}}),
                vec![("sky.exr", exr.clone())],
            ),
            StatusCode::UNPROCESSABLE_ENTITY,
            "environment.filename",
            "part 1 is 200000×200000",
        ),
        (
            "the same EXR as a texture",
            upload(
                rectangle(),
                json!({"materials": [{"id": "m", "type": "diffuse",
                       "reflectance": {"type": "bitmap", "filename": "t.exr"}}]}),
                vec![("t.exr", exr)],
            ),
            StatusCode::UNPROCESSABLE_ENTITY,
            "materials[0].reflectance.filename",
            "part 1 is 200000×200000",
        ),
        (
            "a PLY claiming 10¹¹ elements of another kind",
            upload(
                json!({"type": "ply", "filename": "junk.ply", "material": "m"}),
                json!({}),
                vec![("junk.ply", ascii_junk.as_bytes().to_vec())],
            ),
            StatusCode::UNPROCESSABLE_ENTITY,
            "shapes[0].filename",
            "claims 100000000000 entries",
        ),
        (
            "a serialized mesh of 30 million vertices and one triangle",
            upload(
                json!({"type": "serialized", "filename": "bomb.serialized", "material": "m"}),
                json!({}),
                vec![(
                    "bomb.serialized",
                    bmc_irradiance::testing::serialized_mesh(30_000_000, 1),
                )],
            ),
            StatusCode::UNPROCESSABLE_ENTITY,
            "shapes[0].filename",
            "30000000 vertices for 1 triangles",
        ),
        (
            "a serialized mesh of 6 million vertices, over the scenes budget",
            upload(
                json!({"type": "serialized", "filename": "big.serialized", "material": "m"}),
                json!({}),
                vec![(
                    "big.serialized",
                    bmc_irradiance::testing::serialized_mesh(6_000_000, 2_000_000),
                )],
            ),
            StatusCode::INSUFFICIENT_STORAGE,
            "scenes.max_scene_bytes",
            "shapes[0].filename",
        ),
        (
            "two emitter textures that do not fit the scenes budget together",
            upload(
                glowing("a.png"),
                json!({"shapes": [glowing("a.png"), glowing("b.png")]}),
                vec![("a.png", glow.clone()), ("b.png", glow)],
            ),
            StatusCode::INSUFFICIENT_STORAGE,
            "scenes.max_scene_bytes",
            "shapes[1].emitter.radiance.filename",
        ),
        (
            "a 600-byte JPEG claiming 16384×2048 texels, as an environment map",
            upload(
                rectangle(),
                json!({"environment": {"type": "envmap", "filename": "sky.jpg"}}),
                vec![("sky.jpg", jpeg_claiming(16384, 2048))],
            ),
            StatusCode::UNPROCESSABLE_ENTITY,
            "environment.filename",
            "a truncated or crafted file",
        ),
        (
            "an index of refraction of 1e300 over 1e-300",
            upload(
                rectangle(),
                json!({"materials": [{"id": "m", "type": "dielectric",
                                      "int_ior": 1e300, "ext_ior": 1e-300}]}),
                vec![],
            ),
            StatusCode::UNPROCESSABLE_ENTITY,
            "materials[0].int_ior",
            "not an index of refraction",
        ),
    ];
    for (name, body, status, field, says) in cases {
        let response = client
            .post(url("/v1/scenes"))
            .header(
                "content-type",
                format!("multipart/form-data; boundary={BOUNDARY}"),
            )
            .body(body)
            .send()
            .await
            .unwrap_or_else(|e| panic!("{name}: {e}"));
        assert_eq!(response.status(), status, "{name}");
        let error: Value = response.json().await.unwrap();
        assert_eq!(error["error"]["field"], field, "{name}: {error}");
        let message = error["error"]["message"].as_str().unwrap();
        assert!(message.contains(says), "{name}: {message}");
        // Messages name the files as the scene does, not where the server
        // keeps them.
        assert!(!message.contains("bmc-upload-"), "{name}: {message}");
    }
    // `<ref>` doubling, 30 levels in 2 kB.
    let xml = ref_doubling_xml(30);
    assert!(xml.len() < 4096);
    let response = client
        .post(url("/v1/scenes?id=doubling"))
        .header("content-type", "application/xml")
        .body(xml)
        .send()
        .await
        .unwrap();
    assert_eq!(response.status(), StatusCode::UNPROCESSABLE_ENTITY);
    let error: Value = response.json().await.unwrap();
    let message = error["error"]["message"].as_str().unwrap();
    assert!(message.contains("MAX_MATERIAL_NODES"), "{message}");
    assert!(message.starts_with("body:"), "{message}");

    let peak = peak_rss(service.0.id());
    eprintln!("peak RSS {} MiB", peak >> 20);
    // Any one of the claims would take it past this.
    assert!(peak < 512 << 20, "peak RSS {} MiB", peak >> 20);
    let health = get_json_at(&client, &url("/health")).await;
    assert_eq!(health["status"], "ok", "{health}");
    assert_eq!(scene_ids_at(&client, &url("")).await, ["tiny"]);
}

/// Uploads are written under the data directory's `uploads/`, and what a
/// stopped service left there (an upload cut off by SIGTERM, or a scene
/// load still running when the process ended, whose folder was never
/// dropped) is cleared at the next start.
#[test]
fn uploads_a_stopped_service_left_are_cleared_at_its_next_start() {
    use std::io::Write;
    let scenes = tempfile::tempdir().unwrap();
    std::fs::write(scenes.path().join("tiny.json"), TINY_SCENE).unwrap();
    let data = tempfile::tempdir().unwrap();
    let uploads = data.path().join("uploads");
    // What an earlier process left.
    std::fs::create_dir_all(uploads.join("bmc-upload-left")).unwrap();
    std::fs::write(uploads.join("bmc-upload-left/mesh.obj"), "#").unwrap();
    let grace = [("BMC_SERVER__SHUTDOWN_GRACE_SECS", "1")];
    let (mut service, addr) = serve_with(scenes.path(), data.path(), &grace);
    // The scene part and the start of an asset, then nothing more.
    let body = upload(
        rectangle(),
        json!({}),
        vec![("mesh.obj", vec![b'#'; 1 << 16])],
    );
    let sent = body.len() - 1024;
    let mut stream = std::net::TcpStream::connect(&addr).unwrap();
    write!(
        stream,
        "POST /v1/scenes HTTP/1.1\r\nHost: {addr}\r\n\
         Content-Type: multipart/form-data; boundary={BOUNDARY}\r\nContent-Length: {}\r\n\r\n",
        body.len()
    )
    .unwrap();
    stream.write_all(&body[..sent]).unwrap();
    stream.flush().unwrap();
    // The start cleared what was left; this upload's asset is being written
    // once a file appears there again.
    let holds_a_file = |dir: &std::path::Path| walk(dir).iter().any(|p| p.is_file());
    let deadline = std::time::Instant::now() + std::time::Duration::from_secs(60);
    while !holds_a_file(&uploads) {
        assert!(
            std::time::Instant::now() < deadline,
            "the upload never reached uploads/"
        );
        std::thread::sleep(std::time::Duration::from_millis(20));
    }
    assert!(!uploads.join("bmc-upload-left").exists());
    // SAFETY: a signal to a child process this test started.
    unsafe { libc::kill(service.0.id() as i32, libc::SIGTERM) };
    let exited = service.0.wait().unwrap();
    assert!(exited.success(), "{exited}");
    drop(stream);
    let (_again, _) = serve_with(scenes.path(), data.path(), &grace);
    assert!(walk(&uploads).is_empty(), "{:?}", walk(&uploads));
}

/// Everything under `dir` (nothing if it does not exist).
fn walk(dir: &std::path::Path) -> Vec<std::path::PathBuf> {
    let mut out = Vec::new();
    for entry in std::fs::read_dir(dir).into_iter().flatten().flatten() {
        let path = entry.path();
        if path.is_dir() {
            out.extend(walk(&path));
        }
        out.push(path);
    }
    out
}
