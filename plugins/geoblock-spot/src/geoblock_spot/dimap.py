"""Reader of DIMAP v1 ``METADATA.DIM`` files of SPOT 1-5 level 1A scenes and segments.

:func:`read_dimap` parses, with :mod:`xml.etree.ElementTree`, everything the DIMAP
line-of-sight model (:mod:`geoblock_spot.los`) and the accuracy checks need into an immutable
:class:`SpotDimap`:

* ephemeris (``Data_Strip/Ephemeris/Points/Point``: UTC time, ECEF position and velocity, m and
  m/s), the DORIS points' ``ERROR_ESTIMATION`` (m) when present;
* attitude: SPOT 5 ``Corrected_Attitudes`` (yaw, pitch, roll, rad) and the star-tracker
  quaternions ``Q0..Q3``; SPOT 1-4 ``Raw_Attitudes/Aocs_Attitude`` absolute ``Angles`` and
  ``Angular_Speeds`` (rad, rad/s), integrated by :meth:`SpotDimap.attitude_angles`;
* look angles ``PSI_X`` / ``PSI_Y`` (rad) per detector (two detectors, first and last, for
  SPOT 1-4; the full table for SPOT 5), line period, scene-centre time, line and column;
* image size, the ``Dataset_Frame`` corner vertices and scene centre, the ``Tie_Point``\\ s
  (with their height ``TIE_POINT_CRS_Z``) and the ``Simplified_Location_Model`` (the product's
  own quadratic image <-> ground polynomials, a second description of the geometry).

Conventions
-----------
**Pixels.** DIMAP numbers lines and columns from 1 (``Raster_CS/PIXEL_ORIGIN`` = 1) and its
``RASTER_CS_TYPE`` ``POINT`` puts integer coordinates at pixel centres. Every row/column read
here is converted once to geoblock's 0-based pixel centres:
``row = DIMAP_ROW - PIXEL_ORIGIN``, ``col = DIMAP_COL - PIXEL_ORIGIN`` (and a further
``- 0.5`` for a ``CELL`` raster, whose integers are pixel corners). ASP does the same
(``SPOT_XML.cc``, ``read_line_times``: "Convert from 1-based to 0-based indices").

**Times.** Every time is a float64 number of seconds since :attr:`SpotDimap.epoch`, the UTC
time of the first ephemeris point (ASP's reference time, ``SPOT_XML.cc`` ``parse_xml``); the
DIMAP time strings (``2005-03-13T05:21:07.332158``, UTC) are parsed to microseconds.

**Velocities.** SPOT 5 DIMAP velocities are Earth-fixed (the time derivative of the ECEF
positions). SPOT 1-4 DIMAP velocities are *inertial* velocities expressed on the ECEF axes:
they differ from the derivative of the positions by ``omega x P`` (about 400 m/s). The reader
does not trust the mission number for this: it differentiates the positions and records which
of the two the velocities match in :attr:`SpotDimap.velocity_frame` (``"earth-fixed"`` or
``"inertial"``), and refuses velocities that match neither. The SPOT geometry handbook builds
its local orbital frame from the velocity *as given* (ASP ``LinescanSpotModel.cc``
``get_local_orbital_frame``; COSI-Corr ``Spot_RSM.py``: "For SPOT1-4 spacecraft velocities are
expressed in the Earth Centered Reference System"), which :mod:`geoblock_spot.los` reproduces.

**Attitude.** The angles are those of the SPOT 123-4-5 Geometry Handbook (GAEL-P135-DOC-001,
eq. 11): the rotation ``M = Mp Mr My`` from the navigation frame to the local orbital frame,
used exactly as ASP (``LinescanSpotModel.cc`` ``get_look_rotation_matrix``), OSSIM
(``ossimSpot5Model.cpp`` ``computeSatToOrbRotation``) and COSI-Corr (``Spot_RSM.py``
``__SpotSat2NavMatrix``: ``Rx(-pitch) Ry(-roll) Rz(yaw)``, the same matrix) use them. For
SPOT 1-4 only relative gyro data exist: the angles are the first valid absolute ``Angles``
sample plus the time integral of the ``Angular_Speeds`` (handbook eq. 8, COSI-Corr
``__IntegrateRotationSpeed``), by the trapezoidal rule; samples flagged ``OUT_OF_RANGE`` are
dropped (COSI-Corr interpolates over them, which the trapezoid over the remaining samples does).

Look angles (``PSI_X`` along track, ``PSI_Y`` across track, rad) give the look direction
``normalize(-tan PSI_Y, tan PSI_X, -1)`` in the navigation frame (handbook eq. 5a; ASP
``LinescanSpotModel.cc``; COSI-Corr ``ComputeCCDLookAngles``). SPOT 1-4 give the first and the
last detector only; the others are interpolated linearly in detector number (COSI-Corr
``ComputeCCDLookAngles``, OSSIM ``getInterpolatedLookAngle``).

**Accuracy.** DIMAP v1 SPOT files state no location accuracy; :attr:`SpotDimap.location_accuracy_m`
gives the mission figure (``< 50 m`` without GCPs for SPOT 5, ``350 m`` for SPOT 1-4, ESA EO
portal "SPOT 5 description"; OSSIM uses 50 m with star tracker and 200 m without,
``ossimSpot5Model.cpp`` ``loadSupportData``) with its source in
:attr:`SpotDimap.location_accuracy_source`.
"""

from __future__ import annotations

import os
import re
import xml.etree.ElementTree as ET
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from geoblock.errors import GeoblockError, GeoblockIOError, ModelFormatError, ParameterSetError
from geoblock.io.metadata import XmlFields, parse_utc, read_bytes, read_xml
from geoblock.io.vsi import as_path
from geoblock.models.parameters import ParameterSet
from geoblock.pixels import PIXEL_CENTRE

__all__ = [
    "DimapFormatError",
    "EARTH_ROTATION_RAD_S",
    "AttitudeSamples",
    "GroundPoint",
    "SpotDimap",
    "is_spot_dimap",
    "read_dimap",
]

