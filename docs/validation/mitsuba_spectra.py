#!/usr/bin/env python3
"""Mitsuba 3's RGB of sampled spectra, the reference values of
`color::spectrum::tests::sampled_spectra_match_mitsubas_rgb`: for each
spectrum and use, `spectrum_list_to_srgb(wavelengths, values, bounded, d65)`
with the flags its `Properties::get_texture_impl` passes (a reflectance:
bounded, under D65; an unbounded texture such as a conductor's `eta`: under
D65; an emitter: neither), and `xyz_to_srgb(1, 1, 1)`, the RGB of a
one-valued spectrum on an emitter.

Run in a throwaway venv (`pip install mitsuba`):

    python docs/validation/mitsuba_spectra.py
"""

import mitsuba as mi

mi.set_variant("scalar_rgb")

SPECTRA = [
    "360:1, 830:1",
    "400:0.1, 500:0.8, 600:0.3, 700:0.9",
    "450:2, 550:0.5, 650:3",
    "520:0, 525:5, 530:0",
]
USES = {"Reflectance": (True, True), "Unbounded": (False, True), "Emission": (False, False)}

for text in SPECTRA:
    pairs = [p.split(":") for p in text.split(",")]
    wavelengths = [float(w) for w, _ in pairs]
    values = [float(v) for _, v in pairs]
    for use, (bounded, d65) in USES.items():
        rgb = mi.spectrum_list_to_srgb(wavelengths, values, bounded, d65)
        print(f'("{text}", SpectrumUse::{use}, [{rgb[0]:.6}, {rgb[1]:.6}, {rgb[2]:.6}]),')
print("xyz_to_srgb(1, 1, 1) =", mi.xyz_to_srgb([1, 1, 1]))
