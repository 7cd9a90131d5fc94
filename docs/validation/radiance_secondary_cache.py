"""Radiance queries through the cache with and without the secondary cache
(docs/BENCHMARKS.md "Radiance queries through the secondary cache").

  query BASE MODE SEED POINTS OUT   POST 200 points to BASE's cornell-box
                                    radiance route and write the response to OUT;
                                    MODE: path (1024 repeats, the reference),
                                    paths (records trace 4 paths per direction)
                                    or secondary (1 light sample per direction
                                    at the first hit, secondary_cache: true);
                                    POINTS seeds the point positions
  compare REF EST                   relative RMS error of EST against REF with
                                    REF's own noise removed, and the share of
                                    |z| <= 2 and rms z of the combined error bars

Standard library only; measurement only, never part of the build.
"""

import json
import math
import random
import sys
import time
import urllib.request


def points(seed):
    """200 points on the back wall and the floor, each seen along its normal."""
    rng = random.Random(seed)
    out = []
    for i in range(200):
        if i % 2:
            p, n = [rng.uniform(-0.9, 0.9), rng.uniform(-0.9, 0.9), -1.0], [0, 0, 1]
        else:
            p, n = [rng.uniform(-0.9, 0.9), -1.0, rng.uniform(-0.9, 0.9)], [0, 1, 0]
        out.append({"position": p, "normal": n, "direction": n})
    return out


def query(base, mode, seed, point_seed, out):
    if mode == "path":
        estimator, repeats = {"method": "path"}, 1024
    else:
        secondary = mode == "secondary"
        estimator = {"method": "bmc", "samples": 1024, "accuracy": 0.25, "light_samples": 4,
                     "glossy_samples": 64, "paths_per_direction": 1 if secondary else 4,
                     "secondary_cache": secondary}
        repeats = 4
    body = {"points": points(point_seed), "estimator": estimator, "repeats": repeats,
            "max_depth": 64, "seed": seed}
    request = urllib.request.Request(f"{base}/v1/scenes/cornell-box/radiance",
                                     data=json.dumps(body).encode(),
                                     headers={"content-type": "application/json"})
    start = time.time()
    response = json.load(urllib.request.urlopen(request, timeout=600))
    print(f"{mode} points={point_seed} seed={seed}: {time.time() - start:.2f} s wall, "
          f"{response['rays']} rays")
    with open(out, "w") as f:
        json.dump(response, f)


def compare(ref_path, est_path):
    ref, est = json.load(open(ref_path)), json.load(open(est_path))
    squares = norm = 0.0
    zs = []
    for i, p_rgb in enumerate(ref["radiance"]):
        for c, p in enumerate(p_rgb):
            sp, v, sv = ref["std_dev"][i][c], est["radiance"][i][c], est["std_dev"][i][c]
            squares += (v - p) ** 2 - sp ** 2
            norm += p * p
            s = math.hypot(sv, sp)
            if s > 0:  # black channels (points inside the boxes) have no spread
                zs.append((v - p) / s)
    covered = sum(abs(z) <= 2 for z in zs) / len(zs)
    rms_z = math.sqrt(sum(z * z for z in zs) / len(zs))
    print(f"relative RMS error vs truth {100 * math.sqrt(max(squares, 0) / norm):.2f} %, "
          f"|z| <= 2: {covered:.3f}, rms z {rms_z:.2f} ({len(zs)} channels)")


if __name__ == "__main__":
    if sys.argv[1] == "query":
        query(sys.argv[2], sys.argv[3], int(sys.argv[4]), int(sys.argv[5]), sys.argv[6])
    else:
        compare(sys.argv[2], sys.argv[3])