EARTH_ROTATION_RAD_S = 7.2921151467e-5
"""WGS84 angular velocity of the Earth, rad/s (about ECEF +z)."""

#: velocities within this many m/s of the positions' derivative are accepted
_VELOCITY_TOLERANCE_M_S = 5.0

# ---- physical plausibility of the fields a model is built from (issue 12, item 3); shared
# with :mod:`geoblock_spot.dimap2` (the ``check_*`` functions below). The orbit bounds are
# tighter than core's (:data:`geoblock.models.linescan.ORBIT_RADIUS_M`, ``MAX_SPEED_M_S``, any
# Earth-orbiting platform) and are checked when the file is read, before any model is built.
#: satellite distance from the Earth's centre, metres (SPOT 1-7 and Pleiades fly at 690-830 km)
SPOT_ORBIT_RADIUS_M = (6.5e6, 8.5e6)
#: satellite speed, m/s (about 7.4-7.5 km/s, inertial or Earth-fixed)
SPOT_MAX_SPEED_M_S = 1.0e4
#: image rows and columns (a SPOT 5 HRS segment has ~1e5 rows)
MAX_IMAGE_SIZE = 10_000_000
#: line period, seconds (SPOT 1-4: 1.5 ms, SPOT 5: 0.75 ms, Pleiades: 74 us)
MAX_LINE_PERIOD_S = 1.0
#: ``|tan|`` of a look angle (SPOT's +-27 degree mirror: 0.51)
MAX_LOOK_TANGENT = 1.0
#: ``|yaw|``, ``|pitch|``, ``|roll|`` of the attitude angles relative to the orbital frame, rad
#: (SPOT 1-5 files: below 1e-3), and of the gyro angular speeds, rad/s (below 3e-5)
MAX_ATTITUDE_ANGLE_RAD = 0.2
MAX_ANGULAR_SPEED_RAD_S = 0.01
#: ``| |q| - 1 |`` of a stated attitude quaternion (the files: below 1e-6)
QUATERNION_NORM_TOLERANCE = 1e-3
#: acquisition years accepted in time stamps
YEAR_RANGE = (1950, 2200)

#: mission location accuracy without ground control, metres (see the module docstring)
_MISSION_ACCURACY_M = {1: 350.0, 2: 350.0, 3: 350.0, 4: 350.0, 5: 50.0}
_ACCURACY_SOURCE = (
    "not stated in DIMAP v1; mission figure without GCPs (ESA EO portal, SPOT 5 description: "
    "'< 50 m ... instead of 350 m on SPOT 1 to 4')"
)


class DimapFormatError(ModelFormatError):
    """A SPOT DIMAP file is truncated or inconsistent; the message names the file and field.

    Attributes
    ----------
    path : str
        The metadata file.
    field : str
        The DIMAP element (path below the root) at fault.
    """

    def __init__(self, path: str | os.PathLike[str], field: str, problem: str):
        super().__init__(f"{str(path)!r}: DIMAP field {field}: {problem}")
        self.path = str(path)
        self.field = field


@contextmanager
def file_named(path: str | os.PathLike[str], field: str) -> Iterator[None]:
    """Re-raise a :class:`~geoblock.errors.GeoblockError` of the core model classes (which
    cannot know the file) naming ``path`` and the DIMAP ``field``.

    A :class:`ModelFormatError` becomes a :class:`DimapFormatError`; any other
    ``GeoblockError`` (``ParameterSetError`` ...) keeps its class, with the message
    ``"'path': DIMAP field field: message"`` and ``path`` / ``field`` attributes set (if the
    class cannot be built from a message alone, a ``DimapFormatError`` is raised instead). An
    error that already names ``path`` (a ``DimapFormatError``, or one re-raised by an inner
    ``file_named``) passes unchanged.
    """
    try:
        yield
    except GeoblockError as exc:
        if isinstance(exc, DimapFormatError) or getattr(exc, "path", None) == str(path):
            raise
        if isinstance(exc, ModelFormatError):
            raise DimapFormatError(path, field, str(exc)) from None
        try:
            named = type(exc)(f"{str(path)!r}: DIMAP field {field}: {exc}")
            named.path, named.field = str(path), field
        except Exception:  # a class whose constructor needs more than a message
            raise DimapFormatError(path, field, f"{type(exc).__name__}: {exc}") from exc
        raise named from None


def with_parameters(model, parameters: str | ParameterSet, path: str | os.PathLike[str],
                    names: tuple[str, ...]):
    """``model`` (a :class:`~geoblock.models.linescan.LinescanModel`) with the parameters a
    reader's ``parameters`` option asks for: a ``ParameterSet`` (replaces the model's) or one
    of the parameter-set ``names`` (``model.with_parameter_set(name)``).

    Raises
    ------
    ParameterSetError
        Any other ``parameters``, or a set the model cannot give (``"dg"`` without an
        accuracy); the message names ``path``.
    DimapFormatError
        The model refuses the ``ParameterSet``.
    """
    with file_named(path, "(model)"):
        if isinstance(parameters, ParameterSet):
            return model.replace(parameters=parameters)
        if isinstance(parameters, str) and parameters in names:
            return model.with_parameter_set(parameters)
    known = ", ".join(repr(n) for n in names[:-1]) + f" or {names[-1]!r}" if len(names) > 1 \
        else repr(names[0])
    raise ParameterSetError(f"{str(path)!r}: parameters must be {known}, or a ParameterSet, "
                            f"got {parameters!r}")


# ---------------------------------------------------------------------- plausibility checks
def _sample(field: str, i: int) -> tuple[str, str]:
    """The field of sample ``i`` (``field`` may hold ``{i}``, the 0-based index) and, when it
    does not, a ``"point i+1 "`` to name the sample in the message."""
    return (field.format(i=i), "") if "{i}" in field else (field, f"point {i + 1} ")


