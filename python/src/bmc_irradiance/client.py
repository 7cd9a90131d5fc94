"""The client of every route of the bmc-irradiance HTTP service."""

from __future__ import annotations

import concurrent.futures
import json
import os
import re
import warnings
from pathlib import Path
from typing import (
    Any,
    Callable,
    Dict,
    List,
    Literal,
    Mapping,
    Optional,
    Sequence,
    Tuple,
    Union,
    overload,
)

import numpy as np
import numpy.typing as npt

from ._http import Response, Transport
from ._progress import Progress
from .errors import ServiceError
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

#: Defaults of ``config/default.toml`` (``[limits]``); a service with other
#: limits is followed automatically where its 422/413 answers say so.
DEFAULT_MAX_POINTS = 65536
DEFAULT_MAX_BODY_BYTES = 4194304
DEFAULT_MAX_PATHS_PER_REQUEST = 134217728
DEFAULT_MAX_SAMPLES = 4096

# Longest JSON text of one float (Python's repr, e.g. -1.2345678901234567e-300).
_FLOAT_CHARS = 24

Vectors = npt.ArrayLike
TargetLike = Union[ErrorTarget, Mapping[str, Any]]
Estimator = Union[str, Mapping[str, Any]]


def _point_bytes(vectors: int, names: int) -> int:
    """Most JSON bytes one point of ``vectors`` 3-vectors takes in a request."""
    return 4 + names + vectors * (5 + 3 * _FLOAT_CHARS)


def _splitmix64(z: int) -> int:
    z = (z + 0x9E3779B97F4A7C15) & 0xFFFFFFFFFFFFFFFF
    z = ((z ^ (z >> 30)) * 0xBF58476D1CE4E5B9) & 0xFFFFFFFFFFFFFFFF
    z = ((z ^ (z >> 27)) * 0x94D049BB133111EB) & 0xFFFFFFFFFFFFFFFF
    return z ^ (z >> 31)


def chunk_seed(seed: int, index: int) -> int:
    """Seed of request ``index`` of a split point set.

    The service seeds point ``i`` of a request from ``(seed, i)``, ``i``
    counting from 0 in each request, so a split set cannot reproduce one big
    request's numbers. The first request keeps ``seed`` (its points get
    exactly the numbers one big request would give them); later requests get
    64-bit seeds hashed from ``(seed, index)``, so points at the same index of
    different requests do not share a random stream.
    """
    if index == 0:
        return seed
    return _splitmix64(_splitmix64(seed) ^ (0xD6E8FEB86659FD93 * index & 0xFFFFFFFFFFFFFFFF))


def _vectors(name: str, values: Vectors, count: Optional[int]) -> npt.NDArray[np.float64]:
    """``values`` as an N×3 float array; a single 3-vector is repeated
    ``count`` times, or is one point when ``count`` is ``None``."""
    array = np.asarray(values, dtype=np.float64)
    if array.shape == (3,):
        array = array.reshape(1, 3) if count is None else np.broadcast_to(array, (count, 3))
    if array.ndim != 2 or array.shape[1] != 3:
        raise ValueError(f"{name} must be an N×3 array, got shape {array.shape}")
    if count is not None and array.shape[0] != count:
        raise ValueError(f"{name} has {array.shape[0]} rows, expected {count}")
    if not np.all(np.isfinite(array)):
        raise ValueError(f"{name} must be finite")
    return array


_POINT_FIELD = re.compile(r"^points\[(\d+)\](.*)$")
_LIMIT = re.compile(r"above the limit of (\d+)")
_VALUE = re.compile(r"is (\d+), above")


def _estimator_doc(estimator: Optional[Estimator]) -> Optional[Dict[str, Any]]:
    if estimator is None:
        return None
    if isinstance(estimator, str):
        return {"method": estimator}
    return dict(estimator)


