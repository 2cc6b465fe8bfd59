"""Light-path corrections of the linescan model: velocity aberration, light time, refraction.

A line of sight computed from the attitude and the detector's look direction is the
*apparent* direction of the incoming light in the sensor's (moving) frame. The straight line
from the sensor to the ground point it sees, in the Earth-fixed frame, differs from it by:

``"aberration"``
    The sensor moves at the inertial velocity ``V_i = V + omega x P`` (``V`` the Earth-fixed
    velocity of the ephemeris): light arriving from the true direction ``u`` is seen from
    ``u + V_i,perp / c`` (first order in ``V/c``, exact to ~1e-9 rad). About
    ``|V_i| / c ~ 2.5e-5`` rad for a low orbit: 12-20 m on the ground, 20-40 pixels of a
    0.5 m sensor, mostly along track.
``"light-time"``
    The light left the ground ``D / c`` earlier (``D`` the slant range), while the Earth
    turned: in the inertial frame the source sat at ``G - omega x G D/c``. Together with the
    aberration term it gives the apparent-direction shift ``(V - D omega x u)_perp / c``
    (``omega x P`` cancels). About ``|omega x G| / c ~ 1.5e-6`` rad: 1 m, 1-2 pixels.
``"refraction"``
    The atmosphere bends the ray towards the vertical near the ground; seen from the sensor
    the ground point is shifted away from nadir by ``K tan(z)`` (``z`` the ray's zenith
    angle at the ground, ``K`` Saastamoinen's 1972 coefficient for the sensor's and the
    ground's heights, :func:`refraction_coefficient`). About 1-3e-6 rad at 20-35 degrees off
    nadir: 0.5-2 m, and it changes with the ground height (by ~12 % per km).

The corrections follow the Ames Stereo Pipeline's DigitalGlobe model
(``vw/Camera/OrbitalCorrections.cc``) with two differences, each measured against the vendor
RPBs of five WorldView products: they are applied per ray and at each point's own height
(ASP rotates the attitude once per sample, at the centre column and the scene's mean height:
up to 0.3 pixel off at the swath edges and the ends of the height range), and the refraction
angle grows with ``tan`` of the zenith angle at the ground, not of the off-nadir angle at
the sensor as in ASP (8-19 % larger at these views; the fitted scale of the refraction
against the RPBs is then 0.99-1.05 instead of 1.08-1.19, and the constant 0.15-0.3 pixel
offsets left by ``tan(alpha)`` vanish).

Frames and units: ECEF (EPSG:4978) metres and metres per second; unit direction vectors;
heights metres above the WGS84 ellipsoid.
"""

from __future__ import annotations

from collections.abc import Iterable

import numpy as np

from geoblock import coords
from geoblock.models.linescan._checks import fail

__all__ = [
    "CORRECTIONS",
    "EARTH_ROTATION_RAD_S",
    "SPEED_OF_LIGHT_M_S",
    "apparent_direction",
    "check_corrections",
    "geometric_direction",
    "refraction_coefficient",
]

#: the light-path corrections a :class:`~geoblock.models.linescan.LinescanModel` can apply
CORRECTIONS: tuple[str, ...] = ("aberration", "light-time", "refraction")
#: the Earth's rotation rate (WGS84), radians per second
EARTH_ROTATION_RAD_S = 7.292115e-5
#: metres per second
SPEED_OF_LIGHT_M_S = 299_792_458.0


def check_corrections(value: Iterable[str] | None, where: str) -> tuple[str, ...]:
    """``value`` as a tuple in :data:`CORRECTIONS` order; a ModelFormatError naming ``where``
    for a name that is not one of them or for a string (a common slip for a one-name list)."""
    if value is None:
        return ()
    if isinstance(value, (str, bytes)):
        raise fail(where, f"must be a list of correction names, got the string {value!r}")
    try:
        names = list(value)
    except TypeError:
        raise fail(where, f"must be a list of correction names, got {value!r}") from None
    unknown = [n for n in names if n not in CORRECTIONS]
    if unknown:
        raise fail(where, f"unknown correction(s) {unknown}; known: {list(CORRECTIONS)}")
    return tuple(n for n in CORRECTIONS if n in names)


def refraction_coefficient(sensor_height_m: np.ndarray, ground_height_m: np.ndarray
                           ) -> np.ndarray:
    """Saastamoinen's refraction coefficient ``K`` (radians per unit ``tan(alpha)``).

    ``K = (2335 / (H - h) (1 - 0.02257 h)^5.256 - 0.8540^(H - 11) (82.2 - 521 / (H - h)))
    1e-6`` with ``H``, ``h`` the sensor's and the ground's heights in km (Saastamoinen 1972;
    as in the Ames Stereo Pipeline). ~3e-6 for a 500-700 km orbit over sea-level ground.
    """
    big_h = np.asarray(sensor_height_m, np.float64) / 1000.0
    small_h = np.asarray(ground_height_m, np.float64) / 1000.0
    diff = big_h - small_h
    with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
        p1 = (2335.0 / diff) * np.power(np.maximum(1.0 - 0.02257 * small_h, 0.0), 5.256)
        p2 = np.power(0.8540, big_h - 11.0) * (82.2 - 521.0 / diff)
    return np.where(np.isfinite(p2), p1 - p2, p1) * 1e-6


def _unit(v: np.ndarray) -> np.ndarray:
    with np.errstate(invalid="ignore", divide="ignore"):
        return v / np.linalg.norm(v, axis=-1, keepdims=True)


