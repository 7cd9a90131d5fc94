#!/usr/bin/env python3
"""Issue 39's user workflow, measured against a running service.

The points: 200 on a scene laid out like the bundled overcast one (a ground
plane, two spheres, a box and a wall; `--layout`), of which those behind the
wall, outside the camera's field of view or on the spheres' far sides are not
camera-visible. Run it on a fresh service, then again after fetching the
viewer's tiles (`bmc-irradiance fetch --scene S --preset final`). Every
estimator runs
with N samples and several request seeds against a Monte Carlo reference
(`--ref-seeds` × 4,096 paths per point), at full depth and with
environment light only (`max_depth` 1). Reports, per mode, the relative RMSE
of plain QMC (`"records_prior": false`) and of BMC with the service's
default and with `"records_prior": false`, their ratio, and the ±2σ coverage
and rms z of every row (docs/math.md §10.3, §17.4).

Standard library only:

    python3 docs/validation/records_prior_workflow.py --url http://127.0.0.1:8080 --scene overcast
"""

import argparse
import json
import math
import random
import urllib.request

# Scene layouts: the camera, the spheres (centre, radius), ground footprints
# that points avoid (circles (x, z, r), rectangles (x0, x1, z0, z1)), the
# visible ground region, the out-of-view ground regions and the ground
# region hidden behind the wall (each (x0, x1, z0, z1)).
LAYOUTS = {
    # scenes/overcast.json, the bundled environment-lit scene.
    "overcast": {
        "camera": (0.0, 2.4, 6.5),
        "spheres": [((-1.3, 0.8, -0.4), 0.8), ((1.2, 0.6, 0.3), 0.6)],
        "circles": [(-1.3, -0.4, 0.8), (1.2, 0.3, 0.6)],
        "rectangles": [(-0.6, 0.8, 0.5, 1.9), (-2.05, 2.45, -2.4, -2.0)],
        "visible": (-2.5, 2.5, -1.8, 3.5),
        "out_of_view": [(4.5, 7.5, -3.0, 3.0), (-7.5, -4.5, -3.0, 3.0)],
        "behind_wall": (-1.5, 2.0, -4.5, -2.6),
    },
    # docs/validation/data/heldout/heldout.json, built after the work was
    # done and never used while tuning.
    "heldout": {
        "camera": (2.0, 2.8, 6.0),
        "spheres": [((1.5, 1.0, -1.0), 1.0), ((-1.6, 0.5, 1.0), 0.5)],
        "circles": [(1.5, -1.0, 1.0), (-1.6, 1.0, 0.5), (-0.5, -1.2, 0.9)],
        "rectangles": [(-3.4, -3.0, -2.6, 1.6)],
        "visible": (-2.6, 3.2, -2.5, 3.0),
        "out_of_view": [(5.0, 7.5, -3.0, 3.0)],
        "behind_wall": (-4.8, -3.6, -2.2, 1.2),
    },
    # docs/validation/data/heldout/heldout-sunset.json, a low sun; built after
    # the split mode's variance share changed (its first run showed the
    # environment sampling's defect around a one-texel sun).
    "sunset": {
        "camera": (-1.5, 3.0, 6.5),
        "spheres": [((-1.8, 0.9, -0.6), 0.9), ((1.4, 0.45, 1.2), 0.45)],
        "circles": [(-1.8, -0.6, 0.9), (1.4, 1.2, 0.45)],
        "rectangles": [(0.5, 1.9, -2.2, -0.8), (-1.55, 2.55, -3.4, -3.0)],
        "visible": (-2.8, 2.8, -2.4, 3.2),
        "out_of_view": [(5.5, 7.5, 1.5, 5.0), (-7.5, -5.5, -3.0, 2.0)],
        "behind_wall": (-1.0, 2.0, -4.6, -3.5),
    },
    # docs/validation/data/heldout/heldout-noon.json, a high sun; built after
    # the split mode's direct-light twins (its first run led to the twins'
    # conflict test, so it is not held out for that).
    "noon": {
        "camera": (3.0, 2.5, 6.0),
        "spheres": [((0.8, 0.7, 0.5), 0.7), ((-1.9, 0.4, -0.6), 0.4)],
        "circles": [(0.8, 0.5, 0.7), (-1.9, -0.6, 0.4)],
        "rectangles": [(-1.45, 0.25, -2.65, -0.95), (-2.95, 1.95, -3.7, -3.3)],
        "visible": (-2.5, 3.0, -2.8, 3.0),
        "out_of_view": [(5.5, 7.5, -1.0, 4.0), (-7.5, -6.5, 2.5, 5.0)],
        "behind_wall": (-2.0, 1.0, -5.0, -3.9),
    },
    # docs/validation/data/heldout/heldout-morning.json, a small sun; built
    # after priors in conflict with a point's own estimate were left out,
    # never used while tuning.
    "morning": {
        "camera": (-3.5, 2.2, 5.5),
        "spheres": [((1.2, 0.8, -0.2), 0.8), ((-0.8, 0.35, 1.4), 0.35)],
        "circles": [(1.2, -0.2, 0.8), (-0.8, 1.4, 0.35)],
        "rectangles": [(-0.35, 0.75, -2.55, -1.45), (2.8, 3.2, -3.75, 0.75)],
        "visible": (-2.0, 2.5, -2.5, 2.5),
        "out_of_view": [(-7.5, -5.5, -3.0, 1.0), (5.0, 7.5, 3.0, 5.5)],
        "behind_wall": (3.3, 4.6, -3.0, 0.0),
    },
    # docs/validation/data/heldout/heldout-evening.json, a low sun of a few
    # texels; built after the twins' shadow probes and rotation gradients,
    # never used while tuning.
    "evening": {
        "camera": (1.0, 2.6, 6.5),
        "spheres": [((0.6, 0.75, -0.8), 0.75), ((-1.7, 0.4, 0.9), 0.4)],
        "circles": [(0.6, -0.8, 0.75), (-1.7, 0.9, 0.4)],
        "rectangles": [(1.25, 2.55, 0.35, 1.65), (-2.95, 1.95, -3.4, -3.0)],
        "visible": (-2.0, 2.6, -2.6, 2.5),
        "out_of_view": [(5.5, 7.5, -3.0, 2.0), (-7.5, -5.5, -1.0, 4.0)],
        "behind_wall": (-1.8, 0.8, -4.8, -3.6),
    },
    # docs/validation/data/heldout/heldout-afternoon.json, a small sun 42°
    # up; built after the prior's modelled error was made to grow with the
    # distance to the records, never used while tuning.
    "afternoon": {
        "camera": (-1.0, 2.6, 6.5),
        "spheres": [((-0.7, 0.7, -1.0), 0.7), ((1.3, 0.45, 1.1), 0.45)],
        "circles": [(-0.7, -1.0, 0.7), (1.3, 1.1, 0.45)],
        "rectangles": [(-2.4, -1.2, 0.7, 1.9), (-2.35, 2.75, -3.5, -3.1)],
        "visible": (-2.6, 2.0, -2.6, 2.5),
        "out_of_view": [(5.5, 7.5, -1.0, 4.0), (-7.5, -5.5, -3.0, 2.0)],
        "behind_wall": (-1.6, 2.0, -4.8, -3.7),
    },
    # docs/validation/data/heldout/heldout-haze.json, a wide sun 30° up in
    # a hazy sky; built after combined error bars were held at least to the
    # rule's noise they carry, never used while tuning.
    "haze": {
        "camera": (0.5, 2.8, 6.8),
        "spheres": [((1.4, 0.6, -0.5), 0.6), ((-1.2, 0.5, 0.6), 0.5)],
        "circles": [(1.4, -0.5, 0.6), (-1.2, 0.6, 0.5)],
        "rectangles": [(-0.3, 0.7, 0.9, 1.9), (-2.65, 1.85, -3.2, -2.8)],
        "visible": (-2.3, 2.5, -2.5, 2.8),
        "out_of_view": [(5.5, 7.5, -2.0, 3.0), (-7.5, -5.5, -3.0, 2.0)],
        "behind_wall": (-2.0, 1.4, -4.4, -3.4),
    },
    # docs/validation/data/heldout/heldout-winter.json, a small sun 12° up
    # behind the wall; built after split-mode BMC's error bars took the
    # light samples' unseen-light term, never used while tuning.
    "winter": {
        "camera": (-0.4, 2.7, 6.6),
        "spheres": [((-1.5, 0.55, -0.8), 0.55), ((1.0, 0.45, 1.0), 0.45)],
        "circles": [(-1.5, -0.8, 0.55), (1.0, 1.0, 0.45)],
        "rectangles": [(-1.05, -0.15, 1.15, 2.05), (-1.25, 2.85, -3.4, -3.0)],
        "visible": (-2.4, 2.2, -2.6, 2.6),
        "out_of_view": [(5.5, 7.5, -2.0, 3.0), (-7.5, -5.5, -3.0, 2.0)],
        "behind_wall": (-1.0, 2.6, -4.6, -3.6),
    },
    # docs/validation/data/heldout/heldout-dusk.json, a small sun low to the
    # right; built after the stratified light samples' variance was
    # moderated, never used while tuning.
    "dusk": {
        "camera": (1.0, 2.6, 6.2),
        "spheres": [((1.7, 0.65, -0.3), 0.65), ((-1.2, 0.5, 0.9), 0.5)],
        "circles": [(1.7, -0.3, 0.65), (-1.2, 0.9, 0.5)],
        "rectangles": [(-0.3, 0.7, 1.4, 2.4), (-2.75, 1.75, -3.5, -3.1)],
        "visible": (-2.5, 2.8, -2.6, 2.8),
        "out_of_view": [(5.5, 7.5, -2.5, 2.5), (-7.5, -5.5, -1.0, 4.0)],
        "behind_wall": (-2.0, 1.2, -4.8, -3.7),
    },
}


