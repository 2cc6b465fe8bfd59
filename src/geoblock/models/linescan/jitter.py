"""Attitude (and position) corrections that vary along the image: the ``"jitter"`` set.

Real on-board attitude wanders: measured on the attitude records of the shared sample
products, the roll, pitch and yaw depart from a cubic in time over the image by 0.02-0.12 µrad
RMS (WorldView-1, 50 Hz records) and 0.09-0.43 µrad RMS (SPOT-5, 8 Hz records), in slow
oscillations of about 0.5-3 Hz (issue 27). The linescan model's bias + rate corrections
(:class:`~geoblock.models.linescan.LinescanModel`) cannot follow that; the ``"jitter"``
parameter set adds, per axis, a uniform cubic B-spline in time:

``angle_a(t) = bias_a + rate_a (t - t_ref) + sum_k c_{a,k} B_k(t)``

so ``R'(t) = R(t) Rx(roll) Ry(pitch) Rz(yaw)`` of the summed angles, and optionally the same
for the position offsets in the orbital frame (``dp_along``, ``dp_across``, ``dp_radial``).

The spline (:class:`JitterSpline`)
----------------------------------
Knots every ``interval_s`` seconds (``knot_lines`` lines times the line period's magnitude)
from ``start_s``; ``intervals`` knot intervals cover the exposure times of the image rows'
outer edges with at least half an interval to spare at each end (centred on them, in either
scan direction: a reverse scan's row 0 is its latest line), with ``intervals + 3``
coefficients per axis, ``B_k(t) = B3((t - start_s) /
interval_s - k + 1)`` the uniform cubic B-spline. Outside the grid the spline is held at its
end values (the spline parameter is clamped), so the corrections stay continuous where the
ground -> image search looks beyond the image. Each time has four nonzero basis functions:
a measurement's partials touch four coefficients per axis.

Coefficient names
-----------------
``roll_spline_000``, ``roll_spline_001``, ... ``pitch_spline_...``, ``yaw_spline_...``
(radians); with ``position=True`` also ``dp_along_spline_...``, ``dp_across_spline_...``,
``dp_radial_spline_...`` (metres; radial positive up, like ``dp_radial``). The index has at
least three digits (``{k:03d}``) and counts from the earliest knot.

A-priori (:func:`jitter_parameters`)
------------------------------------
Per axis, the information ``diag(1 / sigma^2) + D2^T D2 / s^2`` with ``D2`` the second
differences of consecutive coefficients: an amplitude prior ``sigma`` (the size of the
wander; it also keeps the spline's constant and linear part, which duplicate the bias and the
rate, determined) and a smoothness prior ``s`` per knot interval. The set carries it as a
:class:`~geoblock.models.ParameterSet` ``information`` matrix, which an adjustment uses as the
weight of the coefficients' pseudo-observations.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from geoblock.errors import ParameterSetError
from geoblock.models.linescan._checks import fail
from geoblock.models.linescan.line_times import LineTimes
from geoblock.models.linescan.presets import ALL_NAMES
from geoblock.models.parameters import ParameterSet, accuracy_or_stored
from geoblock.typing import ArrayLike, Float64Array, IndexArray

if TYPE_CHECKING:
    from geoblock.models.curves import CorrectionCurve
    from geoblock.models.linescan._protocol import Linescan as LinescanModel

__all__ = [
    "ATTITUDE_SPLINE_AXES",
    "DEFAULT_JITTER_SIGMA_RAD",
    "JITTER_BASES",
    "JITTER_OPTIONS",
    "MIN_KNOT_LINES",
    "POSITION_SPLINE_AXES",
    "WANDER_MAX_HZ",
    "JitterSpline",
    "attitude_correction",
    "correction_curves",
    "default_knot_lines",
    "default_smoothness",
    "jitter_parameters",
    "position_correction",
]

#: The attitude axes of the spline, in the order of their coefficients (radians).
ATTITUDE_SPLINE_AXES: tuple[str, ...] = ("roll", "pitch", "yaw")
#: The position axes of the optional position spline (metres, orbital frame, radial up).
POSITION_SPLINE_AXES: tuple[str, ...] = ("dp_along", "dp_across", "dp_radial")
#: Default amplitude sigma of an attitude coefficient, radians: about five times the largest
#: departure of a shared product's attitude record from a cubic in time over its image
#: (SPOT-5 pitch 0.43 µrad RMS; WorldView-1 0.02-0.12 µrad), so the prior does not shrink a
#: real wander while it still determines the spline's constant and linear part.
DEFAULT_JITTER_SIGMA_RAD: float = 2e-6
#: The highest attitude-wander frequency the default smoothness prior lets through, Hz (the
#: upper end of the 0.5-3 Hz wander measured on the DigitalGlobe attitude records, issue 27):
#: the default ``smoothness_rad`` is the second difference over one knot interval ``h`` of a
#: sinusoid of amplitude ``sigma_rad`` at this frequency, ``4 sin^2(pi f h) sigma_rad``
#: (``pi f h`` capped at ``pi / 2``).
WANDER_MAX_HZ: float = 3.0
#: The smallest default knot spacing, lines (a spline faster than this is not what an attitude
#: record's sampling suggests; give ``knot_lines`` to go below it).
MIN_KNOT_LINES: int = 10
#: The parameter sets a ``"jitter"`` set can extend (``base=``).
JITTER_BASES: tuple[str, ...] = ("dg", "physical", "linescan")
#: The options of ``with_parameter_set("jitter", ...)``.
JITTER_OPTIONS: tuple[str, ...] = (
    "base", "knot_lines", "sigma_rad", "smoothness_rad", "position", "position_sigma_m",
    "position_smoothness_m", "accuracy_m")


@dataclass(frozen=True)
class JitterSpline:
    """The knot grid of a linescan model's correction splines.

    Parameters
    ----------
    start_s : float
        Time of the first knot, seconds since the model's epoch (the earliest).
    interval_s : float
        Knot spacing, seconds, > 0.
    intervals : int
        Number of knot intervals, >= 1; each axis has ``intervals + 3`` coefficients.
    position : bool
        Whether the position offsets have splines too (default only the attitude).
    """

    start_s: float
    interval_s: float
    intervals: int
    position: bool = False

    def __post_init__(self) -> None:
        for name in ("start_s", "interval_s"):
            try:
                value = float(getattr(self, name))
            except (TypeError, ValueError):
                raise fail(f"JitterSpline.{name}",
                           f"must be a number, got {getattr(self, name)!r}") from None
            if not np.isfinite(value):
                raise fail(f"JitterSpline.{name}", f"must be finite, got {value!r}")
            object.__setattr__(self, name, value)
        if not self.interval_s > 0:
            raise fail("JitterSpline.interval_s", f"must be > 0 s, got {self.interval_s!r}")
        if isinstance(self.intervals, bool) or not isinstance(self.intervals,
                                                              (int, np.integer)):
            raise fail("JitterSpline.intervals",
                       f"must be an integer >= 1, got {self.intervals!r}")
        object.__setattr__(self, "intervals", int(self.intervals))
        if self.intervals < 1:
            raise fail("JitterSpline.intervals", f"must be >= 1, got {self.intervals}")
        object.__setattr__(self, "position", bool(self.position))

    # ------------------------------------------------------------------ grid
    @classmethod
    def covering(cls, line_times: LineTimes, rows: int, knot_lines: float,
                 position: bool = False) -> JitterSpline:
        """The grid with knots every ``knot_lines`` lines centred on the exposure times of
        rows ``-0.5 .. rows - 0.5`` (the image's outer edges; either scan direction), with at
        least half a knot interval to spare on each side (the spline is held constant beyond
        the grid: its derivative jumps there, and no image point should sit on that kink)."""
        interval = float(knot_lines) * line_times.period_magnitude_s
        t0, t1 = line_times.span(-0.5, rows - 0.5)
        intervals = math.ceil((t1 - t0) / interval - 1e-9) + 1
        start = 0.5 * (t0 + t1) - 0.5 * intervals * interval
        return cls(start, interval, intervals, position)

    @property
    def n_coefficients(self) -> int:
        """Coefficients per axis, ``intervals + 3``."""
        return self.intervals + 3

    @property
    def axes(self) -> tuple[str, ...]:
        """The axes with a spline: :data:`ATTITUDE_SPLINE_AXES`, then
        :data:`POSITION_SPLINE_AXES` with ``position``."""
        return ATTITUDE_SPLINE_AXES + (POSITION_SPLINE_AXES if self.position else ())

    @property
    def names(self) -> tuple[str, ...]:
        """All coefficient names, axis by axis (``roll_spline_000`` ...)."""
        return tuple(f"{axis}_spline_{k:03d}" for axis in self.axes
                     for k in range(self.n_coefficients))

    @property
    def units(self) -> tuple[str, ...]:
        """Units of :attr:`names`: ``"rad"`` for attitude, ``"m"`` for position."""
        n = self.n_coefficients
        return ("rad",) * (3 * n) + (("m",) * (3 * n) if self.position else ())

    @property
    def knots_s(self) -> Float64Array:
        """(intervals + 1,) knot times, seconds since the epoch."""
        return self.start_s + self.interval_s * np.arange(self.intervals + 1, dtype=np.float64)

    def knot_lines(self, line_times: LineTimes) -> float:
        """The knot spacing in lines of ``line_times``."""
        return self.interval_s / line_times.period_magnitude_s

    # ------------------------------------------------------------------ evaluation
    def basis(self, t_s: ArrayLike, derivative: bool = False
              ) -> tuple[IndexArray, Float64Array]:
        """The four nonzero basis functions at times ``t_s``.

        Parameters
        ----------
        t_s : array_like, (N,)
            Seconds since the epoch; clamped to the grid (the spline is constant outside).
        derivative : bool
            Return ``dB_k/dt`` (per second; 0 outside the grid) instead.

        Returns
        -------
        first : ndarray of intp, (N,)
            Index of the first of the four coefficients (0 where ``t_s`` is NaN).
        weights : ndarray, (N, 4)
            ``B_{first + j}(t)``, j = 0..3 (NaN where ``t_s`` is NaN).
        """
        t = np.asarray(t_s, dtype=np.float64).ravel()
        raw = (t - self.start_s) / self.interval_s
        u = np.clip(raw, 0.0, float(self.intervals))
        i = np.minimum(np.floor(u), self.intervals - 1.0)
        s = u - i
        first = np.where(np.isfinite(i), i, 0.0).astype(np.intp)
        if derivative:
            inside = (raw > 0.0) & (raw < self.intervals)
            w = np.stack([-3.0 * (1.0 - s) ** 2, (9.0 * s - 12.0) * s,
                          (-9.0 * s + 6.0) * s + 3.0, 3.0 * s * s], axis=-1) / (
                6.0 * self.interval_s)
            w = np.where(inside[:, None] | np.isnan(t)[:, None], w, 0.0)
            return first, w
        s2 = s * s
        w = np.stack([(1.0 - s) ** 3, 3.0 * s2 * s - 6.0 * s2 + 4.0,
                      -3.0 * s2 * s + 3.0 * s2 + 3.0 * s + 1.0, s2 * s], axis=-1) / 6.0
        return first, w

    def evaluate(self, coefficients: ArrayLike, t_s: ArrayLike, derivative: bool = False
                 ) -> Float64Array:
        """The splines (or their time derivatives) of ``coefficients`` (A, n_coefficients)
        at times ``t_s`` (N,): (N, A)."""
        coef = np.asarray(coefficients, dtype=np.float64)
        first, w = self.basis(t_s, derivative)
        out = np.zeros((first.size, coef.shape[0]))
        for j in range(4):
            out += w[:, j, None] * coef[:, first + j].T
        return out

    # ------------------------------------------------------------------ serialisation
    def to_dict(self) -> dict[str, Any]:
        """JSON-safe dictionary."""
        return {"start_s": self.start_s, "interval_s": self.interval_s,
                "intervals": self.intervals, "position": self.position}

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> JitterSpline:
        """Inverse of :meth:`to_dict`."""
        return cls(data["start_s"], data["interval_s"], data["intervals"],
                   bool(data.get("position", False)))


# ================================================================================ parameter set
def default_knot_lines(model: LinescanModel) -> int:
    """The default knot spacing of a model's ``"jitter"`` set, lines.

    The attitude record's median sample interval divided by the line period's magnitude,
    rounded, at least :data:`MIN_KNOT_LINES`: the spline then has about one coefficient per
    attitude sample, the finest detail the record itself resolves (SPOT-5: 8 Hz, 166 lines;
    Pleiades: 64 Hz, 213 lines; WorldView-1: 50 Hz, 480 lines).
    """
    times = np.asarray(model.attitude.time_s, dtype=np.float64)
    step = float(np.median(np.diff(times))) if times.size > 1 else math.inf
    lines = step / model.line_times.period_magnitude_s
    if not np.isfinite(lines):
        return max(MIN_KNOT_LINES, model.shape[0])
    return max(MIN_KNOT_LINES, round(lines))


def _second_difference(n: int) -> Float64Array:
    """(n - 2, n) second differences ``c_k - 2 c_{k+1} + c_{k+2}``."""
    d = np.zeros((max(n - 2, 0), n))
    k = np.arange(max(n - 2, 0))
    d[k, k], d[k, k + 1], d[k, k + 2] = 1.0, -2.0, 1.0
    return d


def _positive(value: Any, what: str) -> float:
    try:
        # a boolean is not a number here (``knot_lines = true`` in a block file was 1 line)
        out = math.nan if isinstance(value, (bool, np.bool_)) else float(value)
    except (TypeError, ValueError):
        out = math.nan
    if not (np.isfinite(out) and out > 0):
        raise ParameterSetError(f"parameter set 'jitter': {what} must be finite and > 0, "
                                f"got {value!r}")
    return out


def jitter_parameters(
    base: ParameterSet,
    spline: JitterSpline,
    *,
    sigma_rad: float = DEFAULT_JITTER_SIGMA_RAD,
    smoothness_rad: float | None = None,
    position_sigma_m: float | None = None,
    position_smoothness_m: float | None = None,
) -> ParameterSet:
    """A base parameter set extended by the correction splines' coefficients.

    Parameters
    ----------
    base : ParameterSet
        The set the splines extend (e.g. :func:`~geoblock.models.linescan.dg_parameters`);
        its a-priori sigmas (or covariance) become the diagonal (block) of the information.
    spline : JitterSpline
        The grid; its :attr:`~JitterSpline.names` are appended, values 0, adjustable.
    sigma_rad : float
        Amplitude sigma of each attitude coefficient, radians (default
        :data:`DEFAULT_JITTER_SIGMA_RAD`).
    smoothness_rad : float, optional
        Sigma of the second difference of consecutive attitude coefficients (per knot
        interval), radians; default ``4 sin^2(min(pi f h, pi/2)) sigma_rad`` with
        ``f = WANDER_MAX_HZ`` and ``h`` the knot spacing in seconds.
    position_sigma_m, position_smoothness_m : float, optional
        The same for the position coefficients, metres; required with ``spline.position``.

    Returns
    -------
    ParameterSet
        ``base.names + spline.names``; ``information`` block diagonal: the base's inverse
        covariance (zero rows for its free parameters) and, per spline axis,
        ``diag(1 / sigma^2) + D2^T D2 / smoothness^2``.

    Raises
    ------
    ParameterSetError
        A sigma is not finite and > 0, or the position sigmas are missing.
    """
    sigma = _positive(sigma_rad, "sigma_rad")
    if smoothness_rad is None:
        smooth = default_smoothness(sigma, spline.interval_s)
    else:
        smooth = _positive(smoothness_rad, "smoothness_rad")
    n = spline.n_coefficients
    d2 = _second_difference(n)
    block = np.eye(n) / sigma**2 + d2.T @ d2 / smooth**2
    blocks = [block] * 3
    if spline.position:
        if position_sigma_m is None:
            raise ParameterSetError("parameter set 'jitter': position splines need "
                                    "position_sigma_m")
        p_sigma = _positive(position_sigma_m, "position_sigma_m")
        p_smooth = (default_smoothness(p_sigma, spline.interval_s)
                    if position_smoothness_m is None
                    else _positive(position_smoothness_m, "position_smoothness_m"))
        blocks += [np.eye(n) / p_sigma**2 + d2.T @ d2 / p_smooth**2] * 3
    p0 = len(base)
    if base.information is not None:
        base_info = np.array(base.information)
    else:
        cov = np.array(base.prior_covariance)
        finite = np.isfinite(np.diag(cov))
        base_info = np.zeros((p0, p0))
        if finite.any():
            base_info[np.ix_(finite, finite)] = np.linalg.inv(cov[np.ix_(finite, finite)])
    total = p0 + len(blocks) * n
    info = np.zeros((total, total))
    info[:p0, :p0] = base_info
    for a, b in enumerate(blocks):
        sl = slice(p0 + a * n, p0 + (a + 1) * n)
        info[sl, sl] = b
    return ParameterSet(
        base.names + spline.names, np.zeros(total), base.units + spline.units,
        adjustable=np.concatenate([base.adjustable, np.ones(total - p0, bool)]),
        information=info)


def default_smoothness(sigma: float, interval_s: float) -> float:
    """``4 sin^2(min(pi f h, pi/2)) sigma``: the second difference over one knot interval
    ``h`` of a sinusoid of amplitude ``sigma`` at ``f = WANDER_MAX_HZ``."""
    phase = min(math.pi * WANDER_MAX_HZ * interval_s, 0.5 * math.pi)
    return max(4.0 * math.sin(phase) ** 2 * sigma, 1e-6 * sigma)


def jitter_set(model: LinescanModel, *, base: str = "dg", knot_lines: float | None = None,
               sigma_rad: float = DEFAULT_JITTER_SIGMA_RAD,
               smoothness_rad: float | None = None, position: bool | None = None,
               position_sigma_m: float | None = None,
               position_smoothness_m: float | None = None,
               accuracy_m: float | None = None) -> tuple[JitterSpline, ParameterSet]:
    """The grid and the parameter set of ``model.with_parameter_set("jitter", ...)`` (values
    0; the model keeps its current values). See :meth:`LinescanModel.with_parameter_set`."""
    from geoblock.models.linescan.presets import (
        _geometry_scales,
        dg_parameters,
        physical_parameters,
    )

    label = f"{type(model).__qualname__} {model.name!r}"
    if base not in JITTER_BASES:
        raise ParameterSetError(f"{label}: parameter set 'jitter': base must be one of "
                                f"{list(JITTER_BASES)}, got {base!r}")
    current = model.jitter
    if position is None:
        position = current.position if current is not None else False
    if knot_lines is None and current is not None:
        knots = current.interval_s / model.line_times.period_magnitude_s
    elif knot_lines is None:
        knots = float(default_knot_lines(model))
    else:
        knots = _positive(knot_lines, "knot_lines")
        if knots < 1.0:
            raise ParameterSetError(f"{label}: parameter set 'jitter': knot_lines must be "
                                    f">= 1 line, got {knot_lines!r}")
    if not isinstance(position, (bool, np.bool_)):
        raise ParameterSetError(f"{label}: parameter set 'jitter': position must be True or "
                                f"False, got {position!r}")
    spline = JitterSpline.covering(model.line_times, model.shape[0], knots, bool(position))
    if knot_lines is None and current is not None:  # the current grid, exactly
        spline = JitterSpline(current.start_s, current.interval_s, current.intervals,
                              bool(position))
    if base == "linescan":
        if accuracy_m is not None:
            raise ParameterSetError(f"{label}: parameter set 'jitter' with base 'linescan' "
                                    "takes no accuracy_m (the base parameters are free)")
        from geoblock.models.linescan.presets import PARAMETER_NAMES, PARAMETER_UNITS
        base_set = ParameterSet(PARAMETER_NAMES, np.zeros(12), PARAMETER_UNITS)
    else:
        accuracy = accuracy_or_stored(accuracy_m, model.location_accuracy_m, label,
                                      f"jitter (base {base!r})")
        preset = dg_parameters if base == "dg" else physical_parameters
        base_set = preset(model, accuracy)
    p_sigma = position_sigma_m
    p_smooth = position_smoothness_m
    if spline.position:
        slant = _geometry_scales(model)[1]
        sigma = _positive(sigma_rad, "sigma_rad")
        if p_sigma is None:
            p_sigma = sigma * slant
        if p_smooth is None and smoothness_rad is not None:
            p_smooth = _positive(smoothness_rad, "smoothness_rad") * slant
    params = jitter_parameters(base_set, spline, sigma_rad=sigma_rad,
                               smoothness_rad=smoothness_rad, position_sigma_m=p_sigma,
                               position_smoothness_m=p_smooth)
    return spline, params


# ================================================================================ partials
def scatter_partials(spline: JitterSpline, column: np.ndarray, t: Float64Array,
                     base: Float64Array, out: Float64Array) -> None:
    """Fill the spline coefficients' partials into ``out`` (N, 2, P) in place.

    ``column`` (A, n_coefficients) gives each coefficient's column in ``out`` (-1: not in
    the set); ``base`` (N, 2, A) the partials of the axis's bias (``d/dc_{a,k} = B_k(t)
    d/d bias_a``).
    """
    first, w = spline.basis(t)
    pts = np.arange(t.size)
    for a in range(column.shape[0]):
        for j in range(4):
            col = column[a, first + j]
            keep = col >= 0
            if keep.any():
                out[pts[keep], :, col[keep]] = w[keep, j, None] * base[keep, :, a]


# ================================================================================ curves
def _correction(model: LinescanModel, time_s: ArrayLike, attitude: bool,
                covariance: ArrayLike | None, names: Sequence[str] | None, detrend: bool
                ) -> tuple[Float64Array, Float64Array]:
    t = np.asarray(time_s, dtype=np.float64)
    shape = t.shape
    t = t.ravel()
    params = model.parameters
    all_names = params.names
    dt = t - model.line_times.reference_time_s
    if attitude:
        biases = ("roll_bias", "pitch_bias", "yaw_bias")
        rates = ("roll_rate", "pitch_rate", "yaw_rate")
        axes = ATTITUDE_SPLINE_AXES
    else:
        biases = ("dp_along", "dp_across", "dp_radial")
        rates = ("dp_along_rate", "dp_across_rate", "dp_radial_rate")
        axes = POSITION_SPLINE_AXES
    design = np.zeros((t.size, 3, len(all_names)))  # d curve / d parameter
    where = {n: k for k, n in enumerate(all_names)}
    for a in range(3):
        if biases[a] in where:
            design[:, a, where[biases[a]]] = 1.0
        if rates[a] in where:
            design[:, a, where[rates[a]]] = dt
    spline = model.jitter
    if spline is not None and axes[0] in spline.axes:
        first, w = spline.basis(t)
        n = spline.n_coefficients
        pts = np.arange(t.size)
        for a, axis in enumerate(axes):
            column = np.array([where.get(f"{axis}_spline_{k:03d}", -1) for k in range(n)])
            for j in range(4):
                col = column[first + j]
                keep = col >= 0
                design[pts[keep], a, col[keep]] = w[keep, j]
    if detrend:  # minus the least-squares line in time over the times given
        x = np.stack([np.ones(t.size), t - t.mean()], axis=-1)
        fit = np.linalg.lstsq(x, design.reshape(t.size, -1), rcond=None)[0]
        trend = (x @ fit).reshape(design.shape)
        # what is exactly linear in time (bias, rate) goes; rounding stays below this
        tiny = 1e-9 * np.max(np.abs(design), axis=0, keepdims=True)
        design = np.where(np.abs(design - trend) > tiny, design - trend, 0.0)
    values = design @ np.asarray(params.values)
    if covariance is None:
        cov = np.array(params.prior_covariance)
        idx = np.arange(len(all_names))
    else:
        cov = np.asarray(covariance, dtype=np.float64)
        listed = list(all_names) if names is None else [str(n) for n in names]
        if cov.shape != (len(listed), len(listed)):
            raise ValueError(f"covariance of shape {cov.shape} for {len(listed)} parameters "
                             f"(give names= for a covariance of some of the model's "
                             "parameters)")
        unknown = [n for n in listed if n not in where]
        if unknown:
            raise ValueError(f"covariance names parameters the model does not have: "
                             f"{unknown[:5]}")
        idx = np.array([where[n] for n in listed], dtype=np.intp)
    g = design[:, :, idx]  # (T, 3, K)
    with np.errstate(invalid="ignore"):
        finite = np.isfinite(cov)
        # inf variance of a parameter the curve depends on: an unbounded band
        var = np.einsum("tak,kl,tal->ta", g, np.where(finite, cov, 0.0), g)
        free = ~np.all(finite, axis=0)
        if free.any():
            var = np.where(np.any(g[:, :, free] != 0, axis=-1), np.inf, var)
    sigmas = np.sqrt(np.maximum(var, 0.0))
    return values.reshape(shape + (3,)), sigmas.reshape(shape + (3,))


def attitude_correction(model: LinescanModel, time_s: ArrayLike,
                        covariance: ArrayLike | None = None,
                        names: Sequence[str] | None = None, *, detrend: bool = False,
                        ) -> tuple[Float64Array, Float64Array]:
    """A linescan model's attitude correction curve and its standard deviation.

    ``bias + rate (t - t_ref) + spline(t)`` per axis, the angles of
    ``R'(t) = R(t) Rx(roll) Ry(pitch) Rz(yaw)``.

    Parameters
    ----------
    model : LinescanModel
    time_s : array_like, (...)
        Seconds since the model's epoch (rows: ``model.line_times.time(rows)``).
    covariance : array_like, (K, K), optional
        Covariance of the model's parameters ``names`` (default all of
        ``model.parameters.names``), in their units squared, e.g. an adjustment's posterior:
        ``idx = [k for k, (i, n) in enumerate(result.parameter_index) if i == image]``,
        ``covariance=result.covariance[np.ix_(idx, idx)]``,
        ``names=[result.parameter_index[k][1] for k in idx]``. Parameters not named are
        taken as exact. Default: the model's a-priori covariance
        (:attr:`~geoblock.models.ParameterSet.prior_covariance`).
    names : sequence of str, (K,), optional
        The parameters of ``covariance``'s rows.
    detrend : bool
        Take the least-squares straight line in time over ``time_s`` out of the curve and of
        its band: the wander. An adjustment determines the correction's constant and trend
        only together with the position offsets (a pitch bias and an along-track offset move
        the image alike), so the full curve's band is as wide as their a-priori trade-off
        allows, while the wander is what the image measurements fix; compare it with a
        truth detrended the same way.

    Returns
    -------
    angles : ndarray, (..., 3)
        Roll, pitch, yaw corrections, radians.
    sigmas : ndarray, (..., 3)
        Their standard deviations, radians (``inf`` where a free parameter enters).

    Raises
    ------
    ValueError
        ``covariance`` and ``names`` do not match, or name unknown parameters.
    """
    return _correction(model, time_s, True, covariance, names, detrend)


def position_correction(model: LinescanModel, time_s: ArrayLike,
                        covariance: ArrayLike | None = None,
                        names: Sequence[str] | None = None, *, detrend: bool = False,
                        ) -> tuple[Float64Array, Float64Array]:
    """A linescan model's position correction curve (along, across, radial up; metres, in the
    orbital frame) and its standard deviation: ``dp + dp_rate (t - t_ref) + spline(t)``;
    arguments as :func:`attitude_correction`."""
    return _correction(model, time_s, False, covariance, names, detrend)


def correction_curves(model: LinescanModel, covariance: ArrayLike | None = None,
                      names: Sequence[str] | None = None, *,
                      rows: tuple[float, float] | None = None, samples: int = 200,
                      detrend: bool = True) -> tuple[CorrectionCurve, ...]:
    """:meth:`LinescanModel.correction_curves <geoblock.models.linescan.LinescanModel.
    correction_curves>`: the attitude curve (and the position curve with position splines)
    of a model with a :attr:`~geoblock.models.linescan.LinescanModel.jitter` grid, sampled at
    ``samples`` rows evenly over ``rows`` (default the whole image), in increasing time;
    ``()`` without a grid (a bias and a rate only: nothing varies along the image but a
    line). The curves are :func:`attitude_correction` and :func:`position_correction` with
    ``covariance``, ``names`` and ``detrend``; see
    :class:`~geoblock.models.curves.HasCorrectionCurves`.

    Raises
    ------
    ValueError
        ``samples < 2``, ``rows`` not two finite numbers, or ``covariance`` and ``names``
        do not match.
    """
    from geoblock.models.curves import CorrectionCurve

    spline = model.jitter
    if spline is None:
        return ()
    if isinstance(samples, bool) or not isinstance(samples, (int, np.integer)) or samples < 2:
        raise ValueError(f"correction_curves: samples must be an integer >= 2, got {samples!r}")
    first, last = (0.0, model.shape[0] - 1.0) if rows is None else (float(rows[0]),
                                                                      float(rows[1]))
    if not (np.isfinite(first) and np.isfinite(last)):
        raise ValueError(f"correction_curves: rows must be finite, got {rows!r}")
    r = np.linspace(first, last, int(samples))
    t = model.line_times.time(r)
    order = np.argsort(t, kind="stable")
    r, t = r[order], t[order]
    centre = float(model.line_times.time(0.5 * (first + last)))
    out = []
    for quantity, axes, unit, curve in (
            ("attitude", ATTITUDE_SPLINE_AXES, "rad", attitude_correction),
            ("position", POSITION_SPLINE_AXES, "m", position_correction)):
        if axes[0] not in spline.axes:
            continue
        values, sigmas = curve(model, t, covariance, names, detrend=detrend)
        out.append(CorrectionCurve(quantity, axes, unit, t, r, centre, values, sigmas,
                                   bool(detrend)))
    return tuple(out)


def spline_columns(spline: JitterSpline, names: Sequence[str]) -> np.ndarray:
    """(6, n_coefficients) position of each coefficient in ``names`` (-1: absent); rows
    roll, pitch, yaw, along, across, radial."""
    where = {n: k for k, n in enumerate(names)}
    n = spline.n_coefficients
    out = np.full((6, n), -1, dtype=np.intp)
    for a, axis in enumerate(ATTITUDE_SPLINE_AXES + POSITION_SPLINE_AXES):
        for k in range(n):
            out[a, k] = where.get(f"{axis}_spline_{k:03d}", -1)
    return out


def known_names(spline: JitterSpline | None) -> tuple[str, ...]:
    """Every parameter name a linescan model with ``spline`` accepts."""
    return ALL_NAMES + (spline.names if spline is not None else ())
