"""HTTP transport on the standard library: JSON bodies, bearer token, 503 retries."""

from __future__ import annotations

import json
import time
import urllib.error
import urllib.parse
import urllib.request
from dataclasses import dataclass
from typing import Any, Callable, Mapping, Optional

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
        token: Optional[str],
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

    def url(self, path: str, query: Optional[Mapping[str, Any]] = None) -> str:
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
        body: Optional[bytes] = None,
        content_type: Optional[str] = None,
        query: Optional[Mapping[str, Any]] = None,
        accept: tuple[int, ...] = (),
        headers: Optional[Mapping[str, str]] = None,
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
            request = urllib.request.Request(url, data=body, headers=sent, method=method)
            try:
                with urllib.request.urlopen(request, timeout=self.timeout) as answer:
                    return Response(answer.status, _lower(answer.headers), answer.read())
            except urllib.error.HTTPError as err:
                status, answer_headers = err.code, _lower(err.headers)
                answer_body = err.read()
                err.close()
            if status in accept:
                return Response(status, answer_headers, answer_body)
            wait = parse_retry_after(answer_headers.get("retry-after"))
            if status == 503 and wait is not None and attempt < self.retries:
                attempt += 1
                self.sleep(min(wait, self.max_retry_wait))
                continue
            raise ServiceError.from_body(status, answer_body, answer_headers)

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
