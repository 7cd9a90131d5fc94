// The browser viewer of bmc-irradiance: GET tiles (PNG) of the scene camera's
// image, loaded progressively up a ladder of budgets (the cheapest preset's
// image first, then each pass of the chosen preset; every tile's step k
// before any tile's step k + 1, visible tiles first) into one canvas per
// layer, shown with pan and zoom.
// Layers: radiance, the relative standard error (false colour, "std_dev"
// AOV) and the irradiance-cache records ("records" AOV, transparent overlay).
"use strict";

(() => {
  const TILE = 64;
  const WORKERS = 2;
  const $ = (id) => document.getElementById(id);

  const state = {
    scene: null, width: 0, height: 0, presets: new Map(),
    // The steps every radiance tile climbs ({preset, pass, label}), and the
    // labels of the steps shown on the whole image so far, in order.
    ladder: [], shownLog: [],
    preset: "preview", exposure: 0, denoise: false, denoised: false, uncertainty: false, records: false,
    zoom: 1, panX: 0, panY: 0,
    // Bumped whenever what the tiles show changes; older answers are dropped.
    generation: 0,
    layers: {},
    // Highest ladder step drawn per radiance tile, and which std_dev/records tiles are drawn.
    drawn: { radiance: new Map(), std_dev: new Set(), records: new Set() },
    queue: [], inFlight: 0, loaded: 0, total: 0,
    renderMillis: [], rays: 0, errors: 0, stdDevScale: 0.2,
    // The last upload's error (its message), if any.
    uploadError: null,
  };

  // ---- layers -------------------------------------------------------------
  function newLayer() {
    const c = document.createElement("canvas");
    c.width = state.width;
    c.height = state.height;
    return c;
  }

  function resetLayers() {
    state.layers = { radiance: newLayer(), std_dev: newLayer(), records: newLayer() };
    state.drawn = { radiance: new Map(), std_dev: new Set(), records: new Set() };
  }

  // ---- view ---------------------------------------------------------------
  const view = $("view");
  const ctx = view.getContext("2d");

  function resizeView() {
    const ratio = window.devicePixelRatio || 1;
    const rect = view.getBoundingClientRect();
    view.width = Math.max(1, Math.round(rect.width * ratio));
    view.height = Math.max(1, Math.round(rect.height * ratio));
    draw();
  }

  function fit() {
    if (!state.width) return;
    const zoom = Math.min(view.width / state.width, view.height / state.height);
    // Whole pixels per image pixel when the image fits at least once.
    state.zoom = zoom >= 1 ? Math.floor(zoom) : zoom;
    state.panX = (view.width - state.width * state.zoom) / 2;
    state.panY = (view.height - state.height * state.zoom) / 2;
    draw();
    schedule();
  }

  function draw() {
    ctx.setTransform(1, 0, 0, 1, 0, 0);
    ctx.fillStyle = "#0d0e10";
    ctx.fillRect(0, 0, view.width, view.height);
    if (!state.width) return;
    ctx.imageSmoothingEnabled = false;
    ctx.setTransform(state.zoom, 0, 0, state.zoom, state.panX, state.panY);
    ctx.drawImage(state.uncertainty ? state.layers.std_dev : state.layers.radiance, 0, 0);
    if (state.records) ctx.drawImage(state.layers.records, 0, 0);
  }

  // ---- tiles --------------------------------------------------------------
  function tileUrl(tx, ty, aov, step) {
    const { preset, pass } = state.ladder[step];
    const q = new URLSearchParams({ size: TILE, preset, pass });
    if (aov === "radiance") {
      q.set("exposure", state.exposure);
      if (state.denoise) q.set("denoise", "true");
    } else q.set("aov", aov);
    return `/v1/scenes/${encodeURIComponent(state.scene)}/tiles/${tx}/${ty}.png?${q}`;
  }

  // Tiles ordered by distance of their centre from the view's centre, the
  // ones on screen first.
  function tilesInOrder() {
    const cols = Math.ceil(state.width / TILE), rows = Math.ceil(state.height / TILE);
    const cx = (view.width / 2 - state.panX) / state.zoom;
    const cy = (view.height / 2 - state.panY) / state.zoom;
    const x0 = -state.panX / state.zoom, y0 = -state.panY / state.zoom;
    const x1 = x0 + view.width / state.zoom, y1 = y0 + view.height / state.zoom;
    const tiles = [];
    for (let ty = 0; ty < rows; ty++) {
      for (let tx = 0; tx < cols; tx++) {
        const [left, top] = [tx * TILE, ty * TILE];
        const visible = left < x1 && left + TILE > x0 && top < y1 && top + TILE > y0;
        const d = Math.hypot(left + TILE / 2 - cx, top + TILE / 2 - cy);
        tiles.push({ tx, ty, key: `${tx},${ty}`, order: (visible ? 0 : 1e9) + d });
      }
    }
    return tiles.sort((a, b) => a.order - b.order);
  }

  // The ladder of the chosen preset: the cheapest preset's whole image first
  // (the service lists presets cheapest first) when another one is chosen,
  // then each pass of the chosen one, pass k showing the mean of passes 0..k.
  function buildLadder() {
    const chosen = state.presets.get(state.preset) ?? { samples_per_pixel: 1, passes: 1 };
    const cheapest = state.presets.values().next().value;
    const steps = [];
    if (cheapest && cheapest.name !== state.preset) {
      const spp = cheapest.samples_per_pixel * cheapest.passes;
      steps.push({ preset: cheapest.name, pass: cheapest.passes - 1, label: `${cheapest.name} (${spp} spp)` });
    }
    for (let pass = 0; pass < chosen.passes; pass++) {
      const of = chosen.passes > 1 ? ` · pass ${pass + 1} of ${chosen.passes}` : "";
      const spp = chosen.samples_per_pixel * (pass + 1);
      steps.push({ preset: state.preset, pass, label: `${state.preset}${of} (${spp} spp)` });
    }
    return steps;
  }

  function tileCount() {
    return Math.ceil(state.width / TILE) * Math.ceil(state.height / TILE);
  }

  // Rebuilds the queue from what is missing: radiance step by step (every
  // tile's step k before any tile's step k + 1), then the enabled overlays
  // (at the ladder's top).
  function schedule() {
    if (!state.scene) return;
    const tiles = tilesInOrder();
    const top = state.ladder.length - 1;
    const jobs = [];
    for (let step = 0; step <= top; step++) {
      for (const t of tiles) {
        if ((state.drawn.radiance.get(t.key) ?? -1) < step) jobs.push({ ...t, aov: "radiance", step });
      }
      if (step === 0) {
        for (const aov of ["records", "std_dev"]) {
          const wanted = aov === "records" ? state.records : state.uncertainty;
          if (!wanted) continue;
          for (const t of tiles) if (!state.drawn[aov].has(t.key)) jobs.push({ ...t, aov, step: top });
        }
      }
    }
    state.queue = jobs;
    state.total = state.loaded + jobs.length;
    progress();
    for (let i = state.inFlight; i < WORKERS; i++) next();
  }

  async function next() {
    const job = state.queue.shift();
    if (!job) { progress(); return; }
    state.inFlight++;
    const generation = state.generation;
    try {
      await load(job, generation);
    } catch (err) {
      state.errors++;
      $("progress").textContent = `tile ${job.key}: ${err.message}`;
    } finally {
      state.inFlight--;
    }
    if (generation === state.generation) next();
  }

  async function load(job, generation) {
    // A radiance step may already be covered by a later one drawn meanwhile.
    if (job.aov === "radiance" && (state.drawn.radiance.get(job.key) ?? -1) >= job.step) return;
    const started = performance.now();
    let response;
    for (;;) {
      response = await fetch(tileUrl(job.tx, job.ty, job.aov, job.step));
      if (response.status !== 503) break;
      const wait = Number(response.headers.get("retry-after") || 1);
      await new Promise((r) => setTimeout(r, 1000 * wait));
      if (generation !== state.generation) return;
    }
    if (!response.ok) {
      const body = await response.json().catch(() => ({}));
      throw new Error(body.error ? body.error.message : `HTTP ${response.status}`);
    }
    const bitmap = await createImageBitmap(await response.blob());
    if (generation !== state.generation) return;
    const layer = state.layers[job.aov].getContext("2d");
    layer.clearRect(job.tx * TILE, job.ty * TILE, bitmap.width, bitmap.height);
    layer.drawImage(bitmap, job.tx * TILE, job.ty * TILE);
    bitmap.close();
    if (job.aov === "radiance") {
      state.drawn.radiance.set(job.key, job.step);
      // Denoised as asked, or by the preset's choice on this scene.
      state.denoised = response.headers.get("x-denoised") === "1";
    }
    else state.drawn[job.aov].add(job.key);
    if (job.aov === "std_dev") {
      state.stdDevScale = Number(response.headers.get("x-std-dev-scale") || state.stdDevScale);
    }
    const timing = /dur=([\d.]+)/.exec(response.headers.get("server-timing") || "");
    state.renderMillis.push(timing ? Number(timing[1]) : performance.now() - started);
    state.rays += Number(response.headers.get("x-rays") || 0);
    state.loaded++;
    $("tile-last").textContent = `${(performance.now() - started).toFixed(0)} ms`;
    draw();
    progress();
    if (state.loaded % 8 === 0 || state.queue.length === 0) refreshCacheStats();
  }

  // ---- panel --------------------------------------------------------------
  // Which ladder step the image shows: the lowest step over all tiles, and
  // how many tiles are already further up.
  function showLadder() {
    const steps = [...state.drawn.radiance.values()];
    const total = tileCount();
    let text = state.ladder.length ? `loading ${state.ladder[0].label}` : "–";
    if (steps.length === total && total > 0) {
      const low = Math.min(...steps), high = Math.max(...steps);
      const label = state.ladder[low].label;
      if (state.shownLog[state.shownLog.length - 1] !== label) state.shownLog.push(label);
      const ahead = steps.filter((s) => s > low).length;
      const shown = state.denoised ? `${label}, denoised` : label;
      text = ahead ? `${shown}; ${ahead} of ${total} tiles at ${state.ladder[high].label}` : shown;
    }
    $("shown").textContent = text;
  }

  function progress() {
    const done = state.total === 0 ? 1 : state.loaded / state.total;
    if (!state.errors) {
      $("progress").textContent = state.queue.length || state.inFlight
        ? `${state.loaded} / ${state.total} tiles`
        : `done: ${state.ladder.length} step${state.ladder.length > 1 ? "s" : ""} to ${state.preset}`;
    }
    showLadder();
    $("progress-bar").style.width = `${(100 * done).toFixed(1)}%`;
    const ms = state.renderMillis;
    if (ms.length) $("tile-mean").textContent = `${(ms.reduce((a, b) => a + b, 0) / ms.length).toFixed(0)} ms`;
    $("rays").textContent = state.rays.toLocaleString("en");
  }

  async function refreshCacheStats() {
    if (!state.scene) return;
    const response = await fetch(`/v1/scenes/${encodeURIComponent(state.scene)}/cache`);
    if (!response.ok) return;
    const report = await response.json();
    const sum = (field) => report.caches.reduce((a, c) => a + (c.stats[field] || 0), 0);
    $("cache-records").textContent = sum("records").toLocaleString("en");
    $("tile-records").textContent = report.content_keyed.records.toLocaleString("en");
    $("cache-hits").textContent = sum("hits").toLocaleString("en");
    $("cache-bytes").textContent = `${(sum("bytes") / 1024).toFixed(0)} KiB`;
  }

  function drawLegend() {
    const ramp = $("legend-ramp").getContext("2d");
    // The viridis anchors the service's false colour interpolates.
    const anchors = ["#440154", "#472c7a", "#3b518b", "#2c718e", "#21908d", "#27ad81", "#5cc863", "#aadc32", "#fde725"];
    const gradient = ramp.createLinearGradient(0, 0, 200, 0);
    anchors.forEach((c, i) => gradient.addColorStop(i / (anchors.length - 1), c));
    ramp.fillStyle = gradient;
    ramp.fillRect(0, 0, 200, 12);
    $("legend-max").textContent = `≥ ${(100 * state.stdDevScale).toFixed(0)} %`;
    $("legend").hidden = !state.uncertainty;
  }

  // ---- uploads: a scene folder or archive dropped on the page --------------
  // A folder is sent as a tar the page assembles (headers around the File
  // objects, so no file is read into memory here), an archive as it is; the
  // service finds the scene file and names the scene after the folder.
  const ARCHIVES = [[".zip", "application/zip"], [".tar.gz", "application/gzip"],
    [".tgz", "application/gzip"], [".tar", "application/x-tar"]];
  const encoder = new TextEncoder();

  // One ustar header block for a regular file `name` (UTF-8, long names split
  // into the prefix field at a slash) of `size` bytes.
  function tarHeader(name, size) {
    const bytes = encoder.encode(name);
    let [prefix, base] = [new Uint8Array(0), bytes];
    if (bytes.length > 100) {
      const slash = bytes.lastIndexOf(0x2f, 155);
      if (slash < 0 || bytes.length - slash - 1 > 100) throw new Error(`${name}: the name is too long for a tar`);
      [prefix, base] = [bytes.subarray(0, slash), bytes.subarray(slash + 1)];
    }
    const h = new Uint8Array(512);
    const put = (offset, text) => h.set(typeof text === "string" ? encoder.encode(text) : text, offset);
    put(0, base);
    put(100, "0000644\0");
    put(108, "0000000\0");
    put(116, "0000000\0");
    put(124, size.toString(8).padStart(11, "0") + "\0");
    put(136, "00000000000\0");
    put(148, "        ");
    put(156, "0");
    put(257, "ustar\0");
    put(263, "00");
    put(345, prefix);
    const sum = h.reduce((a, b) => a + b, 0);
    put(148, sum.toString(8).padStart(6, "0") + "\0 ");
    return h;
  }

  // A tar of `files` ([relative name, File]) as a Blob.
  function tarOf(files) {
    const parts = [];
    for (const [name, file] of files) {
      parts.push(tarHeader(name, file.size), file);
      if (file.size % 512) parts.push(new Uint8Array(512 - (file.size % 512)));
    }
    parts.push(new Uint8Array(1024));
    return new Blob(parts);
  }

  // The files under a dropped directory entry, named from its own name down.
  async function filesOf(entry, path, out) {
    if (entry.isFile) {
      out.push([path, await new Promise((resolve, reject) => entry.file(resolve, reject))]);
    } else if (entry.isDirectory) {
      const reader = entry.createReader();
      for (;;) {
        const batch = await new Promise((resolve, reject) => reader.readEntries(resolve, reject));
        if (!batch.length) break;
        for (const child of batch) await filesOf(child, `${path}/${child.name}`, out);
      }
    }
    return out;
  }

  // What a dropped item becomes: [body, content type, query, label].
  async function uploadOf(entry, file) {
    if (entry && entry.isDirectory) {
      const files = await filesOf(entry, entry.name, []);
      return [tarOf(files), "application/x-tar", "", `${entry.name}/ (${files.length} files)`];
    }
    const name = file.name.toLowerCase();
    const archive = ARCHIVES.find(([suffix]) => name.endsWith(suffix));
    if (archive) return [file, archive[1], "", file.name];
    if (name.endsWith(".xml")) {
      const id = file.name.replace(/\.xml$/i, "");
      return [file, "application/xml", `?id=${encodeURIComponent(id)}`, file.name];
    }
    if (name.endsWith(".json")) return [file, "application/json", "", file.name];
    throw new Error(`${file.name}: drop a scene folder, a .zip, .tar or .tar.gz of one, or a scene file`);
  }

  async function uploadDropped(dataTransfer) {
    const item = [...dataTransfer.items].find((i) => i.kind === "file");
    if (!item) return;
    const [body, type, query, label] = await uploadOf(item.webkitGetAsEntry?.(), item.getAsFile());
    $("progress").textContent = `uploading ${label}…`;
    const post = (extra) => {
      const url = `/v1/scenes${query}${extra ? (query ? "&" : "?") + extra : ""}`;
      return fetch(url, { method: "POST", headers: { "content-type": type }, body });
    };
    let response = await post("");
    let answer = await response.json().catch(() => ({}));
    // A scene of that id is loaded: replaced only if the user says so.
    if (response.status === 409 && answer.error?.code === "scene_exists"
        && window.confirm(`${answer.error.message}\n\nReplace it with ${label}?`)) {
      response = await post("replace=true");
      answer = await response.json().catch(() => ({}));
    }
    if (!response.ok) {
      const e = answer.error;
      throw new Error(e ? `${label}: ${e.message}${e.field ? ` (${e.field})` : ""}` : `${label}: HTTP ${response.status}`);
    }
    await listScenes(answer.id);
  }

  function bindDrop() {
    const over = (on) => document.body.classList.toggle("dropping", on);
    document.addEventListener("dragover", (e) => { e.preventDefault(); over(true); });
    document.addEventListener("dragleave", (e) => { if (e.target === document.documentElement || !e.relatedTarget) over(false); });
    document.addEventListener("drop", (e) => {
      e.preventDefault();
      over(false);
      uploadDropped(e.dataTransfer).catch((err) => { state.uploadError = err.message; $("progress").textContent = err.message; });
    });
  }

  // ---- scene and controls ---------------------------------------------------
  // Fills the scene list with every scene the service holds and opens
  // `wanted` (else the one shown, else cornell-box, else the first).
  async function listScenes(wanted) {
    const scenes = await (await fetch("/v1/scenes")).json();
    const select = $("scene");
    select.replaceChildren(...scenes.map((s) => new Option(`${s.id} (${s.resolution[0]}×${s.resolution[1]})`, s.id)));
    const first = scenes.find((s) => s.id === wanted) || scenes.find((s) => s.id === state.scene)
      || scenes.find((s) => s.id === "cornell-box") || scenes[0];
    if (!first) { $("progress").textContent = "no scenes loaded: drop a scene folder here"; return; }
    select.value = first.id;
    if (first.id !== state.scene || wanted) await selectScene(first.id);
  }

  async function selectScene(id) {
    const response = await fetch(`/v1/scenes/${encodeURIComponent(id)}`);
    if (!response.ok) throw new Error(`scene ${id}: HTTP ${response.status}`);
    const scene = await response.json();
    state.scene = id;
    [state.width, state.height] = scene.resolution;
    restart();
    fit();
  }

  // Starts the tiles over (a new scene or preset).
  function restart() {
    state.generation++;
    state.queue = [];
    state.loaded = 0;
    state.renderMillis = [];
    state.rays = 0;
    state.errors = 0;
    resetLayers();
    state.ladder = buildLadder();
    state.shownLog = [];
    draw();
    schedule();
  }

  function bindControls() {
    $("scene").addEventListener("change", (e) => selectScene(e.target.value));
    $("preset").addEventListener("change", (e) => { state.preset = e.target.value; restart(); });
    // Only the radiance layer depends on the exposure and denoising: reload
    // it up the ladder again (the service keeps the passes, so this is cheap).
    const reloadRadiance = () => {
      state.generation++;
      state.queue = [];
      state.drawn.radiance = new Map();
      state.loaded = 0;
      schedule();
    };
    $("exposure").addEventListener("input", (e) => {
      state.exposure = Number(e.target.value);
      $("exposure-value").textContent = state.exposure;
      reloadRadiance();
    });
    $("denoise").addEventListener("change", (e) => { state.denoise = e.target.checked; reloadRadiance(); });
    $("uncertainty").addEventListener("change", (e) => {
      state.uncertainty = e.target.checked; drawLegend(); draw(); schedule();
    });
    $("records").addEventListener("change", (e) => { state.records = e.target.checked; draw(); schedule(); });
    $("fit").addEventListener("click", fit);

    let drag = null;
    view.addEventListener("pointerdown", (e) => {
      drag = { x: e.clientX, y: e.clientY, panX: state.panX, panY: state.panY };
      view.setPointerCapture(e.pointerId);
      view.classList.add("dragging");
    });
    view.addEventListener("pointermove", (e) => {
      if (!drag) return;
      const ratio = window.devicePixelRatio || 1;
      state.panX = drag.panX + (e.clientX - drag.x) * ratio;
      state.panY = drag.panY + (e.clientY - drag.y) * ratio;
      draw();
    });
    view.addEventListener("pointerup", () => { drag = null; view.classList.remove("dragging"); schedule(); });
    view.addEventListener("wheel", (e) => {
      e.preventDefault();
      const ratio = window.devicePixelRatio || 1;
      const [mx, my] = [e.offsetX * ratio, e.offsetY * ratio];
      const factor = Math.exp(-e.deltaY * 0.0015);
      const zoom = Math.min(64, Math.max(0.05, state.zoom * factor));
      state.panX = mx - (mx - state.panX) * (zoom / state.zoom);
      state.panY = my - (my - state.panY) * (zoom / state.zoom);
      state.zoom = zoom;
      draw();
      schedule();
    }, { passive: false });
    window.addEventListener("resize", resizeView);
  }

  async function start() {
    bindControls();
    bindDrop();
    resizeView();
    drawLegend();
    const params = new URLSearchParams(location.search);
    if (params.get("preset")) state.preset = params.get("preset");
    if (params.get("uncertainty") === "1") { state.uncertainty = true; $("uncertainty").checked = true; drawLegend(); }
    if (params.get("records") === "1") { state.records = true; $("records").checked = true; }
    if (params.get("denoise") === "1") { state.denoise = true; $("denoise").checked = true; }
    const presets = await (await fetch("/v1/presets")).json();
    state.presets = new Map(presets.map((p) => [p.name, p]));
    for (const p of presets) {
      $("preset").add(new Option(`${p.name} (${p.samples_per_pixel * p.passes} spp)`, p.name));
      if (p.default && !params.get("preset")) state.preset = p.name;
    }
    $("preset").value = state.preset;
    await listScenes(params.get("scene"));
  }

  // For people at the console and for the browser test: the state, whether
  // every scheduled tile is in, and mean RGB (0–255) of a layer or the view.
  function meanRgb(canvas) {
    const data = canvas.getContext("2d").getImageData(0, 0, canvas.width, canvas.height).data;
    const sum = [0, 0, 0];
    let count = 0;
    for (let i = 0; i < data.length; i += 4) {
      if (data[i + 3] === 0) continue;
      sum[0] += data[i]; sum[1] += data[i + 1]; sum[2] += data[i + 2];
      count++;
    }
    return { mean: sum.map((s) => (count ? s / count : 0)), pixels: count };
  }
  window.viewer = {
    state,
    idle: () => state.scene !== null && state.queue.length === 0 && state.inFlight === 0 && state.loaded > 0,
    layerStats: (name) => meanRgb(state.layers[name]),
    viewStats: () => meanRgb(view),
  };

  start().catch((err) => { $("progress").textContent = err.message; });
})();
