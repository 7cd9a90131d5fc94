"""The GET tile route through the client: presets, whole images assembled
from reproducible JSON tiles, AOVs, ETags and 304, typed errors."""

from __future__ import annotations

import urllib.parse
from typing import Any

import numpy as np
import pytest

from bmc_irradiance import Client, Image, ServiceError, TileBytes
from conftest import Server, raw

SCENE = "cornell-box"
SIDE = 256  # the bundled Cornell box's camera resolution
SIZE = 64


def raw_get(
    server: Server, tx: int, ty: int, ext: str = "json", **query: Any
) -> tuple[int, Any, dict[str, str]]:
    """One GET tile without the package: status, body (JSON or bytes), headers."""
    url = f"{server.url}/v1/scenes/{SCENE}/tiles/{tx}/{ty}.{ext}"
    if query:
        url += "?" + urllib.parse.urlencode(query)
    return raw(url)


@pytest.fixture(scope="module")
def preview(server: Server) -> Image:
    """The preview image as the issue asks for it: 16 tiles, cold."""
    return Client(server.url, timeout=300).image(SCENE, preset="preview")


def test_presets_lists_draft_preview_standard_final(client: Client, server: Server) -> None:
    presets = client.presets()
    assert [p["name"] for p in presets] == ["draft", "preview", "interactive", "standard", "final"]
    assert [p["name"] for p in presets if p["default"]] == ["preview"]
    for p in presets:
        assert p["samples_per_pixel"] >= 1 and p["passes"] >= 1 and p["max_depth"] >= 1
        assert p["estimator"]["method"] == "cache"
    status, doc, _ = raw(f"{server.url}/v1/presets")
    assert status == 200 and presets == doc


