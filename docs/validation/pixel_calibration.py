#!/usr/bin/env python3
"""Per-pixel calibration of rendered images' error bars (issue 40): how often
each pixel's value lies within ±2 of its reported standard errors of a
converged image.

Both images are EXRs as `render` and `fetch` write them: RGB plus a
`variance` channel (the variance of the pixel's estimate, mean over RGB). For
each pixel `p` and channel `c` of the lit mask (`compare --exclude-above 1
--exclude-margin 2`'s pixels of the scored reference, as in
interactive_budgets.py),

    z = (x_pc - r_pc) / sqrt(v_p + w_p),

with `v` the tested image's variance and `w` the converged image's own (a
path-traced image of many samples whose variance channel is its sample
variance over spp): the converged image's noise is part of the difference,
so it is part of the scale. Reported: the share of |z| <= 2 (coverage, 0.954
for normal errors) and the rms of z (1 when the bars are right), overall and
with the share of the scale that is the converged image's own, which must be
small for the figure to say much about the tested image. Needs numpy and
OpenEXR (a throwaway venv):

    /tmp/oidnvenv/bin/python docs/validation/pixel_calibration.py \\
        --converged ref4096.exr image.exr [image.exr ...]
"""

import argparse
import os

import numpy as np
import OpenEXR

from interactive_budgets import lit_mask


def read(path):
    with OpenEXR.File(path) as f:
        channels = f.channels()
        rgb = np.asarray(channels["RGB"].pixels, dtype=np.float64)
        variance = np.asarray(channels["variance"].pixels, dtype=np.float64)
    return rgb, variance


def main():
    root = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--converged", required=True, help="EXR with a variance channel")
    ap.add_argument(
        "--mask-from",
        default=os.path.join(root, "docs", "validation", "data", "mitsuba_cornell_256.exr"),
        help="image whose pixels at most 1 (2 pixels in) are scored",
    )
    ap.add_argument("images", nargs="+")
    args = ap.parse_args()
    with OpenEXR.File(args.mask_from) as f:
        mask = lit_mask(np.asarray(f.channels()["RGB"].pixels))
    r, w = read(args.converged)
    print(f"{int(mask.sum())} pixels × 3 channels")
    print("| image | ±2σ coverage | rms z | converged image's share of the variance |")
    print("|---|---|---|---|")
    for path in args.images:
        x, v = read(path)
        scale = np.sqrt(v + w)[mask][:, None]
        z = (x[mask] - r[mask]) / np.where(scale > 0, scale, np.inf)
        share = float(np.mean(w[mask]) / np.mean(v[mask] + w[mask]))
        coverage = float(np.mean(np.abs(z) <= 2))
        rms = float(np.sqrt(np.mean(z**2)))
        print(f"| {os.path.basename(path)} | {coverage:.3f} | {rms:.2f} | {share:.2f} |", flush=True)


if __name__ == "__main__":
    main()
