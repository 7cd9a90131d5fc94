#!/usr/bin/env bash
# A tour of the HTTP service with curl that runs top to bottom on the bundled
# scenes; docs/service.md describes it and lists the routes.
#
#   cargo run --release -- serve          # in one terminal, from the repository root
#   bash examples/walkthrough.sh [BASE]   # in another; BASE defaults to http://127.0.0.1:8080
#
# It reads the scene files in scenes/ beside this script and writes what it
# fetches into a temporary folder it removes at the end, so it leaves no
# file behind. It changes nothing it did not add: the scenes it
# uploads (my-box, my-box-xml, my-sky, my-studio) are deleted at the end, and the bundled
# cornell-box is only queried (its irradiance cache is cleared, which the next
# request refills). With server.auth_token set, export BMC_TOKEN. Any HTTP
# error stops the script, printing the service's JSON error body.
set -euo pipefail

# The bundled scenes beside this script, wherever it is run from.
SCENES="$(cd "$(dirname "${BASH_SOURCE[0]}")/../scenes" && pwd)"

# Prints each command (arguments quoted where the shell needs it) before its
# answer; fails on any 4xx/5xx.
curl() {
    local shown=curl arg
    for arg in "$@"; do
        if [[ $arg =~ ^[A-Za-z0-9_@%+=:,./-]+$ ]]; then shown+=" $arg"; else shown+=" '$arg'"; fi
    done
    printf '\n$ %s\n' "$shown" >&2
    command curl --silent --show-error --fail-with-body \
        ${BMC_TOKEN:+-H "Authorization: Bearer $BMC_TOKEN"} "$@"
    echo
}

# --- walkthrough: from here on, the commands also work pasted into a shell at the repository root ---
BASE="${1:-http://127.0.0.1:8080}" # where the service listens
SCENES="${SCENES:-scenes}"         # the bundled scenes (pasted by hand: from the repository root)
WORK="$(mktemp -d)"                # what the tour fetches goes here, removed at the end

curl "$BASE/health"                # {"status":"ok","version":"0.1.0","scenes":6,"cpu":{...}}
curl "$BASE/ready"                 # 200 when it should get work, 503 when wedged or saturated
curl "$BASE/metrics" | grep '^http_requests_total' # Prometheus text: latency histograms, rays_traced_total, ...
curl "$BASE/openapi.json" | grep -o '"/[^" ]*"' | sort -u # OpenAPI 3 document of every route (its paths)
curl "$BASE/v1/scenes"             # summaries of the loaded scenes
curl "$BASE/v1/scenes/cornell-box" # one scene: shapes, triangles, camera resolution, bounds

# Add a scene: a JSON document's "name" is its id; here a renamed copy. An id the service holds
# is refused (409 scene_exists) unless the POST says ?replace=true.
sed 's/"name": "cornell-box"/"name": "my-box"/' "$SCENES/cornell-box.json" |
    curl -X POST "$BASE/v1/scenes" -H 'content-type: application/json' --data-binary @-
# A Mitsuba 3 scene: the id comes from the query.
curl -X POST "$BASE/v1/scenes?id=my-box-xml&lenient=false" -H 'content-type: application/xml' \
     --data-binary @"$SCENES/cornell-box.xml"
# A scene with the files it references (multipart: one "scene" part, "asset" parts named
# by the relative paths the document uses; "..", absolute names: 422 naming assets[i]):
sed 's/"name": "sky"/"name": "my-sky"/' "$SCENES/sky.json" |
    curl -X POST "$BASE/v1/scenes" -F 'scene=@-;filename=scene.json;type=application/json' \
         -F "asset=@$SCENES/sky.exr;filename=sky.exr"
# A scene folder in one request: a zip, tar or gzipped tar with the scene file at its root
# (or at the root of its one folder: `zip -r lego.zip lego` gives id "lego"); ?file= picks
# it among several. Links, FIFOs, "..", zip bombs: 422 naming archive[i]. `bmc-irradiance
# upload DIR|ARCHIVE` and the Python client's upload_dir do the packing.
tar -czf - -C "$SCENES" studio.xml dusk.hdr textures/tiles.png meshes/blob.obj |
    curl -X POST "$BASE/v1/scenes?id=my-studio&file=studio.xml" -H 'content-type: application/gzip' \
         --data-binary @-

