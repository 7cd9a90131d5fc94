"""Result types: numpy arrays plus the response's metadata."""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from typing import Any, Optional, Tuple, Union

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

    Only ``mc`` and ``qmc`` take a target; ``bmc`` is refused (422, field ``target``).
    """

    relative_error: float
    confidence: float = 0.95
    max_samples: Optional[int] = None

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
    its standard error (calibrated for ``qmc`` and ``bmc`` unless
    ``calibrate=False``). The metadata is the service's: ``decomposition``
    (``split`` or ``hemisphere``), ``prior`` (``environment`` or ``none``),
    ``calibration`` (``scale``, ``floor``, ... or ``None``), and for ``bmc``
    the ``lengthscale`` and kernel ``noise`` used. With a target, per point:
    ``samples`` spent, ``relative_error`` reached and ``target_met``.
    ``rays`` sums all requests; ``chunks`` lists the requests the point set
    was split into (one unless it exceeded the service's limits).
    """

    value: FloatArray
    std_dev: FloatArray
    rays: int
    decomposition: str
    prior: str
    calibration: Optional[dict[str, Any]] = None
    lengthscale: Optional[float] = None
    noise: Optional[float] = None
    samples: Optional[npt.NDArray[np.int64]] = None
    relative_error: Optional[FloatArray] = None
    target_met: Optional[npt.NDArray[np.bool_]] = None
    chunks: Tuple[Chunk, ...] = field(default=())

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
    chunks: Tuple[Chunk, ...] = field(default=())

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
    ``x``, row ``y``; ``variance`` (h×w) is the variance of each pixel's
    estimate averaged over the three channels, or ``None``; ``rays`` traced."""

    x: int
    y: int
    rgb: npt.NDArray[np.float32]
    variance: Optional[npt.NDArray[np.float32]]
    rays: int


@dataclass(frozen=True)
class Image:
    """A camera image assembled from tiles.

    ``rgb`` is ``H×W×3`` linear radiance in W/(m²·sr) (float32, top row
    first). ``variance`` is ``H×W``: the service reports one variance per
    pixel, the variance of the pixel's estimate averaged over R, G and B,
    in (W/(m²·sr))² — ``None`` if the service sent none. ``rays`` sums all tiles.
    """

    rgb: npt.NDArray[np.float32]
    variance: Optional[npt.NDArray[np.float32]]
    rays: int

    @property
    def height(self) -> int:
        return int(self.rgb.shape[0])

    @property
    def width(self) -> int:
        return int(self.rgb.shape[1])

    @property
    def std_dev(self) -> Optional[npt.NDArray[np.float32]]:
        """Per-pixel standard error (H×W, W/(m²·sr)): the square root of ``variance``."""
        return None if self.variance is None else np.sqrt(self.variance)

    def save_png(self, path: Union[str, "os.PathLike[str]"], exposure: float = 0.0) -> None:
        """Tone-mapped 8-bit sRGB PNG, the service's mapping (:func:`imageio.srgb8`)."""
        imageio.write_png(path, self.rgb, exposure)

    def save_exr(self, path: Union[str, "os.PathLike[str]"]) -> None:
        """Linear float OpenEXR with channels R, G, B and ``variance`` (when known)."""
        imageio.write_exr(path, self.rgb, self.variance)

    def save_pfm(self, path: Union[str, "os.PathLike[str]"]) -> None:
        """Linear float PFM (RGB only)."""
        imageio.write_pfm(path, self.rgb)
