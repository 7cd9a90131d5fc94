#!/usr/bin/env python3
"""Radiance `rtrace -I` on issue 39's sensor grids: the time each option
set takes and the nrmse vs truth it reaches, against the same reference as
`sensor_grid.py` (plain MC through the service, 8 × 4,096 paths per point,
its own noise removed).

The Cornell box is `radiance_irradiance.py`'s conversion of Mitsuba's
(the geometry of `scenes/cornell-box.json`; that script's doc lists what
differs); any other `--scene` is `scenes/<scene>.json` converted by
`radiance_json_scene.py` (its doc lists what converts and how). Each
option set is one `rtrace -h -I` call on the whole grid, points lifted
1e-4 along the normal; `-n 2` where asked runs two processes
that share the ambient file. The reference is fetched once from a running
service and kept in `--reference-cache` (which `sensor_grid.py` reads too). Needs `pyradiance` and numpy (a
throwaway venv, never a dependency of the project):

    python3 -m venv /tmp/radvenv && /tmp/radvenv/bin/pip install pyradiance==1.3.1 numpy
    target/release/bmc-irradiance serve --bind 127.0.0.1:8080 &
    /tmp/radvenv/bin/python docs/validation/radiance_sensor_grid.py --scene cornell-box \\
        --y -1 --x -1 1 --z -1 1 --reference-cache /tmp/cornell-grid-ref.json \\
        --opts "-ab 8 -aa 0.1 -ad 1024 -as 512 -ar 128 -lr -10 -lw 1e-5"
    /tmp/radvenv/bin/pip install OpenEXR    # for the overcast scene's map
    /tmp/radvenv/bin/python docs/validation/radiance_sensor_grid.py --scene overcast \\
        --y 0 --x -2.5 2.5 --z 2 4 --reference-cache /tmp/overcast-grid-ref.json \\
        --opts "-ab 4 -aa 0.1 -ad 512 -as 128 -ar 64 -lr -10 -lw 1e-5"
"""

import argparse
import os
import shlex
import subprocess
import sys
import tempfile
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from cornell_common import DEFAULT_REFERENCE, load_reference  # noqa: E402
from radiance_irradiance import radiance_env, scene_rad  # noqa: E402
from radiance_json_scene import scene_rad as json_scene_rad  # noqa: E402
from sensor_grid import Reference, grid_arguments, grid_points  # noqa: E402


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    grid_arguments(ap)
    ap.add_argument("--opts", action="append", required=True, help="rtrace options (repeatable)")
    args = ap.parse_args()
    pts = grid_points(args)
    ref = Reference.cached(args, pts)
    env, version = radiance_env()
    work = tempfile.mkdtemp(prefix="radiance-grid-")
    rad, octree = os.path.join(work, "scene.rad"), os.path.join(work, "scene.oct")
    if args.scene == "cornell-box":
        text = scene_rad(load_reference(DEFAULT_REFERENCE))
    else:
        root = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..")
        text = json_scene_rad(os.path.join(root, "scenes", f"{args.scene}.json"), work)
    with open(rad, "w") as f:
        f.write(text)
    with open(octree, "wb") as f:
        subprocess.run(["oconv", rad], stdout=f, check=True, env=env)
    lines = "".join(
        " ".join(f"{v:.9g}" for v in p["position"] + p["normal"]) + "\n" for p in pts
    )
    print(f"pyradiance {version}; {len(ref.keep)} of {len(pts)} grid points")
    print("| rtrace options | time, s | nrmse vs truth | mean ratio to the reference |")
    print("|---|---|---|---|")
    for k, opts in enumerate(args.opts):
        # A fresh ambient file per option set, so no run reuses another's.
        ambient = os.path.join(work, f"run{k}.amb")
        cmd = ["rtrace", "-h", "-I", "-af", ambient] + shlex.split(opts) + [octree]
        start = time.monotonic()
        out = subprocess.run(cmd, input=lines, capture_output=True, text=True, env=env, check=True)
        wall = time.monotonic() - start
        values = [[float(x) for x in line.split()[:3]] for line in out.stdout.strip().splitlines()]
        assert len(values) == len(pts), (len(values), out.stderr[-500:])
        ratio = sum(sum(values[j]) for j in ref.keep) / sum(sum(ref.mean[j]) for j in ref.keep)
        print(f"| `{opts}` | {wall:.2f} | {ref.nrmse_vs_truth(values):.4f} | {ratio:.4f} |", flush=True)


if __name__ == "__main__":
    main()
