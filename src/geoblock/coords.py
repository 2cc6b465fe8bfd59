"""Geodetic, ECEF and local ENU work frames on WGS84, their Jacobians, and map-CRS helpers.

All functions are vectorised: coordinate arguments broadcast together and results are float64
arrays of the broadcast shape ``S``. Longitudes and latitudes are degrees, heights metres
above the WGS84 ellipsoid (EPSG:4979), ECEF ``x, y, z`` metres (EPSG:4978), local
east/north/up ``e, n, u`` metres in a tangent-plane frame.

The conversions are closed form (no pyproj call per point) and agree with PROJ to well below a
micrometre; pyproj is used for map projections (:func:`utm_crs`, :func:`transformer`).
"""

from __future__ import annotations

import functools
import math
import threading
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
import pyproj

from geoblock._array import broadcast_float64
from geoblock.errors import CoordinateError
from geoblock.typing import ArrayLike, EcefCoords, Float64Array, GroundCoords, Status

__all__ = [
    "WGS84_A",
    "WGS84_B",
    "WGS84_E2",
    "WGS84_F",
    "LocalFrame",
    "ecef_to_geodetic",
    "ecef_to_geodetic_jacobian",
    "enu_offsets",
    "enu_rotation",
    "enu_to_ecef_jacobian",
    "geodetic_to_ecef",
    "geodetic_to_ecef_jacobian",
    "intersect_height",
    "transformer",
    "utm_crs",
]

WGS84_A = 6378137.0
"""WGS84 semi-major axis, metres."""
WGS84_F = 1.0 / 298.257223563
"""WGS84 flattening."""
WGS84_B = WGS84_A * (1.0 - WGS84_F)
"""WGS84 semi-minor axis, metres."""
WGS84_E2 = WGS84_F * (2.0 - WGS84_F)
"""WGS84 first eccentricity squared."""


def geodetic_to_ecef(lon: ArrayLike, lat: ArrayLike, h: ArrayLike) -> EcefCoords:
    """Convert geodetic WGS84 coordinates to ECEF.

    Parameters
    ----------
    lon, lat : array_like, (*S,)
        Longitude and latitude, degrees.
    h : array_like, (*S,)
        Height above the WGS84 ellipsoid, metres.

    Returns
    -------
    EcefCoords
        ``x, y, z`` in metres, each of shape ``S``.

    Examples
    --------
    >>> x, y, z = geodetic_to_ecef(0.0, 0.0, 0.0)
    >>> float(x), float(y), float(z)
    (6378137.0, 0.0, 0.0)
    """
    lon, lat, h = broadcast_float64(lon=lon, lat=lat, h=h)
    lam = np.radians(lon)
    phi = np.radians(lat)
    with np.errstate(invalid="ignore"):  # non-finite in, NaN out
        sin_phi = np.sin(phi)
        cos_phi = np.cos(phi)
        n = WGS84_A / np.sqrt(1.0 - WGS84_E2 * sin_phi**2)
        x = (n + h) * cos_phi * np.cos(lam)
        y = (n + h) * cos_phi * np.sin(lam)
        z = (n * (1.0 - WGS84_E2) + h) * sin_phi
    return EcefCoords(*_nan_where_invalid((lon, lat, h), (x, y, z)))


