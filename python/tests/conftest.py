"""Fixtures: real bmc-irradiance services started from the binary the Rust
build made (``BMC_IRRADIANCE_BIN``), each on an ephemeral port with a
temporary copy of the bundled scenes, stopped after the session."""

from __future__ import annotations

import json
import os
import re
import shutil
import subprocess
import time
import urllib.error
import urllib.request
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pytest

from bmc_irradiance import Client

REPO = Path(__file__).resolve().parents[2]
SCENES = REPO / "scenes"
TOKEN = "python-test-token"

# The services listen on loopback: never send their requests through a proxy.
for _name in ("NO_PROXY", "no_proxy"):
    os.environ[_name] = ",".join(
        v for v in (os.environ.get(_name, ""), "127.0.0.1", "localhost") if v
    )


def binary() -> Path:
    """The service binary named by ``BMC_IRRADIANCE_BIN``."""
    value = os.environ.get("BMC_IRRADIANCE_BIN")
    if not value:
        raise RuntimeError(
            "set BMC_IRRADIANCE_BIN to the bmc-irradiance binary "
            "(e.g. target/debug/bmc-irradiance after `cargo build --bin bmc-irradiance`)"
        )
    path = Path(value)
    if not path.is_file():
        raise RuntimeError(f"BMC_IRRADIANCE_BIN={value} is not a file")
    return path


@dataclass
class Server:
    """A running service: its base URL, scenes directory and process."""

    url: str
    scenes_dir: Path
    process: subprocess.Popen[bytes]
    log: Path

    def stop(self) -> None:
        self.process.terminate()
        try:
            self.process.wait(timeout=15)
        except subprocess.TimeoutExpired:
            self.process.kill()
            self.process.wait()


_LISTENING = re.compile(r"listening\s+addr=(\S+)")
_ANSI = re.compile(r"\x1b\[[0-9;]*m")


def start_server(root: Path, extra_config: str = "") -> Server:
    """Starts ``serve`` with port 0 and the scenes copied under ``root``;
    the bound address comes from its ``listening`` log line."""
    scenes = root / "scenes"
    shutil.copytree(SCENES, scenes)
    config = root / "config.toml"
    config.write_text(
        "[server]\n"
        'bind = "127.0.0.1:0"\n'
        "worker_threads = 2\n"
        f"{extra_config}\n"
        "[scenes]\n"
        f"dir = {json.dumps(str(scenes))}\n"
    )
    log = root / "server.log"
    # Each server its own data directory (the tile log is one process's).
    env = dict(os.environ, NO_COLOR="1", RUST_LOG="info", BMC_CACHE__DATA_DIR=str(root / "data"))
    with open(log, "wb") as sink:
        process = subprocess.Popen(
            [str(binary()), "serve", "--config", str(config)],
            stdout=subprocess.DEVNULL,
            stderr=sink,
            env=env,
        )
    deadline = time.monotonic() + 60
    while time.monotonic() < deadline:
        text = _ANSI.sub("", log.read_text(errors="replace"))
        match = _LISTENING.search(text)
        if match:
            return Server(f"http://{match.group(1)}", scenes, process, log)
        if process.poll() is not None:
            raise RuntimeError(f"the service exited with {process.returncode}:\n{text}")
        time.sleep(0.05)
    process.kill()
    raise RuntimeError(f"the service did not start listening within 60 s:\n{log.read_text()}")


# Debug builds are slow; the queue-wait admission limit would refuse
# concurrent tiles, as in the Rust tests.
_LIMITS = "[limits]\nmax_queue_wait_secs = 3600.0\n"


@pytest.fixture(scope="session")
def server(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Server]:
    """The service with the default configuration (and no queue-wait limit)."""
    running = start_server(tmp_path_factory.mktemp("server"), _LIMITS)
    yield running
    running.stop()


@pytest.fixture(scope="session")
def small_server(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Server]:
    """A service with a bearer token, ``limits.max_points = 10`` and
    ``limits.max_paths_per_request = 1000``."""
    running = start_server(
        tmp_path_factory.mktemp("small-server"),
        f'auth_token = "{TOKEN}"\n' + _LIMITS + "max_points = 10\nmax_paths_per_request = 1000\n",
    )
    yield running
    running.stop()


@pytest.fixture(scope="session")
def tiny_body_server(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Server]:
    """A service that takes request bodies of at most 1024 bytes, and uploads
    of at most 64 KiB."""
    running = start_server(
        tmp_path_factory.mktemp("tiny-body-server"),
        _LIMITS + "max_body_bytes = 1024\nmax_upload_bytes = 65536\n",
    )
    yield running
    running.stop()


@pytest.fixture
def client(server: Server) -> Client:
    return Client(server.url, timeout=60)


def raw(
    url: str, method: str = "GET", document: Any = None, token: str | None = None
) -> tuple[int, Any, dict[str, str]]:
    """One request without the package: status, JSON body (or bytes) and headers."""
    data = None if document is None else json.dumps(document).encode()
    headers = {"content-type": "application/json"} if data is not None else {}
    if token:
        headers["authorization"] = f"Bearer {token}"
    request = urllib.request.Request(url, data=data, headers=headers, method=method)
    head: dict[str, str]
    try:
        with urllib.request.urlopen(request, timeout=60) as answer:
            status, body, head = answer.status, answer.read(), dict(answer.headers)
    except urllib.error.HTTPError as err:
        status, body, head = err.code, err.read(), dict(err.headers)
    if head.get("content-type", head.get("Content-Type", "")).startswith("application/json"):
        return status, json.loads(body), head
    return status, body, head