def points(layout, seed):
    """200 points: 80 on visible ground, 30 on ground out of view, 30 on
    ground behind the wall, 60 on the spheres (the far halves hidden);
    returns them and how many are not camera-visible."""
    rng = random.Random(seed)
    out, hidden = [], 0

    def free(x, z):
        inside_circle = any((x - cx) ** 2 + (z - cz) ** 2 < r * r for cx, cz, r in layout["circles"])
        inside_rect = any(x0 < x < x1 and z0 < z < z1 for x0, x1, z0, z1 in layout["rectangles"])
        return not (inside_circle or inside_rect)

    def ground(region, count):
        x0, x1, z0, z1 = region
        made = 0
        while made < count:
            x, z = rng.uniform(x0, x1), rng.uniform(z0, z1)
            if free(x, z):
                out.append({"position": [x, 0.0, z], "normal": [0.0, 1.0, 0.0]})
                made += 1

    ground(layout["visible"], 80)
    regions = layout["out_of_view"]
    for i in range(30):
        ground(regions[i % len(regions)], 1)
    ground(layout["behind_wall"], 30)
    hidden += 60
    for centre, radius in layout["spheres"]:
        for _ in range(30):
            while True:
                d = [rng.gauss(0, 1) for _ in range(3)]
                norm = math.sqrt(sum(c * c for c in d))
                n = [c / norm for c in d]
                p = [c + radius * k for c, k in zip(centre, n)]
                if p[1] > 0.02:
                    break
            out.append({"position": p, "normal": n})
            to_camera = [c - q for c, q in zip(layout["camera"], p)]
            if sum(a * b for a, b in zip(n, to_camera)) < 0:
                hidden += 1
    return out, hidden


