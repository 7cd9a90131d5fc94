//! The browser viewer (`/`) in a real headless Chromium, driven over the
//! Chrome DevTools Protocol: the page loads, the Cornell box appears (the
//! canvas's pixel statistics equal those of the service's PNG tiles), the
//! uncertainty and denoise toggles change what is shown, and the console stays free of
//! errors. A screenshot of the page is written to
//! `target/viewer-screenshot.png` (the one in `docs/` comes from it).
//!
//! Needs Debian's `chromium` (`.ci/run` installs it); set `CHROMIUM` to use
//! another binary.

use std::io::{BufRead, BufReader};
use std::net::TcpStream;
use std::path::Path;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use base64::Engine;
use serde_json::{Value, json};
use tungstenite::stream::MaybeTlsStream;
use tungstenite::{Message, WebSocket};

use crate::common::{TestApp, spawn_app_in};

/// A headless Chromium, killed on drop.
struct Browser {
    child: Child,
    _profile: tempfile::TempDir,
}

impl Drop for Browser {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// A CDP connection in flattened-session mode, with the console errors and
/// exceptions seen so far.
struct DevTools {
    socket: WebSocket<MaybeTlsStream<TcpStream>>,
    session: Option<String>,
    next_id: u64,
    errors: Vec<String>,
}

impl DevTools {
    fn call(&mut self, method: &str, params: Value) -> Value {
        self.next_id += 1;
        let id = self.next_id;
        let mut message = json!({"id": id, "method": method, "params": params});
        if let Some(session) = &self.session {
            message["sessionId"] = json!(session);
        }
        self.socket
            .send(Message::text(message.to_string()))
            .unwrap();
        loop {
            let Message::Text(text) = self.socket.read().unwrap() else {
                continue;
            };
            let reply: Value = serde_json::from_str(&text).unwrap();
            if reply["id"] == id {
                assert!(reply.get("error").is_none(), "{method}: {reply}");
                return reply["result"].clone();
            }
            self.note_event(&reply);
        }
    }

    fn note_event(&mut self, event: &Value) {
        let params = &event["params"];
        match event["method"].as_str() {
            Some("Runtime.consoleAPICalled") if params["type"] == "error" => {
                self.errors
                    .push(format!("console.error: {}", params["args"]));
            }
            Some("Runtime.exceptionThrown") => {
                self.errors
                    .push(format!("exception: {}", params["exceptionDetails"]));
            }
            Some("Log.entryAdded") if params["entry"]["level"] == "error" => {
                self.errors.push(format!("log: {}", params["entry"]));
            }
            _ => {}
        }
    }

    /// The value of a JavaScript expression (promises awaited).
    fn eval(&mut self, expression: &str) -> Value {
        let result = self.call(
            "Runtime.evaluate",
            json!({"expression": expression, "returnByValue": true, "awaitPromise": true}),
        );
        assert!(
            result.get("exceptionDetails").is_none(),
            "{expression}: {result}"
        );
        result["result"]["value"].clone()
    }

