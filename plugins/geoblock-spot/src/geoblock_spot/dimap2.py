"""The DIMAP v2 line-of-sight model of SPOT 6/7 and Pleiades sensor products.

:func:`read_dimap2` parses the physical metadata of

* DIMAP v2 ``DIM_*.XML`` sensor products (``Dimap_Document`` with
  ``Geometric_Data/Refined_Model``: SPOT 6/7 ``S6_SENSOR``/``S7_SENSOR``, Pleiades
  ``PHR_SENSOR``, Pleiades Neo ``PNEO_SENSOR``), and
* the Pleiades internal level-1 ``PHR_Dimap_Document`` (``PHRDIMAP_*.XML``, with
  ``Geometric_Data/Sensor_Model_Characteristics``; shareloc's test data),

into an immutable :class:`Dimap2`, and :func:`dimap2_model` builds from it a plain
:class:`geoblock.models.linescan.LinescanModel` (registry name ``linescan``), as
:func:`geoblock_spot.los.spot_dimap_model` does for SPOT 1-5: its JSON reopens without this
plugin.

Conventions (each checked against CNES's reference location grid, see below)
------------------------------------------------------------------------------
**Pixels.** DIMAP numbers rows and columns from 1 at pixel centres (``PIXEL_ORIGIN`` 1,
``POINT``/``CENTER``); every row/column read here is converted once to geoblock's 0-based
pixel centres (``row = DIMAP_ROW - 1``).

**Times.** UTC throughout (``Temporal_CRS`` UTC; the ``TAI_TIME`` tables of the internal
format are not used). All times are seconds since :attr:`Dimap2.epoch`, the ``START`` of
``Time_Range`` (``UTC_Sensor_Model_Range`` for the internal format), which is the exposure
time of row 0: ``t(row) = row * LINE_PERIOD`` (ASP ``PleiadesXML::setup_time_func``:
"reference line is the first line"; COSI-Corr ``Spot_RSM.py`` ``cSpot67``: ``linesDate =
arange(nbRows) * linePeriod``). ``LINE_PERIOD`` carries a ``unit`` attribute
(``microsecond`` for SPOT 6/7); without one it is in milliseconds (Pleiades, ASP
``read_times``; ``SENSOR_LINE_PERIOD`` of the internal format).

**Ephemeris.** ECEF (EPSG:4978) positions and velocities, cubic Hermite interpolation
(:class:`~geoblock.models.linescan.Ephemeris`; ASP uses 8-point Lagrange, the difference is
millimetres at these sample spacings). The velocities are classified against a 5-point
finite difference of the positions (:attr:`Dimap2.velocity_frame`): SPOT 6/7 velocities are
Earth-fixed; those of the internal Pleiades format are *inertial velocities on ECEF axes*
(they exceed the derivative of the positions by ``omega x P``, about 470 m/s) and are
converted with ``V_ef = V - omega x P`` (using them as given moves the ground by about 1 km).

**Attitude.** Unit quaternions ``(Q0, Q1, Q2, Q3)`` with ``Q0`` the scalar part, rotating
satellite-frame vectors to ECEF: ``v_ecef = R(q) v_sat`` (ASP ``LinescanPleiadesModel.cc``
``get_camera_pose_at_time`` "order is w, x, y, z" fed to CSM as sensor-to-ECEF; COSI-Corr
``Spot_RSM.py`` ``Quat_2_rot_airbus`` with ``[Q1, Q2, Q3, Q0]``). Sources: the
``Quaternion_List`` table (SPOT 6/7, Neo) or the cubic ``Polynomial_Quaternions`` /
``Sensor_Attitudes/Polynomial_Models`` in ``tau = (t_UTC_seconds_of_day - OFFSET) / SCALE``
(Pleiades; ASP ``read_attitudes_1A1B``: "this offset is from midnight"), sampled here every
``attitude_step_s`` and slerped. The frame is taken from ``Refined_Model``'s
``Geodetic_CRS`` (must be EPSG:4978/geocentric, else the file is refused: inertial attitudes
need Earth-orientation parameters geoblock does not model); the internal format's sensor-model
polynomials are the Earth-fixed ("WGS84") attitudes. The internal format's ``Raw_Attitudes``
and ``Accurate_Attitudes`` (TAI, inertial) are ignored. As a guard against a frame mix-up,
:func:`dimap2_model` refuses a model that puts the product's stated scene centre more than
:data:`CENTRE_TOLERANCE_M` from where the product says.

**Look directions.** ``psi_x = sum XLOS_k d^k``, ``psi_y = sum YLOS_k d^k`` (``PsiX_Model`` /
``PsiY_Model`` in the internal format) with the detector index
``d = col + FIRST_COL - 1`` (0-based image column ``col``; ``FIRST_COL`` of ``Swath_Range`` /
``Position_In_Retina``, 1 in every file seen, so ``d = col``: ASP
``get_local_pixel_vector`` "col + m_ref_col" with ``m_ref_col = FIRST_COL - 1``; COSI-Corr
``ComputeCCDLookAngles`` ``arange(nbCols)``). The polynomial values are the *tangents* of the
look angles, and the look vector in the satellite frame is ``(psi_y, -psi_x, 1)`` normalised
(ASP ``get_local_pixel_vector``: ``Vector3(y, -x, 1.0)``; COSI-Corr: ``VX = tanPsiY, VY =
-tanPsiX, VZ = 1``). So ``LookDirections.from_tan_angles(tan_x=psi_y, tan_y=-psi_x)``: the
satellite frame is geoblock's sensor frame (x along track, z down).

Validation (``plugins/geoblock-spot/tests/test_dimap2.py``)
------------------------------------------------------------
Against CNES's direct-location grid ``GRID_P1BP--2018122638935449CP.tif`` (65 x 65 nodes
over the whole image, 9 heights -30 ... 4900 m) the model of
``PHRDIMAP_P1BP--2018122638935449CP.XML`` backprojects every node within 5 mm (RMS 4 mm).
Each alternative convention is rejected by that grid: detector index ``d = col + 1`` or
``col - 1`` (0.54 m), row 0 at ``START + LINE_PERIOD`` (0.53 m), the polynomials as angles
instead of tangents (0.72 m), the velocities as given (1.2 km), the ``WGS84_Attitudes`` table
instead of the polynomial (2.4 m). The model also agrees with the document's ``Global_RFM``
within 0.02 px over the whole image.
"""

