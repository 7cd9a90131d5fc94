#!/usr/bin/env python3
"""Issue 40's comparison at interactive budgets: path tracing plus Intel Open
Image Denoise against the service's presets, error vs truth and wall time in
one run.

- Path tracing: `bmc-irradiance render --method path --spp S` (all cores),
  then `pyoidn.denoise(color, hdr=True)` on its RGB, and with `--aux` (an
  `.npz` of mitsuba_aux.py) again with the first hits' albedo and normal
  buffers (`clean_aux=True`), as a path tracer would hand them to OIDN. The
  time is the render's wall time plus the denoiser's: the buffers come from
  the camera rays' first hits, so they are not timed. Each budget takes the
  better of the two.
- The service: for each preset a freshly started server on an empty data
  directory (cold), `bmc-irradiance fetch --preset P --pass k` of the whole
  image as GET tiles for each of the preset's passes in turn (as the
  viewer's ladder asks for them: pass k renders only what passes 0..k-1 left
  to do); the time of pass k is the fetches' wall time up to it. With
  `--denoise`, each preset again on another cold server with `fetch
  --denoise` (the tiles' own denoiser, docs/math.md §16.6).

  With `--oidn-ours`, each of the service's images is also handed to OIDN
  (with the buffers when `--aux` is given), its time the fetches' plus the
  denoiser's: whether the gap to path tracing + OIDN is the denoiser's or
  lies in the images themselves. OIDN is a peer, not part of the service, so
  these rows make a column of their own.

At the end, for each budget (`--budgets`, seconds), the best image of each
side whose time is within it.

The error is the relative RMSE against the reference EXR over the pixels
`compare --exclude-above 1 --exclude-margin 2` keeps (emitters and the pixels
within 2 of them left out), reported raw and "vs truth": the reference's own
relative noise on that mask (`--reference-noise`, docs/BENCHMARKS.md) removed
in quadrature. Needs numpy, OpenEXR and pyoidn (a throwaway venv, never a
dependency of the project):

    python3 -m venv /tmp/oidnvenv && /tmp/oidnvenv/bin/pip install pyoidn numpy OpenEXR
    cargo build --release
    /tmp/mtsvenv/bin/python docs/validation/mitsuba_aux.py scenes/cornell-box.xml 64 aux.npz
    /tmp/oidnvenv/bin/python docs/validation/interactive_budgets.py --aux aux.npz \\
        --spp 4 16 32 96 192 --presets draft preview standard final
"""

import argparse
import json
import os
import subprocess
import tempfile
import time

import numpy as np
import OpenEXR


def read_rgb(path):
    with OpenEXR.File(path) as f:
        channels = f.channels()
        if "RGB" in channels:
            rgb = channels["RGB"].pixels
        else:
            rgb = np.stack([channels[c].pixels for c in ("R", "G", "B")], axis=-1)
    return np.asarray(rgb, dtype=np.float32)


def write_rgb(path, rgb):
    header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}
    with OpenEXR.File(header, {"RGB": np.ascontiguousarray(rgb, dtype=np.float32)}) as f:
        f.write(path)


def lit_mask(reference, limit=1.0, margin=2):
    """`compare --exclude-above limit --exclude-margin margin`'s pixels."""
    keep = (reference <= limit).all(axis=-1)
    for _ in range(margin):
        shrunk = keep.copy()
        for dy in (-1, 0, 1):
            for dx in (-1, 0, 1):
                shrunk &= np.roll(np.roll(keep, dy, 0), dx, 1)
        keep = shrunk
    return keep


def trimmed_error(rgb, reference, mask):
    """Issue 67's per-pixel error: the RMS of `(img - ref)^2 / (ref^2 + 0.01)`
    over the mask's pixel values, the worst 0.1 % dropped (the reference's own
    noise included)."""
    r = np.sort((((rgb - reference) ** 2) / (reference**2 + 0.01))[mask].ravel())
    return float(np.sqrt(r[: int(len(r) * 0.999)].mean()))


