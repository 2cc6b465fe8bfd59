"""The DIMAP line-of-sight model of SPOT 1-5 level 1A scenes, on geoblock's linescan model.

:func:`spot_dimap_model` turns a :class:`~geoblock_spot.dimap.SpotDimap` into a plain
:class:`geoblock.models.linescan.LinescanModel` (registry name ``linescan``; nothing is lost,
so no subclass): its ``to_dict`` JSON reopens with :func:`geoblock.io.open_model` without this
plugin. The ground point is Teo et al.'s state-vector form ``G = P(t) + S U(t, col)``: the
satellite position plus the scaled line of sight, intersected with the ellipsoid raised by
``h``.

Frames (SPOT 123-4-5 Geometry Handbook GAEL-P135-DOC-001, as implemented by ASP
``src/asp/Camera/LinescanSpotModel.cc``, OSSIM ``ossimSpot5Model.cpp`` and COSI-Corr
``geoCosiCorr3D/geoRSM/Spot_RSM.py``)
--------------------------------------------------------------------------------------------
* SPOT's local orbital frame O2: ``Z2 = P/|P|`` (up), ``X2 = V x Z2 / |.|`` (right of the
  track), ``Y2 = Z2 x X2`` (forward), built from the DIMAP velocity *as given* (handbook eq.
  7a-c; Earth-fixed for SPOT 5, inertial on ECEF axes for SPOT 1-4).
* Navigation frame O1 -> O2: ``M = Mp Mr My`` (handbook eq. 11) from yaw, pitch, roll.
* Look direction of a detector in O1: ``normalize(-tan PSI_Y, tan PSI_X, -1)`` (eq. 5a).
* geoblock's orbital frame (``linescan.orbital_frame``: x along track, y right, z down) is O2
  with its axes permuted: ``x_o = Y2, y_o = X2, z_o = -Z2``, i.e. ``v_o = A v_2`` with the
  fixed proper rotation ``A = [[0, 1, 0], [1, 0, 0], [0, 0, -1]]`` (``A = A^T = A^-1``; COSI-Corr's
  ``airbus_2_cosi_rot``). geoblock's sensor frame (x forward, y right, z down) is O1 permuted
  the same way, so the look vector is ``A u1 = normalize(tan PSI_X, -tan PSI_Y, 1)``
  (:meth:`LookDirections.from_tan_angles` with ``tan_x = tan PSI_X``, ``tan_y = -tan PSI_Y``)
  and the attitude sensor -> orbital is ``R_att = A M A``.
* SPOT 1-4: geoblock's orbital frame is built from the Earth-fixed velocity (the derivative of
  the positions, needed by the Hermite ephemeris), SPOT's from the inertial one; the fixed-time
  rotation ``C = M_orb(P, V_ef)^T M_orb(P, V_in)`` (about 3 degrees of yaw) is folded into
  ``R_att = C A M A`` at each attitude sample.

Attitude: SPOT 5 corrected yaw/pitch/roll; SPOT 1-4 the integrated angular speeds
(:meth:`SpotDimap.attitude_angles`). Line times: ``SCENE_CENTER_TIME`` at the scene-centre
line, ``LINE_PERIOD`` per row. Ephemeris: cubic Hermite on positions and Earth-fixed
velocities (the handbook prescribes 8-point Lagrange on positions; both agree to well below
a metre at the DIMAP sample spacing of 30-60 s).

DG parameter set
----------------
The model's ``"dg"`` parameter set (``model.with_parameter_set("dg")``, the default of
:func:`spot_dimap_model`) is Teo et al.'s direct-georeferencing correction, a first-degree
polynomial orbital correction ``dP(t)`` (``dp_along/across/radial`` and their ``_rate``) plus
the three attitude biases (``roll/pitch/yaw_bias``); the attitude rates stay in the set, fixed
at 0. Its a-priori sigmas come from the product's location accuracy
(:attr:`SpotDimap.location_accuracy_m`, stored as the model's ``location_accuracy_m``). It is
generic linescan geometry and lives in the core, :func:`geoblock.models.linescan.dg_parameters`;
:func:`dg_parameters` and :data:`DG_ADJUSTABLE` here are re-exports kept for compatibility.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from typing import Any

import numpy as np

from geoblock import coords
from geoblock.models.linescan import (
    DG_ADJUSTABLE,
    Attitude,
    Ephemeris,
    LinescanModel,
    LineTimes,
    LookDirections,
    dg_parameters,
    matrix_to_quaternion,
    orbital_frame,
)
from geoblock.models.parameters import ParameterSet
from geoblock_spot.dimap import (
    _LOOK,
    EARTH_ROTATION_RAD_S,
    MAX_IMAGE_SIZE,
    DimapFormatError,
    SpotDimap,
    file_named,
    read_dimap,
    with_parameters,
)

__all__ = [
    "AXIS_PERMUTATION",
    "DG_ADJUSTABLE",
    "GeolocationCheck",
    "dg_parameters",
    "geolocation_check",
    "handbook_rotation",
    "simplified_model_check",
    "spot_dimap_model",
]

AXIS_PERMUTATION = np.array([[0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, -1.0]])
"""``A``: SPOT orbital/navigation axes (right, forward, up) -> geoblock's (forward, right, down)."""


