"""Synthetic analytic sensor models with closed-form geometry.

They serve tests, benchmarks, documentation examples and the conformance kit's self-test, and
they exercise the two ways of writing a model on :class:`~geoblock.models.SensorModelBase`:

* :class:`AffineCamera` implements ground -> image (like an RPC) with analytic partials; its
  backprojection comes from the base class's Newton inversion.
* :class:`ConstantVelocityPushbroom` implements image -> ground (like a physical line-scanner:
  one exposure per row, a satellite moving at constant velocity, a linear CCD) with numeric
  partials; its projection comes from the base class's Newton inversion.

:func:`with_attitude_offsets` puts a known attitude error (a wander the on-board attitude
lacks) into a :class:`~geoblock.models.linescan.LinescanModel`: the truth of a jitter test.

They build, project, pickle and round-trip ``to_dict``/``from_dict`` on their own. They are
test models, so geoblock's built-in plugin does not register them (``synthetic-affine``,
``synthetic-pushbroom``): :func:`geoblock.testing.enable_synthetic_models` (or
``GEOBLOCK_PLUGIN_MODULES=geoblock.testing.plugin``) does, and their model JSON then opens with
:func:`geoblock.open_model` like any model's.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import TYPE_CHECKING, Any, ClassVar, Self

import numpy as np

from geoblock import coords
from geoblock.models.base import KernelResult, SensorModelBase
from geoblock.models.parameters import ParameterSet
from geoblock.typing import ArrayLike, Float64Array

if TYPE_CHECKING:
    from geoblock.models.linescan import LinescanModel

__all__ = ["AffineCamera", "ConstantVelocityPushbroom", "with_attitude_offsets"]


class AffineCamera(SensorModelBase):
    """Image coordinates affine in local east/north/up metres around an origin.

    ``row = c[0, 0] + c[0, 1] e + c[0, 2] n + c[0, 3] u`` and likewise ``col`` with
    ``c[1, :]``, where ``(e, n, u)`` are local tangent-plane metres at ``origin``.

    Parameters
    ----------
    shape : (int, int)
        ``(rows, cols)``.
    origin : (float, float, float)
        ``(lon, lat, h)`` of the tangent-plane origin, degrees and metres.
    coefficients : array_like, (2, 4)
        Pixels and pixels per metre; these are the model's eight parameters
        ``row_0, row_e, row_n, row_u, col_0, col_e, col_n, col_u``.
    height_range : (float, float)
        Metres above the ellipsoid.
    sigmas : array_like, (8,), optional
        A-priori sigmas of the coefficients (default free).
    """

    name: ClassVar[str] = "synthetic-affine"
    schema_version: ClassVar[int] = 1
    _NAMES = ("row_0", "row_e", "row_n", "row_u", "col_0", "col_e", "col_n", "col_u")
    _UNITS = ("px", "px/m", "px/m", "px/m") * 2

    def __init__(
        self,
        shape: tuple[int, int],
        origin: tuple[float, float, float],
        coefficients: ArrayLike,
        height_range: tuple[float, float] = (-500.0, 5000.0),
        sigmas: ArrayLike | None = None,
    ) -> None:
        self._shape = (int(shape[0]), int(shape[1]))
        self._origin = (float(origin[0]), float(origin[1]), float(origin[2]))
        self._frame = coords.LocalFrame(*self._origin)
        coeffs = np.asarray(coefficients, dtype=np.float64).reshape(2, 4)
        self._height_range = (float(height_range[0]), float(height_range[1]))
        self._parameters = ParameterSet(self._NAMES, coeffs.ravel(), self._UNITS, sigmas)

    @classmethod
    def example(cls, shape: tuple[int, int] = (1000, 1200)) -> AffineCamera:
        """A 2 m GSD north-up camera looking 5.7 degrees off nadir, near Nice, France."""
        rows, cols = shape
        return cls(
            shape,
            origin=(7.05, 43.70, 100.0),
            coefficients=[[(rows - 1) / 2, 0.0, -0.5, 0.05], [(cols - 1) / 2, 0.5, 0.0, -0.02]],
            height_range=(-500.0, 3000.0),
        )

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
    def coefficients(self) -> Float64Array:
        """(2, 4) the affine coefficients (the parameter values)."""
        return self._parameters.values.reshape(2, 4)

    def with_parameters(self, values: ArrayLike) -> Self:
        new = self._parameters.with_values(values)
        return type(self)(self._shape, self._origin, new.values, self._height_range, new.sigmas)

    def to_dict(self) -> dict[str, Any]:
        return {
            "model": self.name,
            "schema_version": self.schema_version,
            "shape": list(self._shape),
            "origin": list(self._origin),
            "height_range": list(self._height_range),
            "parameters": self._parameters.to_dict(),
        }

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> Self:
        params = ParameterSet.from_dict(data["parameters"])
        return cls(tuple(data["shape"]), tuple(data["origin"]), params.values,
                   tuple(data["height_range"]), params.sigmas)

    def ground_seed(self) -> tuple[float, float]:
        return self._origin[0], self._origin[1]

    def ground_to_image(self, lon: Float64Array, lat: Float64Array, h: Float64Array
                        ) -> KernelResult:
        e, n, u = self._frame.from_geodetic(lon, lat, h)
        design = np.stack([np.ones_like(e), e, n, u], axis=-1)
        rc = design @ self.coefficients.T
        return rc[:, 0], rc[:, 1]

    def partials_ground(self, lon: ArrayLike, lat: ArrayLike, h: ArrayLike) -> Float64Array:
        """Analytic: constant ``c[:, 1:] @ R`` (R the ECEF -> ENU rotation at the origin)."""
        lon, lat, h = np.broadcast_arrays(*(np.asarray(v, float) for v in (lon, lat, h)))
        jac = self.coefficients[:, 1:] @ self._frame.rotation
        return np.broadcast_to(jac, lon.shape + (2, 3)).copy()

    def partials_parameters(self, lon: ArrayLike, lat: ArrayLike, h: ArrayLike) -> Float64Array:
        """Analytic: ``[1, e, n, u]`` in the row block and in the column block."""
        e, n, u = self._frame.from_geodetic(lon, lat, h)
        design = np.stack([np.ones_like(e), e, n, u], axis=-1)
        out = np.zeros(e.shape + (2, 8))
        out[..., 0, :4] = design
        out[..., 1, 4:] = design
        return out


class ConstantVelocityPushbroom(SensorModelBase):
    """A line scanner moving at constant velocity in a local tangent-plane frame.

    Row ``r`` is exposed at time ``t = r * line_period``; the satellite is then at
    ``position + velocity * t`` (local ENU metres around ``origin``). Column ``c`` looks along
    ``(tan_psi, 0, -1)`` in the body frame, ``tan_psi = (c - (cols - 1) / 2) * ifov``, rotated
    by the attitude ``roll`` (about north), ``pitch`` (about east) and ``yaw`` (about up).
    The three attitude angles (radians) are the model's parameters.

    Parameters
    ----------
    shape : (int, int)
    origin : (float, float)
        ``(lon, lat)`` of the local frame's origin (at height 0), degrees.
    position : (float, float, float)
        Satellite ENU position at ``t = 0``, metres.
    velocity : (float, float, float)
        ENU velocity, metres per second.
    line_period : float
        Seconds per row.
    ifov : float
        Across-track angle per column, radians.
    attitude : (float, float, float)
        ``roll, pitch, yaw``, radians.
    sigmas : (float, float, float), optional
        A-priori sigmas of the attitude, radians (default 1e-4 each).
    height_range : (float, float)
        Metres above the ellipsoid.
    """

    name: ClassVar[str] = "synthetic-pushbroom"
    schema_version: ClassVar[int] = 1

    #: tolerance (metres of height) and iteration cap of the ray/height-surface intersection
    intersection_tolerance_m: ClassVar[float] = 1e-7
    intersection_max_iterations: ClassVar[int] = 20

    def __init__(
        self,
        shape: tuple[int, int],
        origin: tuple[float, float],
        position: ArrayLike,
        velocity: ArrayLike,
        line_period: float,
        ifov: float,
        attitude: ArrayLike = (0.0, 0.0, 0.0),
        sigmas: ArrayLike | None = (1e-4, 1e-4, 1e-4),
        height_range: tuple[float, float] = (-500.0, 9000.0),
    ) -> None:
        self._shape = (int(shape[0]), int(shape[1]))
        self._origin = (float(origin[0]), float(origin[1]))
        self._frame = coords.LocalFrame(self._origin[0], self._origin[1], 0.0)
        self._position = np.array(position, dtype=np.float64).reshape(3)
        self._velocity = np.array(velocity, dtype=np.float64).reshape(3)
        self._line_period = float(line_period)
        self._ifov = float(ifov)
        self._height_range = (float(height_range[0]), float(height_range[1]))
        self._parameters = ParameterSet(("roll", "pitch", "yaw"), attitude, ("rad",) * 3, sigmas)

    @classmethod
    def example(cls, shape: tuple[int, int] = (800, 1000), roll: float = 0.0) -> Self:
        """A 2.5 m GSD scanner at 700 km flying north over Nice, France."""
        rows, cols = shape
        speed = 7000.0
        line_period = 2.5 / speed
        return cls(
            shape,
            origin=(7.05, 43.70),
            position=(0.0, -speed * line_period * rows / 2, 700e3),
            velocity=(0.0, speed, 0.0),
            line_period=line_period,
            ifov=2.5 / 700e3,
            attitude=(roll, 0.0, 0.0),
        )

    @property
    def shape(self) -> tuple[int, int]:
        return self._shape

    @property
    def height_range(self) -> tuple[float, float]:
        return self._height_range

    @property
    def parameters(self) -> ParameterSet:
        return self._parameters

    def with_parameters(self, values: ArrayLike) -> Self:
        new = self._parameters.with_values(values)
        return type(self)(self._shape, self._origin, self._position, self._velocity,
                          self._line_period, self._ifov, new.values, new.sigmas,
                          self._height_range)

    def to_dict(self) -> dict[str, Any]:
        return {
            "model": self.name,
            "schema_version": self.schema_version,
            "shape": list(self._shape),
            "origin": list(self._origin),
            "position": self._position.tolist(),
            "velocity": self._velocity.tolist(),
            "line_period": self._line_period,
            "ifov": self._ifov,
            "height_range": list(self._height_range),
            "parameters": self._parameters.to_dict(),
        }

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> Self:
        params = ParameterSet.from_dict(data["parameters"])
        return cls(tuple(data["shape"]), tuple(data["origin"]), data["position"],
                   data["velocity"], data["line_period"], data["ifov"], params.values,
                   params.sigmas, tuple(data["height_range"]))

    def _rotation(self) -> Float64Array:
        """(3, 3) body -> ENU rotation from roll (about N), pitch (about E), yaw (about U)."""
        roll, pitch, yaw = self._parameters.values
        cr, sr = np.cos(roll), np.sin(roll)
        cp, sp = np.cos(pitch), np.sin(pitch)
        cy, sy = np.cos(yaw), np.sin(yaw)
        r_roll = np.array([[cr, 0, sr], [0, 1, 0], [-sr, 0, cr]])  # about north: tilts east
        r_pitch = np.array([[1, 0, 0], [0, cp, sp], [0, -sp, cp]])  # about east: tilts north
        r_yaw = np.array([[cy, -sy, 0], [sy, cy, 0], [0, 0, 1]])
        return r_yaw @ r_pitch @ r_roll

    def image_to_ground(self, row: Float64Array, col: Float64Array, h: Float64Array
                        ) -> KernelResult:
        t = row * self._line_period
        origin_enu = self._position + t[:, None] * self._velocity
        tan_psi = (col - (self._shape[1] - 1) / 2.0) * self._ifov
        body = np.stack([tan_psi, np.zeros_like(tan_psi), -np.ones_like(tan_psi)], axis=-1)
        d_enu = body @ self._rotation().T
        d_enu /= np.linalg.norm(d_enu, axis=-1, keepdims=True)
        o = np.stack(self._frame.to_ecef(*origin_enu.T), axis=-1)
        d = d_enu @ self._frame.rotation  # ENU -> ECEF directions
        lon, lat, _, status = coords.intersect_height(
            o, d, h, self.intersection_tolerance_m, self.intersection_max_iterations)
        return lon, lat, status


def with_attitude_offsets(model: LinescanModel,
                          angles: Callable[[Float64Array], ArrayLike], *,
                          step_s: float = 0.002) -> LinescanModel:
    """``model`` whose attitude carries extra roll, pitch, yaw offsets ``angles(t)``.

    Parameters
    ----------
    model : LinescanModel
    angles : callable
        ``angles(time_s) -> (T, 3)`` roll, pitch, yaw, radians, right-multiplied to the
        attitude as the model's own attitude parameters are (``R(t) Rx Ry Rz``); ``time_s``
        (T,) seconds since the model's epoch.
    step_s : float
        Sampling of the new attitude record over the old one's valid span, seconds (fine
        enough for the offsets' highest frequency: the record is interpolated between
        samples).

    Returns
    -------
    LinescanModel
        The same model (frame, parameters, geometry) with the resampled attitude.
    """
    from geoblock.models.linescan import (
        Attitude,
        matrix_to_quaternion,
        rotation_xyz,
    )

    lo, hi = model.attitude.valid_span_s
    t = np.arange(lo, hi, float(step_s))
    a = np.asarray(angles(t), dtype=np.float64)
    rot = model.attitude.matrix(t) @ rotation_xyz(a[:, 0], a[:, 1], a[:, 2])
    return model.replace(attitude=Attitude(t, matrix_to_quaternion(rot),
                                           frame=model.attitude.frame))
