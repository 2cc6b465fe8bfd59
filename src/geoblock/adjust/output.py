"""Deprecated: the report of a block adjustment moved to :mod:`geoblock.report.adjustment`.

``geoblock.adjust.output.write_result``, ``result_dict`` and ``report_markdown`` still work in
geoblock 0.2, with a :class:`~geoblock.errors.GeoblockDeprecationWarning`; import them from
:mod:`geoblock.report.adjustment` (or :mod:`geoblock.report`) instead.
"""

from __future__ import annotations

import warnings
from typing import Any

from geoblock.errors import GeoblockDeprecationWarning

__all__: list[str] = []

_MOVED = ("report_markdown", "result_dict", "write_result")


def __getattr__(name: str) -> Any:
    if name in _MOVED:
        warnings.warn(
            f"geoblock.adjust.output.{name} moved to geoblock.report.adjustment.{name}; "
            "the old name will be removed in geoblock 0.3",
            GeoblockDeprecationWarning,
            stacklevel=2,
        )
        from geoblock.report import adjustment  # the one upward import: a deprecation shim

        return getattr(adjustment, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
