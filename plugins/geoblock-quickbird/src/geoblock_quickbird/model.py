"""The DigitalGlobe/Maxar rigorous physical model: :class:`DigitalGlobeModel` and
:func:`dg_model`.

The model is geoblock's generic pushbroom model
(:class:`geoblock.models.linescan.LinescanModel`) assembled from the image support data
(:mod:`geoblock_quickbird.isd`), with the light-path corrections the vendor's RPB includes:

* **time of each row** from the TLC table (``t = TLC time + (row - TLC row) * period``);
* **ephemeris**: ECEF positions and Earth-fixed velocities, cubic Hermite interpolation
  (ASP uses 8-point Lagrange; at the ISD's 0.02 s sampling the two differ by micrometres);
* **attitude**: body -> ECEF quaternions ``(q1, q2, q3, q4)`` with ``q4`` the scalar part
  (ASP ``LinescanDGModel.cc``: "the order is now w, x, y, z"), composed with the camera ->
  body quaternion ``QCS``, slerp between samples;
* **camera**: detector ``c`` (0-based column) at ``(DETORIGINX + c p sin(theta),
  DETORIGINY - c p cos(theta))`` mm in the camera focal plane, ``p`` the pitch, ``theta``
  ``DETROTANGLE``; its look vector ``(x, y, PD)`` normalised (+z the boresight); the
  perspective-centre offset ``(CX, CY, CZ)`` added to the positions in the body frame;
* **light path**: velocity aberration, light time and atmospheric refraction
  (:mod:`geoblock.models.linescan.light`), per ray and at each point's height.

Measured against the vendor RPB over 50 x 50 x 3 grids (``docs/user-guide/digitalglobe.md``
has the table): the corrections are 24-42 pixels together (aberration 20-40 px, light time
1-2 px, refraction 0.5-4 px and its change with height 0.3 px per km); with them the model
agrees with the RPB to a few tenths of a pixel, the rest being mostly the RPB's own fit
error (a cubic rational function cannot follow the attitude samples).

Registry name ``dg-rigorous``; aliases ``quickbird`` and ``worldview``. Parameter sets: those
of the linescan model (``default``, ``linescan``, ``dg``, ``physical``), with the a-priori
sigmas of ``dg`` and ``physical`` derived from the ISD's ephemeris and attitude covariances
(:func:`isd_location_accuracy`).
"""

from __future__ import annotations

import os
import warnings
from collections.abc import Sequence
from pathlib import Path
from typing import Any, ClassVar, NamedTuple

import numpy as np

from geoblock import coords
from geoblock.errors import GeoblockError, GeoblockWarning, ParameterSetError
from geoblock.models import ParameterSet
from geoblock.models.crop import CroppedModel
from geoblock.models.linescan import (
    CORRECTIONS,
    Attitude,
    Ephemeris,
    LinescanModel,
    LineTimes,
    LookDirections,
    matrix_to_quaternion,
    quaternion_to_matrix,
)
from geoblock.models.parameters import location_accuracy
from geoblock.typing import Status
from geoblock_quickbird.isd import Isd, IsdFormatError, read_isd

__all__ = [
    "DEFAULT_HEIGHT_RANGE",
    "PARAMETER_SETS",
    "RPB_DISAGREEMENT_PX",
    "DigitalGlobeModel",
    "RpbAgreement",
    "RpbDisagreementWarning",
    "dg_model",
    "isd_location_accuracy",
    "rpb_agreement",
]

#: the parameter sets :func:`dg_model` accepts by name
PARAMETER_SETS: tuple[str, ...] = ("default", "linescan", "dg", "physical")
#: Earth-fixed velocities must match the positions' derivative within this, m/s
_VELOCITY_TOLERANCE_M_S = 1.0
#: a-priori location accuracy used when the ISD has no covariances, metres (1 sigma; the
#: order of the stated CE90 of WorldView products without GCPs)
DEFAULT_ACCURACY_M = 5.0
#: valid heights (metres above the ellipsoid) when the support data hold no RPB, or an RPB that
#: disagrees with the physical sections
DEFAULT_HEIGHT_RANGE: tuple[float, float] = (-500.0, 9000.0)
#: the RPB and the physical model of one product are said to disagree beyond this, pixels: the
#: vendor fits its RPB to this very geometry (0.05-0.8 px apart on every real product, and
#: 24-42 px with the light-path corrections off), so tens of pixels more mean that one of the
#: two describes another image (ASP's anonymised ``dg_example4.xml`` moves only the RPB, by 2
#: degrees)
RPB_DISAGREEMENT_PX = 50.0