    /// Waits until `expression` is true.
    fn wait_for(&mut self, expression: &str, timeout: Duration) {
        let start = Instant::now();
        while self.eval(expression) != json!(true) {
            assert!(
                start.elapsed() < timeout,
                "timed out waiting for {expression}"
            );
            std::thread::sleep(Duration::from_millis(200));
        }
    }
}

fn launch() -> (Browser, DevTools) {
    let binary = std::env::var("CHROMIUM").unwrap_or_else(|_| "chromium".into());
    let profile = tempfile::tempdir().unwrap();
    let mut child = Command::new(&binary)
        .args([
            "--headless",
            "--no-sandbox",
            "--disable-gpu",
            "--disable-quic",
            "--no-first-run",
            "--disable-background-networking",
            "--disable-component-update",
            "--disable-sync",
            "--window-size=1280,760",
            "--remote-debugging-port=0",
            "about:blank",
        ])
        .arg(format!("--user-data-dir={}", profile.path().display()))
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap_or_else(|e| {
            panic!("cannot start {binary} ({e}); install Debian's chromium or set CHROMIUM")
        });
    // Chromium prints the browser's DevTools endpoint on stderr.
    let stderr = BufReader::new(child.stderr.take().unwrap());
    let mut endpoint = None;
    for line in stderr.lines() {
        let line = line.unwrap();
        if let Some(url) = line.strip_prefix("DevTools listening on ") {
            endpoint = Some(url.trim().to_owned());
            break;
        }
    }
    let browser = Browser {
        child,
        _profile: profile,
    };
    let endpoint = endpoint.expect("chromium printed no DevTools endpoint");
    let (socket, _) = tungstenite::connect(endpoint.as_str()).unwrap();
    let mut tools = DevTools {
        socket,
        session: None,
        next_id: 0,
        errors: Vec::new(),
    };
    let target = tools.call("Target.createTarget", json!({"url": "about:blank"}));
    let attached = tools.call(
        "Target.attachToTarget",
        json!({"targetId": target["targetId"], "flatten": true}),
    );
    tools.session = Some(attached["sessionId"].as_str().unwrap().to_owned());
    for domain in ["Runtime.enable", "Log.enable", "Page.enable"] {
        tools.call(domain, json!({}));
    }
    (browser, tools)
}

/// Mean RGB (0–255) over all pixels of the service's PNG tiles of `preset`
/// at `pass`, denoised or not, as the viewer requests them.
async fn server_mean(app: &TestApp, aov: &str, preset: &str, pass: u32, denoise: bool) -> [f64; 3] {
    let (mut sum, mut count) = ([0.0; 3], 0usize);
    for ty in 0..4 {
        for tx in 0..4 {
            let query = match aov {
                "radiance" if denoise => {
                    format!("size=64&preset={preset}&pass={pass}&exposure=0&denoise=true")
                }
                "radiance" => format!("size=64&preset={preset}&pass={pass}&exposure=0"),
                other => format!("size=64&preset={preset}&pass={pass}&aov={other}"),
            };
            let url = format!("/v1/scenes/cornell-box/tiles/{tx}/{ty}.png?{query}");
            let response = app.get(&url).await;
            assert_eq!(response.status(), 200, "{url}");
            let png = image::load_from_memory(&response.bytes().await.unwrap())
                .unwrap()
                .to_rgb8();
            for p in png.pixels() {
                for c in 0..3 {
                    sum[c] += f64::from(p[c]);
                }
                count += 1;
            }
        }
    }
    sum.map(|s| s / count as f64)
}

/// Longest wait for the viewer's tiles (CI's two cores run other tests beside).
const LOAD: Duration = Duration::from_secs(300);

/// A browser showing the viewer on `app`'s Cornell box (draft preset), once
/// its tiles are in.
fn open_viewer(app: &TestApp) -> (Browser, DevTools) {
    let (browser, mut tools) = launch();
    tools.call(
        "Page.navigate",
        json!({"url": app.url("/?scene=cornell-box&preset=draft")}),
    );
    tools.wait_for("!!(window.viewer && window.viewer.idle())", LOAD);
    (browser, tools)
}

/// A service whose scenes directory holds only the bundled Cornell box.
async fn serving_the_cornell_box() -> TestApp {
    let dir = tempfile::tempdir().unwrap();
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes");
    std::fs::copy(
        root.join("cornell-box.json"),
        dir.path().join("cornell-box.json"),
    )
    .unwrap();
    spawn_app_in(dir, |_| {}).await
}

/// The viewer's layer and the service's tiles agree to half a level of 255
/// in each channel's mean.
fn assert_means_agree(shown: [f64; 3], served: [f64; 3]) {
    for c in 0..3 {
        assert!(
            (shown[c] - served[c]).abs() < 0.5,
            "{shown:?} vs {served:?}"
        );
    }
}

fn mean_of(stats: &Value) -> [f64; 3] {
    let m = stats["mean"].as_array().unwrap();
    [0, 1, 2].map(|c| m[c].as_f64().unwrap())
}

#[test]
fn the_viewer_shows_the_cornell_box_and_its_uncertainty_in_chromium() {
    let runtime = tokio::runtime::Runtime::new().unwrap();
    let app = runtime.block_on(serving_the_cornell_box());
    let (_browser, mut tools) = open_viewer(&app);
    let load = LOAD;
    assert_eq!(tools.eval("window.viewer.state.width"), json!(256));

    // The radiance layer is the service's PNG tiles, pixel for pixel.
    let radiance = tools.eval("window.viewer.layerStats('radiance')");
    assert_eq!(radiance["pixels"], json!(256 * 256), "{radiance}");
    let expected = runtime.block_on(server_mean(&app, "radiance", "draft", 0, false));
    let got = mean_of(&radiance);
    assert_means_agree(got, expected);
    // The box is lit and coloured: red and green walls.
    assert!(got[0] > 20.0 && got[1] > 20.0, "{got:?}");
    let shown = mean_of(&tools.eval("window.viewer.viewStats()"));
    // The panel counts the records its (reproducible) tiles placed, as the
    // service reports them.
    let report: Value = runtime.block_on(async {
        app.get("/v1/scenes/cornell-box/cache")
            .await
            .json()
            .await
            .unwrap()
    });
    let held = report["content_keyed"]["records"].as_u64().unwrap();
    assert!(held > 0, "{report}");
    tools.wait_for(
        &format!(
            "Number(document.getElementById('tile-records').textContent.replace(/,/g, '')) === {held}"
        ),
        load,
    );

    // The uncertainty toggle shows the std_dev layer instead.
    tools.eval("document.getElementById('uncertainty').click()");
    tools.wait_for(
        "window.viewer.idle() && window.viewer.state.drawn.std_dev.size === 16",
        load,
    );
    let std_dev = mean_of(&tools.eval("window.viewer.layerStats('std_dev')"));
    let expected = runtime.block_on(server_mean(&app, "std_dev", "draft", 0, false));
    assert_means_agree(std_dev, expected);
    let toggled = mean_of(&tools.eval("window.viewer.viewStats()"));
    let change: f64 = (0..3).map(|c| (toggled[c] - shown[c]).abs()).sum();
    assert!(change > 10.0, "{shown:?} → {toggled:?}");
    assert_eq!(
        tools.eval("document.getElementById('legend').hidden"),
        json!(false)
    );

    // The denoise toggle reloads the radiance layer from denoised tiles and
    // says so.
    tools.eval("document.getElementById('uncertainty').click()");
    tools.eval("document.getElementById('denoise').click()");
    tools.wait_for(
        "window.viewer.idle() && window.viewer.state.drawn.radiance.size === 16 \
         && document.getElementById('shown').textContent.endsWith(', denoised')",
        load,
    );
    let asked = tools.eval(
        "performance.getEntriesByType('resource').filter((e) => e.name.includes('denoise=true')).length",
    );
    assert!(
        asked.as_u64().unwrap() >= 16,
        "{asked} denoised tiles fetched"
    );
    let denoised = mean_of(&tools.eval("window.viewer.layerStats('radiance')"));
    let expected = runtime.block_on(server_mean(&app, "radiance", "draft", 0, true));
    assert_means_agree(denoised, expected);
    tools.eval("document.getElementById('denoise').click()");

    // The record overlay draws on top.
    tools.eval("document.getElementById('records').click()");
    tools.wait_for(
        "window.viewer.idle() && window.viewer.state.drawn.records.size === 16",
        load,
    );
    let records = tools.eval("window.viewer.layerStats('records')");
    assert!(records["pixels"].as_u64().unwrap() > 100, "{records}");

    let shot = tools.call("Page.captureScreenshot", json!({"format": "png"}));
    let png = base64::engine::general_purpose::STANDARD
        .decode(shot["data"].as_str().unwrap())
        .unwrap();
    let target = Path::new(env!("CARGO_MANIFEST_DIR")).join("target");
    std::fs::create_dir_all(&target).unwrap();
    std::fs::write(target.join("viewer-screenshot.png"), png).unwrap();

    // Drain pending events, then no console errors.
    tools.eval("1");
    assert!(
        tools.errors.is_empty(),
        "console errors: {:#?}",
        tools.errors
    );
}

/// The viewer climbs the budget ladder: the cheapest preset's image first,
/// then each pass of the chosen one, and says which step the image shows.
/// What it ends on is the chosen preset's last pass, tile for tile.
#[test]
fn the_viewer_climbs_the_pass_ladder_and_labels_each_step() {
    let runtime = tokio::runtime::Runtime::new().unwrap();
    let app = runtime.block_on(serving_the_cornell_box());
    let (_browser, mut tools) = launch();
    tools.call(
        "Page.navigate",
        json!({"url": app.url("/?scene=cornell-box&preset=preview")}),
    );
    tools.wait_for("!!(window.viewer && window.viewer.idle())", LOAD);
    let ladder = tools.eval("window.viewer.state.ladder.map((s) => s.label)");
    let expected = json!([
        "draft (2 spp)",
        "preview · pass 1 of 3 (4 spp)",
        "preview · pass 2 of 3 (8 spp)",
        "preview · pass 3 of 3 (12 spp)"
    ]);
    assert_eq!(ladder, expected);
    // Every step was shown on the whole image, in order, and the panel
    // names the last.
    assert_eq!(tools.eval("window.viewer.state.shownLog"), expected);
    assert_eq!(
        tools.eval("document.getElementById('shown').textContent"),
        json!("preview · pass 3 of 3 (12 spp)")
    );
    // The image is the preset's final pass, as GET tiles serve it.
    let shown = mean_of(&tools.eval("window.viewer.layerStats('radiance')"));
    let served = runtime.block_on(server_mean(&app, "radiance", "preview", 2, false));
    assert_means_agree(shown, served);
    tools.eval("1");
    assert!(tools.errors.is_empty(), "{:#?}", tools.errors);
}

/// Drops `path` (a folder or a file) on the page as a user's drag from the
/// file manager does, through Chromium's own drag machinery.
fn drop_on_page(tools: &mut DevTools, path: &Path) {
    let data = json!({"items": [], "files": [path.to_str().unwrap()], "dragOperationsMask": 1});
    for kind in ["dragEnter", "dragOver", "drop"] {
        tools.call(
            "Input.dispatchDragEvent",
            json!({"type": kind, "x": 400, "y": 300, "data": data}),
        );
    }
}

#[test]
fn a_scene_folder_or_archive_dropped_on_the_viewer_is_uploaded_and_opened() {
    let runtime = tokio::runtime::Runtime::new().unwrap();
    let app = runtime.block_on(serving_the_cornell_box());
    // The tutorials' Cornell box folder, and a gzipped tar of it under
    // another folder name.
    let work = tempfile::tempdir().unwrap();
    let tutorials = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/mitsuba-tutorials");
    let folder = work.path().join("cbox");
    crate::common::copy_dir(&tutorials, &folder);
    crate::common::copy_dir(&tutorials, &work.path().join("box-packed"));
    let status = Command::new("tar")
        .args(["-czf", "box-packed.tar.gz", "box-packed"])
        .current_dir(work.path())
        .status()
        .unwrap();
    assert!(status.success());

    let (_browser, mut tools) = open_viewer(&app);
    let load = LOAD;
    let listed = || "[...document.getElementById('scene').options].map((o) => o.value)";
    assert_eq!(tools.eval(listed()), json!(["cornell-box"]));

    for (dropped, id) in [
        (folder, "cbox"),
        (work.path().join("box-packed.tar.gz"), "box-packed"),
    ] {
        drop_on_page(&mut tools, &dropped);
        tools.wait_for(
            &format!(
                "window.viewer.state.uploadError !== null || \
                 (window.viewer.state.scene === '{id}' && window.viewer.idle())"
            ),
            load,
        );
        assert_eq!(tools.eval("window.viewer.state.uploadError"), Value::Null);
        // Listed, opened and drawn: the box's 256² image is lit.
        assert!(
            tools
                .eval(listed())
                .as_array()
                .unwrap()
                .contains(&json!(id))
        );
        assert_eq!(tools.eval("window.viewer.state.width"), json!(256));
        let shown = tools.eval("window.viewer.layerStats('radiance')");
        assert_eq!(shown["pixels"], json!(256 * 256), "{shown}");
        assert!(mean_of(&shown)[0] > 20.0, "{shown}");
        let summary: Value = runtime.block_on(async {
            app.get(&format!("/v1/scenes/{id}"))
                .await
                .json()
                .await
                .unwrap()
        });
        assert_eq!(summary["id"], id, "{summary}");
    }
    tools.eval("1");
    assert!(
        tools.errors.is_empty(),
        "console errors: {:#?}",
        tools.errors
    );
}
