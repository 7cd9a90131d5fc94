#!/usr/bin/env python3
"""A project JSON scene (``scenes/*.json``) as Radiance input, for the peer
runs of ``radiance_sensor_grid.py`` on scenes other than the Cornell box.

What converts, and how (the project's conventions are Mitsuba's: a
``rectangle`` is [-1,1]^2 in z = 0 with normal +z, a ``cube`` [-1,1]^3, a
``to_world`` list is applied in order):

* ``rectangle`` and ``cube`` shapes become polygons, ``sphere`` (centre and
  radius, no ``to_world``) a Radiance ``sphere``.
* ``diffuse`` materials become ``plastic`` with no specular part.
* ``glossy`` (a diffuse part plus the normalised Phong lobe
  ``(m + 2)/2π cos^m α`` about the mirror direction) has no Radiance
  counterpart; it becomes ``plastic`` with the same diffuse reflectance, the
  specular reflectance's mean as its specularity and roughness
  ``sqrt(1/(2m))``: for small angles ``cos^m α ≈ exp(-m α²/2)`` and the half
  vector is off the normal by ``α/2``, which Radiance's Gaussian lobe
  ``exp(-tan² δ/r²)`` matches for ``r² = 1/(2m)``. Radiance's specular part
  is white and Fresnel-weighted, so this is an approximation; the scripts
  report the mean ratio to the reference, which shows what it costs.
* ``envmap`` becomes a ``glow`` sky with a ``colorpict`` of the map. The
  project reads the map bilinearly with texel column ``i`` at
  ``u = (i + ½)/W`` and row ``j`` at ``v = j/(H − 1)`` (``θ = πv`` from +y,
  ``φ = atan2(x, −z)``, after the inverse of its ``to_world``); Radiance
  reads a picture its own way, so the map is resampled here with the
  project's reading onto ``--upsample`` times as many texels, where the two
  readings differ by a fraction of a fine texel.

Anything else (other shapes, materials, emitters) is refused with the
object's id. Needs numpy and OpenEXR (a throwaway venv).
"""
from __future__ import annotations

import json
import math
import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from cornell_common import rectangle_corners  # noqa: E402
from radiance_irradiance import cube_quads  # noqa: E402


def rotation(axis, degrees: float) -> np.ndarray:
    """3x3 right-handed rotation about `axis` (Rodrigues)."""
    a = np.asarray(axis, dtype=np.float64)
    a = a / np.linalg.norm(a)
    t = math.radians(degrees)
    k = np.array([[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]])
    return np.eye(3) + math.sin(t) * k + (1 - math.cos(t)) * (k @ k)


def to_world(steps) -> np.ndarray:
    """4x4 matrix of a project ``to_world`` (one step or a list, in order)."""
    if isinstance(steps, dict):
        steps = [steps]
    m = np.eye(4)
    for step in steps or []:
        s = np.eye(4)
        if "scale" in step:
            s[:3, :3] = np.diag(np.broadcast_to(np.asarray(step["scale"], dtype=np.float64), 3))
        elif "rotate" in step:
            s[:3, :3] = rotation(step["rotate"]["axis"], step["rotate"]["angle"])
        elif "translate" in step:
            s[:3, 3] = step["translate"]
        else:
            raise ValueError(f"to_world step {step} is not converted")
        m = s @ m
    return m


def material_rad(mat: dict) -> str:
    name, kind = mat["id"], mat["type"]
    if kind == "diffuse":
        r = mat["reflectance"]
        return f"void plastic {name}\n0\n0\n5 {r[0]} {r[1]} {r[2]} 0 0"
    if kind == "glossy":
        spec = float(np.mean(mat["specular"]))
        color = [d / (1 - spec) for d in mat["diffuse"]]
        rough = math.sqrt(1 / (2 * mat["exponent"]))
        return f"void plastic {name}\n0\n0\n5 {color[0]} {color[1]} {color[2]} {spec} {rough}"
    raise ValueError(f"material {name!r} of type {kind!r} is not converted")


def read_exr(path: str) -> np.ndarray:
    import OpenEXR

    part = OpenEXR.File(path).parts[0]
    if "RGB" in part.channels:
        return np.asarray(part.channels["RGB"].pixels, dtype=np.float64)
    return np.stack([np.asarray(part.channels[c].pixels, dtype=np.float64) for c in "RGB"], axis=-1)


