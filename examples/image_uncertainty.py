#!/usr/bin/env python3
"""A scene's camera image and its per-pixel uncertainty, side by side.

    cargo run --release -- serve &
    pip install './python[plot]'
    python3 examples/image_uncertainty.py --scene cornell-box --preset final --out cornell-uncertainty.png

The image is assembled from the service's reproducible GET tiles of a
quality preset (draft, preview or final; `--pass` for an earlier pass of
the progressive render), fetched concurrently (a progress bar shows on a
terminal). Left: the radiance, tone-mapped as the service's PNG tiles
are. Right: the standard error of each pixel's estimate in W/(m²·sr) (the
square root of the service's per-pixel variance, which is averaged over
R, G and B), on a log colour scale. The linear image is also written as
OpenEXR (R, G, B and variance channels) beside the plot.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from bmc_irradiance import Client, srgb8


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--url", default="http://127.0.0.1:8080")
    parser.add_argument("--scene", default="cornell-box")
    parser.add_argument("--preset", default="preview",
                        help="quality preset: draft, preview or final (GET /v1/presets)")
    parser.add_argument("--pass", dest="pass_index", type=int, default=None,
                        help="0-based pass of the progressive render (default: the last)")
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--size", type=int, default=64, help="tile side in pixels")
    parser.add_argument("--workers", type=int, default=4)
    parser.add_argument("--exposure", type=float, default=0.0, help="stops")
    parser.add_argument("--out", default="uncertainty.png")
    args = parser.parse_args()

    client = Client(args.url, timeout=600)
    image = client.image(args.scene, preset=args.preset, pass_index=args.pass_index,
                         seed=args.seed, size=args.size, workers=args.workers)
    exr = Path(args.out).with_suffix(".exr")
    image.save_exr(exr)
    if image.std_dev is None:
        sys.exit("the service sent no per-pixel variance")
    std_dev = image.std_dev
    relative = std_dev / np.maximum(image.rgb.mean(axis=2), 1e-6)
    print(f"{image.width}×{image.height}, {image.rays} rays; median standard error "
          f"{np.median(std_dev):.4g} W/(m²·sr), median relative {np.median(relative):.1%}",
          file=sys.stderr)

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.colors import LogNorm

    fig, (left, right) = plt.subplots(1, 2, figsize=(10, 4.4))
    left.imshow(srgb8(image.rgb, args.exposure))
    shown_pass = "last pass" if args.pass_index is None else f"pass {args.pass_index}"
    left.set_title(f"{args.scene}: {args.preset} preset, {shown_pass}")
    positive = std_dev[std_dev > 0]
    norm = LogNorm(vmin=max(positive.min(), np.percentile(positive, 1)), vmax=positive.max()) \
        if positive.size else None
    cmap = plt.get_cmap("magma").copy()
    cmap.set_bad("black")  # pixels with zero variance
    shown = right.imshow(np.where(std_dev > 0, std_dev, np.nan), cmap=cmap, norm=norm)
    right.set_title("standard error per pixel (black: zero)")
    fig.colorbar(shown, ax=right, label="W/(m²·sr)")
    for ax in (left, right):
        ax.set_xticks([])
        ax.set_yticks([])
    fig.tight_layout()
    fig.savefig(args.out, dpi=90)
    print(f"wrote {args.out} and {exr}", file=sys.stderr)


if __name__ == "__main__":
    main()
