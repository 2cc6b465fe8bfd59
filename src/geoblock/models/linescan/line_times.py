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
    """Exposure time of each row: a constant line period, of either sign.

    A forward scan has ``line_period_s > 0`` (row 0 is exposed first); a reverse scan
    (DigitalGlobe ``SCANDIRECTION Reverse``: agile satellites collect in both directions)
    has ``line_period_s < 0``: the times fall as the row rises and row 0 is the last line
    acquired. Nothing else changes: ``time`` and ``row`` are the same linear map, and the
    model's searches and tolerances use :attr:`period_magnitude_s` and the sorted time span
    (:meth:`span`).

    Parameters
    ----------
    reference_row : float
        Row (0-based pixel centre) exposed at ``reference_time_s``.
    reference_time_s : float
        Seconds since the epoch.
    line_period_s : float
        Seconds per row, non-zero: > 0 for a forward scan, < 0 for a reverse scan.
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
        if self.line_period_s == 0:
            raise fail("LineTimes.line_period_s",
                       "must be non-zero (> 0 for a forward scan, < 0 for a reverse scan), "
                       "got 0.0")

    @property
    def reverse(self) -> bool:
        """Whether the times fall as the row rises (a reverse scan)."""
        return self.line_period_s < 0

    @property
    def period_magnitude_s(self) -> float:
        """``abs(line_period_s)``: seconds between consecutive rows, > 0."""
        return abs(self.line_period_s)

    def span(self, first_row: float, last_row: float) -> tuple[float, float]:
        """``(earliest, latest)`` exposure time of the rows from ``first_row`` to
        ``last_row``, seconds since the epoch (sorted, whatever the scan direction)."""
        t0, t1 = (float(v) for v in self.time(np.array([first_row, last_row], np.float64)))
        return (t0, t1) if t0 <= t1 else (t1, t0)

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
