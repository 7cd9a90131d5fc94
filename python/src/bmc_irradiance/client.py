"""The client of every route of the bmc-irradiance HTTP service, one part per
resource (the ``_*.py`` modules beside this one)."""

from __future__ import annotations

from ._base import Estimator
from ._chunking import (
    DEFAULT_MAX_BODY_BYTES,
    DEFAULT_MAX_PATHS_PER_REQUEST,
    DEFAULT_MAX_POINTS,
    DEFAULT_MAX_SAMPLES,
    chunk_seed,
)
from ._http import Transport
from ._images import _Images
from ._points import TargetLike, Vectors, _Points
from ._quadratures import _Quadratures
from ._records import _Records
from ._service import _Service

__all__ = [
    "DEFAULT_MAX_BODY_BYTES",
    "DEFAULT_MAX_PATHS_PER_REQUEST",
    "DEFAULT_MAX_POINTS",
    "DEFAULT_MAX_SAMPLES",
    "Client",
    "Estimator",
    "TargetLike",
    "Vectors",
    "chunk_seed",
]


# Each base is one resource's routes; _Images builds on _Tiles and _Scenes,
# _Points on _Chunking (the limits and the splitting of point sets).
class Client(_Service, _Images, _Records, _Points, _Quadratures):
    """A client of one bmc-irradiance service.

    ``url`` is the service's base URL. ``timeout`` bounds each HTTP request
    in seconds; ``retries`` is how many times a 503 answer with
    ``Retry-After`` (the CPU queue is full) is retried, each after the wait
    the header names (at most ``max_retry_wait`` seconds). ``token`` is sent
    as ``Authorization: Bearer <token>``; the service requires it for
    ``upload``, ``delete`` and ``clear_cache`` when ``server.auth_token`` is set.

    Point sets larger than one request may carry are split into several
    requests and reassembled in order. No route reports the service's limits,
    so ``max_points``, ``max_body_bytes``, ``max_paths_per_request`` and
    ``max_samples`` start at the defaults of ``config/default.toml``; when the
    service answers 422 ``limit_exceeded`` for ``points`` or
    ``estimated_paths``, or 413, the client lowers its own value to the
    service's and starts the split again. Requests are sent one after the
    other; each must finish within the service's
    ``limits.request_deadline_secs`` (30 s by default, else 504), so pass a
    smaller ``max_points`` for expensive estimators on many points.

    Camera images: :meth:`image` assembles the reproducible GET tiles of a
    quality preset (:meth:`presets`) fetched concurrently; :meth:`tile` and
    :meth:`tile_bytes` fetch one tile, with its ETag and ``if_none_match``
    revalidation (``None`` on 304).

    Errors: any non-2xx answer raises :class:`ServiceError` with the
    service's ``code``, ``message`` and ``field`` (also when the service
    refused a large upload before reading all of it); network failures
    raise an ``OSError`` (``ConnectionRefusedError``, ``TimeoutError``, ...).
    """

    def __init__(
        self,
        url: str = "http://127.0.0.1:8080",
        timeout: float = 120.0,
        retries: int = 5,
        token: str | None = None,
        *,
        max_points: int = DEFAULT_MAX_POINTS,
        max_body_bytes: int = DEFAULT_MAX_BODY_BYTES,
        max_paths_per_request: int = DEFAULT_MAX_PATHS_PER_REQUEST,
        max_samples: int = DEFAULT_MAX_SAMPLES,
        max_retry_wait: float = 60.0,
    ) -> None:
        self._http = Transport(url, timeout, retries, token, max_retry_wait)
        self.max_points = max_points
        self.max_body_bytes = max_body_bytes
        self.max_paths_per_request = max_paths_per_request
        self.max_samples = max_samples

    @property
    def url(self) -> str:
        """The service's base URL."""
        return self._http.base
