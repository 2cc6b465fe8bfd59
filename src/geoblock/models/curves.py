"""Time-dependent corrections a model can show: :class:`CorrectionCurve` and the optional
capability :class:`HasCorrectionCurves`.

A model whose parameters include corrections that vary along the image in time (the attitude
splines of a linescan model's ``"jitter"`` set, :mod:`geoblock.models.linescan.jitter`) can
say so by implementing ``correction_curves``; the report of a block adjustment
(:func:`geoblock.report.adjustment.write_result`) then plots each curve with its posterior
band, for any model that has the method, without asking which class it is. The method is not
part of :class:`~geoblock.models.SensorModel`: a model without time-dependent corrections
simply does not implement it (or returns an empty tuple).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Protocol, runtime_checkable

import numpy as np

from geoblock.errors import ShapeMismatchError
from geoblock.typing import ArrayLike, Float64Array

__all__ = ["CorrectionCurve", "HasCorrectionCurves", "detrend"]


def detrend(time_s: ArrayLike, values: ArrayLike) -> Float64Array:
    """``values`` minus their least-squares straight line in ``time_s``.

    Parameters
    ----------
    time_s : array_like, (T,)
        Times, seconds (any origin).
    values : array_like, (T,) or (T, A)
        A curve per column.

    Returns
    -------
    ndarray
        Same shape as ``values``: what a constant and a linear trend in time do not explain
        (NaN rows are ignored in the fit and stay NaN).

    Raises
    ------
    ShapeMismatchError
        ``values`` has another number of rows than ``time_s``.
    """
    t = np.asarray(time_s, dtype=np.float64).ravel()
    v = np.asarray(values, dtype=np.float64)
    if v.shape[:1] != (t.size,):
        raise ShapeMismatchError(f"detrend: values of shape {v.shape} for {t.size} times")
    table = v.reshape(t.size, -1)
    ok = np.isfinite(t) & np.all(np.isfinite(table), axis=1)
    x = np.stack([np.ones(t.size), t - (t[ok].mean() if ok.any() else 0.0)], axis=-1)
    out = np.full_like(table, np.nan)
    if ok.sum() >= 2:
        coef = np.linalg.lstsq(x[ok], table[ok], rcond=None)[0]
        out = table - x @ coef
    return out.reshape(v.shape)


@dataclass(frozen=True, eq=False)
class CorrectionCurve:
    """A time-dependent correction of a model, sampled along the image, with its band.

    Attributes
    ----------
    quantity : str
        What is corrected, e.g. ``"attitude"`` or ``"position"``.
    axes : tuple of str, (A,)
        The components, e.g. ``("roll", "pitch", "yaw")``.
    unit : str
        Unit of ``values`` and ``sigmas`` (``"rad"``, ``"m"``).
    time_s : ndarray, (T,)
        Sample times, seconds since the model's epoch, increasing.
    rows : ndarray, (T,)
        The image rows exposed at ``time_s`` (pixel centres at integers).
    centre_s : float
        Time of the image's centre row (the origin of a plot's time axis).
    values : ndarray, (T, A)
        The correction at ``time_s``.
    sigmas : ndarray, (T, A)
        Its standard deviation from the covariance the curve was computed with (posterior
        after an adjustment; ``inf`` where a free parameter enters).
    detrended : bool
        Whether the least-squares straight line in time over ``time_s`` was taken out of
        ``values`` and ``sigmas`` (:func:`detrend`): compare with a truth detrended the same
        way.
    """

    quantity: str
    axes: tuple[str, ...]
    unit: str
    time_s: Float64Array
    rows: Float64Array
    centre_s: float
    values: Float64Array
    sigmas: Float64Array
    detrended: bool = False

    def __post_init__(self) -> None:
        t = np.asarray(self.time_s, dtype=np.float64).ravel()
        shape = (t.size, len(self.axes))
        for name in ("values", "sigmas"):
            arr = np.asarray(getattr(self, name), dtype=np.float64)
            if arr.shape != shape:
                raise ShapeMismatchError(f"CorrectionCurve.{name}: shape {arr.shape}, expected "
                                         f"{shape} (times, axes)")
            object.__setattr__(self, name, arr)
        rows = np.asarray(self.rows, dtype=np.float64).ravel()
        if rows.shape != t.shape:
            raise ShapeMismatchError(f"CorrectionCurve.rows: {rows.size} rows for {t.size} "
                                     "times")
        object.__setattr__(self, "time_s", t)
        object.__setattr__(self, "rows", rows)
        object.__setattr__(self, "axes", tuple(str(a) for a in self.axes))
        object.__setattr__(self, "centre_s", float(self.centre_s))

    def compare(self, truth: ArrayLike) -> Float64Array:
        """``truth`` (T, A) at :attr:`time_s` in :attr:`unit`, detrended like the curve when
        :attr:`detrended` (otherwise as given): what :attr:`values` should be."""
        arr = np.asarray(truth, dtype=np.float64)
        if arr.shape != self.values.shape:
            raise ShapeMismatchError(f"CorrectionCurve.compare: truth of shape {arr.shape}, "
                                     f"expected {self.values.shape} (times, axes)")
        return detrend(self.time_s, arr) if self.detrended else arr


@runtime_checkable
class HasCorrectionCurves(Protocol):
    """A model that can show its time-dependent corrections (optional capability).

    :class:`~geoblock.models.linescan.LinescanModel` implements it (its ``"jitter"`` set's
    attitude and position splines); :class:`~geoblock.models.CroppedModel` passes it on for
    its rows. Any model may: ``isinstance(model, HasCorrectionCurves)`` checks only that the
    method exists.
    """

    def correction_curves(
        self,
        covariance: ArrayLike | None = None,
        names: Sequence[str] | None = None,
        *,
        rows: tuple[float, float] | None = None,
        samples: int = 200,
        detrend: bool = True,
    ) -> tuple[CorrectionCurve, ...]:
        """The model's time-dependent corrections, sampled over the image.

        Parameters
        ----------
        covariance : array_like, (K, K), optional
            Covariance of the parameters ``names`` (e.g. an adjustment's posterior,
            :meth:`geoblock.adjust.BlockResult.parameter_covariance`); parameters not named
            are taken as exact. Default: the model's a-priori covariance.
        names : sequence of str, (K,), optional
            The parameters of ``covariance``'s rows (default all of ``parameters.names``).
        rows : (float, float), optional
            First and last image row to sample (default the whole image).
        samples : int
            Number of samples, >= 2.
        detrend : bool
            Take the least-squares line in time out of each curve and its band.

        Returns
        -------
        tuple of CorrectionCurve
            Empty when the model has no correction varying along the image beyond a bias
            and a rate.
        """
        ...
