#!/usr/bin/env python3
"""Error targets through the service on 200 points of a sensor grid (issue
39's third measurement): for each estimator spec, the share of (point, seed)
estimates whose luminance is within the target of the grid's reference,
the share reported met, the share of those reported met that are within
(what a caller relying on `target_met` gets), the rays per point the
estimates traced themselves (`rays - amortised_rays`) and all of them, and
the points a records prior covered.

The points are every `--every`-th kept point of the grid of `sensor_grid.py`
(same arguments) and the reference is that script's `--reference-cache`
(plain MC, 8 x 4,096 paths per point). The service must allow the cap:

    BMC_LIMITS__MAX_SAMPLES=65536 BMC_LIMITS__MAX_PATHS_PER_REQUEST=100000000000 \\
        BMC_LIMITS__REQUEST_DEADLINE_SECS=3600 target/release/bmc-irradiance serve &
    python3 docs/validation/error_target_grid.py --scene cornell-box --y -1 --x -1 1 --z -1 1 \\
        --reference-cache /tmp/cornell-grid-ref.json --specs qmc:false,bmc:false,bmc:auto

Each spec is `method:records_prior` (`false`, `true` or `auto`); they run in
the order given on the same service, so a later one reuses what an earlier
one left (calibrations, records placed among the points).
"""

import argparse
import json
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from sensor_grid import grid_arguments, grid_points, post  # noqa: E402

LUMINANCE = (0.2126, 0.7152, 0.0722)


def luminance(rgb):
    return sum(w * c for w, c in zip(LUMINANCE, rgb))


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    grid_arguments(ap)
    ap.add_argument("--specs", default="qmc:false,bmc:false,bmc:auto")
    ap.add_argument("--every", type=int, default=20, help="every k-th kept grid point, 200 at most")
    ap.add_argument("--seeds", type=int, default=2)
    ap.add_argument("--batch", type=int, default=64, help="the estimator's samples")
    ap.add_argument("--max-samples", type=int, default=65536)
    args = ap.parse_args()
    if not args.reference_cache or not os.path.exists(args.reference_cache):
        sys.exit("needs the grid's --reference-cache (written by sensor_grid.py)")
    with open(args.reference_cache) as f:
        ref = json.load(f)
    pts = grid_points(args)
    idx = ref["keep"][:: args.every][:200]
    points = [pts[j] for j in idx]
    url = f"{args.url}/v1/scenes/{args.scene}/irradiance"
    records_prior = {"false": False, "true": True, "auto": "auto"}
    print(f"{len(points)} points, {args.seeds} seeds, target {args.target:g} at 95 %")
    print("| method:records_prior | within | reported met | met and within | own rays/point "
          "| all rays/point | points covered |")
    print("|---|---|---|---|---|---|---|")
    for spec in args.specs.split(","):
        method, prior = spec.split(":")
        within = met = met_within = count = own = rays = covered = 0
        for s in range(args.seeds):
            body = {
                "points": points,
                "estimator": {"method": method, "samples": args.batch, "records_prior": records_prior[prior]},
                "target": {"relative_error": args.target, "confidence": 0.95, "max_samples": args.max_samples},
                "seed": 100 + s,
            }
            doc, _ = post(url, body)
            for k, j in enumerate(idx):
                e, t = luminance(doc["irradiance"][k]), luminance(ref["mean"][j])
                hit = abs(e - t) <= args.target * abs(t)
                within += hit
                met += doc["target_met"][k]
                met_within += hit and doc["target_met"][k]
                count += 1
            rays += doc["rays"]
            own += doc["rays"] - doc["amortised_rays"]
            covered += doc.get("records_prior_points") or 0
        print(
            f"| {spec} | {within / count:.3f} | {met / count:.3f} | {met_within / max(met, 1):.3f} "
            f"| {own / count:.0f} | {rays / count:.0f} | {covered / args.seeds:.0f} |",
            flush=True,
        )


if __name__ == "__main__":
    main()
