//! Small uploads that claim large payloads, measured against service
//! binaries: what each answers, in how long, at what peak memory, and
//! whether it is still up (the figures of docs/BENCHMARKS.md "Hostile
//! inputs").
//!
//! `cargo run --example hostile_inputs -- BINARY [BINARY …]`
//!
//! For each case and binary, a fresh `serve` on loopback (the tiny scene,
//! an empty data directory, `scenes.max_scene_bytes` 256 MiB, the rest the
//! defaults) under a 4 GiB address-space limit (`prlimit --as`, so that a
//! binary that allocates without bound fails instead of the machine), one
//! `POST /v1/scenes`, then `GET /health`. Printed per case: the status and
//! the field named, the seconds to the answer (or "none" after 60 s), the
//! service's peak resident memory (`VmHWM`) and whether it still answers.

use std::io::{BufRead, BufReader};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use bmc_irradiance::testing::{
    BOUNDARY, TINY_SCENE, jpeg_claiming, multipart, ply_with_junk_element, ref_doubling_xml,
    scene_upload, serialized_mesh, two_part_exr,
};
use serde_json::{Value, json};

/// How long a case may take before it counts as no answer.
const PATIENCE: Duration = Duration::from_secs(60);

/// A request: path and query, content type, body.
struct Case {
    name: &'static str,
    path: String,
    content_type: String,
    body: Vec<u8>,
}

/// A multipart upload of a JSON scene of one shape, `extra` fields and
/// `assets`.
fn upload(name: &'static str, shape: Value, extra: Value, assets: Vec<(&str, Vec<u8>)>) -> Case {
    Case {
        name,
        path: "/v1/scenes".into(),
        content_type: format!("multipart/form-data; boundary={BOUNDARY}"),
        body: scene_upload(shape, extra, assets),
    }
}

fn png(width: u32, height: u32) -> Vec<u8> {
    let mut bytes = Vec::new();
    image::RgbImage::from_pixel(width, height, image::Rgb([200, 150, 100]))
        .write_to(
            &mut std::io::Cursor::new(&mut bytes),
            image::ImageFormat::Png,
        )
        .expect("in memory");
    bytes
}

