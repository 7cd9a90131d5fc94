"""Reference values of Mitsuba 3's rough BSDF lobes for `src/scene/material/`.

Evaluates `roughconductor` and `roughdielectric` (GGX and Beckmann,
isotropic and anisotropic, from outside and from inside) at fixed direction
pairs in the standard local frame (x = the `alpha_u` tangent, z = the
normal) and writes, per case, Mitsuba's BSDF value without the cosine and,
for GGX (which both sample by visible normals), its sampling density.
The Rust unit test `scene::material::mitsuba_agreement` reads the file.

Run in a throwaway venv (`pip install mitsuba numpy`), from the repository root:

    python docs/validation/mitsuba_bsdf_lobes.py > tests/data/mitsuba_bsdf_lobes.json
"""

import json
import math

import mitsuba as mi

mi.set_variant("scalar_rgb")


def direction(theta, phi):
    return [math.sin(theta) * math.cos(phi), math.sin(theta) * math.sin(phi), math.cos(theta)]


VIEWS = [direction(0.0, 0.0), direction(0.8, 0.3), direction(1.3, 2.2), direction(math.pi - 0.5, 1.0)]
LIGHTS = [direction(0.5, 2.9), direction(1.1, -0.7), direction(math.pi - 0.4, 0.2), direction(math.pi - 1.2, 3.0)]

CONDUCTOR = {"eta": [0.18, 0.42, 1.37], "k": [3.42, 2.35, 1.77]}


def plugin(kind, distribution, alpha_u, alpha_v, eta):
    spec = {"type": kind, "distribution": distribution, "alpha_u": alpha_u, "alpha_v": alpha_v}
    if kind == "roughconductor":
        spec["eta"] = {"type": "rgb", "value": CONDUCTOR["eta"]}
        spec["k"] = {"type": "rgb", "value": CONDUCTOR["k"]}
    else:
        spec["int_ior"] = eta
        spec["ext_ior"] = 1.0
    return mi.load_dict(spec)


def main():
    cases = []
    for kind in ["roughconductor", "roughdielectric"]:
        for distribution in ["ggx", "beckmann"]:
            for alpha_u, alpha_v in [(0.1, 0.1), (0.4, 0.4), (0.15, 0.5)]:
                bsdf = plugin(kind, distribution, alpha_u, alpha_v, 1.5)
                for wo in VIEWS:
                    for wi in LIGHTS:
                        si = mi.SurfaceInteraction3f()
                        si.sh_frame = mi.Frame3f(mi.Vector3f(1, 0, 0), mi.Vector3f(0, 1, 0), mi.Vector3f(0, 0, 1))
                        si.n = mi.Normal3f(0, 0, 1)
                        # Mitsuba's `wi` is the direction towards the viewer, its
                        # `wo` the light's; `eval` includes |cos θ| of the light.
                        si.wi = mi.Vector3f(wo)
                        ctx = mi.BSDFContext()
                        value = bsdf.eval(ctx, si, mi.Vector3f(wi))
                        pdf = bsdf.pdf(ctx, si, mi.Vector3f(wi))
                        cos = abs(wi[2])
                        cases.append({
                            "kind": kind,
                            "distribution": distribution,
                            "alpha": [alpha_u, alpha_v],
                            "eta": 1.5,
                            "wo": wo,
                            "wi": wi,
                            "value": [float(value[c]) / cos for c in range(3)],
                            "pdf": float(pdf),
                        })
    json.dump({"mitsuba": mi.__version__, "conductor": CONDUCTOR, "cases": cases}, indent=1,
              fp=__import__("sys").stdout)


if __name__ == "__main__":
    main()
