#!/usr/bin/env python3
"""Reference image of Mitsuba 3's Cornell box, rendered by Mitsuba (scalar_rgb).

Scene: mi.cornell_box() (camera, 256x256 film, materials as in
docs/validation/data/mitsuba-cornell-box.json) with two changes: the film's
reconstruction filter is ``box`` (a pixel is the plain average of radiance
over its area) and the integrator is ``path`` with ``max_depth`` (default 64,
``rr_depth`` default 5).  The image is rendered as two independent halves
(seeds ``--seed`` and ``--seed + 1``; Mitsuba offsets seeds by the pixel count,
so the halves use disjoint random streams), each with spp/2 samples per pixel.

Outputs (in --out-dir, prefix --name):
  NAME.exr        float32 RGB, mean of the two halves (spp samples/pixel)
  NAME_a.exr, NAME_b.exr   the two halves (spp/2 each)
  NAME.png        sRGB 8-bit tone-mapped (clamp) preview of NAME.exr
  NAME_meta.json  spp, times, noise statistics

Noise statistics (m = mean of the full image over all pixels and channels):
  nrmse_halves = RMS(A - B) / m           (relative RMSE between the halves)
  nrmse_full   = RMS(A - B) / (2 m)       (estimated RMSE of the full image vs the
                                           converged image, relative to m)

Example:
    python mitsuba_reference_image.py --spp 16 --out-dir data --name test16
"""
from __future__ import annotations

import argparse
import json
import os
import sys
import time

import numpy as np


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--spp", type=int, default=1024, help="total samples per pixel (split in two halves)")
    ap.add_argument("--res", type=int, default=256)
    ap.add_argument("--max-depth", type=int, default=64)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--threads", type=int, default=0, help="Mitsuba worker threads (0 = all cores)")
    ap.add_argument("--out-dir", default="data")
    ap.add_argument("--name", default="mitsuba_cornell_256")
    args = ap.parse_args(argv)

    import drjit as dr
    import mitsuba as mi
    mi.set_variant("scalar_rgb")
    if args.threads:
        dr.set_thread_count(args.threads)

    d = mi.cornell_box()
    d["integrator"] = {"type": "path", "max_depth": args.max_depth}
    d["sensor"]["film"]["width"] = d["sensor"]["film"]["height"] = args.res
    d["sensor"]["film"]["rfilter"] = {"type": "box"}
    scene = mi.load_dict(d)
    os.makedirs(args.out_dir, exist_ok=True)
    half = args.spp // 2
    imgs, times, cpus = [], [], []
    for j, tag in enumerate("ab"):
        t = time.time()
        c = time.process_time()
        img = mi.render(scene, spp=half, seed=args.seed + j)
        times.append(time.time() - t)
        cpus.append(time.process_time() - c)
        a = np.array(img, dtype=np.float32)
        imgs.append(a)
        mi.Bitmap(a).write(os.path.join(args.out_dir, f"{args.name}_{tag}.exr"))
        print(f"half {tag}: {half} spp in {times[-1]:.1f} s", flush=True)
    A, B = (x.astype(np.float64) for x in imgs)
    F = 0.5 * (A + B)
    mi.Bitmap(F.astype(np.float32)).write(os.path.join(args.out_dir, f"{args.name}.exr"))
    png = mi.Bitmap(F.astype(np.float32)).convert(mi.Bitmap.PixelFormat.RGB,
                                                  mi.Struct.Type.UInt8, srgb_gamma=True)
    png.write(os.path.join(args.out_dir, f"{args.name}.png"))
    m = F.mean()
    rms = float(np.sqrt(np.mean((A - B) ** 2)))
    per_ch = [float(np.sqrt(np.mean((A[..., c] - B[..., c]) ** 2)) / F[..., c].mean()) for c in range(3)]
    meta = {
        "command": " ".join([os.path.basename(sys.executable)] + sys.argv),
        "mitsuba": mi.__version__, "variant": "scalar_rgb", "threads": dr.thread_count(),
        "res": args.res, "spp_total": 2 * half, "spp_per_half": half, "max_depth": args.max_depth,
        "rfilter": "box", "seeds": [args.seed, args.seed + 1],
        "time_s_halves": [round(t, 2) for t in times], "time_s_total": round(sum(times), 2),
        "cpu_s_halves": [round(t, 2) for t in cpus], "cpu_s_total": round(sum(cpus), 2),
        "mean_rgb": F.reshape(-1, 3).mean(0).tolist(),
        "nrmse_halves": rms / m, "nrmse_halves_per_channel": per_ch,
        "nrmse_full_estimate": rms / (2 * m),
    }
    with open(os.path.join(args.out_dir, f"{args.name}_meta.json"), "w") as f:
        json.dump(meta, f, indent=1)
    print(json.dumps(meta, indent=1))


if __name__ == "__main__":
    main()
