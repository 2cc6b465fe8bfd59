"""Image-space polynomial corrections around any sensor model (RPCV-0, RPCV-1, order 2).

Grodecki & Dial's refinement of vendor RPCs, generalised to every model: the wrapped model's
image coordinates ``(r, c)`` are corrected by low-order polynomials in normalised image
coordinates ``u = (r - r0) / s``, ``v = (c - c0) / s`` (``r0, c0`` the image centre, ``s`` half
the larger image dimension, so ``u, v`` lie in about ``[-1, 1]``)::

    row = r + a0 + a1 u + a2 v + a3 u^2 + a4 u v + a5 v^2
    col = c + b0 + b1 u + b2 v + b3 u^2 + b4 u v + b5 v^2

Order 0 keeps ``a0, b0`` (a shift: RPCV-0, at least 1 GCP); order 1 ``a0..a2, b0..b2`` (an
affinity: RPCV-1, at least 3 GCPs); order 2 all twelve (at least 6 GCPs). Every coefficient is
in pixels. The correction is applied explicitly to the wrapped model's projection (Aguilar et
al.'s eqs. 1-2 evaluated at the model's coordinates); backprojection inverts it by Newton
iteration. The wrapped model's own parameters stay fixed.
"""

from __future__ import annotations

import abc
from collections.abc import Callable, Mapping
from typing import Any, ClassVar, Self

import numpy as np

from geoblock.models.base import KernelResult, SensorModelBase
from geoblock.models.parameters import ParameterSet
from geoblock.models.protocol import SensorModel
from geoblock.typing import ArrayLike, Float64Array, Status

__all__ = ["ImageCorrection", "ImageSpaceCorrection", "invert_correction"]

_N_TERMS = {0: 1, 1: 3, 2: 6}


class ImageSpaceCorrection(SensorModelBase):
    """Base class of the image-space correction layers around any sensor model.

    ``project`` is the wrapped model's projection ``(r, c)`` plus a correction
    ``delta(r, c)``; ``backproject`` inverts the correction by Newton iteration
    (:func:`invert_correction`), then backprojects with the wrapped model and keeps the worse
    of the two statuses; ``partials_ground`` is the correction's Jacobian times the wrapped
    model's ground partials. :class:`ImageCorrection` (polynomials) and
    :class:`geoblock.adjust.collocation.CollocationCorrection` (least-squares collocation)
    are the two built in.

    A subclass sets ``self._model`` (the wrapped model) and ``self._parameters`` in its
    constructor, implements :meth:`_correction` and the members every model implements
    (``with_parameters``, ``to_dict``, ``from_dict``, ``partials_parameters``); it may
    override :meth:`_start` (the Newton start) and :meth:`_offset` (the correction without its
    Jacobian, where that is cheaper).
    """

    #: tolerance (pixels) and iteration cap of the correction's inversion
    inversion_tolerance_px: ClassVar[float] = 1e-10
    inversion_max_iterations: ClassVar[int] = 20

    _model: SensorModel
    _parameters: ParameterSet

    # ------------------------------------------------------------------ state
    @property
    def model(self) -> SensorModel:
        """The wrapped model."""
        return self._model

    @property
    def shape(self) -> tuple[int, int]:
        return self._model.shape

    @property
    def height_range(self) -> tuple[float, float]:
        return self._model.height_range

    @property
    def parameters(self) -> ParameterSet:
        return self._parameters

    # ------------------------------------------------------------------ correction
    @abc.abstractmethod
    def _correction(self, r: Float64Array, c: Float64Array) -> tuple[Float64Array, Float64Array]:
        """The correction at the wrapped model's image coordinates.

        Parameters
        ----------
        r, c : ndarray, (N,)
            The wrapped model's image coordinates, pixels.

        Returns
        -------
        delta : ndarray, (N, 2)
            ``(d_row, d_col)``, pixels, to add to ``(r, c)``.
        jacobian : ndarray, (N, 2, 2)
            Of the corrected coordinates ``(r, c) + delta`` with respect to ``(r, c)``.
        """

    def _offset(self, r: Float64Array, c: Float64Array) -> Float64Array:
        """``delta`` (N, 2) of :meth:`_correction` alone; override when it is cheaper."""
        return self._correction(r, c)[0]

    def _start(self, row: Float64Array, col: Float64Array) -> tuple[Float64Array, Float64Array]:
        """Newton start ``(r0, c0)`` (N,) for corrected ``(row, col)``; fresh arrays (the
        inversion updates them in place). Default: the corrected coordinates themselves."""
        return row.copy(), col.copy()

    # ------------------------------------------------------------------ kernels
    def ground_to_image(self, lon: Float64Array, lat: Float64Array, h: Float64Array
                        ) -> KernelResult:
        (r, c), status = self._model.project_with_status(lon, lat, h)
        delta = self._offset(r, c)
        return r + delta[..., 0], c + delta[..., 1], status

    def _uncorrect(self, row: np.ndarray, col: np.ndarray) -> tuple[np.ndarray, ...]:
        """Model coordinates (r, c) whose corrected values are (row, col): Newton, per point."""
        r0, c0 = self._start(row, col)
        return invert_correction(self._correction, row, col, r0, c0,
                                 self.inversion_tolerance_px, self.inversion_max_iterations)

    def image_to_ground(self, row: Float64Array, col: Float64Array, h: Float64Array
                        ) -> KernelResult:
        r, c, status = self._uncorrect(row, col)
        (lon, lat, _), inner = self._model.backproject_with_status(r, c, h)
        return lon, lat, np.maximum(status, inner)

    # ------------------------------------------------------------------ partials
    def partials_ground(self, lon: ArrayLike, lat: ArrayLike, h: ArrayLike) -> Float64Array:
        """Chain rule: d(corrected)/d(model image coords) @ the wrapped model's ground partials.

        Returns
        -------
        ndarray, (*S, 2, 3)
            Pixels per metre (ECEF).
        """
        (r, c), _ = self._model.project_with_status(lon, lat, h)
        _, jac = self._correction(r.ravel(), c.ravel())
        return jac.reshape(r.shape + (2, 2)) @ self._model.partials_ground(lon, lat, h)


