"""The EGM96 geoid (or any NOAA ``.gtx`` geoid grid) and where to find its file.

Heights leaving the DEM service are ellipsoidal: a DEM whose heights are above the geoid
(SRTM, most national DEMs) gets the geoid undulation ``N(lon, lat)`` added,
``h = H + N``. The undulation is bilinear interpolation between the four surrounding grid
nodes, longitude wrapped around the globe, which reproduces shareloc's
``interpolate_geoid_height`` on ``egm96_15.gtx`` to 1e-6 m.

Where the grid comes from (:func:`find_geoid`), first found wins:

1. the ``geoid=`` argument (a path, or a :class:`Geoid`);
2. the ``GEOBLOCK_GEOID`` environment variable (a path to a ``.gtx`` file);
3. ``egm96_15.gtx`` in pyproj's data directories (``pyproj.datadir.get_data_dir()``, which
   honours ``PROJ_DATA``/``PROJ_LIB``, and ``pyproj.datadir.get_user_data_dir()``);
4. ``egm96_15.gtx`` in the standard PROJ data directories: ``$PROJ_DATA``, ``$PROJ_LIB``,
   ``<sys.prefix>/share/proj``, ``/usr/share/proj`` (Debian/Ubuntu ``apt-get install
   proj-data``), ``/usr/local/share/proj``, ``/opt/homebrew/share/proj``.
"""

from __future__ import annotations

import os
import sys
import threading
from pathlib import Path
from typing import Any

import numpy as np

from geoblock._array import broadcast_float64
from geoblock.dem.base import DemBase
from geoblock.dem.protocol import Bounds
from geoblock.errors import DemError, GeoidNotFoundError
from geoblock.io.rasters import read_gtx
from geoblock.typing import ArrayLike, Float64Array

__all__ = ["API_GEOID_HINT", "EGM96_FILENAME", "ConstantGeoidDem", "Geoid", "find_geoid",
           "geoid_search_path"]

#: How to give the geoid grid in the Python API (front ends give their own spelling:
#: :meth:`geoblock.errors.DemSettingError.with_hint`).
API_GEOID_HINT = "pass geoid='path/to/egm96_15.gtx' or set GEOBLOCK_GEOID"

EGM96_FILENAME = "egm96_15.gtx"
"""File name of the EGM96 15-arc-minute geoid grid (PROJ's name, Debian ``proj-data``)."""

_GTX_NODATA = -88.8888  # NOAA's "no value" marker in .gtx grids

_grids: dict[str, tuple[tuple[float, float, float, float], np.ndarray]] = {}
_grids_lock = threading.Lock()


def _read_gtx(path: str) -> tuple[tuple[float, float, float, float], np.ndarray]:
    """Header ``(lat0, lon0, dlat, dlon)`` and (rows, cols) float64 nodes (south row first),
    read once per process (through :func:`geoblock.io.rasters.read_gtx`) and shared."""
    with _grids_lock:
        found = _grids.get(path)
        if found is not None:
            return found
        header, nodes = read_gtx(path)
        nodes[np.abs(nodes - _GTX_NODATA) < 1e-3] = np.nan
        nodes.flags.writeable = False
        found = _grids[path] = (header, nodes)
        return found