def ecef_to_geodetic(x: ArrayLike, y: ArrayLike, z: ArrayLike) -> GroundCoords:
    """Convert ECEF coordinates to geodetic WGS84 coordinates.

    Vermeille's closed-form solution (J. Geodesy 78, 2004), exact for every point farther than
    about 43 km from the Earth's centre (all terrestrial and orbital points).

    Parameters
    ----------
    x, y, z : array_like, (*S,)
        ECEF coordinates, metres.

    Returns
    -------
    GroundCoords
        ``lon, lat`` in degrees and ``h`` in metres above the ellipsoid, each of shape ``S``.
    """
    x, y, z = broadcast_float64(x=x, y=y, z=z)
    e2 = WGS84_E2
    e4 = e2 * e2
    a2 = WGS84_A * WGS84_A
    rho2 = x * x + y * y
    p = rho2 / a2
    q = (1.0 - e2) * z * z / a2
    r = (p + q - e4) / 6.0
    with np.errstate(invalid="ignore", divide="ignore"):
        s = e4 * p * q / (4.0 * r**3)
        t = np.cbrt(1.0 + s + np.sqrt(s * (2.0 + s)))
        u = r * (1.0 + t + 1.0 / t)
        v = np.sqrt(u * u + e4 * q)
        w = e2 * (u + v - q) / (2.0 * v)
        k = np.sqrt(u + v + w * w) - w
        rho = np.sqrt(rho2)
        d = k * rho / (k + e2)
        dz = np.sqrt(d * d + z * z)
        lat = np.degrees(2.0 * np.arctan2(z, d + dz))
        h = (k + e2 - 1.0) / k * dz
    lon = np.degrees(np.arctan2(y, x))
    return GroundCoords(*_nan_where_invalid((x, y, z), (lon, lat, h)))


def _nan_where_invalid(
    inputs: tuple[np.ndarray, np.ndarray, np.ndarray],
    outputs: tuple[np.ndarray, np.ndarray, np.ndarray],
) -> tuple[Float64Array, Float64Array, Float64Array]:
    """NaN in, NaN out: every output is NaN where any input is not finite."""
    bad = ~(np.isfinite(inputs[0]) & np.isfinite(inputs[1]) & np.isfinite(inputs[2]))
    a, b, c = (np.where(bad, np.nan, o) for o in outputs)
    return a, b, c


def enu_rotation(lon: ArrayLike, lat: ArrayLike) -> Float64Array:
    """Rotation from ECEF to the local east/north/up frame at ``(lon, lat)``.

    Parameters
    ----------
    lon, lat : array_like, (*S,)
        Degrees.

    Returns
    -------
    ndarray, (*S, 3, 3)
        Rows are the unit east, north and up vectors in ECEF; ``enu = R @ (xyz - xyz0)``.
        It is also the Jacobian d(e, n, u)/d(x, y, z).
    """
    lon, lat = broadcast_float64(lon=lon, lat=lat)
    lam = np.radians(lon)
    phi = np.radians(lat)
    with np.errstate(invalid="ignore"):  # non-finite in, NaN out
        sl, cl = np.sin(lam), np.cos(lam)
        sp, cp = np.sin(phi), np.cos(phi)
    zero = np.zeros_like(sl)
    rows = [
        [-sl, cl, zero],
        [-sp * cl, -sp * sl, cp],
        [cp * cl, cp * sl, sp],
    ]
    return np.stack([np.stack(r, axis=-1) for r in rows], axis=-2)


def enu_offsets(
    lon_ref: ArrayLike,
    lat_ref: ArrayLike,
    h_ref: ArrayLike,
    lon: ArrayLike,
    lat: ArrayLike,
    h: ArrayLike,
) -> tuple[Float64Array, Float64Array, Float64Array]:
    """East, north and up offsets of points from reference points, in each reference's frame.

    Parameters
    ----------
    lon_ref, lat_ref, h_ref : array_like, (*S,)
        Reference points (degrees, metres above the ellipsoid), e.g. surveyed check points.
    lon, lat, h : array_like, (*S,)
        The points to compare, e.g. the same points located through a sensor model.

    Returns
    -------
    tuple of ndarray, (*S,) each
        ``(de, dn, du)``: point minus reference, metres along the reference's local east,
        north and up.
    """
    ref = np.stack(geodetic_to_ecef(lon_ref, lat_ref, h_ref), axis=-1)
    pts = np.stack(geodetic_to_ecef(lon, lat, h), axis=-1)
    rot = enu_rotation(lon_ref, lat_ref)
    d = np.einsum("...ij,...j->...i", rot, pts - ref)
    return d[..., 0], d[..., 1], d[..., 2]


def enu_to_ecef_jacobian(lon: ArrayLike, lat: ArrayLike) -> Float64Array:
    """d(x, y, z)/d(e, n, u) at ``(lon, lat)``: the transpose of :func:`enu_rotation`,
    (*S, 3, 3)."""
    return np.swapaxes(enu_rotation(lon, lat), -1, -2)