def handbook_rotation(yaw, pitch, roll) -> np.ndarray:
    """SPOT handbook eq. 11: ``M = Mp Mr My``, navigation frame O1 -> local orbital frame O2.

    Parameters
    ----------
    yaw, pitch, roll : array_like, (...)
        DIMAP attitude angles, rad.

    Returns
    -------
    ndarray, (..., 3, 3)
        Equal to ``Rx(-pitch) @ Ry(-roll) @ Rz(yaw)`` (COSI-Corr ``R_opk_xyz(-pitch, -roll,
        yaw)``); entries as ASP ``get_look_rotation_matrix`` and OSSIM
        ``computeSatToOrbRotation``.
    """
    y, p, r = np.broadcast_arrays(*(np.asarray(a, np.float64) for a in (yaw, pitch, roll)))
    cp, sp, cr, sr, cy, sy = np.cos(p), np.sin(p), np.cos(r), np.sin(r), np.cos(y), np.sin(y)
    m = np.empty(y.shape + (3, 3))
    m[..., 0, 0] = cr * cy
    m[..., 0, 1] = -cr * sy
    m[..., 0, 2] = -sr
    m[..., 1, 0] = cp * sy + sp * sr * cy
    m[..., 1, 1] = cp * cy - sp * sr * sy
    m[..., 1, 2] = sp * cr
    m[..., 2, 0] = -sp * sy + cp * sr * cy
    m[..., 2, 1] = -sp * cy - cp * sr * sy
    m[..., 2, 2] = cp * cr
    return m


def _omega_cross(p: np.ndarray) -> np.ndarray:
    w = EARTH_ROTATION_RAD_S
    return np.stack([-w * p[..., 1], w * p[..., 0], np.zeros(p.shape[:-1])], axis=-1)


