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
the N would spend, and the calibrated bars' ±2σ coverage and rms z against
the reference. `--samples 64 256 1024` runs those N only; `--max-depth 1`
restricts the reference and every request to direct light. Standard library
only:

    python3 docs/validation/sensor_grid.py --scene overcast --y 0 --x -2.5 2.5 --z 2 4 --estimators qmc
    (then on a fresh service) ... --estimators bmc

`radiance_sensor_grid.py` runs Radiance's `rtrace -I` on the same grid
against the same reference (`grid_points` and `reference` below).
"""

import argparse
import json
import math
import os
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


def grid_arguments(ap):
    """The grid's and reference's command-line options."""
    ap.add_argument("--url", default="http://127.0.0.1:8080")
    ap.add_argument("--scene", required=True)
    ap.add_argument("--y", type=float, required=True)
    ap.add_argument("--x", type=float, nargs=2, required=True)
    ap.add_argument("--z", type=float, nargs=2, required=True)
    ap.add_argument("--side", type=int, default=64)
    ap.add_argument("--ref-seeds", type=int, default=8)
    ap.add_argument("--target", type=float, default=0.02)
    ap.add_argument(
        "--max-depth", type=int, default=None, help="path depth of the reference and every request (the scene's default)"
    )
    ap.add_argument(
        "--reference-cache", default=None, help="JSON file: the reference is read from it, or written to it"
    )


def grid_points(args):
    """The grid's points as the service takes them, row by row."""
    n = args.side
    return [
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


def with_depth(body, max_depth):
    """`body` with `max_depth` when one is given."""
    return body if max_depth is None else dict(body, max_depth=max_depth)


class Reference:
    """Plain MC with `seeds` × 4,096 paths per point: the mean, its
    variance, the points kept (reference above 1 % of the mean) and their
    mean level."""

    def __init__(self, url, pts, seeds, max_depth=None):
        runs = []
        for s in range(seeds):
            body = with_depth(
                {
                    "points": pts,
                    "estimator": {"method": "mc", "samples": 4096, "calibrate": False},
                    "seed": 2_000_000 + s,
                },
                max_depth,
            )
            runs.append(post(url, body)[0])
        k = seeds
        self.mean = [[sum(r["irradiance"][j][c] for r in runs) / k for c in range(3)] for j in range(len(pts))]
        self.variance = [
            [sum(r["std_dev"][j][c] ** 2 for r in runs) / k**2 for c in range(3)] for j in range(len(pts))
        ]
        overall = sum(sum(r) for r in self.mean) / (3 * len(self.mean))
        self.keep = [j for j in range(len(pts)) if sum(self.mean[j]) / 3 > 0.01 * overall]
        self.level = sum(sum(self.mean[j]) for j in self.keep) / (3 * len(self.keep))

    @classmethod
    def cached(cls, args, pts):
        """The grid's reference, from `args.reference_cache` if that file is
        there (written on first use)."""
        path = args.reference_cache
        if path and os.path.exists(path):
            ref = cls.__new__(cls)
            with open(path) as f:
                ref.__dict__.update(json.load(f))
            return ref
        ref = cls(f"{args.url}/v1/scenes/{args.scene}/irradiance", pts, args.ref_seeds, args.max_depth)
        if path:
            with open(path, "w") as f:
                json.dump(ref.__dict__, f)
        return ref

    def nrmse_vs_truth(self, values):
        """nrmse of `values` (per point, RGB) vs truth: the squared error
        against the reference less the reference's own variance
        (docs/math.md §17.3, §17.4), over the kept points."""
        err2 = sum((values[j][c] - self.mean[j][c]) ** 2 for j in self.keep for c in range(3))
        noise = sum(self.variance[j][c] for j in self.keep for c in range(3))
        return math.sqrt(max(err2 - noise, 0.0) / (3 * len(self.keep))) / self.level

    def calibration(self, values, std_devs):
        """±2σ coverage and rms z of `values` with their standard errors
        against the reference, its own variance added (docs/math.md §10.3),
        over the kept points and channels."""
        zs = [
            (values[j][c] - self.mean[j][c]) / math.sqrt(std_devs[j][c] ** 2 + self.variance[j][c])
            for j in self.keep
            for c in range(3)
        ]
        coverage = sum(abs(z) <= 2 for z in zs) / len(zs)
        return coverage, math.sqrt(sum(z * z for z in zs) / len(zs))


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    grid_arguments(ap)
    ap.add_argument(
        "--estimators",
        default="qmc,bmc",
        help="which to run (each on a fresh service, so neither reuses the other's calibration)",
    )
    ap.add_argument(
        "--samples",
        type=int,
        nargs="+",
        default=None,
        help="run these N only (default: N = 4, 8, … until the target is reached)",
    )
    ap.add_argument(
        "--light-samples",
        type=int,
        default=None,
        help="light samples of the split direct part per point (default: N)",
    )
    args = ap.parse_args()
    url = f"{args.url}/v1/scenes/{args.scene}/irradiance"
    pts = grid_points(args)
    ref = Reference.cached(args, pts)
    print(f"{args.scene}: {len(ref.keep)} of {len(pts)} grid points (reference {args.ref_seeds} × 4096 paths)")
    print(
        "| estimator | N | nrmse vs truth | coverage, rms z | rays | amortised | time, s | total rays | total time, s |"
    )
    print("|---|---|---|---|---|---|---|---|---|")
    chosen = args.estimators.split(",")
    for name, estimator in [
        ("qmc plain", {"method": "qmc", "records_prior": False}),
        ("bmc default", {"method": "bmc"}),
    ]:
        if name.split()[0] not in chosen:
            continue
        if args.light_samples:
            estimator = dict(estimator, light_samples=args.light_samples)
            name += f", {args.light_samples} light samples"
        total_rays, total_time = 0, 0.0
        for samples in args.samples or [4 << k for k in range(11)]:
            body = {"points": pts, "estimator": dict(estimator, samples=samples), "seed": 1}
            doc, wall = post(url, with_depth(body, args.max_depth))
            truth = ref.nrmse_vs_truth(doc["irradiance"])
            coverage, rms_z = ref.calibration(doc["irradiance"], doc["std_dev"])
            total_rays += doc["rays"]
            total_time += wall
            print(
                f"| {name} | {samples} | {truth:.4f} | {coverage:.3f}, {rms_z:.2f} | {doc['rays']} | "
                f"{doc['amortised_rays']} | {wall:.2f} | {total_rays} | {total_time:.2f} |"
            )
            if truth <= args.target and not args.samples:
                break


if __name__ == "__main__":
    main()
