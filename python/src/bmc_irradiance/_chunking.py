"""Point sets split into requests within the service's limits, and the
limits learnt from its refusals."""

from __future__ import annotations

import json
import re
from collections.abc import Mapping
from typing import Any, Callable

from ._base import _Resource
from .errors import ServiceError
from .results import Chunk

#: Defaults of ``config/default.toml`` (``[limits]``); a service with other
#: limits is followed automatically where its 422/413 answers say so.
DEFAULT_MAX_POINTS = 65536
DEFAULT_MAX_BODY_BYTES = 4194304
DEFAULT_MAX_PATHS_PER_REQUEST = 134217728
DEFAULT_MAX_SAMPLES = 4096


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


_POINT_FIELD = re.compile(r"^points\[(\d+)\](.*)$")
_LIMIT = re.compile(r"above the limit of (\d+)")
_VALUE = re.compile(r"is (\d+), above")


class _Chunking(_Resource):
    """The limits a point request must keep to, and :meth:`_split`."""

    max_points: int
    max_body_bytes: int
    max_paths_per_request: int
    max_samples: int

    def _split(
        self,
        path: str,
        base: Mapping[str, Any],
        points: Callable[[int, int], list[dict[str, Any]]],
        count: int,
        point_bytes: int,
        paths_per_point: int,
        seed: int,
    ) -> list[tuple[Chunk, dict[str, Any]]]:
        """Sends ``count`` points in as few requests as the limits allow and
        returns each chunk with its answer, in order. When the service's
        answer shows a lower limit than assumed, the split starts again, so
        the result depends only on the final limits."""
        # Everything but the points, with the longest seed.
        overhead = len(json.dumps(dict(base, points=[], seed=2**64 - 1), separators=(",", ":")))
        previous: int | None = None
        while True:
            size = min(
                self.max_points,
                max(1, (self.max_body_bytes - overhead) // point_bytes),
                max(1, self.max_paths_per_request // max(paths_per_point, 1)),
            )
            if previous is not None and size >= previous:
                raise RuntimeError(f"cannot split {count} points within the service's limits")
            previous = size
            answers: list[tuple[Chunk, dict[str, Any]]] = []
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


def _paths_per_point(err: ServiceError, points: int) -> int:
    """Paths per point the service counted in an ``estimated_paths``
    refusal of ``points`` points."""
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
