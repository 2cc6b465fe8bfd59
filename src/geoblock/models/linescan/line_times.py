"""Row exposure times of the linescan model."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from geoblock.models.linescan._checks import fail
from geoblock.typing import ArrayLike, Float64Array

__all__ = ["LineTimes"]


@dataclass(frozen=True)
class LineTimes:
    """Exposure time of each row: a constant line period.

    Parameters
    ----------
    reference_row : float
        Row (0-based pixel centre) exposed at ``reference_time_s``.
    reference_time_s : float
        Seconds since the epoch.
    line_period_s : float
        Seconds per row, > 0.
    """

    reference_row: float
    reference_time_s: float
    line_period_s: float

    def __post_init__(self) -> None:
        for name in ("reference_row", "reference_time_s", "line_period_s"):
            try:
                value = float(getattr(self, name))
            except (TypeError, ValueError):
                raise fail(f"LineTimes.{name}", f"must be a number, got "
                                                 f"{getattr(self, name)!r}") from None
            if not np.isfinite(value):
                raise fail(f"LineTimes.{name}", f"must be finite, got {value!r}")
            object.__setattr__(self, name, value)
        if not self.line_period_s > 0:
            raise fail("LineTimes.line_period_s", f"must be > 0, got {self.line_period_s!r}")

    def time(self, row: ArrayLike) -> Float64Array:
        """Seconds since the epoch at which ``row`` is exposed."""
        return self.reference_time_s + (np.asarray(row, np.float64) - self.reference_row) * (
            self.line_period_s)

    def row(self, t_s: ArrayLike) -> Float64Array:
        """Row exposed at ``t_s`` seconds since the epoch (inverse of :meth:`time`)."""
        return self.reference_row + (np.asarray(t_s, np.float64) - self.reference_time_s) / (
            self.line_period_s)

    def to_dict(self) -> dict[str, Any]:
        """JSON-safe dictionary."""
        return {"reference_row": self.reference_row, "reference_time_s": self.reference_time_s,
                "line_period_s": self.line_period_s}

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> LineTimes:
        """Inverse of :meth:`to_dict`."""
        return cls(data["reference_row"], data["reference_time_s"], data["line_period_s"])
