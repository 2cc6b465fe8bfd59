"""Observations: ground control with image measurements, as structures of arrays."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, fields

import numpy as np

from geoblock.errors import ObservationError
from geoblock.typing import ArrayLike

__all__ = ["ControlPoints"]


@dataclass(frozen=True, eq=False)
class ControlPoints:
    """Ground points with their measured positions in one image (GCPs or ICPs).

    Parameters
    ----------
    id : array_like of str, (N,)
        Point identifiers (named in error messages and reports).
    lon, lat : array_like, (N,)
        Ground coordinates, degrees (WGS84).
    h : array_like, (N,)
        Height above the WGS84 ellipsoid, metres.
    row, col : array_like, (N,)
        Measured image coordinates, pixels (pixel-centre convention).
    sigma_row, sigma_col : array_like, (N,) or scalar
        Standard deviation of the image measurements, pixels (default 0.5, Teo et al.).
    sigma_e, sigma_n, sigma_h : array_like, (N,) or scalar
        Standard deviation of the ground coordinates along local east, north and up, metres
        (default 0: error-free ground).
    """

    id: np.ndarray
    lon: np.ndarray
    lat: np.ndarray
    h: np.ndarray
    row: np.ndarray
    col: np.ndarray
    sigma_row: np.ndarray | float = 0.5
    sigma_col: np.ndarray | float = 0.5
    sigma_e: np.ndarray | float = 0.0
    sigma_n: np.ndarray | float = 0.0
    sigma_h: np.ndarray | float = 0.0

    def __post_init__(self) -> None:
        ids = np.atleast_1d(np.asarray(self.id)).astype(str)
        n = ids.shape[0]
        if ids.ndim != 1:
            raise ObservationError(
                f"ControlPoints: id must be one-dimensional, got shape {ids.shape}"
            )
        object.__setattr__(self, "id", ids)
        for f in fields(self)[1:]:
            raw = np.asarray(getattr(self, f.name), dtype=np.float64)
            if raw.ndim == 0:
                raw = np.full(n, float(raw))
            if raw.shape != (n,):
                raise ObservationError(
                    f"ControlPoints: {f.name} has shape {raw.shape}, expected ({n},) like id"
                )
            bad = ~np.isfinite(raw)
            if f.name.startswith("sigma"):
                positive = f.name in ("sigma_row", "sigma_col")
                bad |= (raw <= 0) if positive else (raw < 0)
            if bad.any():
                which = ", ".join(ids[bad][:5]) + (" ..." if bad.sum() > 5 else "")
                rule = "finite and > 0" if f.name in ("sigma_row", "sigma_col") else (
                    "finite and >= 0" if f.name.startswith("sigma") else "finite")
                raise ObservationError(f"ControlPoints: {f.name} must be {rule} (points {which})")
            raw.flags.writeable = False
            object.__setattr__(self, f.name, raw)
        dup = {i for i in ids.tolist() if (ids == i).sum() > 1}
        if dup:
            raise ObservationError(f"ControlPoints: duplicate point ids {sorted(dup)}")

    def __len__(self) -> int:
        return int(self.id.shape[0])

    @classmethod
    def from_columns(cls, columns: Mapping[str, ArrayLike], **defaults: float) -> ControlPoints:
        """Build from a column mapping such as :func:`geoblock.io.read_points` returns.

        Columns ``id, lon, lat, h, row, col`` are required; ``sigma_*`` columns are optional
        (``defaults`` override the class defaults for absent ones).
        """
        missing = [c for c in ("lon", "lat", "h", "row", "col") if c not in columns]
        if missing:
            raise ObservationError(f"control points need columns {missing}")
        kwargs = {f.name: columns[f.name] for f in fields(cls) if f.name in columns}
        for name, value in defaults.items():
            kwargs.setdefault(name, value)
        if "id" not in kwargs:
            kwargs["id"] = [str(i + 1) for i in range(len(np.asarray(columns["lon"])))]
        return cls(**kwargs)

    def subset(self, mask: ArrayLike) -> ControlPoints:
        """The points selected by a boolean mask or index array."""
        mask = np.asarray(mask)
        return ControlPoints(**{f.name: getattr(self, f.name)[mask] for f in fields(self)})
