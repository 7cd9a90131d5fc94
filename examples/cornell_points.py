"""Shading points on the surfaces of the bundled Cornell box
(`scenes/cornell-box.json`), shared by the Python examples.

The box spans [-1, 1]³ with its open side at z = +1: floor y = -1, ceiling
y = 1 (the light hangs just below its centre), back wall z = -1, red wall
x = -1, green wall x = 1, and two boxes standing on the floor whose
footprints lie within 0.45 of (0.335, 0.38) and (-0.33, -0.28) in (x, z).
Points sit 0.001 off their surface, on the inside.
"""

from __future__ import annotations

import numpy as np

_BOX_FOOTPRINTS = ((0.335, 0.38), (-0.33, -0.28))
_LIGHT_HALF_SIZE = (0.3, 0.25)  # keep ceiling points out of the light's shadow


def cornell_points(count: int, seed: int = 2026) -> tuple[np.ndarray, np.ndarray]:
    """``count`` random points spread over the five walls (N×3 positions
    and unit normals), never under a box or behind the light."""
    rng = np.random.default_rng(seed)
    positions, normals = [], []
    walls = [
        # (fixed axis, value, normal)
        (1, -0.999, (0, 1, 0)),   # floor
        (1, 0.999, (0, -1, 0)),   # ceiling
        (2, -0.999, (0, 0, 1)),   # back
        (0, -0.999, (1, 0, 0)),   # red wall
        (0, 0.999, (-1, 0, 0)),   # green wall
    ]
    while len(positions) < count:
        axis, value, normal = walls[len(positions) % len(walls)]
        p = rng.uniform(-0.9, 0.9, 3)
        p[axis] = value
        if axis == 1 and value < 0 and any(
            np.hypot(p[0] - x, p[2] - z) < 0.45 for x, z in _BOX_FOOTPRINTS
        ):
            continue
        if axis == 1 and value > 0 and abs(p[0]) < _LIGHT_HALF_SIZE[0] and abs(p[2]) < _LIGHT_HALF_SIZE[1]:
            continue
        positions.append(p)
        normals.append(normal)
    return np.array(positions), np.array(normals, dtype=float)
