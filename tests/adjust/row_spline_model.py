"""A test model whose parameters act locally: an affine image correction plus cubic
B-splines along the image rows (issue 27's sparse normal equations). Shared by
tests/adjust/test_sparse_columns.py and benchmarks/bench_jitter.py, which load it by path; it
uses geoblock's public API only, so it runs on any revision of the engine.
"""

from __future__ import annotations

from typing import Any, ClassVar, Self

import numpy as np

from geoblock.models.corrections import ImageSpaceCorrection
from geoblock.models.parameters import ParameterSet

__all__ = ["RowSplineCorrection"]


def _bspline(t: np.ndarray, n_seg: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Uniform cubic B-spline at ``t`` (knot units): first coefficient (N,), the four basis
    values (N, 4) and their derivatives d/dt (N, 4); outside ``[0, n_seg)`` the end segment's
    polynomial is extended."""
    seg = np.clip(np.floor(t), 0, n_seg - 1).astype(np.intp)
    u = t - seg
    basis = np.stack([(1 - u) ** 3, 3 * u**3 - 6 * u**2 + 4, -3 * u**3 + 3 * u**2 + 3 * u + 1,
                      u**3], -1) / 6.0
    deriv = np.stack([-3 * (1 - u) ** 2, 9 * u**2 - 12 * u, -9 * u**2 + 6 * u + 3,
                      3 * u**2], -1) / 6.0
    return seg, basis, deriv


class RowSplineCorrection(ImageSpaceCorrection):
    """Test model: an affine image correction plus three cubic B-splines along the rows
    (knots every ``spacing`` lines): a row shift, a column shift and a column scale about the
    centre column, as jitter in pitch, roll and yaw would move a pushbroom's pixels.

    Parameters ``a0 a1 a2 b0 b1 b2`` (free, pixels), then ``r<k>``, ``c<k>``, ``s<k>`` (pixels,
    a-priori ``sigma`` each). A measurement's partials are nonzero in the six affine terms and
    four knots per spline: 18 columns whatever the number of knots.
    """

    name: ClassVar[str] = "test-row-spline"
    schema_version: ClassVar[int] = 1

    def __init__(self, model: Any, spacing: float, values: np.ndarray | None = None,
                 sigma: float = 1.0) -> None:
        self._model = model
        self._spacing = float(spacing)
        rows, cols = model.shape
        self._n_seg = max(1, int(np.ceil((rows - 1) / spacing)))
        n = self._n_seg + 3
        self._n = n
        self._origin = ((rows - 1) / 2.0, (cols - 1) / 2.0)
        self._scale = max(rows, cols) / 2.0
        names = (tuple(f"a{k}" for k in range(3)) + tuple(f"b{k}" for k in range(3))
                 + tuple(f"{axis}{k}" for axis in "rcs" for k in range(n)))
        sig = np.concatenate([np.full(6, np.inf), np.full(3 * n, sigma)])
        values = np.zeros(len(names)) if values is None else values
        self._sigma = sigma
        self._parameters = ParameterSet(names, values, ("px",) * len(names), sig)

    def with_parameters(self, values: Any) -> Self:
        return type(self)(self._model, self._spacing, np.asarray(values, float), self._sigma)

    def to_dict(self) -> dict[str, Any]:  # pragma: no cover - not serialised in the tests
        raise NotImplementedError

    @classmethod
    def from_dict(cls, data: Any) -> Self:  # pragma: no cover
        raise NotImplementedError

    def _terms(self, r: np.ndarray, c: np.ndarray) -> tuple[np.ndarray, ...]:
        u = (r - self._origin[0]) / self._scale
        v = (c - self._origin[1]) / self._scale
        seg, basis, deriv = _bspline(r / self._spacing, self._n_seg)
        return u, v, seg, basis, deriv / self._spacing

    def _correction(self, r: np.ndarray, c: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        p = self._parameters.values
        a, b = p[:3], p[3:6]
        knots = p[6:].reshape(3, self._n)
        u, v, seg, basis, deriv = self._terms(r, c)
        idx = seg[:, None] + np.arange(4)
        spl = np.einsum("nk,ank->na", basis, knots[:, idx])  # (N, 3)
        dspl = np.einsum("nk,ank->na", deriv, knots[:, idx])
        s = self._scale
        delta = np.stack([a[0] + a[1] * u + a[2] * v + spl[:, 0],
                          b[0] + b[1] * u + b[2] * v + spl[:, 1] + v * spl[:, 2]], -1)
        jac = np.empty(r.shape + (2, 2))
        jac[:, 0, 0] = 1.0 + a[1] / s + dspl[:, 0]
        jac[:, 0, 1] = a[2] / s
        jac[:, 1, 0] = b[1] / s + dspl[:, 1] + v * dspl[:, 2]
        jac[:, 1, 1] = 1.0 + b[2] / s + spl[:, 2] / s
        return delta, jac

    def partials_parameters(self, lon: Any, lat: Any, h: Any) -> np.ndarray:
        (r, c), _ = self._model.project_with_status(lon, lat, h)
        r, c = np.ravel(r), np.ravel(c)
        u, v, seg, basis, _ = self._terms(r, c)
        n = self._n
        out = np.zeros((r.size, 2, 6 + 3 * n))
        terms = np.stack([np.ones_like(u), u, v], -1)
        out[:, 0, :3] = terms
        out[:, 1, 3:6] = terms
        rows = np.arange(r.size)[:, None]
        col = seg[:, None] + np.arange(4)
        out[rows, 0, 6 + col] = basis
        out[rows, 1, 6 + n + col] = basis
        out[rows, 1, 6 + 2 * n + col] = basis * v[:, None]
        return out