def check_orbit_radius(path: str | os.PathLike[str], field: str, position_m: np.ndarray
                       ) -> None:
    """Refuse ECEF positions (n, 3) outside :data:`SPOT_ORBIT_RADIUS_M` of the Earth's centre."""
    radius = np.linalg.norm(position_m, axis=1)
    lo, hi = SPOT_ORBIT_RADIUS_M
    bad = np.flatnonzero(~((radius >= lo) & (radius <= hi)))
    if bad.size:
        where, point = _sample(field, int(bad[0]))
        raise DimapFormatError(path, where,
                               f"{point}is {radius[bad[0]] / 1000:.6g} km from the Earth's "
                               f"centre: not a satellite orbit (radius outside "
                               f"{lo / 1000:g}-{hi / 1000:g} km)")


def check_speed(path: str | os.PathLike[str], field: str, velocity_m_s: np.ndarray) -> None:
    """Refuse velocities (n, 3) of :data:`SPOT_MAX_SPEED_M_S` or more (or NaN)."""
    speed = np.linalg.norm(velocity_m_s, axis=1)
    bad = np.flatnonzero(~(speed < SPOT_MAX_SPEED_M_S))
    if bad.size:
        where, point = _sample(field, int(bad[0]))
        raise DimapFormatError(path, where,
                               f"{point}moves at {speed[bad[0]]:.6g} m/s: not a satellite "
                               f"velocity (speed must be < {SPOT_MAX_SPEED_M_S:g} m/s)")


def check_unit_quaternions(path: str | os.PathLike[str], field: str, q: np.ndarray,
                           label: Callable[[int], str] | None = None) -> None:
    """Refuse quaternions (n, 4) whose norm is off 1 by more than
    :data:`QUATERNION_NORM_TOLERANCE` (or NaN). ``label(i)`` starts the message about sample
    ``i`` (default: ``"quaternion i+1 "`` unless ``field`` names the sample)."""
    norm = np.linalg.norm(q, axis=1)
    bad = np.flatnonzero(~(np.abs(norm - 1.0) <= QUATERNION_NORM_TOLERANCE))
    if bad.size:
        i = int(bad[0])
        where, point = _sample(field, i)
        start = label(i) if label is not None else (f"quaternion {i + 1} " if point else "")
        raise DimapFormatError(path, where,
                               f"{start}has norm {norm[i]:.6g}: not a unit quaternion "
                               f"(tolerance {QUATERNION_NORM_TOLERANCE:g})")


def parse_time(path: str | os.PathLike[str], field: str, text: str) -> np.datetime64:
    """``text`` (ISO-8601 UTC, optional ``Z``) as a ``datetime64[us]``, refused unless its
    year is within :data:`YEAR_RANGE` (:func:`geoblock.io.metadata.parse_utc`)."""
    return parse_utc(text, lambda f, problem: DimapFormatError(path, f, problem), field,
                     years=YEAR_RANGE)


#: ``|value|`` limits of a stated ground point's fields
GROUND_POINT_LIMITS = {"lon": 360.0, "lat": 90.0, "h": 1e5, "row": MAX_IMAGE_SIZE,
                       "col": MAX_IMAGE_SIZE}


def check_ground_value(path: str | os.PathLike[str], field: str, kind: str, value: float
                       ) -> float:
    """Refuse a ground point's ``kind`` (``lon``, ``lat``, ``h``, ``row``, ``col``) value
    beyond :data:`GROUND_POINT_LIMITS`; returns ``value``."""
    limit = GROUND_POINT_LIMITS[kind]
    if not abs(value) <= limit:
        raise DimapFormatError(path, field, f"{value!r} is not plausible (|value| must be <= "
                                            f"{limit:g})")
    return value


@dataclass(frozen=True)
class GroundPoint:
    """An image point with its ground position, as the product states it.

    ``row, col`` are geoblock 0-based pixel centres (converted from DIMAP's 1-based numbers);
    ``lon, lat`` degrees; ``h`` metres above the ellipsoid (``TIE_POINT_CRS_Z``; 0 for the
    ``Dataset_Frame`` vertices, which state no height and equal the ``h = 0`` tie points).
    """

    lon: float
    lat: float
    h: float
    row: float
    col: float


@dataclass(frozen=True, eq=False)
class AttitudeSamples:
    """Time-tagged yaw, pitch and roll (rad, or rad/s for angular speeds).

    Attributes
    ----------
    time_s : ndarray, (m,)
        Seconds since the epoch, strictly increasing.
    angles : ndarray, (m, 3)
        Columns yaw, pitch, roll.
    out_of_range : ndarray of bool, (m,)
        DIMAP's ``OUT_OF_RANGE`` flag (``Y``).
    """

    time_s: np.ndarray
    angles: np.ndarray
    out_of_range: np.ndarray

    def valid(self) -> AttitudeSamples:
        """The samples not flagged out of range."""
        keep = ~self.out_of_range
        return AttitudeSamples(self.time_s[keep], self.angles[keep], self.out_of_range[keep])


