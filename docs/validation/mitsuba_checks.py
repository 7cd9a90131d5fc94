#!/usr/bin/env python3
"""Sanity checks for the Mitsuba irradiance measurements (mitsuba_irradiance.py).

1. ``dict``     : mi.cornell_box() equals the frozen reference JSON (matrices,
                  reflectances, light radiance).
2. ``furnace``  : a meter disk under a lone ``constant`` emitter of radiance L
                  must read E = pi*L (max_depth 1 and 64).
3. ``analytic`` : direct irradiance from the light rectangle by Lambert's
                  polygon formula (unoccluded) and by a 1000x1000 quadrature
                  over the light with Embree (embreex) shadow rays, compared with the max_depth=1
                  irradiancemeter CSV: shows that max_depth=1 is direct only.
4. ``hide``     : how ``hide_emitters`` treats a directly hit emitter (it lets
                  the ray pass through, so the emitter's reflection is lost).
   ``split``    : plain path max_depth=64 vs the published GI CSVs (black and
                  reflecting light) at a few points.
5. ``meter``    : the meter's own disk does not matter: radius 1e-3 vs 1e-2
                  and offset 1e-4 vs 1e-3 give the same indirect irradiance.

Prints a report in Markdown to stdout (and --out if given).

Example:
    python mitsuba_checks.py --direct-csv data/mitsuba_irradiance_direct.csv --out data/mitsuba_checks.md
"""
from __future__ import annotations

import argparse
import csv
import math
import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from cornell_common import (DEFAULT_POINTS, DEFAULT_REFERENCE, light_radiance,  # noqa: E402
                            load_reference, matrix, polygon_irradiance, read_points,
                            rectangle_corners)
from mitsuba_irradiance import KINDS, meter_scene_dict  # noqa: E402

import mitsuba as mi  # noqa: E402

mi.set_variant("scalar_rgb")


def mean_se(scene, spp, k, seed0):
    v = np.array([np.array(mi.render(scene, sensor=scene.sensors()[0], spp=spp,
                                     seed=seed0 + j)).reshape(-1)[:3] for j in range(k)])
    return v.mean(0), v.std(0, ddof=1) / math.sqrt(k)


def check_dict(ref_path):
    ref = load_reference(ref_path)
    d = mi.cornell_box()
    worst = 0.0
    lines = []
    for key, v in ref.items():
        if key.startswith("_") or not isinstance(v, dict):
            if not key.startswith("_") and v != d.get(key):
                worst = float("inf")
            continue
        if "to_world" in v:
            a = np.array(d[key]["to_world"].matrix, dtype=np.float64)
            b = np.array(v["to_world"]["matrix"])
            worst = max(worst, float(np.abs(a - b).max()))
        if "reflectance" in v:
            a = np.array(d[key]["reflectance"]["value"])
            b = np.array(v["reflectance"]["value"])
            worst = max(worst, float(np.abs(a - b).max()))
            lines.append(f"  - {key} reflectance {b.tolist()}")
        if "emitter" in v:
            a = np.array(d[key]["emitter"]["radiance"]["value"])
            b = np.array(v["emitter"]["radiance"]["value"])
            worst = max(worst, float(np.abs(a - b).max()))
            lines.append(f"  - light radiance {b.tolist()}, light bsdf = {d[key]['bsdf']}")
        if v.get("type") != d[key].get("type"):
            worst = float("inf")
    keys_ok = set(k for k in ref if not k.startswith("_")) == set(d)
    return [f"- mi.cornell_box() vs reference JSON: same keys = {keys_ok}, max |difference| over "
            f"matrices/reflectances/radiance = {worst:.3g}"] + lines


def check_furnace():
    L = [1.0, 2.0, 0.5]
    out = []
    for md in (1, 64):
        d = meter_scene_dict([0, 0, 0], [0.3, 0.5, 0.8], {"type": "path", "max_depth": md})
        d = {"type": "scene", "integrator": d["integrator"], "meter": d["meter"],
             "env": {"type": "constant", "radiance": {"type": "rgb", "value": L}}}
        sc = mi.load_dict(d)
        m, s = mean_se(sc, 4096, 4, 11)
        out.append(f"- furnace (constant emitter L={L}, max_depth={md}): E = {np.round(m, 6).tolist()}, "
                   f"pi*L = {np.round(np.pi * np.array(L), 6).tolist()}")
    return out


