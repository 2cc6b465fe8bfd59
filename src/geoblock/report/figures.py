"""The papers' accuracy figures, drawn with matplotlib (Agg; no display, no pyplot state).

* :func:`error_vector_plot`: error vectors at the points, exaggerated by a stated factor with
  a scale arrow; GCPs and TPs as triangles, ICPs and ICTPs as circles (Teo et al. 2010,
  Figs. 9-12; Aguilar et al. 2007, Fig. 5).
* :func:`rmse_vs_gcp_count`: RMSE against the number of GCPs, a line per model or method,
  with a confidence band or error bars over repetitions (Aguilar et al., Figs. 3, 6, 7).
* :func:`residual_vs_distance`: residuals against the distance from the image centre with a
  least-squares line and its R² (Aguilar et al., Fig. 4).
* :func:`correction_curve_plot`: a time-dependent correction an adjustment recovered (the
  attitude corrections of a jitter parameter set), one panel per axis, with its posterior
  sigma band and, on simulated data, the truth.

Each function takes plain arrays, returns the :class:`matplotlib.figure.Figure` and, given
``path``, saves it (PNG, or the format of the suffix) through :func:`save_figure`.
"""

from __future__ import annotations

import math
import os
from collections.abc import Mapping
from pathlib import Path

import numpy as np
from matplotlib.axes import Axes
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.lines import Line2D

from geoblock import coords
from geoblock.adjust.statistics import POINT_KINDS, _kinds, confidence_interval
from geoblock.errors import ObservationError, ShapeMismatchError
from geoblock.io import files
from geoblock.typing import ArrayLike, Float64Array

__all__ = [
    "KIND_STYLES",
    "correction_curve_plot",
    "error_vector_plot",
    "nice_number",
    "residual_vs_distance",
    "rmse_vs_gcp_count",
    "save_figure",
    "to_local_en",
]

#: marker and colour per point kind: control-type points (GCP, TP) are triangles and
#: check-type points (ICP, ICTP) circles, as in Teo et al.'s error-vector figures
KIND_STYLES: dict[str, dict[str, str]] = {
    "GCP": {"marker": "^", "color": "#c0392b"},
    "TP": {"marker": "^", "color": "#e67e22"},
    "ICP": {"marker": "o", "color": "#1f5fa8"},
    "ICTP": {"marker": "o", "color": "#16a085"},
}
_SERIES_MARKERS = ("o", "s", "^", "D", "v", "P", "X", "<", ">")
_SERIES_COLOURS = ("#1f5fa8", "#c0392b", "#16a085", "#8e44ad", "#e67e22", "#2c3e50")
_VECTOR_COLOUR = "#222222"


# --------------------------------------------------------------------------- helpers
def nice_number(x: float, *, round_down: bool = True) -> float:
    """The 1-2-5 number (1, 2, 5, 10, 20 ...) nearest below (or above) ``x > 0``."""
    if not (x > 0 and math.isfinite(x)):
        return 1.0
    exp = math.floor(math.log10(x))
    steps = (1.0, 2.0, 5.0, 10.0)
    frac = x / 10.0**exp
    if round_down:
        m = max(s for s in steps if s <= frac * (1 + 1e-12))
    else:
        m = min(s for s in steps if s >= frac * (1 - 1e-12))
    return m * 10.0**exp


def to_local_en(lon: ArrayLike, lat: ArrayLike, h: ArrayLike = 0.0,
                origin: tuple[float, float, float] | None = None,
                ) -> tuple[Float64Array, Float64Array]:
    """Positions for the plots: local east and north metres of ``lon, lat`` (degrees).

    The tangent plane is centred on ``origin`` ``(lon, lat, h)`` or, by default, on the
    points' centroid (:meth:`geoblock.coords.LocalFrame.centred_on`).
    """
    lon, lat, h = np.broadcast_arrays(*(np.asarray(v, dtype=np.float64) for v in (lon, lat, h)))
    frame = (coords.LocalFrame(*origin) if origin is not None
             else coords.LocalFrame.centred_on(lon, lat, h))
    e, n, _ = frame.from_geodetic(lon, lat, h)
    return e, n


