#!/usr/bin/env python3
"""Irradiance at points of the environment-lit ``scenes/overcast.json``, measured with Mitsuba 3.

The scene is rebuilt as a Mitsuba dict from the project's JSON (whose
conventions are Mitsuba's: ``rectangle`` = [-1,1]^2 in z = 0 with normal +z,
``cube`` = [-1,1]^3, ``sphere`` by centre and radius, ``to_world`` lists applied
in order, ``envmap`` = Mitsuba's lat-long ``envmap`` with its ``to_world`` and
``scale``).  The irradiance is measured as in ``mitsuba_irradiance.py``: for
every point (x,y,z,nx,ny,nz) of a CSV a tiny black disk (radius ``--radius``,
default 1e-3) is centred at p + offset*n (``--offset``, default 1e-4), faces n
and carries an ``irradiancemeter`` on a 1x1 ``hdrfilm`` (box filter); the
pixel value is the irradiance E [W/m^2] averaged over the disk.

Quantities (``--max-depth``), ``path`` integrator:

* ``--max-depth 1``: the meter's first ray segment only, i.e. the environment
  seen directly, occluded by the geometry (Mitsuba's ``max_depth = 1`` counts
  the meter ray as segment 1, like bmc-irradiance's ``--max-depth 1``).  The
  surfaces' materials play no part (nothing but the environment emits), so
  every shape gets a black diffuse BSDF and the glossy sphere needs no
  counterpart.
* ``--max-depth D > 1`` (global illumination): diffuse shapes keep their
  reflectance.  Mitsuba 3 has no BSDF equal to the project's ``glossy``
  (diffuse + normalised Phong lobe), so such a material is refused unless
  ``--glossy-as-diffuse`` is given, which replaces it by a diffuse BSDF with
  its ``diffuse`` colour; ``--write-scene`` then writes that modified scene as
  project JSON so that bmc-irradiance computes exactly the same quantity.

Variant ``scalar_rgb`` (``--variant``; ``llvm_ad_rgb`` aborted in LLVM code
generation on the machine of the published run).  Each point is the mean of ``--k`` independent renders (distinct seeds) of
``--spp`` samples each; the standard error is std(renders)/sqrt(K).

Output: CSV with columns x,y,z,nx,ny,nz,r,g,b,se_r,se_g,se_b (``--out``) and a
JSON with the run's settings and timings beside it (``.meta.json``).

``--envmap-upsample N`` passes the map to Mitsuba with every texel repeated
NxN times.  Mitsuba's envmap places texel row y at theta = pi*y/(H-1) (the
first row on the zenith, the last on the nadir) and interpolates bilinearly;
bmc-irradiance holds each texel constant over theta in [pi*y/H, pi*(y+1)/H].
The direction <-> (u, v) mapping is the same in both.  With the 128x64
overcast map the two readings differ by about 0.1-0.5 % in irradiance;
repeating the texels 16x16 shrinks the difference 16-fold, so that the
comparison tests the light transport rather than the texel convention.
``--unoccluded`` renders nothing: it integrates the map numerically (no
geometry) at each point under both readings.

Commands behind docs/VALIDATION.md ("Environment map: the overcast scene
against Mitsuba 3"), from the repository root, B=target/release/bmc-irradiance,
S=docs/validation/mitsuba_overcast_irradiance.py, D=docs/validation/data:

    $B study-scene --scene scenes/overcast.json --max-depth 1 --samples 16 \
        --seeds 1 --points-out $D/overcast_points.csv
    python $S --points $D/overcast_points.csv --max-depth 1 --spp 131072 --k 8 \
        --jobs 2 --out $D/mitsuba_overcast_direct_native.csv
    python $S --points $D/overcast_points.csv --max-depth 1 --spp 131072 --k 8 \
        --jobs 2 --envmap-upsample 16 --out $D/mitsuba_overcast_direct.csv
    mkdir -p scratch && cp scenes/overcast.exr scratch/
    python $S --points $D/overcast_points.csv --max-depth 16 --glossy-as-diffuse \
        --write-scene scratch/overcast-diffuse.json --spp 131072 --k 8 --jobs 2 \
        --envmap-upsample 16 --out $D/mitsuba_overcast_gi.csv
    printf "x,y,z,nx,ny,nz\n0,50,0,0,1,0\n0,50,0,1,0,0\n0,50,0,0,0,-1\n0,50,0,0,0,1\n" > sky_points.csv
    python $S --points sky_points.csv --unoccluded

(``--write-scene`` writes the scene with the glossy sphere made diffuse; it
names the map relative to itself, hence the copied EXR.)
"""
from __future__ import annotations

