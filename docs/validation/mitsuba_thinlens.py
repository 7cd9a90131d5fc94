#!/usr/bin/env python3
"""Mitsuba 3's render of `tests/data/mitsuba/thinlens.xml` (a thin-lens
camera focused on the middle of three spheres; box filter, 96x64), the
reference of the Rust test
`mitsuba_images::thin_lens_depth_of_field_agrees_with_mitsuba`.

Run in a throwaway venv (`pip install mitsuba numpy`), from the repository root:

    python docs/validation/mitsuba_thinlens.py --spp 16384 \
        --out tests/data/mitsuba/thinlens_mitsuba.exr
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
    scene = mi.load_file("tests/data/mitsuba/thinlens.xml", spp=args.spp)
    started = time.time()
    image = np.array(mi.render(scene, seed=0))
    print(f"mitsuba {mi.__version__}: {args.spp} spp in {time.time() - started:.1f} s; mean {image.mean():.5f}")
    mi.Bitmap(image.astype(np.float32)).write(args.out)


if __name__ == "__main__":
    main()
