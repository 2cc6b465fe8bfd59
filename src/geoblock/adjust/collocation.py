"""Least-squares collocation of residual vectors, and a correction layer around any model.

Teo et al. (2010, eqs. 4-5) remove the local systematic errors left after a block adjustment
by least-squares collocation of the residual (discrepancy) vectors, each axis independently.
With the residuals ``l_k`` (n,) of axis ``k`` (row or col, in pixels) at n control points,
their mean ``m_k`` (the trend) removed, the correction at a point ``P`` is::

    s_k(P) = m_k + sigma_k(P)^T Sigma_k^-1 (l_k - m_k)                      (eq. 4)

    Sigma_k[i, j] = C_k(d_ij),  sigma_k(P)[i] = C_k(d(P, i))

    C_k(d) = (1 - r_n) mu_k exp(-(2.146 d / d_max)^2)   if d != 0           (eq. 5)
           = mu_k                                         if d == 0

``mu_k`` is the variance of the (centred) residuals, ``r_n`` the filtering ratio (the noise
share of ``mu_k``, 0.2 in the paper) and ``d_max`` the correlation distance (2.146 makes
``C(d_max)`` 1 % of ``(1 - r_n) mu_k``). Because ``C(0) = mu_k`` exceeds the limit ``(1 - r_n)
mu_k`` of ``C(d)`` as ``d -> 0``, the diagonal of ``Sigma`` carries a noise ``r_n mu_k``: the
prediction filters (smooths) the residuals instead of interpolating them, and ``Sigma`` is
positive definite for distinct points (its eigenvalues are at least ``r_n mu_k``).

:func:`fit_collocation` fits the collocation to residuals in image space;
:class:`CollocationCorrection` applies it as an image-space correction layer around any sensor
model, like :class:`~geoblock.models.ImageCorrection` does with polynomials.
"""

from __future__ import annotations

import json
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, ClassVar, Self

import numpy as np

from geoblock._array import broadcast_float64
from geoblock.errors import ObservationError, SerializationError, TooFewPointsError
from geoblock.models.corrections import ImageSpaceCorrection
from geoblock.models.curves import CorrectionCurve
from geoblock.models.parameters import ParameterSet
from geoblock.models.protocol import SensorModel
from geoblock.typing import ArrayLike, BoolArray, Float64Array

__all__ = [
    "GAUSS_FACTOR",
    "Collocation",
    "CollocationCorrection",
    "default_d_max",
    "fit_collocation",
    "gaussian_covariance",
]

#: Teo et al.'s constant: ``exp(-GAUSS_FACTOR**2) = 0.01`` (C(d_max) is 1 % of (1 - r_n) mu).
GAUSS_FACTOR = 2.146

#: Largest number of (point, control point) pairs :meth:`Collocation.predict` evaluates at once.
_MAX_PAIRS = 4_000_000


def _frozen(a: ArrayLike) -> Float64Array:
    out = np.array(a, dtype=np.float64)
    out.flags.writeable = False
    return out


def gaussian_covariance(
    d: ArrayLike, mu: float, d_max: float, filtering_ratio: float = 0.2
) -> Float64Array:
    """Teo et al.'s covariance function (eq. 5), literally.

    Parameters
    ----------
    d : array_like, (*S,)
        Distances, pixels (any unit of ``d_max``).
    mu : float
        Variance of the residuals, pixels squared.
    d_max : float
        Correlation distance, same unit as ``d``.
    filtering_ratio : float
        ``r_n`` in (0, 1): the noise share of ``mu``.

    Returns
    -------
    ndarray, (*S,)
        ``mu`` where ``d == 0``, else ``(1 - r_n) mu exp(-(2.146 d / d_max)^2)``; pixels squared.
    """
    d = np.asarray(d, dtype=np.float64)
    signal = (1.0 - filtering_ratio) * mu * np.exp(-((GAUSS_FACTOR * d / d_max) ** 2))
    return np.where(d == 0.0, float(mu), signal)