@dataclass(frozen=True, eq=False)
class SpotDimap:
    """Parsed DIMAP v1 metadata of a SPOT 1-5 level 1A scene or segment.

    All rows/columns are geoblock 0-based pixel centres; all times seconds since
    :attr:`epoch`; angles radians; positions metres and velocities m/s in ECEF (EPSG:4978).

    Attributes
    ----------
    path : pathlib.Path
        The metadata file read.
    mission : int
        ``MISSION_INDEX`` (1-5).
    instrument : str
        ``INSTRUMENT`` + ``INSTRUMENT_INDEX`` (``"HRV1"``, ``"HRG1"``, ``"HRS1"`` ...).
    sensor_code : str
        ``SENSOR_CODE`` (``P``, ``M``, ``A``, ``S`` ...).
    profile : str
        ``METADATA_PROFILE`` (``SPOTSCENE_1A``, ``SPOTSEGMENT_1A``).
    shape : tuple of int
        ``(NROWS, NCOLS)``.
    epoch : str
        ISO-8601 UTC time of the first ephemeris point (time origin).
    line_period_s : float
        ``LINE_PERIOD``, seconds.
    scene_center_time_s, scene_center_row, scene_center_col : float
        ``SCENE_CENTER_TIME`` / ``_LINE`` / ``_COL`` (0-based).
    ephemeris_time_s : ndarray, (n,)
    position_m, velocity_m_s : ndarray, (n, 3)
        As in the file (see :attr:`velocity_frame`).
    velocity_frame : str
        ``"earth-fixed"`` or ``"inertial"`` (inertial velocity on ECEF axes; SPOT 1-4).
    doris_used : bool
    doris_error_m : ndarray, (k,)
        ``ERROR_ESTIMATION`` of the DORIS points (empty if none).
    raw_angles, angular_speeds, corrected_angles : AttitudeSamples or None
        AOCS absolute angles, gyro angular speeds, SPOT 5 corrected attitudes.
    quaternion_time_s : ndarray, (q,) ; quaternions : ndarray, (q, 4)
        Star-tracker ``Q0..Q3`` as given (empty when absent; informational, not used).
    star_tracker_used : bool or None
        ``STAR_TRACKER_USED`` (None when absent).
    look_detector_col : ndarray of float, (k,)
        0-based column of each ``Look_Angles`` entry (``DETECTOR_ID - 1``).
    psi_x, psi_y : ndarray, (k,)
        ``PSI_X`` (along track) and ``PSI_Y`` (across track) look angles, rad.
    vertices : tuple of GroundPoint
        ``Dataset_Frame/Vertex`` (4 corners, ``h = 0``).
    scene_center : GroundPoint or None
        ``Dataset_Frame/Scene_Center``.
    tie_points : tuple of GroundPoint
        ``Geoposition/Geoposition_Points/Tie_Point``.
    direct_location, reverse_location : ndarray, (2, 6) or None
        ``Simplified_Location_Model`` coefficients (``lc``, ``pc`` rows), see
        :meth:`simplified_image_to_ground`.
    incidence_angle_deg, viewing_angle_deg : float
        NaN when absent.
    mirror_step_count : int or None
        ``Mirror_Position/STEP_COUNT`` (SPOT 1-4 HRV mirror; already included in the look angles).
    location_accuracy_m : float
        Mission location accuracy without GCPs (not stated in the file; see the module notes).
    location_accuracy_source : str
    """

    path: Path
    mission: int
    instrument: str
    sensor_code: str
    profile: str
    shape: tuple[int, int]
    epoch: str
    line_period_s: float
    scene_center_time_s: float
    scene_center_row: float
    scene_center_col: float
    ephemeris_time_s: np.ndarray
    position_m: np.ndarray
    velocity_m_s: np.ndarray
    velocity_frame: str
    doris_used: bool
    doris_error_m: np.ndarray
    raw_angles: AttitudeSamples | None
    angular_speeds: AttitudeSamples | None
    corrected_angles: AttitudeSamples | None
    quaternion_time_s: np.ndarray
    quaternions: np.ndarray
    star_tracker_used: bool | None
    look_detector_col: np.ndarray
    psi_x: np.ndarray
    psi_y: np.ndarray
    vertices: tuple[GroundPoint, ...]
    scene_center: GroundPoint | None
    tie_points: tuple[GroundPoint, ...]
    direct_location: np.ndarray | None
    reverse_location: np.ndarray | None
    incidence_angle_deg: float
    viewing_angle_deg: float
    mirror_step_count: int | None
    location_accuracy_m: float
    location_accuracy_source: str

    # ------------------------------------------------------------------ derived values
    @property
    def scene_width(self) -> int:
        """Number of columns of the scene the geolocation refers to.

        ``NCOLS`` unless the tie points or the scene-centre column lie beyond it, as in a
        metadata file cropped after production (ASP's ``spot_example1.xml``: ``NCOLS`` 300,
        tie points at column 12000): then ``2 * scene_center_col`` (DIMAP puts the scene centre
        at column ``N/2 + 1``) or the last tie-point column + 1, whichever is larger.
        """
        width = self.shape[1]
        candidates = [width]
        if self.scene_center_col > width - 1:
            candidates.append(int(round(2 * self.scene_center_col)))
        candidates += [int(round(p.col)) + 1 for p in self.tie_points]
        return max(candidates)

    def attitude_angles(self) -> tuple[np.ndarray, np.ndarray, str]:
        """The attitude samples the line-of-sight model uses.

        Returns
        -------
        time_s : ndarray, (m,)
            Seconds since the epoch.
        ypr : ndarray, (m, 3)
            Yaw, pitch, roll, rad (handbook navigation -> orbital frame angles).
        source : str
            ``"corrected"`` (SPOT 5 ``Corrected_Attitudes``) or ``"integrated"`` (SPOT 1-4: the
            first valid ``Angles`` sample plus the trapezoidal integral of the valid
            ``Angular_Speeds``, extended to the last ``Angles`` time with the last speed).

        Raises
        ------
        DimapFormatError
            Fewer than two valid samples.
        """
        if self.corrected_angles is not None:
            att = self.corrected_angles.valid()
            if att.time_s.size < 2:
                raise DimapFormatError(self.path, _CORRECTED, "fewer than 2 valid samples")
            return att.time_s, att.angles, "corrected"
        speeds = self.angular_speeds.valid() if self.angular_speeds is not None else None
        if speeds is None or speeds.time_s.size < 2:
            raise DimapFormatError(
                self.path, _SPEEDS, "fewer than 2 valid angular-speed samples (and no "
                "Corrected_Attitudes): the attitude cannot be integrated"
            )
        raw = self.raw_angles.valid() if self.raw_angles is not None else None
        if raw is not None and raw.time_s.size:
            t0, a0, t_end = raw.time_s[0], raw.angles[0], raw.time_s[-1]
        else:  # COSI-Corr: invalid absolute angles are replaced by a null attitude
            t0, a0, t_end = speeds.time_s[0], np.zeros(3), speeds.time_s[-1]
        keep = speeds.time_s > t0
        times = np.concatenate([[t0], speeds.time_s[keep]])
        rates = np.concatenate([speeds.angles[keep][:1] if keep.any() else speeds.angles[-1:],
                                speeds.angles[keep]])
        if t_end > times[-1]:
            times = np.append(times, t_end)
            rates = np.vstack([rates, rates[-1:]])
        steps = 0.5 * (rates[1:] + rates[:-1]) * np.diff(times)[:, None]
        angles = a0 + np.vstack([np.zeros((1, 3)), np.cumsum(steps, axis=0)])
        return times, angles, "integrated"

    def look_angles(self, cols: int | None = None) -> tuple[np.ndarray, np.ndarray]:
        """``PSI_X``, ``PSI_Y`` (rad) for every detector ``0 .. cols-1``.

        Parameters
        ----------
        cols : int, optional
            Number of detectors wanted; default :attr:`scene_width`, the width the product's
            geolocation refers to.

        Returns
        -------
        psi_x, psi_y : ndarray, (cols,)

        Raises
        ------
        DimapFormatError
            The table does not cover the detectors: a full table (more than 2 entries, SPOT 5)
            must list every detector of the scene; a two-entry table (SPOT 1-4) must give the
            first and the last detector of the scene.
        """
        cols = self.scene_width if cols is None else int(cols)
        det = self.look_detector_col
        covers = det[0] == 0 and det[-1] == cols - 1
        if det.size > 2:
            covers = covers and det.size == cols and np.array_equal(det, np.arange(cols))
        if not covers:
            cropped = (
                f" (the file says NCOLS {self.shape[1]} but its geolocation refers to a "
                f"{cols}-column scene: the metadata was cropped)" if cols != self.shape[1] else ""
            )
            raise DimapFormatError(
                self.path, _LOOK,
                f"the look-angle table covers detectors {int(det[0]) + 1}..{int(det[-1]) + 1} "
                f"({det.size} entries) but the image has {cols} columns{cropped}; the look-angle "
                "table doesn't cover the image, so no full-scene model can be built",
            )
        if det.size == cols:
            return self.psi_x.copy(), self.psi_y.copy()
        c = np.arange(cols, dtype=np.float64)
        return np.interp(c, det, self.psi_x), np.interp(c, det, self.psi_y)

    def earth_fixed_velocity_m_s(self) -> np.ndarray:
        """(n, 3) the time derivative of the ECEF positions, m/s (``V - omega x P`` if inertial)."""
        if self.velocity_frame == "earth-fixed":
            return self.velocity_m_s.copy()
        return self.velocity_m_s - _omega_cross(self.position_m)

    def inertial_velocity_m_s(self) -> np.ndarray:
        """(n, 3) inertial velocity on the ECEF axes, m/s (``V + omega x P`` if Earth-fixed)."""
        if self.velocity_frame == "inertial":
            return self.velocity_m_s.copy()
        return self.velocity_m_s + _omega_cross(self.position_m)

    def simplified_image_to_ground(self, row, col) -> tuple[np.ndarray, np.ndarray]:
        """The product's ``Direct_Location_Model``: image -> ``(lon, lat)`` degrees at ``h = 0``.

        A quadratic ``lon = sum(lc * m)``, ``lat = sum(pc * m)`` with
        ``m = [1, R, C, R C, R^2, C^2]`` in DIMAP's 1-based ``R = row + 1``, ``C = col + 1``
        (ordering found by evaluating it at the ``Dataset_Frame`` vertices: it reproduces them
        to a few metres). ``row, col`` are geoblock 0-based pixel centres.
        """
        if self.direct_location is None:
            raise DimapFormatError(self.path, _SIMPLIFIED, "no Direct_Location_Model")
        r = np.asarray(row, np.float64) + 1.0
        c = np.asarray(col, np.float64) + 1.0
        m = np.stack([np.ones_like(r * c), r, c, r * c, r * r, c * c], axis=-1)
        return m @ self.direct_location[0], m @ self.direct_location[1]

    def simplified_ground_to_image(self, lon, lat) -> tuple[np.ndarray, np.ndarray]:
        """The product's ``Reverse_Location_Model``: ``(lon, lat)`` at ``h = 0`` -> ``(row, col)``.

        ``R = sum(lc * m)``, ``C = sum(pc * m)`` with ``m = [1, lat, lon, lat lon, lat^2, lon^2]``
        (degrees; DIMAP 1-based ``R, C``; ordering found at the vertices, within ~0.5 px).
        """
        if self.reverse_location is None:
            raise DimapFormatError(self.path, _SIMPLIFIED, "no Reverse_Location_Model")
        x = np.asarray(lat, np.float64)
        y = np.asarray(lon, np.float64)
        m = np.stack([np.ones_like(x * y), x, y, x * y, x * x, y * y], axis=-1)
        return m @ self.reverse_location[0] - 1.0, m @ self.reverse_location[1] - 1.0

    def __repr__(self) -> str:
        return (
            f"SpotDimap(SPOT{self.mission} {self.instrument} {self.sensor_code}, "
            f"{self.shape[0]}x{self.shape[1]}, epoch {self.epoch}, {self.path.name})"
        )


