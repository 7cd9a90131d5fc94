"""Retries after 503 + Retry-After and error parsing, against a local stub
HTTP server that answers from a script."""

from __future__ import annotations

import email.utils
import json
import threading
import time
from collections.abc import Iterator
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from typing import Any

import pytest

from bmc_irradiance import Client, ServiceError
from bmc_irradiance.errors import parse_retry_after

Answer = tuple[int, dict[str, str], bytes]


class Stub:
    """Answers requests with ``script`` in order (the last answer repeats)
    and records each request's method, path, headers and body."""

    def __init__(self) -> None:
        self.script: list[Answer] = []
        self.requests: list[tuple[str, str, dict[str, str], bytes, float]] = []
        stub = self

        class Handler(BaseHTTPRequestHandler):
            def answer(self) -> None:
                length = int(self.headers.get("content-length") or 0)
                body = self.rfile.read(length)
                stub.requests.append(
                    (
                        self.command,
                        self.path,
                        {k.lower(): v for k, v in self.headers.items()},
                        body,
                        time.monotonic(),
                    )
                )
                index = min(len(stub.requests), len(stub.script)) - 1
                status, headers, payload = stub.script[index]
                self.send_response(status)
                for name, value in headers.items():
                    self.send_header(name, value)
                self.send_header("content-length", str(len(payload)))
                self.end_headers()
                self.wfile.write(payload)

            do_GET = do_POST = do_DELETE = answer

            def log_message(self, *args: Any) -> None:
                pass

        self.server = ThreadingHTTPServer(("127.0.0.1", 0), Handler)
        self.url = f"http://127.0.0.1:{self.server.server_address[1]}"
        self.thread = threading.Thread(
            target=self.server.serve_forever, kwargs={"poll_interval": 0.05}, daemon=True
        )
        self.thread.start()

    def close(self) -> None:
        self.server.shutdown()
        self.server.server_close()


@pytest.fixture
def stub() -> Iterator[Stub]:
    running = Stub()
    yield running
    running.close()


JSON = {"content-type": "application/json"}


def error(
    status: int,
    code: str,
    message: str,
    field: str | None = None,
    headers: dict[str, str] | None = None,
) -> Answer:
    body = json.dumps({"error": {"code": code, "message": message, "field": field}}).encode()
    return status, dict(JSON, **(headers or {})), body


OVERLOADED = "all 2 CPU job slots are taken; retry in 1 s"


def test_a_503_is_retried_after_retry_after(stub: Stub) -> None:
    stub.script = [
        error(503, "overloaded", OVERLOADED, headers={"retry-after": "1"}),
        (200, JSON, b'[{"id": "a"}]'),
    ]
    started = time.monotonic()
    assert Client(stub.url, retries=3).scenes() == [{"id": "a"}]
    assert len(stub.requests) == 2
    waited = stub.requests[1][4] - stub.requests[0][4]
    assert 0.95 <= waited < 5 and time.monotonic() - started >= 0.95


def test_a_retried_post_resends_the_same_body(stub: Stub) -> None:
    answer = {
        "irradiance": [[1.0, 2.0, 3.0]],
        "std_dev": [[0.1, 0.2, 0.3]],
        "rays": 7,
        "amortised_rays": 0,
        "decomposition": "split",
        "prior": "none",
    }
    stub.script = [
        error(503, "overloaded", OVERLOADED, headers={"retry-after": "0"}),
        (200, JSON, json.dumps(answer).encode()),
    ]
    result = Client(stub.url, token="secret").irradiance("s", [[0, 0, 0]], [0, 0, 1], method="mc")
    assert result.value.tolist() == [[1.0, 2.0, 3.0]] and result.rays == 7
    (m1, p1, h1, b1, _), (m2, p2, h2, b2, _) = stub.requests
    assert (m1, p1) == (m2, p2) == ("POST", "/v1/scenes/s/irradiance")
    assert b1 == b2 and json.loads(b1)["points"] == [
        {"position": [0.0, 0.0, 0.0], "normal": [0.0, 0.0, 1.0]}
    ]
    assert h1.get("authorization") == h2.get("authorization") == "Bearer secret"


def test_retries_are_bounded(stub: Stub) -> None:
    stub.script = [error(503, "overloaded", OVERLOADED, headers={"retry-after": "0"})]
    with pytest.raises(ServiceError) as caught:
        Client(stub.url, retries=3).scenes()
    assert len(stub.requests) == 4
    err = caught.value
    assert (err.status, err.code, err.retry_after) == (503, "overloaded", 0.0)


def test_a_503_without_retry_after_is_not_retried(stub: Stub) -> None:
    stub.script = [error(503, "cancelled", "the request's work was cancelled")]
    with pytest.raises(ServiceError) as caught:
        Client(stub.url, retries=3).scenes()
    assert len(stub.requests) == 1
    assert (caught.value.status, caught.value.code) == (503, "cancelled")