def geodetic_to_ecef_jacobian(lon: ArrayLike, lat: ArrayLike, h: ArrayLike) -> Float64Array:
    """d(x, y, z)/d(lon, lat, h) of :func:`geodetic_to_ecef`.

    Parameters
    ----------
    lon, lat : array_like, (*S,)
        Degrees.
    h : array_like, (*S,)
        Metres above the ellipsoid.

    Returns
    -------
    ndarray, (*S, 3, 3)
        Columns: metres per degree of longitude, metres per degree of latitude, metres per
        metre of height.
    """
    lon, lat, h = broadcast_float64(lon=lon, lat=lat, h=h)
    lam = np.radians(lon)
    phi = np.radians(lat)
    with np.errstate(invalid="ignore"):  # non-finite in, NaN out
        sl, cl = np.sin(lam), np.cos(lam)
        sp, cp = np.sin(phi), np.cos(phi)
    w2 = 1.0 - WGS84_E2 * sp * sp
    n = WGS84_A / np.sqrt(w2)
    m = WGS84_A * (1.0 - WGS84_E2) / w2**1.5  # meridian radius of curvature
    deg = np.pi / 180.0
    d_lon = np.stack([-(n + h) * cp * sl, (n + h) * cp * cl, np.zeros_like(sl)], axis=-1) * deg
    d_lat = np.stack([-(m + h) * sp * cl, -(m + h) * sp * sl, (m + h) * cp], axis=-1) * deg
    d_h = np.stack([cp * cl, cp * sl, sp], axis=-1)
    return np.stack([d_lon, d_lat, d_h], axis=-1)


def ecef_to_geodetic_jacobian(lon: ArrayLike, lat: ArrayLike, h: ArrayLike) -> Float64Array:
    """d(lon, lat, h)/d(x, y, z) at a geodetic point: the inverse of
    :func:`geodetic_to_ecef_jacobian`.

    Returns
    -------
    ndarray, (*S, 3, 3)
        Rows: degrees of longitude per metre, degrees of latitude per metre, metres of height
        per metre, against ECEF x, y, z.
    """
    lon, lat, h = broadcast_float64(lon=lon, lat=lat, h=h)
    rot = enu_rotation(lon, lat)  # rows: east, north, up unit vectors
    phi = np.radians(lat)
    with np.errstate(invalid="ignore", divide="ignore"):
        sp, cp = np.sin(phi), np.cos(phi)
        w2 = 1.0 - WGS84_E2 * sp * sp
        n = WGS84_A / np.sqrt(w2)
        m = WGS84_A * (1.0 - WGS84_E2) / w2**1.5
        deg = 180.0 / np.pi
        scale = np.stack([deg / ((n + h) * cp), deg / (m + h), np.ones_like(h)], axis=-1)
    return rot * scale[..., :, None]


