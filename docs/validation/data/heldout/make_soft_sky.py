#!/usr/bin/env python3
"""Writes soft_sky.hdr beside this file: a smooth, sunless sky for issue 39's
held-out scene (made after the work it measures, never used while tuning).

Radiance in the equirectangular map's world frame (y up): a horizon-to-zenith
gradient, a broad glow towards one side and a darker ground half, 128 × 64
pixels, as a Radiance RGBE file with flat scanlines. Standard library only.
"""

import math
import pathlib

WIDTH, HEIGHT = 128, 64
GLOW = (0.6, 0.5, -0.62)  # direction of the broad glow (normalised below)


def radiance(d):
    x, y, z = d
    n = math.sqrt(sum(c * c for c in GLOW))
    glow = sum(a * b / n for a, b in zip(d, GLOW))
    if y < 0:
        return (0.25, 0.22, 0.2)
    sky = 0.9 + 0.6 * y
    warm = 1.4 * math.exp(-(1.0 - glow) / 0.35)
    return (sky * 0.85 + warm, sky * 0.95 + 0.8 * warm, sky * 1.2 + 0.4 * warm)


def rgbe(rgb):
    top = max(rgb)
    if top < 1e-32:
        return bytes(4)
    m, e = math.frexp(top)
    scale = m * 256.0 / top
    return bytes([int(c * scale) for c in rgb] + [e + 128])


def main():
    rows = []
    for j in range(HEIGHT):
        theta = math.pi * (j + 0.5) / HEIGHT
        row = bytearray()
        for i in range(WIDTH):
            phi = 2 * math.pi * (i + 0.5) / WIDTH
            d = (math.sin(theta) * math.sin(phi), math.cos(theta), -math.sin(theta) * math.cos(phi))
            row += rgbe(radiance(d))
        rows.append(bytes(row))
    header = f"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y {HEIGHT} +X {WIDTH}\n".encode()
    out = pathlib.Path(__file__).with_name("soft_sky.hdr")
    out.write_bytes(header + b"".join(rows))
    print(out)


if __name__ == "__main__":
    main()