import argparse
import copy
import json
import math
import multiprocessing as mp
import os
import sys
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
from cornell_common import irradiance_meter, read_points, write_csv  # noqa: E402

DEFAULT_SCENE = os.path.join(HERE, "..", "..", "scenes", "overcast.json")
VARIANTS = ("scalar_rgb", "llvm_ad_rgb")


# ------------------------------------------------------------ scene translation
def _transform(ops):
    """The project's to_world (one op or a list, applied in order) as a
    mi.ScalarTransform4f.  Must be called after mi.set_variant()."""
    import mitsuba as mi
    t = mi.ScalarTransform4f()
    if ops is None:
        return t
    for op in ops if isinstance(ops, list) else [ops]:
        if len(op) != 1:
            raise ValueError(f"one operation per to_world entry, got {op}")
        (kind, arg), = op.items()
        if kind == "scale":
            s = arg if isinstance(arg, list) else [arg] * 3
            step = mi.ScalarTransform4f().scale(s)
        elif kind == "translate":
            step = mi.ScalarTransform4f().translate(arg)
        elif kind == "rotate":
            step = mi.ScalarTransform4f().rotate(arg["axis"], arg["angle"])
        elif kind == "matrix":
            step = mi.ScalarTransform4f(np.array(arg, dtype=np.float64).tolist())
        else:
            raise ValueError(f"unsupported to_world operation {kind!r}")
        t = step @ t  # later operations apply after earlier ones
    return t


def _rgb(v):
    return {"type": "rgb", "value": [float(x) for x in v]}


def diffuse_scene_json(scene: dict) -> dict:
    """A copy of the project scene with every glossy material replaced by a
    diffuse one of its diffuse colour."""
    s = copy.deepcopy(scene)
    s["materials"] = [{"id": m["id"], "type": "diffuse", "reflectance": m["diffuse"]}
                      if m["type"] == "glossy" else m for m in s["materials"]]
    s["name"] = scene.get("name", "scene") + "-diffuse"
    s["description"] = (scene.get("description", "") +
                        " Glossy materials replaced by diffuse ones of their diffuse colour "
                        "(for the Mitsuba comparison of global illumination).").strip()
    return s


def upsampled_envmap(path: str, factor: int):
    """The lat-long EXR with every texel repeated factor x factor times, as a
    mi.Bitmap.  Mitsuba's envmap treats texel rows as samples at
    theta = pi*y/(H-1) (first row at the zenith, last at the nadir) and
    interpolates bilinearly, while bmc-irradiance treats each texel as constant
    over theta in [pi*y/H, pi*(y+1)/H] (see docs/VALIDATION.md).  Repeating
    the texels makes Mitsuba see the project's piecewise-constant map up to
    1/(2*factor) of a texel."""
    import mitsuba as mi
    a = np.array(mi.Bitmap(path).convert(mi.Bitmap.PixelFormat.RGB, mi.Struct.Type.Float32, False))
    a = np.repeat(np.repeat(a, factor, axis=0), factor, axis=1)
    return mi.Bitmap(np.ascontiguousarray(a, dtype=np.float32), mi.Bitmap.PixelFormat.RGB)


