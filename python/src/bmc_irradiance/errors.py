"""Errors raised by the client."""

from __future__ import annotations

import json
from collections.abc import Mapping
from typing import Any


class ServiceError(Exception):
    """An error answer of the service (any status other than 2xx).

    The service's error body is ``{"error": {"code", "message", "field"}}``;
    its parts are kept as attributes:

    * ``status``: the HTTP status (404, 422, 503, ...);
    * ``code``: the machine-readable code (``"not_found"``, ``"invalid_field"``,
      ``"limit_exceeded"``, ``"unauthorized"``, ``"overloaded"``, ...), or
      ``None`` when the body was not the service's JSON error document (e.g. a
      proxy's page);
    * ``message``: the human-readable explanation (the body's text when it was
      not JSON);
    * ``field``: the request field at fault, e.g. ``"points[12].normal"`` or
      ``"target"``, or ``None``. For point sets the client split into several
      requests, ``points[i]`` is the index in the caller's whole array;
    * ``retry_after``: seconds from a ``Retry-After`` header, if any.
    """

    def __init__(
        self,
        status: int,
        code: str | None,
        message: str,
        field: str | None = None,
        retry_after: float | None = None,
    ) -> None:
        self.status = status
        self.code = code
        self.message = message
        self.field = field
        self.retry_after = retry_after
        where = f" (field {field})" if field else ""
        super().__init__(f"{status} {code or 'error'}{where}: {message}")

    @classmethod
    def from_body(
        cls, status: int, body: bytes, headers: Mapping[str, str] | None = None
    ) -> ServiceError:
        """The error an answer with this status, body and headers stands for."""
        value = None
        for name, text in (headers or {}).items():
            if name.lower() == "retry-after":
                value = text
        retry_after = parse_retry_after(value)
        try:
            document: Any = json.loads(body.decode("utf-8"))
            detail = document["error"]
            return cls(
                status,
                str(detail["code"]),
                str(detail.get("message", "")),
                detail.get("field"),
                retry_after,
            )
        except (ValueError, KeyError, TypeError, UnicodeDecodeError):
            text = body.decode("utf-8", errors="replace").strip()
            return cls(status, None, text[:2000] or f"HTTP {status}", None, retry_after)

    def with_field(self, field: str | None) -> ServiceError:
        """The same error naming another field (used to map chunk indices back)."""
        return ServiceError(self.status, self.code, self.message, field, self.retry_after)


def parse_retry_after(value: str | None) -> float | None:
    """Seconds to wait from a ``Retry-After`` header: delay-seconds or an HTTP date."""
    if value is None:
        return None
    value = value.strip()
    try:
        return max(0.0, float(value))
    except ValueError:
        pass
    import datetime
    from email.utils import parsedate_to_datetime

    try:
        when = parsedate_to_datetime(value)
    except (TypeError, ValueError):
        return None
    if when.tzinfo is None:
        when = when.replace(tzinfo=datetime.timezone.utc)
    delta = when - datetime.datetime.now(datetime.timezone.utc)
    return max(0.0, delta.total_seconds())