curl -X POST "$BASE/v1/scenes/cornell-box/irradiance" -H 'content-type: application/json' \
     -d '{"points": [{"position": [0, -0.99, 0], "normal": [0, 1, 0]}],
          "estimator": {"method": "mc", "samples": 64, "decomposition": "split"},
          "max_depth": 16, "seed": 1}'
# → {"irradiance": [[r,g,b]], "std_dev": [[r,g,b]], "rays": n, "amortised_rays": m, …}  (W/m²)
# rays counts every ray the request caused; amortised_rays, those of the work the first
# request of a configuration does for every later one (calibration, kernel fit): 0 next time

curl "$BASE/v1/presets"   # draft, preview (the default), interactive, standard, final: every knob each sets
# Tile (tx, ty) of 64-pixel tiles of the camera image, reproducible and cacheable by HTTP:
curl "$BASE/v1/scenes/cornell-box/tiles/1/1.png?preset=preview" -o "$WORK/tile.png" \
     -w '%{content_type}, %{size_download} bytes\n'   # → image/png, … bytes
# ?size=64 (tile side) &preset=draft|preview|interactive|standard|final &pass=k (mean of passes 0..k; default the
# last) &seed=1 &exposure=0 (PNG) &aov=radiance|std_dev|records &scale=0.2 (std_dev PNG);
# .exr: R, G, B and per-pixel variance; .json: {"width","height","rgb","variance"}.
# aov=std_dev: the standard error (PNG: relative, false colour up to `scale`);
# aov=records: the tile's irradiance-cache records (PNG overlay or JSON list).
# denoise=true: filtered by the tile's own first-hit guides, each pixel kept within and
# reporting its own standard error (docs/math.md §16.6; off by default).
# Headers: ETag (send it back as If-None-Match: 304), Cache-Control, x-rays,
# x-records-created, x-passes, Server-Timing.
curl -s -o /dev/null -w '%{http_code}\n' -H "If-None-Match: $(curl -sI \
     "$BASE/v1/scenes/cornell-box/tiles/1/1.png?preset=preview" | tr -d '\r' | sed -n 's/^etag: //Ip')" \
     "$BASE/v1/scenes/cornell-box/tiles/1/1.png?preset=preview"     # → 304
# The records of the scene's reproducible tiles, for a backup or to seed another service
# (the tile log's format, application/vnd.bmc-records); POST adds them, all or nothing
# (422 naming entries[i] when one is damaged or of another scene's content, and
# entries[i].records[j] when too many of up to 64 of the records it would add disagree
# with fresh estimates of the scene, docs/math.md §9.8; tiles held here are not checked):
curl "$BASE/v1/scenes/cornell-box/records" -o "$WORK/cornell-box.records"
curl -X POST "$BASE/v1/scenes/cornell-box/records" --data-binary @"$WORK/cornell-box.records"
# → {"imported": 0, "already_held": 1, "records": 0, "checked": 0, "disagreeing": 0}
# Any rectangle by POST, the same knobs in the body (explicit ones override the preset;
# an explicit samples_per_pixel renders one pass of that many rays):
curl -X POST "$BASE/v1/scenes/cornell-box/tiles" -H 'content-type: application/json' \
     -d '{"x": 0, "y": 0, "width": 32, "height": 32, "format": "json", "preset": "draft",
          "estimator": {"method": "path"}, "samples_per_pixel": 16}' -o "$WORK/tile.json"
# estimator: {"method": "cache"} (default: the Bayesian irradiance cache; options samples,
#   glossy_samples, lengthscale, noise, accuracy, relative_error_target, occlusion_check,
#   light_samples, paths_per_direction, ambient_bounces, secondary_cache (records' rays read
#   a scene-wide cache at their first hits; the final preset's true), reproducible (the presets' true:
#   records per tile, the same bytes whatever ran before; false: the scene's shared cache),
#   max_records_per_pixel (above it a tile places no records and path traces its indirect
#   light; the final preset's 0.2, for scenes of small parts such as the tutorials' lego),
#   cache: false) or {"method": "path"} (path tracing). Headers x-records-created and
#   x-cache-hits tell what the cache did.

