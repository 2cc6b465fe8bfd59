"""Detector look directions of the linescan model: one unit vector per image column."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from geoblock.models.linescan._checks import fail, sample_array
from geoblock.typing import ArrayLike, Float64Array

__all__ = ["LookDirections"]


@dataclass(frozen=True, eq=False)
class LookDirections:
    """One look vector per detector (image column) in the sensor frame.

    Parameters
    ----------
    vectors : array_like, (cols, 3)
        Look vectors in the sensor frame (+z boresight, +x along track, +y across), one per
        column, cols >= 2; normalised here if they are not unit vectors. The across-track
        tangents ``v_y / v_z`` must be strictly monotonic and ``v_z > 0``.

    Notes
    -----
    Between detectors the look vector is the linear interpolation of the two neighbours'
    vectors, normalised; beyond the ends, the end segments extend linearly.
    """

    vectors: np.ndarray
    _tan_y: np.ndarray = field(init=False, repr=False)
    _ascending: bool = field(init=False, repr=False)

    def __post_init__(self) -> None:
        v = np.array(sample_array(self.vectors, "LookDirections.vectors", (3,), 2))
        norm = np.linalg.norm(v, axis=1)
        if np.any(~(np.abs(norm - 1.0) <= 1e-12)):
            if np.any(~(norm > 0)):
                raise fail("LookDirections.vectors", "has zero vectors")
            v = v / norm[:, None]
        if np.any(~(v[:, 2] > 0)):
            i = int(np.flatnonzero(~(v[:, 2] > 0))[0])
            raise fail("LookDirections.vectors",
                        f"detector {i} does not look down the boresight (z = {v[i, 2]!r} <= 0)")
        tan_y = v[:, 1] / v[:, 2]
        d = np.diff(tan_y)
        if not (np.all(d > 0) or np.all(d < 0)):
            raise fail("LookDirections.vectors",
                        "the across-track tangents v_y / v_z must be strictly monotonic in col")
        v.flags.writeable = False
        object.__setattr__(self, "vectors", v)
        object.__setattr__(self, "_ascending", bool(d[0] > 0))
        object.__setattr__(self, "_tan_y", tan_y if d[0] > 0 else -tan_y)

    @classmethod
    def from_tan_angles(cls, tan_x: ArrayLike, tan_y: ArrayLike) -> LookDirections:
        """Look vectors ``(tan_x, tan_y, 1)`` normalised, from focal-plane tangents (cols,).

        Raises
        ------
        ModelFormatError
            The tangents are not numbers or do not broadcast together.
        """
        try:
            tx, ty = np.broadcast_arrays(np.asarray(tan_x, np.float64),
                                         np.asarray(tan_y, np.float64))
        except (TypeError, ValueError):
            raise fail("LookDirections.from_tan_angles",
                       f"tan_x {np.shape(tan_x)} and tan_y {np.shape(tan_y)} must be numbers "
                       "of one length (one per detector)") from None
        v = np.stack([tx, ty, np.ones_like(tx)], axis=-1)
        return cls(v / np.linalg.norm(v, axis=-1, keepdims=True))

    @property
    def cols(self) -> int:
        """Number of detectors."""
        return int(self.vectors.shape[0])

    def at(self, col: ArrayLike) -> Float64Array:
        """Unit look vectors (..., 3) at columns ``col`` (0-based pixel centres)."""
        c = np.asarray(col, dtype=np.float64)
        i = np.clip(np.floor(c), 0, self.cols - 2)
        i = np.where(np.isfinite(i), i, 0).astype(np.intp)
        a = (c - i)[..., None]
        v = (1.0 - a) * self.vectors[i] + a * self.vectors[i + 1]
        with np.errstate(invalid="ignore", divide="ignore"):
            return v / np.linalg.norm(v, axis=-1, keepdims=True)

    def invert(self, tan_y: ArrayLike) -> tuple[Float64Array, Float64Array, Float64Array]:
        """The column whose look vector has the across-track tangent ``v_y / v_z == tan_y``.

        The exact inverse of :meth:`at` (the ground -> image search of a pushbroom model asks
        which detector sees a direction).

        Parameters
        ----------
        tan_y : array_like, (N,)
            Across-track tangents ``v_y / v_z`` of directions in the sensor frame.

        Returns
        -------
        col : ndarray, (N,)
            Column, 0-based pixel centres (beyond the ends: extrapolated linearly).
        tan_x : ndarray, (N,)
            The along-track tangent ``v_x / v_z`` of the look vector at ``col``.
        dtan_dcol : ndarray, (N, 2)
            ``d(v_x / v_z)/dcol`` and ``d(v_y / v_z)/dcol`` at ``col``, per pixel.
        """
        ratio_y = np.asarray(tan_y, dtype=np.float64)
        key = ratio_y if self._ascending else -ratio_y
        i = np.clip(np.searchsorted(self._tan_y, key) - 1, 0, self.cols - 2)
        v0, v1 = self.vectors[i], self.vectors[i + 1]
        dv = v1 - v0
        with np.errstate(invalid="ignore", divide="ignore"):
            a = (v0[:, 1] - ratio_y * v0[:, 2]) / (ratio_y * dv[:, 2] - dv[:, 1])
            vz = v0[:, 2] + a * dv[:, 2]
            vx = v0[:, 0] + a * dv[:, 0]
            tx = vx / vz
            dtx = (dv[:, 0] * v0[:, 2] - v0[:, 0] * dv[:, 2]) / (vz * vz)
            dty = (dv[:, 1] * v0[:, 2] - v0[:, 1] * dv[:, 2]) / (vz * vz)
        return i + a, tx, np.stack([dtx, dty], axis=-1)

    def to_dict(self) -> dict[str, Any]:
        """JSON-safe dictionary."""
        return {"vectors": self.vectors.tolist()}

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> LookDirections:
        """Inverse of :meth:`to_dict`."""
        return cls(data["vectors"])