class RpbDisagreementWarning(GeoblockWarning):
    """An ISD's RPB and its physical sections (IMD, EPH, ATT, GEO) describe different
    geometries: the message names both, the distance in pixels and on the ground, and which
    height range the physical model uses."""


class RpbAgreement(NamedTuple):
    """The physical model against the product's own RPB at a few points
    (:func:`rpb_agreement`).

    Attributes
    ----------
    max_px, rms_px : float
        Largest and RMS image distance ``hypot(drow, dcol)``, pixels, between the RPB's
        projection and the image point the physical model backprojected, over the points the
        RPB projects (NaN when it projects none).
    n_unprojected : int
        Ground points of the physical model to which the RPB gives no image point (outside
        its validity domain, or a zero of its denominator).
    ground_distance_m : float
        Distance on the ground between the two models' backprojections of the image centre at
        the middle check height, metres (NaN when the RPB cannot backproject it).
    physical_centre, rpb_centre : (float, float)
        ``(lon, lat)`` of those two backprojections, degrees (NaN when not found).
    heights : tuple of float
        The check heights, metres above the ellipsoid (the RPB's range, clipped to
        :data:`DEFAULT_HEIGHT_RANGE`).
    n_points : int
        Image points x heights compared.
    """

    max_px: float
    rms_px: float
    n_unprojected: int
    ground_distance_m: float
    physical_centre: tuple[float, float]
    rpb_centre: tuple[float, float]
    heights: tuple[float, ...]
    n_points: int

    @property
    def disagrees(self) -> bool:
        """Whether the two differ by more than :data:`RPB_DISAGREEMENT_PX` somewhere, or the
        RPB has no image point for some of the physical model's ground points."""
        return self.n_unprojected > 0 or not self.max_px <= RPB_DISAGREEMENT_PX

    def describe(self) -> str:
        """The comparison in words (for messages)."""
        parts = []
        if self.n_unprojected < self.n_points:
            parts.append(f"the two differ by up to {self.max_px:.4g} px "
                         f"({self.rms_px:.4g} px RMS)")
        if self.n_unprojected:
            parts.append(f"the RPB gives no image point for {self.n_unprojected} of them "
                         "(outside its domain)")
        text = (f"compared at {self.n_points} points (image points x heights "
                f"{self.heights[0]:g}-{self.heights[-1]:g} m), " + " and ".join(parts))
        if np.isfinite(self.ground_distance_m):
            text += (f"; the image centre is at lon {self.physical_centre[0]:.5f}, lat "
                     f"{self.physical_centre[1]:.5f} for the physical model and at lon "
                     f"{self.rpb_centre[0]:.5f}, lat {self.rpb_centre[1]:.5f} for the RPB, "
                     f"{self.ground_distance_m / 1000.0:.3g} km apart")
        return text


class DigitalGlobeModel(LinescanModel):
    """The DigitalGlobe/Maxar rigorous model: a :class:`LinescanModel` read from an ISD.

    Same constructor, geometry, parameters and parameter sets as :class:`LinescanModel`
    (see :func:`dg_model` for how the support data fill it); registered as ``dg-rigorous``
    (aliases ``quickbird``, ``worldview``) so that its JSON names the sensor family. The JSON
    reopens with this plugin installed; ``LinescanModel.from_dict`` of the same dictionary
    with ``"model": "linescan"`` gives the identical geometry without it.
    """

    name: ClassVar[str] = "dg-rigorous"
    aliases: ClassVar[tuple[str, ...]] = ("quickbird", "worldview")

    @classmethod
    def example(cls, shape: tuple[int, int] = (800, 1000), **kwargs: Any) -> DigitalGlobeModel:
        """The linescan example with the light-path corrections on (a test model)."""
        base = LinescanModel.example(shape, **kwargs)
        data = base.to_dict()
        data.update(model=cls.name, corrections=list(CORRECTIONS), location_accuracy_m=5.0)
        return cls.from_dict(data)