def spot_dimap_model(
    source: SpotDimap | str | os.PathLike[str],
    *,
    parameters: str | ParameterSet = "dg",
    use_attitude: bool = True,
    height_range: tuple[float, float] = (-500.0, 9000.0),
) -> LinescanModel:
    """The DIMAP line-of-sight model of a SPOT 1-5 level 1A scene.

    Parameters
    ----------
    source : SpotDimap or path
        Parsed metadata, a ``METADATA.DIM`` file or a product directory.
    parameters : {"dg", "linescan"} or ParameterSet
        A parameter set of the model (:meth:`LinescanModel.with_parameter_set`): ``"dg"``
        (default): Teo et al.'s DG set (:func:`dg_parameters`) with sigmas from the product's
        location accuracy; ``"linescan"``: the linescan model's twelve free parameters
        (infinite sigmas); or a ``ParameterSet`` with linescan names.
    use_attitude : bool
        ``False`` sets yaw, pitch and roll to 0 (the SPOT 1-4 products' own corner
        coordinates are reproduced best that way, to about 1 m: they appear to be computed
        without the gyro attitude).
    height_range : (float, float)
        Valid heights, metres above the ellipsoid.

    Returns
    -------
    LinescanModel
        Shape ``(NROWS, NCOLS)``, attitude in the orbital frame, epoch the first ephemeris time,
        ``location_accuracy_m`` the product's (:attr:`SpotDimap.location_accuracy_m`), so that
        ``with_parameter_set("dg")`` needs no option.

    Raises
    ------
    DimapFormatError
        The look-angle table does not cover the image (a cropped file such as ASP's
        ``spot_example1.xml``), or the attitude/ephemeris do not cover the image's time span.
    """
    dimap = source if isinstance(source, SpotDimap) else read_dimap(source)
    rows, cols = dimap.shape[0], dimap.scene_width
    if cols > MAX_IMAGE_SIZE:
        raise DimapFormatError(dimap.path, "Geoposition/Geoposition_Points/Tie_Point",
                               f"the geolocation refers to a {cols}-column scene: not plausible")
    psi_x, psi_y = dimap.look_angles(cols)  # refuses a table that doesn't cover the image
    with file_named(dimap.path, _LOOK):
        look = LookDirections.from_tan_angles(np.tan(psi_x), -np.tan(psi_y))

    with file_named(dimap.path, "Data_Strip/Ephemeris/Points"):
        ephemeris = Ephemeris(dimap.ephemeris_time_s, dimap.position_m,
                              dimap.earth_fixed_velocity_m_s())
    with file_named(dimap.path, "Data_Strip/Sensor_Configuration/Time_Stamp"):
        line_times = LineTimes(dimap.scene_center_row, dimap.scene_center_time_s,
                               dimap.line_period_s)
    t_first, t_last = (float(t) for t in line_times.time([-0.5, rows - 0.5]))

    att_t, ypr, source_kind = dimap.attitude_angles()
    if not use_attitude:
        ypr = np.zeros_like(ypr)
    a = AXIS_PERMUTATION
    r_att = a @ handbook_rotation(ypr[:, 0], ypr[:, 1], ypr[:, 2]) @ a  # (m, 3, 3)
    pos, vel = ephemeris.at(att_t)
    if not np.all(np.isfinite(pos)):
        raise DimapFormatError(dimap.path, "Data_Strip/Ephemeris/Points",
                               "the ephemeris does not cover the attitude samples' times")
    if dimap.velocity_frame == "inertial":
        m_ef = orbital_frame(pos, vel)
        m_in = orbital_frame(pos, vel + _omega_cross(pos))
        r_att = np.swapaxes(m_ef, -1, -2) @ m_in @ r_att
    with file_named(dimap.path, "Data_Strip/Satellite_Attitudes"):
        attitude = Attitude(att_t, matrix_to_quaternion(r_att), frame="orbital")

    for what, span, field in (
        ("attitude", attitude.valid_span_s, "Data_Strip/Satellite_Attitudes"),
        ("ephemeris", ephemeris.valid_span_s, "Data_Strip/Ephemeris/Points"),
    ):
        if not (span[0] <= t_first and t_last <= span[1]):
            raise DimapFormatError(
                dimap.path, field,
                f"the {what} ({source_kind if what == 'attitude' else 'position/velocity'} "
                f"samples, usable from {span[0]:.3f} s to {span[1]:.3f} s after {dimap.epoch}) "
                f"does not cover the image's rows ({t_first:.3f} s to {t_last:.3f} s)",
            )

    with file_named(dimap.path, "(model)"):
        model = LinescanModel((rows, cols), ephemeris, attitude, look, line_times,
                              epoch=dimap.epoch, height_range=height_range,
                              location_accuracy_m=dimap.location_accuracy_m)
    return with_parameters(model, parameters, dimap.path, ("dg", "linescan"))