# ---------------------------------------------------------------------- element paths
_EPHEMERIS = "Data_Strip/Ephemeris/Points/Point"
_ATTITUDES = "Data_Strip/Satellite_Attitudes"
_ANGLES = _ATTITUDES + "/Raw_Attitudes/Aocs_Attitude/Angles_List/Angles"
_SPEEDS = _ATTITUDES + "/Raw_Attitudes/Aocs_Attitude/Angular_Speeds_List/Angular_Speeds"
_CORRECTED = _ATTITUDES + "/Corrected_Attitudes/Corrected_Attitude/Angles"
_QUATERNIONS = _ATTITUDES + "/Raw_Attitudes/Star_Tracker_Attitude/Quaternion_List/Quaternion"
_TIME_STAMP = "Data_Strip/Sensor_Configuration/Time_Stamp"
_LOOK_LISTS = "Data_Strip/Sensor_Configuration/Instrument_Look_Angles_List/Instrument_Look_Angles"
_LOOK = _LOOK_LISTS + "/Look_Angles_List/Look_Angles"
_SIMPLIFIED = "Geoposition/Simplified_Location_Model"
_SOURCE = "Dataset_Sources/Source_Information/Scene_Source"

#: the elements a model needs (the fuzz tests drop each and expect DimapFormatError naming it)
REQUIRED_FIELDS = (
    "Raster_Dimensions/NROWS",
    "Raster_Dimensions/NCOLS",
    _SOURCE + "/MISSION_INDEX",
    _EPHEMERIS,
    _TIME_STAMP + "/LINE_PERIOD",
    _TIME_STAMP + "/SCENE_CENTER_TIME",
    _TIME_STAMP + "/SCENE_CENTER_LINE",
    _TIME_STAMP + "/SCENE_CENTER_COL",
    _LOOK,
)