def default_d_max(row: ArrayLike, col: ArrayLike) -> float:
    """The default correlation distance: the largest distance between two control points.

    This is Teo et al.'s "maximum distance" read literally (their eq. 5). It is the most
    conservative choice: the covariance falls to 1 % at the far side of the point set, so
    the prediction follows patterns of about the points' extent and smooths anything shorter
    (including pure noise, which it barely propagates to new points). Pass a smaller
    ``d_max`` to :func:`fit_collocation` (3 to 10 times the median nearest-neighbour spacing,
    say) to resolve finer residual patterns when the control points are dense and their
    residuals mostly signal.

    Parameters
    ----------
    row, col : array_like, (n,)
        Control points' image coordinates, pixels.

    Returns
    -------
    float
        Pixels.
    """
    p = np.stack([np.ravel(row), np.ravel(col)], axis=-1).astype(np.float64)
    return float(np.max(_distances(p, p)))


def _finite_points(row: ArrayLike, col: ArrayLike) -> tuple[Float64Array, Float64Array, BoolArray]:
    """``row``, ``col`` broadcast together as float64 (*S,), and the (*S,) finite mask."""
    r, c = broadcast_float64(row=row, col=col, _copy=False)
    return r, c, np.isfinite(r) & np.isfinite(c)


def _distances(a: Float64Array, b: Float64Array) -> Float64Array:
    """(N, n) Euclidean distances between (N, 2) and (n, 2) points."""
    return np.hypot(a[:, None, 0] - b[None, :, 0], a[:, None, 1] - b[None, :, 1])


