#!/usr/bin/env python3
"""Full global illumination at chosen Cornell-box points with Mitsuba 3's plain
`path` integrator (max_depth = 64, no hide_emitters split), for checking
bmc-irradiance where the direct + indirect split of mitsuba_irradiance.py
misses the light's reflection (see docs/VALIDATION.md).

Reuses the scene set-up of mitsuba_irradiance.py and the estimator of
mitsuba_checks.py from this directory. Prints one JSON line per point: mean
and standard error over K renders (seeds 900000 + 1000 i + j, distinct from
the other scripts' seeds).

Usage: mitsuba_plain_gi.py POINTS.csv INDICES SPP K
  e.g. mitsuba_plain_gi.py docs/validation/cornell_points.csv 5,10,11,12 400000 12
"""
import json
import os
import sys
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

import mitsuba as mi  # noqa: E402

mi.set_variant("scalar_rgb")

from cornell_common import read_points  # noqa: E402
from mitsuba_checks import mean_se  # noqa: E402
from mitsuba_irradiance import KINDS, meter_scene_dict  # noqa: E402


def main():
    points_csv, indices, spp, k = sys.argv[1], sys.argv[2], int(sys.argv[3]), int(sys.argv[4])
    points = read_points(points_csv)
    for i in (int(x) for x in indices.split(",")):
        scene = mi.load_dict(meter_scene_dict(points[i].p, points[i].n, KINDS["gi_full"]))
        start = time.time()
        mean, se = mean_se(scene, spp, k, 900000 + 1000 * i)
        print(json.dumps({"point": i, "mean": mean.tolist(), "se": se.tolist(), "spp": spp, "k": k,
                          "wall_s": round(time.time() - start, 1)}), flush=True)


if __name__ == "__main__":
    main()
