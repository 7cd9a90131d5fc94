#!/usr/bin/env python3
"""Mitsuba 3's render of `tests/data/mitsuba/textures.xml` (bitmaps and
checkerboards on every kind of shape; box filter, 96x64), the reference of
the Rust test `mitsuba_images::textures_and_texture_coordinates_agree_with_mitsuba`,
and the two texture images it reads: `uv_grid.png` (8-bit, sRGB) and
`uv_grid.exr` (linear), 4x4 texels whose colours name their column (red),
row (green) and parity (blue), so any flip or shift of the texture
coordinates changes the picture.

Run in a throwaway venv (`pip install mitsuba numpy`), from the repository root:

    python docs/validation/mitsuba_textures.py --spp 16384 \
        --out tests/data/mitsuba/textures_mitsuba.exr
"""

import argparse
import time

import mitsuba as mi
import numpy as np

mi.set_variant("scalar_rgb")

DIR = "tests/data/mitsuba"


def grid():
    """The 4x4 texels, row 0 at the top, values in [0, 1]."""
    texels = np.zeros((4, 4, 3))
    for y in range(4):
        for x in range(4):
            texels[y, x] = [(x + 0.5) / 4, (y + 0.5) / 4, 0.15 + 0.7 * ((x + y) % 2)]
    return texels


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--spp", type=int, default=16384)
    ap.add_argument("--out", required=True)
    args = ap.parse_args()
    texels = grid()
    mi.Bitmap(np.round(texels * 255).astype(np.uint8)).write(f"{DIR}/uv_grid.png")
    mi.Bitmap(texels.astype(np.float32)).write(f"{DIR}/uv_grid.exr")
    scene = mi.load_file(f"{DIR}/textures.xml", spp=args.spp)
    started = time.time()
    image = np.array(mi.render(scene, seed=0))
    print(f"mitsuba {mi.__version__}: {args.spp} spp in {time.time() - started:.1f} s; mean {image.mean():.5f}")
    mi.Bitmap(image.astype(np.float32)).write(args.out)


if __name__ == "__main__":
    main()
