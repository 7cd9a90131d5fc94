#!/usr/bin/env python3
"""Mitsuba 3's values of the irradiance meters of `tests/data/mitsuba/meters.xml`
(an `irradiancemeter` on each of three shapes), the reference of the Rust test
`mitsuba_irradiance::the_scenes_meters_agree_with_mitsubas`: each meter rendered
at `--spp` samples, written as `meter,r,g,b,se_r,se_g,se_b` with the standard
error of the mean from 16 independent renders (seeds 0-15) of `spp/16`
samples each. Mitsuba 3.9.1 refuses a scene with two meters ("An endpoint can
be only be attached to a single shape": its parser merges the identical
sensor elements), so each meter is loaded from the file with the other
meters' `<sensor>` elements removed, their shapes kept.

Run in a throwaway venv (`pip install mitsuba numpy`), from the repository root:

    python docs/validation/mitsuba_meters.py --spp 4194304 \
        --out tests/data/mitsuba/meters_mitsuba.csv
"""

import argparse
import re
import time

import mitsuba as mi
import numpy as np

mi.set_variant("scalar_rgb")


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--spp", type=int, default=4194304)
    ap.add_argument("--out", required=True)
    args = ap.parse_args()
    text = open("tests/data/mitsuba/meters.xml").read()
    sensors = re.findall(r'<sensor type="irradiancemeter".*?</sensor>', text, re.S)
    rows = ["meter,r,g,b,se_r,se_g,se_b"]
    for kept in sensors:
        alone = text
        for other in sensors:
            if other != kept:
                alone = alone.replace(other, "")
        scene = mi.load_string(alone)
        started = time.time()
        runs = np.array(
            [np.array(mi.render(scene, spp=args.spp // 16, seed=s)).reshape(3) for s in range(16)]
        )
        mean, se = runs.mean(axis=0), runs.std(axis=0, ddof=1) / 4.0
        name = re.search(r'id="(\w+)_sensor"', kept).group(1)
        print(f"{name}: {mean} ± {se} ({time.time() - started:.1f} s)")
        rows.append(",".join([name] + [f"{v:.6g}" for v in (*mean, *se)]))
    open(args.out, "w").write("\n".join(rows) + "\n")


if __name__ == "__main__":
    main()
