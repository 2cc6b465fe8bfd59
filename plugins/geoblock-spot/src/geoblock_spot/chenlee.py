"""Chen & Lee's (1993) time-dependent collinearity model of SPOT pushbroom images.

The model, exactly as published (Chen & Lee 1993, PE&RS 59(5), eqs. 1-7; Teo et al. 2010, eq. 1):

* **Image coordinates (eq. 1).** Along track ``x = 0``; across track
  ``y = (pixel_no - (N + 1) / 2) * pixel_size`` with the paper's 1-based ``pixel_no``. geoblock's
  0-based ``col`` (integer = pixel centre, ``col = 0`` the centre of the first pixel) is
  ``pixel_no - 1``, so ``y = (col - (N - 1) / 2) * pixel_size``; ``N`` is the number of columns.
* **Sampling time (eq. 6).** ``t`` is relative to the first scan line: row ``r`` (geoblock's
  pixel-centre convention, row 0 the first line) is sampled at ``t = r * line_period``; the
  paper's "Line No." equals geoblock's ``row``.
* **Collinearity (eq. 2)** in a local Cartesian work frame
  (:class:`geoblock.coords.LocalFrame`, ``X`` along the azimuth of the ground track)::

      x      = -f (m11 dX + m12 dY + m13 dZ) / (m31 dX + m32 dY + m33 dZ)
      Sy * y = -f (m21 dX + m22 dY + m23 dZ) / (m31 dX + m32 dY + m33 dZ)

  with ``dX = X - Xc(t)`` etc., ``Sy`` the scale affinity and ``M = R3(kappa) R2(phi) R1(omega)``
  the photogrammetric rotation (Slama 1980's ``m11 = cos(phi) cos(kappa)``, ...,
  ``m33 = cos(omega) cos(phi)``).
* **Orientation (eq. 3).** ``Xc, Yc, Zc, omega, phi, kappa`` are second-order polynomials of
  ``t``: ``Xc = X0 + X1 t + X2 t^2`` and so on: 18 coefficients, plus ``Sy``.
* **Ground -> image (eqs. 4-7).** Newton iteration on ``f(t) = m1(t) . (P - C(t)) = 0`` (the
  numerator of ``x``), with the analytic ``f'(t)``, until ``|t(n+1) - t(n)| <
  time_tolerance_s`` (1e-10 s, i.e. 7e-8 of a line: tighter than the paper's 1e-6 s so that
  project and backproject invert each other to 1e-6 px); then ``row = t / line_period`` and
  ``col`` from the across-track equation.
* **Image -> ground at h.** The ray ``C(t) + s M^T (0, Sy y, -f)`` intersected exactly with the
  surface of ellipsoidal height ``h`` (closed-form intersection with the ellipsoid of semi-axes
  ``a + h, b + h``, then Newton on ``s`` until the geodetic height misses ``h`` by less than
  ``intersection_tolerance_m``).

Angles are radians in the model (Table 1 of the paper is in degrees). Partials with respect to
the ground and to all 19 parameters are analytic (implicit differentiation of ``f(t) = 0``).

Two parameterisations, both reached through the sensor-model protocol's
``with_parameter_set(name, **options)`` (``parameter_sets`` is ``("default", "coefficients",
"mba")``, ``"default"`` the parameters as they are):

* ``"coefficients"``: the 19 values themselves (``x0 ... kappa2, sy``), free (no a-priori
  sigma): the model as published, e.g. Table 1;
* ``"mba"``: corrections ``d_x0 ... d_sy`` to nominal coefficients (e.g. fitted to on-board
  data by :func:`geoblock_spot.fit.fit_chenlee`), with a-priori sigmas derived from the
  product's stated location accuracy (:meth:`ChenLeeModel.mba_sigmas`): Teo et al.'s modified
  bundle adjustment (MBA) pseudo-observations.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, ClassVar, Self

import numpy as np

from geoblock import coords
from geoblock.errors import (
    GeoblockDeprecationWarning,
    ModelFormatError,
    ParameterSetError,
    SerializationError,
)
from geoblock.models import SensorModelBase, broadcast_float64
from geoblock.models.parameters import ParameterSet, accuracy_or_stored, location_accuracy
from geoblock.typing import ArrayLike, Float64Array, GroundCoords, Status

__all__ = [
    "COEFFICIENT_NAMES",
    "COEFFICIENT_UNITS",
    "MBA_NAMES",
    "SPOT1A_INTERIOR",
    "SPOT_LOCATION_ACCURACY_M",
    "TABLE1_COEFFICIENTS",
    "ChenLeeModel",
    "Interior",
    "rotation_matrix",
]

COEFFICIENT_NAMES: tuple[str, ...] = (
    "x0", "x1", "x2", "y0", "y1", "y2", "z0", "z1", "z2",
    "omega0", "omega1", "omega2", "phi0", "phi1", "phi2", "kappa0", "kappa1", "kappa2",
    "sy",
)
"""The 19 parameters in order: orbit ``Xc, Yc, Zc`` then attitude ``omega, phi, kappa``
coefficients of ``t^0, t^1, t^2``, then the scale affinity ``Sy``."""

COEFFICIENT_UNITS: tuple[str, ...] = (
    ("m", "m/s", "m/s^2") * 3 + ("rad", "rad/s", "rad/s^2") * 3 + ("1",)
)
"""Units of :data:`COEFFICIENT_NAMES` (and of the ``mba`` corrections)."""

MBA_NAMES: tuple[str, ...] = tuple(f"d_{n}" for n in COEFFICIENT_NAMES)
"""Names of the ``mba`` set: corrections to the nominal coefficients."""

PARAMETER_SETS = ("coefficients", "mba")

SPOT_LOCATION_ACCURACY_M: dict[int, float] = {1: 350.0, 2: 350.0, 3: 350.0, 4: 350.0, 5: 50.0}
"""Stated 1-sigma location accuracy of SPOT level 1A scenes without GCPs, metres, by satellite
(Spot Image, "Preprocessing levels and location accuracy": better than 350 m for SPOT 1-4,
better than 50 m for SPOT 5). Input of :meth:`ChenLeeModel.mba_sigmas`."""

_DEG = math.pi / 180.0
TABLE1_COEFFICIENTS: Float64Array = np.array(
    [
        -35164.57, 6504.06, -6.98,
        -262740.38, -1577.94, -1.227,
        827883.83, -83.48, -0.52,
        10.399883 * _DEG, -0.000248 * _DEG, 0.000034 * _DEG,
        -2.016735 * _DEG, -0.000291 * _DEG, 0.000046 * _DEG,
        -10.162549 * _DEG, -0.000291 * _DEG, 0.000039 * _DEG,
        1.0,
    ]
)
"""Chen & Lee (1993) Table 1, "calculated exterior orientation parameters" of their SPOT 1A
scene of 15 January 1987 (central west Taiwan), in :data:`COEFFICIENT_NAMES` order, angles
converted from degrees to radians. Table 1 gives no ``Sy``; it is 1 here."""
TABLE1_COEFFICIENTS.flags.writeable = False


@dataclass(frozen=True)
class Interior:
    """Interior geometry of the linear array (Chen & Lee eq. 1 and 6).

    Parameters
    ----------
    pixel_size_m : float
        CCD element size across track, metres (SPOT 1-4 panchromatic: 13 um).
    focal_length_m : float
        Focal length, metres (SPOT HRV: 1.082 m).
    line_period_s : float
        Sampling interval between consecutive lines, seconds (SPOT panchromatic: 1.5 ms).

    Notes
    -----
    In the model only ``focal_length / pixel_size`` and the line period matter, and deviations
    of either are absorbed by ``Sy`` and the time polynomials (Chen & Lee: "deviations of those
    interior orientation related parameters will need to be compensated for by the scale
    affinity and the exterior orientation parameters").
    """

    pixel_size_m: float = 13e-6
    focal_length_m: float = 1.082
    line_period_s: float = 1.5e-3

    def __post_init__(self) -> None:
        for name in ("pixel_size_m", "focal_length_m", "line_period_s"):
            value = float(getattr(self, name))
            if not (math.isfinite(value) and value > 0):
                raise ModelFormatError(f"Interior: {name} must be finite and > 0, got {value!r}")
            object.__setattr__(self, name, value)

    def to_dict(self) -> dict[str, float]:
        return {"pixel_size_m": self.pixel_size_m, "focal_length_m": self.focal_length_m,
                "line_period_s": self.line_period_s}


SPOT1A_INTERIOR = Interior()
"""SPOT 1A panchromatic: 13 um CCD, f = 1082 mm, 1.5 ms per line (Chen & Lee 1993)."""


class _WorkFrame(coords.LocalFrame):
    """Deprecated: :class:`geoblock.coords.LocalFrame` with the 0.1 ``WorkFrame`` methods,
    whose ECEF and work-frame points are stacked on the last axis, (..., 3)."""

    def __post_init__(self) -> None:
        warnings.warn("geoblock_spot.chenlee.WorkFrame is deprecated: use "
                      "geoblock.coords.LocalFrame (same arguments; its from_geodetic returns "
                      "three arrays, from_ecef_xyz/to_ecef_xyz take (..., 3))",
                      GeoblockDeprecationWarning, stacklevel=3)
        super().__post_init__()

    @property
    def local(self) -> coords.LocalFrame:
        """The east/north/up frame at the same origin."""
        return coords.LocalFrame(self.lon0, self.lat0, self.h0)

    def from_ecef(self, xyz: ArrayLike) -> Float64Array:  # type: ignore[override]  # 0.1 API
        """(..., 3) ECEF metres -> (..., 3) work-frame metres."""
        return self.from_ecef_xyz(xyz)

    def to_ecef(self, xyz: ArrayLike) -> Float64Array:  # type: ignore[override]  # 0.1 API
        """(..., 3) work-frame metres -> (..., 3) ECEF metres."""
        return self.to_ecef_xyz(xyz)

    def from_geodetic(  # type: ignore[override]  # 0.1 API
        self, lon: ArrayLike, lat: ArrayLike, h: ArrayLike
    ) -> Float64Array:
        """Geodetic ``(lon, lat, h)`` -> (..., 3) work-frame metres."""
        return self.from_ecef_xyz(np.stack(coords.geodetic_to_ecef(lon, lat, h), axis=-1))

    def to_geodetic(self, xyz: ArrayLike) -> GroundCoords:  # type: ignore[override]  # 0.1 API
        """(..., 3) work-frame metres -> :class:`~geoblock.typing.GroundCoords`."""
        p = self.to_ecef_xyz(xyz)
        return coords.ecef_to_geodetic(p[..., 0], p[..., 1], p[..., 2])


def __getattr__(name: str) -> Any:
    if name == "WorkFrame":  # deprecated in 0.2: geoblock.coords.LocalFrame has its azimuth
        return _WorkFrame
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def _work_points(frame: coords.LocalFrame, lon: ArrayLike, lat: ArrayLike,
                 h: ArrayLike) -> Float64Array:
    """Geodetic points -> work-frame points stacked on the last axis, (*S, 3) metres."""
    return frame.from_ecef_xyz(np.stack(coords.geodetic_to_ecef(lon, lat, h), axis=-1))


# ==================================================================================== algebra
def rotation_matrix(omega: ArrayLike, phi: ArrayLike, kappa: ArrayLike) -> Float64Array:
    """``M = R3(kappa) R2(phi) R1(omega)``, the photogrammetric rotation of Chen & Lee eq. 2.

    Parameters
    ----------
    omega, phi, kappa : array_like, (*S,)
        Radians.

    Returns
    -------
    ndarray, (*S, 3, 3)
        ``m11 = cos(phi) cos(kappa)``, ``m31 = sin(phi)``, ``m33 = cos(omega) cos(phi)``, ...:
        it turns work-frame vectors into image-frame vectors (``u = M (P - C)``).
    """
    omega, phi, kappa = broadcast_float64(omega=omega, phi=phi, kappa=kappa)
    return _rotation(omega, phi, kappa)[0]


def _rotation(omega: np.ndarray, phi: np.ndarray, kappa: np.ndarray, derivatives: bool = False):
    """M (*S, 3, 3) and, if asked, dM/d(omega, phi, kappa) as (3, *S, 3, 3)."""
    so, co = np.sin(omega), np.cos(omega)
    sp, cp = np.sin(phi), np.cos(phi)
    sk, ck = np.sin(kappa), np.cos(kappa)
    zero = np.zeros_like(so)

    def mat(rows):
        return np.stack([np.stack(r, axis=-1) for r in rows], axis=-2)

    m = mat([
        [cp * ck, so * sp * ck + co * sk, -co * sp * ck + so * sk],
        [-cp * sk, -so * sp * sk + co * ck, co * sp * sk + so * ck],
        [sp, -so * cp, co * cp],
    ])
    if not derivatives:
        return m, None
    d_omega = mat([
        [zero, co * sp * ck - so * sk, so * sp * ck + co * sk],
        [zero, -co * sp * sk - so * ck, -so * sp * sk + co * ck],
        [zero, -co * cp, -so * cp],
    ])
    d_phi = mat([
        [-sp * ck, so * cp * ck, -co * cp * ck],
        [sp * sk, -so * cp * sk, co * cp * sk],
        [cp, so * sp, -co * sp],
    ])
    d_kappa = mat([
        [-cp * sk, -so * sp * sk + co * ck, co * sp * sk + so * ck],
        [-cp * ck, -so * sp * ck - co * sk, co * sp * ck - so * sk],
        [zero, zero, zero],
    ])
    return m, np.stack([d_omega, d_phi, d_kappa])


def _first_row(omega, phi, kappa, omega_rate, phi_rate, kappa_rate):
    """Row 1 of M, (N, 3), and its time derivative, from angles and their rates (N,)."""
    so, co = np.sin(omega), np.cos(omega)
    sp, cp = np.sin(phi), np.cos(phi)
    sk, ck = np.sin(kappa), np.cos(kappa)
    m1 = np.stack([cp * ck, so * sp * ck + co * sk, -co * sp * ck + so * sk], axis=-1)
    d1 = np.stack([
        -(phi_rate * sp * ck + kappa_rate * cp * sk),
        omega_rate * (co * sp * ck - so * sk) + phi_rate * so * cp * ck
        + kappa_rate * (-so * sp * sk + co * ck),
        omega_rate * (so * sp * ck + co * sk) - phi_rate * co * cp * ck
        + kappa_rate * (co * sp * sk + so * ck),
    ], axis=-1)
    return m1, d1


# ==================================================================================== model
class ChenLeeModel(SensorModelBase):
    """Chen & Lee's (1993) SPOT pushbroom model (see the module docstring for the equations).

    Parameters
    ----------
    coefficients : array_like, (19,)
        Nominal coefficients in :data:`COEFFICIENT_NAMES` order (metres, seconds, radians);
        e.g. :data:`TABLE1_COEFFICIENTS`.
    frame : geoblock.coords.LocalFrame
        The local work frame of the orbit polynomials and of the ground coordinates (``X``
        usually along track: ``azimuth_deg`` the ground-track heading).
    shape : (int, int)
        ``(rows, cols)``; ``cols`` is the ``N`` of eq. 1. SPOT 1A: 6000 x 6000.
    interior : Interior
        Pixel size, focal length and line period (default SPOT 1A).
    height_range : (float, float)
        Valid ellipsoidal heights, metres.
    parameter_set : {"coefficients", "mba"}
        ``"coefficients"``: the parameters are the 19 coefficients; ``"mba"``: they are
        corrections ``d_*`` added to ``coefficients`` (see :meth:`mba`).
    corrections : array_like, (19,), optional
        Values of the ``mba`` corrections (default zeros); only with ``parameter_set="mba"``.
    sigmas, adjustable, covariance : optional
        A-priori sigmas (default: free), adjustable mask and covariance of the parameters
        (see :class:`~geoblock.models.parameters.ParameterSet`).
    location_accuracy_m : float, optional
        The product's stated location accuracy (1 sigma, metres, > 0, e.g.
        :data:`SPOT_LOCATION_ACCURACY_M`): ``with_parameter_set("mba")`` derives its sigmas
        from it when given no accuracy; None (default) when unknown.

    Notes
    -----
    Ground -> image converges for every point whose solution lies in the validity domain:
    rows within ``domain_margin`` scene lengths of the scene (the time polynomials are not
    extrapolated further), look angles across track up to ``max_look_angle_deg``, in front
    of the sensor. Other points get ``OUT_OF_DOMAIN`` (or ``DIVERGED`` / ``MAX_ITERATIONS``)
    and NaN; so do image points outside that domain in image -> ground.
    """

    name: ClassVar[str] = "spot-chenlee"
    schema_version: ClassVar[int] = 1
    parameter_sets: ClassVar[tuple[str, ...]] = ("default", *PARAMETER_SETS)

    #: Newton on the sampling time stops when |dt| is below this, seconds (paper: 1e-6 s).
    time_tolerance_s: ClassVar[float] = 1e-10
    #: Iteration cap of the Newton iteration on the sampling time.
    time_max_iterations: ClassVar[int] = 30
    #: Ray / height-surface intersection: tolerance on the height, metres, and iteration cap.
    intersection_tolerance_m: ClassVar[float] = 1e-6
    intersection_max_iterations: ClassVar[int] = 10
    #: Validity domain along track: rows within this many scene lengths of the scene.
    domain_margin: ClassVar[float] = 2.0
    #: Validity domain across track: look angles (``atan(Sy y / f)``) up to this, degrees.
    max_look_angle_deg: ClassVar[float] = 45.0
    #: Points handed to the kernels at once (bounds the memory of large calls).
    chunk_points: ClassVar[int | None] = 65536

    def __init__(
        self,
        coefficients: ArrayLike,
        frame: coords.LocalFrame,
        *,
        shape: tuple[int, int] = (6000, 6000),
        interior: Interior = SPOT1A_INTERIOR,
        height_range: tuple[float, float] = (-500.0, 9000.0),
        parameter_set: str = "coefficients",
        corrections: ArrayLike | None = None,
        sigmas: ArrayLike | None = None,
        adjustable: ArrayLike | None = None,
        covariance: ArrayLike | None = None,
        location_accuracy_m: float | None = None,
    ) -> None:
        nominal = np.array(coefficients, dtype=np.float64)
        if nominal.shape != (19,) or not np.all(np.isfinite(nominal)):
            raise ModelFormatError(
                f"ChenLeeModel: coefficients must be 19 finite values {list(COEFFICIENT_NAMES)}, "
                f"got shape {nominal.shape}"
            )
        if not isinstance(frame, coords.LocalFrame):
            raise ModelFormatError(
                f"ChenLeeModel: frame must be a geoblock.coords.LocalFrame, got {frame!r}")
        if type(frame) is not coords.LocalFrame:  # a subclass (the deprecated WorkFrame)
            frame = coords.LocalFrame(frame.lon0, frame.lat0, frame.h0, frame.azimuth_deg)
        if not isinstance(interior, Interior):
            raise ModelFormatError(f"ChenLeeModel: interior must be an Interior, got {interior!r}")
        try:
            rows, cols = (int(v) for v in shape)
        except (TypeError, ValueError):
            raise ModelFormatError(
                f"ChenLeeModel: shape must be (rows, cols), got {shape!r}") from None
        if rows <= 0 or cols <= 0:
            raise ModelFormatError(f"ChenLeeModel: shape must be positive, got {shape!r}")
        h0, h1 = (float(v) for v in height_range)
        if not (math.isfinite(h0) and math.isfinite(h1) and h0 < h1):
            raise ModelFormatError(
                f"ChenLeeModel: height_range must be finite (min, max), got {height_range!r}")
        if location_accuracy_m is not None:
            location_accuracy_m = location_accuracy(
                location_accuracy_m, "ChenLeeModel: location_accuracy_m (or None)")
        if parameter_set not in PARAMETER_SETS:
            raise ModelFormatError(
                f"ChenLeeModel: parameter_set must be one of {PARAMETER_SETS}, "
                f"got {parameter_set!r}"
            )
        if parameter_set == "coefficients":
            if corrections is not None:
                raise ModelFormatError("ChenLeeModel: corrections are only for parameter_set='mba'")
            names, values = COEFFICIENT_NAMES, nominal
        else:
            names = MBA_NAMES
            values = np.zeros(19) if corrections is None else np.array(corrections, np.float64)
        try:
            params = ParameterSet(names, values, COEFFICIENT_UNITS, sigmas, adjustable, covariance)
        except ValueError as exc:
            raise ModelFormatError(f"ChenLeeModel: {exc}") from exc
        effective = nominal if parameter_set == "coefficients" else nominal + params.values
        if not np.all(np.isfinite(effective)) or effective[18] == 0.0:
            raise ModelFormatError(f"ChenLeeModel: invalid coefficients (sy = {effective[18]!r})")
        nominal.flags.writeable = False
        effective = np.array(effective)
        effective.flags.writeable = False
        self._nominal = nominal
        self._coef = effective
        self._frame = frame
        self._interior = interior
        self._shape = (rows, cols)
        self._height_range = (h0, h1)
        self._set = parameter_set
        self._parameters = params
        self._location_accuracy_m = location_accuracy_m
        self._orbit = effective[:9].reshape(3, 3)  # rows X, Y, Z; columns t^0, t^1, t^2
        self._angles = effective[9:18].reshape(3, 3)  # rows omega, phi, kappa
        self._sy = float(effective[18])

    # ------------------------------------------------------------------ construction helpers
    @classmethod
    def table1(cls, frame: coords.LocalFrame | None = None, **kwargs: Any) -> Self:
        """Chen & Lee's Table 1 orientation on a SPOT 1A 6000 x 6000 scene.

        The paper does not give its local frame's origin; the default puts the origin at
        (121.91 E, 24.62 N) with ``X`` pointing south (azimuth 180: the satellite then flies
        SSW, heading 193.6 degrees, as a descending SPOT pass does), which puts the scene in
        central west Taiwan around (120.75 E, 24.40 N), where the paper's scene lies.
        """
        if frame is None:
            frame = coords.LocalFrame(121.91, 24.62, 0.0, 180.0)
        return cls(TABLE1_COEFFICIENTS, frame, **kwargs)

    @classmethod
    def example(cls) -> Self:
        """:meth:`table1` with the ``mba`` parameter set of a SPOT 1-4 product (350 m stated
        location accuracy): the model the conformance kit runs on."""
        return cls.table1().mba(SPOT_LOCATION_ACCURACY_M[1])

    # ------------------------------------------------------------------ properties
    @property
    def shape(self) -> tuple[int, int]:
        return self._shape

    @property
    def height_range(self) -> tuple[float, float]:
        return self._height_range

    @property
    def parameters(self) -> ParameterSet:
        return self._parameters

    @property
    def parameter_set(self) -> str:
        """``"coefficients"`` or ``"mba"``: the parameterisation the model has."""
        return self._set

    @property
    def location_accuracy_m(self) -> float | None:
        """The product's stated location accuracy (1 sigma, metres), or None if unknown."""
        return self._location_accuracy_m

    @property
    def coefficients(self) -> Float64Array:
        """(19,) effective coefficients (nominal + corrections for ``mba``), read-only."""
        return self._coef

    @property
    def nominal_coefficients(self) -> Float64Array:
        """(19,) the nominal coefficients the ``mba`` corrections apply to, read-only."""
        return self._nominal

    @property
    def frame(self) -> coords.LocalFrame:
        """The work frame of the orbit polynomials (:class:`geoblock.coords.LocalFrame`)."""
        return self._frame

    @property
    def interior(self) -> Interior:
        return self._interior

    @property
    def scene_duration_s(self) -> float:
        """``rows * line_period``, seconds."""
        return self._shape[0] * self._interior.line_period_s

    def position(self, t: ArrayLike) -> Float64Array:
        """Orbit ``(Xc, Yc, Zc)(t)`` in the work frame, (*S, 3) metres, ``t`` seconds."""
        (t,) = broadcast_float64(t=t)
        o = self._orbit
        return o[:, 0] + t[..., None] * o[:, 1] + t[..., None] ** 2 * o[:, 2]

    def attitude(self, t: ArrayLike) -> Float64Array:
        """Attitude ``(omega, phi, kappa)(t)``, (*S, 3) radians, ``t`` seconds."""
        (t,) = broadcast_float64(t=t)
        a = self._angles
        return a[:, 0] + t[..., None] * a[:, 1] + t[..., None] ** 2 * a[:, 2]

    # ------------------------------------------------------------------ parameter sets
    def _kwargs(self) -> dict[str, Any]:
        return {"shape": self._shape, "interior": self._interior,
                "height_range": self._height_range,
                "location_accuracy_m": self._location_accuracy_m}

    def with_parameters(self, values: ArrayLike) -> Self:
        new = self._parameters.with_values(values)
        if self._set == "coefficients":
            return type(self)(new.values, self._frame, **self._kwargs(), sigmas=new.sigmas,
                              adjustable=new.adjustable, covariance=new.covariance)
        return type(self)(self._nominal, self._frame, **self._kwargs(), parameter_set="mba",
                          corrections=new.values, sigmas=new.sigmas, adjustable=new.adjustable,
                          covariance=new.covariance)

    def mba_sigmas(self, location_accuracy_m: float) -> Float64Array:
        """A-priori sigmas of the 19 ``mba`` corrections from the product's location accuracy.

        With ``s`` the stated 1-sigma location accuracy (metres, e.g.
        :data:`SPOT_LOCATION_ACCURACY_M`), ``T`` the scene duration, ``H`` the slant range from
        the sensor at mid-scene to the image centre on the frame's origin height and
        ``W = H * (cols / 2) * pixel_size / focal_length`` the half swath:

        * orbit ``d_x0, d_y0, d_z0``: ``s``; rates ``s / T``; accelerations ``s / T^2`` (each
          term alone moves the sensor by ``s`` over the scene);
        * roll and pitch ``d_omega0, d_phi0``: ``s / H`` (the angle that moves the ground point
          by ``s``); ``d_kappa0`` (about the view axis): ``s / W`` (moves the scene edges by
          ``s``); rates and accelerations divided by ``T`` and ``T^2``;
        * ``d_sy``: ``s / W`` (a scale error that moves the scene edges by ``s``).

        Returns
        -------
        ndarray, (19,)
            In the units of :data:`COEFFICIENT_UNITS`.
        """
        s = location_accuracy(location_accuracy_m, "mba_sigmas: location_accuracy_m")
        rows, cols = self._shape
        t_mid = 0.5 * (rows - 1) * self._interior.line_period_s
        centre = self._backproject_work(np.array([(rows - 1) / 2.0]), np.array([(cols - 1) / 2.0]),
                                        np.array([self._frame.h0]))
        sensor = self.position(t_mid)
        slant = float(np.linalg.norm(centre[0][0] - sensor)) if centre[1][0] == Status.CONVERGED \
            else float(sensor[2] - self._frame.h0)
        interior = self._interior
        half_swath = slant * (cols / 2.0) * interior.pixel_size_m / interior.focal_length_m
        t = self.scene_duration_s
        time = np.array([1.0, 1.0 / t, 1.0 / t**2])
        out = np.concatenate([
            np.tile(s * time, 3),
            s / slant * time, s / slant * time, s / half_swath * time,
            [s / half_swath],
        ])
        return out

    def with_parameter_set(self, name: str, **options: Any) -> Self:
        """The same geometry with another parameterisation (the sensor-model protocol's
        parameter presets, :attr:`parameter_sets`).

        Parameters
        ----------
        name : {"default", "coefficients", "mba"}
            * ``"default"``: the parameters as they are (returns ``self``; no options);
            * ``"coefficients"``: the effective coefficients become the parameters, free
              unless ``sigmas`` or an accuracy is given;
            * ``"mba"``: the effective coefficients become the nominal values and the
              parameters are zero corrections, with a-priori sigmas from the accuracy (see
              :meth:`mba_sigmas`) or ``sigmas``; without either, from
              :attr:`location_accuracy_m`.
        **options
            ``accuracy_m`` (float): the location accuracy (1 sigma, metres) the sigmas derive
            from (:meth:`mba_sigmas`), ``location_accuracy_m`` an alias; or ``sigmas``
            (array_like, (19,)): explicit a-priori sigmas instead.

        Returns
        -------
        ChenLeeModel
            Projecting as ``self`` does (corrections are folded into the coefficients).

        Raises
        ------
        ParameterSetError
            An unknown name or option, an accuracy and ``sigmas`` both given, or ``"mba"``
            with no accuracy to derive its sigmas from.
        """
        if name not in PARAMETER_SETS:
            return super().with_parameter_set(name, **options)
        self._parameter_set_request(name, options, ("accuracy_m", "location_accuracy_m", "sigmas"))
        accuracy = options.get("accuracy_m")
        alias = options.get("location_accuracy_m")
        if accuracy is not None and alias is not None:
            raise ParameterSetError(
                f"ChenLeeModel: give accuracy_m or location_accuracy_m (an alias), not both "
                f"(parameter set {name!r})")
        accuracy = alias if accuracy is None else accuracy
        sigmas = options.get("sigmas")
        if accuracy is not None and sigmas is not None:
            raise ParameterSetError(
                f"ChenLeeModel: give accuracy_m or sigmas, not both (parameter set {name!r})")
        if name == "mba" and accuracy is None and sigmas is None:
            accuracy = accuracy_or_stored(
                None, self._location_accuracy_m, "ChenLeeModel 'spot-chenlee'", name,
                advice="accuracy_m= (1 sigma, metres, e.g. SPOT_LOCATION_ACCURACY_M) or sigmas=")
        if accuracy is not None:
            try:
                sigmas = self.mba_sigmas(accuracy)
            except (ModelFormatError, TypeError, ValueError) as exc:
                raise ParameterSetError(f"ChenLeeModel, parameter set {name!r}: {exc}") from exc
        return type(self)(self._coef, self._frame, **self._kwargs(), parameter_set=name,
                          sigmas=sigmas)

    def mba(self, location_accuracy_m: float) -> Self:
        """The ``mba`` set: zero corrections to the current coefficients, a-priori sigmas from
        the stated location accuracy (metres, 1 sigma; see :meth:`mba_sigmas`)."""
        return self.with_parameter_set("mba", location_accuracy_m=location_accuracy_m)

    # ------------------------------------------------------------------ serialisation
    def to_dict(self) -> dict[str, Any]:
        out = {
            "model": self.name,
            "schema_version": self.schema_version,
            "shape": list(self._shape),
            "height_range": list(self._height_range),
            "frame": self._frame.to_dict(),
            "interior": self._interior.to_dict(),
            "coefficients": [float(v) for v in self._nominal],
            "parameter_set": self._set,
            "parameters": self._parameters.to_dict(),
        }
        if self._location_accuracy_m is not None:  # absent from older JSON: stays optional
            out["location_accuracy_m"] = self._location_accuracy_m
        return out

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> Self:
        try:
            version = int(data.get("schema_version", 1))
            if version > cls.schema_version:
                raise SerializationError(
                    f"{cls.name} model dictionary has schema_version {version}; this geoblock-spot "
                    f"reads up to {cls.schema_version}"
                )
            params = ParameterSet.from_dict(data["parameters"])
            parameter_set = data["parameter_set"]
            return cls(
                data["coefficients"] if parameter_set != "coefficients" else params.values,
                coords.LocalFrame.from_dict(data["frame"]),
                shape=tuple(data["shape"]),
                interior=Interior(**data["interior"]),
                height_range=tuple(data["height_range"]),
                parameter_set=parameter_set,
                corrections=params.values if parameter_set == "mba" else None,
                sigmas=params.sigmas,
                adjustable=params.adjustable,
                covariance=params.covariance,
                location_accuracy_m=data.get("location_accuracy_m"),
            )
        except KeyError as exc:
            raise SerializationError(f"{cls.name} model dictionary misses {exc}") from None
        except (TypeError, ValueError) as exc:
            if isinstance(exc, SerializationError):
                raise
            raise SerializationError(f"invalid {cls.name} model dictionary: {exc}") from exc

    # ------------------------------------------------------------------ kernels
    def _in_domain(self, row: np.ndarray, col: np.ndarray) -> np.ndarray:
        """Rows within ``domain_margin`` scene lengths of the scene (the time polynomials'
        extrapolation limit); columns within ``max_look_angle_deg`` of the view axis."""
        rows, cols = self._shape
        m = self.domain_margin
        tan_look = np.abs(self._sy * (col - (cols - 1) / 2.0) * self._interior.pixel_size_m
                          / self._interior.focal_length_m)
        return ((row >= -0.5 - m * rows) & (row <= rows - 0.5 + m * rows)
                & (tan_look <= math.tan(math.radians(self.max_look_angle_deg))))

    def _solve_time(self, p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Newton on f(t) = m1(t) . (P - C(t)) = 0 (eqs. 4-5), vectorised with a status.

        ``p`` (N, 3) work-frame points. Returns ``t`` (N,) seconds and the status
        (CONVERGED, OUT_OF_DOMAIN when ``t`` leaves the time domain, DIVERGED, MAX_ITERATIONS).
        """
        n = p.shape[0]
        rows = self._shape[0]
        lp = self._interior.line_period_s
        t_lo = (-0.5 - self.domain_margin * rows) * lp
        t_hi = (rows - 0.5 + self.domain_margin * rows) * lp
        span = t_hi - t_lo
        t = np.full(n, 0.5 * (rows - 1) * lp)
        status = np.full(n, np.uint8(Status.MAX_ITERATIONS), dtype=np.uint8)
        active = np.arange(n)
        orbit, angles = self._orbit, self._angles
        for _ in range(self.time_max_iterations):
            ta = t[active]
            t1 = ta[:, None]
            pos = orbit[:, 0] + t1 * orbit[:, 1] + t1 * t1 * orbit[:, 2]
            vel = orbit[:, 1] + 2.0 * t1 * orbit[:, 2]
            ang = angles[:, 0] + t1 * angles[:, 1] + t1 * t1 * angles[:, 2]
            rate = angles[:, 1] + 2.0 * t1 * angles[:, 2]
            m1, dm1 = _first_row(*ang.T, *rate.T)
            d = p[active] - pos
            f = np.einsum("ij,ij->i", m1, d)
            fp = np.einsum("ij,ij->i", dm1, d) - np.einsum("ij,ij->i", m1, vel)
            with np.errstate(divide="ignore", invalid="ignore"):
                dt = -f / fp
            t_new = ta + dt
            bad = ~np.isfinite(t_new)
            outside = ~bad & ((t_new < t_lo - span) | (t_new > t_hi + span))
            done = ~bad & ~outside & (np.abs(dt) < self.time_tolerance_s)
            t[active] = np.where(bad, np.nan, t_new)
            status[active[bad]] = Status.DIVERGED
            status[active[outside]] = Status.OUT_OF_DOMAIN
            status[active[done]] = Status.CONVERGED
            active = active[~(bad | outside | done)]
            if active.size == 0:
                break
        return t, status

    def _image_coords(self, p: np.ndarray, t: np.ndarray):
        """Row, col, and the intermediate quantities at solved times."""
        lp = self._interior.line_period_s
        t1 = t[:, None]
        pos = self._orbit[:, 0] + t1 * self._orbit[:, 1] + t1 * t1 * self._orbit[:, 2]
        ang = self._angles[:, 0] + t1 * self._angles[:, 1] + t1 * t1 * self._angles[:, 2]
        so, co = np.sin(ang[:, 0]), np.cos(ang[:, 0])
        sp, cp = np.sin(ang[:, 1]), np.cos(ang[:, 1])
        sk, ck = np.sin(ang[:, 2]), np.cos(ang[:, 2])
        d = p - pos
        u2 = (-cp * sk * d[:, 0] + (-so * sp * sk + co * ck) * d[:, 1]
              + (co * sp * sk + so * ck) * d[:, 2])
        u3 = sp * d[:, 0] - so * cp * d[:, 1] + co * cp * d[:, 2]
        with np.errstate(divide="ignore", invalid="ignore"):
            y = -self._interior.focal_length_m * u2 / (self._sy * u3)
        col = y / self._interior.pixel_size_m + (self._shape[1] - 1) / 2.0
        row = t / lp
        return row, col, u3

    def ground_to_image(self, lon: np.ndarray, lat: np.ndarray, h: np.ndarray) -> tuple:
        p = _work_points(self._frame, lon, lat, h)
        t, status = self._solve_time(p)
        ok = status == Status.CONVERGED
        t = np.where(ok, t, 0.0)
        row, col, u3 = self._image_coords(p, t)
        # the sensor must be above the point's horizon (not through the Earth) and the point
        # in front of the sensor
        lam, phi = np.radians(lon), np.radians(lat)
        up_ecef = np.stack([np.cos(phi) * np.cos(lam), np.cos(phi) * np.sin(lam), np.sin(phi)], -1)
        up_work = up_ecef @ self._frame.rotation.T
        visible = np.einsum("ij,ij->i", self.position(t) - p, up_work) > 0
        bad = ok & ~((u3 < 0) & visible & self._in_domain(row, col))
        status[bad] = Status.OUT_OF_DOMAIN
        return row, col, status

    def _backproject_work(self, row: np.ndarray, col: np.ndarray, h: np.ndarray):
        """Image -> ground at h: work-frame points (N, 3), status, and (lon, lat)."""
        n = row.shape[0]
        status = np.full(n, np.uint8(Status.MAX_ITERATIONS), dtype=np.uint8)
        lon = np.full(n, np.nan)
        lat = np.full(n, np.nan)
        inside = self._in_domain(row, col)
        status[~inside] = Status.OUT_OF_DOMAIN
        t = row * self._interior.line_period_s
        pos = self.position(t)
        m, _ = _rotation(*self.attitude(t).T)
        y = (col - (self._shape[1] - 1) / 2.0) * self._interior.pixel_size_m
        f = self._interior.focal_length_m
        image = np.stack([np.zeros(n), self._sy * y, np.full(n, -f)], axis=-1)
        d_work = np.einsum("nji,nj->ni", m, image)  # M^T u
        d_work /= np.linalg.norm(d_work, axis=-1, keepdims=True)
        o = self._frame.to_ecef_xyz(pos)
        d = d_work @ self._frame.rotation
        todo = np.flatnonzero(inside)
        lon_i, lat_i, s_i, status_i = coords.intersect_height(
            o[todo], d[todo], h[todo], self.intersection_tolerance_m,
            self.intersection_max_iterations)
        lon[todo], lat[todo], status[todo] = lon_i, lat_i, status_i
        s = np.full(n, np.nan)
        s[todo] = s_i
        ok = status == Status.CONVERGED
        p = np.full((n, 3), np.nan)
        p[ok] = self._frame.from_ecef_xyz(o[ok] + s[ok, None] * d[ok])
        return p, status, lon, lat

    def image_to_ground(self, row: np.ndarray, col: np.ndarray, h: np.ndarray) -> tuple:
        _, status, lon, lat = self._backproject_work(row, col, h)
        return lon, lat, status

    # ------------------------------------------------------------------ analytic partials
    def _jacobians(self, lon, lat, h, ground: bool):
        """d(row, col)/d(P_work) (N, 2, 3) or d(row, col)/d(parameters) (N, 2, 19)."""
        shape = lon.shape
        lon, lat, h = (a.ravel() for a in (lon, lat, h))
        width = 3 if ground else 19
        out = np.full((lon.size, 2, width), np.nan)
        ok = np.isfinite(lon) & np.isfinite(lat) & np.isfinite(h)
        if ok.any():
            row, col, status = self.ground_to_image(lon[ok], lat[ok], h[ok])
            good = status == Status.CONVERGED
            idx = np.flatnonzero(ok)[good]
            p = _work_points(self._frame, lon[idx], lat[idx], h[idx])
            t = row[good] * self._interior.line_period_s
            out[idx] = self._jacobian_kernel(p, t, ground)
        return out.reshape(shape + (2, width))

    def _jacobian_kernel(self, p: np.ndarray, t: np.ndarray, ground: bool) -> np.ndarray:
        n = p.shape[0]
        lp = self._interior.line_period_s
        f, ps = self._interior.focal_length_m, self._interior.pixel_size_m
        powers = np.stack([np.ones(n), t, t * t], axis=-1)  # (N, 3)
        t1 = t[:, None]
        pos = self._orbit[:, 0] + t1 * self._orbit[:, 1] + t1 * t1 * self._orbit[:, 2]
        vel = self._orbit[:, 1] + 2.0 * t1 * self._orbit[:, 2]
        ang = self._angles[:, 0] + t1 * self._angles[:, 1] + t1 * t1 * self._angles[:, 2]
        rate = self._angles[:, 1] + 2.0 * t1 * self._angles[:, 2]
        m, dm = _rotation(ang[:, 0], ang[:, 1], ang[:, 2], derivatives=True)  # (N,3,3), (3,N,3,3)
        d = p - pos
        u = np.einsum("nij,nj->ni", m, d)
        dm_d = np.einsum("knij,nj->nik", dm, d)  # (N, 3 u-components, 3 angles)
        # explicit d u / d t at fixed P and parameters
        du_dt = np.einsum("nik,nk->ni", dm_d, rate) - np.einsum("nij,nj->ni", m, vel)
        f_t = du_dt[:, 0]
        sy = self._sy
        dy_du2 = -f / (sy * u[:, 2])
        dy_du3 = f * u[:, 1] / (sy * u[:, 2] ** 2)
        if ground:
            explicit = m  # (N, 3 u, 3 P)
        else:
            explicit = np.zeros((n, 3, 19))
            for axis in range(3):  # orbit X, Y, Z: du/dC = -M
                explicit[:, :, 3 * axis:3 * axis + 3] = -m[:, :, axis, None] * powers[:, None, :]
            for k in range(3):  # omega, phi, kappa
                explicit[:, :, 9 + 3 * k:12 + 3 * k] = dm_d[:, :, k, None] * powers[:, None, :]
        dt = -explicit[:, 0, :] / f_t[:, None]  # (N, W) implicit d t / d var from f(t) = 0
        du = explicit + du_dt[:, :, None] * dt[:, None, :]
        d_col = (dy_du2[:, None] * du[:, 1, :] + dy_du3[:, None] * du[:, 2, :]) / ps
        if not ground:
            y = -f * u[:, 1] / (sy * u[:, 2])
            d_col[:, 18] = -y / sy / ps
        return np.stack([dt / lp, d_col], axis=1)

    def partials_ground(self, lon: ArrayLike, lat: ArrayLike, h: ArrayLike) -> Float64Array:
        """d(row, col)/d(x, y, z) ECEF, pixels per metre, analytic, (*S, 2, 3).

        Implicit differentiation of ``f(t) = 0`` for the row, chained through the
        across-track equation for the column. NaN where the point does not project.
        """
        lon, lat, h = broadcast_float64(lon=lon, lat=lat, h=h)
        return self._jacobians(lon, lat, h, ground=True) @ self._frame.rotation

    def partials_parameters(self, lon: ArrayLike, lat: ArrayLike, h: ArrayLike) -> Float64Array:
        """d(row, col)/d(parameter), analytic, (*S, 2, 19), pixels per parameter unit.

        The same columns for both sets (a correction ``d_k`` moves the coefficient ``k``).
        """
        lon, lat, h = broadcast_float64(lon=lon, lat=lat, h=h)
        return self._jacobians(lon, lat, h, ground=False)
