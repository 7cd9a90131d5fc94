#!/usr/bin/env python3
"""Mitsuba 3's render of `tests/data/mitsuba/hide_emitters.xml` (an area
light and an environment hidden from the camera; box filter, 64x64), the
reference of the Rust test
`mitsuba_images::hidden_emitters_agree_with_mitsuba`. The file asks for a
gaussian filter, which bmc-irradiance approximates by a box (with a
warning), so the reference is rendered with a box.

Run in a throwaway venv (`pip install mitsuba numpy`), from the repository root:

    python docs/validation/mitsuba_hide_emitters.py --spp 16384 \
        --out tests/data/mitsuba/hide_emitters_mitsuba.exr
"""

import argparse
import time

import mitsuba as mi
import numpy as np

mi.set_variant("scalar_rgb")


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--spp", type=int, default=16384)
    ap.add_argument("--out", required=True)
    args = ap.parse_args()
    text = open("tests/data/mitsuba/hide_emitters.xml").read()
    text = text.replace('<rfilter type="gaussian"/>', '<rfilter type="box"/>')
    scene = mi.load_string(text.replace("$spp", str(args.spp)))
    started = time.time()
    image = np.array(mi.render(scene, seed=0))
    print(f"mitsuba {mi.__version__}: {args.spp} spp in {time.time() - started:.1f} s; mean {image.mean():.5f}")
    mi.Bitmap(image.astype(np.float32)).write(args.out)


if __name__ == "__main__":
    main()
