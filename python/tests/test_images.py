"""Images assembled from tiles, the progress bar, and the PNG/EXR/PFM writers
checked against the service's own encodings."""

from __future__ import annotations

import struct
import subprocess
import zlib
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from bmc_irradiance import Client, Image, read_pfm, write_exr, write_png
from bmc_irradiance._progress import Progress
from conftest import Server, binary, raw

SPP = 2


def raw_tile(server: Server, x: int, y: int, w: int, h: int, **extra: object) -> dict[str, Any]:
    body = {
        "x": x,
        "y": y,
        "width": w,
        "height": h,
        "format": "json",
        "samples_per_pixel": SPP,
        "estimator": {"method": "path"},
    }
    body.update(extra)
    doc: dict[str, Any]
    status, doc, _ = raw(f"{server.url}/v1/scenes/cornell-box/tiles", "POST", body)
    assert status == 200, doc
    return doc


@pytest.fixture(scope="module")
def image(server: Server) -> Image:
    return Client(server.url).image("cornell-box", spp=SPP, estimator="path", tile=64, workers=4)


def test_image_equals_the_tiles_fetched_one_by_one(image: Image, server: Server) -> None:
    assert image.rgb.shape == (256, 256, 3) and image.rgb.dtype == np.float32
    assert image.variance is not None and image.variance.shape == (256, 256)
    rgb = np.zeros((256, 256, 3), dtype=np.float32)
    variance = np.zeros((256, 256), dtype=np.float32)
    for y in range(0, 256, 64):
        for x in range(0, 256, 64):
            doc = raw_tile(server, x, y, 64, 64)
            rgb[y : y + 64, x : x + 64] = np.array(doc["rgb"], dtype=np.float32).reshape(64, 64, 3)
            variance[y : y + 64, x : x + 64] = np.array(doc["variance"]).reshape(64, 64)
    assert np.array_equal(image.rgb, rgb)
    assert np.array_equal(image.variance, variance)
    assert image.rgb.mean() > 0.01 and image.rays > 256 * 256 * SPP
    assert image.std_dev is not None
    assert np.array_equal(image.std_dev, np.sqrt(variance))


def test_path_traced_pixels_do_not_depend_on_the_tiling(image: Image, server: Server) -> None:
    other = Client(server.url).image("cornell-box", spp=SPP, estimator="path", tile=100, workers=2)
    assert np.array_equal(other.rgb, image.rgb)
    reseeded = Client(server.url).image("cornell-box", spp=SPP, estimator="path", seed=2)
    assert not np.array_equal(reseeded.rgb, image.rgb)


def test_a_posted_image_can_be_denoised_within_its_error_bars(image: Image, server: Server) -> None:
    denoised = Client(server.url).image(
        "cornell-box", spp=SPP, estimator="path", tile=64, workers=4, denoise=True
    )
    assert denoised.variance is not None and image.variance is not None
    assert np.array_equal(denoised.variance, image.variance)
    moved = np.abs(denoised.rgb.astype(np.float64) - image.rgb)
    sigma = np.sqrt(image.variance.astype(np.float64))[..., None]
    assert np.all(moved <= sigma * (1 + 1e-5) + 1e-6)
    assert np.count_nonzero(moved) > 256 * 256
    # The same pass was rendered for `image` and is kept: only the guides'
    # four camera rays per pixel are traced.
    assert denoised.rays == 4 * 256 * 256


def test_the_progress_bar_shows_only_on_a_terminal(
    server: Server, capsys: pytest.CaptureFixture[str]
) -> None:
    client = Client(server.url)
    client.image("cornell-box", spp=1, estimator="path", tile=128)
    assert capsys.readouterr().err == ""  # captured stderr is no terminal
    client.image("cornell-box", spp=1, estimator="path", tile=128, progress=True)
    err = capsys.readouterr().err
    assert "4/4 tiles" in err and "[" + "#" * 30 + "]" in err


def test_progress_text() -> None:
    class Stream:
        def __init__(self) -> None:
            self.text = ""

        def write(self, s: str) -> None:
            self.text += s

        def flush(self) -> None:
            pass

        def isatty(self) -> bool:
            return True

    stream = Stream()
    bar = Progress(4, "tiles", stream=stream, width=8)  # type: ignore[arg-type]
    bar.advance()
    bar.advance()
    bar.close()
    assert stream.text == "\r[........] 0/4 tiles\r[##......] 1/4 tiles\r[####....] 2/4 tiles\n"


