//! Reproducible tiles survive a restart through `cache.data_dir/tiles.log`:
//! the second service renders nothing again, gives the same bytes and the
//! same records (no loss, no duplicates), and a log cut at an arbitrary byte
//! loads without a crash, keeping what was complete before the cut.

use std::path::Path;
use std::sync::Arc;

use crate::common::{TestApp, copy_dir, spawn_app_in};
use serde_json::{Value, json};

/// The Cornell box with a 64×48 camera: four 32-pixel tiles (the bottom
/// row 16 pixels high), all shaded by the records of the image's one
/// record block (`integrator::cached::tiles`): one records entry, each
/// tile's passes entries of their own.
fn scenes_dir() -> tempfile::TempDir {
    let dir = tempfile::tempdir().unwrap();
    let mut doc: Value =
        serde_json::from_str(include_str!("../../scenes/cornell-box.json")).unwrap();
    doc["camera"]["width"] = json!(64);
    doc["camera"]["height"] = json!(48);
    std::fs::write(dir.path().join("box.json"), doc.to_string()).unwrap();
    dir
}

async fn spawn(data: &Path) -> TestApp {
    let data = data.to_owned();
    spawn_app_in(scenes_dir(), move |config| config.cache.data_dir = data).await
}

const TILES: [(u32, u32); 4] = [(0, 0), (1, 0), (0, 1), (1, 1)];

/// Every tile's PNG, records (JSON) and the rays all of it took.
async fn render_all(app: &TestApp) -> (Vec<Vec<u8>>, Vec<Value>, u64) {
    let (mut images, mut records, mut rays) = (vec![], vec![], 0);
    for (tx, ty) in TILES {
        for (aov, sink) in [("radiance", 0), ("records", 1)] {
            let ext = if sink == 0 { "png" } else { "json" };
            let url =
                format!("/v1/scenes/box/tiles/{tx}/{ty}.{ext}?size=32&preset=draft&aov={aov}");
            let response = app.get(&url).await;
            assert_eq!(response.status(), 200, "{url}");
            rays += response.headers()["x-rays"]
                .to_str()
                .unwrap()
                .parse::<u64>()
                .unwrap();
            let bytes = response.bytes().await.unwrap().to_vec();
            if sink == 0 {
                images.push(bytes);
            } else {
                records.push(serde_json::from_slice(&bytes).unwrap());
            }
        }
    }
    (images, records, rays)
}

/// Waits until the stopped service has released the log's lock.
async fn released(data: &Path) {
    let log = data.join("tiles.log");
    for _ in 0..200 {
        let file = std::fs::OpenOptions::new()
            .read(true)
            .write(true)
            .open(&log)
            .unwrap();
        if file.try_lock().is_ok() {
            return;
        }
        tokio::time::sleep(std::time::Duration::from_millis(50)).await;
    }
    panic!("the stopped service still holds {}", log.display());
}

#[tokio::test]
async fn tiles_survive_a_restart_and_a_torn_log() {
    let data = tempfile::tempdir().unwrap();
    let first = spawn(data.path()).await;
    let (images, records, rays) = render_all(&first).await;
    assert!(rays > 0);
    let stored = first.health().await["tiles"].clone();
    assert_eq!(stored["tiles"], json!(1), "{stored}");
    assert!(stored["log_bytes"].as_u64().unwrap() > 0);
    drop(first);
    released(data.path()).await;

    // Restarted: everything from the log, nothing traced, the same bytes
    // and the same records.
    let second = spawn(data.path()).await;
    let loaded = second.health().await["tiles"].clone();
    assert_eq!(loaded["dropped_bytes"], json!(0), "{loaded}");
    assert_eq!(loaded["tiles"], json!(1), "{loaded}");
    let (again, records_again, rays_again) = render_all(&second).await;
    assert_eq!(rays_again, 0);
    assert_eq!(again, images);
    assert_eq!(records_again, records);
    drop(second);
    released(data.path()).await;

    // Cut the log at an arbitrary byte inside it (a torn write): the
    // service starts, reports the cut, keeps the entries before it and
    // recomputes the rest, bit-identically.
    let log = data.path().join("tiles.log");
    let bytes = std::fs::read(&log).unwrap();
    let cut = bytes.len() * 5 / 7 + 3;
    std::fs::write(&log, &bytes[..cut]).unwrap();
    let third = spawn(data.path()).await;
    let report = third.health().await;
    assert_eq!(report["status"], "ok");
    let tiles = &report["tiles"];
    let kept = tiles["loaded_entries"].as_u64().unwrap();
    assert!(
        kept > 0 && kept < loaded["loaded_entries"].as_u64().unwrap(),
        "{tiles}"
    );
    assert!(tiles["dropped_bytes"].as_u64().unwrap() > 0, "{tiles}");
    let (after_cut, records_after_cut, rays_after_cut) = render_all(&third).await;
    assert!(
        rays_after_cut > 0 && rays_after_cut < rays,
        "{rays_after_cut} of {rays}"
    );
    assert_eq!(after_cut, images);
    assert_eq!(records_after_cut, records);
}

