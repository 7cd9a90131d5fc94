#!/usr/bin/env python3
"""Closest-hit ray throughput of Embree 4 (PyPI ``embreex``) on the Cornell box.

Scene: the Cornell box of docs/validation/data/mitsuba-cornell-box.json as 36
triangles (8 objects: light, floor, ceiling, back, green-wall, red-wall as 2
triangles each from the transformed [-1,1]^2 rectangle, small-box and
large-box as 12 triangles each from the transformed [-1,1]^3 cube), built as
one ``TriangleMesh`` in one ``EmbreeScene`` (default flags).  Optionally a
second scene: a geodesic sphere (icosahedron with every face subdivided into
n^2 triangles, n=71 -> 100,820 triangles, radius 1).

Rays: N (default 2^21 = 2,097,152) incoherent rays, origins uniform in
[-1,1]^3, directions uniform on the unit sphere, float32, generated with
numpy.random.default_rng(seed) (seed 12345): o = rng.uniform(-1,1,(N,3)),
then z = rng.uniform(-1,1,N), phi = rng.uniform(0,2pi,N),
d = (sqrt(1-z^2) cos phi, sqrt(1-z^2) sin phi, z).

Timing (wall clock and process CPU time, since the machine may be shared):
``scene.run(o, d)`` (query INTERSECT -> primitive ids, i.e. closest
hit) and ``scene.run(o, d, query='DISTANCE')`` (closest-hit t); embreex's
run() loops over the rays calling rtcIntersect1 one ray at a time on the
calling thread, so a single call is single-threaded.  "both cores" = two
worker processes, each with its own scene and half of the rays, started
together behind a barrier; wall time from the barrier to the last finisher.
Also tried: two Python threads in one process (shows whether run() releases
the GIL).  Each figure is the best of --repeats runs (default 5).  BVH build
time is excluded (scene.run commits on first call; a warm-up call does that).

Writes a Markdown table to stdout (and --out) and, with --sample-out, the
first 1000 rays with Embree's primitive id / distance as a CSV so other ray
tracers can check their hits (owner = object name of the hit triangle).

Example:
    python embree_throughput.py --out data/embree_throughput.md --sample-out data/embree_rays_sample.csv
"""
from __future__ import annotations

import argparse
import multiprocessing as mp
import os
import sys
import threading
import time

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from cornell_common import DEFAULT_REFERENCE, cornell_triangles, load_reference, write_csv  # noqa: E402


def make_rays(n: int, seed: int):
    rng = np.random.default_rng(seed)
    o = rng.uniform(-1.0, 1.0, (n, 3))
    z = rng.uniform(-1.0, 1.0, n)
    phi = rng.uniform(0.0, 2 * np.pi, n)
    s = np.sqrt(np.maximum(0.0, 1 - z * z))
    d = np.stack([s * np.cos(phi), s * np.sin(phi), z], axis=1)
    return o.astype(np.float32), d.astype(np.float32)


def geodesic_sphere(n: int) -> np.ndarray:
    """Icosahedron, each face split into n^2 triangles, projected to the unit sphere."""
    t = (1 + 5 ** 0.5) / 2
    v = np.array([[-1, t, 0], [1, t, 0], [-1, -t, 0], [1, -t, 0], [0, -1, t], [0, 1, t],
                  [0, -1, -t], [0, 1, -t], [t, 0, -1], [t, 0, 1], [-t, 0, -1], [-t, 0, 1]], float)
    f = [[0, 11, 5], [0, 5, 1], [0, 1, 7], [0, 7, 10], [0, 10, 11], [1, 5, 9], [5, 11, 4],
         [11, 10, 2], [10, 7, 6], [7, 1, 8], [3, 9, 4], [3, 4, 2], [3, 2, 6], [3, 6, 8],
         [3, 8, 9], [4, 9, 5], [2, 4, 11], [6, 2, 10], [8, 6, 7], [9, 8, 1]]
    tris = []
    for a, b, c in f:
        A, B, C = v[a], v[b], v[c]

        def P(i, j):
            q = A + (B - A) * (i / n) + (C - A) * (j / n)
            return q / np.linalg.norm(q)
        for i in range(n):
            for j in range(n - i):
                tris.append([P(i, j), P(i + 1, j), P(i, j + 1)])
                if i + j + 1 < n:
                    tris.append([P(i + 1, j), P(i + 1, j + 1), P(i, j + 1)])
    return np.array(tris)


def build_scene(tris: np.ndarray):
    from embreex import mesh_construction, rtcore_scene
    scene = rtcore_scene.EmbreeScene()
    verts = tris.reshape(-1, 3).astype(np.float32)
    faces = np.arange(len(verts), dtype=np.int32).reshape(-1, 3)
    mesh = mesh_construction.TriangleMesh(scene, verts, faces)
    return scene, mesh


def time_run(scene, o, d, query, repeats):
    """Best wall time and best CPU time (process_time) of `repeats` calls."""
    best, best_cpu = float("inf"), float("inf")
    out = None
    for _ in range(repeats):
        c = time.process_time()
        t = time.perf_counter()
        out = scene.run(o, d, query=query)
        best = min(best, time.perf_counter() - t)
        best_cpu = min(best_cpu, time.process_time() - c)
    return best, best_cpu, out


