#!/usr/bin/env python3
"""Renders a Mitsuba 3 scene file at SPP samples per pixel (seed 0) to an
EXR, timing `mi.render` alone: the references and the Mitsuba rows of
docs/BENCHMARKS.md ("The bundled studio scene", the tutorials' Cornell box).
Extra NAME=VALUE arguments set the file's `$NAME` parameters.

Run in a throwaway venv (`pip install mitsuba numpy`):

    python docs/validation/mitsuba_render.py scenes/studio.xml 4096 studio_ref.exr
"""

import sys
import time

import mitsuba as mi

mi.set_variant("scalar_rgb")


def main():
    path, spp, out = sys.argv[1], int(sys.argv[2]), sys.argv[3]
    parameters = dict(a.split("=", 1) for a in sys.argv[4:])
    scene = mi.load_file(path, **parameters)
    started = time.time()
    image = mi.render(scene, spp=spp, seed=0)
    print(f"{path} {parameters}: {spp} spp in {time.time() - started:.2f} s")
    mi.util.write_bitmap(out, image)


if __name__ == "__main__":
    main()