@dataclass(frozen=True, eq=False)
class GeolocationCheck:
    """A model against the geolocation its product states (corners, centre, tie points).

    Attributes
    ----------
    label : tuple of str, (k,)
        ``"vertex 1"`` ... ``"scene centre"``, ``"tie point 1"`` ...
    row, col, lon, lat, h : ndarray, (k,)
        The stated points (0-based pixel centres; degrees; metres).
    error_m : ndarray, (k,)
        Horizontal distance between the stated ground point and the model's backprojection
        of the stated pixel at ``h``, metres.
    error_px : ndarray, (k,)
        Distance between the stated pixel and the model's projection of the stated ground
        point, pixels.
    d_row, d_col : ndarray, (k,)
        Model projection minus stated pixel.
    accuracy_m : float
        The product's location accuracy.
    """

    label: tuple[str, ...]
    row: np.ndarray
    col: np.ndarray
    lon: np.ndarray
    lat: np.ndarray
    h: np.ndarray
    error_m: np.ndarray
    error_px: np.ndarray
    d_row: np.ndarray
    d_col: np.ndarray
    accuracy_m: float

    def summary(self) -> str:
        """One line: max and RMS error in metres and pixels."""
        return (f"max {np.max(self.error_m):.2f} m / {np.max(self.error_px):.3f} px, "
                f"RMS {np.sqrt(np.mean(self.error_m**2)):.2f} m / "
                f"{np.sqrt(np.mean(self.error_px**2)):.3f} px over {len(self.label)} points "
                f"(stated accuracy {self.accuracy_m:g} m)")


def geolocation_check(
    model: Any, dimap: SpotDimap, *, tie_points: bool = False
) -> GeolocationCheck:
    """Compare a model with the product's ``Dataset_Frame`` vertices and scene centre.

    Parameters
    ----------
    model : SensorModel
        Any model of the scene (normally :func:`spot_dimap_model`).
    dimap : SpotDimap
    tie_points : bool
        Also compare the ``Tie_Point``\\ s (at their ``TIE_POINT_CRS_Z``).

    Returns
    -------
    GeolocationCheck
    """
    points = [(f"vertex {i + 1}", p) for i, p in enumerate(dimap.vertices)]
    if dimap.scene_center is not None:
        points.append(("scene centre", dimap.scene_center))
    if tie_points:
        points += [(f"tie point {i + 1}", p) for i, p in enumerate(dimap.tie_points)]
    if not points:
        raise DimapFormatError(dimap.path, "Dataset_Frame", "no vertices or scene centre")
    labels = tuple(lbl for lbl, _ in points)
    row, col, lon, lat, h = (np.array([getattr(p, k) for _, p in points], dtype=np.float64)
                             for k in ("row", "col", "lon", "lat", "h"))
    back = model.backproject(row, col, h)
    stated = np.stack(coords.geodetic_to_ecef(lon, lat, h), axis=-1)
    got = np.stack(coords.geodetic_to_ecef(back.lon, back.lat, h), axis=-1)
    proj = model.project(lon, lat, h)
    d_row, d_col = proj.row - row, proj.col - col
    return GeolocationCheck(labels, row, col, lon, lat, h,
                            np.linalg.norm(got - stated, axis=-1), np.hypot(d_row, d_col),
                            d_row, d_col, dimap.location_accuracy_m)


def simplified_model_check(model: Any, dimap: SpotDimap, n: int = 21) -> tuple[float, float]:
    """Max and RMS pixel distance between a model and the product's simplified location model.

    The ``Direct_Location_Model`` quadratic maps an ``n x n`` grid over the whole image to
    ``(lon, lat)`` at ``h = 0``; the model projects those back. The figure is dominated by the
    quadratic's own approximation error.

    Returns
    -------
    max_px, rms_px : float
    """
    rows, cols = model.shape
    r, c = np.meshgrid(np.linspace(-0.5, rows - 0.5, n), np.linspace(-0.5, cols - 0.5, n),
                       indexing="ij")
    lon, lat = dimap.simplified_image_to_ground(r, c)
    proj = model.project(lon, lat, 0.0)
    d = np.hypot(proj.row - r, proj.col - c)
    return float(np.max(d)), float(np.sqrt(np.mean(d**2)))
