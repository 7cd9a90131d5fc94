#!/usr/bin/env python3
"""Mitsuba 3's render of `tests/data/mitsuba/envmap.xml` (a rotated, scaled
Radiance HDR environment map seen directly and lighting a diffuse and a
rough metal sphere; box filter, 96x64), the reference of the Rust test
`mitsuba_images::hdr_environment_map_agrees_with_mitsuba`, and the map
`sky.hdr` it reads: 32x16 texels, coarse enough that the lookup's
interpolation shows.

Run in a throwaway venv (`pip install mitsuba numpy`), from the repository root:

    python docs/validation/mitsuba_envmap.py --spp 16384 \
        --out tests/data/mitsuba/envmap_mitsuba.exr
"""

import argparse
import time

import mitsuba as mi
import numpy as np

mi.set_variant("scalar_rgb")

DIR = "tests/data/mitsuba"


def sky(width=32, height=16):
    """Rows from the +Y pole (top) to the -Y pole."""
    texels = np.zeros((height, width, 3), dtype=np.float32)
    for y in range(height):
        for x in range(width):
            up = 1.0 - (y + 0.5) / height * 2.0  # cos(theta), roughly
            if up > 0:
                texels[y, x] = [0.3 + 0.4 * up, 0.5 + 0.3 * up, 0.9 + 0.2 * x / width]
            else:
                texels[y, x] = [0.15, 0.12, 0.1]
    # A warm patch (a low sun, spread over a few texels).
    texels[4:7, 9:12] = [8.0, 6.5, 4.0]
    return texels


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--spp", type=int, default=16384)
    ap.add_argument("--out", required=True)
    args = ap.parse_args()
    mi.Bitmap(sky()).write(f"{DIR}/sky.hdr")
    scene = mi.load_file(f"{DIR}/envmap.xml", spp=args.spp)
    started = time.time()
    image = np.array(mi.render(scene, seed=0))
    print(f"mitsuba {mi.__version__}: {args.spp} spp in {time.time() - started:.1f} s; mean {image.mean():.5f}")
    mi.Bitmap(image.astype(np.float32)).write(args.out)


if __name__ == "__main__":
    main()
