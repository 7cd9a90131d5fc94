"""Irradiance and radiance at point sets."""

from __future__ import annotations

import warnings
from collections.abc import Mapping, Sequence
from typing import Any, Union

import numpy as np
import numpy.typing as npt

from ._base import Estimator, _estimator_doc, _segment
from ._chunking import _Chunking
from .results import Chunk, ErrorTarget, IrradianceResult, RadianceResult

Vectors = npt.ArrayLike
TargetLike = Union[ErrorTarget, Mapping[str, Any]]

# Longest JSON text of one float (Python's repr, e.g. -1.2345678901234567e-300).
_FLOAT_CHARS = 24


def _point_bytes(vectors: int, names: int) -> int:
    """Most JSON bytes one point of ``vectors`` 3-vectors takes in a request."""
    return 4 + names + vectors * (5 + 3 * _FLOAT_CHARS)


def _vectors(name: str, values: Vectors, count: int | None) -> npt.NDArray[np.float64]:
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


def _rows(answers: Sequence[tuple[Chunk, dict[str, Any]]], key: str) -> npt.NDArray[np.float64]:
    parts = [np.asarray(doc[key], dtype=np.float64).reshape(-1, 3) for _, doc in answers]
    return np.concatenate(parts, axis=0)


def _flat(
    answers: Sequence[tuple[Chunk, dict[str, Any]]], key: str, dtype: Any
) -> npt.NDArray[Any]:
    return np.concatenate([np.asarray(doc[key], dtype=dtype) for _, doc in answers])


class _Points(_Chunking):
    """``/v1/scenes/{id}/irradiance`` and ``/v1/scenes/{id}/radiance``."""

    def irradiance(
        self,
        scene: str,
        positions: Vectors,
        normals: Vectors,
        method: str | None = None,
        samples: int | None = None,
        *,
        light_samples: int | None = None,
        decomposition: str | None = None,
        prior: str | None = None,
        calibrate: bool | None = None,
        records_prior: bool | str | None = None,
        sample_set: str | Mapping[str, Any] | None = None,
        kernel: Mapping[str, Any] | None = None,
        target: TargetLike | None = None,
        max_depth: int | None = None,
        seed: int | None = None,
    ) -> IrradianceResult:
        """Irradiance E(x, n) in W/m² (RGB) at N points
        (``POST /v1/scenes/{id}/irradiance``).

        ``positions`` and ``normals`` are N×3 (a single normal applies to all
        points; normals need not be unit length). ``method`` is ``"mc"``,
        ``"qmc"`` or ``"bmc"`` with ``samples`` hemisphere samples per point
        (both default to the service's: ``"bmc"`` with 64);
        ``light_samples`` (default ``samples``) are the split direct part's
        samples, a shadow ray each; ``decomposition`` (``"auto"``, ``"split"``, ``"hemisphere"``),
        ``prior`` (``"environment"``, ``"none"``), ``calibrate``,
        ``sample_set`` (a kind such as ``"fibonacci_cosine"`` or
        ``{"kind", "seed"}``) and ``kernel`` (``{"kind", "lengthscale",
        "variance", "noise"}``, ``bmc`` only) default to the service's
        choices. ``records_prior`` (``True``, ``False`` or ``"auto"``, the
        service's default: on for ``bmc``, off for ``mc`` and ``qmc``)
        combines each point's indirect part with the records rendered tiles
        left where they cover it, and its direct part with the direct light
        seen from the records' places;
        ``result.prior_used`` says per point which records served
        (``"records"`` or ``"cache"``), ``result.records_prior_points`` and
        ``result.direct_records_points`` count them. ``target`` (an
        :class:`ErrorTarget` or a dict with ``relative_error``,
        ``confidence``, ``max_samples``) estimates each
        point until its error bar meets it.
        ``max_depth`` is the longest path in segments (default: the scene's
        depth less the camera's segment, else the service's 16);
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
        estimator: dict[str, Any] = {}
        if method is not None:
            estimator["method"] = method
        if samples is not None:
            estimator["samples"] = int(samples)
        if light_samples is not None:
            estimator["light_samples"] = int(light_samples)
        if decomposition is not None:
            estimator["decomposition"] = decomposition
        if prior is not None:
            estimator["prior"] = prior
        if calibrate is not None:
            estimator["calibrate"] = bool(calibrate)
        if records_prior is not None:
            estimator["records_prior"] = (
                records_prior if isinstance(records_prior, str) else bool(records_prior)
            )
        if sample_set is not None:
            estimator["sample_set"] = (
                {"kind": sample_set} if isinstance(sample_set, str) else dict(sample_set)
            )
        if kernel is not None:
            estimator["kernel"] = dict(kernel)
        base: dict[str, Any] = {"estimator": estimator}
        if max_depth is not None:
            base["max_depth"] = int(max_depth)
        # Requests are split by the paths they may trace: without a number,
        # the most the service lets a point take bounds its default.
        paths_per_point = int(samples) if samples is not None else self.max_samples
        if target is not None:
            target_doc = target.to_json() if isinstance(target, ErrorTarget) else dict(target)
            base["target"] = target_doc
            paths_per_point = int(target_doc.get("max_samples") or self.max_samples)
        pos, nor = positions.tolist(), normals.tolist()

        def points(start: int, stop: int) -> list[dict[str, Any]]:
            return [{"position": p, "normal": n} for p, n in zip(pos[start:stop], nor[start:stop])]

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
            amortised_rays=sum(int(doc["amortised_rays"]) for _, doc in answers),
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
            prior_used=(
                tuple(dict(p) for _, doc in answers for p in doc["prior_used"])
                if "prior_used" in first
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
        estimator: Estimator | None = None,
        repeats: int | None = None,
        max_depth: int | None = None,
        seed: int | None = None,
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
        base: dict[str, Any] = {}
        integrator = _estimator_doc(estimator)
        if integrator is not None:
            base["estimator"] = integrator
        if repeats is not None:
            base["repeats"] = int(repeats)
        if max_depth is not None:
            base["max_depth"] = int(max_depth)
        paths_per_point = repeats if repeats is not None else 16
        if (integrator or {}).get("method", "cache") == "cache":
            options = integrator or {}
            paths_per_point += (
                int(options.get("samples") or 64)
                * int(options.get("paths_per_direction") or 1)
                * (1 + int(options.get("ambient_bounces") or 0))
            )
        pos, nor, dirs = positions.tolist(), normals.tolist(), directions.tolist()

        def points(start: int, stop: int) -> list[dict[str, Any]]:
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