def project_lookup(texels: np.ndarray, u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """The project's bilinear reading of a lat-long map (module docs)."""
    h, w, _ = texels.shape
    x, y = u * w - 0.5, v * (h - 1)
    fx, fy = np.floor(x), np.floor(y)
    tx, ty = (x - fx)[..., None], (y - fy)[..., None]
    x0, x1 = fx.astype(int) % w, (fx.astype(int) + 1) % w
    y0 = np.clip(fy.astype(int), 0, h - 1)
    y1 = np.clip(fy.astype(int) + 1, 0, h - 1)
    top = texels[y0, x0] * (1 - tx) + texels[y0, x1] * tx
    bottom = texels[y1, x0] * (1 - tx) + texels[y1, x1] * tx
    return top * (1 - ty) + bottom * ty


def write_hdr(path: str, rgb: np.ndarray) -> None:
    """Radiance RGBE picture, flat scanlines, top row first."""
    h, w, _ = rgb.shape
    peak = rgb.max(axis=-1)
    mantissa, exponent = np.frexp(peak)
    scale = np.where(peak > 1e-32, mantissa * 256.0 / np.where(peak > 0, peak, 1), 0.0)
    out = np.zeros((h, w, 4), dtype=np.uint8)
    out[..., :3] = np.clip(rgb * scale[..., None], 0, 255).astype(np.uint8)
    out[..., 3] = np.where(peak > 1e-32, exponent + 128, 0).astype(np.uint8)
    with open(path, "wb") as f:
        f.write(f"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y {h} +X {w}\n".encode())
        f.write(out.tobytes())


def environment_rad(env: dict, scene_dir: str, work: str, upsample: int) -> str:
    if env.get("type") != "envmap":
        raise ValueError(f"environment of type {env.get('type')!r} is not converted")
    texels = read_exr(os.path.join(scene_dir, env["filename"]))
    h, w, _ = texels.shape
    big_h, big_w = h * upsample, w * upsample
    v, u = np.meshgrid((np.arange(big_h) + 0.5) / big_h, (np.arange(big_w) + 0.5) / big_w, indexing="ij")
    picture = os.path.join(work, "environment.hdr")
    write_hdr(picture, project_lookup(texels, u, v))
    # Directions reach the map through the inverse of its to_world.
    world_to_map = to_world(env.get("to_world"))[:3, :3].T
    rows = [" + ".join(f"({world_to_map[r, c]:.12g})*D{'xyz'[c]}" for c in range(3)) for r in range(3)]
    cal = os.path.join(work, "environment.cal")
    with open(cal, "w") as f:
        f.write(
            f"mx = {rows[0]};\nmy = {rows[1]};\nmz = {rows[2]};\n"
            "ph = atan2(mx, -mz) / (2*PI);\n"
            "eu = if(ph, ph, ph + 1);\n"
            "ev = acos(if(my - 1, 1, if(-1 - my, -1, my))) / PI;\n"
            # Picture coordinates: the shorter side spans [0, 1], (0, 0) at the bottom left.
            f"pu = eu * {big_w / big_h:.12g};\n"
            "pv = 1 - ev;\n"
        )
    s = float(env.get("scale", 1.0))
    return (
        f"void colorpict environment_map\n7 red green blue {picture} {cal} pu pv\n0\n0\n"
        f"environment_map glow environment_glow\n0\n0\n4 {s} {s} {s} 0\n"
        "environment_glow source sky\n0\n0\n4 0 1 0 180\n"
        "environment_glow source underground\n0\n0\n4 0 -1 0 180"
    )


def scene_rad(scene_path: str, work: str, upsample: int = 8) -> str:
    """Radiance input of the JSON scene at `scene_path` (module docs); the
    environment's picture and function file are written into `work`."""
    with open(scene_path) as f:
        scene = json.load(f)
    out = [f"# {os.path.basename(scene_path)} (generated by radiance_json_scene.py)"]
    out += [material_rad(m) for m in scene["materials"]]
    for shape in scene["shapes"]:
        name, kind, mat = shape["id"], shape["type"], shape["material"]
        if "emitter" in shape:
            raise ValueError(f"shape {name!r} emits: area lights are not converted")
        if kind == "sphere" and "to_world" not in shape:
            c, r = shape["center"], shape["radius"]
            out.append(f"{mat} sphere {name}\n0\n0\n4 {c[0]} {c[1]} {c[2]} {r}")
            continue
        m = to_world(shape.get("to_world"))
        if kind == "rectangle":
            polys = [rectangle_corners(m)]
        elif kind == "cube":
            polys = cube_quads(m)
        else:
            raise ValueError(f"shape {name!r} of type {kind!r} is not converted")
        for j, c in enumerate(polys):
            coords = " ".join(f"{x:.9g}" for x in c.reshape(-1))
            out.append(f"{mat} polygon {name}.{j}\n0\n0\n12 {coords}")
    for key in ("emitters", "lights"):
        if scene.get(key):
            raise ValueError(f"`{key}` are not converted")
    if "environment" in scene:
        out.append(environment_rad(scene["environment"], os.path.dirname(scene_path), work, upsample))
    return "\n".join(out) + "\n"