@dataclass(frozen=True, eq=False)
class Collocation:
    """A fitted least-squares collocation of image-space residual vectors (per axis).

    Build it with :func:`fit_collocation`, which checks the data and names what is wrong. The
    constructor takes the data and the settings only and fits the derived fields (``mean``,
    ``mu``, ``weights``) itself.

    Attributes
    ----------
    row, col : ndarray, (n,)
        Control points' image coordinates, pixels (pixel-centre convention).
    d_row, d_col : ndarray, (n,)
        Residual vectors, pixels: observed minus computed, the correction to *add* to a
        model's projection.
    mean : ndarray, (2,)
        Per-axis mean (trend) of ``d_row``, ``d_col``, pixels.
    mu : ndarray, (2,)
        Per-axis variance of the centred residuals, pixels squared.
    filtering_ratio : float
        ``r_n``, the noise share of ``mu``.
    d_max : float
        Correlation distance, pixels.
    weights : ndarray, (2, n)
        ``Sigma_k^-1 (l_k - m_k)`` per axis, 1/pixels.

    Notes
    -----
    :meth:`predict` evaluates ``sigma_k(P)`` with the *signal* covariance ``(1 - r_n) mu_k
    exp(-(2.146 d / d_max)^2)`` at every distance, its limit at ``d = 0`` included: the
    prediction is a smooth function of ``P``, and at a control point it is the filtered value
    (Moritz's signal estimate), not the observed residual that eq. 5's ``C(0) = mu_k`` would
    reproduce there. Everywhere else (``d > 0``) this is eq. 4 exactly.
    """

    row: Float64Array
    col: Float64Array
    d_row: Float64Array
    d_col: Float64Array
    mean: Float64Array = field(init=False)
    mu: Float64Array = field(init=False)
    filtering_ratio: float
    d_max: float
    weights: Float64Array = field(init=False)

    def __post_init__(self) -> None:
        for name in ("row", "col", "d_row", "d_col"):
            object.__setattr__(self, name, _frozen(getattr(self, name)))
        object.__setattr__(self, "filtering_ratio", float(self.filtering_ratio))
        object.__setattr__(self, "d_max", float(self.d_max))
        mean, mu, weights = self._fit()
        for name, value in (("mean", mean), ("mu", mu), ("weights", weights)):
            object.__setattr__(self, name, _frozen(value))

    def _fit(self) -> tuple[Float64Array, Float64Array, Float64Array]:
        """``mean`` (2,), ``mu`` (2,) and ``weights`` (2, n) of the data (see fit_collocation)."""
        import scipy.linalg  # here: registering the model (every command) must not load SciPy

        shapes = [getattr(self, k).shape for k in ("row", "col", "d_row", "d_col")]
        if len(set(shapes)) != 1 or len(shapes[0]) != 1:
            raise ObservationError(
                "Collocation: row, col, d_row and d_col must be 1-D arrays of one shape (n,); "
                f"got {shapes}"
            )
        l_obs = np.stack([self.d_row, self.d_col])  # (2, n)
        mean = l_obs.mean(axis=1)
        centred = l_obs - mean[:, None]
        mu = np.mean(centred * centred, axis=1)
        # Sigma_k = mu_k R: R is eq. 5 with mu = 1 (1 on the diagonal, the signal correlation
        # elsewhere; the points are distinct, so d == 0 on the diagonal only)
        p = np.stack([self.row, self.col], axis=-1)
        corr = gaussian_covariance(_distances(p, p), 1.0, self.d_max, self.filtering_ratio)
        try:
            factor = scipy.linalg.cho_factor(corr, lower=True, check_finite=True)
        except (np.linalg.LinAlgError, ValueError) as exc:
            raise ObservationError(
                "Collocation: the covariance matrix is not positive definite (coincident or "
                f"non-finite points, or a bad filtering_ratio or d_max?): {exc}"
            ) from exc
        solved = scipy.linalg.cho_solve(factor, centred.T, check_finite=False).T  # R^-1 (l - m)
        with np.errstate(divide="ignore", invalid="ignore"):
            weights = np.where(mu[:, None] > 0.0, solved / mu[:, None], 0.0)
        return mean, mu, weights

    @property
    def n_points(self) -> int:
        """Number of control points n."""
        return int(self.row.shape[0])

    # ------------------------------------------------------------------ covariance
    def covariance(self, d: ArrayLike) -> Float64Array:
        """Eq. 5 for both axes.

        Parameters
        ----------
        d : array_like, (*S,)
            Distances, pixels.

        Returns
        -------
        ndarray, (*S, 2)
            ``C_row(d)``, ``C_col(d)``, pixels squared (``mu`` where ``d == 0``).
        """
        return np.stack(
            [gaussian_covariance(d, m, self.d_max, self.filtering_ratio) for m in self.mu],
            axis=-1,
        )

    # ------------------------------------------------------------------ prediction
    def _coefficients(self) -> Float64Array:
        """(n, 2): ``(1 - r_n) mu_k w_k``, so that ``s - m = exp(...) @ coefficients``."""
        return ((1.0 - self.filtering_ratio) * self.mu[:, None] * self.weights).T

    def _evaluate(
        self, r: Float64Array, c: Float64Array, gradient: bool
    ) -> tuple[Float64Array, Float64Array | None]:
        """Corrections (N, 2) and, if asked, their (N, 2, 2) Jacobian wrt (row, col)."""
        n = self.n_points
        coef = self._coefficients()
        a2 = (GAUSS_FACTOR / self.d_max) ** 2
        out = np.empty(r.shape + (2,))
        jac = np.empty(r.shape + (2, 2)) if gradient else None
        step = max(1, _MAX_PAIRS // n)
        for start in range(0, r.shape[0], step):
            sl = slice(start, start + step)
            dr = r[sl, None] - self.row[None, :]  # (m, n)
            dc = c[sl, None] - self.col[None, :]
            with np.errstate(over="ignore"):  # far away: exp(-inf) = 0
                g = np.exp(-a2 * (dr * dr + dc * dc))  # (m, n)
            # sums along each row (not BLAS products, whose rounding depends on how many
            # rows are multiplied at once): a point's value does not depend on the chunking
            for k in range(2):
                out[sl, k] = np.sum(g * coef[:, k], axis=1) + self.mean[k]
            if jac is not None:
                # d exp(-a2 |x - x_i|^2)/dx = -2 a2 (x - x_i) exp(...)
                g_r, g_c = (-2.0 * a2) * g * dr, (-2.0 * a2) * g * dc
                for k in range(2):
                    jac[sl, k, 0] = np.sum(g_r * coef[:, k], axis=1)
                    jac[sl, k, 1] = np.sum(g_c * coef[:, k], axis=1)
        return out, jac

    def predict(self, row: ArrayLike, col: ArrayLike) -> tuple[Float64Array, Float64Array]:
        """The corrections ``(d_row, d_col)`` at image points (eq. 4 plus the mean).

        Parameters
        ----------
        row, col : array_like, (*S,)
            Pixels, pixel-centre convention; broadcast together.

        Returns
        -------
        d_row, d_col : ndarray, (*S,)
            Pixels, to add to a model's projection. NaN where an input is not finite.
        """
        r, c, ok = _finite_points(row, col)
        out = np.full(r.shape + (2,), np.nan)
        out[ok], _ = self._evaluate(r[ok], c[ok], gradient=False)
        return out[..., 0], out[..., 1]

    def gradient(self, row: ArrayLike, col: ArrayLike) -> Float64Array:
        """Analytic Jacobian of :meth:`predict` wrt the image coordinates.

        Parameters
        ----------
        row, col : array_like, (*S,)
            Pixels.

        Returns
        -------
        ndarray, (*S, 2, 2)
            ``[..., k, 0]`` = d(correction k)/d row, ``[..., k, 1]`` = d(correction k)/d col;
            pixels per pixel. NaN where an input is not finite.
        """
        r, c, ok = _finite_points(row, col)
        jac = np.full(r.shape + (2, 2), np.nan)
        _, jac[ok] = self._evaluate(r[ok], c[ok], gradient=True)
        return jac

    # ------------------------------------------------------------------ value semantics
    def to_dict(self) -> dict[str, Any]:
        """JSON-safe: the data and the settings (the derived fields are refitted on load)."""
        return {
            "row": [float(v) for v in self.row],
            "col": [float(v) for v in self.col],
            "d_row": [float(v) for v in self.d_row],
            "d_col": [float(v) for v in self.d_col],
            "filtering_ratio": self.filtering_ratio,
            "d_max": self.d_max,
        }

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> Collocation:
        """Inverse of :meth:`to_dict` (refits with the stored ``filtering_ratio`` and ``d_max``).

        Raises
        ------
        SerializationError
            A field is missing or not numeric.
        """
        try:
            fields = {k: np.asarray(data[k], dtype=np.float64)
                      for k in ("row", "col", "d_row", "d_col")}
            r_n, d_max = float(data["filtering_ratio"]), float(data["d_max"])
        except (KeyError, TypeError, ValueError) as exc:
            raise SerializationError(f"invalid collocation dictionary: {exc!r}") from exc
        return fit_collocation(fields["row"], fields["col"], fields["d_row"], fields["d_col"],
                               filtering_ratio=r_n, d_max=d_max)

    def _key(self) -> str:
        return json.dumps(self.to_dict(), sort_keys=True, separators=(",", ":"))

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, Collocation):
            return NotImplemented
        return self._key() == other._key()

    def __hash__(self) -> int:
        return hash(self._key())

    def __repr__(self) -> str:
        return (f"<Collocation of {self.n_points} points, r_n {self.filtering_ratio:g}, "
                f"d_max {self.d_max:g} px, mean ({self.mean[0]:.3g}, {self.mean[1]:.3g}) px, "
                f"sqrt(mu) ({np.sqrt(self.mu[0]):.3g}, {np.sqrt(self.mu[1]):.3g}) px>")