class ImageCorrection(ImageSpaceCorrection):
    """A sensor model with an image-space polynomial correction of order 0, 1 or 2.

    Parameters
    ----------
    model : SensorModel
        Any registered model (RPC, pushbroom, a third party's ...).
    order : {0, 1, 2}
        0: shift (RPCV-0), 1: affine (RPCV-1), 2: quadratic.
    values : array_like, (P,), optional
        Coefficients ``a0.., b0..`` in pixels; default zeros (no correction).
    sigmas : array_like, (P,) or float, optional
        A-priori standard deviations in pixels; default ``inf`` (free).

    Examples
    --------
    >>> from geoblock.testing.synthetic import AffineCamera
    >>> refined = ImageCorrection(AffineCamera.example(), order=1)
    >>> refined.parameters.names
    ('a0', 'a1', 'a2', 'b0', 'b1', 'b2')
    """

    name: ClassVar[str] = "image-correction"
    schema_version: ClassVar[int] = 1

    def __init__(
        self,
        model: SensorModel,
        order: int = 1,
        values: ArrayLike | None = None,
        sigmas: ArrayLike | float | None = None,
        adjustable: ArrayLike | None = None,
    ) -> None:
        if order not in _N_TERMS:
            raise ValueError(f"ImageCorrection: order must be 0, 1 or 2, got {order!r}")
        self._model = model
        self._order = int(order)
        rows, cols = model.shape
        self._origin = ((rows - 1) / 2.0, (cols - 1) / 2.0)
        self._scale = max(rows, cols) / 2.0
        n = _N_TERMS[order]
        names = tuple(f"a{k}" for k in range(n)) + tuple(f"b{k}" for k in range(n))
        values = np.zeros(2 * n) if values is None else values
        sig = None if sigmas is None else np.broadcast_to(np.asarray(sigmas, float), (2 * n,))
        self._parameters = ParameterSet(names, values, ("px",) * (2 * n), sig, adjustable)

    # ------------------------------------------------------------------ state
    @property
    def source_ids(self) -> Mapping[str, str]:
        """The wrapped model's image ids (a correction describes the same image)."""
        return dict(getattr(self._model, "source_ids", None) or {})

    @property
    def order(self) -> int:
        """Polynomial order (0, 1 or 2)."""
        return self._order

    def with_parameters(self, values: ArrayLike) -> Self:
        new = self._parameters.with_values(values)
        return type(self)(self._model, self._order, new.values, new.sigmas, new.adjustable)

    def to_dict(self) -> dict[str, Any]:
        return {
            "model": self.name,
            "schema_version": self.schema_version,
            "order": self._order,
            "base": self._model.to_dict(),
            "parameters": self._parameters.to_dict(),
        }

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> Self:
        from geoblock.plugins import from_dict

        params = ParameterSet.from_dict(data["parameters"])
        return cls(from_dict(data["base"]), int(data["order"]), params.values,
                   params.sigmas, params.adjustable)

    # ------------------------------------------------------------------ polynomial
    def _basis(self, r: Float64Array, c: Float64Array,
               ) -> tuple[Float64Array, Float64Array, Float64Array]:
        """Terms (N, n) and their derivatives d/dr, d/dc (N, n) at image coordinates."""
        s = self._scale
        u = (r - self._origin[0]) / s
        v = (c - self._origin[1]) / s
        one, zero = np.ones_like(u), np.zeros_like(u)
        terms = [one, u, v, u * u, u * v, v * v][: _N_TERMS[self._order]]
        d_u = [zero, one, zero, 2 * u, v, zero][: _N_TERMS[self._order]]
        d_v = [zero, zero, one, zero, u, 2 * v][: _N_TERMS[self._order]]
        return (np.stack(terms, -1), np.stack(d_u, -1) / s, np.stack(d_v, -1) / s)

    def _correction(self, r: Float64Array, c: Float64Array) -> tuple[Float64Array, Float64Array]:
        """(N, 2) corrections and the (N, 2, 2) Jacobian of the corrected coords wrt (r, c)."""
        n = _N_TERMS[self._order]
        a, b = self._parameters.values[:n], self._parameters.values[n:]
        terms, d_r, d_c = self._basis(r, c)
        jac = np.empty(r.shape + (2, 2))
        jac[..., 0, 0] = 1.0 + d_r @ a
        jac[..., 0, 1] = d_c @ a
        jac[..., 1, 0] = d_r @ b
        jac[..., 1, 1] = 1.0 + d_c @ b
        return np.stack([terms @ a, terms @ b], axis=-1), jac

    # ------------------------------------------------------------------ partials
    def partials_parameters(self, lon: ArrayLike, lat: ArrayLike, h: ArrayLike) -> Float64Array:
        """Analytic d(row, col)/d(a_k, b_k): the polynomial terms at the model's projection.

        Returns
        -------
        ndarray, (*S, 2, P)
            Pixels per pixel (dimensionless).
        """
        (r, c), _ = self._model.project_with_status(lon, lat, h)
        terms, _, _ = self._basis(r, c)
        n = terms.shape[-1]
        out = np.zeros(r.shape + (2, 2 * n))
        out[..., 0, :n] = terms
        out[..., 1, n:] = terms
        return out

    def __repr__(self) -> str:
        return f"<ImageCorrection order {self._order} of {self._model!r}>"


