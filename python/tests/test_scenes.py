"""Scene routes: list, get, upload (JSON and Mitsuba XML), delete, the
bearer token, and the service routes."""

from __future__ import annotations

import io
import json
import shutil
import zipfile
from pathlib import Path

import pytest

from bmc_irradiance import Client, ServiceError
from conftest import REPO, SCENES, TOKEN, Server, raw

# A scene that references no file, small enough for any body limit.
TINY = {
    "name": "tiny",
    "materials": [{"id": "m", "type": "diffuse", "reflectance": [0.5, 0.5, 0.5]}],
    "shapes": [
        {"type": "rectangle", "material": "m", "to_world": {"scale": [10, 10, 1]}},
    ],
    "environment": {"type": "constant", "radiance": [1, 1, 1]},
    "camera": {
        "type": "perspective",
        "fov": 40,
        "width": 32,
        "height": 24,
        "origin": [0, 0, 5],
        "target": [0, 0, 0],
        "up": [0, 1, 0],
    },
}


def test_scenes_and_scene_equal_the_raw_responses(client: Client, server: Server) -> None:
    listed = client.scenes()
    status, doc, _ = raw(f"{server.url}/v1/scenes")
    assert status == 200 and listed == doc
    ids = [s["id"] for s in listed]
    assert {"cornell-box", "cornell-box-xml", "overcast", "sky", "mesh", "studio"} <= set(ids)
    one = client.scene("cornell-box")
    status, doc, _ = raw(f"{server.url}/v1/scenes/cornell-box")
    assert status == 200 and one == doc
    assert one["resolution"] == [256, 256]


def test_upload_json_and_xml_then_delete(client: Client, tmp_path: Path) -> None:
    summary = client.upload(SCENES / "cornell-box.json", id="box-copy")
    assert summary["id"] == "box-copy"
    original = client.scene("cornell-box")
    assert summary["triangles"] == original["triangles"]
    assert summary["shapes"] == original["shapes"]

    xml = (SCENES / "cornell-box.xml").read_text()
    from_text = client.upload(xml, id="box-xml-text")
    assert from_text["id"] == "box-xml-text"
    copy = tmp_path / "box-from-file.xml"
    copy.write_text(xml)
    from_file = client.upload(str(copy))
    assert from_file["id"] == "box-from-file"  # the file's stem
    with pytest.raises(ValueError):
        client.upload(xml)  # XML text needs an id
    # $NAME parameters of an XML scene (the studio's resolution).
    small = client.upload(SCENES / "studio.xml", id="studio-small", params={"resx": 40, "resy": 30})
    assert small["resolution"] == [40, 30]
    client.delete("studio-small")
    with pytest.raises(ValueError):
        client.upload(SCENES / "cornell-box.json", params={"spp": 4})
    ids = {s["id"] for s in client.scenes()}
    assert {"box-copy", "box-xml-text", "box-from-file"} <= ids
    # An id the service holds is replaced only when asked to.
    with pytest.raises(ServiceError) as taken:
        client.upload(SCENES / "cornell-box.json", id="box-copy")
    refused = taken.value
    assert (refused.status, refused.code, refused.field) == (409, "scene_exists", "name")
    replaced = client.upload(SCENES / "cornell-box.json", id="box-copy", replace=True)
    assert replaced["id"] == "box-copy"

    for scene in ("box-copy", "box-xml-text", "box-from-file"):
        client.delete(scene)
        with pytest.raises(ServiceError) as caught:
            client.scene(scene)
        err = caught.value
        assert (err.status, err.code, err.field) == (404, "not_found", None)
        assert scene in err.message


def test_upload_errors_are_typed(client: Client) -> None:
    with pytest.raises(ServiceError) as caught:
        client.upload('{"name": "broken", ')
    assert (caught.value.status, caught.value.code) == (400, "malformed_json")
    bad = dict(TINY, name="bad", shapes=[{"type": "rectangle", "material": "nope"}])
    with pytest.raises(ServiceError) as caught:
        client.upload(json.dumps(bad))
    assert caught.value.status == 422
    assert caught.value.field is not None and caught.value.field.startswith("shapes[0]")
    with pytest.raises(ValueError):
        client.upload(b"neither json nor xml")
    with pytest.raises(FileNotFoundError):
        client.upload("no-such-file.json")  # not a document, so a path
    with pytest.raises(ServiceError) as caught:
        client.delete("no-such-scene")
    assert (caught.value.status, caught.value.code) == (404, "not_found")


def test_mutating_routes_need_the_token(small_server: Server, tmp_path: Path) -> None:
    anonymous = Client(small_server.url)
    with pytest.raises(ServiceError) as caught:
        anonymous.upload(json.dumps(TINY))
    assert (caught.value.status, caught.value.code) == (401, "unauthorized")
    path = tmp_path / "tiny.json"
    path.write_text(json.dumps(TINY))
    trusted = Client(small_server.url, token=TOKEN)
    assert trusted.upload(path)["id"] == "tiny"
    assert anonymous.scene("tiny")["resolution"] == [32, 24]  # reading needs no token
    with pytest.raises(ServiceError) as caught:
        anonymous.delete("tiny")
    assert caught.value.status == 401
    trusted.delete("tiny")
    assert "tiny" not in {s["id"] for s in trusted.scenes()}


