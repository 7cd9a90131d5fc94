#!/usr/bin/env python3
"""A 64 × 64 sensor grid on a floor (issue 39): the rays and time each
estimator needs to reach 2 % nrmse against a converged reference.

The grid covers the rectangle `--x x0 x1 --z z0 z1` at height `--y`, normal
+y, lifted 1e-4. The reference is plain MC with `--ref-seeds` × 4,096 paths
per point; grid points whose reference is below 1 % of the mean (inside an
object standing on the floor) are left out of every error. Then, on the same
service, plain QMC (`"records_prior": false`) or default BMC runs at
N = 4, 8, 16, ... (one request each, seed 1) until the nrmse vs truth
(docs/math.md §17.3, §17.4) is at most 2 %. Each row reports the request's
rays (its `rays`, which for BMC's first request include the records it
placed among the grid's points, `amortised_rays`) and wall time; the
"total" columns add the estimator's earlier rows, as a user searching for
the N would spend. Standard library only:

    python3 docs/validation/sensor_grid.py --scene overcast --y 0 --x -2.5 2.5 --z 2 4 --estimators qmc
    (then on a fresh service) ... --estimators bmc
"""

import argparse
import json
import math
import time
import urllib.request


def post(url, body):
    req = urllib.request.Request(
        url, data=json.dumps(body).encode(), headers={"content-type": "application/json"}
    )
    start = time.monotonic()
    with urllib.request.urlopen(req, timeout=7200) as r:
        doc = json.load(r)
    return doc, time.monotonic() - start


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--url", default="http://127.0.0.1:8080")
    ap.add_argument("--scene", required=True)
    ap.add_argument("--y", type=float, required=True)
    ap.add_argument("--x", type=float, nargs=2, required=True)
    ap.add_argument("--z", type=float, nargs=2, required=True)
    ap.add_argument("--side", type=int, default=64)
    ap.add_argument("--ref-seeds", type=int, default=8)
    ap.add_argument("--target", type=float, default=0.02)
    ap.add_argument(
        "--estimators",
        default="qmc,bmc",
        help="which to run (each on a fresh service, so neither reuses the other's calibration)",
    )
    args = ap.parse_args()
    url = f"{args.url}/v1/scenes/{args.scene}/irradiance"
    n = args.side
    pts = [
        {
            "position": [
                args.x[0] + (args.x[1] - args.x[0]) * (i + 0.5) / n,
                args.y + 1e-4,
                args.z[0] + (args.z[1] - args.z[0]) * (j + 0.5) / n,
            ],
            "normal": [0, 1, 0],
        }
        for j in range(n)
        for i in range(n)
    ]
    runs = []
    for s in range(args.ref_seeds):
        body = {
            "points": pts,
            "estimator": {"method": "mc", "samples": 4096, "calibrate": False},
            "seed": 2_000_000 + s,
        }
        runs.append(post(url, body)[0])
    k = args.ref_seeds
    ref = [[sum(r["irradiance"][j][c] for r in runs) / k for c in range(3)] for j in range(len(pts))]
    rv = [[sum(r["std_dev"][j][c] ** 2 for r in runs) / k**2 for c in range(3)] for j in range(len(pts))]
    mean = sum(sum(r) for r in ref) / (3 * len(ref))
    keep = [j for j in range(len(pts)) if sum(ref[j]) / 3 > 0.01 * mean]
    level = sum(sum(ref[j]) for j in keep) / (3 * len(keep))
    print(f"{args.scene}: {len(keep)} of {len(pts)} grid points (reference {k} × 4096 paths)")
    print("| estimator | N | nrmse vs truth | rays | amortised | time, s | total rays | total time, s |")
    print("|---|---|---|---|---|---|---|---|")
    chosen = args.estimators.split(",")
    for name, estimator in [
        ("qmc plain", {"method": "qmc", "records_prior": False}),
        ("bmc default", {"method": "bmc"}),
    ]:
        if name.split()[0] not in chosen:
            continue
        total_rays, total_time, samples = 0, 0.0, 4
        while samples <= 4096:
            doc, wall = post(url, {"points": pts, "estimator": dict(estimator, samples=samples), "seed": 1})
            err2 = sum((doc["irradiance"][j][c] - ref[j][c]) ** 2 for j in keep for c in range(3))
            noise = sum(rv[j][c] for j in keep for c in range(3))
            truth = math.sqrt(max(err2 - noise, 0.0) / (3 * len(keep))) / level
            total_rays += doc["rays"]
            total_time += wall
            print(
                f"| {name} | {samples} | {truth:.4f} | {doc['rays']} | {doc['amortised_rays']} | "
                f"{wall:.2f} | {total_rays} | {total_time:.2f} |"
            )
            if truth <= args.target:
                break
            samples *= 2


if __name__ == "__main__":
    main()
