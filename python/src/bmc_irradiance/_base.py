"""What every resource of :class:`~bmc_irradiance.Client` shares: the
transport, scene ids as URL path segments and estimator documents."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any, Union
from urllib.parse import quote

from ._http import Transport

Estimator = Union[str, Mapping[str, Any]]


class _Resource:
    """Base of the per-resource parts :class:`~bmc_irradiance.Client` is made of."""

    _http: Transport


def _segment(id: str) -> str:
    """A scene id as one URL path segment."""
    return quote(id, safe="")


def _estimator_doc(estimator: Estimator | None) -> dict[str, Any] | None:
    if estimator is None:
        return None
    if isinstance(estimator, str):
        return {"method": estimator}
    return dict(estimator)
