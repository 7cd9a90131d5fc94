"""The RGB complex indices of refraction Mitsuba 3 uses for its named
conductors (`<string name="material" value="Au"/>`) in its RGB variants.

Mitsuba stores each metal as measured spectra (`data/ior/<name>.eta.spd`,
`.k.spd`) and, in an RGB variant, turns each into linear sRGB by
integrating against the CIE 1931 matching functions (`spectrum_to_rgb`),
clamping out-of-gamut negatives to zero. This prints those values as the
rows of `NAMED_METALS` in `src/scene/material/metals.rs`, so a scene naming a
metal gets the numbers Mitsuba renders it with.

Run in a throwaway venv (`pip install mitsuba`):

    python docs/validation/mitsuba_named_metals.py
"""

import mitsuba as mi

mi.set_variant("scalar_rgb")
# The clamping warnings would interleave with the rows.
mi.set_log_level(mi.LogLevel.Error)

NAMES = [
    "a-C", "Ag", "Al", "AlAs", "AlSb", "Au", "Be", "Cr", "CsI", "Cu", "Cu2O", "CuO", "d-C",
    "Hg", "HgTe", "Ir", "K", "Li", "MgO", "Mo", "Na_palik", "Nb", "Ni_palik", "Rh", "Se", "SiC",
    "SnTe", "Ta", "Te", "ThF4", "TiC", "TiN", "TiO2", "VC", "V_palik", "VN", "W",
]


def rgb(value):
    return "[" + ", ".join(f"{float(value[c]):.6}" for c in range(3)) + "]"


print(f"// mitsuba {mi.__version__}, scalar_rgb")
for name in NAMES:
    params = mi.traverse(mi.load_dict({"type": "conductor", "material": name}))
    print(f'    ("{name}", {rgb(params["eta.value"])}, {rgb(params["k.value"])}),')