def _shift(position_m: np.ndarray, velocity_m_s: np.ndarray, u: np.ndarray,
           range_m: np.ndarray, corrections: tuple[str, ...]) -> np.ndarray:
    """The apparent-minus-geometric direction shift (N, 3) of aberration and light time."""
    w = np.zeros_like(u)
    omega = np.array([0.0, 0.0, EARTH_ROTATION_RAD_S])
    if "aberration" in corrections:
        w += velocity_m_s + np.cross(omega, position_m)
    if "light-time" in corrections:
        w -= np.cross(omega, position_m + range_m[:, None] * u)
    w -= np.sum(w * u, axis=-1, keepdims=True) * u
    return w / SPEED_OF_LIGHT_M_S


def _refraction(position_m: np.ndarray, u: np.ndarray, sensor_height_m: np.ndarray,
                ground_height_m: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Refraction angle (N,) and the unit vector (N, 3) towards nadir, perpendicular to u.

    The angle is ``K tan(z)``, ``z`` the ray's zenith angle at the ground (on the sphere of
    radius ``R + h`` below the sensor: ``sin z = |P| sin(alpha) / (R + h)``, ``alpha`` the
    off-nadir angle at the sensor).
    """
    nadir = -_unit(position_m)
    cos_alpha = np.clip(np.sum(nadir * u, axis=-1), -1.0, 1.0)
    towards = _unit(nadir - cos_alpha[:, None] * u)
    sin_alpha = np.sqrt(np.maximum(1.0 - cos_alpha**2, 0.0))
    radius, surface = _ellipsoid_radius(position_m)
    sin_z = np.clip(radius * sin_alpha / (surface + ground_height_m), 0.0, 1.0)
    with np.errstate(invalid="ignore", divide="ignore"):
        tan_z = sin_z / np.sqrt(1.0 - sin_z**2)
    angle = refraction_coefficient(sensor_height_m, ground_height_m) * tan_z
    return np.where(np.isfinite(angle), angle, 0.0), np.nan_to_num(towards)


def _ellipsoid_radius(position_m: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``|P|`` and the ellipsoid's radius below ``P`` (same geocentric direction), metres."""
    radius = np.linalg.norm(position_m, axis=-1)
    with np.errstate(invalid="ignore", divide="ignore"):
        sin2 = (position_m[:, 2] / radius) ** 2
    a, b = coords.WGS84_A, coords.WGS84_B
    return radius, a * b / np.sqrt(b * b * (1.0 - sin2) + a * a * sin2)


def _sensor_height(position_m: np.ndarray) -> np.ndarray:
    """The sensor's height above the ellipsoid along the geocentric vertical (within ~0.2 %
    of the geodetic height at orbital altitudes: K changes by less than 1e-3 relative)."""
    radius, surface = _ellipsoid_radius(position_m)
    return radius - surface


def geometric_direction(u_apparent: np.ndarray, position_m: np.ndarray,
                        velocity_m_s: np.ndarray, h: np.ndarray,
                        corrections: tuple[str, ...]) -> np.ndarray:
    """The straight line (ECEF) to the ground point that a line of sight sees (image -> ground).

    Parameters
    ----------
    u_apparent : ndarray, (N, 3)
        Unit lines of sight from the attitude and the look directions, ECEF.
    position_m, velocity_m_s : ndarray, (N, 3)
        The sensor's ECEF position and Earth-fixed velocity.
    h : ndarray, (N,)
        The ground heights the rays are intersected with, metres above the ellipsoid (the
        refraction's ground height; the light time's range to the surface of that height).
    corrections : tuple of str
        Names from :data:`CORRECTIONS`.

    Returns
    -------
    ndarray, (N, 3)
        Unit directions, ECEF.
    """
    u = u_apparent
    if "refraction" in corrections:
        angle, towards = _refraction(position_m, u, _sensor_height(position_m), h)
        u = np.cos(angle)[:, None] * u + np.sin(angle)[:, None] * towards
    if "aberration" in corrections or "light-time" in corrections:
        # the slant range to the sphere through the surface of height h below the sensor
        # (1 % of range error moves the light-time term by ~1e-8 rad)
        radius, surface = _ellipsoid_radius(position_m)
        surface = surface + h
        pu = np.sum(position_m * u, axis=-1)
        with np.errstate(invalid="ignore"):
            rng = -pu - np.sqrt(np.maximum(pu**2 - radius**2 + surface**2, 0.0))
        u = u - _shift(position_m, velocity_m_s, u, rng, corrections)
    return _unit(u)


def apparent_direction(u_geometric: np.ndarray, position_m: np.ndarray,
                       velocity_m_s: np.ndarray, h: np.ndarray,
                       corrections: tuple[str, ...]) -> np.ndarray:
    """The line of sight under which a ground point is seen (ground -> image): the inverse of
    :func:`geometric_direction`, to ~1e-15 rad.

    Two fixed-point steps ``u <- u + (u_geometric - geometric_direction(u))``: each shrinks
    the error by the size of the corrections (~2.5e-5), so that project and backproject
    invert each other to float64 precision.

    Parameters
    ----------
    u_geometric : ndarray, (N, 3)
        Unit directions from the sensor to the ground points, ECEF.
    position_m, velocity_m_s : ndarray, (N, 3)
        The sensor's ECEF position and Earth-fixed velocity.
    h : ndarray, (N,)
        The ground points' heights, metres above the ellipsoid.
    corrections : tuple of str
        Names from :data:`CORRECTIONS`.

    Returns
    -------
    ndarray, (N, 3)
        Unit lines of sight, ECEF.
    """
    u = u_geometric
    for _ in range(2):
        u = _unit(u + (u_geometric - geometric_direction(u, position_m, velocity_m_s, h,
                                                         corrections)))
    return u
