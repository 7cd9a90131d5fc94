"""Result types: numpy arrays plus the response's metadata."""

from __future__ import annotations

import json
import os
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import numpy.typing as npt

from . import imageio

FloatArray = npt.NDArray[np.float64]


@dataclass(frozen=True)
class ErrorTarget:
    """An error target per point (docs/math.md §10.6): estimate in batches of
    the estimator's ``samples`` until the calibrated error bar meets it.

    * ``relative_error``: largest relative error of the luminance, in (0, 1];
    * ``confidence``: probability that the error is within it, in [0.5, 0.9999];
    * ``max_samples``: most hemisphere samples per point (default: the
      service's ``limits.max_samples``).

    ``bmc`` batches are twice ``samples``: the set's directions and as many
    fresh ones for an unbiased correction. With the records prior (the
    default for ``bmc``) the batches run without it and their mean is
    combined with it once.
    """

    relative_error: float
    confidence: float = 0.95
    max_samples: int | None = None

    def to_json(self) -> dict[str, Any]:
        document: dict[str, Any] = {
            "relative_error": float(self.relative_error),
            "confidence": float(self.confidence),
        }
        if self.max_samples is not None:
            document["max_samples"] = int(self.max_samples)
        return document


@dataclass(frozen=True)
class Chunk:
    """One request of a split point set: points ``start:stop`` sent with ``seed``."""

    start: int
    stop: int
    seed: int


@dataclass(frozen=True)
class IrradianceResult:
    """Irradiance at N points (``POST /v1/scenes/{id}/irradiance``).

    ``value`` and ``std_dev`` are ``N×3`` arrays (RGB) in W/m²: the estimate and
    its standard error (calibrated on the scene for every method unless
    ``calibrate=False``). The metadata is the service's: ``decomposition``
    (``split`` or ``hemisphere``), ``prior`` (``environment`` or ``none``),
    ``calibration`` (``scale``, ``floor``, ..., with ``records_prior`` the
    fitted ``prior_scales``; or ``None``), and for ``bmc``
    the ``lengthscale`` and kernel ``noise`` used; with ``records_prior``,
    ``records_prior_points`` counts the points the records covered and
    ``direct_records_points`` those the records' direct-light twins covered;
    ``prior_used`` says per point which records served each part
    (``{"indirect": "records", "direct": "records"}``, ``{}`` where none did). With a
    target, per point:
    ``samples`` spent, ``relative_error`` reached and ``target_met``.
    ``rays`` sums all requests, and ``amortised_rays`` the part of them spent
    on work the service keeps for later requests (kernel fits, calibrations);
    ``chunks`` lists the requests the point set was split into (one unless
    it exceeded the service's limits).
    """

    value: FloatArray
    std_dev: FloatArray
    rays: int
    amortised_rays: int
    decomposition: str
    prior: str
    calibration: dict[str, Any] | None = None
    lengthscale: float | None = None
    noise: float | None = None
    records_prior_points: int | None = None
    direct_records_points: int | None = None
    prior_used: tuple[dict[str, str], ...] | None = None
    samples: npt.NDArray[np.int64] | None = None
    relative_error: FloatArray | None = None
    target_met: npt.NDArray[np.bool_] | None = None
    chunks: tuple[Chunk, ...] = field(default=())

    def __len__(self) -> int:
        return int(self.value.shape[0])


@dataclass(frozen=True)
class RadianceResult:
    """Outgoing radiance at N surface points towards a direction each
    (``POST /v1/scenes/{id}/radiance``): ``value`` and ``std_dev`` are ``N×3``
    arrays in W/(m²·sr); ``rays`` sums all requests."""

    value: FloatArray
    std_dev: FloatArray
    rays: int
    chunks: tuple[Chunk, ...] = field(default=())

    def __len__(self) -> int:
        return int(self.value.shape[0])


@dataclass(frozen=True)
class Quadrature:
    """BMC weights of one configuration (``POST /v1/quadratures``).

    ``directions`` (N×3, local frame with z = normal), ``kernel_means`` (N)
    and ``weights`` (N) are arrays, ``Î = Σ weights[i] · f(directions[i])``.
    The scalars are the service's: ``prior_variance``, ``posterior_variance``
    (in units of the kernel's σ²), ``jitter``, ``condition_estimate``,
    ``density_integral``; ``id`` is the configuration's stable hash and
    ``cached`` whether the weights came from the service's cache.
    """

    id: str
    directions: FloatArray
    kernel_means: FloatArray
    weights: FloatArray
    prior_variance: float
    posterior_variance: float
    jitter: float
    condition_estimate: float
    density_integral: float
    cached: bool

    def integrate(self, values: npt.ArrayLike) -> npt.NDArray[np.float64]:
        """``Σ weights[i] · values[i]`` over the first axis (values N or N×k)."""
        return np.tensordot(self.weights, np.asarray(values, dtype=np.float64), axes=1)


