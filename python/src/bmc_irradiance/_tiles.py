"""Single tiles of the scene camera's image: GET tiles of a preset's grid
and POST tiles of any pixel rectangle, as floats or encoded bytes."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np
import numpy.typing as npt

from ._base import Estimator, _estimator_doc, _Resource, _segment
from ._http import Response
from .results import Tile, TileBytes


class _Tiles(_Resource):
    """``/v1/scenes/{id}/tiles/{tx}/{ty}.{ext}`` and ``/v1/scenes/{id}/tiles``."""

    def _grid_tile(
        self,
        scene: str,
        tx: int,
        ty: int,
        extension: str,
        query: Mapping[str, Any],
        if_none_match: str | None,
    ) -> Response | None:
        """``GET /v1/scenes/{id}/tiles/{tx}/{ty}.{extension}``; ``None`` on 304."""
        headers = {"accept": "application/json" if extension == "json" else "*/*"}
        if if_none_match is not None:
            headers["if-none-match"] = if_none_match
        answer = self._http.request(
            "GET",
            f"/v1/scenes/{_segment(scene)}/tiles/{int(tx)}/{int(ty)}.{_segment(extension)}",
            query=query,
            accept=(304,),
            headers=headers,
        )
        return None if answer.status == 304 else answer

    def _tile_request(
        self,
        scene: str,
        x: int,
        y: int,
        width: int,
        height: int,
        format: str,
        spp: int | None,
        estimator: Estimator | None,
        max_depth: int | None,
        seed: int | None,
        exposure: float | None = None,
        preset: str | None = None,
        pass_index: int | None = None,
        denoise: bool | None = None,
    ) -> Response:
        """``POST /v1/scenes/{id}/tiles`` of a pixel rectangle."""
        body: dict[str, Any] = {
            "x": int(x),
            "y": int(y),
            "width": int(width),
            "height": int(height),
            "format": format,
        }
        if preset is not None:
            body["preset"] = preset
        if pass_index is not None:
            body["pass"] = int(pass_index)
        if spp is not None:
            body["samples_per_pixel"] = int(spp)
        integrator = _estimator_doc(estimator)
        if integrator is not None:
            body["estimator"] = integrator
        if max_depth is not None:
            body["max_depth"] = int(max_depth)
        if seed is not None:
            body["seed"] = int(seed)
        if exposure is not None:
            body["exposure"] = float(exposure)
        if denoise is not None:
            body["denoise"] = bool(denoise)
        return self._http.post_json(f"/v1/scenes/{_segment(scene)}/tiles", body)

    def tile(
        self,
        scene: str,
        x: int,
        y: int,
        width: int | None = None,
        height: int | None = None,
        *,
        size: int | None = None,
        preset: str | None = None,
        pass_index: int | None = None,
        aov: str = "radiance",
        seed: int | None = None,
        if_none_match: str | None = None,
        spp: int | None = None,
        estimator: Estimator | None = None,
        max_depth: int | None = None,
    ) -> Tile | None:
        """One tile of the scene camera's image as floats (JSON tiles).

        Two forms:

        * ``tile(scene, tx, ty)`` — the GET route
          (``/v1/scenes/{id}/tiles/{tx}/{ty}.json``): ``tx`` and ``ty`` are
          the tile's column and row on the grid of ``size``-pixel squares
          (service default 64; edge tiles are smaller). ``preset``
          (``"draft"``, ``"preview"`` — the service's default —,
          ``"interactive"``, ``"standard"`` or ``"final"``, see :meth:`presets`),
          ``pass_index`` (0-based; pass
          *k* is the mean of passes 0..*k*; default the preset's last),
          ``seed`` (default 1) and ``aov`` (``"radiance"`` or
          ``"std_dev"``: ``rgb`` is then the per-pixel standard error).
          The same arguments give the same numbers on any service of the
          same version and scene content; ``tile.etag`` names them. With
          ``if_none_match=`` a previous tile's ``etag``, the answer is
          ``None`` when that is still the tile (HTTP 304: nothing rendered
          or sent).
        * ``tile(scene, x, y, width, height)`` — ``POST
          /v1/scenes/{id}/tiles`` of any pixel rectangle (``x``, ``y`` its
          top-left pixel), with ``preset`` and ``pass_index`` as above and
          explicit knobs that override the preset: ``spp`` camera rays per
          pixel in each pass, ``estimator`` (``"cache"``, ``"path"`` or a
          dict of options) and ``max_depth``. Never ``None``.

        Radiance in W/(m²·sr). The records AOV is not an image: use
        :meth:`image` with ``aov="records"``, or :meth:`tile_bytes` with
        ``format="json", aov="records"`` and ``.json()``.
        """
        if _grid_form(width, height):
            _refuse_knobs("tile", spp=spp, estimator=estimator, max_depth=max_depth)
            if aov not in ("radiance", "std_dev"):
                raise ValueError(
                    f"tile() returns images (aov 'radiance' or 'std_dev'), not {aov!r}; "
                    "records come from image(scene, aov='records') or "
                    "tile_bytes(scene, tx, ty, format='json', aov='records').json()"
                )
            query = _grid_query(size, preset, pass_index, seed, aov)
            answer = self._grid_tile(scene, x, y, "json", query, if_none_match)
            if answer is None:
                return None
            return _tile_of(answer, aov)
        _refuse_grid_options("tile", size=size, if_none_match=if_none_match)
        if aov != "radiance":
            raise ValueError("POST tiles are radiance; aov needs the GET form tile(scene, tx, ty)")
        assert width is not None and height is not None
        answer = self._tile_request(
            scene,
            x,
            y,
            width,
            height,
            "json",
            spp,
            estimator,
            max_depth,
            seed,
            preset=preset,
            pass_index=pass_index,
        )
        return _tile_of(answer, "radiance", (x, y))

    def tile_bytes(
        self,
        scene: str,
        x: int,
        y: int,
        width: int | None = None,
        height: int | None = None,
        *,
        format: str = "png",
        size: int | None = None,
        preset: str | None = None,
        pass_index: int | None = None,
        aov: str | None = None,
        seed: int | None = None,
        exposure: float | None = None,
        scale: float | None = None,
        if_none_match: str | None = None,
        spp: int | None = None,
        estimator: Estimator | None = None,
        max_depth: int | None = None,
    ) -> TileBytes | None:
        """One tile encoded by the service, as :class:`TileBytes` (``bytes``
        with the answer's ``etag``, ``content_type``, ``rays`` and
        ``headers``).

        ``format``: ``"png"`` (8-bit sRGB, radiance tone-mapped with
        ``exposure`` in stops), ``"exr"`` (float R, G, B and ``variance``)
        or ``"json"``. The two forms of :meth:`tile`:

        * ``tile_bytes(scene, tx, ty, format=..., preset=..., aov=...)`` —
          the GET route on the grid of ``size``-pixel tiles, with
          ``pass_index``, ``seed``, ``aov`` (``"radiance"``, ``"std_dev"``:
          as PNG the relative standard error through a colour map whose top
          is ``scale``, default 0.2, also in the ``x-std-dev-scale`` header;
          ``"records"``: a transparent PNG overlay or JSON) and
          ``if_none_match``: a previous answer's ``etag``, which makes the
          call return ``None`` if the tile is unchanged (HTTP 304). The
          bytes are reproducible, so the ETag can key a client-side cache::

              png = client.tile_bytes("cornell-box", 1, 2, preset="final")
              again = client.tile_bytes("cornell-box", 1, 2, preset="final",
                                        if_none_match=png.etag)
              assert again is None  # still the same bytes

        * ``tile_bytes(scene, x, y, width, height, format=...)`` — POST of a
          pixel rectangle with ``preset``, ``pass_index``, ``seed``,
          ``exposure`` and the explicit knobs ``spp``, ``estimator`` and
          ``max_depth``; never ``None`` (and no ETag).
        """
        if _grid_form(width, height):
            _refuse_knobs("tile_bytes", spp=spp, estimator=estimator, max_depth=max_depth)
            query = _grid_query(size, preset, pass_index, seed, aov, exposure, scale)
            answer = self._grid_tile(scene, x, y, format, query, if_none_match)
            return None if answer is None else TileBytes(answer.body, answer.headers)
        _refuse_grid_options(
            "tile_bytes", size=size, if_none_match=if_none_match, aov=aov, scale=scale
        )
        assert width is not None and height is not None
        answer = self._tile_request(
            scene,
            x,
            y,
            width,
            height,
            format,
            spp,
            estimator,
            max_depth,
            seed,
            exposure,
            preset=preset,
            pass_index=pass_index,
        )
        return TileBytes(answer.body, answer.headers)


def _grid_form(width: int | None, height: int | None) -> bool:
    """Whether a tile call is the GET form (no width and height)."""
    if (width is None) != (height is None):
        raise ValueError(
            "give both width and height (a POST pixel rectangle) or neither (GET tx, ty)"
        )
    return width is None


def _refuse_knobs(method: str, **knobs: Any) -> None:
    given = [name for name, value in knobs.items() if value is not None]
    if given:
        raise ValueError(
            f"{method}(scene, tx, ty) is a GET tile of a preset; {', '.join(given)} need "
            f"the POST form {method}(scene, x, y, width, height, ...)"
        )


def _refuse_grid_options(method: str, **options: Any) -> None:
    given = [name for name, value in options.items() if value is not None]
    if given:
        raise ValueError(
            f"{', '.join(given)}: only for the GET form {method}(scene, tx, ty, ...) "
            "(without width and height)"
        )


def _grid_query(
    size: int | None,
    preset: str | None,
    pass_index: int | None,
    seed: int | None,
    aov: str | None,
    exposure: float | None = None,
    scale: float | None = None,
    denoise: bool | None = None,
) -> dict[str, Any]:
    """The query of a GET tile; ``None`` values are left out (the service's defaults)."""
    return {
        "denoise": None if denoise is None else ("true" if denoise else "false"),
        "size": None if size is None else int(size),
        "preset": preset,
        "pass": None if pass_index is None else int(pass_index),
        "seed": None if seed is None else int(seed),
        "aov": aov,
        "exposure": None if exposure is None else float(exposure),
        "scale": None if scale is None else float(scale),
    }


def _tile_arrays(
    doc: Mapping[str, Any],
) -> tuple[npt.NDArray[np.float32], npt.NDArray[np.float32] | None]:
    """``rgb`` (h×w×3) and ``variance`` (h×w or ``None``) of a JSON tile."""
    w, h = int(doc["width"]), int(doc["height"])
    rgb = np.asarray(doc["rgb"], dtype=np.float32).reshape(h, w, 3)
    variance = doc.get("variance")
    if variance is None:
        return rgb, None
    return rgb, np.asarray(variance, dtype=np.float32).reshape(h, w)


def _header_int(headers: Mapping[str, str], name: str) -> int | None:
    value = headers.get(name)
    return None if value is None else int(value)


def _tile_of(answer: Response, aov: str, origin: tuple[int, int] = (0, 0)) -> Tile:
    rgb, variance = _tile_arrays(answer.json())
    h = answer.headers
    return Tile(
        x=int(h.get("x-tile-x", origin[0])),
        y=int(h.get("x-tile-y", origin[1])),
        rgb=rgb,
        variance=variance,
        rays=int(h.get("x-rays", 0)),
        etag=h.get("etag"),
        aov=aov,
        records_created=int(h.get("x-records-created", 0)),
        passes=_header_int(h, "x-passes"),
        passes_rendered=_header_int(h, "x-passes-rendered"),
    )
