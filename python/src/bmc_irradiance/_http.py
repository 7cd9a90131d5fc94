"""HTTP transport on the standard library: JSON bodies, bearer token, 503 retries."""

from __future__ import annotations

import http.client
import json
import time
import urllib.parse
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, Callable

from .errors import ServiceError, parse_retry_after


@dataclass(frozen=True)
class Response:
    """A successful answer: status, headers (lower-case names) and body bytes."""

    status: int
    headers: Mapping[str, str]
    body: bytes

    def json(self) -> Any:
        """The body parsed as JSON."""
        return json.loads(self.body.decode("utf-8"))


class Transport:
    """Sends requests to one service; retries 503 answers that carry ``Retry-After``.

    ``retries`` is the number of retries after the first attempt; each waits
    what the header says (capped at ``max_retry_wait`` seconds). A 503 without
    ``Retry-After`` (``/ready`` when busy, a cancelled job) is not retried.
    """

    def __init__(
        self,
        url: str,
        timeout: float,
        retries: int,
        token: str | None,
        max_retry_wait: float,
        sleep: Callable[[float], None] = time.sleep,
    ) -> None:
        if retries < 0:
            raise ValueError("retries must be >= 0")
        self.base = url.rstrip("/")
        self.timeout = timeout
        self.retries = retries
        self.token = token
        self.max_retry_wait = max_retry_wait
        self.sleep = sleep

    def url(self, path: str, query: Mapping[str, Any] | None = None) -> str:
        """Absolute URL of ``path`` (which starts with ``/``) with a query string."""
        url = self.base + path
        if query:
            pairs = {k: _query_value(v) for k, v in query.items() if v is not None}
            if pairs:
                url += "?" + urllib.parse.urlencode(pairs)
        return url

    def request(
        self,
        method: str,
        path: str,
        *,
        body: bytes | None = None,
        content_type: str | None = None,
        query: Mapping[str, Any] | None = None,
        accept: tuple[int, ...] = (),
        headers: Mapping[str, str] | None = None,
    ) -> Response:
        """Sends one request, retrying 503 + ``Retry-After``; raises
        :class:`ServiceError` for any other non-2xx status unless it is in
        ``accept`` (then its answer is returned, e.g. 304). ``headers``
        (lower-case names) are added to, or replace, the default ones."""
        sent = {"accept": "application/json"}
        sent.update(headers or {})
        if content_type is not None:
            sent["content-type"] = content_type
        if self.token:
            sent["authorization"] = f"Bearer {self.token}"
        url = self.url(path, query)
        attempt = 0
        while True:
            status, answer_headers, answer_body = self._exchange(method, url, body, sent)
            if 200 <= status < 300 or status in accept:
                return Response(status, answer_headers, answer_body)
            wait = parse_retry_after(answer_headers.get("retry-after"))
            if status == 503 and wait is not None and attempt < self.retries:
                attempt += 1
                self.sleep(min(wait, self.max_retry_wait))
                continue
            raise ServiceError.from_body(status, answer_body, answer_headers)

    def _exchange(
        self, method: str, url: str, body: bytes | None, headers: Mapping[str, str]
    ) -> tuple[int, dict[str, str], bytes]:
        """One request and its answer: status, headers (lower-case), body.

        A service that refuses a large body answers before reading all of it
        and closes the connection, so sending may fail with a broken pipe or
        a reset; its answer is read all the same (as curl does), and only
        when there is none does the sending error propagate."""
        parts = urllib.parse.urlsplit(url)
        connection_class = (
            http.client.HTTPSConnection if parts.scheme == "https" else http.client.HTTPConnection
        )
        connection = connection_class(parts.netloc, timeout=self.timeout)
        target = parts.path + ("?" + parts.query if parts.query else "")
        try:
            try:
                connection.request(method, target, body=body, headers=dict(headers))
            except (BrokenPipeError, ConnectionResetError) as sending:
                try:
                    answer = connection.getresponse()
                except (OSError, http.client.HTTPException):
                    raise sending from None
            else:
                answer = connection.getresponse()
            return answer.status, _lower(answer.headers), answer.read()
        finally:
            connection.close()

    def get_json(self, path: str, accept: tuple[int, ...] = ()) -> Any:
        return self.request("GET", path, accept=accept).json()

    def post_json(self, path: str, document: Any) -> Response:
        data = json.dumps(document, separators=(",", ":"), allow_nan=False).encode()
        return self.request("POST", path, body=data, content_type="application/json")


def _lower(headers: Any) -> dict[str, str]:
    return {k.lower(): v for k, v in headers.items()} if headers is not None else {}


def _query_value(value: Any) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    return str(value)
