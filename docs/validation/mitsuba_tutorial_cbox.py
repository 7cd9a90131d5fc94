#!/usr/bin/env python3
"""Mitsuba 3's render of the tutorials' Cornell box with a glass and a
mirror sphere (`tests/data/mitsuba-tutorials/cbox.xml`, the file of
mitsuba-renderer/mitsuba-tutorials `scenes/cbox.xml`), the reference of the
Rust test `mitsuba_images::cbox_with_glass_and_mirror_agrees_with_mitsuba`.

The file is loaded as it is, with its own `max_depth` (6) and its film's
`tent` filter (which this project's film reads as Mitsuba does), at a
resolution of 64x64. Rendered with `--spp` samples per pixel in two
independent halves (seeds 0 and 1).

Run in a throwaway venv (`pip install mitsuba numpy`), from the repository root:

    python docs/validation/mitsuba_tutorial_cbox.py --spp 16384 \
        --out tests/data/mitsuba-tutorials/cbox_mitsuba_64.exr

Prints the time taken and the relative RMSE between the two halves.
"""

import argparse
import pathlib
import time

import mitsuba as mi
import numpy as np

mi.set_variant("scalar_rgb")


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--spp", type=int, default=16384)
    ap.add_argument("--res", type=int, default=64)
    ap.add_argument("--max-depth", type=int, help="overrides the file's max_depth (6)")
    ap.add_argument("--out", required=True)
    args = ap.parse_args()
    path = pathlib.Path("tests/data/mitsuba-tutorials/cbox.xml")
    text = path.read_text()
    assert '<rfilter type="tent"/>' in text
    # Load from the scene's folder so its relative mesh paths resolve.
    mi.file_resolver().prepend(str(path.parent.resolve()))
    params = {"res": args.res, "spp": args.spp // 2}
    if args.max_depth is not None:
        params["max_depth"] = args.max_depth
    scene = mi.load_string(text, **params)
    started = time.time()
    halves = [np.array(mi.render(scene, seed=seed, spp=args.spp // 2)) for seed in (0, 1)]
    seconds = time.time() - started
    image = 0.5 * (halves[0] + halves[1])
    mean = image.mean()
    nrmse_halves = np.sqrt(((halves[0] - halves[1]) ** 2).mean()) / mean
    mi.Bitmap(image.astype(np.float32)).write(args.out)
    print(f"mitsuba {mi.__version__}: {args.res}x{args.res}, {args.spp} spp in {seconds:.1f} s; "
          f"mean {mean:.5f}; relative RMSE between halves {nrmse_halves:.4f}")


if __name__ == "__main__":
    main()
