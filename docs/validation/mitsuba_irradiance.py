#!/usr/bin/env python3
"""Irradiance at points in Mitsuba 3's Cornell box, measured with Mitsuba itself.

For every point (x,y,z,nx,ny,nz) of a CSV, a tiny disk (radius ``--radius``,
default 1e-3) is centred at p + offset*n (``--offset``, default 1e-4), facing
n, and carries an ``irradiancemeter`` sensor on a 1x1 ``hdrfilm`` with a box
filter.  Mitsuba's irradiancemeter samples a uniform point on its shape and a
cosine-distributed direction about the normal and weights the returned
radiance by pi, so the pixel value is the irradiance E [W/m^2] averaged over
the disk (sanity-checked by ``mitsuba_checks.py``: furnace test gives pi*L).

Quantities (``--kinds``), all with the ``path`` integrator in ``scalar_rgb``:

* ``direct``   : path, ``max_depth = 1`` (only the radiance emitted by the surface
  the meter's ray hits first = direct irradiance from the light);
* ``indirect`` : path, ``max_depth = 64`` (``rr_depth`` default 5) with
  ``hide_emitters = true``.  CAUTION: Mitsuba 3.9 implements hide_emitters by
  letting a depth-0 ray pass *through* an emitter (verified), so this is
  E_gi - E_direct only when the light does not reflect: use it with
  ``--black-light`` (then the only error is the radiance of the ceiling
  1 cm behind the light, seen through it: ~1e-5 relative).  With the
  default reflecting light it misses the light's reflection at depth 0;
* ``lightrefl``: the light's reflection, E_gi(reflecting light) -
  E_gi(black light), from paired plain ``max_depth = 64`` renders with the
  same seed (common random numbers: both follow identical paths until one
  reflects off the light, so the large direct-light noise cancels);
* ``gi_full``  : plain path ``max_depth = 64`` (used only for checks).

GI with the black light = direct + indirect(--black-light); GI of
mi.cornell_box() (reflecting light) = that + lightrefl (``--base-csv``).
Independent runs; standard errors add in quadrature.  The split is used for
efficiency: the meter's first ray has no next-event estimation, so the
direct part needs ~1e7 cheap 1-ray samples per point, the rest ~1e5 paths.

Each quantity is the mean of K independent renders (distinct seeds); the
standard error is std(renders)/sqrt(K).  The samples per render are chosen
from a pilot run so that the relative standard error of the mean is about
``--target-rse`` in every non-zero channel (capped by ``--max-spp``).

Outputs (in --out-dir): mitsuba_irradiance_<kind>[_blacklight].csv,
mitsuba_irradiance_gi[_blacklight].csv (columns
x,y,z,nx,ny,nz,r,g,b,se_r,se_g,se_b; E in W/m^2) and
mitsuba_irradiance_meta[_blacklight].json.

Example (the three runs behind the published tables):
    python mitsuba_irradiance.py --kinds direct --out-dir data
    python mitsuba_irradiance.py --kinds indirect --black-light \
        --direct-csv data/mitsuba_irradiance_direct.csv --out-dir data
    python mitsuba_irradiance.py --kinds lightrefl \
        --base-csv data/mitsuba_irradiance_gi_blacklight.csv \
        --rse-reference data/mitsuba_irradiance_gi_blacklight.csv --out-dir data
"""
from __future__ import annotations

import argparse
import json
import math
import multiprocessing as mp
import os
import sys
import time

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from cornell_common import DEFAULT_POINTS, irradiance_meter, read_points, write_csv  # noqa: E402

VARIANT = "scalar_rgb"
KINDS = {
    # name: integrator dict
    "direct": {"type": "path", "max_depth": 1},
    "indirect": {"type": "path", "max_depth": 64, "hide_emitters": True},
    "gi_full": {"type": "path", "max_depth": 64},
    # paired difference gi_full(reflecting light) - gi_full(black light), same seeds
    "lightrefl": {"type": "path", "max_depth": 64},
}