def block_error(rgb, reference, mask, b=8):
    """Relative RMS of the means of `b`×`b` blocks over the mask (blocks with
    a masked pixel count their masked pixels only)."""
    h, w = mask.shape[0] // b * b, mask.shape[1] // b * b
    k = mask[:h, :w]

    def means(a):
        s = (a[:h, :w] * k[..., None]).reshape(h // b, b, w // b, b, 3).sum((1, 3))
        n = k.reshape(h // b, b, w // b, b).sum((1, 3))[..., None]
        return s / np.maximum(n, 1), n[..., 0] > 0

    img, some = means(rgb)
    ref, _ = means(reference)
    return float(np.sqrt(np.sum((img - ref)[some] ** 2) / np.sum(ref[some] ** 2)))


class Scorer:
    def __init__(self, reference_path, reference_noise):
        self.reference = read_rgb(reference_path)
        self.mask = lit_mask(self.reference)
        self.noise = reference_noise

    def __call__(self, rgb):
        a, b = rgb[self.mask], self.reference[self.mask]
        raw = float(np.sqrt(np.mean((a - b) ** 2)) / np.mean(b))
        return raw, float(np.sqrt(max(raw**2 - self.noise**2, 0.0)))

    def issue67(self, rgb):
        """(trimmed per-pixel, 8×8 blocks), both against the reference as it is."""
        return trimmed_error(rgb, self.reference, self.mask), block_error(rgb, self.reference, self.mask)


def timed(cmd):
    start = time.monotonic()
    subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    return time.monotonic() - start


def main():
    import pyoidn  # here, so that pixel_calibration.py can import this module without it

    root = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--bin", default=os.path.join(root, "target", "release", "bmc-irradiance"))
    ap.add_argument("--scene", default="cornell-box", help="the scene's id and file stem in --scenes-dir")
    ap.add_argument("--scenes-dir", default=os.path.join(root, "scenes"), help="the service's scenes directory")
    ap.add_argument("--size", type=int, default=64, help="side of the GET tiles fetched")
    ap.add_argument(
        "--reference", default=os.path.join(root, "docs", "validation", "data", "mitsuba_cornell_256.exr")
    )
    ap.add_argument("--reference-noise", type=float, default=0.0299)
    ap.add_argument("--spp", type=int, nargs="*", default=[4, 16, 64, 256])
    ap.add_argument("--presets", nargs="*", default=["draft", "preview", "final"])
    ap.add_argument("--port", type=int, default=18777)
    ap.add_argument("--budgets", type=float, nargs="*", default=[0.3, 1, 2, 5, 10])
    ap.add_argument("--aux", help="albedo and normal buffers (.npz of mitsuba_aux.py) for OIDN")
    ap.add_argument("--denoise", action="store_true", help="also each preset's denoised tiles (docs/math.md §16.6)")
    ap.add_argument("--oidn-ours", action="store_true", help="also each of the service's images through OIDN")
    args = ap.parse_args()
    score = Scorer(args.reference, args.reference_noise)
    work = tempfile.mkdtemp(prefix="budgets-")
    stem = os.path.join(args.scenes_dir, args.scene)
    scene_file = next(f"{stem}{ext}" for ext in (".json", ".xml") if os.path.exists(f"{stem}{ext}"))
    print(f"{int(score.mask.sum())} of {score.mask.size} pixels compared")
    print("| what | time, s | rel. RMSE raw | vs truth | trimmed per pixel | 8×8 blocks |")
    print("|---|---|---|---|---|---|")
    pyoidn.denoise(np.zeros((8, 8, 3), np.float32), hdr=True)  # the device's start-up, not timed
    aux = None
    if args.aux:
        with np.load(args.aux) as f:
            aux = {k: np.ascontiguousarray(f[k], dtype=np.float32) for k in ("albedo", "normal")}
    rows = []  # (side, what, seconds, vs truth, trimmed, blocks)

    def row(side, what, seconds, rgb):
        raw, truth = score(rgb)
        trimmed, blocks = score.issue67(rgb)
        print(f"| {what} | {seconds:.2f} | {raw:.4f} | {truth:.4f} | {trimmed:.4f} | {blocks:.4f} |", flush=True)
        if side:
            rows.append((side, what, seconds, truth, trimmed, blocks))

    for spp in args.spp:
        out = os.path.join(work, f"path{spp}.exr")
        wall = timed([args.bin, "render", "--scene", scene_file, "--method", "path", "--spp", str(spp), "--out", out])
        noisy = read_rgb(out)
        row(None, f"path {spp} spp", wall, noisy)
        start = time.monotonic()
        clean = pyoidn.denoise(noisy, hdr=True)
        denoise = time.monotonic() - start
        write_rgb(os.path.join(work, f"path{spp}_oidn.exr"), clean)
        row("path tracing + OIDN", f"path {spp} spp + OIDN", wall + denoise, clean)
        if aux is not None:
            start = time.monotonic()
            clean = pyoidn.denoise(noisy, aux["albedo"], aux["normal"], hdr=True, clean_aux=True)
            denoise = time.monotonic() - start
            write_rgb(os.path.join(work, f"path{spp}_oidn_aux.exr"), clean)
            row("path tracing + OIDN", f"path {spp} spp, albedo and normal + OIDN", wall + denoise, clean)
    variants = [False, True] if args.denoise else [False]
    for preset, denoised in [(p, d) for p in args.presets for d in variants]:
        tag = f"{preset}-denoised" if denoised else preset
        data = os.path.join(work, f"data-{tag}")
        os.makedirs(data)
        env = dict(
            os.environ,
            BMC_SERVER__BIND=f"127.0.0.1:{args.port}",
            BMC_CACHE__DATA_DIR=data,
            BMC_SCENES__DIR=args.scenes_dir,
        )
        server = subprocess.Popen([args.bin, "serve"], env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        try:
            url = f"http://127.0.0.1:{args.port}"
            for _ in range(200):
                try:
                    subprocess.run(["curl", "-sf", f"{url}/ready"], check=True, capture_output=True)
                    break
                except subprocess.CalledProcessError:
                    time.sleep(0.1)
            listed = subprocess.run(["curl", "-sf", f"{url}/v1/presets"], check=True, capture_output=True).stdout
            passes = next(p["passes"] for p in json.loads(listed) if p["name"] == preset)
            wall = 0.0
            for k in range(passes):
                out = os.path.join(work, f"{tag}-{k}.exr")
                fetch = [args.bin, "fetch", "--url", url, "--scene", args.scene, "--preset", preset]
                fetch += ["--size", str(args.size)]
                fetch += ["--denoise"] if denoised else []
                wall += timed(fetch + ["--pass", str(k), "--out", out])
                image = read_rgb(out)
                what = f"`{preset}` pass {k + 1} of {passes}" + (", denoised" if denoised else "")
                row("the service", f"service {what}, cold", wall, image)
                if args.oidn_ours and not denoised:
                    start = time.monotonic()
                    if aux is None:
                        clean = pyoidn.denoise(image, hdr=True)
                    else:
                        clean = pyoidn.denoise(image, aux["albedo"], aux["normal"], hdr=True, clean_aux=True)
                    seconds = wall + time.monotonic() - start
                    row("the service + OIDN", f"service {what} + OIDN", seconds, clean)
        finally:
            server.terminate()
            server.wait()
    print()
    sides = ["path tracing + OIDN", "the service"] + (["the service + OIDN"] if args.oidn_ours else [])
    # Each side's best image within each budget: by the error vs truth, and
    # by issue 67's trimmed per-pixel error (its 8×8-block error beside it).
    for metric, index in (("vs truth", 3), ("trimmed per pixel / 8×8 blocks", 4)):
        print(f"\nbest by {metric}")
        print("| budget | " + " | ".join(sides) + " |")
        print("|---" * (len(sides) + 1) + "|")
        for budget in args.budgets:
            best = []
            for side in sides:
                within = [r for r in rows if r[0] == side and r[2] <= budget]
                if within:
                    r = min(within, key=lambda r: r[index])
                    figure = f"{100 * r[3]:.2f} %" if index == 3 else f"{100 * r[4]:.2f} % / {100 * r[5]:.2f} %"
                    best.append(f"{figure} ({r[1]}, {r[2]:.2f} s)")
                else:
                    best.append("–")
            print(f"| {budget:g} s | " + " | ".join(best) + " |", flush=True)


if __name__ == "__main__":
    main()