def _omega_cross(p: np.ndarray) -> np.ndarray:
    """``omega x P`` for the Earth's rotation about +z, (n, 3) m/s."""
    return EARTH_ROTATION_RAD_S * np.stack([-p[:, 1], p[:, 0], np.zeros(len(p))], axis=1)


# ---------------------------------------------------------------------- sniffing
def _metadata_file(path: str | os.PathLike[str]) -> Path:
    """The metadata file: ``path`` itself, or ``METADATA.DIM`` inside a product directory."""
    path = as_path(path)  # a GDAL virtual path (/vsizip/...) stays one
    if path.is_dir():
        for child in sorted(path.iterdir()):
            if child.name.upper() == "METADATA.DIM" and child.is_file():
                return child
        raise GeoblockIOError(f"{str(path)!r}: directory has no METADATA.DIM (SPOT DIMAP product)")
    if not path.is_file():
        raise GeoblockIOError(f"{str(path)!r} does not exist or is not a file")
    return path


def is_spot_dimap(path: str | os.PathLike[str]) -> bool:
    """Whether ``path`` (a file or a product directory) looks like a SPOT DIMAP v1 document.

    Reads the first 8 kB: a ``Dimap_Document`` whose ``METADATA_FORMAT`` is ``DIMAP`` version
    1.x and whose ``METADATA_PROFILE`` starts with ``SPOT``.
    """
    try:
        head = read_bytes(_metadata_file(path), 8192).decode("utf-8", "replace")
    except (OSError, GeoblockIOError):  # GeoblockIOError: missing, a directory without one
        return False
    if "<Dimap_Document" not in head:
        return False
    try:
        fmt = head.split("<METADATA_FORMAT", 1)[1].split("</METADATA_FORMAT>", 1)[0]
        profile = head.split("<METADATA_PROFILE>", 1)[1].split("</METADATA_PROFILE>", 1)[0]
    except IndexError:
        return False
    return bool(re.match(r"\s+version\s*=\s*[\"']1\.", fmt)) and (
        profile.strip().upper().startswith("SPOT"))


# ---------------------------------------------------------------------- parsing helpers
def _angle_samples(doc: XmlFields, field: str, seconds: Callable[[np.datetime64], float],
                   time_tag: str = "TIME") -> AttitudeSamples | None:
    """The yaw/pitch/roll samples at ``field`` (None when there are none)."""
    items = doc.nodes(field)
    if not items:
        return None
    t = np.array([seconds(doc.time(time_tag, e, field + "/", years=YEAR_RANGE)) for e in items])
    ang = np.array(
        [[doc.number(k, e, field + "/") for k in ("YAW", "PITCH", "ROLL")] for e in items]
    ).reshape(-1, 3)
    limit, what = ((MAX_ANGULAR_SPEED_RAD_S, "angular speed (rad/s)") if field == _SPEEDS
                   else (MAX_ATTITUDE_ANGLE_RAD, "angle (rad)"))
    for k, name in enumerate(("YAW", "PITCH", "ROLL")):
        doc.bounded(ang[:, k], limit, f"{field}/{name}", what)
    oor = np.array([(e.findtext("OUT_OF_RANGE") or "N").strip().upper() == "Y" for e in items])
    doc.increasing(t, field, "times")
    return AttitudeSamples(t, ang, oor)


def _vectors(doc: XmlFields, items: list[ET.Element], sub: str, field: str) -> np.ndarray:
    """(n, 3) the ``sub/X``, ``sub/Y``, ``sub/Z`` numbers of each element of ``items``."""
    return np.array(
        [[doc.number(f"{sub}/{c}", e, field + "/") for c in "XYZ"] for e in items]
    ).reshape(-1, 3)


