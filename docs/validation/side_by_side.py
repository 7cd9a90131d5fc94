#!/usr/bin/env python3
"""docs/studio.png: an image of ours (left) beside Mitsuba 3's render of the
same file (right), both tone-mapped as the service's PNGs are (linear to
sRGB, clamped, exposure 0), with a 4-pixel white gap.

Run in a throwaway venv (`pip install mitsuba numpy`):

    python docs/validation/side_by_side.py studio_final.exr studio_ref.exr docs/studio.png
"""

import sys

import mitsuba as mi
import numpy as np

mi.set_variant("scalar_rgb")


def srgb(x):
    x = np.clip(x, 0.0, 1.0)
    return np.where(x <= 0.0031308, 12.92 * x, 1.055 * x ** (1 / 2.4) - 0.055)


def main():
    ours, theirs, out = sys.argv[1:4]
    a = np.array(mi.Bitmap(ours))[..., :3]
    b = np.array(mi.Bitmap(theirs))[..., :3]
    gap = np.ones((a.shape[0], 4, 3))
    image = np.concatenate([srgb(a), gap, srgb(b)], axis=1)
    mi.util.write_bitmap(out, mi.Bitmap((image * 255 + 0.5).astype(np.uint8)))


if __name__ == "__main__":
    main()