from __future__ import annotations

import numbers
import os
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from geoblock import coords
from geoblock.errors import GeoblockIOError
from geoblock.io.metadata import XmlFields, read_bytes, read_xml
from geoblock.io.vsi import as_path
from geoblock.models.linescan import (
    Attitude,
    Ephemeris,
    LinescanModel,
    LineTimes,
    LookDirections,
    matrix_to_quaternion,
    quaternion_to_matrix,
)
from geoblock.models.parameters import ParameterSet, location_accuracy
from geoblock.pixels import image_domain
from geoblock_spot.dimap import (
    EARTH_ROTATION_RAD_S,
    MAX_IMAGE_SIZE,
    MAX_LINE_PERIOD_S,
    MAX_LOOK_TANGENT,
    YEAR_RANGE,
    DimapFormatError,
    GroundPoint,
    check_ground_value,
    check_orbit_radius,
    check_speed,
    check_unit_quaternions,
    file_named,
    with_parameters,
)

__all__ = [
    "CENTRE_TOLERANCE_M",
    "Dimap2",
    "QuaternionPolynomial",
    "dimap2_model",
    "is_dimap2",
    "read_dimap2",
]

#: velocities within this many m/s of the positions' derivative (or of it plus omega x P)
#: are accepted as Earth-fixed (inertial)
_VELOCITY_TOLERANCE_M_S = 5.0

#: the model must put the product's stated scene centre (its pixel backprojected at h = 0)
#: within this distance of the stated lon/lat, metres. The stated point is at an unstated
#: height (terrain, at most a few km at <= 30 degrees of incidence); mixing up an inertial
#: and the Earth-fixed attitude frame moves it by the Earth's rotation angle since the
#: frames' epoch times ~6400 km, i.e. far more unless that angle is below ~0.2 degrees.
CENTRE_TOLERANCE_M = 20_000.0

#: ``(END - START)`` must equal ``(rows - 1) * LINE_PERIOD`` within this fraction (plus two
#: line periods; ``END`` is rounded to milliseconds in the internal format)
_DURATION_TOLERANCE = 0.01

#: largest ``attitude_step_s`` accepted, seconds
MAX_ATTITUDE_STEP_S = 10.0

_LINE_PERIOD_UNITS = {"microsecond": 1e-6, "us": 1e-6, "millisecond": 1e-3, "ms": 1e-3,
                      "second": 1.0, "s": 1.0}


@dataclass(frozen=True, eq=False)
class QuaternionPolynomial:
    """Quaternions as cubic (or any degree) polynomials of scaled time.

    ``q_i(t) = sum_k coefficients[i, k] tau^k`` with ``tau = (t - offset_s) / scale_s``,
    ``t`` seconds since :attr:`Dimap2.epoch`; ``i`` runs over ``(Q0, Q1, Q2, Q3)``, Q0 scalar.

    Attributes
    ----------
    coefficients : ndarray, (4, k)
        Increasing powers.
    offset_s, scale_s : float
        ``OFFSET`` (converted from seconds since UTC midnight to seconds since the epoch) and
        ``SCALE``.
    """

    coefficients: np.ndarray
    offset_s: float
    scale_s: float

    def raw(self, t_s: np.ndarray) -> np.ndarray:
        """The polynomials' values (n, 4) ``(w, x, y, z)`` at times (n,), not normalised."""
        tau = (np.asarray(t_s, np.float64) - self.offset_s) / self.scale_s
        return np.stack([np.polynomial.polynomial.polyval(tau, c) for c in self.coefficients],
                        axis=-1)

    def at(self, t_s: np.ndarray) -> np.ndarray:
        """Unit quaternions (n, 4) ``(w, x, y, z)`` at times (n,), normalised."""
        q = self.raw(t_s)
        return q / np.linalg.norm(q, axis=-1, keepdims=True)