def meter_scene_dict(p, n, integrator: dict, radius: float = 1e-3,
                     offset: float = 1e-4, meter_bsdf: dict | None = None,
                     black_light: bool = False):
    """mi.cornell_box() with its camera removed and an irradiance-meter disk at
    p + offset*n facing n (the disk is black: reflectance 0).  With
    black_light the light rectangle's white BSDF is replaced by a black one
    (a non-reflecting light, as Radiance's ``light`` material).  Must be
    called after mi.set_variant()."""
    import mitsuba as mi
    d = mi.cornell_box()
    del d["sensor"]
    if black_light:
        d["light"]["bsdf"] = {"type": "diffuse", "reflectance": {"type": "rgb", "value": 0.0}}
    d["integrator"] = dict(integrator)
    d["meter"] = irradiance_meter(p, n, radius, offset, meter_bsdf)
    return d


# ----------------------------------------------------------------- workers
_SCENES: dict = {}
_CFG: dict = {}


def _init_worker(cfg):
    import mitsuba as mi
    mi.set_variant(cfg.get("variant", VARIANT))
    mi.set_log_level(mi.LogLevel.Warn)
    _CFG.update(cfg)


def _render(task):
    """task = (point_index, kind, seed, spp) -> (task, rgb, cpu_seconds)."""
    import mitsuba as mi
    i, kind, seed, spp = task
    variants = [(kind, _CFG["black_light"])] if kind != "lightrefl" else [(kind, False), (kind, True)]
    vals = []
    t0 = time.process_time()
    for kd, black in variants:
        key = (i, kd, black)
        if key not in _SCENES:
            pt = _CFG["points"][i]
            _SCENES[key] = mi.load_dict(meter_scene_dict(
                pt[:3], pt[3:], KINDS[kd], _CFG["radius"], _CFG["offset"], black_light=black))
        scene = _SCENES[key]
        img = mi.render(scene, sensor=scene.sensors()[0], spp=int(spp), seed=int(seed))
        vals.append(np.array(img, dtype=np.float64).reshape(-1)[:3])
    dt = time.process_time() - t0
    # lightrefl: common random numbers -> both renders follow identical paths until a path
    # reflects off the light, so the difference isolates the light's reflection
    return task, (vals[0] - vals[1] if len(vals) == 2 else vals[0]), dt


def run_tasks(pool, tasks):
    out = {}
    cpu = 0.0
    for task, rgb, dt in pool.imap_unordered(_render, tasks):
        out[task] = rgb
        cpu += dt
    return out, cpu


