"""A scene's irradiance-cache statistics and records: clear, export, import."""

from __future__ import annotations

from typing import Any

from ._base import _Resource, _segment


class _Records(_Resource):
    """``/v1/scenes/{id}/cache`` and ``/v1/scenes/{id}/records``."""

    def cache(self, scene: str) -> dict[str, Any]:
        """``GET /v1/scenes/{id}/cache``: irradiance-cache statistics per configuration."""
        return dict(self._http.get_json(f"/v1/scenes/{_segment(scene)}/cache"))

    def clear_cache(self, scene: str) -> dict[str, Any]:
        """``DELETE /v1/scenes/{id}/cache``: drops the shared caches' records (secondary too).

        The content-keyed records of reproducible tiles and point sets stay
        (``content_keyed`` in the report): they would be computed again bit for bit.
        """
        return dict(self._http.request("DELETE", f"/v1/scenes/{_segment(scene)}/cache").json())

    def export_records(self, scene: str) -> bytes:
        """``GET /v1/scenes/{id}/records``: the records of the scene's
        reproducible tiles held by the service, as bytes in the service's log
        format (``BMCLOG01`` then checksummed entries); keep them as a backup
        or pass them to :meth:`import_records` of another service."""
        return self._http.request(
            "GET",
            f"/v1/scenes/{_segment(scene)}/records",
            headers={"accept": "application/vnd.bmc-records"},
        ).body

    def import_records(self, scene: str, records: bytes) -> dict[str, Any]:
        """``POST /v1/scenes/{id}/records``: adds an export of the same scene
        content, all or nothing; returns ``{"imported", "already_held",
        "records"}``. A damaged entry or one of another scene's content raises
        :class:`ServiceError` (422) naming ``entries[i]``."""
        answer = self._http.request(
            "POST",
            f"/v1/scenes/{_segment(scene)}/records",
            body=bytes(records),
            content_type="application/vnd.bmc-records",
        )
        return dict(answer.json())
