"""Writing images with numpy and the standard library only: PNG (tone-mapped
8-bit sRGB, the service's own mapping), PFM and OpenEXR (linear 32-bit floats).

Arrays are row-major with the top row first, ``H×W×3`` linear RGB radiance
in W/(m²·sr), as :meth:`bmc_irradiance.Client.image` returns them.
"""

from __future__ import annotations

import os
import struct
import zlib
from typing import Union

import numpy as np
import numpy.typing as npt

PathLike = Union[str, "os.PathLike[str]"]


def _rgb_array(rgb: npt.ArrayLike) -> npt.NDArray[np.float32]:
    array = np.asarray(rgb, dtype=np.float32)
    if array.ndim != 3 or array.shape[2] != 3 or array.shape[0] < 1 or array.shape[1] < 1:
        raise ValueError(f"expected an H×W×3 array, got shape {array.shape}")
    return array


def srgb8(rgb: npt.ArrayLike, exposure: float = 0.0) -> npt.NDArray[np.uint8]:
    """8-bit sRGB codes of linear values, as the service's PNG tiles compute
    them: scale by ``2**exposure``, clamp to [0, 1] (NaN → 0), apply the sRGB
    transfer function (IEC 61966-2-1) and round, in 32-bit floats."""
    x = np.asarray(rgb, dtype=np.float32) * np.float32(2.0**exposure)
    x = np.nan_to_num(np.clip(x, np.float32(0.0), np.float32(1.0)), nan=0.0)
    with np.errstate(invalid="ignore"):
        curve = np.float32(1.055) * np.power(x, np.float32(1.0 / 2.4)) - np.float32(0.055)
    encoded = np.where(x <= np.float32(0.0031308), np.float32(12.92) * x, curve)
    codes: npt.NDArray[np.uint8] = np.floor(encoded * np.float32(255.0) + np.float32(0.5)).astype(
        np.uint8
    )
    return codes


def _png_chunk(kind: bytes, payload: bytes) -> bytes:
    crc = zlib.crc32(kind + payload) & 0xFFFFFFFF
    return struct.pack(">I", len(payload)) + kind + payload + struct.pack(">I", crc)


def png_bytes(pixels: npt.ArrayLike) -> bytes:
    """PNG file bytes of 8-bit pixels: ``H×W×3`` (RGB) or ``H×W`` (grey)."""
    array = np.asarray(pixels)
    if array.dtype != np.uint8:
        raise ValueError(f"expected uint8 pixels, got {array.dtype}")
    if array.ndim == 2:
        colour_type = 0
    elif array.ndim == 3 and array.shape[2] == 3:
        colour_type = 2
    else:
        raise ValueError(f"expected H×W or H×W×3 pixels, got shape {array.shape}")
    height, width = array.shape[:2]
    rows = np.ascontiguousarray(array).reshape(height, -1)
    # Filter type 0 (none) before every row.
    raw = np.concatenate([np.zeros((height, 1), dtype=np.uint8), rows], axis=1).tobytes()
    header = struct.pack(">IIBBBBB", width, height, 8, colour_type, 0, 0, 0)
    return (
        b"\x89PNG\r\n\x1a\n"
        + _png_chunk(b"IHDR", header)
        + _png_chunk(b"IDAT", zlib.compress(raw, 6))
        + _png_chunk(b"IEND", b"")
    )


def write_png(path: PathLike, rgb: npt.ArrayLike, exposure: float = 0.0) -> None:
    """Writes linear ``H×W×3`` radiance as an 8-bit sRGB PNG (see :func:`srgb8`)."""
    with open(path, "wb") as out:
        out.write(png_bytes(srgb8(_rgb_array(rgb), exposure)))


