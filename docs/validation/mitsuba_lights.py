#!/usr/bin/env python3
"""Mitsuba 3's render of `tests/data/mitsuba/lights.xml` (point, spot and
directional lights on rough gold, rough plastic and a two-sided disk; box
filter, 64x64), the reference of the Rust test
`mitsuba_images::delta_lights_and_rough_materials_agree_with_mitsuba`.

Run in a throwaway venv (`pip install mitsuba numpy`), from the repository root:

    python docs/validation/mitsuba_lights.py --spp 16384 \
        --out tests/data/mitsuba/lights_mitsuba_64.exr
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
    scene = mi.load_file("tests/data/mitsuba/lights.xml", spp=args.spp)
    started = time.time()
    image = np.array(mi.render(scene, seed=0))
    print(f"mitsuba {mi.__version__}: {args.spp} spp in {time.time() - started:.1f} s; mean {image.mean():.5f}")
    mi.Bitmap(image.astype(np.float32)).write(args.out)


if __name__ == "__main__":
    main()