fn cases() -> Vec<Case> {
    let rectangle = json!({"type": "rectangle", "material": "m"});
    let ior_texture = {
        let shapes: String = (0..30)
            .map(|i| format!(r#"<shape type="sphere"><point name="center" x="{i}" y="0" z="0"/><bsdf type="dielectric"><ref name="int_ior" id="t"/></bsdf></shape>"#))
            .collect();
        format!(
            r#"<scene version="3.0.0"><sensor type="perspective"><film type="hdrfilm"><integer name="width" value="8"/><integer name="height" value="8"/></film></sensor><texture type="bitmap" id="t"><string name="filename" value="ior.png"/></texture>{shapes}</scene>"#
        )
    };
    let ior_upload = multipart(&[
        (
            "scene",
            Some("ior.xml"),
            "application/xml",
            ior_texture.into_bytes(),
        ),
        ("asset", Some("ior.png"), "image/png", png(8192, 4096)),
    ]);
    let glowing = |file: &str| {
        json!({"type": "rectangle", "material": "m",
               "emitter": {"type": "area", "radiance": {"type": "bitmap", "filename": file}}})
    };
    let glow = png(8192, 4096);
    vec![
        upload(
            "1. EXR: 1×1 part before a 200000² one (envmap)",
            rectangle.clone(),
            json!({"environment": {"type": "envmap", "filename": "sky.exr"}}),
            vec![("sky.exr", two_part_exr(200_000))],
        ),
        upload(
            "2. PLY of 244 bytes: element junk 10^11",
            json!({"type": "ply", "filename": "junk.ply", "material": "m"}),
            json!({}),
            vec![("junk.ply", ply_with_junk_element())],
        ),
        upload(
            "3. serialized: 30 M vertices, 1 triangle",
            json!({"type": "serialized", "filename": "bomb.serialized", "material": "m"}),
            json!({}),
            vec![("bomb.serialized", serialized_mesh(30_000_000, 1))],
        ),
        Case {
            name: "4. <ref> doubling, 24 levels",
            path: "/v1/scenes?id=doubling".into(),
            content_type: "application/xml".into(),
            body: ref_doubling_xml(24).into_bytes(),
        },
        Case {
            name: "5. 30 int_ior = one 8192×4096 PNG (lenient)",
            path: "/v1/scenes?id=ior&lenient=true".into(),
            content_type: format!("multipart/form-data; boundary={BOUNDARY}"),
            body: ior_upload,
        },
        upload(
            "6. dielectric int_ior 1e300, ext_ior 1e-300",
            rectangle.clone(),
            json!({"materials": [{"id": "m", "type": "dielectric", "int_ior": 1e300, "ext_ior": 1e-300}]}),
            vec![],
        ),
        upload(
            "8. two 8192×4096 emitter textures",
            glowing("a.png"),
            json!({"shapes": [glowing("a.png"), glowing("b.png")]}),
            vec![("a.png", glow.clone()), ("b.png", glow)],
        ),
        upload(
            "11. JPEG of ~600 bytes claiming 16384×2048 (envmap)",
            rectangle,
            json!({"environment": {"type": "envmap", "filename": "sky.jpg"}}),
            vec![("sky.jpg", jpeg_claiming(16384, 2048))],
        ),
    ]
}

/// `serve` of `binary` on loopback under a 4 GiB address-space limit, and
/// its address.
fn serve(binary: &str, scenes: &std::path::Path, data: &std::path::Path) -> (Child, String) {
    let mut child = Command::new("prlimit")
        .args([
            "--as=4294967296",
            "--",
            binary,
            "serve",
            "--bind",
            "127.0.0.1:0",
        ])
        .env("BMC_SCENES__DIR", scenes)
        .env("BMC_CACHE__DATA_DIR", data)
        .env("BMC_SCENES__MAX_SCENE_BYTES", (256u64 << 20).to_string())
        .env("NO_COLOR", "1")
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .expect("prlimit and the binary run");
    let mut lines = BufReader::new(child.stderr.take().expect("piped")).lines();
    let addr = loop {
        let line = lines.next().expect("the service exited").expect("a line");
        if let Some(rest) = line.split("addr=").nth(1)
            && line.contains("listening")
        {
            break rest
                .split_whitespace()
                .next()
                .expect("an address")
                .to_owned();
        }
    };
    std::thread::spawn(move || for _ in lines {});
    (child, addr)
}

/// Peak resident memory of `pid`, MiB (`None` once it has exited).
fn peak_mib(pid: u32) -> Option<u64> {
    let status = std::fs::read_to_string(format!("/proc/{pid}/status")).ok()?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kib: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kib >> 10)
}

#[tokio::main]
async fn main() -> anyhow::Result<()> {
    let binaries: Vec<String> = std::env::args().skip(1).collect();
    anyhow::ensure!(
        !binaries.is_empty(),
        "usage: hostile_inputs BINARY [BINARY …]"
    );
    let client = reqwest::Client::builder().timeout(PATIENCE).build()?;
    println!("| case | binary | answer | seconds | peak RSS (MiB) | up after |");
    println!("|---|---|---|---|---|---|");
    for case in cases() {
        for binary in &binaries {
            let scenes = tempfile::tempdir()?;
            std::fs::write(scenes.path().join("tiny.json"), TINY_SCENE)?;
            let data = tempfile::tempdir()?;
            let (mut child, addr) = serve(binary, scenes.path(), data.path());
            // prlimit execs the binary, so its pid is the service's.
            let pid = child.id();
            let started = Instant::now();
            let answer = client
                .post(format!("http://{addr}{}", case.path))
                .header("content-type", &case.content_type)
                .body(case.body.clone())
                .send()
                .await;
            let seconds = started.elapsed().as_secs_f64();
            let answer = match answer {
                Ok(response) => {
                    let status = response.status().as_u16();
                    let body: Value = response.json().await.unwrap_or_default();
                    let field = body["error"]["field"].as_str().unwrap_or("").to_owned();
                    format!("{status} {field}")
                }
                Err(e) if e.is_timeout() => "none".to_owned(),
                Err(_) => "connection lost".to_owned(),
            };
            let peak = peak_mib(pid).map_or("exited".to_owned(), |m| m.to_string());
            let up = client
                .get(format!("http://{addr}/health"))
                .timeout(Duration::from_secs(5))
                .send()
                .await
                .map_or("no".to_owned(), |r| r.status().as_u16().to_string());
            println!(
                "| {} | {binary} | {answer} | {seconds:.2} | {peak} | {up} |",
                case.name
            );
            let _ = child.kill();
            let _ = child.wait();
        }
    }
    Ok(())
}