def _proc_worker(tris, o, d, query, repeats, barrier, q):
    scene, _mesh = build_scene(tris)
    scene.run(o[:16], d[:16])  # commit / build BVH
    for _ in range(repeats):
        barrier.wait()
        c = time.process_time()
        scene.run(o, d, query=query)
        q.put(time.process_time() - c)
        barrier.wait()


def time_processes(tris, o, d, query, repeats, nproc=2):
    ctx = mp.get_context("fork")
    barrier = ctx.Barrier(nproc + 1)
    q = ctx.Queue()
    parts = np.array_split(np.arange(len(o)), nproc)
    procs = [ctx.Process(target=_proc_worker, args=(tris, o[p], d[p], query, repeats, barrier, q))
             for p in parts]
    for p in procs:
        p.start()
    best, best_cpu = float("inf"), float("inf")
    for _ in range(repeats):
        barrier.wait()
        t = time.perf_counter()
        barrier.wait()
        wall = time.perf_counter() - t
        cpus = [q.get() for _ in range(nproc)]
        best = min(best, wall)
        best_cpu = min(best_cpu, max(cpus))
    for p in procs:
        p.join()
    return best, best_cpu


def time_threads(scene, o, d, query, repeats, nthreads=2):
    parts = np.array_split(np.arange(len(o)), nthreads)
    chunks = [(np.ascontiguousarray(o[p]), np.ascontiguousarray(d[p])) for p in parts]
    best = float("inf")
    for _ in range(repeats):
        ths = [threading.Thread(target=scene.run, args=c, kwargs={"query": query}) for c in chunks]
        t = time.perf_counter()
        for th in ths:
            th.start()
        for th in ths:
            th.join()
        best = min(best, time.perf_counter() - t)
    return best


def bench(name, tris, o, d, repeats, lines):
    scene, mesh = build_scene(tris)
    t = time.perf_counter()
    scene.run(o[:16], d[:16])
    build = time.perf_counter() - t
    n = len(o)
    t1, c1, prim = time_run(scene, o, d, "INTERSECT", repeats)
    t1d, c1d, dist = time_run(scene, o, d, "DISTANCE", repeats)
    tth = time_threads(scene, o, d, "INTERSECT", repeats)
    t2, c2 = time_processes(tris, o, d, "INTERSECT", repeats)
    hit = float(np.mean(prim >= 0))
    lines.append(f"| {name} | {len(tris):,} | {n:,} | {hit:.4f} | {n / t1 / 1e6:.3f} / {n / c1 / 1e6:.3f} | "
                 f"{n / t1d / 1e6:.3f} / {n / c1d / 1e6:.3f} | {n / tth / 1e6:.3f} | "
                 f"{n / t2 / 1e6:.3f} / {n / c2 / 1e6:.3f} | {t1 / t2:.2f} | {build * 1e3:.1f} |")
    print(lines[-1], flush=True)
    return scene, mesh, prim, dist


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--reference", default=DEFAULT_REFERENCE)
    ap.add_argument("--rays", type=int, default=2 ** 21)
    ap.add_argument("--seed", type=int, default=12345)
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--sphere-n", type=int, default=71, help="0 = skip the sphere scene")
    ap.add_argument("--out", default=None)
    ap.add_argument("--sample-out", default=None)
    args = ap.parse_args(argv)

    from importlib.metadata import version
    ref = load_reference(args.reference)
    tris, owners = cornell_triangles(ref)
    assert tris.shape == (36, 3, 3), tris.shape
    o, d = make_rays(args.rays, args.seed)
    lines = [f"embreex {version('embreex')} (Embree 4 bundled), numpy {np.__version__}, "
             f"{args.rays:,} rays, seed {args.seed}, best of {args.repeats}", "",
             "Mrays/s given as wall / CPU-time based (rays / best wall time, rays / best process CPU time; for 2 "
             "processes the CPU figure is rays / max over the workers' CPU times = what 2 dedicated cores would do).", "",
             "| scene | triangles | rays | hit fraction | Mrays/s 1 thread, INTERSECT (wall / CPU) | "
             "Mrays/s 1 thread, DISTANCE (wall / CPU) | Mrays/s 2 Python threads (wall) | "
             "Mrays/s 2 processes (wall / CPU) | 2-proc wall speed-up | BVH build ms |",
             "|---|---|---|---|---|---|---|---|---|---|"]
    _, _, prim, dist = bench("Cornell box", tris, o, d, args.repeats, lines)
    if args.sample_out:
        rows = []
        for i in range(1000):
            p = int(prim[i])
            rows.append(list(map(float, o[i])) + list(map(float, d[i])) + [p, float(dist[i]) if p >= 0 else float("inf"),
                                                                      owners[p] if p >= 0 else "miss"])
        write_csv(args.sample_out, ["ox", "oy", "oz", "dx", "dy", "dz", "prim_id", "t", "owner"], rows)
    if args.sphere_n:
        sph = geodesic_sphere(args.sphere_n)
        bench(f"geodesic sphere n={args.sphere_n}", sph, o, d, args.repeats, lines)
    text = "\n".join(lines)
    print(text)
    if args.out:
        with open(args.out, "w") as f:
            f.write(text + "\n")


if __name__ == "__main__":
    main()