@dataclass(frozen=True)
class LocalFrame:
    """A local tangent-plane work frame at a chosen origin: east/north/up, or turned by an
    azimuth.

    This is the "work coordinate system" of Teo et al. (2010): a local Cartesian frame whose
    origin is usually the centroid of the control points, in which Earth curvature does not
    enter the collinearity equations. Its third axis ``Z`` is the ellipsoid normal (up) at the
    origin; its first axis ``X`` the horizontal direction at ``azimuth_deg`` (clockwise from
    north), and ``Y = Z x X`` (to the left of ``X``). The default ``azimuth_deg = 90`` gives
    plain east/north/up ``(e, n, u)``; the ground-track heading gives ``X`` along track, the
    LVLH-like axes of Teo et al. and of Chen & Lee's SPOT model.

    Parameters
    ----------
    lon0, lat0 : float
        Origin, degrees.
    h0 : float
        Origin height above the ellipsoid, metres.
    azimuth_deg : float
        Direction of ``X``, degrees clockwise from north (default 90: ``X`` east).

    Raises
    ------
    CoordinateError
        A non-finite value, or ``lat0`` outside [-90, 90].

    Examples
    --------
    >>> frame = LocalFrame(7.0, 43.7, 100.0)
    >>> e, n, u = frame.from_geodetic(7.0, 43.7, 110.0)
    >>> round(float(u), 9)
    10.0
    >>> south = LocalFrame(7.0, 43.7, 100.0, azimuth_deg=180.0)  # X south, Y east, Z up
    >>> x, y, z = south.from_geodetic(7.0, 43.69, 100.0)
    >>> round(float(x)), round(float(y))
    (1111, 0)
    """

    lon0: float
    lat0: float
    h0: float = 0.0
    azimuth_deg: float = 90.0

    def __post_init__(self) -> None:
        for name in ("lon0", "lat0", "h0", "azimuth_deg"):
            try:
                value = float(getattr(self, name))
            except (TypeError, ValueError):
                raise CoordinateError(
                    f"LocalFrame: {name} must be a number, got {getattr(self, name)!r}"
                ) from None
            if not np.isfinite(value):
                raise CoordinateError(f"LocalFrame: {name} must be finite, got {value!r}")
            object.__setattr__(self, name, value)
        if not -90.0 <= self.lat0 <= 90.0:
            raise CoordinateError(
                f"LocalFrame: lat0 must be within [-90, 90] degrees, got {self.lat0}"
            )

    @classmethod
    def centred_on(
        cls, lon: ArrayLike, lat: ArrayLike, h: ArrayLike, azimuth_deg: float = 90.0
    ) -> LocalFrame:
        """A frame at the ECEF centroid of the finite points given (e.g. the GCPs), at their
        mean height, with ``X`` at ``azimuth_deg``.

        Raises
        ------
        CoordinateError
            No point is finite.
        """
        lon, lat, h = broadcast_float64(lon=lon, lat=lat, h=h)
        x, y, z = geodetic_to_ecef(lon, lat, h)
        ok = np.isfinite(x) & np.isfinite(y) & np.isfinite(z)
        if not ok.any():
            raise CoordinateError("LocalFrame.centred_on: no finite point given")
        centre = ecef_to_geodetic(x[ok].mean(), y[ok].mean(), z[ok].mean())
        # The ECEF centroid lies below the surface; put the origin at the points' mean height.
        return cls(float(centre.lon), float(centre.lat), float(h[ok].mean()), azimuth_deg)

    @functools.cached_property
    def rotation(self) -> Float64Array:
        """(3, 3) ECEF -> frame rotation: rows are the unit ``X, Y, Z`` axes in ECEF (east,
        north, up at the default azimuth); ``local = R @ (xyz - origin_ecef)``."""
        enu = enu_rotation(self.lon0, self.lat0)
        if self.azimuth_deg == 90.0:  # east/north/up exactly (no cos(90 deg) = 6e-17 terms)
            out = enu
        else:
            a = math.radians(self.azimuth_deg)
            sa, ca = math.sin(a), math.cos(a)
            enu_to_frame = np.array([[sa, ca, 0.0], [-ca, sa, 0.0], [0.0, 0.0, 1.0]])
            out = enu_to_frame @ enu
        out.flags.writeable = False
        return out

    @functools.cached_property
    def origin_ecef(self) -> Float64Array:
        """(3,) ECEF coordinates of the origin, metres."""
        out = np.array(geodetic_to_ecef(self.lon0, self.lat0, self.h0), dtype=np.float64)
        out.flags.writeable = False
        return out

    def from_ecef(self, x: ArrayLike, y: ArrayLike, z: ArrayLike) -> tuple[Float64Array, ...]:
        """ECEF metres -> local ``(X, Y, Z)`` metres (``(e, n, u)`` at azimuth 90), each (*S,)."""
        local = self.from_ecef_xyz(np.stack(broadcast_float64(x=x, y=y, z=z), axis=-1))
        return local[..., 0], local[..., 1], local[..., 2]

    def to_ecef(self, e: ArrayLike, n: ArrayLike, u: ArrayLike) -> EcefCoords:
        """Local ``(X, Y, Z)`` metres (``(e, n, u)`` at azimuth 90) -> ECEF metres."""
        xyz = self.to_ecef_xyz(np.stack(broadcast_float64(e=e, n=n, u=u), axis=-1))
        return EcefCoords(xyz[..., 0], xyz[..., 1], xyz[..., 2])

    def from_ecef_xyz(self, xyz: ArrayLike) -> Float64Array:
        """ECEF points stacked on the last axis, (*S, 3) metres -> local (*S, 3) metres."""
        return (np.asarray(xyz, dtype=np.float64) - self.origin_ecef) @ self.rotation.T

    def to_ecef_xyz(self, local: ArrayLike) -> Float64Array:
        """Local points stacked on the last axis, (*S, 3) metres -> ECEF (*S, 3) metres."""
        return np.asarray(local, dtype=np.float64) @ self.rotation + self.origin_ecef

    def from_geodetic(
        self, lon: ArrayLike, lat: ArrayLike, h: ArrayLike
    ) -> tuple[Float64Array, ...]:
        """Geodetic ``(lon, lat, h)`` -> local ``(X, Y, Z)`` metres, each (*S,)."""
        return self.from_ecef(*geodetic_to_ecef(lon, lat, h))

    def to_geodetic(self, e: ArrayLike, n: ArrayLike, u: ArrayLike) -> GroundCoords:
        """Local ``(X, Y, Z)`` metres -> geodetic ``(lon, lat, h)``."""
        return ecef_to_geodetic(*self.to_ecef(e, n, u))

    def to_dict(self) -> dict[str, float]:
        """JSON-safe ``{"lon0", "lat0", "h0", "azimuth_deg"}``."""
        return {"lon0": self.lon0, "lat0": self.lat0, "h0": self.h0,
                "azimuth_deg": self.azimuth_deg}

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> LocalFrame:
        """Inverse of :meth:`to_dict` (``h0`` and ``azimuth_deg`` optional).

        Raises
        ------
        CoordinateError
            A key is missing or unknown, or a value is invalid.
        """
        unknown = sorted(set(data) - {"lon0", "lat0", "h0", "azimuth_deg"})
        if unknown or "lon0" not in data or "lat0" not in data:
            raise CoordinateError(
                f"LocalFrame: a frame is {{lon0, lat0[, h0][, azimuth_deg]}}, got keys "
                f"{sorted(data)}"
            )
        return cls(**data)


