#!/usr/bin/env python3
"""Embree 4 (PyPI ``embreex``) timed on exactly the rays our tracer traces.

``cargo run --release --example ray_throughput -- --dump DIR`` writes, per
bundled scene, its triangles and two ray sets as little-endian f32 rows
(see that example). This script builds one Embree scene from the triangles
and times, on one thread and in process CPU time (the machine may be
shared), closest hit (``query='INTERSECT'``, rtcIntersect1 per ray) and
shadow rays (``query='OCCLUDED'`` with each ray's t_max as its ``dists``,
rtcOccluded1 per ray). Every figure is the best of ``--repeats`` calls;
the BVH build is excluded (a warm-up call commits the scene).

It prints the hit fractions beside the rates: they must agree with the
ones ``ray_throughput`` prints for the same rays, which shows both tracers
answered the same question.

Measurement only: embreex lives in a throwaway venv, never in the project:
    python3 -m venv /tmp/embree-venv && /tmp/embree-venv/bin/pip install embreex numpy
    /tmp/embree-venv/bin/python docs/validation/embree_same_rays.py DIR [--repeats 5]
"""
from __future__ import annotations

import argparse
import os
import sys
import time

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from embree_throughput import build_scene  # noqa: E402


def load_rows(path: str, width: int) -> np.ndarray:
    return np.fromfile(path, dtype="<f4").reshape(-1, width)


def best_cpu(call, repeats: int):
    best, out = float("inf"), None
    for _ in range(repeats):
        c = time.process_time()
        out = call()
        best = min(best, time.process_time() - c)
    return best, out


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("dir")
    ap.add_argument("--repeats", type=int, default=5)
    args = ap.parse_args(argv)
    stems = sorted(f[: -len(".triangles.f32")] for f in os.listdir(args.dir) if f.endswith(".triangles.f32"))
    for stem in stems:
        tris = load_rows(os.path.join(args.dir, f"{stem}.triangles.f32"), 9)
        scene, _mesh = build_scene(tris)
        for kind, query in (("closest", "INTERSECT"), ("shadow", "OCCLUDED")):
            rays = load_rows(os.path.join(args.dir, f"{stem}.{kind}.f32"), 7)
            o = np.ascontiguousarray(rays[:, 0:3])
            d = np.ascontiguousarray(rays[:, 3:6])
            t_max = np.ascontiguousarray(np.minimum(rays[:, 6], np.float32(1e37)))
            scene.run(o[:16], d[:16], dists=t_max[:16].copy(), query=query)  # commit
            # `dists` is written to by INTERSECT, so each call gets a fresh copy.
            cpu, out = best_cpu(lambda: scene.run(o, d, dists=t_max.copy(), query=query), args.repeats)
            hits = np.count_nonzero(out != -1)  # -1: missed (INTERSECT) or unoccluded (OCCLUDED)
            print(f"{stem} {kind}: {len(rays) / cpu / 1e6:.2f} M rays per CPU-second, "
                  f"hit fraction {hits / len(rays):.3f} (embreex, {len(tris)} triangles)")


if __name__ == "__main__":
    main()
