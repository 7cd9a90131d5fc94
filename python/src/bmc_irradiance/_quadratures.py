"""BMC quadrature weights of one configuration."""

from __future__ import annotations

from typing import Any

import numpy as np

from ._base import _Resource
from .results import Quadrature


class _Quadratures(_Resource):
    """``/v1/quadratures``."""

    def quadrature(
        self,
        samples: int = 64,
        *,
        sample_set: str = "fibonacci",
        kernel: str = "squared_exponential",
        lengthscale: float = 0.5,
        variance: float | None = None,
        noise: float | None = None,
        density: str = "lambert",
        exponent: float | None = None,
        mirror_elevation: float | None = None,
        prior_mean: str = "zero",
        kernel_mean: str = "exact",
        seed: int | None = None,
    ) -> Quadrature:
        """BMC weights of one configuration (``POST /v1/quadratures``).

        ``samples`` directions of ``sample_set`` (``fibonacci``,
        ``fibonacci_cosine``, ``uniform``, ``cosine``, ``stratified``,
        ``stratified_cosine``; ``seed`` for the random kinds), a ``kernel``
        (``squared_exponential``, ``matern32``, ``matern52``) with
        ``lengthscale`` (chordal distance),
        ``variance`` σ² (service default 1) and ``noise`` σ_n² (default 1e-8),
        the ``density`` (``lambert``, ``uniform``, or ``phong`` with
        ``exponent`` and ``mirror_elevation`` in radians), ``prior_mean``
        (``zero``, ``gls``) and ``kernel_mean`` (``exact``,
        ``spherical_gaussian``). Computed once, then served from the
        service's cache (``cached``).
        """
        sample_doc: dict[str, Any] = {"kind": sample_set, "count": int(samples)}
        if seed is not None:
            sample_doc["seed"] = int(seed)
        kernel_doc: dict[str, Any] = {"kind": kernel, "lengthscale": float(lengthscale)}
        if variance is not None:
            kernel_doc["variance"] = float(variance)
        if noise is not None:
            kernel_doc["noise"] = float(noise)
        density_doc: dict[str, Any] = {"kind": density}
        if exponent is not None:
            density_doc["exponent"] = float(exponent)
        if mirror_elevation is not None:
            density_doc["mirror_elevation"] = float(mirror_elevation)
        doc = self._http.post_json(
            "/v1/quadratures",
            {
                "sample_set": sample_doc,
                "kernel": kernel_doc,
                "density": density_doc,
                "prior_mean": prior_mean,
                "kernel_mean": kernel_mean,
            },
        ).json()
        return Quadrature(
            id=str(doc["id"]),
            directions=np.asarray(doc["directions"], dtype=np.float64).reshape(-1, 3),
            kernel_means=np.asarray(doc["kernel_means"], dtype=np.float64),
            weights=np.asarray(doc["weights"], dtype=np.float64),
            prior_variance=float(doc["prior_variance"]),
            posterior_variance=float(doc["posterior_variance"]),
            jitter=float(doc["jitter"]),
            condition_estimate=float(doc["condition_estimate"]),
            density_integral=float(doc["density_integral"]),
            cached=bool(doc["cached"]),
        )
