#!/usr/bin/env python3
"""Writes the sun skies of issue 39's held-out scenes beside this file, each
made after the work it measures and never used while tuning:

- sunset_sky.hdr (heldout-sunset.json, made after the split mode's variance
  share changed): a warm sky and a sun of one texel 24° above the horizon,
  about half of a horizontal plane's irradiance;
- noon_sky.hdr (heldout-noon.json, made after the split mode's direct-light
  twins): a blue sky and a sun of a few texels 55° up, about three quarters
  of it;
- morning_sky.hdr (heldout-morning.json, made after priors in conflict with
  a point's own estimate were left out): a pale sky and a small sun 35° up;
- evening_sky.hdr (heldout-evening.json, made after the twins' shadow
  probes and rotation gradients): an amber sky and a sun of a few texels
  18° up;
- afternoon_sky.hdr (heldout-afternoon.json, made after the prior's modelled
  error was made to grow with the distance to the records): a clear sky and
  a small sun 42° up;
- haze_sky.hdr (heldout-haze.json, made after combined error bars were held
  at least to the rule's noise they carry): a hazy sky and a wide sun 30°
  up;
- winter_sky.hdr (heldout-winter.json, made after split-mode BMC's error
  bars took the light samples' unseen-light term): a pale sky and a small
  sun 12° up behind the wall;
- dusk_sky.hdr (heldout-dusk.json, made after the stratified light samples'
  variance was moderated toward the scene's pooled ratio): a violet sky and
  a small sun 20° up, shadows toward the camera.

Radiance in the equirectangular map's world frame (y up), a dark ground half,
written as Radiance RGBE files with flat scanlines. Standard library only.
"""

import math
import pathlib

from make_soft_sky import rgbe

SKIES = {
    "sunset_sky.hdr": {
        "size": (128, 64),
        "sun": (24.0, 205.0),  # elevation, azimuth (degrees)
        "sun_radius": 0.0,  # one texel, the one nearest the sun's direction
        "sun_radiance": (2900.0, 2450.0, 1900.0),
        "zenith": (0.45, 0.5, 0.8),
        "horizon": (0.8, 0.56, 0.24),
        "glow": (2.0, 1.2, 0.5),
    },
    "noon_sky.hdr": {
        "size": (256, 128),
        "sun": (55.0, 120.0),
        "sun_radius": 2.0,  # degrees
        "sun_radiance": (1500.0, 1450.0, 1350.0),
        "zenith": (0.25, 0.4, 0.9),
        "horizon": (0.5, 0.55, 0.6),
        "glow": (0.8, 0.75, 0.6),
    },
    "morning_sky.hdr": {
        "size": (256, 128),
        "sun": (35.0, 300.0),
        "sun_radius": 1.0,
        "sun_radiance": (5200.0, 4900.0, 4300.0),
        "zenith": (0.35, 0.45, 0.75),
        "horizon": (0.7, 0.6, 0.45),
        "glow": (1.2, 1.0, 0.7),
    },
    "evening_sky.hdr": {
        "size": (256, 128),
        "sun": (18.0, 60.0),
        "sun_radius": 1.5,
        "sun_radiance": (2600.0, 1900.0, 1100.0),
        "zenith": (0.3, 0.35, 0.65),
        "horizon": (0.85, 0.6, 0.35),
        "glow": (1.6, 1.0, 0.45),
    },
    "afternoon_sky.hdr": {
        "size": (256, 128),
        "sun": (42.0, 145.0),
        "sun_radius": 1.2,
        "sun_radiance": (3800.0, 3600.0, 3200.0),
        "zenith": (0.3, 0.45, 0.85),
        "horizon": (0.6, 0.62, 0.65),
        "glow": (1.0, 0.9, 0.7),
    },
    "haze_sky.hdr": {
        "size": (256, 128),
        "sun": (30.0, 250.0),
        "sun_radius": 3.0,
        "sun_radiance": (900.0, 880.0, 820.0),
        "zenith": (0.5, 0.55, 0.7),
        "horizon": (0.75, 0.75, 0.72),
        "glow": (1.5, 1.3, 1.0),
    },
    "winter_sky.hdr": {
        "size": (256, 128),
        "sun": (12.0, 330.0),
        "sun_radius": 0.8,
        "sun_radiance": (6000.0, 5200.0, 4200.0),
        "zenith": (0.32, 0.42, 0.7),
        "horizon": (0.75, 0.65, 0.5),
        "glow": (1.4, 1.0, 0.6),
    },
    "dusk_sky.hdr": {
        "size": (256, 128),
        "sun": (20.0, 75.0),
        "sun_radius": 1.0,
        "sun_radiance": (3300.0, 2500.0, 1600.0),
        "zenith": (0.28, 0.33, 0.62),
        "horizon": (0.8, 0.55, 0.4),
        "glow": (1.3, 0.85, 0.45),
    },
}


def direction(i, j, w, h):
    theta = math.pi * (j + 0.5) / h
    phi = 2 * math.pi * (i + 0.5) / w
    return (math.sin(theta) * math.sin(phi), math.cos(theta), -math.sin(theta) * math.cos(phi))


def sun_direction(sky):
    elevation, azimuth = (math.radians(a) for a in sky["sun"])
    return (
        math.cos(elevation) * math.sin(azimuth),
        math.sin(elevation),
        -math.cos(elevation) * math.cos(azimuth),
    )


def background(sky, d):
    """The sky (or ground) without the sun's disc."""
    if d[1] < 0:
        return (0.18, 0.15, 0.13)
    towards_sun = sum(a * b for a, b in zip(d, sun_direction(sky)))
    glow = math.exp(-(1.0 - towards_sun) / 0.08)
    horizon = math.exp(-d[1] / 0.25)
    return tuple(
        z + horizon * h + glow * g for z, h, g in zip(sky["zenith"], sky["horizon"], sky["glow"])
    )


def texels(sky):
    w, h = sky["size"]
    sun = sun_direction(sky)
    cos_radius = math.cos(math.radians(sky["sun_radius"]))
    nearest = max(
        ((i, j) for j in range(h) for i in range(w)),
        key=lambda ij: sum(a * b for a, b in zip(direction(*ij, w, h), sun)),
    )
    for j in range(h):
        for i in range(w):
            d = direction(i, j, w, h)
            in_disc = sum(a * b for a, b in zip(d, sun)) >= cos_radius
            yield sky["sun_radiance"] if in_disc or (i, j) == nearest else background(sky, d)


def main():
    for name, sky in SKIES.items():
        w, h = sky["size"]
        header = f"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y {h} +X {w}\n".encode()
        body = b"".join(rgbe(t) for t in texels(sky))
        out = pathlib.Path(__file__).with_name(name)
        out.write_bytes(header + body)
        print(out)


if __name__ == "__main__":
    main()