def isd_location_accuracy(isd: Isd, slant_range_m: float) -> float:
    """The location accuracy (1 sigma, metres) the ISD's covariances give at a slant range.

    ``sqrt(s_p^2 + (D s_a)^2)``: ``s_p`` the RMS position sigma (the mean of the position
    covariances' traces over 3), ``s_a = 2 sqrt(mean(q11, q22, q33))`` the attitude angle
    sigma (a quaternion's vector part is half the rotation angle), ``D`` the slant range.
    Falls back to :data:`DEFAULT_ACCURACY_M` when the support data give no covariances.
    """
    pos = isd.position_covariance_m2
    att = isd.attitude_covariance
    var_p = float(np.mean(pos[:, 0] + pos[:, 3] + pos[:, 5]) / 3.0) if pos.size else 0.0
    var_q = float(np.mean(att[:, [0, 4, 7]])) if att.size else 0.0
    if not (var_p > 0 or var_q > 0) or not (np.isfinite(var_p) and np.isfinite(var_q)):
        return DEFAULT_ACCURACY_M
    sigma_angle = 2.0 * np.sqrt(max(var_q, 0.0))
    return float(np.hypot(np.sqrt(max(var_p, 0.0)), slant_range_m * sigma_angle))


def _look_vectors(isd: Isd) -> np.ndarray:
    cols = isd.shape[1]
    c = np.arange(cols, dtype=np.float64)
    theta = np.radians(isd.detector_rotation_deg)
    pitch = isd.detector_pitch_mm
    x0, y0 = isd.detector_origin_mm
    return np.stack([x0 + c * pitch * np.sin(theta), y0 - c * pitch * np.cos(theta),
                     np.full(cols, isd.principal_distance_mm)], axis=-1)


def _check_velocities(isd: Isd) -> None:
    """Refuse velocities that are not the Earth-fixed derivative of the positions."""
    t, p, v = isd.ephemeris_time_s, isd.position_m, isd.velocity_m_s
    if t.size < 5:
        return
    derivative = np.gradient(p, t, axis=0, edge_order=2)
    miss = np.linalg.norm(derivative[2:-2] - v[2:-2], axis=1)
    if np.any(~(miss <= _VELOCITY_TOLERANCE_M_S)):
        i = int(np.flatnonzero(~(miss <= _VELOCITY_TOLERANCE_M_S))[0]) + 2
        raise IsdFormatError(isd.sources["EPH"], f"EPH.EPHEMLIST[{i}]",
                             f"the velocity differs from the positions' derivative by "
                             f"{miss[i - 2]:.3g} m/s (Earth-fixed ECEF velocities expected)")


def rpb_agreement(model: LinescanModel, rpb: Any, n: int = 3) -> RpbAgreement:
    """The physical model of a product against its RPB at ``n x n`` image points x 3 heights.

    The physical model backprojects the grid (image corners, edges' middles and centre for
    ``n = 3``) at the RPB's lowest, middle and highest height (clipped to
    :data:`DEFAULT_HEIGHT_RANGE`); the RPB projects the ground points back. The physical
    model is compared with all light-path corrections on (the vendor's RPB includes them).

    Parameters
    ----------
    model : LinescanModel
        The physical model of the full image.
    rpb : SensorModel
        The product's RPB as a sensor model (``open_model(path, model="rpc")``), in the full
        image's pixels.
    n : int
        Grid points per image side (>= 2).

    Returns
    -------
    RpbAgreement
    """
    if tuple(model.corrections) != tuple(CORRECTIONS):
        model = model.replace(corrections=tuple(CORRECTIONS))
    rows, cols = model.shape
    lo, hi = DEFAULT_HEIGHT_RANGE
    h0, h1 = (min(max(float(v), lo), hi) for v in rpb.height_range)
    heights = (h0, 0.5 * (h0 + h1), h1)
    rr, cc, hh = (a.ravel() for a in np.meshgrid(np.linspace(0.0, rows - 1.0, n),
                                                 np.linspace(0.0, cols - 1.0, n),
                                                 np.array(heights), indexing="ij"))
    g, ok = model.backproject_with_status(rr, cc, hh)
    p, _ = rpb.project_with_status(g.lon, g.lat, hh)
    with np.errstate(invalid="ignore"):
        d = np.hypot(p.row - rr, p.col - cc)[ok == Status.CONVERGED]
    finite = np.isfinite(d)
    worst = float(np.max(d[finite])) if finite.any() else float("nan")
    rms = float(np.sqrt(np.mean(d[finite] ** 2))) if finite.any() else float("nan")
    centre = ((rows - 1) / 2.0, (cols - 1) / 2.0)
    mine, _ = model.backproject_with_status(centre[0], centre[1], heights[1])
    theirs, status = rpb.backproject_with_status(centre[0], centre[1], heights[1])
    ecef = [np.array([float(v) for v in coords.geodetic_to_ecef(c.lon, c.lat, heights[1])])
            for c in (mine, theirs)]
    distance = float(np.linalg.norm(ecef[1] - ecef[0]))  # NaN when either is not found
    return RpbAgreement(worst, rms, int(np.sum(~finite)), distance,
                        (float(mine.lon), float(mine.lat)),
                        (float(theirs.lon), float(theirs.lat)), heights, int(d.size))


