#!/usr/bin/env python3
"""Add the light rectangle's own reflection to Mitsuba GI irradiance (reflecting light).

In mi.cornell_box() the light rectangle also carries the white diffuse BSDF.
``mitsuba_irradiance.py --kinds indirect`` (path, max_depth 64,
hide_emitters) lets the meter's first ray pass *through* an emitter, so it
misses exactly one term: radiance reflected by the light's surface towards
the meter on the meter's first segment,

    M(p) = int_light V(p,y) * (rho_white/pi) * E_in(y) * cos_p * cos_y / r^2 dA(y),

where E_in(y) is the irradiance arriving at the light's emitting (downward)
side.  E_in is smooth over the small light, so it is measured with Mitsuba
irradiance meters (facing -y, 1e-4 below the light, hide_emitters run, which
is exact there because no emitter is visible from the light's front) on a
``--grid`` x ``--grid`` lattice of points on the light and interpolated
bilinearly; M is then a 400x400 midpoint quadrature over the light with
Embree (embreex) visibility.  Output:

  mitsuba_irradiance_lightrefl.csv  M(p) with its standard error
  mitsuba_irradiance_light_ein.csv  E_in at the lattice points
  mitsuba_irradiance_gi.csv         direct + indirect(hidden) + M   (GI of mi.cornell_box())

Example:
    python mitsuba_light_reflection.py --out-dir data
"""
from __future__ import annotations

import argparse
import csv
import multiprocessing as mp
import os
import sys
import time

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import mitsuba_irradiance as MI  # noqa: E402
from cornell_common import (DEFAULT_POINTS, DEFAULT_REFERENCE, cornell_triangles,  # noqa: E402
                            load_reference, matrix, read_points, rectangle_corners,
                            reflectance, write_csv)


