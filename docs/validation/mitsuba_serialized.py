#!/usr/bin/env python3
"""Writes tests/data/mitsuba/two_meshes.serialized (Mitsuba's `serialized`
mesh format, version 4: a single-precision quad with normals and texture
coordinates, then a double-precision triangle without either) and checks that
Mitsuba 3 reads back exactly the numbers the unit test of
src/scene/serialized.rs asserts. Run in a throwaway venv (`pip install
mitsuba numpy`):

    python docs/validation/mitsuba_serialized.py
"""

import struct
import zlib
from pathlib import Path

import mitsuba as mi
import numpy as np

mi.set_variant("scalar_rgb")
OUT = Path(__file__).resolve().parents[2] / "tests/data/mitsuba/two_meshes.serialized"

QUAD = dict(
    positions=[[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]],
    normals=[[0, 0, 1]] * 4,
    uvs=[[0, 0], [1, 0], [1, 1], [0, 1]],
    faces=[[0, 1, 2], [0, 2, 3]],
    double=False,
)
TRIANGLE = dict(
    positions=[[0, 0, 0], [2.5, 0, 1 / 3], [0, 2, 0]],
    normals=None,
    uvs=None,
    faces=[[0, 1, 2]],
    double=True,
)


def mesh_bytes(name, mesh):
    real = "d" if mesh["double"] else "f"
    flags = (0x1 if mesh["normals"] else 0) | (0x2 if mesh["uvs"] else 0)
    flags |= 0x2000 if mesh["double"] else 0x1000
    body = struct.pack("<I", flags) + name.encode() + b"\0"
    body += struct.pack("<QQ", len(mesh["positions"]), len(mesh["faces"]))
    for key in ("positions", "normals", "uvs"):
        for row in mesh[key] or []:
            body += struct.pack(f"<{len(row)}{real}", *row)
    for face in mesh["faces"]:
        body += struct.pack("<3I", *face)
    return struct.pack("<HH", 0x041C, 4) + zlib.compress(body)


def main():
    parts = [mesh_bytes("quad", QUAD), mesh_bytes("triangle", TRIANGLE)]
    offsets = [0, len(parts[0])]
    OUT.write_bytes(b"".join(parts) + struct.pack("<2Q", *offsets) + struct.pack("<I", 2))
    for index, mesh in enumerate([QUAD, TRIANGLE]):
        shape = mi.load_dict({"type": "serialized", "filename": str(OUT), "shape_index": index})
        params = mi.traverse(shape)
        positions = np.array(params["vertex_positions"]).reshape(-1, 3)
        faces = np.array(params["faces"]).reshape(-1, 3)
        assert np.allclose(positions, mesh["positions"], rtol=1e-7), positions
        assert (faces == mesh["faces"]).all(), faces
        if mesh["uvs"]:
            uvs = np.array(params["vertex_texcoords"]).reshape(-1, 2)
            assert np.allclose(uvs, mesh["uvs"]), uvs
        print(f"mesh {index}: Mitsuba reads {len(positions)} vertices, {len(faces)} triangles, as written")
    print(f"wrote {OUT}")


if __name__ == "__main__":
    main()
