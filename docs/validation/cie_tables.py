#!/usr/bin/env python3
"""Writes `src/color/cie.rs`: the CIE 1931 2° colour-matching functions and
the CIE D65 illuminant at 5 nm from 360 to 830 nm (95 samples), the tables
Mitsuba 3's RGB variants integrate spectra against (docs/math.md §18.4).

Source: the CIE's own tables as the `colour-science` package ships them
(CIE 1931 2° observer, 1 nm, of which every fifth sample; CIE D65, 5 nm to
780 nm). D65 beyond 780 nm is the CIE daylight basis S0 + M1 S1 + M2 S2 with
D65's coefficients M1 = -0.295, M2 = -0.689, rounded to 4 decimals as the
CIE's table is; on 360-780 nm this reproduces the tabulated D65 within
0.001.

Run in a throwaway venv (`pip install colour-science numpy`), from the
repository root:

    python docs/validation/cie_tables.py > src/color/cie.rs
"""

import warnings

import numpy as np

warnings.filterwarnings("ignore")
import colour  # noqa: E402

WAVELENGTHS = np.arange(360, 831, 5)


def d65():
    table = colour.SDS_ILLUMINANTS["D65"]
    basis = colour.colorimetry.datasets.illuminants.SDS_BASIS_FUNCTIONS_CIE_ILLUMINANT_D_SERIES
    shape = colour.SpectralShape(300, 830, 5)
    s0, s1, s2 = (basis[k].copy().align(shape) for k in ("S0", "S1", "S2"))
    out = []
    for w in WAVELENGTHS:
        if w <= 780:
            out.append(float(table[w]))
        else:
            out.append(round(float(s0[w] - 0.295 * s1[w] - 0.689 * s2[w]), 4))
    return out


def rows(name, doc, values):
    body = ",\n".join(
        "    " + ", ".join(f"{v:.6e}" for v in values[i : i + 6]) for i in range(0, len(values), 6)
    )
    return f"/// {doc}\npub const {name}: [f64; SAMPLES] = [\n{body},\n];\n"


def main():
    cmfs = colour.MSDS_CMFS["CIE 1931 2 Degree Standard Observer"]
    xyz = np.array([cmfs[w] for w in WAVELENGTHS])
    print("//! The CIE 1931 2° colour-matching functions and the CIE D65 illuminant")
    print("//! (relative, 100 at 560 nm) at 5 nm from 360 to 830 nm, the tables")
    print("//! Mitsuba 3's RGB variants integrate spectra against (docs/math.md §18.4).")
    print("//! Written by `docs/validation/cie_tables.py`; do not edit.")
    print()
    print("/// Shortest tabulated wavelength, nm.")
    print("pub const MIN: f64 = 360.0;")
    print("/// Longest tabulated wavelength, nm.")
    print("pub const MAX: f64 = 830.0;")
    print("/// Samples per table, 5 nm apart.")
    print("pub const SAMPLES: usize = 95;")
    print()
    for i, axis in enumerate("XYZ"):
        print(rows(f"{axis}_BAR", f"CIE 1931 2° {axis.lower()}̄(λ).", list(xyz[:, i])))
    print(rows("D65", "CIE D65, relative spectral power.", d65()), end="")


if __name__ == "__main__":
    main()