def save_figure(fig: Figure, path: str | os.PathLike[str], *, dpi: int = 150) -> Path:
    """Save ``fig`` to ``path`` atomically (:func:`geoblock.io.files.save_figure`); the
    suffix picks the format (``.png``, ``.svg``).

    Raises
    ------
    GeoblockIOError
        The file cannot be written.
    """
    fmt = Path(path).suffix.lstrip(".").lower() or "png"
    return files.save_figure(fig, path, format=fmt, dpi=dpi)


def _new_axes(ax: Axes | None, figsize: tuple[float, float]) -> tuple[Figure, Axes]:
    if ax is not None:
        figure = ax.figure
        return (figure if isinstance(figure, Figure) else figure.figure), ax  # a SubFigure's root
    fig = Figure(figsize=figsize, layout="constrained")
    FigureCanvasAgg(fig)
    return fig, fig.add_subplot()


def _finish(fig: Figure, path: str | os.PathLike[str] | None, dpi: int) -> Figure:
    if path is not None:
        save_figure(fig, path, dpi=dpi)
    return fig


def _same_length(where: str, **arrays: ArrayLike) -> dict[str, Float64Array]:
    out = {k: np.asarray(v, dtype=np.float64).ravel() if np.ndim(v) else
           np.asarray(v, dtype=np.float64) for k, v in arrays.items()}
    sizes = {k: v.size for k, v in out.items() if v.ndim}
    if len(set(sizes.values())) > 1:
        listed = ", ".join(f"{k} ({s})" for k, s in sizes.items())
        raise ShapeMismatchError(f"{where}: the arrays differ in length: {listed}")
    n = next(iter(sizes.values()), 1)
    return {k: np.broadcast_to(v, (n,)) for k, v in out.items()}