def test_service_routes(client: Client, server: Server) -> None:
    health = client.health()
    assert health["status"] == "ok" and health["scenes"] >= 5
    assert client.ready() is True
    document = client.openapi()
    assert "/v1/scenes/{id}/irradiance" in document["paths"]
    assert "http_requests_total" in client.metrics()
    stats = client.cache("cornell-box")
    status, doc, _ = raw(f"{server.url}/v1/scenes/cornell-box/cache")
    assert status == 200 and stats == doc
    cleared = client.clear_cache("cornell-box")
    assert cleared["cleared_records"] >= 0 and cleared["scene"] == "cornell-box"
    assert cleared["content_keyed"] == stats["content_keyed"]


def test_upload_with_assets_found_in_the_document(client: Client, tmp_path: Path) -> None:
    """A scene outside the service's scenes directory travels with the files
    it names (``assets="auto"``): the bundled mesh scene under a new name."""
    scene_dir = tmp_path / "elsewhere"
    (scene_dir / "meshes").mkdir(parents=True)
    (scene_dir / "meshes" / "blob.obj").write_bytes((SCENES / "meshes" / "blob.obj").read_bytes())
    document = json.loads((SCENES / "mesh.json").read_text())
    document["name"] = "carried-mesh"
    path = scene_dir / "carried.json"
    path.write_text(json.dumps(document))
    summary = client.upload(path, assets="auto")
    assert summary["id"] == "carried-mesh"
    assert summary["triangles"] == client.scene("mesh")["triangles"]
    # The same content as the bundled scene's, apart from its name.
    assert summary["digest"] != client.scene("mesh")["digest"]
    # A name that climbs out is refused, naming the part.
    with pytest.raises(ServiceError) as refused:
        client.upload(path, assets={"../blob.obj": b"v 0 0 0\n"})
    assert refused.value.status == 422
    assert refused.value.field == "assets[0]"
    client.delete("carried-mesh")


def test_xml_assets_are_found_in_either_attribute_order_and_through_parameters(
    client: Client, tmp_path: Path
) -> None:
    """``assets="auto"`` finds ``<string value=… name="filename">`` and file
    names made of ``$NAME`` parameters, from ``params`` or the document's
    ``<default>``."""
    scene_dir = tmp_path / "params"
    (scene_dir / "meshes").mkdir(parents=True)
    blob = (SCENES / "meshes" / "blob.obj").read_bytes()
    (scene_dir / "meshes" / "blob.obj").write_bytes(blob)
    (scene_dir / "meshes" / "other.obj").write_bytes(blob)
    path = scene_dir / "blobs.xml"
    path.write_text(
        """<scene version="3.0.0">
  <default name="mesh" value="blob"/>
  <sensor type="perspective"><film type="hdrfilm">
    <integer name="width" value="8"/><integer name="height" value="8"/></film></sensor>
  <shape type="obj"><string value="meshes/$mesh.obj" name="filename"/></shape>
  <shape type="obj"><string name='filename' value='meshes/blob.obj'/></shape>
</scene>"""
    )
    summary = client.upload(path, id="xml-assets", assets="auto")
    faces = sum(1 for line in blob.splitlines() if line.startswith(b"f "))
    assert summary["triangles"] == 2 * faces
    other = client.upload(
        path, id="xml-assets", assets="auto", params={"mesh": "other"}, replace=True
    )
    assert other["triangles"] == summary["triangles"]
    client.delete("xml-assets")


def test_an_upload_refused_while_sending_raises_the_services_error(
    tiny_body_server: Server, tmp_path: Path
) -> None:
    """The service refuses an upload over ``limits.max_upload_bytes`` (64 KiB
    here) before reading all of it and closes the connection: the client,
    still sending 16 MiB, reads the answer instead of failing on the broken
    pipe."""
    path = tmp_path / "tiny.json"
    document = dict(TINY, shapes=[{"type": "obj", "filename": "big.obj", "material": "m"}])
    path.write_text(json.dumps(document))
    client = Client(tiny_body_server.url, timeout=60)
    with pytest.raises(ServiceError) as refused:
        client.upload(path, assets={"big.obj": b"v 0 0 0\n" * (2 << 20)})
    assert refused.value.status == 422
    assert refused.value.field == "limits.max_upload_bytes"
    assert "65536 bytes" in str(refused.value)


def test_a_scene_folder_uploads_whole_or_packed(client: Client, tmp_path: Path) -> None:
    """The tutorials' Cornell box folder (``cbox.xml`` and its ``meshes/``)
    uploads as a folder, named after it, and as a gzipped tar made by the
    standard library; an archive with a ``..`` entry is refused naming it."""
    folder = tmp_path / "cbox"
    shutil.copytree(REPO / "tests" / "data" / "mitsuba-tutorials", folder)
    summary = client.upload_dir(folder)
    assert summary["id"] == "cbox"
    packed = shutil.make_archive(str(tmp_path / "packed"), "gztar", root_dir=folder)
    again = client.upload_archive(packed, "cbox-tar")
    assert again["id"] == "cbox-tar" and again["digest"] == summary["digest"]
    escaping = io.BytesIO()
    with zipfile.ZipFile(escaping, "w") as out:
        out.writestr("scene.json", json.dumps(TINY))
        out.writestr("../evil.obj", "v 0 0 0\n")
    with pytest.raises(ServiceError) as refused:
        client.upload_archive(escaping.getvalue())
    assert refused.value.status == 422
    assert refused.value.field == "archive[1]"
    assert "../evil.obj" in str(refused.value)
    for id in ("cbox", "cbox-tar"):
        client.delete(id)