class Client:
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
        token: Optional[str] = None,
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

    # -- service -----------------------------------------------------------

    def health(self) -> Dict[str, Any]:
        """``GET /health``: ``status`` (``ok`` or ``wedged``), ``version``, ``scenes``, ``cpu``."""
        return dict(self._http.get_json("/health", accept=(503,)))

    def ready(self) -> bool:
        """``GET /ready``: whether the service should be sent work now."""
        return self._http.request("GET", "/ready", accept=(503,)).status == 200

    def openapi(self) -> Dict[str, Any]:
        """``GET /openapi.json``: the OpenAPI 3 document of every route."""
        return dict(self._http.get_json("/openapi.json"))

    def metrics(self) -> str:
        """``GET /metrics``: Prometheus text."""
        return self._http.request("GET", "/metrics").body.decode("utf-8")

    # -- scenes ------------------------------------------------------------

    def scenes(self) -> List[Dict[str, Any]]:
        """``GET /v1/scenes``: summaries of the loaded scenes, sorted by id."""
        return list(self._http.get_json("/v1/scenes"))

    def scene(self, id: str) -> Dict[str, Any]:
        """``GET /v1/scenes/{id}``: ``shapes``, ``triangles``, ``emitters``,
        ``resolution`` ([width, height] in pixels), bounds, fitted kernels..."""
        return dict(self._http.get_json(f"/v1/scenes/{_segment(id)}"))

    def upload(
        self,
        scene: Union[str, bytes, "os.PathLike[str]"],
        id: Optional[str] = None,
        *,
        lenient: bool = False,
        assets: Union[None, str, Sequence[str], Mapping[str, Union[bytes, "os.PathLike[str]"]]] = None,
    ) -> Dict[str, Any]:
        """``POST /v1/scenes``: adds a scene, or replaces the one with the same id.

        ``scene`` is a path to a JSON scene document or a Mitsuba 3 XML file,
        or the document's text. A JSON document's id is its ``name``; ``id``
        replaces that name. An XML scene's id is ``id``, by default the file's
        stem; ``lenient`` approximates unsupported Mitsuba features instead of
        refusing them. Returns the scene's summary.

        Without ``assets``, files the scene references (meshes, environment
        maps, textures) must already be in the service's scenes directory.
        With ``assets`` they travel with it (``multipart/form-data``):

        - ``"auto"``: every file the document names (``"filename"`` values
          of a JSON document, ``<string name="filename" value=…>`` of XML),
          read relative to the scene file's directory;
        - a list of such relative names;
        - a mapping from relative name to bytes or a local path.

        The service refuses names that climb out (``..``), absolute names and
        uploads over its ``limits.max_upload_bytes``, as a
        :class:`ServiceError` naming the part (``assets[i]``).
        """
        text, stem = _scene_text(scene)
        first = text.lstrip()[:1]
        if first not in ("{", "<"):
            raise ValueError("the scene is neither a JSON document nor Mitsuba XML")
        xml = first == "<"
        query: Dict[str, Any] = {}
        if first == "{" and id is not None:
            document = json.loads(text)
            document["name"] = id
            text = json.dumps(document)
        if xml:
            scene_id = id if id is not None else stem
            if scene_id is None:
                raise ValueError("an XML scene given as text needs an id")
            query = {"id": scene_id, "lenient": True if lenient else None}
        if assets is None:
            answer = self._http.request(
                "POST",
                "/v1/scenes",
                body=text.encode("utf-8"),
                content_type="application/xml" if xml else "application/json",
                query=query,
            )
            return dict(answer.json())
        # A scene given as a path (it has a stem): names resolve beside it.
        base = Path(os.fspath(scene)).parent if stem is not None else None  # type: ignore[arg-type]
        files = _asset_files(text, xml, assets, base)
        boundary = "bmc-" + os.urandom(12).hex()
        parts = [("scene", "scene.xml" if xml else "scene.json", text.encode("utf-8"))]
        parts += [("asset", name, data) for name, data in files]
        answer = self._http.request(
            "POST",
            "/v1/scenes",
            body=_multipart(parts, boundary),
            content_type=f"multipart/form-data; boundary={boundary}",
            query=query,
        )
        return dict(answer.json())

    def delete(self, id: str) -> None:
        """``DELETE /v1/scenes/{id}``; requests already using the scene finish normally."""
        self._http.request("DELETE", f"/v1/scenes/{_segment(id)}")

    def cache(self, scene: str) -> Dict[str, Any]:
        """``GET /v1/scenes/{id}/cache``: irradiance-cache statistics per configuration."""
        return dict(self._http.get_json(f"/v1/scenes/{_segment(scene)}/cache"))

    def clear_cache(self, scene: str) -> Dict[str, Any]:
        """``DELETE /v1/scenes/{id}/cache``: drops the scene's cache records (secondary too)."""
        return dict(self._http.request("DELETE", f"/v1/scenes/{_segment(scene)}/cache").json())

    def export_records(self, scene: str) -> bytes:
        """``GET /v1/scenes/{id}/records``: the records of the scene's
        reproducible tiles held by the service, as bytes in the service's log
        format (``BMCLOG01`` then checksummed entries); keep them as a backup
        or pass them to :meth:`import_records` of another service."""
        return self._http.request(
            "GET",
            f"/v1/scenes/{_segment(scene)}/records",
            headers={"accept": "application/vnd.bmc-records"},
        ).body

    def import_records(self, scene: str, records: bytes) -> Dict[str, Any]:
        """``POST /v1/scenes/{id}/records``: adds an export of the same scene
        content, all or nothing; returns ``{"imported", "already_held",
        "records"}``. A damaged entry or one of another scene's content raises
        :class:`ServiceError` (422) naming ``entries[i]``."""
        answer = self._http.request(
            "POST",
            f"/v1/scenes/{_segment(scene)}/records",
            body=bytes(records),
            content_type="application/vnd.bmc-records",
        )
        return dict(answer.json())

    # -- points ------------------------------------------------------------

    def irradiance(
        self,
        scene: str,
        positions: Vectors,
        normals: Vectors,
        method: str = "bmc",
        samples: int = 64,
        *,
        decomposition: Optional[str] = None,
        prior: Optional[str] = None,
        calibrate: Optional[bool] = None,
        records_prior: Optional[bool] = None,
        sample_set: Optional[Union[str, Mapping[str, Any]]] = None,
        kernel: Optional[Mapping[str, Any]] = None,
        target: Optional[TargetLike] = None,
        max_depth: Optional[int] = None,
        seed: Optional[int] = None,
    ) -> IrradianceResult:
        """Irradiance E(x, n) in W/m² (RGB) at N points
        (``POST /v1/scenes/{id}/irradiance``).

        ``positions`` and ``normals`` are N×3 (a single normal applies to all
        points; normals need not be unit length). ``method`` is ``"mc"``,
        ``"qmc"`` or ``"bmc"`` with ``samples`` hemisphere samples per point;
        ``decomposition`` (``"auto"``, ``"split"``, ``"hemisphere"``),
        ``prior`` (``"environment"``, ``"none"``), ``calibrate``,
        ``sample_set`` (a kind such as ``"fibonacci_cosine"`` or
        ``{"kind", "seed"}``) and ``kernel`` (``{"kind", "lengthscale",
        "variance", "noise"}``, ``bmc`` only) default to the service's
        choices. ``records_prior=True`` (``qmc``, ``bmc``) combines
        each point's indirect part with the irradiance cache's records where
        rendered tiles left some, and under the hemisphere decomposition its
        direct part with the direct light seen from the records' places;
        ``result.records_prior_points`` and ``result.direct_records_points``
        count the points they covered. ``target`` (an :class:`ErrorTarget` or a dict with
        ``relative_error``, ``confidence``, ``max_samples``) estimates each
        point until its error bar meets it (``mc`` and ``qmc`` only).
        ``max_depth`` is the longest path in segments (service default 16);
        ``seed`` defaults to the service's 1.

        Point sets over the service's limits are sent as several requests
        (``result.chunks``) and reassembled in order. The first request's
        points get exactly the numbers of one big request; later requests use
        seeds derived with :func:`chunk_seed`, because the service seeds each
        point from its index *within its request*. So a split result is
        equivalent in distribution to one big request, not bit-identical,
        and it is reproducible for the same limits and seed.
        """
        positions = _vectors("positions", positions, None)
        count = positions.shape[0]
        normals = _vectors("normals", normals, count)
        if count == 0:
            raise ValueError("no points")
        estimator: Dict[str, Any] = {"method": method, "samples": int(samples)}
        if decomposition is not None:
            estimator["decomposition"] = decomposition
        if prior is not None:
            estimator["prior"] = prior
        if calibrate is not None:
            estimator["calibrate"] = bool(calibrate)
        if records_prior is not None:
            estimator["records_prior"] = bool(records_prior)
        if sample_set is not None:
            estimator["sample_set"] = (
                {"kind": sample_set} if isinstance(sample_set, str) else dict(sample_set)
            )
        if kernel is not None:
            estimator["kernel"] = dict(kernel)
        base: Dict[str, Any] = {"estimator": estimator}
        if max_depth is not None:
            base["max_depth"] = int(max_depth)
        paths_per_point = int(samples)
        if target is not None:
            target_doc = target.to_json() if isinstance(target, ErrorTarget) else dict(target)
            base["target"] = target_doc
            paths_per_point = int(target_doc.get("max_samples") or self.max_samples)
        pos, nor = positions.tolist(), normals.tolist()

        def points(start: int, stop: int) -> List[Dict[str, Any]]:
            return [
                {"position": p, "normal": n} for p, n in zip(pos[start:stop], nor[start:stop])
            ]

        answers = self._split(
            f"/v1/scenes/{_segment(scene)}/irradiance",
            base,
            points,
            count,
            _point_bytes(2, len('"position":,"normal":')),
            max(paths_per_point, 1),
            1 if seed is None else int(seed),
        )
        first = answers[0][1]
        for chunk, doc in answers[1:]:
            for key in ("decomposition", "prior", "lengthscale", "noise", "calibration"):
                if doc.get(key) != first.get(key):
                    warnings.warn(
                        f"request for points {chunk.start}:{chunk.stop} reported "
                        f"{key}={doc.get(key)!r}, the first {first.get(key)!r}",
                        stacklevel=2,
                    )
        targeted = "samples" in first
        return IrradianceResult(
            value=_rows(answers, "irradiance"),
            std_dev=_rows(answers, "std_dev"),
            rays=sum(int(doc["rays"]) for _, doc in answers),
            decomposition=str(first.get("decomposition")),
            prior=str(first.get("prior")),
            calibration=first.get("calibration"),
            lengthscale=first.get("lengthscale"),
            noise=first.get("noise"),
            records_prior_points=(
                sum(int(doc["records_prior_points"]) for _, doc in answers)
                if "records_prior_points" in first
                else None
            ),
            direct_records_points=(
                sum(int(doc["direct_records_points"]) for _, doc in answers)
                if "direct_records_points" in first
                else None
            ),
            samples=_flat(answers, "samples", np.int64) if targeted else None,
            relative_error=_flat(answers, "relative_error", np.float64) if targeted else None,
            target_met=_flat(answers, "target_met", np.bool_) if targeted else None,
            chunks=tuple(chunk for chunk, _ in answers),
        )

    def radiance(
        self,
        scene: str,
        positions: Vectors,
        normals: Vectors,
        directions: Vectors,
        *,
        estimator: Optional[Estimator] = None,
        repeats: Optional[int] = None,
        max_depth: Optional[int] = None,
        seed: Optional[int] = None,
    ) -> RadianceResult:
        """Outgoing radiance in W/(m²·sr) (RGB) leaving surface points towards
        a viewer direction each (``POST /v1/scenes/{id}/radiance``).

        ``positions`` must lie on surfaces; ``normals`` and ``directions``
        (from the point towards the viewer, world frame) are N×3 or one
        3-vector for all. ``estimator`` is ``"cache"`` (the service's default:
        the scene's shared irradiance cache), ``"path"`` (path tracing) or a
        dict with ``method`` and the cache options; ``repeats`` independent
        evaluations are averaged per point (service default 16). Large point
        sets are split as for :meth:`irradiance`.
        """
        positions = _vectors("positions", positions, None)
        count = positions.shape[0]
        normals = _vectors("normals", normals, count)
        directions = _vectors("directions", directions, count)
        if count == 0:
            raise ValueError("no points")
        base: Dict[str, Any] = {}
        integrator = _estimator_doc(estimator)
        if integrator is not None:
            base["estimator"] = integrator
        if repeats is not None:
            base["repeats"] = int(repeats)
        if max_depth is not None:
            base["max_depth"] = int(max_depth)
        paths_per_point = repeats if repeats is not None else 16
        if (integrator or {}).get("method", "cache") in ("cache", "bmc"):
            options = integrator or {}
            paths_per_point += (
                int(options.get("samples") or 64)
                * int(options.get("paths_per_direction") or 1)
                * (1 + int(options.get("ambient_bounces") or 0))
            )
        pos, nor, dirs = positions.tolist(), normals.tolist(), directions.tolist()

        def points(start: int, stop: int) -> List[Dict[str, Any]]:
            return [
                {"position": p, "normal": n, "direction": d}
                for p, n, d in zip(pos[start:stop], nor[start:stop], dirs[start:stop])
            ]

        answers = self._split(
            f"/v1/scenes/{_segment(scene)}/radiance",
            base,
            points,
            count,
            _point_bytes(3, len('"position":,"normal":,"direction":')),
            paths_per_point,
            1 if seed is None else int(seed),
        )
        return RadianceResult(
            value=_rows(answers, "radiance"),
            std_dev=_rows(answers, "std_dev"),
            rays=sum(int(doc["rays"]) for _, doc in answers),
            chunks=tuple(chunk for chunk, _ in answers),
        )

    def _split(
        self,
        path: str,
        base: Mapping[str, Any],
        points: Callable[[int, int], List[Dict[str, Any]]],
        count: int,
        point_bytes: int,
        paths_per_point: int,
        seed: int,
    ) -> List[Tuple[Chunk, Dict[str, Any]]]:
        """Sends ``count`` points in as few requests as the limits allow and
        returns each chunk with its answer, in order. When the service's
        answer shows a lower limit than assumed, the split starts again, so
        the result depends only on the final limits."""
        # Everything but the points, with the longest seed.
        overhead = len(json.dumps(dict(base, points=[], seed=2**64 - 1), separators=(",", ":")))
        previous: Optional[int] = None
        while True:
            size = min(
                self.max_points,
                max(1, (self.max_body_bytes - overhead) // point_bytes),
                max(1, self.max_paths_per_request // max(paths_per_point, 1)),
            )
            if previous is not None and size >= previous:
                raise RuntimeError(f"cannot split {count} points within the service's limits")
            previous = size
            answers: List[Tuple[Chunk, Dict[str, Any]]] = []
            sent = 0
            try:
                for index, start in enumerate(range(0, count, size)):
                    chunk = Chunk(start, min(start + size, count), chunk_seed(seed, index))
                    document = dict(base)
                    document["points"] = points(chunk.start, chunk.stop)
                    document["seed"] = chunk.seed
                    data = json.dumps(document, separators=(",", ":"), allow_nan=False).encode()
                    sent = len(data)
                    answer = self._http.request(
                        "POST", path, body=data, content_type="application/json"
                    )
                    answers.append((chunk, answer.json()))
                return answers
            except ServiceError as err:
                offset = len(answers) * size
                if size <= 1 or not self._learn(err, sent):
                    raise _shift_point_field(err, offset) from None
                paths_per_point = max(
                    paths_per_point, _paths_per_point(err, min(size, count - offset))
                )

    def _learn(self, err: ServiceError, sent: int) -> bool:
        """Lowers an assumed limit after a 422 ``limit_exceeded`` (``points``,
        ``estimated_paths``) or a 413 for a body of ``sent`` bytes; whether
        the split should start again."""
        if err.status == 422 and err.code == "limit_exceeded":
            match = _LIMIT.search(err.message)
            if match is None:
                return False
            limit = int(match.group(1))
            if err.field == "points":
                self.max_points = min(self.max_points, max(limit, 1))
                return True
            if err.field == "estimated_paths":
                self.max_paths_per_request = min(self.max_paths_per_request, limit)
                return True
            return False
        if err.status == 413:
            self.max_body_bytes = min(self.max_body_bytes, sent) - 1
            return True
        return False

    # -- quadratures -------------------------------------------------------

    def quadrature(
        self,
        samples: int = 64,
        *,
        sample_set: str = "fibonacci",
        kernel: str = "squared_exponential",
        lengthscale: float = 0.5,
        variance: Optional[float] = None,
        noise: Optional[float] = None,
        density: str = "lambert",
        exponent: Optional[float] = None,
        mirror_elevation: Optional[float] = None,
        prior_mean: str = "zero",
        kernel_mean: str = "exact",
        seed: Optional[int] = None,
    ) -> Quadrature:
        """BMC weights of one configuration (``POST /v1/quadratures``).

        ``samples`` directions of ``sample_set`` (``fibonacci``,
        ``fibonacci_cosine``, ``uniform``, ``cosine``, ``stratified``; ``seed``
        for the random kinds), a ``kernel`` (``squared_exponential``,
        ``matern32``, ``matern52``) with ``lengthscale`` (chordal distance),
        ``variance`` σ² (service default 1) and ``noise`` σ_n² (default 1e-8),
        the ``density`` (``lambert``, ``uniform``, or ``phong`` with
        ``exponent`` and ``mirror_elevation`` in radians), ``prior_mean``
        (``zero``, ``gls``) and ``kernel_mean`` (``exact``,
        ``spherical_gaussian``). Computed once, then served from the
        service's cache (``cached``).
        """
        sample_doc: Dict[str, Any] = {"kind": sample_set, "count": int(samples)}
        if seed is not None:
            sample_doc["seed"] = int(seed)
        kernel_doc: Dict[str, Any] = {"kind": kernel, "lengthscale": float(lengthscale)}
        if variance is not None:
            kernel_doc["variance"] = float(variance)
        if noise is not None:
            kernel_doc["noise"] = float(noise)
        density_doc: Dict[str, Any] = {"kind": density}
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

    # -- images ------------------------------------------------------------

    def presets(self) -> List[Dict[str, Any]]:
        """``GET /v1/presets``: the quality presets of camera tiles, cheapest
        first (``draft``, ``preview``, ``final``). Each is a dict with
        ``name``, ``default`` (``True`` for the one used when none is named,
        ``preview``), ``samples_per_pixel`` (camera rays per pixel in each
        pass), ``passes``, ``max_depth`` and ``estimator`` (the irradiance
        cache's knobs)."""
        return list(self._http.get_json("/v1/presets"))

    def _grid_tile(
        self,
        scene: str,
        tx: int,
        ty: int,
        extension: str,
        query: Mapping[str, Any],
        if_none_match: Optional[str],
    ) -> Optional[Response]:
        """``GET /v1/scenes/{id}/tiles/{tx}/{ty}.{extension}``; ``None`` on 304."""
        headers = {"accept": "application/json" if extension == "json" else "*/*"}
        if if_none_match is not None:
            headers["if-none-match"] = if_none_match
        answer = self._http.request(
            "GET",
            f"/v1/scenes/{_segment(scene)}/tiles/{int(tx)}/{int(ty)}.{_segment(extension)}",
            query=query,
            accept=(304,),
            headers=headers,
        )
        return None if answer.status == 304 else answer

    def _tile_request(
        self,
        scene: str,
        x: int,
        y: int,
        width: int,
        height: int,
        format: str,
        spp: Optional[int],
        estimator: Optional[Estimator],
        max_depth: Optional[int],
        seed: Optional[int],
        exposure: Optional[float] = None,
        preset: Optional[str] = None,
        pass_index: Optional[int] = None,
    ) -> Response:
        """``POST /v1/scenes/{id}/tiles`` of a pixel rectangle."""
        body: Dict[str, Any] = {
            "x": int(x),
            "y": int(y),
            "width": int(width),
            "height": int(height),
            "format": format,
        }
        if preset is not None:
            body["preset"] = preset
        if pass_index is not None:
            body["pass"] = int(pass_index)
        if spp is not None:
            body["samples_per_pixel"] = int(spp)
        integrator = _estimator_doc(estimator)
        if integrator is not None:
            body["estimator"] = integrator
        if max_depth is not None:
            body["max_depth"] = int(max_depth)
        if seed is not None:
            body["seed"] = int(seed)
        if exposure is not None:
            body["exposure"] = float(exposure)
        return self._http.post_json(f"/v1/scenes/{_segment(scene)}/tiles", body)

    def tile(
        self,
        scene: str,
        x: int,
        y: int,
        width: Optional[int] = None,
        height: Optional[int] = None,
        *,
        size: Optional[int] = None,
        preset: Optional[str] = None,
        pass_index: Optional[int] = None,
        aov: str = "radiance",
        seed: Optional[int] = None,
        if_none_match: Optional[str] = None,
        spp: Optional[int] = None,
        estimator: Optional[Estimator] = None,
        max_depth: Optional[int] = None,
    ) -> Optional[Tile]:
        """One tile of the scene camera's image as floats (JSON tiles).

        Two forms:

        * ``tile(scene, tx, ty)`` — the GET route
          (``/v1/scenes/{id}/tiles/{tx}/{ty}.json``): ``tx`` and ``ty`` are
          the tile's column and row on the grid of ``size``-pixel squares
          (service default 64; edge tiles are smaller). ``preset``
          (``"draft"``, ``"preview"`` — the service's default — or
          ``"final"``, see :meth:`presets`), ``pass_index`` (0-based; pass
          *k* is the mean of passes 0..*k*; default the preset's last),
          ``seed`` (default 1) and ``aov`` (``"radiance"`` or
          ``"std_dev"``: ``rgb`` is then the per-pixel standard error).
          The same arguments give the same numbers on any service of the
          same version and scene content; ``tile.etag`` names them. With
          ``if_none_match=`` a previous tile's ``etag``, the answer is
          ``None`` when that is still the tile (HTTP 304: nothing rendered
          or sent).
        * ``tile(scene, x, y, width, height)`` — ``POST
          /v1/scenes/{id}/tiles`` of any pixel rectangle (``x``, ``y`` its
          top-left pixel), with ``preset`` and ``pass_index`` as above and
          explicit knobs that override the preset: ``spp`` camera rays per
          pixel in each pass, ``estimator`` (``"cache"``, ``"path"`` or a
          dict of options) and ``max_depth``. Never ``None``.

        Radiance in W/(m²·sr). The records AOV is not an image: use
        :meth:`image` with ``aov="records"``, or :meth:`tile_bytes` with
        ``format="json", aov="records"`` and ``.json()``.
        """
        if _grid_form(width, height):
            _refuse_knobs("tile", spp=spp, estimator=estimator, max_depth=max_depth)
            if aov not in ("radiance", "std_dev"):
                raise ValueError(
                    f"tile() returns images (aov 'radiance' or 'std_dev'), not {aov!r}; "
                    "records come from image(scene, aov='records') or "
                    "tile_bytes(scene, tx, ty, format='json', aov='records').json()"
                )
            query = _grid_query(size, preset, pass_index, seed, aov)
            answer = self._grid_tile(scene, x, y, "json", query, if_none_match)
            if answer is None:
                return None
            return _tile_of(answer, aov)
        _refuse_grid_options("tile", size=size, if_none_match=if_none_match)
        if aov != "radiance":
            raise ValueError("POST tiles are radiance; aov needs the GET form tile(scene, tx, ty)")
        assert width is not None and height is not None
        answer = self._tile_request(
            scene, x, y, width, height, "json", spp, estimator, max_depth, seed,
            preset=preset, pass_index=pass_index,
        )
        return _tile_of(answer, "radiance", (x, y))

    def tile_bytes(
        self,
        scene: str,
        x: int,
        y: int,
        width: Optional[int] = None,
        height: Optional[int] = None,
        *,
        format: str = "png",
        size: Optional[int] = None,
        preset: Optional[str] = None,
        pass_index: Optional[int] = None,
        aov: Optional[str] = None,
        seed: Optional[int] = None,
        exposure: Optional[float] = None,
        scale: Optional[float] = None,
        if_none_match: Optional[str] = None,
        spp: Optional[int] = None,
        estimator: Optional[Estimator] = None,
        max_depth: Optional[int] = None,
    ) -> Optional[TileBytes]:
        """One tile encoded by the service, as :class:`TileBytes` (``bytes``
        with the answer's ``etag``, ``content_type``, ``rays`` and
        ``headers``).

        ``format``: ``"png"`` (8-bit sRGB, radiance tone-mapped with
        ``exposure`` in stops), ``"exr"`` (float R, G, B and ``variance``)
        or ``"json"``. The two forms of :meth:`tile`:

        * ``tile_bytes(scene, tx, ty, format=..., preset=..., aov=...)`` —
          the GET route on the grid of ``size``-pixel tiles, with
          ``pass_index``, ``seed``, ``aov`` (``"radiance"``, ``"std_dev"``:
          as PNG the relative standard error through a colour map whose top
          is ``scale``, default 0.2, also in the ``x-std-dev-scale`` header;
          ``"records"``: a transparent PNG overlay or JSON) and
          ``if_none_match``: a previous answer's ``etag``, which makes the
          call return ``None`` if the tile is unchanged (HTTP 304). The
          bytes are reproducible, so the ETag can key a client-side cache::

              png = client.tile_bytes("cornell-box", 1, 2, preset="final")
              again = client.tile_bytes("cornell-box", 1, 2, preset="final",
                                        if_none_match=png.etag)
              assert again is None  # still the same bytes

        * ``tile_bytes(scene, x, y, width, height, format=...)`` — POST of a
          pixel rectangle with ``preset``, ``pass_index``, ``seed``,
          ``exposure`` and the explicit knobs ``spp``, ``estimator`` and
          ``max_depth``; never ``None`` (and no ETag).
        """
        if _grid_form(width, height):
            _refuse_knobs("tile_bytes", spp=spp, estimator=estimator, max_depth=max_depth)
            query = _grid_query(size, preset, pass_index, seed, aov, exposure, scale)
            answer = self._grid_tile(scene, x, y, format, query, if_none_match)
            return None if answer is None else TileBytes(answer.body, answer.headers)
        _refuse_grid_options(
            "tile_bytes", size=size, if_none_match=if_none_match, aov=aov, scale=scale
        )
        assert width is not None and height is not None
        answer = self._tile_request(
            scene, x, y, width, height, format, spp, estimator, max_depth, seed, exposure,
            preset=preset, pass_index=pass_index,
        )
        return TileBytes(answer.body, answer.headers)

    @overload
    def image(
        self,
        scene: str,
        preset: Optional[str] = ...,
        *,
        aov: Literal["radiance", "std_dev"] = ...,
        pass_index: Optional[int] = ...,
        seed: int = ...,
        size: Optional[int] = ...,
        workers: int = ...,
        progress: Optional[bool] = ...,
        spp: Optional[int] = ...,
        estimator: Optional[Estimator] = ...,
        max_depth: Optional[int] = ...,
        tile: Optional[int] = ...,
    ) -> Image: ...

    @overload
    def image(
        self,
        scene: str,
        preset: Optional[str] = ...,
        *,
        aov: Literal["records"],
        pass_index: Optional[int] = ...,
        seed: int = ...,
        size: Optional[int] = ...,
        workers: int = ...,
        progress: Optional[bool] = ...,
    ) -> List[Dict[str, Any]]: ...

    def image(
        self,
        scene: str,
        preset: Optional[str] = "preview",
        *,
        aov: str = "radiance",
        pass_index: Optional[int] = None,
        seed: int = 1,
        size: Optional[int] = None,
        workers: int = 4,
        progress: Optional[bool] = None,
        spp: Optional[int] = None,
        estimator: Optional[Estimator] = None,
        max_depth: Optional[int] = None,
        tile: Optional[int] = None,
    ) -> Union[Image, List[Dict[str, Any]]]:
        """The scene camera's whole image, assembled from JSON tiles of
        ``size`` pixels (default 64) fetched ``workers`` at a time, with a
        text progress bar on stderr (``progress``; default only when stderr
        is a terminal).

        By default the tiles come from the GET route
        (``/v1/scenes/{id}/tiles/{tx}/{ty}.json``) with a quality
        ``preset`` (``"draft"``, ``"preview"``, ``"final"``; see
        :meth:`presets`), ``pass_index`` (0-based; pass *k* is the mean of
        passes 0..*k*; default the preset's last) and ``seed``. Each tile is
        reproducible, so the image is the same bytes whatever the order the
        tiles arrive in, on any service of the same version with the same
        scene content; each tile's ``etag`` is in ``image.tiles``.

        ``aov``:

        * ``"radiance"`` (default): an :class:`Image` with ``rgb`` (H×W×3,
          W/(m²·sr)), ``variance`` and ``std_dev`` (H×W);
        * ``"std_dev"``: an :class:`Image` whose ``rgb`` is the per-pixel
          standard error in all three channels (``std_dev`` is one of them,
          ``variance`` is ``None``);
        * ``"records"``: the list of irradiance-cache record dicts of every
          tile (``position``, ``normal``, ``radius``, ``irradiance``,
          ``pixel``, ``radius_pixels``), tiles in row-major order.

        Explicit knobs — ``spp`` (camera rays per pixel in each pass),
        ``estimator`` (``"cache"``, ``"path"`` or a dict of options) or
        ``max_depth`` — switch to ``POST /v1/scenes/{id}/tiles``, where they
        override the preset's (radiance only). With ``"path"`` a pixel
        depends only on the seed and its position. ``tile`` is the former
        name of ``size``.

        Errors: a 503 with ``Retry-After`` is retried per tile (the client's
        ``retries``); any other error answer, e.g. 422 for an unknown preset
        (``field == "preset"``) or pass (``"pass"``), raises
        :class:`ServiceError`.
        """
        if preset is not None and not isinstance(preset, str):
            raise TypeError(
                "preset is a name ('draft', 'preview', 'final'); "
                f"got {preset!r} (camera rays per pixel are spp=...)"
            )
        if tile is not None and size is not None and tile != size:
            raise ValueError("tile is the former name of size: give one")
        side = int(size if size is not None else tile if tile is not None else 64)
        if side < 1 or workers < 1:
            raise ValueError("size and workers must be at least 1")
        if aov not in _AOVS:
            raise ValueError(f"aov must be one of {', '.join(_AOVS)}, not {aov!r}")
        post = spp is not None or estimator is not None or max_depth is not None
        if post and aov != "radiance":
            raise ValueError(
                "spp, estimator and max_depth use POST tiles, which are radiance only; "
                f"aov={aov!r} needs a preset alone"
            )
        width, height = (int(v) for v in self.scene(scene)["resolution"])
        grid = [
            (tx, ty)
            for ty in range(-(-height // side))
            for tx in range(-(-width // side))
        ]
        query = _grid_query(side, preset, pass_index, seed, aov)

        def fetch(tx: int, ty: int) -> Response:
            if post:
                x, y = tx * side, ty * side
                return self._tile_request(
                    scene, x, y, min(side, width - x), min(side, height - y), "json",
                    spp, estimator, max_depth, seed, preset=preset, pass_index=pass_index,
                )
            answer = self._grid_tile(scene, tx, ty, "json", query, None)
            assert answer is not None  # no If-None-Match, no 304
            return answer

        rgb = np.zeros((height, width, 3), dtype=np.float32)
        variance: Optional[npt.NDArray[np.float32]] = (
            np.zeros((height, width), dtype=np.float32) if aov == "radiance" else None
        )
        records: Dict[Tuple[int, int], List[Dict[str, Any]]] = {}
        infos: Dict[Tuple[int, int], TileInfo] = {}
        bar = Progress(len(grid), "tiles", enabled=progress)
        pool = concurrent.futures.ThreadPoolExecutor(max_workers=workers)
        try:
            futures = {pool.submit(fetch, tx, ty): (tx, ty) for tx, ty in grid}
            for future in concurrent.futures.as_completed(futures):
                tx, ty = futures[future]
                answer = future.result()
                x, y = tx * side, ty * side
                w, h = min(side, width - x), min(side, height - y)
                doc = answer.json()
                if aov == "records":
                    records[(tx, ty)] = list(doc["records"])
                else:
                    part, part_variance = _tile_arrays(doc)
                    if part.shape[:2] != (h, w):
                        raise RuntimeError(
                            f"tile ({tx}, {ty}) is {part.shape[1]}×{part.shape[0]}, "
                            f"expected {w}×{h}"
                        )
                    rgb[y : y + h, x : x + w] = part
                    if variance is not None:
                        if part_variance is None:
                            variance = None
                        else:
                            variance[y : y + h, x : x + w] = part_variance
                infos[(tx, ty)] = _tile_info(tx, ty, x, y, w, h, answer.headers)
                bar.advance()
        finally:
            pool.shutdown(wait=True, cancel_futures=True)
            bar.close()
        if aov == "records":
            return [record for key in grid for record in records[key]]
        tiles = tuple(infos[key] for key in grid)
        return Image(
            rgb=rgb,
            variance=variance,
            rays=sum(t.rays for t in tiles),
            aov=aov,
            preset=preset,
            pass_index=pass_index,
            seed=seed,
            size=side,
            tiles=tiles,
        )


_AOVS = ("radiance", "std_dev", "records")


def _grid_form(width: Optional[int], height: Optional[int]) -> bool:
    """Whether a tile call is the GET form (no width and height)."""
    if (width is None) != (height is None):
        raise ValueError(
            "give both width and height (a POST pixel rectangle) or neither (GET tx, ty)"
        )
    return width is None


def _refuse_knobs(method: str, **knobs: Any) -> None:
    given = [name for name, value in knobs.items() if value is not None]
    if given:
        raise ValueError(
            f"{method}(scene, tx, ty) is a GET tile of a preset; {', '.join(given)} need "
            f"the POST form {method}(scene, x, y, width, height, ...)"
        )


def _refuse_grid_options(method: str, **options: Any) -> None:
    given = [name for name, value in options.items() if value is not None]
    if given:
        raise ValueError(
            f"{', '.join(given)}: only for the GET form {method}(scene, tx, ty, ...) "
            "(without width and height)"
        )


def _grid_query(
    size: Optional[int],
    preset: Optional[str],
    pass_index: Optional[int],
    seed: Optional[int],
    aov: Optional[str],
    exposure: Optional[float] = None,
    scale: Optional[float] = None,
) -> Dict[str, Any]:
    """The query of a GET tile; ``None`` values are left out (the service's defaults)."""
    return {
        "size": None if size is None else int(size),
        "preset": preset,
        "pass": None if pass_index is None else int(pass_index),
        "seed": None if seed is None else int(seed),
        "aov": aov,
        "exposure": None if exposure is None else float(exposure),
        "scale": None if scale is None else float(scale),
    }


def _tile_arrays(
    doc: Mapping[str, Any]
) -> Tuple[npt.NDArray[np.float32], Optional[npt.NDArray[np.float32]]]:
    """``rgb`` (h×w×3) and ``variance`` (h×w or ``None``) of a JSON tile."""
    w, h = int(doc["width"]), int(doc["height"])
    rgb = np.asarray(doc["rgb"], dtype=np.float32).reshape(h, w, 3)
    variance = doc.get("variance")
    if variance is None:
        return rgb, None
    return rgb, np.asarray(variance, dtype=np.float32).reshape(h, w)


def _header_int(headers: Mapping[str, str], name: str) -> Optional[int]:
    value = headers.get(name)
    return None if value is None else int(value)


def _tile_of(answer: Response, aov: str, origin: Tuple[int, int] = (0, 0)) -> Tile:
    rgb, variance = _tile_arrays(answer.json())
    h = answer.headers
    return Tile(
        x=int(h.get("x-tile-x", origin[0])),
        y=int(h.get("x-tile-y", origin[1])),
        rgb=rgb,
        variance=variance,
        rays=int(h.get("x-rays", 0)),
        etag=h.get("etag"),
        aov=aov,
        records_created=int(h.get("x-records-created", 0)),
        passes=_header_int(h, "x-passes"),
        passes_rendered=_header_int(h, "x-passes-rendered"),
    )


def _tile_info(
    tx: int, ty: int, x: int, y: int, w: int, h: int, headers: Mapping[str, str]
) -> TileInfo:
    return TileInfo(
        tx=tx,
        ty=ty,
        x=x,
        y=y,
        width=w,
        height=h,
        etag=headers.get("etag"),
        rays=int(headers.get("x-rays", 0)),
        records_created=int(headers.get("x-records-created", 0)),
        passes_rendered=_header_int(headers, "x-passes-rendered"),
    )


def _segment(id: str) -> str:
    """A scene id as one URL path segment."""
    from urllib.parse import quote

    return quote(id, safe="")


def _referenced_files(text: str, xml: bool) -> List[str]:
    """The files a scene document names, each once, in order."""
    if xml:
        names = re.findall(r'<string\s+name="filename"\s+value="([^"]*)"', text)
    else:
        names = []

        def walk(value: Any) -> None:
            if isinstance(value, dict):
                for key, item in value.items():
                    if key == "filename" and isinstance(item, str):
                        names.append(item)
                    else:
                        walk(item)
            elif isinstance(value, list):
                for item in value:
                    walk(item)

        walk(json.loads(text))
    return list(dict.fromkeys(names))


def _asset_files(
    text: str,
    xml: bool,
    assets: Union[str, Sequence[str], Mapping[str, Union[bytes, "os.PathLike[str]"]]],
    base: Optional[Path],
) -> List[Tuple[str, bytes]]:
    """``(relative name, bytes)`` of the assets to upload (see ``upload``)."""
    if isinstance(assets, Mapping):
        return [
            (name, data if isinstance(data, bytes) else Path(data).read_bytes())
            for name, data in assets.items()
        ]
    names = _referenced_files(text, xml) if assets == "auto" else list(assets)
    if names and base is None:
        raise ValueError("assets by name need the scene as a file path (or pass a mapping)")
    return [(name, (base / name).read_bytes()) for name in names] if base else []


def _multipart(parts: Sequence[Tuple[str, str, bytes]], boundary: str) -> bytes:
    """A ``multipart/form-data`` body of ``(part name, filename, bytes)``."""
    out = bytearray()
    for name, filename, data in parts:
        out += f"--{boundary}\r\n".encode()
        out += (
            f'Content-Disposition: form-data; name="{name}"; filename="{filename}"\r\n'
            "Content-Type: application/octet-stream\r\n\r\n"
        ).encode()
        out += data + b"\r\n"
    out += f"--{boundary}--\r\n".encode()
    return bytes(out)


def _scene_text(scene: Union[str, bytes, "os.PathLike[str]"]) -> Tuple[str, Optional[str]]:
    """The scene's text and, for a file, its stem."""
    if isinstance(scene, bytes):
        return scene.decode("utf-8"), None
    if isinstance(scene, str) and scene.lstrip()[:1] in ("{", "<"):
        return scene, None
    path = Path(scene)
    return path.read_text(encoding="utf-8"), path.stem


def _rows(answers: Sequence[Tuple[Chunk, Dict[str, Any]]], key: str) -> npt.NDArray[np.float64]:
    parts = [np.asarray(doc[key], dtype=np.float64).reshape(-1, 3) for _, doc in answers]
    return np.concatenate(parts, axis=0)


def _flat(
    answers: Sequence[Tuple[Chunk, Dict[str, Any]]], key: str, dtype: Any
) -> npt.NDArray[Any]:
    return np.concatenate([np.asarray(doc[key], dtype=dtype) for _, doc in answers])


def _paths_per_point(err: ServiceError, points: int) -> int:
    """Paths per point the service counted in an ``estimated_paths`` refusal of ``points`` points."""
    match = _VALUE.search(err.message) if err.field == "estimated_paths" else None
    return -(-int(match.group(1)) // max(points, 1)) if match else 1


def _shift_point_field(err: ServiceError, offset: int) -> ServiceError:
    """``err`` with ``points[i]`` in its field shifted by the chunk's offset."""
    if offset == 0 or err.field is None:
        return err
    match = _POINT_FIELD.match(err.field)
    if match is None:
        return err
    return err.with_field(f"points[{int(match.group(1)) + offset}]{match.group(2)}")
