"""Sensor attitude of the linescan model: time-tagged unit quaternions, slerp-interpolated."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from geoblock.models.linescan._checks import check_increasing, fail, sample_array, segment
from geoblock.models.linescan.rotations import quaternion_to_matrix
from geoblock.typing import ArrayLike, Float64Array

__all__ = ["Attitude"]


@dataclass(frozen=True, eq=False)
class Attitude:
    """Time-tagged attitude quaternions, slerp-interpolated.

    Parameters
    ----------
    time_s : array_like, (m,)
        Strictly increasing, seconds since the epoch; m >= 1 (1: constant attitude).
    quaternion : array_like, (m, 4)
        ``(w, x, y, z)`` unit quaternions: ``v_frame = R(q) @ v_sensor``.
    frame : {"ecef", "orbital"}
        The frame the quaternions rotate sensor vectors into (``"orbital"``: the frame of
        :func:`orbital_frame` at the same time).
    """

    time_s: np.ndarray
    quaternion: np.ndarray
    frame: str = "ecef"
    _unit: np.ndarray = field(init=False, repr=False)

    def __post_init__(self) -> None:
        t = sample_array(self.time_s, "Attitude.time_s", (), 1)
        q = sample_array(self.quaternion, "Attitude.quaternion", (4,), 1)
        if q.shape[0] != t.shape[0]:
            raise fail("Attitude.quaternion", f"has {q.shape[0]} samples, time_s has {t.shape[0]}")
        check_increasing(t, "Attitude.time_s")
        norm = np.linalg.norm(q, axis=1)
        if np.any(~(np.abs(norm - 1.0) < 1e-3)):
            i = int(np.flatnonzero(~(np.abs(norm - 1.0) < 1e-3))[0])
            raise fail("Attitude.quaternion", f"sample {i} is not a unit quaternion (norm "
                                               f"{norm[i]!r})")
        if self.frame not in ("ecef", "orbital"):
            raise fail("Attitude.frame", f"must be 'ecef' or 'orbital', got {self.frame!r}")
        unit = q / norm[:, None]
        # sign-align consecutive samples so that slerp takes the short way
        flips = np.concatenate([[1.0], np.sign(np.sum(unit[1:] * unit[:-1], axis=1))])
        flips[flips == 0] = 1.0
        unit = unit * np.cumprod(flips)[:, None]
        object.__setattr__(self, "time_s", t)
        object.__setattr__(self, "quaternion", q)
        object.__setattr__(self, "_unit", unit)

    @property
    def valid_span_s(self) -> tuple[float, float]:
        """``(t_min, t_max)`` where :meth:`matrix` is finite (unbounded for one sample)."""
        t = self.time_s
        if t.size == 1:
            return -np.inf, np.inf
        return float(t[0] - (t[1] - t[0])), float(t[-1] + (t[-1] - t[-2]))

    def quaternion_at(self, t_s: ArrayLike) -> Float64Array:
        """Interpolated unit quaternions (..., 4) at ``t_s`` (slerp; NaN outside the span)."""
        t = np.asarray(t_s, dtype=np.float64)
        shape = t.shape
        t = t.ravel()
        if self.time_s.size == 1:
            q = np.broadcast_to(self._unit[0], (t.size, 4)).copy()
        else:
            i, s, _ = segment(self.time_s, t)
            s = np.clip(s, 0.0, 1.0)  # hold the end values
            q0, q1 = self._unit[i], self._unit[i + 1]
            cos = np.clip(np.sum(q0 * q1, axis=1), -1.0, 1.0)
            theta = np.arccos(cos)
            small = theta < 1e-6
            sin = np.where(small, 1.0, np.sin(theta))
            w0 = np.where(small, 1.0 - s, np.sin((1.0 - s) * theta) / sin)
            w1 = np.where(small, s, np.sin(s * theta) / sin)
            q = w0[:, None] * q0 + w1[:, None] * q1
            q /= np.linalg.norm(q, axis=1, keepdims=True)
        lo, hi = self.valid_span_s
        q[~((t >= lo) & (t <= hi))] = np.nan
        return q.reshape(shape + (4,))

    def matrix(self, t_s: ArrayLike) -> Float64Array:
        """Sensor -> ``frame`` rotation matrices (..., 3, 3) at ``t_s`` (slerp between samples).

        Held constant up to one sample interval beyond the ends, NaN farther.
        """
        return quaternion_to_matrix(self.quaternion_at(t_s))

    def to_dict(self) -> dict[str, Any]:
        """JSON-safe dictionary."""
        return {"time_s": self.time_s.tolist(), "quaternion": self.quaternion.tolist(),
                "frame": self.frame}

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> Attitude:
        """Inverse of :meth:`to_dict`."""
        return cls(data["time_s"], data["quaternion"], data.get("frame", "ecef"))