def post(url, body):
    req = urllib.request.Request(
        url, data=json.dumps(body).encode(), headers={"content-type": "application/json"}
    )
    with urllib.request.urlopen(req, timeout=3600) as r:
        return json.load(r)


def reference(url, pts, depth, seeds):
    """Mean and standard error per point and channel of `seeds` MC runs of
    4,096 paths, with the model's own variance (no calibration)."""
    runs = []
    for s in range(seeds):
        body = {
            "points": pts,
            "estimator": {"method": "mc", "samples": 4096, "calibrate": False},
            "seed": 1_000_000 + s,
        }
        if depth is not None:
            body["max_depth"] = depth
        runs.append(post(url, body))
    mean = [[sum(r["irradiance"][j][c] for r in runs) / seeds for c in range(3)] for j in range(len(pts))]
    var = [
        [sum(r["std_dev"][j][c] ** 2 for r in runs) / seeds**2 for c in range(3)]
        for j in range(len(pts))
    ]
    return mean, var


def score(estimates, ref, ref_var):
    """nrmse (§17.4), nrmse with the reference's noise removed, ±2σ coverage
    and rms z (§10.3) over points, seeds and channels."""
    err2, noise2, zs = 0.0, 0.0, []
    count = 0
    for est in estimates:
        for j, (e, s) in enumerate(zip(est["irradiance"], est["std_dev"])):
            for c in range(3):
                d = e[c] - ref[j][c]
                err2 += d * d
                noise2 += ref_var[j][c]
                count += 1
                zs.append(d / math.sqrt(s[c] ** 2 + ref_var[j][c]))
    level = sum(sum(r) for r in ref) / (3 * len(ref))
    nrmse = math.sqrt(err2 / count) / level
    truth = math.sqrt(max(err2 - noise2, 0.0) / count) / level
    coverage = sum(abs(z) <= 2 for z in zs) / len(zs)
    rms_z = math.sqrt(sum(z * z for z in zs) / len(zs))
    return nrmse, truth, coverage, rms_z


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--url", default="http://127.0.0.1:8080")
    ap.add_argument("--scene", default="overcast")
    ap.add_argument("--samples", type=int, default=64)
    ap.add_argument("--seeds", type=int, default=6)
    ap.add_argument("--ref-seeds", type=int, default=16)
    ap.add_argument("--layout", choices=sorted(LAYOUTS), default="overcast")
    ap.add_argument("--points-seed", type=int, default=39)
    ap.add_argument("--modes", default="env,full")
    args = ap.parse_args()
    url = f"{args.url}/v1/scenes/{args.scene}/irradiance"
    pts, hidden = points(LAYOUTS[args.layout], args.points_seed)
    print(f"{len(pts)} points, {hidden} not camera-visible")
    for mode in args.modes.split(","):
        depth = 1 if mode == "env" else None
        ref, ref_var = reference(url, pts, depth, args.ref_seeds)
        rows = {}
        for name, estimator in [
            ("qmc plain", {"method": "qmc", "records_prior": False}),
            ("bmc plain", {"method": "bmc", "records_prior": False}),
            ("bmc default", {"method": "bmc"}),
        ]:
            runs = []
            for s in range(args.seeds):
                body = {"points": pts, "estimator": dict(estimator, samples=args.samples), "seed": s + 1}
                if depth is not None:
                    body["max_depth"] = depth
                runs.append(post(url, body))
            covered = runs[0].get("records_prior_points"), runs[0].get("direct_records_points")
            rows[name] = (score(runs, ref, ref_var), covered, sum(r["rays"] for r in runs))
        base = rows["qmc plain"][0][1]
        print(f"\n{mode} (N = {args.samples}, {args.seeds} seeds, reference {args.ref_seeds} × 4096 paths)")
        print("| estimator | nrmse | vs truth | ÷ qmc plain | coverage | rms z | covered (indirect, direct) | rays |")
        print("|---|---|---|---|---|---|---|---|")
        for name, ((nrmse, truth, cov, rz), covered, rays) in rows.items():
            print(
                f"| {name} | {nrmse:.4f} | {truth:.4f} | {truth / base:.2f} | {cov:.3f} | {rz:.3f} | {covered} | {rays} |"
            )


if __name__ == "__main__":
    main()
