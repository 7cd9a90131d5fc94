#!/usr/bin/env python3
"""Our path tracer's variance per sample against Mitsuba 3's on one scene,
with no reference image: each renderer renders the scene twice at SPP samples
per pixel with two seeds, and its noise is `sqrt(mean((a − b)² / 2))` over
the pixels (the standard deviation of one render), relative to the mean of
the two renders. Reports both, the ratio of the variances (ours / Mitsuba's,
in absolute terms) and the ratio of the means (a bias check at the noise's
scale), with the wall time of each render. "The bundled studio scene" in
docs/BENCHMARKS.md.

Run in a throwaway venv (`pip install mitsuba numpy OpenEXR`), from any
directory (the script's own is on Python's path):

    cargo build --release
    python docs/validation/variance_vs_mitsuba.py scenes/studio.xml 32
"""

import argparse
import os
import subprocess
import sys
import tempfile
import time

import numpy as np

from interactive_budgets import read_rgb


def noise(a, b):
    """(relative standard deviation of one render, mean of both)."""
    mean = 0.5 * (a + b).mean()
    return np.sqrt(((a - b) ** 2 / 2).mean()) / mean, mean


def main():
    root = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("scene", help="a Mitsuba 3 XML scene both renderers read")
    ap.add_argument("spp", type=int)
    ap.add_argument("--seeds", type=int, nargs=2, default=[11, 12])
    ap.add_argument("--bin", default=os.path.join(root, "target", "release", "bmc-irradiance"))
    args = ap.parse_args()
    work = tempfile.mkdtemp(prefix="variance-")
    here = os.path.dirname(os.path.abspath(__file__))
    renders = {"ours": [], "mitsuba": []}
    for seed in args.seeds:
        out = os.path.join(work, f"mitsuba{seed}.exr")
        start = time.monotonic()
        subprocess.run(
            [sys.executable, os.path.join(here, "mitsuba_render.py"), args.scene, str(args.spp), out, "--seed", str(seed)],
            check=True,
            capture_output=True,
        )
        renders["mitsuba"].append((read_rgb(out).astype(np.float64), time.monotonic() - start))
        out = os.path.join(work, f"ours{seed}.exr")
        start = time.monotonic()
        subprocess.run(
            [args.bin, "render", "--scene", args.scene, "--method", "path", "--spp", str(args.spp), "--seed", str(seed), "--out", out],
            check=True,
            capture_output=True,
        )
        renders["ours"].append((read_rgb(out).astype(np.float64), time.monotonic() - start))
    figures = {}
    for name, ((a, ta), (b, tb)) in renders.items():
        rel, mean = noise(a, b)
        figures[name] = (rel, mean)
        print(f"{name}: {100 * rel:.2f} % per render of {args.spp} spp, mean {mean:.5f}, {ta:.2f} s and {tb:.2f} s")
    (ro, mo), (rm, mm) = figures["ours"], figures["mitsuba"]
    print(f"variance ours / Mitsuba's: {(ro * mo) ** 2 / (rm * mm) ** 2:.2f}; mean ours / Mitsuba's: {mo / mm:.4f}")


if __name__ == "__main__":
    main()