class Geoid:
    """A geoid grid in NOAA ``.gtx`` format: undulation ``N`` (metres of geoid above the WGS84
    ellipsoid) by bilinear interpolation.

    Parameters
    ----------
    path : str or os.PathLike
        The ``.gtx`` file, e.g. ``/usr/share/proj/egm96_15.gtx``. Grids are loaded once per
        process and shared; a ``Geoid`` pickles by path.

    Raises
    ------
    DemError
        The file is missing or is not a ``.gtx`` grid.
    """

    def __init__(self, path: str | os.PathLike[str]) -> None:
        self._path = str(Path(path).expanduser().resolve())
        header, nodes = _read_gtx(self._path)
        self._lat0, self._lon0, self._dlat, self._dlon = header
        self._nodes = nodes
        rows, cols = nodes.shape
        self._global = abs(cols * self._dlon - 360.0) < 1e-9

    @property
    def path(self) -> str:
        """Absolute path of the grid file."""
        return self._path

    @property
    def name(self) -> str:
        """File name of the grid, e.g. ``egm96_15.gtx``."""
        return Path(self._path).name

    def undulation(self, lon: ArrayLike, lat: ArrayLike) -> Float64Array:
        """Geoid undulation at points.

        Parameters
        ----------
        lon, lat : array_like, (*S,)
            Degrees (WGS84); any longitude range (wrapped).

        Returns
        -------
        ndarray, (*S,)
            ``N``, metres of the geoid above the ellipsoid (ellipsoidal = geoid height + N).
            NaN for non-finite input and outside a regional grid.
        """
        lon, lat = broadcast_float64(lon=lon, lat=lat)
        return _undulation_nodes(self._nodes, self.header, lon, lat)

    @property
    def header(self) -> np.ndarray:
        """(5,) ``lat0, lon0, dlat, dlon, global`` (degrees; ``global`` 1.0 when the grid
        wraps around the Earth) of :attr:`nodes`: for compiled kernels."""
        return np.array([self._lat0, self._lon0, self._dlat, self._dlon,
                         1.0 if self._global else 0.0])

    @property
    def nodes(self) -> np.ndarray:
        """(rows, cols) undulations at the grid nodes, metres (NaN for none; read-only),
        row 0 at ``lat0``."""
        return self._nodes

    def undulation_range(self, bounds: Bounds) -> tuple[float, float]:
        """``(min, max)`` of ``N`` over ``(west, south, east, north)`` degrees, metres.

        Taken over the grid nodes inside the box and one node around it (bilinear values lie
        between node values), so it bounds every interpolated value in the box.
        """
        w, s, e, n = (float(v) for v in bounds)
        rows, cols = self._nodes.shape
        i0 = max(int(np.floor((s - self._lat0) / self._dlat)), 0)
        i1 = min(int(np.ceil((n - self._lat0) / self._dlat)), rows - 1)
        j0 = int(np.floor((w - self._lon0) / self._dlon))
        j1 = int(np.ceil((e - self._lon0) / self._dlon))
        if self._global:
            if j1 - j0 >= cols:
                jj = np.arange(cols)
            else:
                jj = np.arange(j0, j1 + 1) % cols
        else:
            jj = np.arange(max(j0, 0), min(j1, cols - 1) + 1)
        block = self._nodes[i0:i1 + 1][:, jj]
        if block.size == 0 or not np.isfinite(block).any():
            return (float("nan"), float("nan"))
        return (float(np.nanmin(block)), float(np.nanmax(block)))

    def to_dict(self) -> dict[str, Any]:
        return {"geoid": "gtx", "path": self._path}

    def __reduce__(self) -> tuple[Any, ...]:
        return (Geoid, (self._path,))

    def __eq__(self, other: object) -> bool:
        return isinstance(other, Geoid) and other._path == self._path

    def __hash__(self) -> int:
        return hash(("Geoid", self._path))

    def __repr__(self) -> str:
        return f"Geoid({self._path!r})"


def _undulation_nodes(nodes: np.ndarray, header: np.ndarray, lon: np.ndarray,
                      lat: np.ndarray) -> np.ndarray:
    """:meth:`Geoid.undulation` from the grid's nodes and :attr:`Geoid.header`."""
    lat0, lon0, dlat, dlon, glob = (float(v) for v in header)
    rows, cols = nodes.shape
    out = np.full(lon.shape, np.nan)
    ok = np.isfinite(lon) & np.isfinite(lat)
    x = (lon[ok] - lon0) / dlon
    y = (lat[ok] - lat0) / dlat
    if glob:
        x = np.mod(x, cols)
    inside = (y >= 0) & (y <= rows - 1)
    if not glob:
        inside &= (x >= 0) & (x <= cols - 1)
    x, y = x[inside], y[inside]
    i0 = np.minimum(np.floor(y).astype(np.intp), rows - 2)
    ty = y - i0
    if glob:
        j0 = np.floor(x).astype(np.intp) % cols
        j1 = (j0 + 1) % cols
        tx = x - np.floor(x)
    else:
        j0 = np.minimum(np.floor(x).astype(np.intp), cols - 2)
        j1 = j0 + 1
        tx = x - j0
    g = nodes
    val = ((1 - ty) * ((1 - tx) * g[i0, j0] + tx * g[i0, j1])
           + ty * ((1 - tx) * g[i0 + 1, j0] + tx * g[i0 + 1, j1]))
    sub = np.full(inside.shape, np.nan)
    sub[inside] = val
    out[ok] = sub
    return out


