#!/usr/bin/env python3
"""Irradiance at points of `tests/data/mitsuba/materials.xml` (textures, a
blend with gold, a mask, glass, plastic; a constant environment and a
directional light) measured by Mitsuba 3's `irradiancemeter`, the reference
of the Rust test `mitsuba_irradiance::irradiance_agrees_with_mitsubas_meter`.

Each point gets a meter on a disk of radius 1e-4 facing its normal, lifted
1e-4 off the surface; the meter integrates the incident radiance with the
scene's `path` integrator (`max_depth` 8, so light paths of up to 8 segments
from the point). A meter cannot receive the directional light (a delta
light no sampled direction hits), so its direct part is added here from
Mitsuba's own `emitter.sample_direction` and `scene.ray_test`.

Run in a throwaway venv (`pip install mitsuba numpy`), from the repository root:

    python docs/validation/mitsuba_irradiance_meter.py --spp 65536 \
        --out tests/data/mitsuba/materials_irradiance.csv
"""

import argparse
import os
import time

import mitsuba as mi
import numpy as np

mi.set_variant("scalar_rgb")

SCENE = "tests/data/mitsuba/materials.xml"


def points():
    """(position, normal) pairs on the floor (y = -1) and the back wall
    (z = -1.5): in the open, in shadows, next to the glass and the metal."""
    out = []
    for x in np.linspace(-2.2, 2.2, 9):
        for z in (-1.0, 0.0, 0.6, 1.4):
            out.append(((x, -1.0, z), (0.0, 1.0, 0.0)))
    for x in np.linspace(-2.0, 2.0, 5):
        for y in (-0.6, 0.2, 1.2):
            out.append(((x, y, -1.5), (0.0, 0.0, 1.0)))
    return out


def meter(position, normal):
    p = np.array(position) + 1e-4 * np.array(normal)
    frame = mi.Frame3f(mi.Vector3f(normal))
    rows = np.eye(4)
    rows[:3, 0] = np.array(frame.s) * 1e-4
    rows[:3, 1] = np.array(frame.t) * 1e-4
    rows[:3, 2] = np.array(frame.n) * 1e-4
    rows[:3, 3] = p
    matrix = " ".join(f"{v:.9g}" for v in rows.flatten())
    return f"""<shape type="disk"><transform name="to_world"><matrix value="{matrix}"/></transform>
  <sensor type="irradiancemeter"><film type="hdrfilm"><integer name="width" value="1"/>
  <integer name="height" value="1"/><rfilter type="box"/></film>
  <sampler type="independent"><integer name="sample_count" value="64"/></sampler></sensor></shape>"""


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--spp", type=int, default=65536)
    ap.add_argument("--out", required=True)
    args = ap.parse_args()
    pts = points()
    text = open(SCENE).read()
    # File names in the scene are relative to its folder.
    mi.file_resolver().prepend(os.path.dirname(SCENE))
    # One meter per scene, in place of the camera (Mitsuba refuses several
    # meters in one document).
    start, end = text.index("<sensor"), text.index("</sensor>") + len("</sensor>")
    started = time.time()
    rows = []
    for i, (p, n) in enumerate(pts):
        scene = mi.load_string(text[:start] + meter(p, n) + text[end:])
        [light] = [
            e for e in scene.emitters() if mi.has_flag(e.flags(), mi.EmitterFlags.DeltaDirection)
        ]
        image = np.array(mi.render(scene, spp=args.spp, seed=i)).reshape(-1)[:3]
        # The directional light's direct irradiance, E cos θ if unshadowed.
        it = mi.Interaction3f()
        it.p = mi.Point3f(np.array(p) + 1e-4 * np.array(n))
        it.n = mi.Normal3f(n)
        ds, weight = light.sample_direction(it, mi.Point2f(0.5, 0.5))
        cos = max(0.0, float(np.dot(np.array(ds.d), n)))
        blocked = scene.ray_test(it.spawn_ray(ds.d))
        direct = np.zeros(3) if blocked else np.array(weight) * cos
        rows.append((*p, *n, *(image + direct)))
    print(f"mitsuba {mi.__version__}: {len(pts)} meters at {args.spp} spp in {time.time() - started:.1f} s")
    with open(args.out, "w") as f:
        f.write("x,y,z,nx,ny,nz,r,g,b\n")
        for r in rows:
            f.write(",".join(f"{v:.9g}" for v in r) + "\n")


if __name__ == "__main__":
    main()