def test_retry_after_is_capped(stub: Stub) -> None:
    stub.script = [
        error(503, "overloaded", OVERLOADED, headers={"retry-after": "3600"}),
        (200, JSON, b"[]"),
    ]
    started = time.monotonic()
    assert Client(stub.url, max_retry_wait=0.2).scenes() == []
    assert time.monotonic() - started < 5


def test_error_bodies_become_typed_errors(stub: Stub) -> None:
    stub.script = [
        error(422, "invalid_field", "normal must have non-zero length", "points[0].normal")
    ]
    with pytest.raises(ServiceError) as caught:
        Client(stub.url).scene("x")
    err = caught.value
    assert (err.status, err.code, err.field) == (422, "invalid_field", "points[0].normal")
    assert err.message == "normal must have non-zero length"
    assert "points[0].normal" in str(err)
    assert len(stub.requests) == 1  # 4xx are never retried


def test_non_json_errors_keep_their_text(stub: Stub) -> None:
    stub.script = [(502, {"content-type": "text/html"}, b"<h1>Bad gateway</h1>")]
    with pytest.raises(ServiceError) as caught:
        Client(stub.url).scenes()
    assert (caught.value.status, caught.value.code, caught.value.field) == (502, None, None)
    assert "Bad gateway" in caught.value.message


def test_a_body_the_service_always_refuses_ends_in_an_error(stub: Stub) -> None:
    stub.script = [
        error(
            413,
            "payload_too_large",
            "request body larger than the configured limits.max_body_bytes",
        )
    ]
    with pytest.raises(ServiceError) as caught:
        Client(stub.url).irradiance("s", [[0, 0, 0]] * 50, [0, 0, 1], method="mc")
    assert caught.value.status == 413
    assert 2 <= len(stub.requests) <= 20
    sizes = [len(json.loads(r[3])["points"]) for r in stub.requests]
    assert sizes[0] == 50 and sizes[-1] == 1 and sizes == sorted(sizes, reverse=True)


def test_retry_after_formats() -> None:
    assert parse_retry_after("2") == 2.0
    assert parse_retry_after(" 0.5 ") == 0.5
    assert parse_retry_after(None) is None
    assert parse_retry_after("soon") is None
    later = parse_retry_after(email.utils.formatdate(time.time() + 30, usegmt=True))
    assert later is not None and 25 <= later <= 31
    assert parse_retry_after(email.utils.formatdate(time.time() - 30, usegmt=True)) == 0.0


def test_image_tiles_are_retried_after_retry_after(stub: Stub) -> None:
    def tile(value: float, etag: str) -> Answer:
        doc = {"width": 1, "height": 1, "rgb": [[value, value, value]], "variance": [0.25]}
        return 200, dict(JSON, etag=etag, **{"x-rays": "5"}), json.dumps(doc).encode()

    stub.script = [
        (200, JSON, json.dumps({"id": "s", "resolution": [2, 1]}).encode()),
        error(503, "overloaded", OVERLOADED, headers={"retry-after": "0"}),
        tile(1.0, '"a"'),
        tile(2.0, '"b"'),
    ]
    image = Client(stub.url, retries=2).image("s", preset="draft", size=1, workers=1)
    paths = [r[1] for r in stub.requests]
    query = "?size=1&preset=draft&seed=1&aov=radiance"
    assert paths == [
        "/v1/scenes/s",
        "/v1/scenes/s/tiles/0/0.json" + query,
        "/v1/scenes/s/tiles/0/0.json" + query,
        "/v1/scenes/s/tiles/1/0.json" + query,
    ]
    assert image.std_dev is not None
    assert image.rgb[:, :, 0].tolist() == [[1.0, 2.0]] and image.std_dev.tolist() == [[0.5, 0.5]]
    assert [t.etag for t in image.tiles] == ['"a"', '"b"'] and image.rays == 10


def test_if_none_match_is_sent_and_a_304_is_none(stub: Stub) -> None:
    stub.script = [(304, {"etag": '"a"'}, b"")]
    client = Client(stub.url)
    assert client.tile_bytes("s", 3, 4, format="exr", preset="final", if_none_match='"a"') is None
    assert client.tile("s", 3, 4, if_none_match='"a"') is None
    (m1, p1, h1, _, _), (m2, p2, h2, _, _) = stub.requests
    assert (m1, p1) == ("GET", "/v1/scenes/s/tiles/3/4.exr?preset=final")
    assert (m2, p2) == ("GET", "/v1/scenes/s/tiles/3/4.json?aov=radiance")
    assert h1["if-none-match"] == h2["if-none-match"] == '"a"'