def test_preview_image_equals_the_get_tiles_assembled_by_hand(
    preview: Image, server: Server
) -> None:
    assert preview.rgb.shape == (SIDE, SIDE, 3) and preview.rgb.dtype == np.float32
    assert preview.variance is not None and preview.variance.shape == (SIDE, SIDE)
    assert (preview.aov, preview.preset, preview.pass_index, preview.seed, preview.size) == (
        "radiance",
        "preview",
        None,
        1,
        SIZE,
    )
    rgb = np.zeros((SIDE, SIDE, 3), dtype=np.float32)
    variance = np.zeros((SIDE, SIDE), dtype=np.float32)
    etags = []
    for ty in range(SIDE // SIZE):
        for tx in range(SIDE // SIZE):
            status, doc, headers = raw_get(server, tx, ty, preset="preview")
            assert status == 200, doc
            assert (doc["width"], doc["height"]) == (SIZE, SIZE)
            y, x = ty * SIZE, tx * SIZE
            rgb[y : y + SIZE, x : x + SIZE] = np.array(doc["rgb"], dtype=np.float32).reshape(
                SIZE, SIZE, 3
            )
            variance[y : y + SIZE, x : x + SIZE] = np.array(
                doc["variance"], dtype=np.float32
            ).reshape(SIZE, SIZE)
            etags.append(headers["etag"])
    assert np.array_equal(preview.rgb, rgb)
    assert np.array_equal(preview.variance, variance)
    assert preview.std_dev is not None
    assert np.array_equal(preview.std_dev, np.sqrt(variance))
    assert [t.etag for t in preview.tiles] == etags and len(set(etags)) == 16
    assert [(t.tx, t.ty) for t in preview.tiles] == [(tx, ty) for ty in range(4) for tx in range(4)]
    assert preview.rays == sum(t.rays for t in preview.tiles)
    assert 0.01 < preview.rgb.mean() < 10 and np.all(np.isfinite(preview.rgb))


def test_the_same_call_gives_the_same_image(
    preview: Image, server: Server, tiny_body_server: Server
) -> None:
    again = Client(server.url).image(SCENE, preset="preview", workers=2)
    assert np.array_equal(again.rgb, preview.rgb)
    assert again.variance is not None and preview.variance is not None
    assert np.array_equal(again.variance, preview.variance)
    assert [t.etag for t in again.tiles] == [t.etag for t in preview.tiles]
    # Another process, nothing memoised: the same numbers and ETags.
    other = Client(tiny_body_server.url, timeout=300).image(SCENE, preset="preview")
    assert other.rays > 0
    assert np.array_equal(other.rgb, preview.rgb)
    assert [t.etag for t in other.tiles] == [t.etag for t in preview.tiles]


def test_the_std_dev_aov_is_the_square_root_of_the_variance(preview: Image, client: Client) -> None:
    image = client.image(SCENE, preset="preview", aov="std_dev")
    assert image.aov == "std_dev" and image.variance is None
    assert image.rgb.shape == (SIDE, SIDE, 3)
    assert np.array_equal(image.rgb[:, :, 0], image.rgb[:, :, 2])
    assert image.std_dev is not None and preview.std_dev is not None
    assert np.array_equal(image.std_dev, preview.std_dev)
    assert image.tiles[0].etag != preview.tiles[0].etag


def test_the_records_aov_lists_every_tiles_records(client: Client, server: Server) -> None:
    records = client.image(SCENE, preset="preview", aov="records")
    expected: list[dict[str, Any]] = []
    for ty in range(4):
        for tx in range(4):
            status, doc, _ = raw_get(server, tx, ty, preset="preview", aov="records")
            assert status == 200 and (doc["x"], doc["y"]) == (tx * SIZE, ty * SIZE)
            expected.extend(doc["records"])
    assert records == expected and len(records) > 16
    keys = {"position", "normal", "radius", "irradiance", "pixel", "radius_pixels"}
    assert all(set(r) == keys for r in records)
    assert all(0 <= r["pixel"][0] <= SIDE and 0 <= r["pixel"][1] <= SIDE for r in records)


def test_an_earlier_pass_is_its_own_image(preview: Image, client: Client) -> None:
    first = client.image(SCENE, preset="preview", pass_index=0)
    assert first.pass_index == 0 and first.rgb.shape == preview.rgb.shape
    assert not np.array_equal(first.rgb, preview.rgb)
    tile = client.tile(SCENE, 1, 2, preset="preview", pass_index=0)
    assert tile is not None and (tile.x, tile.y) == (64, 128)
    assert np.array_equal(tile.rgb, first.rgb[128:192, 64:128])
    passes = next(p["passes"] for p in client.presets() if p["name"] == "preview")
    assert (tile.passes, tile.etag) == (passes, first.tiles[2 * 4 + 1].etag)


def test_a_denoised_image_moves_each_pixel_within_its_error_bar(
    preview: Image, client: Client
) -> None:
    denoised = client.image(SCENE, preset="preview", denoise=True)
    assert denoised.variance is not None and preview.variance is not None
    assert np.array_equal(denoised.variance, preview.variance)
    moved = np.abs(denoised.rgb.astype(np.float64) - preview.rgb)
    sigma = np.sqrt(preview.variance.astype(np.float64))[..., None]
    assert np.all(moved <= sigma * (1 + 1e-5) + 1e-6)
    assert np.count_nonzero(moved) > SIDE * SIDE
    assert all(a.etag != b.etag for a, b in zip(denoised.tiles, preview.tiles))
    with pytest.raises(ValueError, match="denoise"):
        client.image(SCENE, preset="preview", aov="std_dev", denoise=True)  # type: ignore[call-overload]


def test_a_repeated_tile_with_its_etag_is_a_304(client: Client, server: Server) -> None:
    png = client.tile_bytes(SCENE, 2, 1, format="png", preset="draft", exposure=1.0)
    assert isinstance(png, TileBytes) and png[:8] == b"\x89PNG\r\n\x1a\n"
    assert png.content_type == "image/png" and (png.x, png.y) == (128, 64)
    assert png.etag is not None and png.etag.startswith('"')
    status, body, headers = raw_get(server, 2, 1, "png", preset="draft", exposure=1.0)
    assert (status, headers["etag"]) == (200, png.etag) and body == png
    assert (
        client.tile_bytes(
            SCENE, 2, 1, format="png", preset="draft", exposure=1.0, if_none_match=png.etag
        )
        is None
    )
    # Other bytes, another tag: the old one no longer matches.
    brighter = client.tile_bytes(
        SCENE, 2, 1, format="png", preset="draft", exposure=2.0, if_none_match=png.etag
    )
    assert brighter is not None and brighter.etag != png.etag and brighter != png
    tile = client.tile(SCENE, 2, 1, preset="draft")
    assert tile is not None and tile.etag is not None and tile.passes == 1
    assert client.tile(SCENE, 2, 1, preset="draft", if_none_match=tile.etag) is None
    records = client.tile_bytes(SCENE, 2, 1, format="json", preset="draft", aov="records")
    assert records is not None and records.json()["x"] == 128


def test_an_unknown_preset_is_a_typed_error(client: Client) -> None:
    with pytest.raises(ServiceError) as caught:
        client.image(SCENE, preset="best")
    err = caught.value
    assert (err.status, err.code, err.field) == (422, "invalid_field", "preset")
    assert "preview" in err.message
    with pytest.raises(ServiceError) as caught:
        client.tile_bytes(SCENE, 0, 0, preset="best")
    assert caught.value.field == "preset"
    with pytest.raises(ServiceError) as caught:
        client.image(SCENE, preset="draft", pass_index=1)
    assert (caught.value.status, caught.value.field) == (422, "pass")
    with pytest.raises(ServiceError) as caught:
        client.tile(SCENE, 9, 0)
    assert (caught.value.status, caught.value.field) == (422, "tx")


def test_arguments_of_the_wrong_form_are_refused(client: Client) -> None:
    with pytest.raises(TypeError, match="spp="):
        client.image(SCENE, 16)  # type: ignore[call-overload]
    with pytest.raises(ValueError, match="aov"):
        client.image(SCENE, aov="depth")  # type: ignore[call-overload]
    with pytest.raises(ValueError, match="POST"):
        client.image(SCENE, aov="std_dev", spp=4)  # type: ignore[call-overload]
    with pytest.raises(ValueError, match="spp"):
        client.tile(SCENE, 0, 0, spp=4)
    with pytest.raises(ValueError, match="if_none_match"):
        client.tile_bytes(SCENE, 0, 0, 64, 64, if_none_match='"x"')
    with pytest.raises(ValueError, match="width and height"):
        client.tile(SCENE, 0, 0, 64)


def test_records_export_and_import(client: Client, server: Server, preview: Image) -> None:
    """The preview's tile records come back as the raw export; importing
    them again adds nothing, and bytes that are not an export are refused."""
    exported = client.export_records(SCENE)
    status, body, _ = raw(f"{server.url}/v1/scenes/{SCENE}/records")
    assert status == 200 and exported == body
    assert exported.startswith(b"BMCLOG01") and len(exported) > 8
    report = client.import_records(SCENE, exported)
    assert report["imported"] == 0 and report["already_held"] >= 16
    with pytest.raises(ServiceError) as refused:
        client.import_records(SCENE, b"not an export")
    assert refused.value.status == 422 and refused.value.field == "body"
