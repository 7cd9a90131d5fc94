#!/usr/bin/env python3
"""The auxiliary buffers Intel Open Image Denoise takes beside the colour
(issue 40's comparison, interactive_budgets.py `--aux`): the first hit's
albedo and shading normal per pixel, from Mitsuba 3's `aov` integrator on the
same scene file, written to an `.npz` (`albedo`, `normal`, H×W×3 float32).

A path tracer writes these from its camera rays' first hits at no extra
tracing, so the comparison does not time them; they are rendered here at
enough samples to be nearly noise-free (OIDN is then told `clean_aux`). Run in
a throwaway venv (`pip install mitsuba numpy`):

    python docs/validation/mitsuba_aux.py scenes/cornell-box.xml 64 cornell_aux.npz
"""

import argparse

import mitsuba as mi
import numpy as np

mi.set_variant("scalar_rgb")


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("scene")
    ap.add_argument("spp", type=int)
    ap.add_argument("out")
    args = ap.parse_args()
    scene = mi.load_file(args.scene)
    aov = mi.load_dict({"type": "aov", "aovs": "albedo:albedo,nn:sh_normal"})
    image = np.asarray(mi.render(scene, integrator=aov, spp=args.spp), dtype=np.float32)
    # The aov integrator's channels: its own AOVs in the order named.
    albedo, normal = image[..., -6:-3], image[..., -3:]
    np.savez(args.out, albedo=np.clip(albedo, 0, 1), normal=np.clip(normal, -1, 1))
    print(f"{args.scene}: {image.shape} channels, albedo mean {albedo.mean():.3f}")


if __name__ == "__main__":
    main()
