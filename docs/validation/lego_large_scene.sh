#!/usr/bin/env bash
# The large-scene figures of docs/BENCHMARKS.md ("A 2-million-triangle scene"),
# ours and Mitsuba 3's in one run on the tutorials' lego folder: load time,
# resident memory once loaded, and the scene path-traced at 512², 64 spp, at
# its own max_depth (8). Mitsuba runs from a throwaway venv (MITSUBA_PYTHON,
# `pip install mitsuba numpy`), never as a dependency of the project.
#
#   bash docs/validation/lego_large_scene.sh /path/to/mitsuba-tutorials/scenes/lego
set -euo pipefail
LEGO=${1:?the tutorials\' lego folder}
PY=${MITSUBA_PYTHON:-python3}
BIN=${BIN:-target/release/bmc-irradiance}
OUT=$(mktemp -d)
# The same picture from both: Mitsuba's Gaussian filter becomes a box, as
# ours approximates it (the test of image agreement uses the same edit).
mkdir -p "$OUT/served" && cp -r "$LEGO" "$OUT/served/lego"
SCENE="$OUT/served/lego/box_filter.xml"
sed 's/<rfilter type="gaussian"\/>/<rfilter type="box"\/>/' "$LEGO/scene.xml" > "$SCENE"
echo "== ours: load (in-process), then resident memory of a service holding only lego"
"$BIN" render --scene "$SCENE" --method path --spp 1 --param resx=8 --param resy=8 \
    --out "$OUT/load.exr" | grep loaded
# The folder holds scene.xml and box_filter.xml; scene.xml is its scene.
BMC_SCENES__DIR="$OUT/served" BMC_CACHE__DATA_DIR="$OUT/data" BMC_SERVER__BIND=127.0.0.1:18499 \
    "$BIN" serve > "$OUT/serve.log" 2>&1 &
SERVER=$!
until curl -sf http://127.0.0.1:18499/v1/scenes/lego > /dev/null; do sleep 0.2; done
grep -E "VmRSS|VmHWM" /proc/$SERVER/status
kill $SERVER; wait $SERVER || true
echo "== mitsuba (scalar_rgb): load, resident memory after loading"
"$PY" - "$SCENE" <<'PY'
import sys, time
import mitsuba as mi
mi.set_variant("scalar_rgb")
before = time.time()
scene = mi.load_file(sys.argv[1])
print(f"mitsuba loaded in {time.time() - before:.2f} s")
print("".join(l for l in open("/proc/self/status") if l.startswith(("VmRSS", "VmHWM"))), end="")
PY
echo "== path traced 512², 64 spp, max_depth 8"
/usr/bin/time -f "ours: %e s wall" "$BIN" render --scene "$SCENE" --method path --spp 64 \
    --out "$OUT/ours.exr"
"$PY" "$(dirname "$0")/mitsuba_render.py" "$SCENE" 64 "$OUT/mitsuba.exr"
"$BIN" compare "$OUT/ours.exr" "$OUT/mitsuba.exr" || true
echo "images in $OUT"