def invert_correction(
    correction: Callable[[Float64Array, Float64Array], tuple[Float64Array, Float64Array]],
    row: np.ndarray, col: np.ndarray, r: np.ndarray, c: np.ndarray,
    tolerance_px: float, max_iterations: int,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Invert an image-space correction ``(row, col) = (r, c) + correction(r, c)`` by Newton.

    What :class:`ImageSpaceCorrection` backprojects with, so every correction layer around a
    model (:class:`ImageCorrection`, :class:`geoblock.adjust.collocation.CollocationCorrection`)
    shares it.

    Parameters
    ----------
    correction : callable
        ``(r, c) (N,) -> (delta (N, 2), jacobian (N, 2, 2))``: the correction in pixels and
        the Jacobian of the corrected coordinates with respect to ``(r, c)``.
    row, col : ndarray, (N,)
        Corrected coordinates, pixels.
    r, c : ndarray, (N,)
        Starting model coordinates (updated in place).
    tolerance_px : float
        A point converges when its Newton step is at most this many pixels.
    max_iterations : int

    Returns
    -------
    r, c : ndarray, (N,)
    status : ndarray of uint8, (N,)
        CONVERGED, DIVERGED (a singular Jacobian) or MAX_ITERATIONS per point.
    """
    status = np.full(row.shape, np.uint8(Status.MAX_ITERATIONS), dtype=np.uint8)
    todo = np.arange(row.size)
    for _ in range(max_iterations):
        delta, jac = correction(r[todo], c[todo])
        f_r = r[todo] + delta[:, 0] - row[todo]
        f_c = c[todo] + delta[:, 1] - col[todo]
        det = jac[:, 0, 0] * jac[:, 1, 1] - jac[:, 0, 1] * jac[:, 1, 0]
        with np.errstate(divide="ignore", invalid="ignore"):
            step_r = (jac[:, 1, 1] * f_r - jac[:, 0, 1] * f_c) / det
            step_c = (-jac[:, 1, 0] * f_r + jac[:, 0, 0] * f_c) / det
        r[todo] -= step_r
        c[todo] -= step_c
        bad = ~(np.isfinite(step_r) & np.isfinite(step_c))
        done = np.maximum(np.abs(step_r), np.abs(step_c)) <= tolerance_px
        status[todo[bad]] = Status.DIVERGED
        status[todo[done & ~bad]] = Status.CONVERGED
        todo = todo[~done & ~bad]
        if todo.size == 0:
            break
    return r, c, status