/// Scenes posted at runtime, with or without assets, come back after a
/// restart with the same content digest (a packed folder's too); a deleted
/// one does not.
#[tokio::test]
async fn posted_scenes_survive_a_restart() {
    let data = tempfile::tempdir().unwrap();
    let first = spawn(data.path()).await;
    let mut doc: Value =
        serde_json::from_str(include_str!("../../scenes/cornell-box.json")).unwrap();
    doc["name"] = json!("posted-box");
    let response = first.post_json("/v1/scenes", &doc).await;
    assert_eq!(response.status(), 201);
    let posted: Value = response.json().await.unwrap();
    // With an asset: the bundled sky map under a scene of its own.
    let boundary = "persist-boundary";
    let sky = std::fs::read(Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/sky.exr")).unwrap();
    let scene = json!({
        "name": "posted-sky",
        "materials": [{"id": "m", "type": "diffuse", "reflectance": [0.5, 0.5, 0.5]}],
        "shapes": [{"type": "sphere", "center": [0, 0, 0], "radius": 1, "material": "m"}],
        "environment": {"type": "envmap", "filename": "maps/sky.exr"},
        "camera": {"type": "perspective", "fov": 40, "width": 8, "height": 8,
                   "origin": [0, 0, 4], "target": [0, 0, 0], "up": [0, 1, 0]}
    })
    .to_string();
    let mut body = format!(
        "--{boundary}\r\nContent-Disposition: form-data; name=\"scene\"; filename=\"s.json\"\r\n\r\n{scene}\r\n\
         --{boundary}\r\nContent-Disposition: form-data; name=\"asset\"; filename=\"maps/sky.exr\"\r\n\r\n"
    )
    .into_bytes();
    body.extend(&sky);
    body.extend(format!("\r\n--{boundary}--\r\n").bytes());
    let response = first
        .client
        .post(first.url("/v1/scenes"))
        .header(
            "content-type",
            format!("multipart/form-data; boundary={boundary}"),
        )
        .body(body)
        .send()
        .await
        .unwrap();
    assert_eq!(response.status(), 201, "{}", response.text().await.unwrap());
    let with_asset: Value = first
        .get("/v1/scenes/posted-sky")
        .await
        .json()
        .await
        .unwrap();
    // Mitsuba XML with a `$res` parameter set by the query.
    let xml = r#"<scene version="3.0.0"><default name="res" value="8"/>
        <sensor type="perspective"><film type="hdrfilm">
          <integer name="width" value="$res"/><integer name="height" value="$res"/>
        </film></sensor><shape type="rectangle"/></scene>"#;
    let response = first
        .client
        .post(first.url("/v1/scenes?id=posted-xml&param.res=12"))
        .header("content-type", "application/xml")
        .body(xml)
        .send()
        .await
        .unwrap();
    assert_eq!(response.status(), 201);
    let with_parameter: Value = response.json().await.unwrap();
    assert_eq!(with_parameter["resolution"], json!([12, 12]));
    // A packed scene folder: the tutorials' Cornell box, zipped by Info-ZIP.
    let work = tempfile::tempdir().unwrap();
    let tutorials = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/mitsuba-tutorials");
    copy_dir(&tutorials, &work.path().join("cbox"));
    let zipped = std::process::Command::new("zip")
        .args(["-q", "-r", "cbox.zip", "cbox"])
        .current_dir(work.path())
        .status()
        .unwrap();
    assert!(zipped.success());
    let response = first
        .client
        .post(first.url("/v1/scenes"))
        .header("content-type", "application/zip")
        .body(std::fs::read(work.path().join("cbox.zip")).unwrap())
        .send()
        .await
        .unwrap();
    assert_eq!(response.status(), 201);
    let packed: Value = response.json().await.unwrap();
    drop(first);
    released(data.path()).await;

    let second = spawn(data.path()).await;
    for (id, digest) in [
        ("posted-box", &posted["digest"]),
        ("posted-sky", &with_asset["digest"]),
        ("posted-xml", &with_parameter["digest"]),
        ("cbox", &packed["digest"]),
    ] {
        let summary: Value = second
            .get(&format!("/v1/scenes/{id}"))
            .await
            .json()
            .await
            .unwrap();
        assert_eq!(&summary["digest"], digest, "{id}: {summary}");
        assert_eq!(summary["source"], "uploaded");
        if id == "posted-xml" {
            assert_eq!(
                summary["resolution"],
                json!([12, 12]),
                "the parameter is kept"
            );
        }
    }
    let deleted = second.delete("/v1/scenes/posted-box").await;
    assert_eq!(deleted.status(), 204);
    drop(second);
    released(data.path()).await;

    let third = spawn(data.path()).await;
    assert_eq!(third.get("/v1/scenes/posted-box").await.status(), 404);
    assert_eq!(third.get("/v1/scenes/posted-sky").await.status(), 200);
}

/// A scene's records exported from one service and imported into another
/// (memory only, nothing shared): the second renders the same bytes
/// without placing a record. Imports that are not exports of this scene's
/// content are refused whole, naming the entry.
#[tokio::test]
async fn records_export_from_one_service_and_import_into_another() {
    let first = spawn_app_in(scenes_dir(), |_| {}).await;
    let (images, _, rays) = render_all(&first).await;
    assert!(rays > 0);
    let export = first.get("/v1/scenes/box/records").await;
    assert_eq!(export.status(), 200);
    assert_eq!(
        export.headers()["content-type"],
        "application/vnd.bmc-records"
    );
    let export = export.bytes().await.unwrap().to_vec();
    assert!(export.starts_with(b"BMCLOG01"));

    let second = spawn_app_in(scenes_dir(), |_| {}).await;
    let imported: Value = post_records(&second, "box", export.clone())
        .await
        .unwrap()
        .json()
        .await
        .unwrap();
    assert_eq!(imported["imported"], 1, "{imported}");
    assert!(imported["records"].as_u64().unwrap() > 0);
    // Records of every tile come from the import: the passes cost camera
    // rays only, and the images are the first service's.
    for (i, (tx, ty)) in TILES.into_iter().enumerate() {
        let url = format!("/v1/scenes/box/tiles/{tx}/{ty}.png?size=32&preset=draft");
        let response = second.get(&url).await;
        assert_eq!(response.headers()["x-records-created"], "0", "{url}");
        assert_eq!(response.bytes().await.unwrap(), images[i], "{url}");
    }
    let again: Value = post_records(&second, "box", export.clone())
        .await
        .unwrap()
        .json()
        .await
        .unwrap();
    assert_eq!(
        (again["imported"].as_u64(), again["already_held"].as_u64()),
        (Some(0), Some(1))
    );

    // Another scene's content, a cut export, and something else entirely.
    let mut doc: Value =
        serde_json::from_str(include_str!("../../scenes/cornell-box.json")).unwrap();
    doc["name"] = json!("other");
    let posted = second.post_json("/v1/scenes", &doc).await;
    assert_eq!(posted.status(), 201);
    for (id, body, field) in [
        ("other", export.clone(), "entries[0]"),
        // The export's one entry, cut.
        ("box", export[..export.len() - 5].to_vec(), "entries[0]"),
        ("box", b"not an export".to_vec(), "body"),
    ] {
        let response = post_records(&second, id, body).await.unwrap();
        assert_eq!(response.status(), 422);
        let (_, named) = crate::common::error_of(response).await;
        assert_eq!(named.as_deref(), Some(field));
    }
    let response = post_records(&second, "missing", export).await.unwrap();
    assert_eq!(response.status(), 404);
}

/// An export with its first entry's records changed by `forge` and framed
/// again with a valid checksum (the log format of `cache::log`: magic, then
/// `length u32 | checksum 8 | kind 1 | key 32 | payload`, the checksum the
/// first 8 bytes of BLAKE3 over kind, key and payload; a records payload is
/// the scene digest, then 31 little-endian f64s per record).
fn forged(export: &[u8], forge: impl FnOnce(&mut Vec<[f64; 31]>)) -> Vec<u8> {
    let length = u32::from_le_bytes(export[8..12].try_into().unwrap()) as usize;
    let body = &export[20..20 + length];
    // Kind, key, scene digest and camera depth, then the records.
    let (head, payload) = body.split_at(33 + 32 + 4);
    let mut records: Vec<[f64; 31]> = payload
        .chunks_exact(31 * 8)
        .map(|r| {
            std::array::from_fn(|i| f64::from_le_bytes(r[8 * i..8 * i + 8].try_into().unwrap()))
        })
        .collect();
    forge(&mut records);
    let mut body = head.to_vec();
    body.extend(records.iter().flatten().flat_map(|v| v.to_le_bytes()));
    let mut out = b"BMCLOG01".to_vec();
    out.extend(framed(&body));
    out.extend(&export[20 + length..]);
    out
}

/// One log entry as `cache::log` frames it: `length u32 | checksum 8 |
/// body`, the body being kind, key and payload, the checksum the first 8
/// bytes of BLAKE3 over it.
fn framed(body: &[u8]) -> Vec<u8> {
    let mut out = (body.len() as u32).to_le_bytes().to_vec();
    out.extend(&blake3::hash(body).as_bytes()[..8]);
    out.extend(body);
    out
}

/// A records export is streamed entry by entry: a client that stops
/// reading has it cut off once it has paused for
/// `server.header_read_timeout_secs`, instead of the service holding the
/// whole export for it.
#[tokio::test]
async fn an_export_nobody_reads_is_cut_off() {
    use tokio::io::{AsyncReadExt, AsyncWriteExt};
    // A lone rectangle under a sky: no light reaches it by a reflection, so
    // records of zero indirect irradiance are what the scene gives, and an
    // import of many of them passes the check against fresh estimates.
    let dir = scenes_dir();
    std::fs::write(dir.path().join("tiny.json"), crate::common::TINY_SCENE).unwrap();
    let app = spawn_app_in(dir, |c| c.server.header_read_timeout_secs = 2).await;
    let summary: Value = app.get("/v1/scenes/tiny").await.json().await.unwrap();
    let hex = summary["digest"].as_str().unwrap();
    let digest: Vec<u8> = (0..32)
        .map(|i| u8::from_str_radix(&hex[2 * i..2 * i + 2], 16).unwrap())
        .collect();
    // 40 tiles of 4000 records (about 40 MB): far more than a connection buffers.
    let mut image = b"BMCLOG01".to_vec();
    for tile in 0..40u32 {
        let mut body = vec![4u8];
        body.extend(blake3::hash(&tile.to_le_bytes()).as_bytes());
        body.extend(&digest);
        body.extend(8u32.to_le_bytes());
        for i in 0..4000 {
            let (x, y) = (f64::from(i % 100) / 100.0, f64::from(i / 100) / 40.0);
            let mut record = [0.0; 31];
            record[..6].copy_from_slice(&[1.8 * x - 0.9, 1.8 * y - 0.9, 0.0, 0.0, 0.0, 1.0]);
            record[12] = 0.1;
            body.extend(record.iter().flat_map(|v| v.to_le_bytes()));
        }
        image.extend(framed(&body));
    }
    let imported = app
        .client
        .post(app.url("/v1/scenes/tiny/records"))
        .body(image.clone())
        .send()
        .await
        .unwrap();
    assert_eq!(imported.status(), 200);
    let imported: Value = imported.json().await.unwrap();
    assert_eq!(imported["imported"], 40, "{imported}");
    assert_eq!(
        (
            imported["checked"].as_u64(),
            imported["disagreeing"].as_u64()
        ),
        (Some(64), Some(0)),
        "{imported}"
    );

    let addr = app.base.trim_start_matches("http://").to_owned();
    let mut stalled = tokio::net::TcpStream::connect(&addr).await.unwrap();
    stalled
        .write_all(b"GET /v1/scenes/tiny/records HTTP/1.1\r\nHost: x\r\n\r\n")
        .await
        .unwrap();
    tokio::time::sleep(std::time::Duration::from_secs(6)).await;
    let mut received = 0;
    let mut buffer = vec![0; 1 << 16];
    loop {
        let read = tokio::time::timeout(
            std::time::Duration::from_secs(10),
            stalled.read(&mut buffer),
        )
        .await
        .expect("the stalled export was not cut off");
        match read {
            Ok(0) | Err(_) => break,
            Ok(n) => received += n,
        }
    }
    assert!(received > 0);
    assert!(
        received < image.len(),
        "{received} bytes of a {} byte export arrived after the client stalled",
        image.len()
    );
    assert_eq!(app.get("/health").await.status(), 200);
}

/// The tiles a first service rendered ([`render_all`]), its records'
/// export, and a second service on the same scenes holding nothing.
async fn exported_and_another() -> (Vec<Vec<u8>>, Vec<u8>, TestApp) {
    let first = spawn_app_in(scenes_dir(), |_| {}).await;
    let (images, _, _) = render_all(&first).await;
    let export = first
        .get("/v1/scenes/box/records")
        .await
        .bytes()
        .await
        .unwrap()
        .to_vec();
    (images, export, spawn_app_in(scenes_dir(), |_| {}).await)
}

/// `POST /v1/scenes/{id}/records` of `body` to `app`.
fn post_records(
    app: &TestApp,
    id: &str,
    body: Vec<u8>,
) -> impl std::future::Future<Output = reqwest::Result<reqwest::Response>> {
    app.client
        .post(app.url(&format!("/v1/scenes/{id}/records")))
        .header("content-type", "application/vnd.bmc-records")
        .body(body)
        .send()
}

/// Records that no computation could produce are refused whole, naming the
/// entry and record, although their checksums are valid; nothing of them is
/// kept, and the tiles stay finite.
#[tokio::test]
async fn poisoned_records_imports_are_refused() {
    let (images, export, second) = exported_and_another().await;
    let post = |body: Vec<u8>| post_records(&second, "box", body);
    // Field offsets within a record: position 0, irradiance 6, variance 9, radius 12.
    let cases: Vec<(&str, Vec<u8>, &str)> = vec![
        (
            "huge",
            forged(&export, |r| r[0][6] = 1e300),
            "entries[0].records[0]",
        ),
        (
            "negative",
            forged(&export, |r| r[1][7] = -1e4),
            "entries[0].records[1]",
        ),
        (
            "not a number",
            forged(&export, |r| r[0][8] = f64::NAN),
            "entries[0].records[0]",
        ),
        (
            "negative variance",
            forged(&export, |r| r[0][9] = -1.0),
            "entries[0].records[0]",
        ),
        (
            "huge radius",
            forged(&export, |r| r[0][12] = 1e6),
            "entries[0].records[0]",
        ),
        (
            "outside the scene",
            forged(&export, |r| r[0][0] = 50.0),
            "entries[0].records[0]",
        ),
        (
            "duplicated",
            forged(&export, |r| {
                let copy = r[0];
                r.extend(std::iter::repeat_n(copy, 3));
            }),
            "entries[0].records[",
        ),
    ];
    for (what, body, field) in cases {
        let response = post(body).await.unwrap();
        assert_eq!(response.status(), 422, "{what}");
        let (code, named) = crate::common::error_of(response).await;
        assert_eq!(code, "invalid_field", "{what}");
        assert!(
            named.as_deref().unwrap_or("").starts_with(field),
            "{what}: {named:?}"
        );
    }
    let health: Value = second.get("/health").await.json().await.unwrap();
    assert_eq!(health["tiles"]["tiles"], 0, "{health}");
    // The genuine export still imports, and gives the first service's bytes.
    let imported: Value = post(export).await.unwrap().json().await.unwrap();
    assert_eq!(imported["imported"], 1, "{imported}");
    let url = "/v1/scenes/box/tiles/0/0.png?size=32&preset=draft";
    assert_eq!(second.get(url).await.bytes().await.unwrap(), images[0]);
}

/// Every record of an export scaled by 1,000, its variance by 10⁶ and its
/// gradients with it: each record is one computed records could be (finite,
/// under `MAX_IRRADIANCE`, gradients within their clamp), framed with valid
/// checksums, and tiles shaded from them would be hundreds of times too
/// bright under the genuine ETags. The import is refused naming a record,
/// by its disagreement with fresh estimates of the scene (docs/math.md
/// §9.8); nothing of it is kept, what the service held is, and the genuine
/// export still imports and serves the first service's bytes.
#[tokio::test]
async fn records_scaled_by_a_thousand_are_refused() {
    let (images, export, second) = exported_and_another().await;
    // Held before the import: the first tile of another seed, computed
    // here (its own record block, not the export's).
    let url =
        |(tx, ty): (u32, u32)| format!("/v1/scenes/box/tiles/{tx}/{ty}.png?size=32&preset=draft");
    let other_seed = format!("{}&seed=5", url(TILES[0]));
    let held = second.get(&other_seed).await;
    assert_eq!(held.status(), 200);
    let held = held.bytes().await.unwrap();
    let post = |body: Vec<u8>| post_records(&second, "box", body);
    let response = post(scaled(&export, 1000.0)).await.unwrap();
    assert_eq!(response.status(), 422);
    let (body, _) = crate::common::error_json(response).await;
    let error = &body["error"];
    assert_eq!(error["code"], "invalid_field", "{body}");
    let field = error["field"].as_str().unwrap();
    assert!(
        field.starts_with("entries[") && field.contains("].records["),
        "{body}"
    );
    assert!(
        error["message"]
            .as_str()
            .unwrap()
            .contains("fresh estimates"),
        "{body}"
    );
    // Healthy, the tile it held kept, nothing of the import added: the
    // tiles are computed, as the first service computed them (the first
    // places the block's records).
    let health: Value = second.get("/health").await.json().await.unwrap();
    assert_eq!(health["status"], "ok", "{health}");
    assert_eq!(health["tiles"]["tiles"], 1, "{health}");
    assert_eq!(second.get(&other_seed).await.bytes().await.unwrap(), held);
    for (i, tile) in TILES.into_iter().enumerate() {
        let response = second.get(&url(tile)).await;
        let created = response.headers()["x-records-created"]
            .to_str()
            .unwrap()
            .to_owned();
        assert_eq!(
            created == "0",
            i != 0,
            "{tile:?}: {created} records created"
        );
        assert_eq!(response.bytes().await.unwrap(), images[i], "{tile:?}");
    }
    // The genuine export (from another run, into a service that holds
    // records of another seed) is checked and added.
    let third = spawn_app_in(scenes_dir(), |_| {}).await;
    assert_eq!(third.get(&other_seed).await.status(), 200);
    let imported = post_records(&third, "box", export).await.unwrap();
    assert_eq!(imported.status(), 200);
    let imported: Value = imported.json().await.unwrap();
    assert_eq!(
        (
            imported["imported"].as_u64(),
            imported["already_held"].as_u64()
        ),
        (Some(1), Some(0)),
        "{imported}"
    );
    assert!(imported["checked"].as_u64().unwrap() > 0, "{imported}");
    for (i, tile) in TILES.into_iter().enumerate() {
        let response = third.get(&url(tile)).await;
        assert_eq!(response.headers()["x-records-created"], "0", "{tile:?}");
        assert_eq!(response.bytes().await.unwrap(), images[i], "{tile:?}");
    }
}

/// An export with every record of every entry scaled by `factor` (its
/// irradiance, its variance by the square, both gradients), each entry
/// framed again with a valid checksum (the format of [`forged`]).
fn scaled(export: &[u8], factor: f64) -> Vec<u8> {
    let mut out = b"BMCLOG01".to_vec();
    let mut at = 8;
    while at < export.len() {
        let length = u32::from_le_bytes(export[at..at + 4].try_into().unwrap()) as usize;
        let body = &export[at + 12..at + 12 + length];
        let (head, payload) = body.split_at(33 + 32 + 4);
        let mut body = head.to_vec();
        for record in payload.chunks_exact(31 * 8) {
            for (i, v) in record.chunks_exact(8).enumerate() {
                let v = f64::from_le_bytes(v.try_into().unwrap());
                // Position and normal 0..6, irradiance 6..9, variance 9..12,
                // radius 12, gradients 13..31.
                let v = match i {
                    6..=8 | 13..=30 => v * factor,
                    9..=11 => v * factor * factor,
                    _ => v,
                };
                body.extend(v.to_le_bytes());
            }
        }
        out.extend(framed(&body));
        at += 12 + length;
    }
    out
}

/// A tmpfs of `bytes` mounted on a fresh directory, unmounted on drop: a
/// data directory that can be filled to ENOSPC.
struct SmallDisk {
    dir: Option<tempfile::TempDir>,
    at: Option<std::path::PathBuf>,
}

fn mount_tmpfs(at: &Path, bytes: u64) {
    let status = std::process::Command::new("mount")
        .args(["-t", "tmpfs", "-o", &format!("size={bytes}"), "tmpfs"])
        .arg(at)
        .status()
        .expect("mount must be installed");
    assert!(
        status.success(),
        "cannot mount a tmpfs (the tests run as root, as CI does)"
    );
}

impl SmallDisk {
    fn mount(bytes: u64) -> SmallDisk {
        let dir = tempfile::tempdir().unwrap();
        mount_tmpfs(dir.path(), bytes);
        SmallDisk {
            dir: Some(dir),
            at: None,
        }
    }

    /// A tmpfs over the existing folder `at`, unmounted on drop.
    fn mount_at(at: &Path, bytes: u64) -> SmallDisk {
        mount_tmpfs(at, bytes);
        SmallDisk {
            dir: None,
            at: Some(at.to_owned()),
        }
    }

    fn path(&self) -> &Path {
        self.dir
            .as_ref()
            .map_or_else(|| self.at.as_deref().unwrap(), |d| d.path())
    }

    /// Fills the disk to its last byte with a file `filler`.
    fn fill(&self) {
        use std::io::Write;
        let mut filler = std::fs::File::create(self.path().join("filler")).unwrap();
        let block = vec![0xAB; 4096];
        while filler.write_all(&block).is_ok() {}
        while filler.write_all(&block[..1]).is_ok() {}
        let _ = filler.sync_all();
    }

    fn free(&self) {
        std::fs::remove_file(self.path().join("filler")).unwrap();
    }
}

impl Drop for SmallDisk {
    fn drop(&mut self) {
        let _ = std::process::Command::new("umount")
            .arg("-l")
            .arg(self.path())
            .status();
    }
}

/// The data directory on a small disk filled to ENOSPC and freed again, and
/// a deletion whose copy is busy: tiles are still served while the disk is full (their
/// parts are not kept), a scene change that cannot be kept is refused with
/// 507 or 500 and not made, and after a restart every acknowledged change
/// is there and every tile part that was kept loads intact.
#[tokio::test]
async fn a_full_or_read_only_data_directory_loses_nothing_acknowledged() {
    if unsafe { libc::geteuid() } != 0 {
        eprintln!("skipped: mounting a tmpfs needs root (CI runs as root)");
        return;
    }
    let disk = SmallDisk::mount(4 << 20);
    let data = disk.path().to_owned();
    let app = spawn(&data).await;
    let mut doc: Value =
        serde_json::from_str(include_str!("../../scenes/cornell-box.json")).unwrap();
    doc["name"] = json!("posted");
    doc["camera"]["width"] = json!(32);
    doc["camera"]["height"] = json!(32);
    let posted = app.post_json("/v1/scenes", &doc).await;
    assert_eq!(posted.status(), 201);
    let digest: Value = posted.json().await.unwrap();
    let digest = digest["digest"].clone();
    let tile = |i: u32| {
        format!(
            "/v1/scenes/box/tiles/{}/{}.png?size=32&preset=draft",
            i % 2,
            i / 2
        )
    };
    let before = app.get(&tile(0)).await.bytes().await.unwrap();

    // Full: tiles are still served; a replacement and a new scene are refused.
    disk.fill();
    let during = app.get(&tile(1)).await;
    assert_eq!(during.status(), 200);
    let during = during.bytes().await.unwrap();
    let mut changed = doc.clone();
    changed["camera"]["width"] = json!(16);
    for body in [changed.clone(), {
        let mut other = doc.clone();
        other["name"] = json!("other");
        other
    }] {
        let refused = app.post_json("/v1/scenes?replace=true", &body).await;
        assert_eq!(refused.status(), 507, "{body}");
        let (code, field) = crate::common::error_of(refused).await;
        assert_eq!(
            (code.as_str(), field.as_deref()),
            ("insufficient_storage", Some("cache.data_dir"))
        );
    }
    let kept: Value = app.get("/v1/scenes/posted").await.json().await.unwrap();
    assert_eq!(kept["digest"], digest);
    assert_eq!(app.get("/v1/scenes/other").await.status(), 404);

    // Freed: appends go on after the failed ones.
    disk.free();
    let after = app.get(&tile(2)).await.bytes().await.unwrap();

    // A deletion that cannot be kept (its copy is busy: a mount point here)
    // is refused and not made.
    let copy = data.join("scenes/posted");
    let saved = tempfile::tempdir().unwrap();
    copy_dir(&copy, saved.path());
    let busy = SmallDisk::mount_at(&copy, 1 << 20);
    copy_dir(saved.path(), &copy);
    let refused = app.delete("/v1/scenes/posted").await;
    assert_eq!(refused.status(), 500);
    assert_eq!(app.get("/v1/scenes/posted").await.status(), 200);
    drop(busy);
    drop(app);
    released(&data).await;

    // Restarted: the acknowledged scene, every kept part intact, the part
    // computed while the disk was full computed again with the same bytes.
    let again = spawn(&data).await;
    let report = again.health().await;
    assert_eq!(report["tiles"]["dropped_bytes"], 0, "{report}");
    let kept: Value = again.get("/v1/scenes/posted").await.json().await.unwrap();
    assert_eq!(kept["digest"], digest);
    assert_eq!(again.get("/v1/scenes/other").await.status(), 404);
    for (tx, bytes, stored) in [(0, &before, true), (1, &during, false), (2, &after, true)] {
        let response = again.get(&tile(tx)).await;
        assert_eq!(
            response.status(),
            200,
            "tile {tx}: {:?}",
            response.headers()
        );
        let rays: u64 = response.headers()["x-rays"]
            .to_str()
            .unwrap()
            .parse()
            .unwrap();
        assert_eq!(rays == 0, stored, "tile {tx}: {rays} rays");
        assert_eq!(&response.bytes().await.unwrap(), bytes, "tile {tx}");
    }
}

/// A bit flipped in the middle of the tile log costs the entry it hit, not
/// the entries after it.
#[tokio::test]
async fn a_flipped_bit_mid_log_costs_one_entry() {
    let data = tempfile::tempdir().unwrap();
    let first = spawn(data.path()).await;
    let (images, _, _) = render_all(&first).await;
    let entries = first.health().await["tiles"]["tiles"].as_u64().unwrap()
        + first.health().await["tiles"]["passes"].as_u64().unwrap();
    drop(first);
    released(data.path()).await;
    let log = data.path().join("tiles.log");
    let mut bytes = std::fs::read(&log).unwrap();
    // Inside the first entry's payload (magic 8, header 12, kind and key 33).
    bytes[8 + 12 + 33 + 100] ^= 0x04;
    std::fs::write(&log, &bytes).unwrap();
    let second = spawn(data.path()).await;
    let report = second.health().await["tiles"].clone();
    assert_eq!(
        report["loaded_entries"].as_u64().unwrap(),
        entries - 1,
        "{report}"
    );
    assert!(report["dropped_bytes"].as_u64().unwrap() > 0);
    let (again, _, _) = render_all(&second).await;
    assert_eq!(again, images);
}

fn mkfifo(path: &Path) {
    let name = std::ffi::CString::new(path.as_os_str().as_encoded_bytes()).unwrap();
    assert_eq!(
        unsafe { libc::mkfifo(name.as_ptr(), 0o600) },
        0,
        "mkfifo {}",
        path.display()
    );
}

/// Special files where the data directory keeps files never hang startup:
/// a FIFO as a kept scene's document is skipped (the service starts and
/// serves the rest), and a FIFO as the tile log is refused with an error.
#[tokio::test]
async fn special_files_in_the_data_directory_never_hang_startup() {
    let data = tempfile::tempdir().unwrap();
    let kept = data.path().join("scenes/fifo");
    std::fs::create_dir_all(&kept).unwrap();
    std::fs::write(
        kept.join("post.json"),
        r#"{"xml": false, "lenient": false, "with_assets": false}"#,
    )
    .unwrap();
    mkfifo(&kept.join("scene.json"));
    let started = tokio::time::timeout(std::time::Duration::from_secs(60), spawn(data.path()))
        .await
        .expect("startup hung on a FIFO");
    assert_eq!(started.get("/v1/scenes/fifo").await.status(), 404);
    assert_eq!(started.get("/v1/scenes/box").await.status(), 200);
    drop(started);
    released(data.path()).await;

    let other = tempfile::tempdir().unwrap();
    mkfifo(&other.path().join("tiles.log"));
    let dir = scenes_dir();
    let config = crate::common::test_config(&dir, |c| c.cache.data_dir = other.path().to_owned());
    let built = tokio::time::timeout(
        std::time::Duration::from_secs(60),
        bmc_irradiance::service::Application::build(config),
    )
    .await
    .expect("startup hung on a FIFO tile log");
    let Err(err) = built else {
        panic!("a FIFO tile log was opened");
    };
    assert!(format!("{err:#}").contains("not a regular file"), "{err:#}");
}

/// Killed with SIGKILL while tiles are being computed and appended: after a
/// restart every tile whose answer had been received is served from the log
/// (no ray traced) with the same bytes.
#[tokio::test]
async fn a_kill_during_appends_loses_nothing_acknowledged() {
    let data = tempfile::tempdir().unwrap();
    let scenes = scenes_dir();
    let (mut service, addr) = crate::common::serve_with(
        scenes.path(),
        data.path(),
        &[("BMC_LIMITS__MAX_QUEUE_WAIT_SECS", "3600")],
    );
    let client = reqwest::Client::new();
    let acknowledged = Arc::new(std::sync::Mutex::new(Vec::<(String, Vec<u8>)>::new()));
    let mut clients = tokio::task::JoinSet::new();
    for worker in 0..2u32 {
        let (client, addr, acknowledged) = (client.clone(), addr.clone(), acknowledged.clone());
        clients.spawn(async move {
            for seed in 0..200u32 {
                let (tx, ty) = TILES[(seed % 4) as usize];
                let url = format!(
                    "/v1/scenes/box/tiles/{tx}/{ty}.png?size=32&preset=draft&seed={}",
                    2 * seed + worker
                );
                let Ok(response) = client.get(format!("http://{addr}{url}")).send().await else {
                    return;
                };
                let Ok(bytes) = response.bytes().await else {
                    return;
                };
                acknowledged.lock().unwrap().push((url, bytes.to_vec()));
            }
        });
    }
    // Kill it once a few tiles are in, mid-stream.
    while acknowledged.lock().unwrap().len() < 6 {
        tokio::time::sleep(std::time::Duration::from_millis(20)).await;
    }
    service.0.kill().unwrap();
    service.0.wait().unwrap();
    clients.join_all().await;
    let acknowledged = acknowledged.lock().unwrap().clone();
    assert!(acknowledged.len() >= 6);
    eprintln!("{} tiles acknowledged before the kill", acknowledged.len());

    let again = spawn_app_in(scenes, {
        let data = data.path().to_owned();
        move |config| config.cache.data_dir = data
    })
    .await;
    for (url, bytes) in &acknowledged {
        let response = again.get(url).await;
        assert_eq!(response.status(), 200, "{url}");
        assert_eq!(
            response.headers()["x-rays"],
            "0",
            "{url} was acknowledged but not kept"
        );
        assert_eq!(&response.bytes().await.unwrap().to_vec(), bytes, "{url}");
    }
}