def mitsuba_scene_dict(scene: dict, scene_dir: str, max_depth: int,
                       glossy_as_diffuse: bool = False, envmap_upsample: int = 1) -> dict:
    """The project scene as a Mitsuba dict without a sensor.  At depth 1 all
    BSDFs are irrelevant and become black diffuse.  envmap_upsample > 1: the
    map is passed as an upsampled bitmap (see upsampled_envmap)."""
    d = {"type": "scene", "integrator": {"type": "path", "max_depth": int(max_depth)}}
    mats = {m["id"]: m for m in scene["materials"]}
    for i, sh in enumerate(scene["shapes"]):
        m = mats[sh["material"]]
        if max_depth == 1:
            bsdf = {"type": "diffuse", "reflectance": _rgb([0, 0, 0])}
        elif m["type"] == "diffuse":
            bsdf = {"type": "diffuse", "reflectance": _rgb(m["reflectance"])}
        elif m["type"] == "glossy" and glossy_as_diffuse:
            bsdf = {"type": "diffuse", "reflectance": _rgb(m["diffuse"])}
        else:
            raise ValueError(f"material {m['id']!r} ({m['type']}) has no Mitsuba counterpart "
                             "here; use --max-depth 1 or --glossy-as-diffuse")
        if sh["type"] in ("rectangle", "cube"):
            out = {"type": sh["type"], "to_world": _transform(sh.get("to_world"))}
        elif sh["type"] == "sphere":
            if "to_world" in sh:
                raise ValueError("sphere with to_world not handled")
            out = {"type": "sphere", "center": [float(x) for x in sh["center"]],
                   "radius": float(sh["radius"])}
        else:
            raise ValueError(f"unsupported shape {sh['type']!r}")
        if "emitter" in sh or "emission" in sh:
            raise ValueError("area lights not handled (the overcast scene has none)")
        out["bsdf"] = bsdf
        d[f"shape{i}-{sh.get('id', '')}"] = out
    env = scene.get("environment")
    if env is not None:
        if env["type"] == "envmap":
            path = os.path.join(scene_dir, env["filename"])
            d["environment"] = {"type": "envmap",
                                "scale": float(env.get("scale", 1.0)),
                                "to_world": _transform(env.get("to_world"))}
            if envmap_upsample > 1:
                d["environment"]["bitmap"] = upsampled_envmap(path, envmap_upsample)
            else:
                d["environment"]["filename"] = path
        elif env["type"] == "constant":
            d["environment"] = {"type": "constant", "radiance": _rgb(env["radiance"])}
        else:
            raise ValueError(f"unsupported environment {env['type']!r}")
    return d


def add_meter(d: dict, p, n, radius: float, offset: float) -> dict:
    """Adds the (black) irradiance-meter disk at p + offset*n facing n."""
    d = dict(d)
    d["meter"] = irradiance_meter(p, n, radius, offset)
    return d


