"""Routes about the service itself: health, readiness, OpenAPI, metrics, presets."""

from __future__ import annotations

from typing import Any

from ._base import _Resource


class _Service(_Resource):
    """``/health``, ``/ready``, ``/openapi.json``, ``/metrics`` and ``/v1/presets``."""

    def health(self) -> dict[str, Any]:
        """``GET /health``: ``status`` (``ok`` or ``wedged``), ``version``, ``scenes``, ``cpu``."""
        return dict(self._http.get_json("/health", accept=(503,)))

    def ready(self) -> bool:
        """``GET /ready``: whether the service should be sent work now."""
        return self._http.request("GET", "/ready", accept=(503,)).status == 200

    def openapi(self) -> dict[str, Any]:
        """``GET /openapi.json``: the OpenAPI 3 document of every route."""
        return dict(self._http.get_json("/openapi.json"))

    def metrics(self) -> str:
        """``GET /metrics``: Prometheus text."""
        return self._http.request("GET", "/metrics").body.decode("utf-8")

    def presets(self) -> list[dict[str, Any]]:
        """``GET /v1/presets``: the quality presets of camera tiles, cheapest
        first (``draft``, ``preview``, ``interactive``, ``standard``, ``final``). Each is a
        dict with ``name``, ``default`` (``True`` for the one used when none
        is named, ``preview``), ``samples_per_pixel`` (camera rays per pixel
        in each pass), ``passes``, ``max_depth`` and ``estimator`` (the
        irradiance cache's knobs)."""
        return list(self._http.get_json("/v1/presets"))