def utm_crs(lon: ArrayLike, lat: ArrayLike) -> pyproj.CRS:
    """The WGS84 / UTM CRS of the zone holding the centre of the given points.

    The centre is the midpoint of the finite points' longitude range (unwrapped across the
    antimeridian) and latitude range; Norway's and Svalbard's zone exceptions are applied.

    Parameters
    ----------
    lon, lat : array_like
        Degrees; for example the corners of an image footprint.

    Returns
    -------
    pyproj.CRS
        ``EPSG:326zz`` (north) or ``EPSG:327zz`` (south).
    """
    lon, lat = broadcast_float64(lon=lon, lat=lat)
    ok = np.isfinite(lon) & np.isfinite(lat)
    if not ok.any():
        raise CoordinateError("utm_crs: no finite point given")
    lon_ok = np.unwrap(np.radians(lon[ok].ravel()))
    lon_c = (np.degrees((lon_ok.min() + lon_ok.max()) / 2.0) + 180.0) % 360.0 - 180.0
    lat_c = float((lat[ok].min() + lat[ok].max()) / 2.0)
    if not -80.0 <= lat_c <= 84.0:
        raise CoordinateError(
            f"utm_crs: latitude {lat_c:.3f} is outside UTM's range [-80, 84]"
        )
    zone = int((lon_c + 180.0) // 6.0) % 60 + 1
    if 56.0 <= lat_c < 64.0 and 3.0 <= lon_c < 12.0:
        zone = 32
    elif 72.0 <= lat_c < 84.0 and 0.0 <= lon_c < 42.0:
        zone = 31 if lon_c < 9.0 else 33 if lon_c < 21.0 else 35 if lon_c < 33.0 else 37
    return pyproj.CRS.from_epsg((32600 if lat_c >= 0 else 32700) + zone)


_local = threading.local()


def transformer(src: pyproj.CRS | str | int, dst: pyproj.CRS | str | int) -> pyproj.Transformer:
    """A cached, thread-local ``pyproj.Transformer`` from ``src`` to ``dst`` with ``always_xy``.

    pyproj transformers are not thread-safe; each thread (and each dask worker thread) gets
    its own.
    """
    cache = getattr(_local, "cache", None)
    if cache is None:
        cache = _local.cache = {}
    key = (pyproj.CRS.from_user_input(src).to_wkt(), pyproj.CRS.from_user_input(dst).to_wkt())
    found = cache.get(key)
    if found is None:
        found = cache[key] = pyproj.Transformer.from_crs(src, dst, always_xy=True)
    return found


def intersect_height(
    origin: np.ndarray,
    direction: np.ndarray,
    h: np.ndarray,
    tolerance_m: float = 1e-7,
    max_iterations: int = 10,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Intersect rays with the surfaces of given geodetic heights: a line of sight's ground
    point at ``h`` (every pushbroom model's image -> ground).

    Start: the nearer root on the ellipsoid of semi-axes ``(a + h, b + h)``; then Newton on
    the ray parameter ``s`` with ``dh/ds = up . direction`` until the geodetic height misses
    ``h`` by at most ``tolerance_m``.

    Parameters
    ----------
    origin : ndarray, (N, 3)
        Ray origins, ECEF metres (a sensor above the surface).
    direction : ndarray, (N, 3)
        Unit ray directions, ECEF.
    h : ndarray, (N,)
        Heights above the WGS84 ellipsoid, metres.
    tolerance_m : float
        Height tolerance, metres.
    max_iterations : int
        Newton iteration cap.

    Returns
    -------
    lon, lat : ndarray, (N,)
        Degrees; NaN where not converged.
    s : ndarray, (N,)
        Ray parameter of the ground point (``origin + s direction``), metres.
    status : ndarray, (N,) uint8
        ``CONVERGED``; ``NO_INTERSECTION`` for rays that miss the surface or leave it upwards;
        ``MAX_ITERATIONS``.
    """
    origin = np.asarray(origin, dtype=np.float64)
    direction = np.asarray(direction, dtype=np.float64)
    h = np.asarray(h, dtype=np.float64)
    n = h.shape[0]
    status = np.full(n, np.uint8(Status.NO_INTERSECTION), dtype=np.uint8)
    lon = np.full(n, np.nan)
    lat = np.full(n, np.nan)
    ax = WGS84_A + h
    bz = WGS84_B + h
    with np.errstate(invalid="ignore", divide="ignore"):
        scale = np.stack([ax, ax, bz], axis=-1)
        pa = origin / scale
        ua = direction / scale
        qa = np.sum(ua * ua, axis=1)
        qb = np.sum(pa * ua, axis=1)  # half the linear coefficient
        qc = np.sum(pa * pa, axis=1) - 1.0
        disc = qb * qb - qa * qc
        s = qc / (-qb + np.sqrt(disc))  # the nearer root, stable form (qb < 0, qc > 0)
    todo = np.flatnonzero(np.isfinite(s) & (s > 0) & (qc > 0))
    for _ in range(max_iterations):
        if todo.size == 0:
            break
        p = origin[todo] + s[todo, None] * direction[todo]
        g = ecef_to_geodetic(p[:, 0], p[:, 1], p[:, 2])
        lon[todo], lat[todo] = g.lon, g.lat
        miss = g.h - h[todo]
        cl = np.cos(np.radians(g.lat))
        up = np.stack([cl * np.cos(np.radians(g.lon)), cl * np.sin(np.radians(g.lon)),
                       np.sin(np.radians(g.lat))], axis=-1)
        rate = np.sum(up * direction[todo], axis=1)
        done = np.abs(miss) <= tolerance_m
        bad = ~(rate < 0) | ~np.isfinite(miss)
        status[todo[done & ~bad]] = Status.CONVERGED
        with np.errstate(invalid="ignore", divide="ignore"):
            s[todo] -= miss / rate
        todo = todo[~done & ~bad]
    status[todo] = Status.MAX_ITERATIONS
    failed = status != Status.CONVERGED
    lon[failed] = np.nan
    lat[failed] = np.nan
    return lon, lat, s, status