def geoid_search_path() -> list[Path]:
    """The directories searched for ``egm96_15.gtx``, in order (after ``geoid=`` and
    ``GEOBLOCK_GEOID``); duplicates removed, missing directories kept (they are reported)."""
    dirs: list[str] = []
    try:
        import pyproj.datadir

        dirs += pyproj.datadir.get_data_dir().split(os.pathsep)
        dirs.append(pyproj.datadir.get_user_data_dir())
    except Exception:  # pragma: no cover - pyproj without data directory
        pass
    for var in ("PROJ_DATA", "PROJ_LIB"):
        dirs += [d for d in os.environ.get(var, "").split(os.pathsep) if d]
    dirs += [
        os.path.join(sys.prefix, "share", "proj"),
        "/usr/share/proj",
        "/usr/local/share/proj",
        "/opt/homebrew/share/proj",
    ]
    out: list[Path] = []
    for d in dirs:
        p = Path(d)
        if p not in out:
            out.append(p)
    return out


def find_geoid(geoid: Geoid | str | os.PathLike[str] | None = None) -> Geoid:
    """The EGM96 geoid grid to use.

    Parameters
    ----------
    geoid : Geoid, str or os.PathLike, optional
        An explicit grid (any ``.gtx``); otherwise ``GEOBLOCK_GEOID``, then ``egm96_15.gtx``
        in pyproj's and the standard PROJ data directories.

    Returns
    -------
    Geoid

    Raises
    ------
    DemError
        Nothing was found: the message lists every place searched and how to provide the
        grid (``apt-get install proj-data``, ``geoid=`` or ``GEOBLOCK_GEOID``).
    """
    if isinstance(geoid, Geoid):
        return geoid
    if geoid is not None:
        path = Path(geoid).expanduser()
        if not path.is_file():
            raise GeoidNotFoundError("", f"geoid grid not found: {str(geoid)!r} is not a file",
                                     "give the path of a .gtx grid")
        return Geoid(path)
    env = os.environ.get("GEOBLOCK_GEOID")
    if env:
        path = Path(env).expanduser()
        if not path.is_file():
            raise GeoidNotFoundError(
                "", f"geoid grid not found: GEOBLOCK_GEOID={env!r} is not a file",
                "set GEOBLOCK_GEOID to the path of a .gtx grid, or unset it")
        return Geoid(path)
    searched = geoid_search_path()
    for d in searched:
        candidate = d / EGM96_FILENAME
        if candidate.is_file():
            return Geoid(candidate)
    raise GeoidNotFoundError(
        "",
        f"the EGM96 geoid grid {EGM96_FILENAME} is needed (the DEM's heights are above the "
        "geoid) but was not found; searched: GEOBLOCK_GEOID (not set), "
        + ", ".join(str(d) for d in searched)
        + ". Install it with 'apt-get install proj-data' (Debian/Ubuntu: /usr/share/proj), or "
        "download egm96_15.gtx from https://download.osgeo.org/proj/vdatum/",
        API_GEOID_HINT)


class ConstantGeoidDem(DemBase):
    """A constant height above the geoid (``open_dem("const:H", vertical="geoid")``):
    ellipsoidal height ``H + N(lon, lat)``.

    Parameters
    ----------
    h : float
        Metres above the geoid.
    geoid : Geoid
    """

    def __init__(self, h: float, geoid: Geoid) -> None:
        self._h = float(h)
        if not np.isfinite(self._h):
            raise DemError(f"const DEM: height must be finite, got {h!r}")
        self._geoid = geoid

    @property
    def h(self) -> float:
        """The height, metres above the geoid."""
        return self._h

    @property
    def geoid(self) -> Geoid:
        return self._geoid

    @property
    def bounds(self) -> tuple[float, float, float, float]:
        return (-180.0, -90.0, 180.0, 90.0)

    @property
    def resolution_m(self) -> float:
        return 0.0

    def _heights(self, lon: np.ndarray, lat: np.ndarray) -> np.ndarray:
        return self._h + self._geoid.undulation(lon, lat)

    def height_range(self, bounds: Bounds | None = None) -> tuple[float, float]:
        lo, hi = self._geoid.undulation_range(bounds or self.bounds)
        return (self._h + lo, self._h + hi)

    def to_dict(self) -> dict[str, Any]:
        return {"dem": "constant", "h": self._h, "vertical": "geoid", "geoid": self._geoid.path}

    def __reduce__(self) -> tuple[Any, ...]:
        return (ConstantGeoidDem, (self._h, self._geoid))

    def __repr__(self) -> str:
        return f"ConstantGeoidDem({self._h:g} m above the geoid {self._geoid.name})"