def _position_derivative(t: np.ndarray, p: np.ndarray) -> np.ndarray:
    """(n, 3) dP/dt at the samples from local polynomials through up to 7 neighbours."""
    n = t.size
    half = min(3, (n - 1) // 2) if n > 2 else 0
    out = np.empty_like(p)
    for i in range(n):  # n ~ 10 ephemeris samples: a loop over samples, not points
        lo = min(max(i - half, 0), max(n - (2 * half + 1), 0))
        sl = slice(lo, min(lo + 2 * half + 1, n)) if n > 2 else slice(0, n)
        tt = t[sl] - t[i]
        scale = max(float(np.abs(tt).max()), 1.0)
        deg = len(tt) - 1
        coeffs = np.polyfit(tt / scale, p[sl], deg)  # (deg+1, 3), highest power first
        out[i] = coeffs[-2] / scale
    return out


# ---------------------------------------------------------------------- reader
def read_dimap(path: str | os.PathLike[str]) -> SpotDimap:
    """Read a SPOT 1-5 DIMAP v1 ``METADATA.DIM`` (or a product directory containing it).

    Parameters
    ----------
    path : str or path-like
        The metadata file (any name: ``METADATA.DIM``, ``spot_example1.xml``) or the product
        directory.

    Returns
    -------
    SpotDimap

    Raises
    ------
    GeoblockIOError
        The file does not exist or cannot be read.
    DimapFormatError
        Not a SPOT DIMAP v1 document, not raw (level 1A) geometry, or truncated/inconsistent
        metadata; the message names the file and the DIMAP field.
    """
    file = _metadata_file(path)
    doc = read_xml(file, DimapFormatError)
    root = doc.root
    if root.tag != "Dimap_Document":
        raise doc.error("(root)", f"root element is <{root.tag}>, not <Dimap_Document>")
    fmt = doc.find("Metadata_Id/METADATA_FORMAT")
    version = "" if fmt is None else fmt.get("version", "")
    if fmt is None or (fmt.text or "").strip() != "DIMAP" or not version.startswith("1."):
        raise doc.error("Metadata_Id/METADATA_FORMAT",
                        f"not DIMAP version 1.x (got version {version!r}); SPOT 6/7 DIMAP v2 "
                        "physical metadata is not read by this reader")
    profile = doc.optional_text("Metadata_Id/METADATA_PROFILE") or ""
    level = doc.optional_text("Data_Processing/PROCESSING_LEVEL") or ""
    if not profile.upper().startswith("SPOT"):
        raise doc.error("Metadata_Id/METADATA_PROFILE", f"{profile!r} is not a SPOT profile")
    if level and level.upper() != "1A":
        raise doc.error("Data_Processing/PROCESSING_LEVEL",
                        f"level {level!r}: only level 1A (raw geometry) has a line-of-sight model")
    mission_name = doc.optional_text(_SOURCE + "/MISSION")
    if mission_name is not None and mission_name.upper() != "SPOT":
        raise doc.error(_SOURCE + "/MISSION", f"{mission_name!r} is not SPOT")
    mission = doc.integer(_SOURCE + "/MISSION_INDEX")
    if mission not in _MISSION_ACCURACY_M:
        raise doc.error(_SOURCE + "/MISSION_INDEX", f"SPOT {mission}: only SPOT 1-5 are DIMAP v1")

    # ---- pixel convention
    origin_text = doc.optional_text("Raster_CS/PIXEL_ORIGIN")
    origin = 1.0 if origin_text is None else doc.number("Raster_CS/PIXEL_ORIGIN")
    if origin not in (0.0, 1.0):
        raise doc.error("Raster_CS/PIXEL_ORIGIN", f"{origin_text!r}: must be 0 or 1")
    cs_type = (doc.optional_text("Raster_CS/RASTER_CS_TYPE") or "POINT").upper()
    if cs_type not in ("POINT", "CELL"):
        raise doc.error("Raster_CS/RASTER_CS_TYPE", f"{cs_type!r} is neither POINT nor CELL")
    offset = origin + (PIXEL_CENTRE if cs_type == "CELL" else 0.0)  # geoblock = DIMAP - offset

    rows = doc.integer("Raster_Dimensions/NROWS", minimum=1, maximum=MAX_IMAGE_SIZE)
    cols = doc.integer("Raster_Dimensions/NCOLS", minimum=2, maximum=MAX_IMAGE_SIZE)

    # ---- ephemeris and the time origin
    points = doc.nodes(_EPHEMERIS, minimum=2)
    times = [doc.time("TIME", p, _EPHEMERIS + "/", years=YEAR_RANGE) for p in points]
    epoch64 = min(times)

    def seconds(t64: np.datetime64) -> float:
        return float((t64 - epoch64) / np.timedelta64(1, "us")) * 1e-6

    eph_t = np.array([seconds(t) for t in times])
    doc.increasing(eph_t, _EPHEMERIS + "/TIME", "times")
    pos = _vectors(doc, points, "Location", _EPHEMERIS)
    vel = _vectors(doc, points, "Velocity", _EPHEMERIS)
    check_orbit_radius(file, _EPHEMERIS + "/Location", pos)
    check_speed(file, _EPHEMERIS + "/Velocity", vel)
    derivative = _position_derivative(eph_t, pos)
    err_fixed = np.abs(derivative - vel).max()
    err_inertial = np.abs(derivative - (vel - _omega_cross(pos))).max()
    if len(points) < 3:  # no derivative check possible: trust the mission convention
        velocity_frame = "earth-fixed" if mission == 5 else "inertial"
    elif err_fixed <= _VELOCITY_TOLERANCE_M_S:
        velocity_frame = "earth-fixed"
    elif err_inertial <= _VELOCITY_TOLERANCE_M_S:
        velocity_frame = "inertial"
    else:
        raise doc.error(
            _EPHEMERIS + "/Velocity",
            f"velocities disagree with the positions' time derivative by {err_fixed:.1f} m/s "
            f"(Earth-fixed) / {err_inertial:.1f} m/s (inertial): inconsistent ephemeris",
        )
    doris_used = (doc.optional_text("Data_Strip/Ephemeris/DORIS_USED") or "N").upper() == "Y"
    doris = doc.nodes("Data_Strip/Ephemeris/Doris_Points/Doris_Point")
    doris_err = np.array(
        [doc.number("ERROR_ESTIMATION", d, "Doris_Point/")
         for d in doris if d.find("ERROR_ESTIMATION") is not None]
    )

    # ---- line dating
    period = doc.number(_TIME_STAMP + "/LINE_PERIOD")
    if not 0 < period <= MAX_LINE_PERIOD_S:
        raise doc.error(_TIME_STAMP + "/LINE_PERIOD",
                        f"{period!r} s: a line period must be > 0 and <= {MAX_LINE_PERIOD_S:g} s")
    center_time = seconds(doc.time(_TIME_STAMP + "/SCENE_CENTER_TIME", years=YEAR_RANGE))
    center_row = doc.number(_TIME_STAMP + "/SCENE_CENTER_LINE") - offset
    center_col = doc.number(_TIME_STAMP + "/SCENE_CENTER_COL") - offset
    for name, value in (("SCENE_CENTER_LINE", center_row), ("SCENE_CENTER_COL", center_col)):
        doc.bounded(np.array([value]), MAX_IMAGE_SIZE, f"{_TIME_STAMP}/{name}", "pixel")

    # ---- attitude
    raw = _angle_samples(doc, _ANGLES, seconds)
    speeds = _angle_samples(doc, _SPEEDS, seconds)
    corrected = _angle_samples(doc, _CORRECTED, seconds)
    if corrected is None and speeds is None:
        raise doc.error(_ATTITUDES, "neither Corrected_Attitudes nor Aocs_Attitude "
                        "Angular_Speeds: no attitude (truncated metadata?)")
    quats = doc.nodes(_QUATERNIONS)
    q_t = np.array([seconds(doc.time("Q_TIME", q, _QUATERNIONS + "/", years=YEAR_RANGE))
                    for q in quats])
    q = np.array([[doc.number(f"Q{k}", e, _QUATERNIONS + "/") for k in range(4)]
                  for e in quats]).reshape(-1, 4)
    doc.increasing(q_t, _QUATERNIONS + "/Q_TIME", "times")
    check_unit_quaternions(file, _QUATERNIONS + "/Q0..Q3", q)
    star = doc.optional_text(_ATTITUDES + "/Corrected_Attitudes/STAR_TRACKER_USED")

    # ---- look angles (first band's table)
    look_list = doc.find(_LOOK_LISTS)
    look = [] if look_list is None else doc.nodes("Look_Angles_List/Look_Angles", look_list,
                                                  _LOOK_LISTS + "/")
    if len(look) < 2:
        raise doc.error(_LOOK, f"{len(look)} element(s), at least 2 needed (truncated metadata?)")
    det = np.array([doc.integer("DETECTOR_ID", e, _LOOK + "/") for e in look], float)
    psi_x = np.array([doc.number("PSI_X", e, _LOOK + "/") for e in look])
    psi_y = np.array([doc.number("PSI_Y", e, _LOOK + "/") for e in look])
    if not np.all(np.diff(det) > 0):
        raise doc.error(_LOOK + "/DETECTOR_ID", "detector numbers are not strictly increasing")
    if det[0] < 1 or det[-1] > MAX_IMAGE_SIZE:
        raise doc.error(_LOOK + "/DETECTOR_ID",
                        f"detectors {int(det[0])}..{int(det[-1])}: must be from 1 to "
                        f"{MAX_IMAGE_SIZE}")
    for name, psi in (("PSI_X", psi_x), ("PSI_Y", psi_y)):
        # radians expected; |tan| < 1: within +-45 degrees of the nadir
        tangent = np.where(np.abs(psi) < np.pi / 2, np.tan(psi), np.inf)
        doc.bounded(tangent, MAX_LOOK_TANGENT, f"{_LOOK}/{name}", "look-angle tangent")

    # ---- geolocation stated by the product
    def ground_point(e: ET.Element, field: str, tags: tuple[str, str, str | None, str, str]
                     ) -> GroundPoint:
        lon, lat, h, row, col = (
            0.0 if tag is None or (k == 2 and e.find(tag) is None)
            else check_ground_value(file, f"{field}/{tag}", kind,
                                    doc.number(tag, e, field + "/"))
            for k, (tag, kind) in enumerate(zip(tags, GROUND_POINT_LIMITS, strict=True)))
        return GroundPoint(lon=lon, lat=lat, h=h, row=row - offset, col=col - offset)

    def frame_point(e: ET.Element, field: str) -> GroundPoint:
        return ground_point(e, field, ("FRAME_LON", "FRAME_LAT", None, "FRAME_ROW", "FRAME_COL"))

    vertices = tuple(frame_point(v, "Dataset_Frame/Vertex")
                     for v in doc.nodes("Dataset_Frame/Vertex"))
    center_elem = doc.find("Dataset_Frame/Scene_Center")
    scene_center = None if center_elem is None else frame_point(center_elem,
                                                                "Dataset_Frame/Scene_Center")
    tie_field = "Geoposition/Geoposition_Points/Tie_Point"
    tie_points = tuple(
        ground_point(t, tie_field, ("TIE_POINT_CRS_X", "TIE_POINT_CRS_Y", "TIE_POINT_CRS_Z",
                                    "TIE_POINT_DATA_Y", "TIE_POINT_DATA_X"))
        for t in doc.nodes(tie_field)
    )

    def simplified(kind: str) -> np.ndarray | None:
        field = f"{_SIMPLIFIED}/{kind}"
        node = doc.find(field)
        if node is None:
            return None
        lc = [doc.number(".", e, field + "/lc_List/lc/") for e in node.findall("lc_List/lc")]
        pc = [doc.number(".", e, field + "/pc_List/pc/") for e in node.findall("pc_List/pc")]
        if len(lc) != 6 or len(pc) != 6:
            raise doc.error(field, f"{len(lc)} lc and {len(pc)} pc coefficients, 6 each expected")
        return np.array([lc, pc])

    def opt_float(sub: str) -> float:
        return np.nan if doc.optional_text(sub) is None else doc.number(sub)

    step_field = "Data_Strip/Sensor_Configuration/Mirror_Position/STEP_COUNT"
    step = None if doc.optional_text(step_field) is None else doc.integer(step_field)
    instrument = (doc.optional_text(_SOURCE + "/INSTRUMENT") or "") + (
        doc.optional_text(_SOURCE + "/INSTRUMENT_INDEX") or "")
    return SpotDimap(
        path=file,
        mission=mission,
        instrument=instrument,
        sensor_code=doc.optional_text(_SOURCE + "/SENSOR_CODE") or "",
        profile=profile,
        shape=(rows, cols),
        epoch=str(epoch64) + "Z",
        line_period_s=period,
        scene_center_time_s=center_time,
        scene_center_row=center_row,
        scene_center_col=center_col,
        ephemeris_time_s=eph_t,
        position_m=pos,
        velocity_m_s=vel,
        velocity_frame=velocity_frame,
        doris_used=doris_used,
        doris_error_m=doris_err,
        raw_angles=raw,
        angular_speeds=speeds,
        corrected_angles=corrected,
        quaternion_time_s=q_t,
        quaternions=q,
        star_tracker_used=None if star is None else star.upper() == "Y",
        look_detector_col=det - 1.0,
        psi_x=psi_x,
        psi_y=psi_y,
        vertices=vertices,
        scene_center=scene_center,
        tie_points=tie_points,
        direct_location=simplified("Direct_Location_Model"),
        reverse_location=simplified("Reverse_Location_Model"),
        incidence_angle_deg=opt_float(_SOURCE + "/INCIDENCE_ANGLE"),
        viewing_angle_deg=opt_float(_SOURCE + "/VIEWING_ANGLE"),
        mirror_step_count=step,
        location_accuracy_m=_MISSION_ACCURACY_M[mission],
        location_accuracy_source=_ACCURACY_SOURCE,
    )