def light_quadrature(tris, p, n, corners, ln, grid=1000):
    """Direct irradiance per unit radiance at p (normal n) from the light
    rectangle by midpoint quadrature on a grid x grid lattice over the light,
    E/L = sum V * cos_p * cos_l / r^2 * dA, with the visibility V traced by
    Embree (embreex) against the 36-triangle Cornell box (the light's own two
    triangles excluded).  Returns (E/L, visible fraction)."""
    from embreex import mesh_construction, rtcore_scene
    scene = rtcore_scene.EmbreeScene()
    occl = tris[2:]  # triangles 0,1 are the light itself
    verts = occl.reshape(-1, 3).astype(np.float32)
    mesh = mesh_construction.TriangleMesh(scene, verts, np.arange(len(verts), dtype=np.int32).reshape(-1, 3))
    a, b, d = corners[0], corners[1], corners[3]
    u = (np.arange(grid) + 0.5) / grid
    uu, vv = np.meshgrid(u, u, indexing="ij")
    q = a + uu.reshape(-1, 1) * (b - a) + vv.reshape(-1, 1) * (d - a)
    dA = np.linalg.norm(np.cross(b - a, d - a)) / grid ** 2
    o = p + 1e-4 * n
    w = q - o
    r = np.linalg.norm(w, axis=1)
    wd = w / r[:, None]
    cos_p = np.clip(wd @ n, 0, None)
    cos_l = np.clip(-(wd @ ln), 0, None)
    dist = scene.run(np.repeat(o[None].astype(np.float32), len(q), 0), wd.astype(np.float32),
                     query="DISTANCE")
    vis = dist >= r.astype(np.float32) * (1 - 1e-5)
    del mesh
    e = float(np.sum(vis * cos_p * cos_l / r ** 2) * dA)
    return e, float(vis[cos_p * cos_l > 0].mean()) if np.any(cos_p * cos_l > 0) else float("nan")


def check_analytic(points, direct_csv, ref_path):
    from cornell_common import cornell_triangles
    ref = load_reference(ref_path)
    L = light_radiance(ref)
    m = matrix(ref, "light")
    corners = rectangle_corners(m)
    ln = np.cross(corners[1] - corners[0], corners[3] - corners[0])
    ln /= np.linalg.norm(ln)  # emitting side of the light (+z local)
    tris, owners = cornell_triangles(ref)
    assert owners[0] == owners[1] == "light"
    rows = list(csv.DictReader(open(direct_csv))) if direct_csv and os.path.exists(direct_csv) else None
    out = ["| point | normal | light visible | Lambert formula, unoccluded (r,g,b) | quadrature with visibility (r,g,b) "
           "| Mitsuba max_depth=1 (r,g,b) | Mitsuba/quadrature (g) | z vs quadrature (g) |",
           "|---|---|---|---|---|---|---|---|"]
    for i, pt in enumerate(points):
        in_front = np.dot(pt.p - corners[0], ln) > 0
        side = [np.dot(c - pt.p, pt.n) > 0 for c in corners]
        if not in_front or not any(side):
            lam = 0.0 * L
        elif all(side):
            lam = polygon_irradiance(pt.p, pt.n, corners) * L
        else:
            lam = None
        eq, vis = light_quadrature(tris, pt.p, pt.n, corners, ln) if in_front else (0.0, float("nan"))
        eq = eq * L
        mit = se = None
        ratio = z = "-"
        if rows:
            r = rows[i]
            mit = np.array([float(r[c]) for c in "rgb"])
            se = np.array([float(r["se_" + c]) for c in "rgb"])
            if eq[1] > 0:
                ratio = f"{mit[1] / eq[1]:.4f}"
                z = f"{(mit[1] - eq[1]) / se[1]:+.2f}"
        fmt = lambda v: "-" if v is None else str(np.round(v, 5).tolist())
        out.append(f"| {pt.p.tolist()} | {pt.n.tolist()} | {vis:.3f} | {fmt(lam)} | {fmt(eq)} | {fmt(mit)} | {ratio} | {z} |")
    return out


def check_split(points, idx, spp_full, k, gi_black_csv, gi_csv):
    """Plain path max_depth=64 (K renders) vs the published GI CSVs (black and reflecting light)."""
    out = ["| point | light | plain max_depth=64 (r,g,b) ± se | published GI (r,g,b) ± se | z (r,g,b) |",
           "|---|---|---|---|---|"]
    for label, black, path in (("black", True, gi_black_csv), ("reflecting", False, gi_csv)):
        if not path or not os.path.exists(path):
            continue
        rows = list(csv.DictReader(open(path)))
        for i in idx:
            pt = points[i]
            sc = mi.load_dict(meter_scene_dict(pt.p, pt.n, KINDS["gi_full"], black_light=black))
            mf, sf = mean_se(sc, spp_full, k, 100 + 1000 * i)
            mp_ = np.array([float(rows[i][c]) for c in "rgb"])
            sp_ = np.array([float(rows[i]["se_" + c]) for c in "rgb"])
            z = (mf - mp_) / np.sqrt(sf ** 2 + sp_ ** 2)
            out.append(f"| {pt.p.tolist()} n={pt.n.tolist()} | {label} | {np.round(mf, 5).tolist()} ± "
                       f"{np.round(sf, 5).tolist()} | {np.round(mp_, 5).tolist()} ± {np.round(sp_, 5).tolist()} | "
                       f"{np.round(z, 2).tolist()} |")
    return out