def _check_rpb(isd: Isd, model: DigitalGlobeModel, heights_given: bool,
               ) -> DigitalGlobeModel:
    """Compare the ISD's RPB with the physical model; warn (naming both) when they disagree,
    and then keep the RPB's height range out of the model."""
    from geoblock.io import open_model

    source = isd.sources.get("RPB", isd.path)
    physical = sorted({str(isd.sources[s]) for s in ("IMD", "EPH", "ATT", "GEO")})
    what = f"the physical model (IMD, EPH, ATT, GEO of {', '.join(repr(p) for p in physical)})"
    default = DEFAULT_HEIGHT_RANGE
    try:
        with warnings.catch_warnings():  # the RPB's own warnings are model="rpc"'s to give
            warnings.simplefilter("ignore")
            rpb = open_model(source, model="rpc")
            agreement = rpb_agreement(model, rpb)
    except GeoblockError as exc:
        if heights_given or isd.rpb_height_range is None:
            return model
        warnings.warn(f"{str(source)!r}: the RPB cannot be compared with {what} ({exc}); the "
                      f"physical model uses the heights {default} m, not the RPB's "
                      f"{isd.rpb_height_range}", RpbDisagreementWarning, stacklevel=3)
        return model.replace(height_range=default)
    if not agreement.disagrees:
        return model
    heights = ("" if heights_given or isd.rpb_height_range is None else
               f"; the physical model uses the heights {default} m, not the RPB's "
               f"{isd.rpb_height_range}")
    warnings.warn(
        f"{str(source)!r}: the RPB disagrees with {what}: {agreement.describe()} (the "
        f"two agree to < 1 px in a genuine product, {RPB_DISAGREEMENT_PX:g} px is the limit: "
        f"one of them is of another image){heights}; model='rpc' opens the RPB",
        RpbDisagreementWarning, stacklevel=3)
    return model if heights_given or isd.rpb_height_range is None else model.replace(
        height_range=default)


