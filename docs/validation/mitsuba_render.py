#!/usr/bin/env python3
"""Renders a Mitsuba 3 scene file at SPP samples per pixel to an EXR,
timing `mi.render` alone: the references and the Mitsuba rows of
docs/BENCHMARKS.md ("The bundled studio scene", the tutorials' Cornell box
and lego). NAME=VALUE arguments set the file's `$NAME` parameters; a
reference takes another `--seed` than the render it judges.

Run in a throwaway venv (`pip install mitsuba numpy`):

    python docs/validation/mitsuba_render.py scenes/studio.xml 4096 studio_ref.exr
"""

import argparse
import time

import mitsuba as mi

mi.set_variant("scalar_rgb")


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("scene")
    ap.add_argument("spp", type=int)
    ap.add_argument("out")
    ap.add_argument("parameters", nargs="*", help="NAME=VALUE")
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args()
    parameters = dict(a.split("=", 1) for a in args.parameters)
    scene = mi.load_file(args.scene, **parameters)
    started = time.time()
    image = mi.render(scene, spp=args.spp, seed=args.seed)
    print(f"{args.scene} {parameters}: {args.spp} spp (seed {args.seed}) in {time.time() - started:.2f} s")
    mi.util.write_bitmap(args.out, image)


if __name__ == "__main__":
    main()