def write_pfm(path: PathLike, rgb: npt.ArrayLike) -> None:
    """Writes ``H×W×3`` floats as a little-endian Portable Float Map (bottom row first)."""
    array = _rgb_array(rgb)
    height, width = array.shape[:2]
    with open(path, "wb") as out:
        out.write(f"PF\n{width} {height}\n-1.0\n".encode())
        out.write(np.ascontiguousarray(array[::-1], dtype="<f4").tobytes())


def read_pfm(path: PathLike) -> npt.NDArray[np.float32]:
    """Reads a colour PFM (as :func:`write_pfm` writes it) into ``H×W×3``, top row first."""
    with open(path, "rb") as f:
        data = f.read()
    parts = data.split(b"\n", 3)
    if len(parts) < 4 or parts[0].strip() != b"PF":
        raise ValueError("not a colour PFM file")
    width, height = (int(v) for v in parts[1].split())
    scale = float(parts[2])
    dtype = "<f4" if scale < 0 else ">f4"
    pixels = np.frombuffer(parts[3], dtype=dtype, count=width * height * 3)
    return pixels.reshape(height, width, 3)[::-1].astype(np.float32)


def _exr_attribute(name: str, kind: str, value: bytes) -> bytes:
    return name.encode() + b"\0" + kind.encode() + b"\0" + struct.pack("<i", len(value)) + value


def exr_bytes(rgb: npt.ArrayLike, variance: npt.ArrayLike | None = None) -> bytes:
    """OpenEXR file bytes: one uncompressed scanline part with 32-bit float
    channels ``R``, ``G``, ``B`` and, when given, ``variance`` (``H×W``) —
    the channels of the service's EXR tiles."""
    array = _rgb_array(rgb)
    height, width = array.shape[:2]
    channels = {"R": array[:, :, 0], "G": array[:, :, 1], "B": array[:, :, 2]}
    if variance is not None:
        v = np.asarray(variance, dtype=np.float32)
        if v.shape != (height, width):
            raise ValueError(f"variance must be {height}×{width}, got shape {v.shape}")
        channels["variance"] = v
    names = sorted(channels)  # EXR stores channels in alphabetical order
    chlist = (
        b"".join(n.encode() + b"\0" + struct.pack("<iB3xii", 2, 0, 1, 1) for n in names) + b"\0"
    )
    box = struct.pack("<iiii", 0, 0, width - 1, height - 1)
    header = (
        struct.pack("<ii", 20000630, 2)
        + _exr_attribute("channels", "chlist", chlist)
        + _exr_attribute("compression", "compression", b"\0")
        + _exr_attribute("dataWindow", "box2i", box)
        + _exr_attribute("displayWindow", "box2i", box)
        + _exr_attribute("lineOrder", "lineOrder", b"\0")
        + _exr_attribute("pixelAspectRatio", "float", struct.pack("<f", 1.0))
        + _exr_attribute("screenWindowCenter", "v2f", struct.pack("<ff", 0.0, 0.0))
        + _exr_attribute("screenWindowWidth", "float", struct.pack("<f", 1.0))
        + b"\0"
    )
    row_bytes = 4 * width * len(names)
    block = 8 + row_bytes
    first = len(header) + 8 * height
    offsets = struct.pack(f"<{height}Q", *(first + y * block for y in range(height)))
    # Per scanline: y, byte count, then each channel's row.
    planes = np.stack([channels[n] for n in names], axis=1).astype("<f4")  # H×C×W
    prefix = np.empty((height, 2), dtype="<i4")
    prefix[:, 0] = np.arange(height)
    prefix[:, 1] = row_bytes
    blocks = b"".join(prefix[y].tobytes() + planes[y].tobytes() for y in range(height))
    return header + offsets + blocks


def write_exr(path: PathLike, rgb: npt.ArrayLike, variance: npt.ArrayLike | None = None) -> None:
    """Writes linear radiance (and optionally the per-pixel variance) as
    OpenEXR (:func:`exr_bytes`)."""
    with open(path, "wb") as out:
        out.write(exr_bytes(rgb, variance))