def fit_collocation(
    row: ArrayLike,
    col: ArrayLike,
    d_row: ArrayLike,
    d_col: ArrayLike,
    *,
    filtering_ratio: float = 0.2,
    d_max: float | None = None,
) -> Collocation:
    """Fit Teo et al.'s least-squares collocation to image-space residual vectors.

    Per axis, removes the mean, takes ``mu`` as the variance of the centred residuals, builds
    ``Sigma`` from eq. 5 and solves ``Sigma w = l - m`` by a Cholesky factorisation (one for
    both axes: ``Sigma_k = mu_k R`` with the same correlation matrix ``R``).

    Parameters
    ----------
    row, col : array_like, (n,)
        Control points' image coordinates, pixels (pixel-centre convention); n >= 2 distinct
        points.
    d_row, d_col : array_like, (n,)
        Residual vectors at the points, pixels: observed minus computed (the correction to add
        to the model's projection).
    filtering_ratio : float
        ``r_n`` in (0, 1), the noise share of the residuals' variance (Teo et al.: 0.2).
    d_max : float, optional
        Correlation distance, pixels (> 0): ``C(d_max)`` is 1 % of ``(1 - r_n) mu``. Default
        :func:`default_d_max`: the largest distance between two control points.

    Returns
    -------
    Collocation

    Raises
    ------
    ObservationError
        Non-finite or mismatched inputs, coincident control points (the message names the field
        or the points), ``filtering_ratio`` not in (0, 1), ``d_max`` not finite and > 0.
    TooFewPointsError
        Fewer than 2 points.

    Examples
    --------
    >>> import numpy as np
    >>> r, c = np.array([0.0, 0.0, 900.0, 900.0]), np.array([0.0, 900.0, 0.0, 900.0])
    >>> colloc = fit_collocation(r, c, d_row=[1.0, 1.2, 0.8, 1.0], d_col=[0.0, 0.0, 0.0, 0.0])
    >>> d_row, d_col = colloc.predict(450.0, 450.0)
    >>> round(float(d_row), 6), float(d_col)
    (1.0, 0.0)
    """
    arrays = {}
    for name, value in (("row", row), ("col", col), ("d_row", d_row), ("d_col", d_col)):
        try:
            arrays[name] = np.asarray(value, dtype=np.float64)
        except (TypeError, ValueError) as exc:
            raise ObservationError(f"fit_collocation: {name} is not numeric: {exc}") from exc
    shapes = {name: a.shape for name, a in arrays.items()}
    if len(set(shapes.values())) != 1 or arrays["row"].ndim != 1:
        raise ObservationError(
            "fit_collocation: row, col, d_row and d_col must be 1-D arrays of one shape (n,); "
            f"got {', '.join(f'{k} {s}' for k, s in shapes.items())}"
        )
    n = arrays["row"].shape[0]
    if n < 2:
        raise TooFewPointsError(f"fit_collocation: needs at least 2 control points, got {n}")
    for name, a in arrays.items():
        bad = np.flatnonzero(~np.isfinite(a))
        if bad.size:
            raise ObservationError(
                f"fit_collocation: {name} is not finite at {bad.size} point(s), indices "
                f"{bad[:10].tolist()}"
            )
    r_n = float(filtering_ratio)
    if not 0.0 < r_n < 1.0:
        raise ObservationError(f"fit_collocation: filtering_ratio must be in (0, 1), got {r_n!r}")
    p = np.stack([arrays["row"], arrays["col"]], axis=-1)
    d = _distances(p, p)
    i, j = np.nonzero(np.triu(d == 0.0, k=1))
    if i.size:
        pairs = [(int(a), int(b)) for a, b in zip(i[:5], j[:5], strict=True)]
        raise ObservationError(
            f"fit_collocation: row/col hold coincident control points (index pairs {pairs}); "
            "merge them (average their residuals) first"
        )
    d_max = default_d_max(arrays["row"], arrays["col"]) if d_max is None else float(d_max)
    if not (np.isfinite(d_max) and d_max > 0.0):
        raise ObservationError(f"fit_collocation: d_max must be finite and > 0 px, got {d_max!r}")
    return Collocation(arrays["row"], arrays["col"], arrays["d_row"], arrays["d_col"],
                       filtering_ratio=r_n, d_max=d_max)