def read_rgb(path):
    rows = list(csv.DictReader(open(path)))
    return (np.array([[float(r[c]) for c in "rgb"] for r in rows]),
            np.array([[float(r["se_" + c]) for c in "rgb"] for r in rows]))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--points", default=DEFAULT_POINTS)
    ap.add_argument("--reference", default=DEFAULT_REFERENCE)
    ap.add_argument("--out-dir", default="data")
    ap.add_argument("--grid", type=int, default=3)
    ap.add_argument("--spp", type=int, default=65536, help="spp per render for E_in")
    ap.add_argument("--k", type=int, default=8)
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--quad", type=int, default=400)
    args = ap.parse_args(argv)

    ref = load_reference(args.reference)
    corners = rectangle_corners(matrix(ref, "light"))
    ln = np.cross(corners[1] - corners[0], corners[3] - corners[0])
    ln /= np.linalg.norm(ln)
    a, b, d = corners[0], corners[1], corners[3]
    g = args.grid
    uv = [((i + 0.5) / g, (j + 0.5) / g) for i in range(g) for j in range(g)]
    lpts = [list(a + u * (b - a) + v * (d - a)) + list(ln) for u, v in uv]

    # E_in on the light's lattice (meters 1e-4 below the light, facing down)
    t0 = time.time()
    cfg = {"points": [[float(x) for x in r] for r in lpts], "radius": 1e-3, "offset": 1e-4,
           "variant": MI.VARIANT, "black_light": False}
    with mp.get_context("spawn").Pool(args.jobs, initializer=MI._init_worker, initargs=(cfg,)) as pool:
        m_in, s_in, cpu = MI.estimate(pool, len(lpts), "indirect", [args.spp] * len(lpts), args.k, 77_000_000)
    wall = time.time() - t0
    write_csv(os.path.join(args.out_dir, "mitsuba_irradiance_light_ein.csv"),
              ["x", "y", "z", "nx", "ny", "nz", "r", "g", "b", "se_r", "se_g", "se_b"],
              [lpts[i] + list(m_in[i]) + list(s_in[i]) for i in range(len(lpts))])
    print(f"E_in on the light ({g}x{g}): wall {wall:.1f} s, cpu {cpu:.1f} s")
    for i in range(len(lpts)):
        print("  ", np.round(lpts[i][:3], 4), np.round(m_in[i], 5), np.round(s_in[i], 5))

    # bilinear interpolation of E_in over the light (constant extrapolation to the edges)
    Ein = m_in.reshape(g, g, 3)
    Sin = s_in.reshape(g, g, 3)
    n = args.quad
    uq = (np.arange(n) + 0.5) / n
    gu = (np.arange(g) + 0.5) / g

    def interp(field):
        out = np.zeros((n, n, 3))
        for c in range(3):
            tmp = np.array([np.interp(uq, gu, field[:, j, c]) for j in range(g)]).T  # n x g
            out[:, :, c] = np.array([np.interp(uq, gu, tmp[i]) for i in range(n)])
        return out
    E_q = interp(Ein)
    uu, vv = np.meshgrid(uq, uq, indexing="ij")
    q = a + uu.reshape(-1, 1) * (b - a) + vv.reshape(-1, 1) * (d - a)
    dA = np.linalg.norm(np.cross(b - a, d - a)) / n ** 2
    rho = reflectance(ref, "light")

    from embreex import mesh_construction, rtcore_scene
    tris, owners = cornell_triangles(ref)
    scene = rtcore_scene.EmbreeScene()
    verts = tris[2:].reshape(-1, 3).astype(np.float32)
    mesh = mesh_construction.TriangleMesh(scene, verts, np.arange(len(verts), dtype=np.int32).reshape(-1, 3))

    pts = read_points(args.points)
    md, sd = read_rgb(os.path.join(args.out_dir, "mitsuba_irradiance_direct.csv"))
    mh, sh = read_rgb(os.path.join(args.out_dir, "mitsuba_irradiance_indirect.csv"))
    rows_m, rows_gi = [], []
    for i, pt in enumerate(pts):
        o = pt.p + 1e-4 * pt.n
        w = q - o
        r = np.linalg.norm(w, axis=1)
        wd = w / r[:, None]
        cos_p = np.clip(wd @ pt.n, 0, None)
        cos_l = np.clip(-(wd @ ln), 0, None)
        if np.dot(o - a, ln) <= 0:
            M = np.zeros(3)
            sM = np.zeros(3)
        else:
            dist = scene.run(np.repeat(o[None].astype(np.float32), len(q), 0), wd.astype(np.float32),
                             query="DISTANCE")
            vis = dist >= r.astype(np.float32) * (1 - 1e-5)
            wgt = (vis * cos_p * cos_l / r ** 2 * dA).reshape(n, n)
            M = rho / np.pi * np.einsum("ij,ijc->c", wgt, E_q)
            # SE: E_in lattice errors are independent; propagate through the (linear) weights
            cell = np.zeros((g, g))
            for gi in range(g):
                for gj in range(g):
                    e = np.zeros((g, g, 1))
                    e[gi, gj, 0] = 1.0
                    cell[gi, gj] = np.sum(wgt * interp(np.repeat(e, 3, axis=2))[:, :, 0])
            sM = rho / np.pi * np.sqrt(np.einsum("ij,ijc->c", cell ** 2, Sin ** 2))
        rows_m.append(pt.row() + list(M) + list(sM))
        gi_v = md[i] + mh[i] + M
        gi_s = np.sqrt(sd[i] ** 2 + sh[i] ** 2 + sM ** 2)
        rows_gi.append(pt.row() + list(gi_v) + list(gi_s))
        print(i, pt.row(), "M =", np.round(M, 5), "GI =", np.round(gi_v, 5))
    hdr = ["x", "y", "z", "nx", "ny", "nz", "r", "g", "b", "se_r", "se_g", "se_b"]
    write_csv(os.path.join(args.out_dir, "mitsuba_irradiance_lightrefl.csv"), hdr, rows_m)
    write_csv(os.path.join(args.out_dir, "mitsuba_irradiance_gi.csv"), hdr, rows_gi)
    del mesh


if __name__ == "__main__":
    main()