# --------------------------------------------------------------------------- error vectors
def error_vector_plot(
    e: ArrayLike,
    n: ArrayLike,
    de: ArrayLike,
    dn: ArrayLike,
    kind: ArrayLike = "ICP",
    *,
    scale: float | None = None,
    scale_bar: float | None = None,
    title: str | None = None,
    xlabel: str = "E (m)",
    ylabel: str = "N (m)",
    unit: str = "m",
    y_down: bool = False,
    ax: Axes | None = None,
    figsize: tuple[float, float] = (6.4, 6.4),
    path: str | os.PathLike[str] | None = None,
    dpi: int = 150,
) -> Figure:
    """Error vectors at the points, exaggerated by ``scale`` (Teo et al. Figs. 9-12).

    Parameters
    ----------
    e, n : array_like, (N,)
        Point positions, metres (a local frame, :func:`to_local_en`, or map coordinates).
    de, dn : array_like, (N,)
        Errors (estimated minus reference, or ICTP discrepancies), metres. Points with a
        non-finite error get a marker and no vector.
    kind : array_like of str, (N,), or str
        ``GCP``, ``ICP``, ``TP`` or ``ICTP``: GCPs and TPs are triangles, ICPs and ICTPs
        circles (:data:`KIND_STYLES`).
    scale : float, optional
        Exaggeration of the vectors (an error of 1 m is drawn ``scale`` metres long).
        Default: a 1-2-5 number making the 95th-percentile error about 12 % of the plot's
        extent.
    scale_bar : float, optional
        Length of the reference arrow, metres of error. Default: a 1-2-5 number near the
        RMS error.
    title, xlabel, ylabel : str
        The exaggeration is appended to the title.
    unit : str
        Unit of the positions and errors in the key (``"m"``; ``"px"`` for image residuals:
        ``e, n`` then are ``col, row`` and ``de, dn`` the residuals ``v_col, v_row``).
    y_down : bool
        Draw the second axis downwards, as image rows are.
    ax : matplotlib Axes, optional
        Draw into these axes (their figure is returned) instead of a new figure.
    figsize : (float, float)
        Inches, for a new figure.
    path : path-like, optional
        Save the figure there (:func:`save_figure`).
    dpi : int

    Returns
    -------
    matplotlib.figure.Figure

    Raises
    ------
    ShapeMismatchError
        Arrays of different lengths.
    ObservationError
        An unknown point kind, no point, or a non-positive ``scale`` / ``scale_bar``.
    """
    where = "error_vector_plot"
    a = _same_length(where, e=e, n=n, de=de, dn=dn)
    size = a["e"].size
    if size == 0:
        raise ObservationError(f"{where}: no point to plot")
    kinds = _kinds(kind, size, where=where)
    finite = np.isfinite(a["de"]) & np.isfinite(a["dn"])
    err = np.hypot(a["de"][finite], a["dn"][finite])
    extent = max(float(np.ptp(a["e"])), float(np.ptp(a["n"])), 1.0)
    if scale is None:
        typical = float(np.percentile(err, 95)) if err.size else 0.0
        scale = nice_number(0.12 * extent / typical) if typical > 0 else 1.0
    if scale_bar is None:
        rms = float(np.sqrt(np.mean(err**2))) if err.size else 0.0
        scale_bar = nice_number(rms, round_down=False) if rms > 0 else 1.0
    if not (scale > 0 and scale_bar > 0):
        raise ObservationError(f"{where}: scale and scale_bar must be positive, got "
                               f"{scale!r} and {scale_bar!r}")

    fig, ax = _new_axes(ax, figsize)
    ax.set_axisbelow(True)
    ax.grid(True, color="#dddddd", linewidth=0.6)
    q = ax.quiver(a["e"][finite], a["n"][finite], a["de"][finite], a["dn"][finite],
                  angles="xy", scale_units="xy", scale=1.0 / scale, color=_VECTOR_COLOUR,
                  width=0.004, headwidth=3.5, headlength=4.5, zorder=2)
    for k in POINT_KINDS:
        sel = kinds == k
        if sel.any():
            style = KIND_STYLES[k]
            ax.plot(a["e"][sel], a["n"][sel], linestyle="none", marker=style["marker"],
                    markersize=6.5, markerfacecolor=style["color"], markeredgecolor="white",
                    markeredgewidth=0.6, label=f"{k} ({int(sel.sum())})", zorder=3)
    # limits: the points and the arrow tips, with a margin
    xs = np.concatenate([a["e"], a["e"][finite] + scale * a["de"][finite]])
    ys = np.concatenate([a["n"], a["n"][finite] + scale * a["dn"][finite]])
    half = 0.54 * max(float(np.ptp(xs)), float(np.ptp(ys)), 1.0)  # square, 8 % margin
    cx, cy = (xs.min() + xs.max()) / 2, (ys.min() + ys.max()) / 2
    ax.set_xlim(cx - half, cx + half)
    ax.set_ylim(cy - half, cy + half)
    ax.set_aspect("equal", adjustable="box")
    if y_down:
        ax.invert_yaxis()  # angles="xy": the vectors follow the data axes
    key_x = 0.995 - 0.5 * scale * scale_bar / (2 * half)  # the arrow is centred on key_x
    ax.quiverkey(q, key_x, -0.10, scale_bar, f"{scale_bar:g} {unit} error (vectors ×{scale:g})",
                 labelpos="W", coordinates="axes", fontproperties={"size": 9})
    ax.legend(loc="upper left", bbox_to_anchor=(0.0, -0.07), ncol=4, frameon=False,
              fontsize=9, handletextpad=0.3, columnspacing=1.0)
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    ax.ticklabel_format(useOffset=False, style="plain")
    full = f"{title}\n" if title else ""
    ax.set_title(f"{full}error vectors exaggerated ×{scale:g}", fontsize=11)
    return _finish(fig, path, dpi)


