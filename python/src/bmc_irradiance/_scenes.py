"""Scenes: list, show, upload (with their asset files, or as a packed folder) and delete."""

from __future__ import annotations

import io
import json
import os
import re
import zipfile
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from ._base import _Resource, _segment


class _Scenes(_Resource):
    """``/v1/scenes`` and ``/v1/scenes/{id}``."""

    def scenes(self) -> list[dict[str, Any]]:
        """``GET /v1/scenes``: summaries of the loaded scenes, sorted by id."""
        return list(self._http.get_json("/v1/scenes"))

    def scene(self, id: str) -> dict[str, Any]:
        """``GET /v1/scenes/{id}``: ``shapes``, ``triangles``, ``emitters``,
        ``resolution`` ([width, height] in pixels), bounds, fitted kernels..."""
        return dict(self._http.get_json(f"/v1/scenes/{_segment(id)}"))

    def upload(
        self,
        scene: str | bytes | os.PathLike[str],
        id: str | None = None,
        *,
        lenient: bool = False,
        params: Mapping[str, str | int | float] | None = None,
        assets: str | Sequence[str] | Mapping[str, bytes | os.PathLike[str]] | None = None,
        replace: bool = False,
    ) -> dict[str, Any]:
        """``POST /v1/scenes``: adds a scene; with ``replace`` replaces the one
        with the same id (without it the service refuses an id it holds:
        :class:`ServiceError` with status 409 and code ``scene_exists``).

        ``scene`` is a path to a JSON scene document or a Mitsuba 3 XML file,
        or the document's text. A JSON document's id is its ``name``; ``id``
        replaces that name. An XML scene's id is ``id``, by default the file's
        stem; ``lenient`` approximates unsupported Mitsuba features instead of
        refusing them, and ``params`` sets its ``$NAME`` parameters over the
        file's ``<default>`` values (like ``mitsuba -D NAME=VALUE``; sent as
        ``param.NAME`` query parameters). Returns the scene's summary.

        Without ``assets``, files the scene references (meshes, environment
        maps, textures) must already be in the service's scenes directory.
        With ``assets`` they travel with it (``multipart/form-data``):

        - ``"auto"``: every file the document names (``"filename"`` values
          of a JSON document, ``<string name="filename" value=…>`` of XML in
          either attribute order, its ``$NAME`` parameters filled in from
          ``params`` and the file's ``<default>`` values), read relative to
          the scene file's directory;
        - a list of such relative names;
        - a mapping from relative name to bytes or a local path.

        The service refuses names that climb out (``..``), absolute names and
        uploads over its ``limits.max_upload_bytes``, as a
        :class:`ServiceError` naming the part (``assets[i]``).
        """
        text, path = _scene_text(scene)
        first = text.lstrip()[:1]
        if first not in ("{", "<"):
            raise ValueError("the scene is neither a JSON document nor Mitsuba XML")
        xml = first == "<"
        query: dict[str, Any] = {"replace": True if replace else None}
        if first == "{" and id is not None:
            document = json.loads(text)
            document["name"] = id
            text = json.dumps(document)
        if xml:
            scene_id = id if id is not None else path.stem if path is not None else None
            if scene_id is None:
                raise ValueError("an XML scene given as text needs an id")
            query |= {"id": scene_id, "lenient": True if lenient else None}
            for name, value in (params or {}).items():
                query[f"param.{name}"] = str(value)
        elif params:
            raise ValueError("params set a Mitsuba XML scene's $NAME; a JSON scene has none")
        if assets is None:
            answer = self._http.request(
                "POST",
                "/v1/scenes",
                body=text.encode("utf-8"),
                content_type="application/xml" if xml else "application/json",
                query=query,
            )
            return dict(answer.json())
        # A scene given as a path: names resolve beside it.
        files = _asset_files(text, xml, assets, None if path is None else path.parent, params or {})
        boundary = "bmc-" + os.urandom(12).hex()
        # The service names the document by this in its messages.
        document = path.name if path is not None else "scene.xml" if xml else "scene.json"
        parts = [("scene", document, text.encode("utf-8"))]
        parts += [("asset", name, data) for name, data in files]
        answer = self._http.request(
            "POST",
            "/v1/scenes",
            body=_multipart(parts, boundary),
            content_type=f"multipart/form-data; boundary={boundary}",
            query=query,
        )
        return dict(answer.json())

    def upload_archive(
        self,
        archive: bytes | os.PathLike[str] | str,
        id: str | None = None,
        *,
        file: str | None = None,
        lenient: bool = False,
        params: Mapping[str, str | int | float] | None = None,
        replace: bool = False,
    ) -> dict[str, Any]:
        """``POST /v1/scenes`` with a packed scene folder: a zip, tar or
        gzipped tar (a path, or its bytes), holding the scene file at its root
        or at the root of the one folder that holds everything, beside the
        meshes, maps and textures it names.

        The scene file is the only ``.xml``/``.json`` there, or the one named
        ``scene`` or after the folder, else ``file`` (``"scene_box.xml"``).
        An XML scene's id is ``id``, by default the stem of ``file`` when it is
        given, else the folder's name (``lego`` for ``zip -r lego.zip lego``)
        or the file's stem; a JSON scene's is its ``name``. ``lenient``,
        ``params`` and ``replace`` are as for :meth:`upload`. An
        entry the service refuses (``..``, a link, a FIFO, a zip bomb, more
        than its ``limits.max_assets``) raises :class:`ServiceError` naming
        ``archive[i]``. Returns the scene's summary.
        """
        data = archive if isinstance(archive, bytes) else Path(archive).read_bytes()
        query: dict[str, Any] = {
            "id": id,
            "file": file,
            "lenient": True if lenient else None,
            "replace": True if replace else None,
        }
        for name, value in (params or {}).items():
            query[f"param.{name}"] = str(value)
        answer = self._http.request(
            "POST",
            "/v1/scenes",
            body=data,
            content_type=_archive_type(archive),
            query=query,
        )
        return dict(answer.json())

    def upload_dir(
        self,
        folder: os.PathLike[str] | str,
        id: str | None = None,
        *,
        file: str | None = None,
        lenient: bool = False,
        params: Mapping[str, str | int | float] | None = None,
        replace: bool = False,
    ) -> dict[str, Any]:
        """``POST /v1/scenes`` with a whole scene folder (Mitsuba's ``lego/``
        with its ``scene.xml``, ``meshes/`` and ``textures/``), zipped in
        memory as ``<folder name>/...`` and sent as :meth:`upload_archive`
        does, so an XML scene's id is the folder's name unless ``id`` is
        given. Links and special files in the folder are refused here, as the
        service would refuse them."""
        root = Path(folder)
        if not root.is_dir():
            raise ValueError(f"{root} is not a folder")
        packed = io.BytesIO()
        with zipfile.ZipFile(packed, "w", zipfile.ZIP_DEFLATED) as out:
            for path in sorted(root.rglob("*")):
                if path.is_symlink() or not (path.is_file() or path.is_dir()):
                    raise ValueError(f"{path} is a link or a special file, not a regular file")
                if path.is_file():
                    out.write(path, f"{root.resolve().name}/{path.relative_to(root).as_posix()}")
        return self.upload_archive(
            packed.getvalue(), id, file=file, lenient=lenient, params=params, replace=replace
        )

    def delete(self, id: str) -> None:
        """``DELETE /v1/scenes/{id}``; requests already using the scene finish normally."""
        self._http.request("DELETE", f"/v1/scenes/{_segment(id)}")