def check_hide_emitters():
    """Does hide_emitters kill a depth-0 path at an emitter or let it pass through?"""
    T = mi.ScalarTransform4f
    d = meter_scene_dict([0, 0, 0], [0, 0, 1], {"type": "path", "max_depth": 64, "hide_emitters": True})
    sc = mi.load_dict({
        "type": "scene", "integrator": d["integrator"], "meter": d["meter"],
        "A": {"type": "rectangle", "to_world": T().translate([0, 0, 1]).rotate([1, 0, 0], 180).scale(1000),
              "bsdf": {"type": "diffuse", "reflectance": {"type": "rgb", "value": 0.0}},
              "emitter": {"type": "area", "radiance": {"type": "rgb", "value": 1.0}}},
        "C": {"type": "rectangle", "to_world": T().translate([0, 0, 2]).rotate([1, 0, 0], 180).scale(1000),
              "bsdf": {"type": "diffuse", "reflectance": {"type": "rgb", "value": 0.5}}},
        "P": {"type": "point", "position": [0, 0, 1.5], "intensity": {"type": "rgb", "value": 10.0}}})
    m, _ = mean_se(sc, 20000, 2, 1)
    return [f"- hide_emitters test: meter under a black emitting plane A (z=1) with a lit diffuse plane C "
            f"behind it (z=2): E = {m[0]:.4f} (0 would mean the path stops at the hidden emitter; > 0 means "
            f"the ray passes through the emitter and sees C, i.e. hide_emitters treats a directly hit emitter "
            f"as invisible, so its reflection at depth 0 is lost)"]


def check_meter(points, i, spp, k):
    pt = points[i]
    out = ["| meter radius | offset | indirect E (r,g,b) ± se |", "|---|---|---|"]
    for radius, offset in ((1e-3, 1e-4), (1e-2, 1e-4), (1e-3, 1e-3)):
        sc = mi.load_dict(meter_scene_dict(pt.p, pt.n, KINDS["indirect"], radius, offset))
        m, s = mean_se(sc, spp, k, 500)
        out.append(f"| {radius:g} | {offset:g} | {np.round(m, 5).tolist()} ± {np.round(s, 5).tolist()} |")
    return out


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--points", default=DEFAULT_POINTS)
    ap.add_argument("--reference", default=DEFAULT_REFERENCE)
    ap.add_argument("--direct-csv", default="data/mitsuba_irradiance_direct.csv")
    ap.add_argument("--gi-black-csv", default="data/mitsuba_irradiance_gi_blacklight.csv")
    ap.add_argument("--gi-csv", default="data/mitsuba_irradiance_gi.csv")
    ap.add_argument("--checks", default="dict,furnace,analytic,hide,split,meter")
    ap.add_argument("--split-points", default="0,6,12")
    ap.add_argument("--split-spp", type=int, default=400000, help="spp per plain render")
    ap.add_argument("--k", type=int, default=8)
    ap.add_argument("--out", default=None)
    args = ap.parse_args(argv)
    pts = read_points(args.points)
    checks = args.checks.split(",")
    lines = [f"Mitsuba {mi.__version__}, variant scalar_rgb", ""]
    if "dict" in checks:
        lines += check_dict(args.reference) + [""]
    if "furnace" in checks:
        lines += check_furnace() + [""]
    if "analytic" in checks:
        lines += ["Direct irradiance: Lambert's polygon formula (unoccluded) and a 1000x1000 midpoint quadrature "
                  "over the light with Embree shadow rays, vs the Mitsuba irradiancemeter with path max_depth=1:", ""]
        lines += check_analytic(pts, args.direct_csv, args.reference) + [""]
    if "hide" in checks:
        lines += check_hide_emitters() + [""]
    if "split" in checks:
        lines += [f"Published GI vs a plain path max_depth=64 run (K={args.k} renders of {args.split_spp} spp):", ""]
        lines += check_split(pts, [int(x) for x in args.split_points.split(",")], args.split_spp, args.k,
                             args.gi_black_csv, args.gi_csv) + [""]
    if "meter" in checks:
        lines += ["Meter geometry check at point 0 (indirect, 40000 spp x 8 renders):", ""]
        lines += check_meter(pts, 0, 40000, 8) + [""]
    text = "\n".join(lines)
    print(text)
    if args.out:
        with open(args.out, "w") as f:
            f.write(text + "\n")


if __name__ == "__main__":
    main()