# --------------------------------------------------------------------------- RMSE vs GCPs
def rmse_vs_gcp_count(
    series: Mapping[str, tuple[ArrayLike, ArrayLike]],
    *,
    ci_level: float | None = 0.95,
    ci_method: str = "t",
    band: str = "fill",
    title: str | None = None,
    xlabel: str = "Number of GCPs",
    ylabel: str = "RMSE 2D at ICPs (m)",
    ax: Axes | None = None,
    figsize: tuple[float, float] = (6.4, 4.2),
    path: str | os.PathLike[str] | None = None,
    dpi: int = 150,
) -> Figure:
    """RMSE against the number of GCPs, a line per model or method (Aguilar et al. Figs. 3, 6, 7).

    Parameters
    ----------
    series : mapping of str to (n_gcps, rmse)
        Per model (e.g. ``"RPCV-0"``): the GCP counts ``(K,)`` and the RMSE, metres, ``(K,)``
        or ``(R, K)`` for ``R`` repetitions (Monte-Carlo runs or GCP samplings). With
        repetitions the line is the mean and the confidence interval is drawn.
    ci_level : float or None
        Confidence level of the interval (:func:`geoblock.adjust.confidence_interval`);
        None draws no interval.
    ci_method : {"t", "percentile"}
        ``"t"``: interval of the mean (Aguilar et al.'s 95 % error bars); ``"percentile"``:
        spread of single runs.
    band : {"fill", "bars"}
        A shaded band or error bars.
    title, xlabel, ylabel, ax, figsize, path, dpi
        As :func:`error_vector_plot`.

    Returns
    -------
    matplotlib.figure.Figure

    Raises
    ------
    ShapeMismatchError
        ``rmse``'s last dimension differs from the number of GCP counts.
    ObservationError
        No series, or an unknown ``band``.
    """
    where = "rmse_vs_gcp_count"
    if not series:
        raise ObservationError(f"{where}: no series to plot")
    if band not in ("fill", "bars"):
        raise ObservationError(f"{where}: band must be 'fill' or 'bars', got {band!r}")
    fig, ax = _new_axes(ax, figsize)
    ax.grid(True, color="#dddddd", linewidth=0.6)
    counts: set[float] = set()
    for i, (label, (x, y)) in enumerate(series.items()):
        x = np.asarray(x, dtype=np.float64).ravel()
        y = np.asarray(y, dtype=np.float64)
        if y.shape[-1:] != x.shape or y.ndim not in (1, 2):
            raise ShapeMismatchError(
                f"{where}: series {label!r}: rmse has shape {y.shape}, expected ({x.size},) "
                f"or (R, {x.size}) for {x.size} GCP counts"
            )
        order = np.argsort(x)
        x = x[order]
        y = y[..., order]
        counts.update(x.tolist())
        colour = _SERIES_COLOURS[i % len(_SERIES_COLOURS)]
        marker = _SERIES_MARKERS[i % len(_SERIES_MARKERS)]
        if y.ndim == 2 and y.shape[0] > 1:
            ci = confidence_interval(y, level=ci_level or 0.95, method=ci_method)
            mean = np.asarray(ci.mean)
            (line,) = ax.plot(x, mean, marker=marker, color=colour,
                              label=f"{label} (mean of {y.shape[0]})")
            if ci_level is not None:
                low, high = np.asarray(ci.low), np.asarray(ci.high)
                if band == "fill":
                    ax.fill_between(x, low, high, color=line.get_color(), alpha=0.18, linewidth=0)
                else:
                    ax.errorbar(x, mean, yerr=[mean - low, high - mean], fmt="none",
                                ecolor=line.get_color(), capsize=3, linewidth=1)
        else:
            ax.plot(x, y.reshape(-1), marker=marker, color=colour, label=label)
    ticks = sorted(counts)
    if len(ticks) <= 15:
        ax.set_xticks(ticks)
        ax.set_xticklabels([f"{t:g}" for t in ticks])
    ax.set_ylim(bottom=0)
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    handles, labels = ax.get_legend_handles_labels()
    if ci_level is not None and any(np.ndim(y) == 2 and np.shape(y)[0] > 1
                                   for _, y in series.values()):
        of = "mean" if ci_method == "t" else "runs"
        labels.append(f"{ci_level:.0%} confidence interval ({of})")
        handles.append(Line2D([], [], color="grey", alpha=0.4,
                              linewidth=6 if band == "fill" else 1))
    ax.legend(handles, labels, fontsize=9, frameon=False)
    if title:
        ax.set_title(title, fontsize=11)
    return _finish(fig, path, dpi)


