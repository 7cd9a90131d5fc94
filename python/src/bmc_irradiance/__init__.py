"""Python client of the bmc-irradiance HTTP service: numpy in, numpy out.

    >>> from bmc_irradiance import Client
    >>> client = Client("http://127.0.0.1:8080")
    >>> result = client.irradiance("cornell-box", [[0, -0.99, 0]], [0, 1, 0], method="qmc")
    >>> result.value, result.std_dev          # N×3 arrays, W/m²
    >>> image = client.image("cornell-box", preset="preview")
    >>> image.rgb, image.std_dev              # H×W×3 and H×W, W/(m²·sr)
    >>> png = client.tile_bytes("cornell-box", 0, 0, format="png", preset="draft")
    >>> client.tile_bytes("cornell-box", 0, 0, format="png", preset="draft",
    ...                   if_none_match=png.etag) is None   # 304: unchanged
    True

Units: irradiance in W/m², radiance in W/(m²·sr), per linear RGB channel.
"""

from .client import Client, chunk_seed
from .errors import ServiceError
from .imageio import read_pfm, srgb8, write_exr, write_pfm, write_png
from .results import (
    Chunk,
    ErrorTarget,
    Image,
    IrradianceResult,
    Quadrature,
    RadianceResult,
    Tile,
    TileBytes,
    TileInfo,
)

__all__ = [
    "Chunk",
    "Client",
    "ErrorTarget",
    "Image",
    "IrradianceResult",
    "Quadrature",
    "RadianceResult",
    "ServiceError",
    "Tile",
    "TileBytes",
    "TileInfo",
    "chunk_seed",
    "read_pfm",
    "srgb8",
    "write_exr",
    "write_pfm",
    "write_png",
]

__version__ = "0.1.0"
