#!/usr/bin/env python3
"""Fetch a scene's camera image tile by tile from a running bmc-irradiance
service and write it as a PNG (tone-mapped sRGB) and a PFM (linear floats).

Standard library only. Tiles are requested as JSON floats, a few at a time
in parallel, and retried when the service answers 503 (its CPU queue is full)
after the Retry-After it sends.

    cargo run --release -- serve &
    python3 examples/tile_client.py --scene cornell-box --out cornell.png

Every pixel depends only on the seed and its position, so the assembled image
is the same whatever the tile size or the order the tiles arrive in.
"""

import argparse
import concurrent.futures
import json
import math
import struct
import sys
import time
import urllib.error
import urllib.request
import zlib


class ServiceError(Exception):
    """A non-retryable error answer, with the service's code, field and message."""


def post_json(url, body, attempts=20):
    data = json.dumps(body).encode()
    for _ in range(attempts):
        request = urllib.request.Request(
            url, data=data, headers={"content-type": "application/json"}
        )
        try:
            with urllib.request.urlopen(request, timeout=120) as response:
                return json.load(response)
        except urllib.error.HTTPError as err:
            if err.code == 503:
                time.sleep(float(err.headers.get("retry-after", "1")))
                continue
            detail = json.load(err).get("error", {})
            raise ServiceError(
                f"{err.code} {detail.get('code')} field={detail.get('field')}: "
                f"{detail.get('message')}"
            ) from None
    raise ServiceError(f"still overloaded after {attempts} attempts: {url}")


def get_json(url):
    with urllib.request.urlopen(url, timeout=30) as response:
        return json.load(response)


def fetch_image(base, scene, tile, spp, seed, estimator, workers):
    width, height = get_json(f"{base}/v1/scenes/{scene}")["resolution"]
    rgb = [[0.0, 0.0, 0.0] for _ in range(width * height)]
    jobs = [
        (x, y, min(tile, width - x), min(tile, height - y))
        for y in range(0, height, tile)
        for x in range(0, width, tile)
    ]

    def one(job):
        x, y, w, h = job
        body = {
            "x": x, "y": y, "width": w, "height": h, "format": "json",
            "samples_per_pixel": spp, "seed": seed,
        }
        if estimator:
            body["estimator"] = {"method": estimator}
        return job, post_json(f"{base}/v1/scenes/{scene}/tiles", body)

    with concurrent.futures.ThreadPoolExecutor(workers) as pool:
        for done, ((x, y, w, h), reply) in enumerate(pool.map(one, jobs), 1):
            for row in range(h):
                for col in range(w):
                    rgb[(y + row) * width + x + col] = reply["rgb"][row * w + col]
            print(f"\r{done}/{len(jobs)} tiles", end="", file=sys.stderr)
    print(file=sys.stderr)
    return width, height, rgb


def srgb8(linear, exposure):
    x = min(max(linear * 2.0**exposure, 0.0), 1.0)
    x = 12.92 * x if x <= 0.0031308 else 1.055 * x ** (1 / 2.4) - 0.055
    return int(round(x * 255))


def write_png(path, width, height, rgb, exposure):
    rows = bytearray()
    for y in range(height):
        rows.append(0)  # filter type None
        for r, g, b in rgb[y * width:(y + 1) * width]:
            rows += bytes((srgb8(r, exposure), srgb8(g, exposure), srgb8(b, exposure)))

    def chunk(kind, payload):
        crc = zlib.crc32(kind + payload) & 0xFFFFFFFF
        return struct.pack(">I", len(payload)) + kind + payload + struct.pack(">I", crc)

    header = struct.pack(">IIBBBBB", width, height, 8, 2, 0, 0, 0)  # 8-bit RGB
    with open(path, "wb") as out:
        out.write(b"\x89PNG\r\n\x1a\n")
        out.write(chunk(b"IHDR", header))
        out.write(chunk(b"IDAT", zlib.compress(bytes(rows), 9)))
        out.write(chunk(b"IEND", b""))


def write_pfm(path, width, height, rgb):
    """Portable float map: little-endian, bottom row first."""
    with open(path, "wb") as out:
        out.write(f"PF\n{width} {height}\n-1.0\n".encode())
        for y in reversed(range(height)):
            for pixel in rgb[y * width:(y + 1) * width]:
                out.write(struct.pack("<3f", *pixel))


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--url", default="http://127.0.0.1:8080")
    parser.add_argument("--scene", default="cornell-box")
    parser.add_argument("--out", default="image.png", help="PNG path; a .pfm is written beside it")
    parser.add_argument("--tile", type=int, default=64, help="tile side in pixels")
    parser.add_argument("--spp", type=int, default=16, help="samples per pixel")
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--estimator", default=None, help="tile estimator method, e.g. path")
    parser.add_argument("--exposure", type=float, default=0.0, help="PNG exposure in stops")
    parser.add_argument("--workers", type=int, default=4, help="tiles in flight at once")
    args = parser.parse_args()
    try:
        width, height, rgb = fetch_image(
            args.url.rstrip("/"), args.scene, args.tile, args.spp, args.seed,
            args.estimator, args.workers,
        )
    except (ServiceError, urllib.error.URLError) as err:
        sys.exit(f"error: {err}")
    write_png(args.out, width, height, rgb, args.exposure)
    pfm = args.out.rsplit(".", 1)[0] + ".pfm"
    write_pfm(pfm, width, height, rgb)
    mean = sum(sum(p) for p in rgb) / (3 * len(rgb))
    assert math.isfinite(mean)
    print(f"wrote {args.out} and {pfm}: {width}x{height}, mean radiance {mean:.4f}")


if __name__ == "__main__":
    main()