# --------------------------------------------------------------------------- residual vs distance
def residual_vs_distance(
    series: Mapping[str, tuple[ArrayLike, ArrayLike]],
    *,
    fit: bool = True,
    unit: str = "km",
    panels: bool = False,
    title: str | None = None,
    xlabel: str | None = None,
    ylabel: str = "2D residual at ICPs (m)",
    ax: Axes | None = None,
    figsize: tuple[float, float] | None = None,
    path: str | os.PathLike[str] | None = None,
    dpi: int = 150,
) -> Figure:
    """Residuals against the planimetric distance from the image centre (Aguilar et al. Fig. 4).

    Parameters
    ----------
    series : mapping of str to (distance, residual)
        Per model: distances from the image centre, metres
        (:func:`geoblock.adjust.distance_from_image_centre`), and residuals, metres (e.g.
        ``hypot(de, dn)`` at the ICPs), both ``(N,)``.
    fit : bool
        Draw the least-squares line ``residual = a + b * distance`` and give its slope and R²
        in the legend (Aguilar et al. found R² = 0.37 for RPCV-0).
    unit : {"km", "m"}
        Unit of the distance axis.
    panels : bool
        One panel per series (as Aguilar et al.'s (a)-(d)) instead of one shared axes.
    title, xlabel, ylabel, ax, figsize, path, dpi
        As :func:`error_vector_plot` (``ax`` only without ``panels``).

    Returns
    -------
    matplotlib.figure.Figure

    Raises
    ------
    ShapeMismatchError
        A series' arrays differ in length.
    ObservationError
        No series, an unknown ``unit``, or ``ax`` with ``panels``.
    """
    where = "residual_vs_distance"
    if not series:
        raise ObservationError(f"{where}: no series to plot")
    if unit not in ("km", "m"):
        raise ObservationError(f"{where}: unit must be 'km' or 'm', got {unit!r}")
    if panels and ax is not None:
        raise ObservationError(f"{where}: give either ax or panels=True, not both")
    factor = 1e-3 if unit == "km" else 1.0
    xlabel = xlabel or f"Distance from the image centre ({unit})"
    if panels:
        k = len(series)
        cols = min(k, 2)
        rows = math.ceil(k / cols)
        fig = Figure(figsize=figsize or (4.2 * cols, 3.4 * rows), layout="constrained")
        FigureCanvasAgg(fig)
        axes: list[Axes] = list(
            fig.subplots(rows, cols, sharex=True, sharey=True, squeeze=False).ravel())
        for j, extra in enumerate(axes[k:], start=k):
            extra.set_visible(False)
            axes[j - cols].xaxis.set_tick_params(labelbottom=True)  # the panel above it
    else:
        fig, single = _new_axes(ax, figsize or (6.4, 4.2))
        axes = [single] * len(series)
    for i, (label, (d, r)) in enumerate(series.items()):
        arr = _same_length(f"{where}: series {label!r}", distance=d, residual=r)
        x = arr["distance"] * factor
        y = arr["residual"]
        ok = np.isfinite(x) & np.isfinite(y)
        a_ = axes[i]
        colour = _SERIES_COLOURS[i % len(_SERIES_COLOURS)]
        marker = _SERIES_MARKERS[i % len(_SERIES_MARKERS)]
        a_.plot(x[ok], y[ok], linestyle="none", marker=marker, markersize=4.5, alpha=0.75,
                color=colour, label=f"{label} ({int(ok.sum())} points)")
        if fit and ok.sum() >= 3 and np.ptp(x[ok]) > 0:
            slope, intercept = np.polyfit(x[ok], y[ok], 1)
            pred = intercept + slope * x[ok]
            ss_tot = float(np.sum((y[ok] - y[ok].mean()) ** 2))
            r2 = 1.0 - float(np.sum((y[ok] - pred) ** 2)) / ss_tot if ss_tot > 0 else float("nan")
            xs = np.array([x[ok].min(), x[ok].max()])
            a_.plot(xs, intercept + slope * xs, color=colour, linewidth=1.5,
                    label=f"fit: slope {slope:.3f} m/{unit}, R² = {r2:.2f}")
        if panels:
            a_.set_title(label, fontsize=10)
    for a_ in (axes[: len(series)] if panels else axes[:1]):
        a_.grid(True, color="#dddddd", linewidth=0.6)
        a_.set_xlim(left=0)
        a_.set_ylim(bottom=0)
        a_.legend(fontsize=8, frameon=False, loc="upper left")
    if panels:
        fig.supxlabel(xlabel, fontsize=10)
        fig.supylabel(ylabel, fontsize=10)
        if title:
            fig.suptitle(title, fontsize=11)
    else:
        axes[0].set_xlabel(xlabel)
        axes[0].set_ylabel(ylabel)
        if title:
            axes[0].set_title(title, fontsize=11)
    return _finish(fig, path, dpi)


