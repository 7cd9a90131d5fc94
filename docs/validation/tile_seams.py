#!/usr/bin/env python3
"""Issue 67's seam measure: does an image's error jump at tile boundaries?

For each image, the error against a converged reference,
`e = mean_c(img_c - ref_c) / sqrt(mean_c(ref_c^2) + 0.01)` per pixel (the
relative error of the issue's per-pixel metric, signed), is blurred over
`--blur` pixels along each line (a box along the columns for the vertical
lines, along the rows for the horizontal ones, so the blur never crosses the
line it measures), and the jump across the line between pixel columns
`x - 1` and `x` is `rms_y(E(x, y) - E(x - 1, y))` (rows alike). The ratio
reported is the mean jump across tile boundaries (`x` a multiple of
`--tile`) over the mean jump across every other line inside the image: 1
where tiles leave no mark, above 1 where they do (the issue asks for at most
1.2). A path-traced image, whose pixels know nothing of tiles, is the
control: its ratio is what the image's structure alone gives. Pixels where the reference exceeds `--exclude-above` (emitters), and
those within `--exclude-margin` of them, are left out of both sides of a
jump, as `bmc-irradiance compare` leaves them out.

    python3 docs/validation/tile_seams.py --reference ref.exr a.exr b.exr

Needs numpy and OpenEXR (a throwaway venv).
"""

import argparse

import numpy as np

from interactive_budgets import lit_mask, read_rgb


def box_along(a, width, axis):
    """Mean over `width` consecutive pixels along `axis` (valid part)."""
    kernel = np.ones(width) / width
    return np.apply_along_axis(lambda v: np.convolve(v, kernel, mode="valid"), axis, a)


def jumps(err, keep, tile, blur):
    """Mean jump across tile boundaries and across the other lines, vertical
    and horizontal lines together."""
    boundary, inside = [], []
    for axis in (1, 0):
        e = np.moveaxis(err, axis, 0)
        k = np.moveaxis(keep, axis, 0)
        n = e.shape[0]
        for x in range(1, n):
            both = k[x] & k[x - 1]
            d = np.where(both, e[x] - e[x - 1], 0.0)
            # Blurred along the line: the mean of `blur` consecutive
            # differences where all of them are kept.
            counts = box_along(both.astype(np.float64), blur, 0) * blur
            sums = box_along(d, blur, 0) * blur
            full = counts > blur - 0.5
            if not full.any():
                continue
            jump = np.median(np.abs(sums[full] / blur))
            (boundary if x % tile == 0 else inside).append(jump)
    return np.mean(boundary), np.mean(inside)


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("images", nargs="+")
    p.add_argument("--reference", required=True)
    p.add_argument("--tile", type=int, default=64)
    p.add_argument("--blur", type=int, default=4)
    p.add_argument("--exclude-above", type=float, default=1.0)
    p.add_argument("--exclude-margin", type=int, default=2)
    args = p.parse_args()
    ref = read_rgb(args.reference)
    keep = lit_mask(ref, args.exclude_above, args.exclude_margin)
    scale = np.sqrt(np.mean(ref**2, axis=-1) + 0.01)
    for path in args.images:
        img = read_rgb(path)
        err = np.mean(img - ref, axis=-1) / scale
        at, elsewhere = jumps(err, keep, args.tile, args.blur)
        print(
            f"{path}: jump across tile boundaries {at:.4f}, across other lines "
            f"{elsewhere:.4f}, ratio {at / elsewhere:.3f}"
        )


if __name__ == "__main__":
    main()
