"""Whole camera images assembled from concurrently fetched tiles."""

from __future__ import annotations

import concurrent.futures
from collections.abc import Mapping
from typing import Any, Literal, overload

import numpy as np
import numpy.typing as npt

from ._base import Estimator
from ._http import Response
from ._progress import Progress
from ._scenes import _Scenes
from ._tiles import _grid_query, _header_int, _tile_arrays, _Tiles
from .results import Image, TileInfo

_AOVS = ("radiance", "std_dev", "records")


class _Images(_Tiles, _Scenes):
    """:meth:`image`: the tiles of a scene's camera (its resolution from :meth:`scene`)."""

    @overload
    def image(
        self,
        scene: str,
        preset: str | None = ...,
        *,
        aov: Literal["radiance"] = ...,
        pass_index: int | None = ...,
        seed: int = ...,
        size: int | None = ...,
        workers: int = ...,
        progress: bool | None = ...,
        spp: int | None = ...,
        estimator: Estimator | None = ...,
        max_depth: int | None = ...,
        tile: int | None = ...,
        denoise: bool | None = ...,
    ) -> Image: ...

    # spp, estimator and max_depth are radiance only (POST tiles).
    @overload
    def image(
        self,
        scene: str,
        preset: str | None = ...,
        *,
        aov: Literal["std_dev"],
        pass_index: int | None = ...,
        seed: int = ...,
        size: int | None = ...,
        workers: int = ...,
        progress: bool | None = ...,
        tile: int | None = ...,
    ) -> Image: ...

    @overload
    def image(
        self,
        scene: str,
        preset: str | None = ...,
        *,
        aov: Literal["records"],
        pass_index: int | None = ...,
        seed: int = ...,
        size: int | None = ...,
        workers: int = ...,
        progress: bool | None = ...,
    ) -> list[dict[str, Any]]: ...

    def image(
        self,
        scene: str,
        preset: str | None = "preview",
        *,
        aov: str = "radiance",
        pass_index: int | None = None,
        seed: int = 1,
        size: int | None = None,
        workers: int = 4,
        progress: bool | None = None,
        spp: int | None = None,
        estimator: Estimator | None = None,
        max_depth: int | None = None,
        tile: int | None = None,
        denoise: bool | None = None,
    ) -> Image | list[dict[str, Any]]:
        """The scene camera's whole image, assembled from JSON tiles of
        ``size`` pixels (default 64) fetched ``workers`` at a time, with a
        text progress bar on stderr (``progress``; default only when stderr
        is a terminal).

        By default the tiles come from the GET route
        (``/v1/scenes/{id}/tiles/{tx}/{ty}.json``) with a quality
        ``preset`` (``"draft"``, ``"preview"``, ``"interactive"``, ``"standard"``, ``"final"``; see
        :meth:`presets`), ``pass_index`` (0-based; pass *k* is the mean of
        passes 0..*k*; default the preset's last) and ``seed``. Each tile is
        reproducible, so the image is the same bytes whatever the order the
        tiles arrive in, on any service of the same version with the same
        scene content; each tile's ``etag`` is in ``image.tiles``.

        ``aov``:

        * ``"radiance"`` (default): an :class:`Image` with ``rgb`` (H×W×3,
          W/(m²·sr)), ``variance`` and ``std_dev`` (H×W);
        * ``"std_dev"``: an :class:`Image` whose ``rgb`` is the per-pixel
          standard error in all three channels (``std_dev`` is one of them,
          ``variance`` is ``None``);
        * ``"records"``: the list of irradiance-cache record dicts of every
          tile (``position``, ``normal``, ``radius``, ``irradiance``,
          ``pixel``, ``radius_pixels``), tiles in row-major order.

        Explicit knobs — ``spp`` (camera rays per pixel in each pass),
        ``estimator`` (``"cache"``, ``"path"`` or a dict of options) or
        ``max_depth`` — switch to ``POST /v1/scenes/{id}/tiles``, where they
        override the preset's (radiance only). With ``"path"`` a pixel
        depends only on the seed and its position. ``tile`` is the former
        name of ``size``.

        ``denoise=True`` (radiance only) asks for tiles filtered by their
        own first-hit guides, ``False`` for tiles as rendered; ``None`` (the
        default) leaves it to the preset, which denoises the path traced
        presets of scenes with mirrors, glass or sharp gloss (the service's
        docs/math.md §16.6, §16.7). Each denoised pixel carries a measured
        standard error.

        Errors: a 503 with ``Retry-After`` is retried per tile (the client's
        ``retries``); any other error answer, e.g. 422 for an unknown preset
        (``field == "preset"``) or pass (``"pass"``), raises
        :class:`ServiceError`.
        """
        if preset is not None and not isinstance(preset, str):
            raise TypeError(
                "preset is a name ('draft', 'preview', 'interactive', 'standard', 'final'); "
                f"got {preset!r} (camera rays per pixel are spp=...)"
            )
        if tile is not None and size is not None and tile != size:
            raise ValueError("tile is the former name of size: give one")
        side = int(size if size is not None else tile if tile is not None else 64)
        if side < 1 or workers < 1:
            raise ValueError("size and workers must be at least 1")
        if aov not in _AOVS:
            raise ValueError(f"aov must be one of {', '.join(_AOVS)}, not {aov!r}")
        post = spp is not None or estimator is not None or max_depth is not None
        if denoise and aov != "radiance":
            raise ValueError(f"denoise applies to radiance, not aov={aov!r}")
        if post and aov != "radiance":
            raise ValueError(
                "spp, estimator and max_depth use POST tiles, which are radiance only; "
                f"aov={aov!r} needs a preset alone"
            )
        width, height = (int(v) for v in self.scene(scene)["resolution"])
        grid = [(tx, ty) for ty in range(-(-height // side)) for tx in range(-(-width // side))]
        query = _grid_query(side, preset, pass_index, seed, aov, denoise=denoise)

        def fetch(tx: int, ty: int) -> Response:
            if post:
                x, y = tx * side, ty * side
                return self._tile_request(
                    scene,
                    x,
                    y,
                    min(side, width - x),
                    min(side, height - y),
                    "json",
                    spp,
                    estimator,
                    max_depth,
                    seed,
                    preset=preset,
                    pass_index=pass_index,
                    denoise=denoise,
                )
            answer = self._grid_tile(scene, tx, ty, "json", query, None)
            assert answer is not None  # no If-None-Match, no 304
            return answer

        rgb = np.zeros((height, width, 3), dtype=np.float32)
        variance: npt.NDArray[np.float32] | None = (
            np.zeros((height, width), dtype=np.float32) if aov == "radiance" else None
        )
        records: dict[tuple[int, int], list[dict[str, Any]]] = {}
        infos: dict[tuple[int, int], TileInfo] = {}
        bar = Progress(len(grid), "tiles", enabled=progress)
        pool = concurrent.futures.ThreadPoolExecutor(max_workers=workers)
        try:
            futures = {pool.submit(fetch, tx, ty): (tx, ty) for tx, ty in grid}
            for future in concurrent.futures.as_completed(futures):
                tx, ty = futures[future]
                answer = future.result()
                x, y = tx * side, ty * side
                w, h = min(side, width - x), min(side, height - y)
                doc = answer.json()
                if aov == "records":
                    records[(tx, ty)] = list(doc["records"])
                else:
                    part, part_variance = _tile_arrays(doc)
                    if part.shape[:2] != (h, w):
                        raise RuntimeError(
                            f"tile ({tx}, {ty}) is {part.shape[1]}×{part.shape[0]}, "
                            f"expected {w}×{h}"
                        )
                    rgb[y : y + h, x : x + w] = part
                    if variance is not None:
                        if part_variance is None:
                            variance = None
                        else:
                            variance[y : y + h, x : x + w] = part_variance
                infos[(tx, ty)] = _tile_info(tx, ty, x, y, w, h, answer.headers)
                bar.advance()
        finally:
            pool.shutdown(wait=True, cancel_futures=True)
            bar.close()
        if aov == "records":
            return [record for key in grid for record in records[key]]
        tiles = tuple(infos[key] for key in grid)
        return Image(
            rgb=rgb,
            variance=variance,
            rays=sum(t.rays for t in tiles),
            aov=aov,
            preset=preset,
            pass_index=pass_index,
            seed=seed,
            size=side,
            tiles=tiles,
        )


def _tile_info(
    tx: int, ty: int, x: int, y: int, w: int, h: int, headers: Mapping[str, str]
) -> TileInfo:
    return TileInfo(
        tx=tx,
        ty=ty,
        x=x,
        y=y,
        width=w,
        height=h,
        etag=headers.get("etag"),
        rays=int(headers.get("x-rays", 0)),
        records_created=int(headers.get("x-records-created", 0)),
        passes_rendered=_header_int(headers, "x-passes-rendered"),
    )