@dataclass(frozen=True)
class Tile:
    """One tile of the camera image: ``rgb`` (h×w×3, W/(m²·sr)) at column
    ``x``, row ``y`` (pixels from the top-left corner); ``variance`` (h×w)
    is the variance of each pixel's estimate averaged over the three
    channels, or ``None``; ``rays`` traced for it by this request (0 when the
    service had the tile memoised).

    Tiles of the GET route (``Client.tile(scene, tx, ty)``) also carry their
    strong ``etag`` (pass it as ``if_none_match`` to revalidate), the ``aov``
    they show, ``records_created``, the preset's ``passes`` and the
    ``passes_rendered`` by this request. With ``aov="std_dev"``, ``rgb`` is
    the per-pixel standard error in all three channels and ``variance`` is
    ``None``.
    """

    x: int
    y: int
    rgb: npt.NDArray[np.float32]
    variance: npt.NDArray[np.float32] | None
    rays: int
    etag: str | None = None
    aov: str = "radiance"
    records_created: int = 0
    passes: int | None = None
    passes_rendered: int | None = None

    @property
    def height(self) -> int:
        return int(self.rgb.shape[0])

    @property
    def width(self) -> int:
        return int(self.rgb.shape[1])

    @property
    def std_dev(self) -> npt.NDArray[np.float32] | None:
        """Per-pixel standard error (h×w, W/(m²·sr)), see :attr:`Image.std_dev`."""
        return _std_dev(self.aov, self.rgb, self.variance)


@dataclass(frozen=True)
class TileInfo:
    """What one tile of an assembled image answered, without its pixels:
    grid column ``tx`` and row ``ty``, pixel rectangle ``x``, ``y``,
    ``width``, ``height``, its ``etag`` (GET tiles only), ``rays`` and
    ``records_created`` by that request, and ``passes_rendered`` (GET tiles:
    passes the service rendered rather than took from its memo)."""

    tx: int
    ty: int
    x: int
    y: int
    width: int
    height: int
    etag: str | None
    rays: int
    records_created: int
    passes_rendered: int | None = None


class TileBytes(bytes):
    """An encoded tile (PNG, EXR or JSON bytes, usable wherever ``bytes``
    is) with the answer's headers: ``etag`` (GET tiles), ``content_type``,
    ``x`` and ``y`` (pixels), ``rays``, and ``headers`` (every header,
    lower-case names, e.g. ``x-passes``, ``x-std-dev-scale``)."""

    headers: Mapping[str, str]

    def __new__(cls, data: bytes, headers: Mapping[str, str]) -> TileBytes:
        obj = super().__new__(cls, data)
        obj.headers = dict(headers)
        return obj

    @property
    def etag(self) -> str | None:
        """The strong ETag, quoted as the service sent it (``None`` for POST tiles)."""
        return self.headers.get("etag")

    @property
    def content_type(self) -> str:
        return self.headers.get("content-type", "")

    @property
    def x(self) -> int:
        return int(self.headers.get("x-tile-x", 0))

    @property
    def y(self) -> int:
        return int(self.headers.get("x-tile-y", 0))

    @property
    def rays(self) -> int:
        return int(self.headers.get("x-rays", 0))

    def json(self) -> Any:
        """The body parsed as JSON (``format="json"`` tiles)."""
        return json.loads(self.decode("utf-8"))


@dataclass(frozen=True)
class Image:
    """A camera image assembled from tiles.

    ``rgb`` is ``H×W×3`` float32, top row first: linear radiance in
    W/(m²·sr), or with ``aov="std_dev"`` the per-pixel standard error in all
    three channels. ``variance`` is ``H×W``: the service reports one variance
    per pixel, the variance of the pixel's estimate averaged over R, G and
    B, in (W/(m²·sr))² — ``None`` for ``aov="std_dev"`` or if the service
    sent none. ``std_dev`` is the standard error either way.

    Metadata: ``rays`` sums what the tiles' requests traced (0 for tiles
    the service had memoised), ``aov``, ``preset``, ``pass_index`` (``None``:
    the preset's last pass), ``seed``, ``size`` (the tile side) and
    ``tiles``, one :class:`TileInfo` per tile in row-major grid order (each
    GET tile's ``etag`` among them).
    """

    rgb: npt.NDArray[np.float32]
    variance: npt.NDArray[np.float32] | None
    rays: int
    aov: str = "radiance"
    preset: str | None = None
    pass_index: int | None = None
    seed: int | None = None
    size: int | None = None
    tiles: tuple[TileInfo, ...] = field(default=())

    @property
    def height(self) -> int:
        return int(self.rgb.shape[0])

    @property
    def width(self) -> int:
        return int(self.rgb.shape[1])

    @property
    def std_dev(self) -> npt.NDArray[np.float32] | None:
        """Per-pixel standard error (H×W, W/(m²·sr)): the square root of
        ``variance`` (negative rounding clamped to 0, as the service does),
        or for ``aov="std_dev"`` the first channel of ``rgb``; bit-identical
        either way."""
        return _std_dev(self.aov, self.rgb, self.variance)

    @property
    def records_created(self) -> int:
        """Irradiance-cache records the tiles' requests placed."""
        return sum(t.records_created for t in self.tiles)

    def save_png(self, path: str | os.PathLike[str], exposure: float = 0.0) -> None:
        """Tone-mapped 8-bit sRGB PNG, the service's mapping (:func:`imageio.srgb8`)."""
        imageio.write_png(path, self.rgb, exposure)

    def save_exr(self, path: str | os.PathLike[str]) -> None:
        """Linear float OpenEXR with channels R, G, B and ``variance`` (when known)."""
        imageio.write_exr(path, self.rgb, self.variance)

    def save_pfm(self, path: str | os.PathLike[str]) -> None:
        """Linear float PFM (RGB only)."""
        imageio.write_pfm(path, self.rgb)


def _std_dev(
    aov: str, rgb: npt.NDArray[np.float32], variance: npt.NDArray[np.float32] | None
) -> npt.NDArray[np.float32] | None:
    if aov == "std_dev":
        return rgb[:, :, 0]
    if variance is None:
        return None
    return np.sqrt(np.maximum(variance, np.float32(0.0)))