curl -X POST "$BASE/v1/scenes/cornell-box/radiance" -H 'content-type: application/json' \
     -d '{"points": [{"position": [0.1, 0.6, -1.0], "normal": [0, 0, 1], "direction": [0.2, -0.1, 1]}],
          "estimator": {"method": "cache"}, "repeats": 16, "max_depth": 16, "seed": 1}'
# → {"radiance": [[r,g,b]], "std_dev": [[r,g,b]], "rays": n}  (W/(m²·sr) leaving the surface towards "direction")
curl "$BASE/v1/scenes/cornell-box/cache"           # cache stats per estimator configuration; tiles' content-keyed records
curl -X DELETE "$BASE/v1/scenes/cornell-box/cache" # drop the shared caches' records (secondary too; content-keyed ones stay)

curl -X POST "$BASE/v1/scenes/cornell-box/irradiance" -H 'content-type: application/json' \
     -d '{"points": [{"position": [0, -0.99, 0], "normal": [0, 1, 0]}],
          "estimator": {"method": "bmc", "samples": 64, "decomposition": "split",
                        "sample_set": {"kind": "fibonacci_cosine"},
                        "kernel": {"kind": "squared_exponential", "lengthscale": "auto"}},
          "max_depth": 16, "seed": 1}'
# → {"irradiance": …, "std_dev": …, "rays": n, "kernel": "squared_exponential", "lengthscale": ℓ, "noise": σ_n²,
#    "decomposition": "split", "prior": "none", "calibration": {"scale", "floor", …}}
#   "decomposition": "auto" (default) integrates a scene lit only by a smooth environment
#   (scenes/overcast.json) through the hemisphere, with the unoccluded environment as the
#   prior mean of "bmc" ("prior": "environment" | "none"; docs/math.md §10.4), and
#   light-samples suns and emitters otherwise ("light_samples": the split direct part's
#   samples, a shadow ray each, default "samples"; many more of them than directions are
#   cheap where the error is in the direct light). std_dev of every method is calibrated on
#   the scene (§10.5; "mc" and "qmc", and "bmc" in split mode for its light samples, add a
#   term for light all their samples missed; "calibrate": false gives the model's own variance).
#   "qmc" takes "sample_set" (fibonacci_cosine | fibonacci); "bmc" also a kernel whose
#   lengthscale is a number or "auto" (default: fitted once per scene and configuration
#   by marginal likelihood, listed under "fitted_kernels" by GET /v1/scenes/{id}); with
#   "auto" and no "kind", the family (squared_exponential | matern32 | matern52) is
#   selected by marginal likelihood too, and the response's "kernel" names it.
#   "records_prior" ("auto" by default: on for bmc, off for mc and qmc; true; false)
#   combines each point's indirect part with the records that cover it (§10.7): every
#   reproducible tile's, gathered the same on every replica (§10.10), and those a query of
#   64 points or more places among its own points (§10.11, counted in "amortised_rays");
#   also its direct part with the direct light seen from the records' places (§10.8;
#   light-sampled in split mode, left out where the point's own samples contradict
#   it), each prior weighed by a variance scale fitted
#   with the calibration ("calibration": {"prior_scales": …}, §10.9); "prior_used" says
#   per point which records served ("records" or "cache"), "records_prior_points" and
#   "direct_records_points" count them.

curl -X POST "$BASE/v1/quadratures" -H 'content-type: application/json' \
     -d '{"sample_set": {"kind": "fibonacci", "count": 64},
          "kernel": {"kind": "squared_exponential", "lengthscale": 0.5, "variance": 1.0, "noise": 1e-8},
          "density": {"kind": "lambert"}, "prior_mean": "zero", "kernel_mean": "exact"}'
# → {"id": "…16 hex…", "cached": false, "directions": [[x,y,z], …], "kernel_means": […],
#    "weights": […], "prior_variance": …, "posterior_variance": …, "jitter": …,
#    "condition_estimate": …, "density_integral": 1.0}; the same request again: "cached": true.
#   Cache hits/misses/bytes: bmc_factorisation_cache_{hits,misses}_total, bmc_factorisation_cache_bytes.

# Remove the scenes this walkthrough added (the bundled ones stay).
curl -X DELETE "$BASE/v1/scenes/my-box"
curl -X DELETE "$BASE/v1/scenes/my-box-xml"
curl -X DELETE "$BASE/v1/scenes/my-sky"
curl -X DELETE "$BASE/v1/scenes/my-studio"
rm -r "$WORK"