def estimate(pool, npts, kind, spp_list, k, seed0):
    """K renders per point; returns mean[npts,3], se[npts,3], cpu seconds."""
    tasks = [(i, kind, seed0 + 1000 * i + j, spp_list[i])
             for j in range(k) for i in range(npts)]
    res, cpu = run_tasks(pool, tasks)
    mean = np.zeros((npts, 3))
    se = np.zeros((npts, 3))
    for i in range(npts):
        v = np.array([res[(i, kind, seed0 + 1000 * i + j, spp_list[i])] for j in range(k)])
        mean[i] = v.mean(0)
        se[i] = v.std(0, ddof=1) / math.sqrt(k)
    return mean, se, cpu


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--points", default=DEFAULT_POINTS)
    ap.add_argument("--out-dir", default="data")
    ap.add_argument("--kinds", default="direct", help="comma list of: " + ",".join(KINDS))
    ap.add_argument("--radius", type=float, default=1e-3)
    ap.add_argument("--offset", type=float, default=1e-4)
    ap.add_argument("--k", type=int, default=16, help="independent renders (seeds) per point")
    ap.add_argument("--target-rse", type=float, default=0.0025)
    ap.add_argument("--pilot-k", type=int, default=8)
    ap.add_argument("--pilot-spp", default="direct=200000,indirect=2000,gi_full=20000,lightrefl=20000")
    ap.add_argument("--max-spp", default="direct=8000000,indirect=200000,gi_full=2000000,lightrefl=1000000",
                    help="cap on samples per render")
    ap.add_argument("--min-spp", type=int, default=1024)
    ap.add_argument("--safety", type=float, default=1.5, help="factor on the planned sample count")
    ap.add_argument("--jobs", type=int, default=2, help="worker processes")
    ap.add_argument("--seed", type=int, default=1, help="base seed")
    ap.add_argument("--direct-csv", default=None,
                    help="reuse this direct CSV (same points) to form GI when --kinds lacks 'direct'")
    ap.add_argument("--base-csv", default=None,
                    help="with --kinds lightrefl: GI with a black light; writes mitsuba_irradiance_gi.csv "
                         "= base + lightrefl")
    ap.add_argument("--rse-reference", default=None,
                    help="CSV whose r,g,b set the scale of --target-rse (used for lightrefl, whose own "
                         "value is small); default: the quantity itself")
    ap.add_argument("--black-light", action="store_true",
                    help="light rectangle does not reflect (output names get suffix _blacklight)")
    args = ap.parse_args(argv)

    pts = read_points(args.points)
    rows = [pt.row() for pt in pts]
    npts = len(pts)
    kinds = args.kinds.split(",")
    pilot_spp = dict(kv.split("=") for kv in args.pilot_spp.split(","))
    max_spp = dict(kv.split("=") for kv in args.max_spp.split(","))
    os.makedirs(args.out_dir, exist_ok=True)

    import mitsuba as mi
    mi.set_variant(VARIANT)
    meta = {"command": " ".join([os.path.basename(sys.executable)] + sys.argv),
            "mitsuba": mi.__version__, "variant": VARIANT, "radius": args.radius,
            "offset": args.offset, "k": args.k, "target_rse": args.target_rse,
            "jobs": args.jobs, "kinds": {}}
    cfg = {"points": rows, "radius": args.radius, "offset": args.offset, "variant": VARIANT,
           "black_light": args.black_light}
    sfx = "_blacklight" if args.black_light else ""
    meta["black_light"] = args.black_light
    ctx = mp.get_context("spawn")
    results = {}
    with ctx.Pool(args.jobs, initializer=_init_worker, initargs=(cfg,)) as pool:
        for kind in kinds:
            t0 = time.time()
            ps = int(pilot_spp[kind])
            seed_pilot = args.seed * 10_000_000 + 5_000_000 + 100_000 * list(KINDS).index(kind)
            m0, s0, cpu0 = estimate(pool, npts, kind, [ps] * npts, args.pilot_k, seed_pilot)
            scale = m0
            if args.rse_reference:
                import csv as _csv
                scale = np.array([[float(r[c]) for c in "rgb"] for r in _csv.DictReader(open(args.rse_reference))])
            spp = []
            for i in range(npts):
                need = 0.0
                for mc, sc in zip(scale[i], s0[i]):
                    if mc > 0 and sc > 0:
                        # relative variance of ONE sample = (sc/mc)^2 * pilot_k * ps
                        rv = (sc / mc) ** 2 * args.pilot_k * ps
                        need = max(need, rv / args.target_rse ** 2)
                per = int(math.ceil(args.safety * need / args.k))
                per = max(args.min_spp, min(int(max_spp[kind]), per))
                spp.append(int(2 ** math.ceil(math.log2(per))) if per < 4096 else int(math.ceil(per / 4096) * 4096))
            print(f"[{kind}] pilot done in {time.time()-t0:.1f}s; spp/render: {spp}", flush=True)
            t1 = time.time()
            seed_main = args.seed * 10_000_000 + 100_000 * list(KINDS).index(kind)
            m, s, cpu = estimate(pool, npts, kind, spp, args.k, seed_main)
            wall = time.time() - t1
            results[kind] = (m, s)
            meta["kinds"][kind] = {
                "integrator": KINDS[kind], "spp_per_render": spp,
                "total_samples": int(sum(spp) * args.k),
                "pilot_wall_s": round(t1 - t0, 2), "pilot_cpu_s": round(cpu0, 2),
                "wall_s": round(wall, 2), "cpu_s": round(cpu, 2)}
            print(f"[{kind}] main done: wall {wall:.1f}s, cpu {cpu:.1f}s", flush=True)
            hdr = ["x", "y", "z", "nx", "ny", "nz", "r", "g", "b", "se_r", "se_g", "se_b"]
            write_csv(os.path.join(args.out_dir, f"mitsuba_irradiance_{kind}{sfx}.csv"), hdr,
                      [rows[i] + list(m[i]) + list(s[i]) for i in range(npts)])
            for i in range(npts):
                rse = [f"{sc/mc*100:.2f}%" if mc > 0 else "-" for mc, sc in zip(scale[i], s[i])]
                print(f"  {rows[i]}  E={np.round(m[i], 5)}  rse={rse}", flush=True)
            with open(os.path.join(args.out_dir, f"mitsuba_irradiance_meta{sfx}.json"), "w") as f:
                json.dump(meta, f, indent=1)

    if "lightrefl" in results and args.base_csv:
        import csv as _csv
        rr = list(_csv.DictReader(open(args.base_csv)))
        mb = np.array([[float(r[c]) for c in "rgb"] for r in rr])
        sb = np.array([[float(r["se_" + c]) for c in "rgb"] for r in rr])
        ml, sl = results["lightrefl"]
        hdr = ["x", "y", "z", "nx", "ny", "nz", "r", "g", "b", "se_r", "se_g", "se_b"]
        write_csv(os.path.join(args.out_dir, "mitsuba_irradiance_gi.csv"), hdr,
                  [rows[i] + list(mb[i] + ml[i]) + list(np.sqrt(sb[i] ** 2 + sl[i] ** 2)) for i in range(npts)])
        meta["gi"] = f"{args.base_csv} + lightrefl (independent runs), se added in quadrature"
        with open(os.path.join(args.out_dir, f"mitsuba_irradiance_meta{sfx}.json"), "w") as f:
            json.dump(meta, f, indent=1)
        print("GI (reflecting light) written")
    if "direct" not in results and args.direct_csv:
        import csv as _csv
        rr = list(_csv.DictReader(open(args.direct_csv)))
        results["direct"] = (np.array([[float(r[c]) for c in "rgb"] for r in rr]),
                             np.array([[float(r["se_" + c]) for c in "rgb"] for r in rr]))
        meta["direct_from"] = args.direct_csv
    if "direct" in results and "indirect" in results and not args.black_light:
        print("NOTE: not writing GI = direct + indirect: with a reflecting light hide_emitters misses the "
              "light's reflection at depth 0 (see the docstring); use --black-light + lightrefl")
    elif "direct" in results and "indirect" in results:
        md, sd = results["direct"]
        mi_, si_ = results["indirect"]
        m = md + mi_
        s = np.sqrt(sd ** 2 + si_ ** 2)
        hdr = ["x", "y", "z", "nx", "ny", "nz", "r", "g", "b", "se_r", "se_g", "se_b"]
        write_csv(os.path.join(args.out_dir, f"mitsuba_irradiance_gi{sfx}.csv"), hdr,
                  [rows[i] + list(m[i]) + list(s[i]) for i in range(npts)])
        meta["gi"] = "direct + indirect (independent runs), se added in quadrature"
        with open(os.path.join(args.out_dir, f"mitsuba_irradiance_meta{sfx}.json"), "w") as f:
            json.dump(meta, f, indent=1)
        print("GI written")


if __name__ == "__main__":
    main()