# --------------------------------------------------------------------------- correction curves
def correction_curve_plot(
    time_s: ArrayLike,
    value: ArrayLike,
    sigma: ArrayLike | None = None,
    truth: ArrayLike | None = None,
    *,
    axes_names: tuple[str, ...] = ("roll", "pitch", "yaw"),
    unit: str = "µrad",
    scale: float = 1e6,
    band: float = 2.0,
    title: str | None = None,
    xlabel: str = "Time from the image centre (s)",
    figsize: tuple[float, float] | None = None,
    path: str | os.PathLike[str] | None = None,
    dpi: int = 150,
) -> Figure:
    """A recovered correction against time, one panel per axis, with a sigma band and the truth.

    Parameters
    ----------
    time_s : array_like, (T,)
        Times, seconds (any origin; the axis is labelled by ``xlabel``).
    value : array_like, (T, A)
        The estimated correction per axis, in the unit of the data (radians for attitude).
    sigma : array_like, (T, A), optional
        Its posterior standard deviation; a band of ``+-band * sigma`` is shaded.
    truth : array_like, (T, A), optional
        The injected correction (simulated data), drawn dashed; the legend gives the RMS of
        ``value - truth`` per axis.
    axes_names : tuple of str, (A,)
        Panel titles.
    unit, scale : str, float
        The plotted unit and the factor from the data's unit to it (default radians to µrad).
    band : float
        Half-width of the shaded band in sigmas (default 2: ~95 %).
    title, xlabel, figsize, path, dpi
        As :func:`error_vector_plot`.

    Returns
    -------
    matplotlib.figure.Figure

    Raises
    ------
    ShapeMismatchError
        ``value``, ``sigma`` or ``truth`` is not (T, A) with ``T = len(time_s)`` and
        ``A = len(axes_names)``.
    """
    where = "correction_curve_plot"
    t = np.asarray(time_s, dtype=np.float64).ravel()
    k = len(axes_names)

    def as_table(name: str, a: ArrayLike | None) -> Float64Array | None:
        if a is None:
            return None
        arr = np.asarray(a, dtype=np.float64)
        if arr.ndim == 1 and k == 1:
            arr = arr[:, None]
        if arr.shape != (t.size, k):
            raise ShapeMismatchError(f"{where}: {name} must be ({t.size}, {k}) (times, axes), "
                                     f"got {arr.shape}")
        return arr * scale

    v = as_table("value", value)
    s = as_table("sigma", sigma)
    tr = as_table("truth", truth)
    assert v is not None
    fig = Figure(figsize=figsize or (7.0, 1.9 * k + 0.6), layout="constrained")
    FigureCanvasAgg(fig)
    panels: list[Axes] = list(fig.subplots(k, 1, sharex=True, squeeze=False).ravel())
    for i, (ax, name) in enumerate(zip(panels, axes_names, strict=True)):
        if s is not None:
            ax.fill_between(t, v[:, i] - band * s[:, i], v[:, i] + band * s[:, i],
                            color="#1f5fa8", alpha=0.2, linewidth=0,
                            label=f"±{band:g} σ (posterior)")
        ax.plot(t, v[:, i], color="#1f5fa8", linewidth=1.4, label="recovered")
        if tr is not None:
            ok = np.isfinite(tr[:, i]) & np.isfinite(v[:, i])
            rms = float(np.sqrt(np.mean((v[ok, i] - tr[ok, i]) ** 2))) if ok.any() else np.nan
            ax.plot(t, tr[:, i], color="#c0392b", linewidth=1.2, linestyle="--",
                    label=f"truth (recovered − truth: {rms:.3g} {unit} RMS)")
        ax.set_ylabel(f"{name} ({unit})", fontsize=9)
        ax.grid(True, color="#dddddd", linewidth=0.6)
        ax.legend(fontsize=7, frameon=False, loc="upper right")
    panels[-1].set_xlabel(xlabel)
    if title:
        fig.suptitle(title, fontsize=11)
    return _finish(fig, path, dpi)