def _archive_type(archive: bytes | os.PathLike[str] | str) -> str:
    """The media type an archive's file name declares; bytes are sent as
    ``application/octet-stream``, whose format the service reads from them."""
    if isinstance(archive, bytes):
        return "application/octet-stream"
    name = Path(archive).name.lower()
    if name.endswith(".zip"):
        return "application/zip"
    if name.endswith((".tar.gz", ".tgz")):
        return "application/gzip"
    if name.endswith(".tar"):
        return "application/x-tar"
    return "application/octet-stream"


def _referenced_files(text: str, xml: bool, params: Mapping[str, str | int | float]) -> list[str]:
    """The files a scene document names, each once, in order; in XML, its
    ``$NAME`` parameters are filled in from ``params``, else from the
    document's ``<default name=… value=…>``."""
    names: list[str] = []
    if xml:
        values: dict[str, str] = {}
        for tag in re.findall(r"<default\b[^>]*>", text):
            name, value = _attribute(tag, "name"), _attribute(tag, "value")
            if name is not None and value is not None:
                values[name] = value
        values |= {name: str(value) for name, value in params.items()}
        for tag in re.findall(r"<string\b[^>]*>", text):
            value = _attribute(tag, "value")
            if _attribute(tag, "name") == "filename" and value is not None:
                names.append(
                    re.sub(r"\$(\w+)", lambda m: values.get(m.group(1), m.group(0)), value)
                )
    else:

        def walk(value: Any) -> None:
            if isinstance(value, dict):
                for key, item in value.items():
                    if key == "filename" and isinstance(item, str):
                        names.append(item)
                    else:
                        walk(item)
            elif isinstance(value, list):
                for item in value:
                    walk(item)

        walk(json.loads(text))
    return list(dict.fromkeys(names))


def _attribute(tag: str, name: str) -> str | None:
    """The value of attribute ``name`` of an XML start tag, in either quotes."""
    found = re.search(rf"""\b{name}\s*=\s*(?:"([^"]*)"|'([^']*)')""", tag)
    if found is None:
        return None
    return found.group(1) if found.group(1) is not None else found.group(2)


def _asset_files(
    text: str,
    xml: bool,
    assets: str | Sequence[str] | Mapping[str, bytes | os.PathLike[str]],
    base: Path | None,
    params: Mapping[str, str | int | float],
) -> list[tuple[str, bytes]]:
    """``(relative name, bytes)`` of the assets to upload (see ``upload``)."""
    if isinstance(assets, Mapping):
        return [
            (name, data if isinstance(data, bytes) else Path(data).read_bytes())
            for name, data in assets.items()
        ]
    names = _referenced_files(text, xml, params) if assets == "auto" else list(assets)
    if names and base is None:
        raise ValueError("assets by name need the scene as a file path (or pass a mapping)")
    return [(name, (base / name).read_bytes()) for name in names] if base else []


def _multipart(parts: Sequence[tuple[str, str, bytes]], boundary: str) -> bytes:
    """A ``multipart/form-data`` body of ``(part name, filename, bytes)``."""
    out = bytearray()
    for name, filename, data in parts:
        out += f"--{boundary}\r\n".encode()
        out += (
            f'Content-Disposition: form-data; name="{name}"; filename="{filename}"\r\n'
            "Content-Type: application/octet-stream\r\n\r\n"
        ).encode()
        out += data + b"\r\n"
    out += f"--{boundary}--\r\n".encode()
    return bytes(out)


def _scene_text(scene: str | bytes | os.PathLike[str]) -> tuple[str, Path | None]:
    """The scene's text and, for a file, its path."""
    if isinstance(scene, bytes):
        return scene.decode("utf-8"), None
    if isinstance(scene, str) and scene.lstrip()[:1] in ("{", "<"):
        return scene, None
    path = Path(scene)
    return path.read_text(encoding="utf-8"), path
