"""Satellite ephemeris of the linescan model: time-tagged ECEF states, Hermite-interpolated."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from geoblock.models.linescan._checks import check_increasing, fail, sample_array, segment
from geoblock.typing import ArrayLike, Float64Array

__all__ = ["MAX_SPEED_M_S", "ORBIT_RADIUS_M", "Ephemeris"]

#: distances of a platform from the Earth's centre accepted in an ephemeris, metres (from
#: below the surface's highest point plus a low airborne platform to beyond geostationary)
ORBIT_RADIUS_M = (6.35e6, 5.0e7)
#: largest platform speed accepted in an ephemeris, metres per second (low orbits ~7.6 km/s)
MAX_SPEED_M_S = 2.0e4


@dataclass(frozen=True, eq=False)
class Ephemeris:
    """Time-tagged satellite positions and velocities (ECEF), Hermite-interpolated.

    Parameters
    ----------
    time_s : array_like, (n,)
        Strictly increasing, seconds since the model's epoch; n >= 2.
    position_m : array_like, (n, 3)
        ECEF positions, metres.
    velocity_m_s : array_like, (n, 3)
        ECEF (Earth-fixed) velocities, metres per second.
    """

    time_s: np.ndarray
    position_m: np.ndarray
    velocity_m_s: np.ndarray
    _coefficients: np.ndarray = field(init=False, repr=False)
    _inv_width: np.ndarray = field(init=False, repr=False)

    def __post_init__(self) -> None:
        t = sample_array(self.time_s, "Ephemeris.time_s", (), 2)
        n = t.shape[0]
        p = sample_array(self.position_m, "Ephemeris.position_m", (3,), 2)
        v = sample_array(self.velocity_m_s, "Ephemeris.velocity_m_s", (3,), 2)
        for name, a in (("position_m", p), ("velocity_m_s", v)):
            if a.shape[0] != n:
                raise fail(f"Ephemeris.{name}", f"has {a.shape[0]} samples, time_s has {n}")
        check_increasing(t, "Ephemeris.time_s")
        radius = np.linalg.norm(p, axis=1)
        bad = ~((radius >= ORBIT_RADIUS_M[0]) & (radius <= ORBIT_RADIUS_M[1]))
        if bad.any():
            i = int(np.flatnonzero(bad)[0])
            raise fail("Ephemeris.position_m",
                        f"sample {i} is {radius[i]:.6g} m from the Earth's centre: not an orbit "
                        f"(expected {ORBIT_RADIUS_M[0]:g} to {ORBIT_RADIUS_M[1]:g} m)")
        speed = np.linalg.norm(v, axis=1)
        bad = ~(speed <= MAX_SPEED_M_S)
        if bad.any():
            i = int(np.flatnonzero(bad)[0])
            raise fail("Ephemeris.velocity_m_s",
                        f"sample {i} has a speed of {speed[i]:.6g} m/s (more than "
                        f"{MAX_SPEED_M_S:g} m/s: not an Earth-orbiting platform)")
        object.__setattr__(self, "time_s", t)
        object.__setattr__(self, "position_m", p)
        object.__setattr__(self, "velocity_m_s", v)
        # Hermite polynomial of each interval in s = (t - t_i) / h: P = c0 + c1 s + c2 s^2 + c3 s^3
        h = np.diff(t)[:, None]
        p0, p1, v0, v1 = p[:-1], p[1:], v[:-1] * h, v[1:] * h
        coefficients = np.stack(
            [p0, v0, 3.0 * (p1 - p0) - 2.0 * v0 - v1, 2.0 * (p0 - p1) + v0 + v1], axis=1)
        object.__setattr__(self, "_coefficients", coefficients)
        object.__setattr__(self, "_inv_width", 1.0 / h[:, 0])

    @property
    def valid_span_s(self) -> tuple[float, float]:
        """``(t_min, t_max)``: where :meth:`at` is finite (the samples plus one interval)."""
        t = self.time_s
        return float(t[0] - (t[1] - t[0])), float(t[-1] + (t[-1] - t[-2]))

    def at(self, t_s: ArrayLike) -> tuple[Float64Array, Float64Array]:
        """Position and velocity at times ``t_s`` by cubic Hermite interpolation.

        Parameters
        ----------
        t_s : array_like, (...)
            Seconds since the epoch.

        Returns
        -------
        position_m, velocity_m_s : ndarray, (..., 3)
            ECEF. Exact at the samples, C1 between them; extrapolated by the end
            polynomials up to one sample interval beyond the ends, NaN farther.
        """
        t = np.asarray(t_s, dtype=np.float64)
        shape = t.shape
        t = t.ravel()
        i, s, _ = segment(self.time_s, t)
        c = self._coefficients[i]  # (N, 4, 3)
        s_ = s[:, None]
        pos = c[:, 0] + s_ * (c[:, 1] + s_ * (c[:, 2] + s_ * c[:, 3]))
        vel = (c[:, 1] + s_ * (2.0 * c[:, 2] + 3.0 * s_ * c[:, 3])) * self._inv_width[i, None]
        lo, hi = self.valid_span_s
        bad = ~((t >= lo) & (t <= hi))
        pos[bad] = np.nan
        vel[bad] = np.nan
        return pos.reshape(shape + (3,)), vel.reshape(shape + (3,))

    def to_dict(self) -> dict[str, Any]:
        """JSON-safe dictionary."""
        return {"time_s": self.time_s.tolist(), "position_m": self.position_m.tolist(),
                "velocity_m_s": self.velocity_m_s.tolist()}

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> Ephemeris:
        """Inverse of :meth:`to_dict`."""
        return cls(data["time_s"], data["position_m"], data["velocity_m_s"])