def unoccluded_irradiance(scene: dict, scene_dir: str, points, reading: str,
                          n_theta: int = 2048, n_phi: int = 4096) -> np.ndarray:
    """Irradiance [npts,3] from the environment alone (no geometry), by a
    midpoint rule over the sphere, with the map read as bmc-irradiance does
    (``reading='project'``: each texel constant over its (u, v) cell) or as
    Mitsuba's envmap does (``'mitsuba'``: row y at v = y/(H-1), column x at
    u = (x+0.5)/W, bilinear, periodic in u).  Needs mitsuba only to read the EXR."""
    import mitsuba as mi
    env = scene["environment"]
    img = np.array(mi.Bitmap(os.path.join(scene_dir, env["filename"])).convert(
        mi.Bitmap.PixelFormat.RGB, mi.Struct.Type.Float32, False), dtype=np.float64)
    img *= float(env.get("scale", 1.0))
    h, w, _ = img.shape
    m = np.array(_transform(env.get("to_world")).matrix, dtype=np.float64)[:3, :3]
    th = (np.arange(n_theta) + 0.5) / n_theta * np.pi
    ph = (np.arange(n_phi) + 0.5) / n_phi * 2 * np.pi
    t, f = np.meshgrid(th, ph, indexing="ij")
    d = np.stack([np.sin(t) * np.cos(f), np.cos(t), np.sin(t) * np.sin(f)], -1)  # world
    dw = np.sin(t) * (np.pi / n_theta) * (2 * np.pi / n_phi)
    dm = d @ m  # world -> map (m is a rotation: inverse = transpose)
    u = (np.arctan2(dm[..., 0], -dm[..., 2]) / (2 * np.pi)) % 1.0
    v = np.arccos(np.clip(dm[..., 1], -1, 1)) / np.pi
    if reading == "project":
        rad = img[np.minimum((v * h).astype(int), h - 1), np.minimum((u * w).astype(int), w - 1)]
    else:
        padded = np.concatenate([img, img[:, :1]], 1)
        fx, fy = ((u - 0.5 / w) % 1.0) * w, v * (h - 1)
        x0 = np.minimum(np.floor(fx).astype(int), w - 1)
        y0 = np.minimum(np.floor(fy).astype(int), h - 2)
        ax, ay = (fx - x0)[..., None], (fy - y0)[..., None]
        rad = ((1 - ay) * ((1 - ax) * padded[y0, x0] + ax * padded[y0, x0 + 1])
               + ay * ((1 - ax) * padded[y0 + 1, x0] + ax * padded[y0 + 1, x0 + 1]))
    out = []
    for pt in points:
        c = np.clip(d @ np.asarray(pt[3:6], float), 0, None) * dw
        out.append((rad * c[..., None]).sum((0, 1)))
    return np.array(out)


# ----------------------------------------------------------------- workers
_CFG: dict = {}


def _init_worker(cfg):
    import mitsuba as mi
    mi.set_variant(cfg["variant"])
    mi.set_log_level(mi.LogLevel.Warn)
    if cfg["variant"].startswith("llvm"):
        import drjit as dr
        dr.set_thread_count(cfg["threads"])
    _CFG.update(cfg)
    _CFG["base"] = mitsuba_scene_dict(cfg["scene"], cfg["scene_dir"], cfg["max_depth"],
                                      cfg["glossy_as_diffuse"], cfg["envmap_upsample"])