@dataclass(frozen=True, eq=False)
class Dimap2:
    """Parsed physical metadata of a DIMAP v2 / Pleiades internal sensor product.

    All rows/columns are geoblock 0-based pixel centres; times seconds since :attr:`epoch`;
    positions metres and velocities m/s in ECEF (EPSG:4978).

    Attributes
    ----------
    path : pathlib.Path
    format : str
        ``"dimap-v2"`` (``Dimap_Document`` ``Refined_Model``) or ``"phr-internal"``
        (``PHR_Dimap_Document`` ``Sensor_Model_Characteristics``).
    profile : str
        ``METADATA_PROFILE`` (``S6_SENSOR``, ``PHR_SENSOR``, ``PHR_SYSTEM_RECTIFIED_PRODUCT``...).
    mission : str
        ``"SPOT 6"``, ``"PHR 1B"``...
    shape : tuple of int
        ``(NROWS, NCOLS)``.
    epoch : str
        ISO-8601 UTC time of row 0 (``START``).
    end_time_s : float
        ``END`` of the time range.
    line_period_s : float
    ephemeris_time_s : ndarray, (n,)
    position_m, velocity_m_s : ndarray, (n, 3)
        As in the file (see :attr:`velocity_frame`).
    velocity_frame : str
        ``"earth-fixed"`` or ``"inertial"`` (inertial velocity on ECEF axes).
    quaternion_time_s : ndarray, (m,) ; quaternions : ndarray, (m, 4)
        Tabulated ``(Q0, Q1, Q2, Q3)`` (empty when the attitude is a polynomial).
    quaternion_polynomial : QuaternionPolynomial or None
    attitude_source : str
        The element the attitude was read from.
    first_detector : int
        ``FIRST_COL`` (1-based detector of image column 0).
    psi_x_coefficients, psi_y_coefficients : ndarray, (k,)
        Look-angle tangent polynomials in the 0-based detector index, increasing powers.
    vertices : tuple of GroundPoint
        The product's corner vertices (no height stated; ``h = 0``).
    centre : GroundPoint or None
        The product's stated scene centre.
    """

    path: Path
    format: str
    profile: str
    mission: str
    shape: tuple[int, int]
    epoch: str
    end_time_s: float
    line_period_s: float
    ephemeris_time_s: np.ndarray
    position_m: np.ndarray
    velocity_m_s: np.ndarray
    velocity_frame: str
    quaternion_time_s: np.ndarray
    quaternions: np.ndarray
    quaternion_polynomial: QuaternionPolynomial | None
    attitude_source: str
    first_detector: int
    psi_x_coefficients: np.ndarray
    psi_y_coefficients: np.ndarray
    vertices: tuple[GroundPoint, ...]
    centre: GroundPoint | None

    def earth_fixed_velocity_m_s(self) -> np.ndarray:
        """Velocities (n, 3) relative to the rotating Earth (the positions' derivative)."""
        if self.velocity_frame == "inertial":
            return self.velocity_m_s - _omega_cross(self.position_m)
        return self.velocity_m_s

    def look_tangents(self, cols: int | None = None) -> tuple[np.ndarray, np.ndarray]:
        """``(psi_x, psi_y)`` (cols,) look-angle tangents of image columns ``0 .. cols-1``."""
        n = self.shape[1] if cols is None else int(cols)
        return (_look_tangents(self.psi_x_coefficients, self.first_detector, n),
                _look_tangents(self.psi_y_coefficients, self.first_detector, n))

    def __repr__(self) -> str:
        return (f"Dimap2({self.mission}, {self.format}, shape={self.shape}, epoch={self.epoch}, "
                f"attitude={self.attitude_source}, path={str(self.path)!r})")


# ==================================================================================== reading
def is_dimap2(path: str | os.PathLike[str]) -> bool:
    """True if ``path`` is a DIMAP v2 / Pleiades internal document with a physical model.

    Cheap: looks at the first 8 KiB for the root element, then parses the file only when
    it is one of the two roots, and checks for ``Geometric_Data/Refined_Model`` or
    ``Geometric_Data/Sensor_Model_Characteristics`` (DIMAP v2 RPC files and ortho products
    have neither, and are left to other readers). A document that is not well-formed XML but
    holds one of these elements' tags is claimed too, so that :func:`read_dimap2` names the
    XML error instead of the file going unrecognised.
    """
    p = as_path(path)
    if not p.is_file():
        return False
    try:
        head = read_bytes(p, 8192)
    except GeoblockIOError:
        return False
    if b"<Dimap_Document" not in head and b"<PHR_Dimap_Document" not in head:
        return False
    try:
        root = read_xml(p, DimapFormatError).root
    except GeoblockIOError:
        return False
    except DimapFormatError:  # not well-formed: claimed if it holds a physical model's tag
        try:
            data = read_bytes(p)
        except GeoblockIOError:
            return False
        return b"<Refined_Model" in data or b"<Sensor_Model_Characteristics" in data
    if root.tag == "Dimap_Document":
        return root.find("Geometric_Data/Refined_Model") is not None
    if root.tag == "PHR_Dimap_Document":
        return root.find("Geometric_Data/Sensor_Model_Characteristics") is not None
    return False


def read_dimap2(path: str | os.PathLike[str]) -> Dimap2:
    """Parse the physical model metadata of a DIMAP v2 / Pleiades internal sensor document.

    Parameters
    ----------
    path : str or os.PathLike
        A ``DIM_*.XML`` (SPOT 6/7, Pleiades, Pleiades Neo sensor product) or a
        ``PHRDIMAP_*.XML`` Pleiades internal level-1 document.

    Returns
    -------
    Dimap2

    Raises
    ------
    GeoblockIOError
        The file cannot be read.
    DimapFormatError
        Not well-formed XML; missing, malformed or inconsistent fields (named in the
        message), attitudes in a frame other than ECEF, velocities that are neither
        Earth-fixed nor inertial.
    """
    p = as_path(path)
    doc = read_xml(p, DimapFormatError)
    root = doc.root
    if root.tag == "Dimap_Document" and root.find("Geometric_Data/Refined_Model") is not None:
        return _read_refined_model(p, doc)
    if (root.tag == "PHR_Dimap_Document"
            and root.find("Geometric_Data/Sensor_Model_Characteristics") is not None):
        return _read_phr_internal(p, doc)
    raise DimapFormatError(p, "Geometric_Data",
                           f"root <{root.tag}> holds no physical sensor model (neither "
                           "Dimap_Document/Geometric_Data/Refined_Model nor PHR_Dimap_Document/"
                           "Geometric_Data/Sensor_Model_Characteristics)")


