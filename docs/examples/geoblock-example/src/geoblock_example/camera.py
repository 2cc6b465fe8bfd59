"""A frame (central-perspective) camera: the collinearity equations in a local ENU frame."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any, ClassVar, Self

import numpy as np

from geoblock.coords import LocalFrame
from geoblock.errors import ModelFormatError
from geoblock.models import ParameterSet, SensorModelBase, broadcast_float64, warn_status
from geoblock.typing import ArrayLike, Float64Array, Status

__all__ = ["FrameCamera"]

# The six exterior-orientation parameters an adjustment may refine.
PARAMETER_NAMES = ("east_offset", "north_offset", "up_offset", "omega", "phi", "kappa")
PARAMETER_UNITS = ("m", "m", "m", "rad", "rad", "rad")


def rotation_matrix(omega: float, phi: float, kappa: float) -> np.ndarray:
    """(3, 3) ``M = R3(kappa) R2(phi) R1(omega)``: local ENU -> camera axes."""
    co, so = np.cos(omega), np.sin(omega)
    cp, sp = np.cos(phi), np.sin(phi)
    ck, sk = np.cos(kappa), np.sin(kappa)
    r_omega = np.array([[1.0, 0.0, 0.0], [0.0, co, so], [0.0, -so, co]])
    r_phi = np.array([[cp, 0.0, -sp], [0.0, 1.0, 0.0], [sp, 0.0, cp]])
    r_kappa = np.array([[ck, sk, 0.0], [-sk, ck, 0.0], [0.0, 0.0, 1.0]])
    return r_kappa @ r_phi @ r_omega


# --8<-- [start:init]
class FrameCamera(SensorModelBase):
    """A pinhole (frame) camera looking down from a projection centre.

    The camera axes are ``x`` along image columns, ``y`` against image rows and ``z`` away
    from the scene; with all angles zero the camera looks straight down, north up. A ground
    point with local east/north/up coordinates ``X`` (metres, in a tangent-plane frame at the
    projection centre) is imaged at::

        (xc, yc, zc) = M(omega, phi, kappa) @ (X - offset)
        col = col0 - f * xc / zc
        row = row0 + f * yc / zc

    Parameters
    ----------
    shape : (int, int)
        ``(rows, cols)`` of the image.
    principal_distance : float
        ``f``, pixels.
    principal_point : (float, float)
        ``(row0, col0)``, pixels (pixel-centre convention).
    centre : (float, float, float)
        Nominal projection centre ``(lon, lat, h)``: degrees, metres above the ellipsoid.
    attitude : (float, float, float)
        ``(omega, phi, kappa)``, radians, rotations about the local east, north and up axes.
    offset : (float, float, float)
        Correction of the projection centre ``(east, north, up)``, metres (default 0).
    sigmas : array_like, (6,), optional
        A-priori sigmas of ``east_offset, north_offset, up_offset`` (m) and
        ``omega, phi, kappa`` (rad). Default 10 m and 1e-4 rad.
    height_range : (float, float)
        Heights where the model is used, metres above the ellipsoid.
    """

    name: ClassVar[str] = "example-frame"
    schema_version: ClassVar[int] = 1

    def __init__(
        self,
        shape: tuple[int, int],
        principal_distance: float,
        principal_point: tuple[float, float],
        centre: tuple[float, float, float],
        attitude: ArrayLike = (0.0, 0.0, 0.0),
        offset: ArrayLike = (0.0, 0.0, 0.0),
        sigmas: ArrayLike | None = (10.0, 10.0, 10.0, 1e-4, 1e-4, 1e-4),
        height_range: tuple[float, float] = (-500.0, 5000.0),
    ) -> None:
        self._shape = (int(shape[0]), int(shape[1]))
        self._f = float(principal_distance)
        self._pp = (float(principal_point[0]), float(principal_point[1]))
        self._centre = tuple(float(v) for v in centre)
        self._height_range = (float(height_range[0]), float(height_range[1]))
        if not self._f > 0:
            raise ModelFormatError(
                f"FrameCamera: principal_distance must be > 0, got {self._f!r}")
        if not self._height_range[1] < self._centre[2]:
            raise ModelFormatError(
                f"FrameCamera: height_range {self._height_range} must lie below the "
                f"projection centre (h = {self._centre[2]} m)"
            )
        values = np.concatenate([np.ravel(offset), np.ravel(attitude)]).astype(np.float64)
        self._parameters = ParameterSet(PARAMETER_NAMES, values, PARAMETER_UNITS, sigmas)
        # Derived, never serialised: the work frame and the rotation.
        self._frame = LocalFrame(*self._centre)
        self._rotation = rotation_matrix(*values[3:])
# --8<-- [end:init]

    @classmethod
    def example(cls) -> Self:
        """A small-satellite frame camera, 3.7 m pixels from 475 km, over Nice, France."""
        return cls(
            shape=(1100, 1650),
            principal_distance=128_000.0,
            principal_point=(549.5, 824.5),
            centre=(7.05, 43.70, 475_000.0),
            attitude=(0.02, -0.01, 0.3),
            height_range=(-500.0, 4000.0),
        )

    # --8<-- [start:state]
    # ---------------------------------------------------------------- state
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
        return type(self)(
            self._shape, self._f, self._pp, self._centre,
            attitude=new.values[3:], offset=new.values[:3],
            sigmas=new.sigmas, height_range=self._height_range,
        )

    def to_dict(self) -> dict[str, Any]:
        return {
            "model": self.name,
            "schema_version": self.schema_version,
            "shape": list(self._shape),
            "principal_distance": self._f,
            "principal_point": list(self._pp),
            "centre": list(self._centre),
            "height_range": list(self._height_range),
            "parameters": self._parameters.to_dict(),
        }

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> Self:
        params = ParameterSet.from_dict(data["parameters"])
        return cls(
            tuple(data["shape"]), data["principal_distance"], tuple(data["principal_point"]),
            tuple(data["centre"]), attitude=params.values[3:], offset=params.values[:3],
            sigmas=params.sigmas, height_range=tuple(data["height_range"]),
        )

    # --8<-- [end:state]
    # --8<-- [start:geometry]
    # ---------------------------------------------------------------- geometry
    def ground_to_image(
        self, lon: Float64Array, lat: Float64Array, h: Float64Array
    ) -> tuple[Float64Array, Float64Array, np.ndarray]:
        """The kernel: collinearity on flat, finite float64 arrays.

        Parameters
        ----------
        lon, lat : ndarray, (N,)
            Degrees (WGS84).
        h : ndarray, (N,)
            Metres above the WGS84 ellipsoid.

        Returns
        -------
        row, col : ndarray, (N,)
            Pixels, pixel-centre convention.
        status : ndarray of uint8, (N,)
            ``OUT_OF_DOMAIN`` for points behind the camera, else ``CONVERGED``.
        """
        enu = np.stack(self._frame.from_geodetic(lon, lat, h), axis=-1)  # (N, 3)
        cam = (enu - self._parameters.values[:3]) @ self._rotation.T  # (N, 3) camera axes
        behind = ~(cam[:, 2] < 0.0)  # the scene must be in front of the camera (zc < 0)
        with np.errstate(divide="ignore", invalid="ignore"):
            col = self._pp[1] - self._f * cam[:, 0] / cam[:, 2]
            row = self._pp[0] + self._f * cam[:, 1] / cam[:, 2]
        status = np.where(behind, np.uint8(Status.OUT_OF_DOMAIN), np.uint8(Status.CONVERGED))
        return row, col, status

    def ground_seed(self) -> tuple[float, float]:
        """Where the principal ray meets the middle of the height range (the Newton start)."""
        look = self._rotation.T @ np.array([0.0, 0.0, -1.0])  # camera -z axis in ENU
        start = self._parameters.values[:3]
        h_mid = 0.5 * (self._height_range[0] + self._height_range[1])
        s = (h_mid - self._centre[2] - start[2]) / look[2]
        ground = self._frame.to_geodetic(*(start + s * look))
        return float(ground.lon), float(ground.lat)
    # --8<-- [end:geometry]

    # --8<-- [start:helper]
    # ---------------------------------------------------------------- a public helper
    def view_angle(self, lon: ArrayLike, lat: ArrayLike, h: ArrayLike) -> Float64Array:
        """Angle between the camera axis and the ray to each ground point, degrees.

        Parameters
        ----------
        lon, lat, h : array_like, (*S,)
            Degrees, degrees and metres above the WGS84 ellipsoid; broadcast together.

        Returns
        -------
        ndarray, (*S,)
            Degrees; NaN for NaN input and for points behind the camera (one
            ``OutOfBoundsWarning`` with their count).
        """
        lon, lat, h = broadcast_float64(lon=lon, lat=lat, h=h)  # names them in a shape error
        enu = np.stack(self._frame.from_geodetic(lon, lat, h), axis=-1)  # (*S, 3)
        cam = (enu - self._parameters.values[:3]) @ self._rotation.T
        with np.errstate(invalid="ignore", divide="ignore"):
            angle = np.degrees(np.arccos(-cam[..., 2] / np.linalg.norm(cam, axis=-1)))
        status = np.where(cam[..., 2] < 0.0, np.uint8(Status.CONVERGED),
                          np.uint8(Status.OUT_OF_DOMAIN))
        status[~np.all(np.isfinite(enu), axis=-1)] = Status.INVALID_INPUT  # NaN in: silent
        warn_status(status, f"{self.name}.view_angle")  # one warning per failure kind
        return np.where(status == Status.CONVERGED, angle, np.nan)
    # --8<-- [end:helper]