def _point(i):
    """All K renders of point i -> (i, values[K,3], cpu seconds)."""
    import mitsuba as mi
    t0 = time.process_time()
    pt = _CFG["points"][i]
    scene = mi.load_dict(add_meter(_CFG["base"], pt[:3], pt[3:], _CFG["radius"], _CFG["offset"]))
    vals = []
    for j in range(_CFG["k"]):
        img = mi.render(scene, sensor=scene.sensors()[0], spp=_CFG["spp"],
                        seed=_CFG["seed"] * 1_000_000 + 1000 * i + j)
        vals.append(np.array(img, dtype=np.float64).reshape(-1)[:3])
    return i, np.array(vals), time.process_time() - t0


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--scene", default=DEFAULT_SCENE, help="project scene JSON (default scenes/overcast.json)")
    ap.add_argument("--points", required=True, help="CSV x,y,z,nx,ny,nz")
    ap.add_argument("--out", help="output CSV (not needed with --unoccluded)")
    ap.add_argument("--max-depth", type=int, default=1)
    ap.add_argument("--glossy-as-diffuse", action="store_true",
                    help="depth > 1: glossy materials become diffuse with their diffuse colour")
    ap.add_argument("--write-scene", default=None,
                    help="with --glossy-as-diffuse: write the modified scene as project JSON here")
    ap.add_argument("--envmap-upsample", type=int, default=1,
                    help="repeat every envmap texel NxN times, so that Mitsuba's vertex-sampled, "
                         "bilinear reading of the map approaches the project's piecewise-constant one")
    ap.add_argument("--spp", type=int, default=16384, help="samples per render")
    ap.add_argument("--k", type=int, default=8, help="independent renders (seeds) per point")
    ap.add_argument("--radius", type=float, default=1e-3)
    ap.add_argument("--offset", type=float, default=1e-4)
    ap.add_argument("--variant", default=VARIANTS[0], choices=VARIANTS)
    ap.add_argument("--jobs", type=int, default=1, help="worker processes")
    ap.add_argument("--threads", type=int, default=2, help="Dr.Jit threads per worker (llvm variant)")
    ap.add_argument("--seed", type=int, default=1, help="base seed")
    ap.add_argument("--unoccluded", action="store_true",
                    help="no rendering: print the environment's irradiance at each point ignoring all "
                         "geometry, integrated numerically under both readings of the map")
    ap.add_argument("--first", type=int, default=0, help="first point (for partial runs)")
    ap.add_argument("--count", type=int, default=None, help="number of points (default: all)")
    args = ap.parse_args(argv)

    with open(args.scene) as f:
        scene = json.load(f)
    scene_dir = os.path.dirname(os.path.abspath(args.scene))
    if args.write_scene:
        if not args.glossy_as_diffuse:
            sys.exit("--write-scene needs --glossy-as-diffuse")
        with open(args.write_scene, "w") as f:
            json.dump(diffuse_scene_json(scene), f, indent=1)
    pts = read_points(args.points)
    rows = [pt.row() for pt in pts]
    last = len(rows) if args.count is None else min(len(rows), args.first + args.count)
    idx = list(range(args.first, last))

    if not args.unoccluded and not args.out:
        sys.exit("--out is required")
    import mitsuba as mi
    if args.unoccluded:
        mi.set_variant(args.variant)
        sel = [rows[i] for i in idx]
        e_p = unoccluded_irradiance(scene, scene_dir, sel, "project")
        e_m = unoccluded_irradiance(scene, scene_dir, sel, "mitsuba")
        print("point, normal | project reading (r, g, b) | Mitsuba's reading (r, g, b) | ratio - 1")
        for r, a, b in zip(sel, e_p, e_m):
            print(f"{r[:3]}, {r[3:]} | {np.round(a, 5)} | {np.round(b, 5)} | {np.round(100 * (b / a - 1), 3)} %")
        return
    cfg = {"scene": scene, "scene_dir": scene_dir, "max_depth": args.max_depth,
           "glossy_as_diffuse": args.glossy_as_diffuse, "points": rows, "radius": args.radius,
           "offset": args.offset, "variant": args.variant, "threads": args.threads,
           "k": args.k, "spp": args.spp, "seed": args.seed,
           "envmap_upsample": args.envmap_upsample}
    t0 = time.time()
    res, cpu = {}, 0.0
    with mp.get_context("spawn").Pool(args.jobs, initializer=_init_worker, initargs=(cfg,)) as pool:
        for n_done, (i, v, dt) in enumerate(pool.imap_unordered(_point, idx), 1):
            res[i] = v
            cpu += dt
            if n_done % 10 == 0 or n_done == len(idx):
                print(f"{n_done}/{len(idx)} points, {time.time() - t0:.0f} s", flush=True)
    wall = time.time() - t0
    hdr = ["x", "y", "z", "nx", "ny", "nz", "r", "g", "b", "se_r", "se_g", "se_b"]
    out = []
    for i in idx:
        v = res[i]
        out.append(rows[i] + list(v.mean(0)) + list(v.std(0, ddof=1) / math.sqrt(args.k)))
    write_csv(args.out, hdr, out)
    meta = {"command": " ".join(["python", os.path.basename(__file__)] + sys.argv[1:]),
            "mitsuba": mi.__version__, "variant": args.variant, "integrator": "path",
            "max_depth": args.max_depth, "glossy_as_diffuse": args.glossy_as_diffuse,
            "envmap_upsample": args.envmap_upsample, "radius": args.radius, "offset": args.offset, "spp_per_render": args.spp,
            "k": args.k, "points": len(idx), "jobs": args.jobs, "threads": args.threads,
            "wall_s": round(wall, 1), "worker_cpu_s": round(cpu, 1)}
    with open(os.path.splitext(args.out)[0] + ".meta.json", "w") as f:
        json.dump(meta, f, indent=1)
    print(f"wrote {args.out} ({len(idx)} points) in {wall:.0f} s")


if __name__ == "__main__":
    main()