class CollocationCorrection(ImageSpaceCorrection):
    """A sensor model corrected in image space by a least-squares collocation.

    ``project`` is the wrapped model's projection ``(r, c)`` plus the collocation's prediction
    at ``(r, c)``; ``backproject`` inverts the correction by Newton iteration, then
    backprojects with the wrapped model. The collocation is fixed: the model has no
    parameters (adjust the wrapped model first, collocate its residuals, then wrap).

    Parameters
    ----------
    model : SensorModel
        Any registered model.
    collocation : Collocation
        Fitted to residuals (observed minus ``model``'s projection) in ``model``'s image
        coordinates; see :func:`fit_collocation`.

    Examples
    --------
    >>> corrected = CollocationCorrection.example()
    >>> len(corrected.parameters)
    0
    """

    name: ClassVar[str] = "collocation"
    schema_version: ClassVar[int] = 1

    def __init__(self, model: SensorModel, collocation: Collocation) -> None:
        if not isinstance(collocation, Collocation):
            raise TypeError(
                f"CollocationCorrection: collocation must be a Collocation, got "
                f"{type(collocation).__name__}"
            )
        self._model = model
        self._collocation = collocation
        self._parameters = ParameterSet.empty()

    @classmethod
    def example(cls) -> CollocationCorrection:
        """Around a 1000 x 1200 px ``LinescanModel.example``: 40 points with a smooth field
        of about 1-2 px."""
        from geoblock.models.linescan import LinescanModel

        base = LinescanModel.example((1000, 1200))
        rows, cols = base.shape
        rng = np.random.default_rng(20100)
        r = rng.uniform(0.0, rows - 1.0, 40)
        c = rng.uniform(0.0, cols - 1.0, 40)
        d_row = 1.5 * np.sin(2 * np.pi * r / rows) + 0.5 * np.cos(2 * np.pi * c / cols) + 0.3
        d_col = -np.cos(np.pi * r / rows) * np.sin(2 * np.pi * c / cols) - 0.2
        return cls(base, fit_collocation(r, c, d_row, d_col, d_max=0.5 * max(rows, cols)))

    # ------------------------------------------------------------------ state
    @property
    def collocation(self) -> Collocation:
        """The collocation applied to the wrapped model's image coordinates."""
        return self._collocation

    def correction_curves(self, covariance: ArrayLike | None = None,
                          names: Sequence[str] | None = None, *,
                          rows: tuple[float, float] | None = None, samples: int = 200,
                          detrend: bool = True) -> tuple[CorrectionCurve, ...]:
        """The wrapped model's time-dependent corrections
        (:class:`~geoblock.models.curves.HasCorrectionCurves`; ``covariance`` and ``names``
        are of the wrapped model's parameters, as in a block adjustment's result), ``()``
        when it has none. The collocation itself is a function of the image position, not of
        time, and is not part of them."""
        curves = getattr(self._model, "correction_curves", None)
        if not callable(curves):
            return ()
        found: tuple[CorrectionCurve, ...] = curves(covariance, names, rows=rows,
                                                    samples=samples, detrend=detrend)
        return found

    def with_parameters(self, values: ArrayLike) -> Self:
        """A copy; ``values`` must be empty (the model has no parameters)."""
        self._parameters.with_values(values)  # raises ValueError unless the shape is (0,)
        return type(self)(self._model, self._collocation)

    def to_dict(self) -> dict[str, Any]:
        return {
            "model": self.name,
            "schema_version": self.schema_version,
            "base": self._model.to_dict(),
            "collocation": self._collocation.to_dict(),
        }

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> Self:
        from geoblock.plugins import from_dict

        try:
            base, colloc = data["base"], data["collocation"]
        except KeyError as exc:
            raise SerializationError(f"collocation model dictionary lacks {exc}") from exc
        return cls(from_dict(base), Collocation.from_dict(colloc))

    # ------------------------------------------------------------------ correction
    def _correction(self, r: Float64Array, c: Float64Array) -> tuple[Float64Array, Float64Array]:
        """(N, 2) corrections and the (N, 2, 2) Jacobian of the corrected coords wrt (r, c)."""
        out, jac = self._collocation._evaluate(r, c, gradient=True)
        assert jac is not None  # asked for with gradient=True
        jac[:, 0, 0] += 1.0
        jac[:, 1, 1] += 1.0
        return out, jac

    def _offset(self, r: Float64Array, c: Float64Array) -> Float64Array:
        """(N, 2) corrections, without their Jacobian."""
        out, _ = self._collocation._evaluate(r, c, gradient=False)
        return out

    def _start(self, row: Float64Array, col: Float64Array) -> tuple[Float64Array, Float64Array]:
        """Fixed-point start: the corrected coordinates minus the correction there."""
        out = self._offset(row, col)
        return row - out[:, 0], col - out[:, 1]

    # ------------------------------------------------------------------ partials
    def partials_parameters(self, lon: ArrayLike, lat: ArrayLike, h: ArrayLike) -> Float64Array:
        """No parameters.

        Returns
        -------
        ndarray, (*S, 2, 0)
        """
        lon, _, _ = broadcast_float64(lon=lon, lat=lat, h=h, _copy=False)
        return np.zeros(lon.shape + (2, 0))

    def __repr__(self) -> str:
        return f"<CollocationCorrection ({self._collocation.n_points} points) of {self._model!r}>"