def _time(doc: XmlFields, where: str, base: ET.Element | None = None,
          label: str = "") -> np.datetime64:
    """A ``datetime64[ns]`` time, its year plausible (the internal Pleiades format has seven
    digits of seconds: those below the microsecond are kept)."""
    return doc.time(where, base, label, years=YEAR_RANGE, unit="ns")


def _seconds(t: np.datetime64, epoch: np.datetime64) -> float:
    return float((t - epoch) / np.timedelta64(1, "ns")) * 1e-9


def _omega_cross(p: np.ndarray) -> np.ndarray:
    w = EARTH_ROTATION_RAD_S
    return np.stack([-w * p[..., 1], w * p[..., 0], np.zeros(p.shape[:-1])], axis=-1)


def _derivative(t: np.ndarray, p: np.ndarray) -> np.ndarray:
    """dP/dt (n, 3) at the samples: derivative of the degree-4 polynomial through the 5
    nearest samples (fewer when there are fewer); error ~1e-3 m/s at 30 s spacing, ends
    included."""
    n = t.size
    k = min(5, n)
    out = np.empty_like(p)
    for i in range(n):
        j0 = min(max(i - k // 2, 0), n - k)
        x = t[j0:j0 + k] - t[i]
        c = np.polynomial.polynomial.polyfit(x, p[j0:j0 + k], k - 1)
        out[i] = c[1]
    return out


def _velocity_frame(doc: XmlFields, field: str, t: np.ndarray, p: np.ndarray, v: np.ndarray) -> str:
    """``"earth-fixed"`` or ``"inertial"``: every sample within the tolerance of one of them."""
    d = _derivative(t, p)
    err_ef = float(np.max(np.linalg.norm(v - d, axis=-1)))
    err_in = float(np.max(np.linalg.norm(v - _omega_cross(p) - d, axis=-1)))
    if err_ef <= _VELOCITY_TOLERANCE_M_S and err_ef <= err_in:
        return "earth-fixed"
    if err_in <= _VELOCITY_TOLERANCE_M_S:
        return "inertial"
    raise doc.error(field,
                           f"the velocities match neither the derivative of the positions "
                           f"(off by up to {err_ef:.1f} m/s) nor it plus the Earth's rotation "
                           f"omega x P ({err_in:.1f} m/s); tolerance "
                           f"{_VELOCITY_TOLERANCE_M_S} m/s")


def _ephemeris(doc: XmlFields, points: list[ET.Element], field: str, pos_tag: str, vel_tag: str,
               time_tag: str, epoch: np.datetime64):
    if len(points) < 2:
        raise doc.error(field, f"needs at least 2 points, got {len(points)}")
    t = np.array([_seconds(_time(doc, time_tag, e, f"{field}[{i}]/"), epoch)
                  for i, e in enumerate(points)])
    pos = np.array([doc.numbers(pos_tag, e, f"{field}[{i}]/", 3) for i, e in enumerate(points)])
    vel = np.array([doc.numbers(vel_tag, e, f"{field}[{i}]/", 3) for i, e in enumerate(points)])
    for e in points:
        unit = e.find(pos_tag).get("unit", "m")
        if unit not in ("m", "meter", "metre"):
            raise doc.error(f"{field}/{pos_tag}", f"unit {unit!r}, expected m")
    if np.any(~(np.diff(t) > 0)):
        raise doc.error(field, "point times are not strictly increasing")
    check_orbit_radius(doc.source, f"{field}[{{i}}]/{pos_tag}", pos)
    check_speed(doc.source, f"{field}[{{i}}]/{vel_tag}", vel)
    return t, pos, vel, _velocity_frame(doc, field, t, pos, vel)


def _line_period(doc: XmlFields, where: str, default_unit: str) -> float:
    e = doc.node(where)
    unit = e.get("unit", default_unit)
    if unit not in _LINE_PERIOD_UNITS:
        raise doc.error(where, f"unknown unit {unit!r}")
    value = doc.number(where) * _LINE_PERIOD_UNITS[unit]
    if not 0 < value <= MAX_LINE_PERIOD_S:
        raise doc.error(where, f"must be > 0 and <= {MAX_LINE_PERIOD_S:g} s, "
                                                f"got {value!r} s")
    return value


def _points(doc: XmlFields, base: ET.Element | None) -> tuple[tuple[GroundPoint, ...],
                                                         GroundPoint | None]:
    if base is None:
        return (), None

    def point(e: ET.Element, label: str) -> GroundPoint:
        values = {tag: check_ground_value(doc.source, label + tag, tag.lower(),
                                          doc.number(tag, e, label))
                  for tag in ("LON", "LAT", "ROW", "COL")}
        return GroundPoint(lon=values["LON"], lat=values["LAT"], h=0.0, row=values["ROW"] - 1.0,
                           col=values["COL"] - 1.0)

    vertices = tuple(point(e, f"Vertex[{i}]/") for i, e in enumerate(base.findall("Vertex")))
    c = base.find("Center")
    return vertices, (point(c, "Center/") if c is not None else None)


def _check_raster_origin(doc: XmlFields, where: str) -> None:
    e = doc.root.find(where)
    if e is not None and e.text is not None and e.text.strip() not in ("1", "1.0"):
        raise doc.error(where,
                               f"only PIXEL_ORIGIN 1 is supported, got {e.text.strip()!r}")


def _check_duration(doc: XmlFields, where: str, rows: int, line_period: float,
                    end_s: float) -> None:
    expected = (rows - 1) * line_period
    if not abs(end_s - expected) <= _DURATION_TOLERANCE * expected + 2.0 * line_period:
        raise doc.error(where,
                               f"END - START = {end_s:.6f} s but (NROWS - 1) x line period = "
                               f"{expected:.6f} s: the line period or the image size is wrong")


def _read_refined_model(path: Path, doc: XmlFields) -> Dimap2:
    root = doc.root
    profile = doc.text("Metadata_Identification/METADATA_PROFILE")
    _check_raster_origin(doc, "Geoposition/Raster_CRS/PIXEL_ORIGIN")
    rows = doc.integer("Raster_Data/Raster_Dimensions/NROWS", minimum=1, maximum=MAX_IMAGE_SIZE)
    cols = doc.integer("Raster_Data/Raster_Dimensions/NCOLS", minimum=2, maximum=MAX_IMAGE_SIZE)
    rm = "Geometric_Data/Refined_Model"
    crs = root.find(f"{rm}/Coordinate_Reference_System/Geodetic_CRS")
    if crs is not None:
        code = (crs.findtext("GEODETIC_CRS_CODE") or "").strip()
        kind = (crs.findtext("GEODETIC_CRS_TYPE") or "").strip().upper()
        if not (code.endswith(":4978") or code == "4978" or (not code and kind == "GEOCENTRIC")):
            raise DimapFormatError(
                path, f"{rm}/Coordinate_Reference_System/Geodetic_CRS",
                f"ephemeris and attitudes are given in {code or kind or 'an unnamed frame'!r}, "
                "not the Earth-fixed EPSG:4978; inertial frames are not supported (they need "
                "Earth-orientation parameters)")
    start = _time(doc, f"{rm}/Time/Time_Range/START")
    end_s = _seconds(_time(doc, f"{rm}/Time/Time_Range/END"), start)
    line_period = _line_period(doc, f"{rm}/Time/Time_Stamp/LINE_PERIOD",
                               "microsecond" if profile.startswith("PNEO") else "millisecond")
    _check_duration(doc, f"{rm}/Time/Time_Range", rows, line_period, end_s)

    points = root.findall(f"{rm}/Ephemeris/Point_List/Point")
    t_e, pos, vel, vframe = _ephemeris(doc, points, f"{rm}/Ephemeris/Point_List/Point",
                                       "LOCATION_XYZ", "VELOCITY_XYZ", "TIME", start)

    att = f"{rm}/Attitudes"
    table = root.findall(f"{att}/Quaternion_List/Quaternion")
    poly_node = root.find(f"{att}/Polynomial_Quaternions")
    q_t, q, poly, source = np.empty(0), np.empty((0, 4)), None, ""
    if table:
        field = f"{att}/Quaternion_List/Quaternion"
        q_t = np.array([_seconds(_time(doc, "TIME", e, f"{field}[{i}]/"), start)
                        for i, e in enumerate(table)])
        q = np.array([[doc.number(f"Q{k}", e, f"{field}[{i}]/") for k in range(4)]
                      for i, e in enumerate(table)])
        if np.any(~(np.diff(q_t) > 0)):
            i = int(np.flatnonzero(~(np.diff(q_t) > 0))[0]) + 1
            raise DimapFormatError(path, f"{field}[{i}]/TIME",
                                   "quaternion times are not strictly increasing")
        check_unit_quaternions(path, f"{field}[{{i}}]/Q0..Q3", q)
        source = field
    elif poly_node is not None:
        poly = _quaternion_polynomial(doc, poly_node, f"{att}/Polynomial_Quaternions", start)
        source = f"{att}/Polynomial_Quaternions"
        _check_unit(doc, source, poly, rows, line_period)
    else:
        raise DimapFormatError(path, att, "neither Quaternion_List nor Polynomial_Quaternions")

    cal = root.find(f"{rm}/Geometric_Calibration/Instrument_Calibration")
    if cal is None:
        raise DimapFormatError(path, f"{rm}/Geometric_Calibration/Instrument_Calibration",
                               "missing")
    band = cal.find("Band_Calibration_List/Band_Calibration")
    base = band if band is not None else cal
    label = ("Instrument_Calibration/Band_Calibration_List/Band_Calibration/"
             if band is not None else "Instrument_Calibration/")
    first = doc.integer("Swath_Range/FIRST_COL", base, label, minimum=1, maximum=MAX_IMAGE_SIZE)
    look = doc.node("Polynomial_Look_Angles", base, label)
    psi_x = _los_coefficients(doc, look, "XLOS", label + "Polynomial_Look_Angles/")
    psi_y = _los_coefficients(doc, look, "YLOS", label + "Polynomial_Look_Angles/")
    for name, c in (("XLOS", psi_x), ("YLOS", psi_y)):
        _check_look(doc, f"{label}Polynomial_Look_Angles/{name}_*", c, first, cols)
    biases = cal.find("Instrument_Biases")
    if biases is not None:
        for name in ("YAW", "PITCH", "ROLL"):
            if biases.find(name) is not None and doc.number(
                    name, biases, "Instrument_Calibration/Instrument_Biases/") != 0.0:
                raise DimapFormatError(path, f"Instrument_Calibration/Instrument_Biases/{name}",
                                       f"non-zero instrument bias {biases.findtext(name)!r} is "
                                       "not supported")

    mission = " ".join(x for x in (
        root.findtext("Dataset_Sources/Source_Identification/Strip_Source/MISSION", "").strip(),
        root.findtext("Dataset_Sources/Source_Identification/Strip_Source/MISSION_INDEX",
                      "").strip()) if x) or profile
    vertices, centre = _points(doc, root.find("Dataset_Content/Dataset_Extent"))
    return Dimap2(path, "dimap-v2", profile, mission, (rows, cols), _iso(start), end_s,
                  line_period, t_e, pos, vel, vframe, q_t, q, poly, source, first, psi_x, psi_y,
                  vertices, centre)


def _read_phr_internal(path: Path, doc: XmlFields) -> Dimap2:
    root = doc.root
    profile = doc.text("Metadata_Identification/METADATA_PROFILE")
    _check_raster_origin(doc, "Product_Frame/PIXEL_ORIGIN")
    rows = doc.integer("Raster_Dimensions/NROWS", minimum=1, maximum=MAX_IMAGE_SIZE)
    cols = doc.integer("Raster_Dimensions/NCOLS", minimum=2, maximum=MAX_IMAGE_SIZE)
    smc = "Geometric_Data/Sensor_Model_Characteristics"
    start = _time(doc, f"{smc}/UTC_Sensor_Model_Range/START")
    end_s = _seconds(_time(doc, f"{smc}/UTC_Sensor_Model_Range/END"), start)
    line_period = _line_period(doc, f"{smc}/SENSOR_LINE_PERIOD", "millisecond")
    _check_duration(doc, f"{smc}/UTC_Sensor_Model_Range", rows, line_period, end_s)
    field = f"{smc}/Sensor_Ephemeris/Point_List/Point"
    t_e, pos, vel, vframe = _ephemeris(doc, root.findall(field), field, "LOCATION_VALUES",
                                       "VELOCITY_VALUES", "UTC_TIME", start)
    att = doc.node(f"{smc}/Sensor_Attitudes")
    poly = _quaternion_polynomial(doc, att, f"{smc}/Sensor_Attitudes", start,
                                  models="Polynomial_Models/")
    _check_unit(doc, f"{smc}/Sensor_Attitudes/Polynomial_Models", poly, rows, line_period)
    viewing = f"{smc}/Sensor_Viewing_Model"
    first = doc.integer(f"{viewing}/Position_In_Retina/FIRST_COL", minimum=1,
                        maximum=MAX_IMAGE_SIZE)
    psi = []
    for name in ("PsiX_Model", "PsiY_Model"):
        where = f"{viewing}/Viewing_Directions/{name}"
        degree = doc.number(f"{where}/DEGREE")
        c = doc.numbers(f"{where}/COEFFICIENTS")
        if c.size != degree + 1:
            raise DimapFormatError(path, f"{where}/COEFFICIENTS",
                                   f"DEGREE {degree:g} needs {degree + 1:g} coefficients, "
                                   f"got {c.size}")
        _check_look(doc, f"{where}/COEFFICIENTS", c, first, cols)
        psi.append(c)
    platform = " ".join(root.findtext(f"Data_Strip/Data_Strip_Identification/{k}", "").strip()
                        for k in ("PLATFORM_NAME", "PLATFORM_SERIAL_NUMBER")).strip()
    vertices, centre = _points(doc, root.find("Product_Frame/Dataset_Frame"))
    return Dimap2(path, "phr-internal", profile, platform or profile, (rows, cols), _iso(start),
                  end_s, line_period, t_e, pos, vel, vframe, np.empty(0), np.empty((0, 4)), poly,
                  f"{smc}/Sensor_Attitudes/Polynomial_Models", first, psi[0], psi[1], vertices,
                  centre)


def _iso(t: np.datetime64) -> str:
    return str(t) + "Z"


def _los_coefficients(doc: XmlFields, node: ET.Element, prefix: str, label: str) -> np.ndarray:
    """``XLOS_0, XLOS_1, ...`` (consecutive, at least ``_0``) as an array."""
    values = []
    while node.find(f"{prefix}_{len(values)}") is not None:
        values.append(doc.number(f"{prefix}_{len(values)}", node, label))
    if not values:
        raise doc.error(f"{label}{prefix}_0", "missing")
    return np.array(values)


def _check_unit(doc: XmlFields, field: str, poly: QuaternionPolynomial, rows: int,
                line_period: float) -> None:
    """The attitude polynomials must give unit quaternions over the image's rows."""
    first, _, last, _ = image_domain((rows, 1))  # the outer edges of the rows
    t = np.linspace(first, last, 101) * line_period
    with np.errstate(all="ignore"):
        check_unit_quaternions(
            doc.source, f"{field}/Q0..Q3", poly.raw(t),
            lambda i: f"the polynomials' quaternion at {t[i]:.3f} s after START ")


def _look_tangents(coefficients: np.ndarray, first: int, cols: int) -> np.ndarray:
    """The look-angle tangent polynomial at image columns ``0 .. cols-1`` (detector index
    ``col + first - 1``)."""
    d = np.arange(cols, dtype=np.float64) + (first - 1)
    return np.polynomial.polynomial.polyval(d, coefficients)


def _check_look(doc: XmlFields, field: str, coefficients: np.ndarray, first: int,
                cols: int) -> None:
    """The look-angle tangents of every detector of the image must be finite and small."""
    with np.errstate(all="ignore"):
        tangent = _look_tangents(coefficients, first, cols)
    bad = np.flatnonzero(~(np.abs(tangent) < MAX_LOOK_TANGENT))
    if bad.size:
        raise doc.error(field,
                               f"the look-angle tangent of column {bad[0]} is "
                               f"{tangent[bad[0]]!r}: not plausible (|tan| must be < "
                               f"{MAX_LOOK_TANGENT:g})")


def _quaternion_polynomial(doc: XmlFields, node: ET.Element, where: str, start: np.datetime64,
                           models: str = "") -> QuaternionPolynomial:
    coefficients = []
    for k in range(4):
        label = f"{where}/{models}Q{k}/"
        c = doc.numbers(f"{models}Q{k}/COEFFICIENTS", node, f"{where}/")
        degree = doc.number("DEGREE", doc.node(f"{models}Q{k}", node, f"{where}/"), label)
        if c.size != degree + 1:
            raise doc.error(f"{label}COEFFICIENTS",
                                   f"DEGREE {degree:g} needs {degree + 1:g} coefficients, "
                                   f"got {c.size}")
        coefficients.append(c)
    width = max(c.size for c in coefficients)
    coef = np.zeros((4, width))
    for k, c in enumerate(coefficients):
        coef[k, :c.size] = c
    offset = doc.number("OFFSET", node, f"{where}/")
    scale = doc.number("SCALE", node, f"{where}/")
    if not scale > 0:
        raise doc.error(f"{where}/SCALE", f"must be > 0, got {scale}")
    midnight = start.astype("datetime64[D]").astype("datetime64[ns]")
    return QuaternionPolynomial(coef, offset - _seconds(start, midnight), scale)


# ==================================================================================== model
def dimap2_model(
    source: Dimap2 | str | os.PathLike[str],
    *,
    parameters: str | ParameterSet = "linescan",
    accuracy_m: float | None = None,
    attitude_step_s: float = 1.0 / 64.0,
    height_range: tuple[float, float] = (-500.0, 9000.0),
) -> LinescanModel:
    """The line-of-sight model of a SPOT 6/7 or Pleiades sensor product.

    Parameters
    ----------
    source : Dimap2 or path
        Parsed metadata or a ``DIM_*.XML`` / ``PHRDIMAP_*.XML`` file.
    parameters : {"linescan", "dg"} or ParameterSet
        A parameter set of the model (:meth:`LinescanModel.with_parameter_set`):
        ``"linescan"`` (default): the linescan model's twelve free parameters; ``"dg"``:
        Teo et al.'s DG set (:func:`geoblock.models.linescan.dg_parameters`) with sigmas from
        ``accuracy_m``; or a ``ParameterSet`` with linescan names.
    accuracy_m : float, optional
        The product's location accuracy (1 sigma, metres), required for ``"dg"`` (DIMAP v2
        states none in metres); stored as the model's ``location_accuracy_m``, so that a later
        ``with_parameter_set("dg")`` needs no option.
    attitude_step_s : float
        Sampling step of a polynomial attitude, seconds (slerp between samples; 1/64 s
        reproduces the polynomial to well below a microradian).
    height_range : (float, float)
        Valid heights, metres above the ellipsoid.

    Returns
    -------
    LinescanModel
        Shape ``(NROWS, NCOLS)``, attitude in ECEF, epoch ``START`` (row 0).

    Raises
    ------
    DimapFormatError
        The ephemeris or attitude does not cover the image's rows, or the model puts the
        product's stated scene centre more than :data:`CENTRE_TOLERANCE_M` away (attitude
        frame or time convention not understood); ``accuracy_m`` not finite and > 0,
        ``attitude_step_s`` not a number in ``(0, MAX_ATTITUDE_STEP_S]``, ``height_range`` not
        two finite heights ``h_min < h_max`` (field ``(option ...)`` / ``(model)``).
    ParameterSetError
        ``parameters`` is none of the above, or ``"dg"`` without ``accuracy_m``; the message
        names the file.
    """
    path = source.path if isinstance(source, Dimap2) else as_path(source)
    if accuracy_m is not None:
        with file_named(path, "(option accuracy_m)"):
            location_accuracy(accuracy_m, "the location accuracy")
    if (isinstance(attitude_step_s, bool) or not isinstance(attitude_step_s, numbers.Real)
            or not 0 < attitude_step_s <= MAX_ATTITUDE_STEP_S):
        raise DimapFormatError(path, "(option attitude_step_s)",
                               f"must be a sampling step > 0 and <= {MAX_ATTITUDE_STEP_S:g} s, "
                               f"got {attitude_step_s!r}")
    meta = source if isinstance(source, Dimap2) else read_dimap2(source)
    rows, cols = meta.shape
    psi_x, psi_y = meta.look_tangents(cols)
    with file_named(meta.path, "Polynomial_Look_Angles"):
        look = LookDirections.from_tan_angles(psi_y, -psi_x)
    with file_named(meta.path, "Ephemeris/Point_List"):
        ephemeris = Ephemeris(meta.ephemeris_time_s, meta.position_m,
                              meta.earth_fixed_velocity_m_s())
    with file_named(meta.path, "LINE_PERIOD"):
        line_times = LineTimes(0.0, 0.0, meta.line_period_s)
    first, _, last, _ = image_domain(meta.shape)  # the outer edges of the rows
    t_first, t_last = first * meta.line_period_s, last * meta.line_period_s
    if meta.quaternion_polynomial is not None:
        # the search span of LinescanModel (rows plus max(half the image, 1 s) each side),
        # limited to the ephemeris
        margin = max(0.5 * (t_last - t_first), LinescanModel.search_margin_s) + attitude_step_s
        e0, e1 = ephemeris.valid_span_s
        lo, hi = max(t_first - margin, e0), min(t_last + margin, e1)
        n = int(np.ceil((hi - lo) / attitude_step_s)) + 1
        t_att = lo + np.arange(n) * attitude_step_s
        with file_named(meta.path, meta.attitude_source), np.errstate(all="ignore"):
            attitude = Attitude(t_att, meta.quaternion_polynomial.at(t_att), frame="ecef")
    else:
        t_q = meta.quaternion_time_s
        with file_named(meta.path, meta.attitude_source):
            span = Attitude(t_q, meta.quaternions, frame="ecef").valid_span_s
        if not (span[0] <= t_first and t_last <= span[1]):
            raise DimapFormatError(
                meta.path, meta.attitude_source,
                f"the attitude (usable from {span[0]:.3f} s to {span[1]:.3f} s after "
                f"{meta.epoch}) does not cover the image's rows ({t_first:.3f} s to "
                f"{t_last:.3f} s)")
        # a table that ends with the image (SPOT 6/7) would hold the attitude constant beyond
        # its last sample, a kink at the first/last row: extend it at constant angular
        # velocity (ASP extrapolateAtStartTime/EndTime) over the ephemeris' span
        t_att, q_att = _extend_table(meta.quaternion_time_s, meta.quaternions,
                                     *ephemeris.valid_span_s)
        with file_named(meta.path, meta.attitude_source):
            attitude = Attitude(t_att, q_att, frame="ecef")

    for what, span, field in (("attitude", attitude.valid_span_s, meta.attitude_source),
                              ("ephemeris", ephemeris.valid_span_s, "Ephemeris/Point_List")):
        if not (span[0] <= t_first and t_last <= span[1]):
            raise DimapFormatError(
                meta.path, field,
                f"the {what} (usable from {span[0]:.3f} s to {span[1]:.3f} s after "
                f"{meta.epoch}) does not cover the image's rows ({t_first:.3f} s to "
                f"{t_last:.3f} s)")

    with file_named(meta.path, "(model)"):
        model = LinescanModel((rows, cols), ephemeris, attitude, look, line_times,
                              epoch=meta.epoch, height_range=height_range,
                              location_accuracy_m=accuracy_m)
    if meta.centre is not None:
        _check_centre(meta, model)
    return with_parameters(model, parameters, meta.path, ("linescan", "dg"))


def _extend_table(t: np.ndarray, q: np.ndarray, lo: float, hi: float,
                  max_samples: int = 1000) -> tuple[np.ndarray, np.ndarray]:
    """Quaternion table extended to cover ``[lo, hi]`` at the end intervals' constant
    rotation (``R_{n+k} = R_n (R_{n-1}^T R_n)^k``), with the end spacing; at most
    ``max_samples`` added per side."""
    if t.size < 2:
        return t, q
    r = quaternion_to_matrix(q)
    times, mats = [t], [r]
    for end in (0, -1):
        inner = 1 if end == 0 else -2
        step = t[end] - t[inner]  # negative at the start
        limit = lo if end == 0 else hi
        n = int(min(max(np.ceil((limit - t[end]) / step), 0), max_samples))
        if n == 0:
            continue
        delta = r[inner].T @ r[end]
        ext, m = [], r[end]
        for _ in range(n):
            m = m @ delta
            ext.append(m)
        ext_t = t[end] + step * np.arange(1, n + 1)
        if end == 0:
            times.insert(0, ext_t[::-1])
            mats.insert(0, np.array(ext[::-1]))
        else:
            times.append(ext_t)
            mats.append(np.array(ext))
    r_all = np.concatenate(mats)
    # re-orthonormalise the products of many rotations before converting
    u, _, vt = np.linalg.svd(r_all)
    return np.concatenate(times), matrix_to_quaternion(u @ vt)


def _check_centre(meta: Dimap2, model: LinescanModel) -> None:
    c = meta.centre
    g = model.backproject(c.row, c.col, 0.0)
    got = np.stack(coords.geodetic_to_ecef(g.lon, g.lat, 0.0), axis=-1)
    want = np.stack(coords.geodetic_to_ecef(c.lon, c.lat, 0.0), axis=-1)
    miss = float(np.linalg.norm(got - want))
    if not miss <= CENTRE_TOLERANCE_M:
        raise DimapFormatError(
            meta.path, meta.attitude_source,
            f"the model puts the stated scene centre (row {c.row:g}, col {c.col:g}: "
            f"{c.lon:.6f}, {c.lat:.6f}) {miss / 1000:.1f} km away (tolerance "
            f"{CENTRE_TOLERANCE_M / 1000:g} km): the attitude is probably not sensor -> ECEF "
            "(inertial quaternions are not supported) or the time/look conventions differ")

