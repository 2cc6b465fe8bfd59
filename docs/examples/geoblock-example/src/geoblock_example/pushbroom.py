"""A pushbroom sensor needs no model class of its own: its reader fills geoblock's linescan
building blocks (:mod:`geoblock.models.linescan`) and returns a ``LinescanModel``.

:func:`linescan_from_metadata` is the part of such a reader that comes after the parsing:
vendor arrays in, model out, every convention converted once. :func:`example_metadata`
makes the arrays of a small made-up scanner so that the function can be tried and tested.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from geoblock import coords
from geoblock.models.linescan import (
    Attitude,
    Ephemeris,
    LinescanModel,
    LineTimes,
    LookDirections,
    matrix_to_quaternion,
    rotation_xyz,
)
from geoblock.typing import ArrayLike

__all__ = ["example_metadata", "linescan_from_metadata"]


# --8<-- [start:linescan]
def linescan_from_metadata(
    shape: tuple[int, int],
    epoch: str,
    ephemeris_time_s: ArrayLike,
    position_m: ArrayLike,
    velocity_m_s: ArrayLike,
    attitude_time_s: ArrayLike,
    roll_pitch_yaw_rad: ArrayLike,
    psi_x_rad: ArrayLike,
    psi_y_rad: ArrayLike,
    line_period_s: float,
) -> LinescanModel:
    """The line-of-sight model of a pushbroom scene from its (parsed) metadata.

    Parameters
    ----------
    shape : (int, int)
        ``(rows, cols)``.
    epoch : str
        ISO-8601 UTC time of row 0; every time below is seconds after it.
    ephemeris_time_s : array_like, (n,)
    position_m, velocity_m_s : array_like, (n, 3)
        ECEF (EPSG:4978) positions and Earth-fixed velocities, metres and m/s.
    attitude_time_s : array_like, (m,)
    roll_pitch_yaw_rad : array_like, (m, 3)
        The sensor's attitude relative to the orbital frame, radians (``Rx Ry Rz``).
    psi_x_rad, psi_y_rad : array_like, (cols,)
        Each detector's look angles along and across track, radians.
    line_period_s : float
        Seconds between rows.
    """
    ephemeris = Ephemeris(ephemeris_time_s, position_m, velocity_m_s)  # Hermite-interpolated
    angles = np.asarray(roll_pitch_yaw_rad, dtype=np.float64)
    quaternions = matrix_to_quaternion(rotation_xyz(angles[:, 0], angles[:, 1], angles[:, 2]))
    attitude = Attitude(attitude_time_s, quaternions, frame="orbital")  # slerp-interpolated
    look = LookDirections.from_tan_angles(np.tan(psi_x_rad), np.tan(psi_y_rad))
    lines = LineTimes(reference_row=0.0, reference_time_s=0.0, line_period_s=line_period_s)
    return LinescanModel(shape, ephemeris, attitude, look, lines, epoch=epoch)
# --8<-- [end:linescan]


def example_metadata(shape: tuple[int, int] = (600, 800)) -> dict[str, Any]:
    """The arguments of :func:`linescan_from_metadata` for a made-up 3 m scanner on a 700 km
    circular orbit over Nice (the Earth's rotation ignored), looking 2 degrees to the side."""
    rows, cols = shape
    radius, gsd = coords.WGS84_A + 700e3, 3.0
    omega = np.sqrt(3.986004418e14 / radius**3)  # rad/s on a circular orbit
    east, north, up = coords.enu_rotation(7.05, 43.70)
    line_period = gsd / (omega * coords.WGS84_A)  # one GSD of ground track per row
    t = np.arange(-5.0, rows * line_period + 6.0, 1.0)  # covers the rows with a margin
    angle = omega * t[:, None]
    position = radius * (np.cos(angle) * up - np.sin(angle) * north)  # flying south
    velocity = radius * omega * (-np.sin(angle) * up - np.cos(angle) * north)
    t_att = np.arange(t[0], t[-1] + 0.5, 0.5)
    attitude = np.zeros((t_att.size, 3))
    attitude[:, 0] = np.radians(2.0) + 1e-5 * np.sin(t_att)  # roll with a little jitter
    c = np.arange(cols) - (cols - 1) / 2.0
    return {
        "shape": shape, "epoch": "2020-06-21T10:30:00Z",
        "ephemeris_time_s": t, "position_m": position, "velocity_m_s": velocity,
        "attitude_time_s": t_att, "roll_pitch_yaw_rad": attitude,
        "psi_x_rad": np.full(cols, 1e-4), "psi_y_rad": np.arctan(c * gsd / 700e3),
        "line_period_s": line_period,
    }
