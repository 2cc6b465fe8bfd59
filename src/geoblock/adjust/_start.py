"""Warm start of :func:`~geoblock.adjust.adjust` from a previous solution (``start=``).

A previous solution gives, per image, its adjusted parameters by name and, per point, its
adjusted ground coordinates: a :class:`~geoblock.adjust.BlockResult`, or what
``geoblock adjust`` wrote (its output directory, or the ``report.json`` in it: its
``parameters`` and ``points``). The images and points it holds start from there; the others
from their on-board models and ray-traced positions. Only the starting point changes: the
a-priori values, sigmas and every observation are the block's, so the solution is the one
of a cold start (to the convergence tolerance), reached in fewer iterations.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from geoblock.errors import AdjustmentError, GeoblockError
from geoblock.io.files import read_json
from geoblock.typing import Float64Array, StrArray

__all__ = ["WarmStart", "warm_start"]


@dataclass(frozen=True)
class WarmStart:
    """Where a previous solution left the block.

    Attributes
    ----------
    parameters : dict of str to dict of str to float
        Per image, adjusted parameter values by name (the parameters' units).
    id : ndarray of str, (J,)
        Points; ``lon``, ``lat`` (degrees) and ``h`` (metres above the ellipsoid) (J,) their
        adjusted coordinates.
    source : str
        What it was read from, for messages.
    """

    parameters: dict[str, dict[str, float]]
    id: StrArray
    lon: Float64Array
    lat: Float64Array
    h: Float64Array
    source: str = "a previous solution"


def warm_start(start: Any) -> WarmStart:
    """A :class:`WarmStart` from a BlockResult, a WarmStart, or the path of ``geoblock
    adjust``'s output directory or of its ``report.json``.

    Raises
    ------
    AdjustmentError
        A path without a readable report, or an object of another type.
    """
    if isinstance(start, WarmStart):
        return start
    if isinstance(start, str | os.PathLike):
        path = Path(start)
        report = path / "report.json" if path.is_dir() else path
        try:
            data = read_json(report, "the warm start's report")
            params = {image: {str(p["name"]): float(p["value"]) for p in rows
                              if p.get("value") is not None}
                      for image, rows in data["parameters"].items()}
            pts = [p for p in data["points"]
                   if all(p.get(k) is not None for k in ("lon", "lat", "h"))]
        except (GeoblockError, OSError, ValueError, KeyError, TypeError) as exc:
            raise AdjustmentError(
                f"adjust: start {str(path)!r}: not a geoblock adjust output (its report.json "
                f"with 'parameters' and 'points' could not be read: {exc})") from None
        return WarmStart(
            parameters=params, id=np.array([str(p["id"]) for p in pts], dtype=str),
            lon=np.array([p["lon"] for p in pts], dtype=np.float64),
            lat=np.array([p["lat"] for p in pts], dtype=np.float64),
            h=np.array([p["h"] for p in pts], dtype=np.float64), source=str(report))
    parameters = getattr(start, "parameters", None)
    points = getattr(start, "points", None)
    if parameters is None or points is None:
        raise AdjustmentError("adjust: start must be a BlockResult or the path of a geoblock "
                              f"adjust output, got {type(start).__name__}")
    ok = np.isfinite(points.lon) & np.isfinite(points.lat) & np.isfinite(points.h)
    return WarmStart(
        parameters={image: dict(zip(e.names, (float(v) for v in e.values), strict=True))
                    for image, e in parameters.items()},
        id=np.asarray(points.id, dtype=str)[ok], lon=np.asarray(points.lon)[ok],
        lat=np.asarray(points.lat)[ok], h=np.asarray(points.h)[ok])