def dg_model(
    source: Isd | str | os.PathLike[str],
    *,
    parameters: str | ParameterSet = "physical",
    accuracy_m: float | None = None,
    height_range: Sequence[float] | None = None,
    corrections: Sequence[str] = CORRECTIONS,
    tile: str | None = None,
    check_rpb: bool = True,
) -> DigitalGlobeModel | CroppedModel:
    """The rigorous model of a DigitalGlobe/Maxar basic product.

    Parameters
    ----------
    source : Isd or path
        Parsed support data, or anything :func:`geoblock_quickbird.isd.find_isd` accepts.
    parameters : {"physical", "dg", "linescan", "default"} or ParameterSet
        The parameter set (:meth:`LinescanModel.with_parameter_set`); default
        ``"physical"``: attitude biases and drifts, along/across-track position biases and
        the focal scale, a-priori sigmas from the location accuracy.
    accuracy_m : float, optional
        Location accuracy (1 sigma, metres) for the a-priori sigmas; default from the ISD's
        covariances (:func:`isd_location_accuracy`). Stored as the model's
        ``location_accuracy_m``.
    height_range : (float, float), optional
        Valid heights, metres above the ellipsoid; default the RPB's height range when the
        support data hold an RPB that agrees with the physical model, else
        :data:`DEFAULT_HEIGHT_RANGE`.
    corrections : sequence of str
        Light-path corrections (default all: aberration, light time, refraction); ``()``
        gives the bare geometry (tens of pixels off).
    tile : str, optional
        A tile file name of the ``TIL`` section: the model of that tile (a
        :class:`~geoblock.models.crop.CroppedModel` of the full image).
    check_rpb : bool
        Compare the support data's RPB (when they hold one) with the physical model at
        27 points (:func:`rpb_agreement`): beyond :data:`RPB_DISAGREEMENT_PX` a
        :class:`RpbDisagreementWarning` names both and the distance, and the model does not
        take its height range from the RPB. Default True.

    Returns
    -------
    DigitalGlobeModel or CroppedModel

    Raises
    ------
    IsdFormatError
        Bad support data, velocities that are not Earth-fixed, an ephemeris or attitude that
        does not cover the image's rows, an unknown tile, a bad option (named).
    ParameterSetError
        An unknown parameter set.
    """
    isd = source if isinstance(source, Isd) else read_isd(source)
    where = isd.sources.get("IMD", isd.path)
    if accuracy_m is not None:
        try:
            accuracy_m = location_accuracy(accuracy_m, "the location accuracy")
        except ValueError as exc:
            raise IsdFormatError(where, "(option accuracy_m)", str(exc)) from None
    _check_velocities(isd)
    rows, cols = isd.shape
    r_att = quaternion_to_matrix(np.column_stack([isd.quaternion[:, 3], isd.quaternion[:, :3]]))
    qcs = isd.camera_attitude
    r_cam = quaternion_to_matrix([qcs[3], qcs[0], qcs[1], qcs[2]])
    attitude = Attitude(isd.attitude_time_s, matrix_to_quaternion(r_att @ r_cam), frame="ecef")
    position = isd.position_m
    if any(isd.perspective_centre_m):
        body = Attitude(isd.attitude_time_s, matrix_to_quaternion(r_att))
        position = position + np.einsum("nij,j->ni", body.matrix(isd.ephemeris_time_s),
                                        np.asarray(isd.perspective_centre_m))
    ephemeris = Ephemeris(isd.ephemeris_time_s, position, isd.velocity_m_s)
    try:  # either sign: a reverse scan's times fall as the row rises
        line_times = LineTimes(isd.reference_row, isd.reference_time_s, isd.line_period_s)
    except GeoblockError as exc:
        raise IsdFormatError(isd.sources["IMD"], "IMD.IMAGE.TLCLIST", str(exc)) from None
    look = LookDirections(_look_vectors(isd))
    t_rows = line_times.span(-0.5, rows - 0.5)
    for what, span, field in (("ephemeris", ephemeris.valid_span_s, "EPH.EPHEMLIST"),
                              ("attitude", attitude.valid_span_s, "ATT.ATTLIST")):
        if not (span[0] <= t_rows[0] and t_rows[1] <= span[1]):
            section = field.split(".")[0]
            raise IsdFormatError(isd.sources[section], field,
                                 f"the {what} (from {span[0]:.3f} s to {span[1]:.3f} s after "
                                 f"{isd.epoch}) does not cover the image's rows "
                                 f"({t_rows[0]:.3f} s to {t_rows[1]:.3f} s)")
    heights_given = height_range is not None
    if height_range is None:  # the RPB's, unless it disagrees with the physical model (below)
        height_range = isd.rpb_height_range or DEFAULT_HEIGHT_RANGE
    try:
        h_low, h_high = (float(v) for v in height_range)
    except (TypeError, ValueError):
        raise IsdFormatError(where, "(option height_range)", f"must be two heights in "
                             f"metres, got {height_range!r}") from None
    try:
        model = DigitalGlobeModel((rows, cols), ephemeris, attitude, look, line_times,
                                  epoch=isd.epoch, height_range=(h_low, h_high),
                                  corrections=tuple(corrections))
    except (ValueError, TypeError) as exc:
        raise IsdFormatError(where, "(model)", str(exc)) from None
    if check_rpb and isd.has_rpb:
        model = _check_rpb(isd, model, heights_given)
    if accuracy_m is None:
        centre = (0.5 * (rows - 1), 0.5 * (cols - 1))
        g = model.backproject_ecef(centre[0], centre[1], float(np.mean(model.height_range)))
        sat, _, _ = model.sensor_state(centre[0])
        slant = float(np.linalg.norm(np.array([float(v) for v in g]) - sat))
        accuracy_m = isd_location_accuracy(isd, slant)
    model = model.replace(location_accuracy_m=accuracy_m)
    model = _with_parameters(model, parameters, where)
    if tile is None:
        return model
    found = isd.tile(tile)
    if found is None:
        raise IsdFormatError(isd.sources.get("TIL", where), "TIL.TILE",
                             f"no tile named {Path(tile).name!r}; tiles: "
                             f"{[t.filename for t in isd.tiles][:8]}")
    return CroppedModel(model, found.offset, found.shape)


def _with_parameters(model: DigitalGlobeModel, parameters: str | ParameterSet,
                     where: Path) -> DigitalGlobeModel:
    if isinstance(parameters, ParameterSet):
        return model.replace(parameters=parameters)
    if parameters not in PARAMETER_SETS:
        raise ParameterSetError(f"{str(where)!r}: unknown parameter set {parameters!r}; "
                                f"known: {list(PARAMETER_SETS)}")
    return model.with_parameter_set(parameters)