def decode_png(data: bytes) -> np.ndarray:
    """8-bit RGB PNG pixels (every filter type), for comparing encoders."""
    assert data[:8] == b"\x89PNG\r\n\x1a\n"
    pos, idat = 8, b""
    while pos < len(data):
        length, kind = struct.unpack(">I4s", data[pos : pos + 8])
        payload = data[pos + 8 : pos + 8 + length]
        pos += 12 + length
        if kind == b"IHDR":
            width, height, depth, colour = struct.unpack(">IIBB", payload[:10])
            assert (depth, colour) == (8, 2)
        elif kind == b"IDAT":
            idat += payload
    raw_bytes = zlib.decompress(idat)
    stride = 3 * width
    rows = np.zeros((height, stride), dtype=np.int64)
    previous = np.zeros(stride, dtype=np.int64)
    for y in range(height):
        start = y * (stride + 1)
        kind = raw_bytes[start]
        line = np.frombuffer(raw_bytes[start + 1 : start + 1 + stride], dtype=np.uint8).astype(
            np.int64
        )
        if kind == 0:
            current = line
        elif kind == 2:
            current = (line + previous) % 256
        else:
            current = np.zeros(stride, dtype=np.int64)
            for i in range(stride):
                a = current[i - 3] if i >= 3 else 0
                b = previous[i]
                c = previous[i - 3] if i >= 3 else 0
                if kind == 1:
                    predictor = a
                elif kind == 3:
                    predictor = (a + b) // 2
                else:
                    p = a + b - c
                    pa, pb, pc = abs(p - a), abs(p - b), abs(p - c)
                    predictor = a if pa <= pb and pa <= pc else (b if pb <= pc else c)
                current[i] = (line[i] + predictor) % 256
        rows[y] = current
        previous = current
    return rows.reshape(height, width, 3).astype(np.uint8)


def test_png_matches_the_services_png(image: Image, server: Server, tmp_path: Path) -> None:
    client = Client(server.url)
    theirs = client.tile_bytes(
        "cornell-box", 0, 0, 256, 256, format="png", spp=SPP, estimator="path", exposure=1.0
    )
    path = tmp_path / "mine.png"
    image.save_png(path, exposure=1.0)
    mine = decode_png(path.read_bytes())
    assert theirs is not None  # a POST tile is never a 304
    reference = decode_png(theirs)
    assert mine.shape == reference.shape == (256, 256, 3)
    difference = np.abs(mine.astype(int) - reference.astype(int))
    assert difference.max() <= 1
    assert np.mean(difference == 0) > 0.999
    assert 20 < mine.mean() < 250


def test_exr_is_read_by_the_service_binary(image: Image, server: Server, tmp_path: Path) -> None:
    theirs = tmp_path / "theirs.exr"
    exr = Client(server.url).tile_bytes(
        "cornell-box", 0, 0, 256, 256, format="exr", spp=SPP, estimator="path"
    )
    assert exr is not None  # a POST tile is never a 304
    theirs.write_bytes(exr)
    mine = tmp_path / "mine.exr"
    image.save_exr(mine)

    def compare(a: Path, b: Path) -> str:
        done = subprocess.run(
            [str(binary()), "compare", str(a), str(b)], capture_output=True, text=True
        )
        assert done.returncode == 0, done.stderr
        return done.stdout

    same = compare(mine, theirs)
    assert "relative RMSE 0.00000" in same and "mean ratio 1.00000" in same, same
    assert "expected from the image's variance channel alone" in same
    scaled = tmp_path / "scaled.exr"
    write_exr(scaled, image.rgb * 1.5, image.variance)
    assert "mean ratio 1.50000" in compare(scaled, theirs)


def test_pfm_round_trip(image: Image, tmp_path: Path) -> None:
    path = tmp_path / "image.pfm"
    image.save_pfm(path)
    assert np.array_equal(read_pfm(path), image.rgb)


def test_writers_refuse_wrong_shapes(tmp_path: Path) -> None:
    with pytest.raises(ValueError):
        write_png(tmp_path / "x.png", np.zeros((4, 4)))
    with pytest.raises(ValueError):
        write_exr(tmp_path / "x.exr", np.zeros((4, 4, 3)), np.zeros((3, 4)))
