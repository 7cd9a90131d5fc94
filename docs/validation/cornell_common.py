"""Shared helpers for the peer-renderer validation scripts (Cornell box).

The scene is Mitsuba 3's built-in ``mi.cornell_box()``; the project keeps a
frozen copy as ``data/mitsuba-cornell-box.json`` beside this file (row-major 4x4
float32 ``to_world`` matrices; rectangles span [-1,1]^2 in local xy with
normal +z, cubes span [-1,1]^3).  Everything here works on that JSON so that
the other peers (Embree, Radiance) use exactly the same geometry.
"""
from __future__ import annotations

import csv
import json
import os
from dataclasses import dataclass

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))


def _find_reference() -> str:
    """$CORNELL_REFERENCE, else the frozen copy in data/ beside this file."""
    return os.environ.get("CORNELL_REFERENCE") or os.path.join(
        HERE, "data", "mitsuba-cornell-box.json")


DEFAULT_REFERENCE = _find_reference()
# the 14 query points ship next to the scripts (cornell_points.csv)
DEFAULT_POINTS = os.environ.get("CORNELL_POINTS", os.path.join(HERE, "cornell_points.csv"))

SHAPE_KEYS = ["light", "floor", "ceiling", "back", "green-wall", "red-wall",
              "small-box", "large-box"]


@dataclass
class Point:
    """A query point p with unit normal n (the hemisphere is the +n side)."""
    p: np.ndarray
    n: np.ndarray

    def row(self):
        return [float(x) for x in self.p] + [float(x) for x in self.n]


def read_points(path: str) -> list[Point]:
    """Read a CSV with header x,y,z,nx,ny,nz; normals are normalised."""
    pts = []
    with open(path) as f:
        for r in csv.DictReader(f):
            p = np.array([float(r[k]) for k in ("x", "y", "z")])
            n = np.array([float(r[k]) for k in ("nx", "ny", "nz")])
            pts.append(Point(p, n / np.linalg.norm(n)))
    return pts


def load_reference(path: str = DEFAULT_REFERENCE) -> dict:
    with open(path) as f:
        return json.load(f)


def matrix(ref: dict, key: str) -> np.ndarray:
    """4x4 to_world matrix (float64 copy of the stored float32 values)."""
    return np.array(ref[key]["to_world"]["matrix"], dtype=np.float64)


def reflectance(ref: dict, key: str) -> np.ndarray:
    bsdf = ref[key]["bsdf"]["id"]
    return np.array(ref[bsdf]["reflectance"]["value"], dtype=np.float64)


def light_radiance(ref: dict) -> np.ndarray:
    return np.array(ref["light"]["emitter"]["radiance"]["value"], dtype=np.float64)


def _xf(m: np.ndarray, v: np.ndarray) -> np.ndarray:
    v = np.atleast_2d(v)
    h = np.hstack([v, np.ones((len(v), 1))]) @ m.T
    return h[:, :3] / h[:, 3:4]


def rectangle_corners(m: np.ndarray) -> np.ndarray:
    """World-space corners (counter-clockwise seen from the +z local side)."""
    loc = np.array([[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]], float)
    return _xf(m, loc)


def rectangle_triangles(m: np.ndarray) -> np.ndarray:
    c = rectangle_corners(m)
    return np.array([[c[0], c[1], c[2]], [c[0], c[2], c[3]]])


def cube_triangles(m: np.ndarray) -> np.ndarray:
    """12 outward-facing triangles of the transformed [-1,1]^3 cube."""
    tris = []
    for axis in range(3):
        for sign in (-1.0, 1.0):
            u, v = [(axis + 1) % 3, (axis + 2) % 3]
            quad = []
            for a, b in [(-1, -1), (1, -1), (1, 1), (-1, 1)]:
                q = np.zeros(3)
                q[axis] = sign
                q[u] = a
                q[v] = b
                quad.append(q)
            quad = np.array(quad)
            if sign < 0:
                quad = quad[::-1]
            w = _xf(m, quad)
            tris += [[w[0], w[1], w[2]], [w[0], w[2], w[3]]]
    return np.array(tris)


def cornell_triangles(ref: dict) -> tuple[np.ndarray, list[str]]:
    """The Cornell box as 36 triangles (6 rectangles x 2 + 2 cubes x 12).

    Returns (tris[36,3,3] float64, owner name per triangle)."""
    tris, names = [], []
    for key in SHAPE_KEYS:
        m = matrix(ref, key)
        t = cube_triangles(m) if ref[key]["type"] == "cube" else rectangle_triangles(m)
        tris.append(t)
        names += [key] * len(t)
    return np.concatenate(tris), names


def polygon_irradiance(p: np.ndarray, n: np.ndarray, poly: np.ndarray) -> float:
    """Irradiance at p (normal n) from a unit-radiance, unoccluded, Lambertian
    polygon that lies entirely above p's horizon (Lambert's formula):
    E = 1/2 * sum_i angle(r_i, r_{i+1}) * n . unit(r_i x r_{i+1}).
    The sign is made positive (the caller decides whether the emitting side
    faces p)."""
    r = poly - p
    r /= np.linalg.norm(r, axis=1, keepdims=True)
    e = 0.0
    for i in range(len(r)):
        a, b = r[i], r[(i + 1) % len(r)]
        c = np.cross(a, b)
        theta = np.arccos(np.clip(np.dot(a, b), -1, 1))
        e += theta * np.dot(n, c / np.linalg.norm(c))
    return abs(0.5 * e)


def write_csv(path: str, header: list[str], rows: list[list]) -> None:
    os.makedirs(os.path.dirname(os.path.abspath(path)), exist_ok=True)
    with open(path, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(header)
        for r in rows:
            w.writerow([f"{v:.9g}" if isinstance(v, float) else v for v in r])


def irradiance_meter(p, n, radius: float, offset: float, bsdf: dict | None = None) -> dict:
    """A Mitsuba shape dict: a disk of ``radius`` at p + offset*n facing n,
    carrying an ``irradiancemeter`` on a 1x1 box-filtered ``hdrfilm`` (the
    pixel is the irradiance E [W/m^2] averaged over the disk); black unless
    ``bsdf`` is given.  Must be called after mi.set_variant()."""
    import mitsuba as mi
    p = np.asarray(p, float)
    n = np.asarray(n, float) / np.linalg.norm(n)
    o = p + offset * n
    up = [0, 0, 1] if abs(n[2]) < 0.9 else [0, 1, 0]
    to_world = mi.ScalarTransform4f().look_at(
        origin=o.tolist(), target=(o + n).tolist(), up=up).scale([radius, radius, 1])
    return {
        "type": "disk",
        "to_world": to_world,
        "bsdf": bsdf or {"type": "diffuse", "reflectance": {"type": "rgb", "value": 0.0}},
        "sensor": {
            "type": "irradiancemeter",
            "sampler": {"type": "independent", "sample_count": 1},
            "film": {"type": "hdrfilm", "width": 1, "height": 1,
                     "rfilter": {"type": "box"}, "pixel_format": "rgb",
                     "component_format": "float32"},
        },
    }
