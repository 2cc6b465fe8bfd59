"""The report of a block adjustment: what ``geoblock adjust`` writes (adjusted models,
``report.json``, ``report.md`` and plots).

:func:`result_dict` is the JSON-safe content of a :class:`~geoblock.adjust.BlockResult`;
:func:`report_markdown` the papers' tables (GCP/ICP RMSE E/N per image, ICTP relative
accuracy per overlap, single versus block); :func:`write_result` writes everything into a
directory atomically (:func:`geoblock.io.files.atomic_directory`): into a temporary sibling
first, renamed into place only when every file is written, so a failure leaves nothing
half-written under the output directory.

Moved here from ``geoblock.adjust.output`` (geoblock 0.2): the adjustment engine computes, the
report presents.
"""

from __future__ import annotations

import math
import os
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from geoblock.adjust.accuracy import AccuracyStatement
from geoblock.adjust.block import BlockResult
from geoblock.adjust.statistics import AccuracyStats, ImageResidualStats
from geoblock.io import files
from geoblock.io.models import write_model
from geoblock.models.curves import CorrectionCurve, HasCorrectionCurves
from geoblock.models.uncertainty import ModelPosterior
from geoblock.report.figures import correction_curve_plot, error_vector_plot, to_local_en
from geoblock.report.tables import stats_table
from geoblock.typing import ArrayLike

__all__ = ["accuracy_statements", "check_output_directory", "correction_curves",
           "correction_figure",
           "image_residuals", "report_markdown", "result_dict", "write_result"]

#: Plotting unit and factor of a correction curve's unit (others plot as they are).
_DISPLAY_UNITS: dict[str, tuple[str, float]] = {"rad": ("µrad", 1e6), "m": ("m", 1.0)}


def _f(x: Any) -> Any:
    """JSON-safe float (None for NaN/inf)."""
    x = float(x)
    return x if math.isfinite(x) else None


def _stats(st: AccuracyStats) -> dict[str, Any]:
    return {k: (_f(v) if isinstance(v, float) else v) for k, v in st.as_dict().items()}


def result_dict(result: BlockResult, single: BlockResult | None = None) -> dict[str, Any]:
    """JSON-safe report of a block adjustment (and of a single adjustment to compare with)."""
    m = result.measurements
    p = result.points
    sources = result._check_sources()
    pred_cov = result.predicted_covariance
    out: dict[str, Any] = {
        "mode": result.mode, "dem_control": result.dem_control, "robust": result.robust,
        "converged": result.converged, "iterations": result.iterations,
        "sigma0": _f(result.sigma0), "dof": result.dof, "solver": result.solver,
        "history": [{k: (_f(v) if isinstance(v, float) else v) for k, v in h.items()}
                    for h in result.history],
        "notes": list(result.notes),
        "parameters": {
            image: [{"name": n, "unit": u, "prior": _f(a), "value": _f(v),
                     "prior_sigma": _f(ps), "sigma": _f(s)}
                    for n, u, a, v, ps, s in zip(e.names, e.units, e.prior, e.values,
                                                 e.prior_sigmas, e.sigmas, strict=True)]
            for image, e in result.parameters.items()},
        "statistics": _statistics(result),
        "measurements": [
            {"id": str(m.id[i]), "image": str(m.image[i]), "kind": str(m.kind[i]),
             "row": _f(m.row[i]), "col": _f(m.col[i]), "v_row": _f(m.v_row[i]),
             "v_col": _f(m.v_col[i]), "weight": _f(m.weight[i]),
             "redundancy_row": _f(m.redundancy_row[i]),
             "redundancy_col": _f(m.redundancy_col[i]), "test": _f(m.test[i]),
             "flagged": bool(m.flagged[i]), "ambiguous": bool(m.ambiguous[i])}
            for i in range(len(m.id))],
        "points": [
            {"id": str(p.id[j]), "kind": str(p.kind[j]), "lon": _f(p.lon[j]),
             "lat": _f(p.lat[j]), "h": _f(p.h[j]), "images": int(p.images[j]),
             "dem_height": _f(p.dem_height[j]), "status": str(p.status[j]),
             "covariance_enu_m2": [[_f(v) for v in row] for row in p.covariance[j]]}
            for j in range(len(p.id))],
        "check_points": [
            {"id": str(result.check.id[i]), "image": str(result.check.image[i]),
             "kind": str(result.check.kind[i]).lower(), "source": str(sources[i]),
             "e": _f(result.check.e[i]),
             "n": _f(result.check.n[i]), "predicted_sigma_e": _f(result.predicted_sigma[i, 0]),
             "predicted_sigma_n": _f(result.predicted_sigma[i, 1]),
             "predicted_covariance_en_m2": None if pred_cov is None
             else [[_f(v) for v in row] for row in pred_cov[i]]}
            for i in range(len(result.check.id))],
        "source_shifts": {
            key: {"source": sh.source, "solution": sh.solution, "n_points": sh.n_points,
                  "centroid": {"lon": _f(sh.lon), "lat": _f(sh.lat), "h": _f(sh.h)},
                  **{f"shift_{a}_m": _f(v) for a, v in zip("enh", sh.values, strict=True)},
                  **{f"sigma_{a}_m": _f(v) for a, v in zip("enh", sh.sigmas, strict=True)},
                  **{f"prior_sigma_{a}_m": _f(v)
                     for a, v in zip("enh", sh.prior_sigmas, strict=True)}}
            for key, sh in result.shifts.items()},
        "accuracy_statements": {
            ("block" if st.image is None else f"image:{st.image}"): {
                k: (_f(v) if isinstance(v, float) else v) for k, v in st.as_dict().items()}
            for st in accuracy_statements(result)},
    }
    if result.hcp is not None:
        h = result.hcp
        out["height_control"] = {
            "statistics": {k: (_f(v) if isinstance(v, float) else v)
                           for k, v in h.stats().items()},
            "points": [{"id": str(h.id[j]), "source": str(h.source[j]),
                        "observed_h": _f(h.observed[j]), "adjusted_h": _f(h.adjusted[j]),
                        "residual_m": _f(h.residual[j]), "sigma_h": _f(h.sigma[j]),
                        "posterior_sigma_h": _f(h.posterior_sigma[j])}
                       for j in range(len(h))]}
    if result.vertical is not None:
        v = result.vertical
        out["vertical_check"] = [
            {"id": str(v.id[j]), "rays": int(v.rays[j]), "e": _f(v.e[j]), "n": _f(v.n[j]),
             "u": _f(v.u[j]), "predicted_sigma_u": _f(v.sigma_up[j])} for j in range(len(v))]
    if single is not None:
        out["single"] = {"sigma0": _f(single.sigma0), "statistics": _statistics(single)}
    return out


def _statistics(result: BlockResult) -> dict[str, Any]:
    out: dict[str, Any] = {}
    for kind in ("gcp", "icp"):
        out[kind] = {image: _stats(st) for image, st in result.stats_by_image(kind).items()}
        out[f"{kind}_by_source"] = {source: _stats(st) for source, st in
                                    result.stats_by_source(kind).items()}
    out["ictp"] = {f"{a} & {b}": _stats(st) for (a, b), st in result.ictp_by_pair().items()}
    residuals: dict[str, dict[str, Any]] = {}
    for (image, kind), st in image_residuals(result).items():
        residuals.setdefault(image, {})[kind] = {k: _f(v) if isinstance(v, float) else v
                                                 for k, v in vars(st).items()}
    out["image_residuals_px"] = residuals
    return out


def accuracy_statements(result: BlockResult) -> list[AccuracyStatement]:
    """:meth:`BlockResult.accuracy_statement <geoblock.adjust.BlockResult.accuracy_statement>`
    of every image that has ICP measurements or a grid prediction, then of the block."""
    images = [i for i in result.models
              if np.any((result.check.image == i) & (result.check.kind == "ICP"))
              or i in result.grid_covariance]
    return [*(result.accuracy_statement(i) for i in images), result.accuracy_statement()]


def _value(x: float) -> str:
    return f"{x:.2f}" if math.isfinite(x) else "n/a"


def _accuracy_table(result: BlockResult) -> list[str]:
    rows = accuracy_statements(result)
    if not rows or (rows[-1].n_icp == 0 and not math.isfinite(rows[-1].ce90_grid)):
        return ["## Accuracy statements (NSSDA)", "",
                "No ICP and no DEM: the accuracy cannot be stated (add independent check "
                "points).", ""]
    lines = ["## Accuracy statements (NSSDA)", "",
             "Metres. **Predicted**: from the posterior covariance (each ICP measurement's "
             "east/north covariance, parameters, image measurement and survey errors; the "
             "radius holding 90 % / 95 % of the population of errors). **Empirical**: the "
             "90th / 95th percentile of the ICPs' radial errors; **NSSDA**: 2.1460 / 2.4477 x "
             "RMSE_r / sqrt(2) (FGDC-STD-007.3-1998). LE90: ICPs measured in two images or "
             "more, intersected through the adjusted models; predicted by first-order "
             "propagation of the image noise and the parameters' posterior covariance. **CE90 "
             "grid**: predicted over a 9 x 9 grid of each image's points on the DEM (the "
             "parameters' posterior and the DEM's sigma, no measurement error: what an ortho "
             "pixel carries), needing no ICP.", "",
             "| image | n ICP | CE90 predicted | CE90 empirical (percentile) | CE90 NSSDA | "
             "CE95 predicted | CE95 empirical | n LE | LE90 predicted | LE90 empirical | "
             "CE90 grid |",
             "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|"]
    notes = []
    for st in rows:
        label = "**block**" if st.image is None else st.image
        lines.append(f"| {label} | {st.n_icp} | {_value(st.ce90_predicted)} | "
                     f"{_value(st.ce90_empirical)} | {_value(st.ce90_nssda)} | "
                     f"{_value(st.ce95_predicted)} | {_value(st.ce95_empirical)} | {st.n_le} | "
                     f"{_value(st.le90_predicted)} | {_value(st.le90_empirical)} | "
                     f"{_value(st.ce90_grid)} |")
        if st.reason:
            notes.append(f"- {'block' if st.image is None else st.image}: {st.reason}")
    return lines + [""] + notes + ([""] if notes else [])


def _source_tables(result: BlockResult) -> list[str]:
    lines: list[str] = []
    for kind in ("gcp", "icp"):
        rows = result.stats_by_source(kind)
        if rows and set(rows) != {"survey"}:
            lines += [f"**{kind.upper()}s by source** (reference control apart from surveyed "
                      "points)", "", *_table(rows, "source"), ""]
    if result.shifts:
        lines += ["## Common error of each control source", "",
                  "The error shared by all control points of a source (a reference "
                  "orthoimage's misregistration), a translation along local east, north and "
                  "up at the source's centroid (metres; its a-priori sigma from the ground "
                  "file's sigma_shift_e/n/h). Solution *considered* (the default): the block "
                  "is registered to the source and the shift's sigma is propagated into every "
                  "posterior figure; otherwise estimated in that solution.", "",
                  "| source | solution | points | shift E | shift N | shift H | sigma E | "
                  "sigma N | sigma H | prior sigma E/N/H |",
                  "|---|---|---:|---:|---:|---:|---:|---:|---:|---|"]
        for sh in result.shifts.values():
            v, sg, ps = sh.values, sh.sigmas, sh.prior_sigmas
            lines.append(f"| {sh.source} | {sh.solution} | {sh.n_points} | {v[0]:.3f} | "
                         f"{v[1]:.3f} | {v[2]:.3f} | {sg[0]:.3f} | {sg[1]:.3f} | {sg[2]:.3f} | "
                         f"{ps[0]:.3g} / {ps[1]:.3g} / {ps[2]:.3g} |")
        lines.append("")
    h = result.hcp
    if h is not None and len(h):
        st = h.stats()
        lines += ["## Height control points", "",
                  "Observed minus adjusted height of the HCPs (tie points whose height is "
                  "observed), metres.", "",
                  "| n | RMSE | mean | max | RMS residual / sigma_h |",
                  "|---:|---:|---:|---:|---:|",
                  f"| {st['n']} | {st['rmse']:.3f} | {st['mean']:.3f} | {st['max']:.3f} | "
                  f"{st['rms_normalised']:.3f} |", ""]
    return lines


def image_residuals(result: BlockResult) -> dict[tuple[str, str], ImageResidualStats]:
    """Image residuals (observed minus computed, pixels) per image and measurement kind
    (``gcp``, ``icp``, ``tp``; ICTPs have none), then, for an image with more than one kind,
    over all of them (``all``)."""
    m = result.measurements
    finite = np.isfinite(m.v_row) & np.isfinite(m.v_col)
    out: dict[tuple[str, str], ImageResidualStats] = {}
    for image in result.models:
        mine = (m.image == image) & finite
        for kind in ("gcp", "icp", "tp"):
            sel = mine & (m.kind == kind)
            if sel.any():
                out[(image, kind)] = ImageResidualStats.from_residuals(m.v_row[sel],
                                                                       m.v_col[sel])
        if len({k for (i, k) in out if i == image}) > 1:
            out[(image, "all")] = ImageResidualStats.from_residuals(m.v_row[mine],
                                                                    m.v_col[mine])
    return out


def correction_curves(result: BlockResult, image: str, *, samples: int = 200,
                      detrend: bool = True) -> tuple[CorrectionCurve, ...]:
    """The time-dependent corrections an adjustment recovered for one image, with their
    posterior bands.

    Any adjusted model that implements
    :class:`~geoblock.models.curves.HasCorrectionCurves` (a linescan model with the
    ``"jitter"`` set, also inside a crop or a collocation correction) gives its curves,
    computed with :meth:`BlockResult.parameter_covariance
    <geoblock.adjust.BlockResult.parameter_covariance>`; other models give ``()``.

    Parameters
    ----------
    result : BlockResult
    image : str
        An image of ``result.models``.
    samples : int
        Samples over the image's rows.
    detrend : bool
        Take the least-squares line in time out of each curve and its band (default): the
        constant and the trend of an attitude correction trade with the position offsets, so
        their band is as wide as the priors allow, while the rest (the wander) is what the
        image measurements fix.

    Returns
    -------
    tuple of CorrectionCurve

    Raises
    ------
    KeyError
        ``image`` is not in the block.
    """
    names, cov = result.parameter_covariance(image)
    model = result.models[image]
    if not isinstance(model, HasCorrectionCurves):
        return ()
    return tuple(model.correction_curves(cov, names, samples=samples, detrend=detrend))


def correction_figure(curve: CorrectionCurve, truth: ArrayLike | None = None, *,
                      title: str | None = None, band: float = 2.0,
                      path: str | os.PathLike[str] | None = None) -> Any:
    """:func:`~geoblock.report.figures.correction_curve_plot` of a :class:`CorrectionCurve`:
    against the time from the image's centre row, radians shown as µrad, with its
    ``+-band`` sigma band.

    Parameters
    ----------
    curve : CorrectionCurve
        E.g. from :func:`correction_curves`.
    truth : array_like, (T, A), optional
        The injected correction at ``curve.time_s`` in ``curve.unit`` (simulated data); it is
        detrended like the curve (:meth:`CorrectionCurve.compare
        <geoblock.models.curves.CorrectionCurve.compare>`).
    title : str, optional
    band : float
        Half-width of the band, sigmas.
    path : path-like, optional
        Save the figure there.

    Returns
    -------
    matplotlib.figure.Figure
    """
    unit, scale = _DISPLAY_UNITS.get(curve.unit, (curve.unit, 1.0))
    sigma = np.where(np.isfinite(curve.sigmas), curve.sigmas, np.nan)
    return correction_curve_plot(
        curve.time_s - curve.centre_s, curve.values, sigma,
        None if truth is None else curve.compare(truth), axes_names=curve.axes, unit=unit,
        scale=scale, band=band,
        title=title or f"{curve.quantity} correction"
        + (" (detrended)" if curve.detrended else ""), path=path)


def _curve_table(result: BlockResult) -> list[str]:
    rows = []
    for image in result.models:
        for c in correction_curves(result, image):
            unit, scale = _DISPLAY_UNITS.get(c.unit, (c.unit, 1.0))
            for k, axis in enumerate(c.axes):
                v, s = c.values[:, k] * scale, c.sigmas[:, k] * scale
                rows.append(f"| {image} | {c.quantity} | {axis} | {unit} | "
                            f"{math.sqrt(float(np.mean(v**2))):.3g} | "
                            f"{float(np.max(np.abs(v))):.3g} | {float(np.median(s)):.3g} |")
    if not rows:
        return []
    return ["## Time-dependent corrections", "",
            "The corrections that vary along the image in time (e.g. a linescan model's "
            "\"jitter\" set), detrended: the least-squares line in time is taken out, since "
            "their constant and trend trade with the position offsets. Figures below.", "",
            "| image | correction | axis | unit | RMS | max abs | median sigma |",
            "|---|---|---|---|---:|---:|---:|", *rows, ""]


def _residual_table(result: BlockResult) -> list[str]:
    rows = image_residuals(result)
    if not rows:
        return []
    lines = ["## Image residuals", "",
             "Observed minus computed with the adjusted models, pixels (ICPs: at their surveyed "
             "ground point, so they carry the check error too).", "",
             "| image | kind | n | RMS row | RMS col | RMS 2D | mean row | mean col | max 2D |",
             "|---|---|---:|---:|---:|---:|---:|---:|---:|"]
    for (image, kind), s in rows.items():
        lines.append(f"| {image} | {kind.upper() if kind != 'all' else 'all'} | {s.n} | "
                     f"{s.rmse_row:.3f} | {s.rmse_col:.3f} | {s.rmse_2d:.3f} | "
                     f"{s.mean_row:.3f} | {s.mean_col:.3f} | {s.max_2d:.3f} |")
    return lines + [""]


def _table(rows: Mapping[str, AccuracyStats], label: str) -> list[str]:
    return stats_table(rows, labels=(label,)).rstrip("\n").splitlines()


def report_markdown(result: BlockResult, single: BlockResult | None = None, *,
                    title: str = "Block adjustment", figures: Mapping[str, str] | None = None
                    ) -> str:
    """The Markdown report: convergence, parameters, the papers' accuracy tables, flags."""
    r = result
    lines = [f"# {title}", "",
             f"Mode **{r.mode}**, DEM control **{r.dem_control}**, robust **{r.robust}**: "
             f"{'converged' if r.converged else '**NOT converged**'} in {r.iterations} "
             f"iterations; sigma0 = {r.sigma0:.4g} with {r.dof} degrees of freedom.", ""]
    if r.solver:
        lines += [f"Normal equations: {r.solver}.", ""]
    for note in r.notes:
        lines.append(f"- {note}")
    if r.notes:
        lines.append("")
    if r.check is not None and len(r.check.id):
        lines += ["## Accuracy at control and check points", "",
                  "Errors: the measured image point located at the point's surveyed height "
                  "through the adjusted model, minus the surveyed point (metres, local east E "
                  "and north N).", ""]
    for kind in ("gcp", "icp"):
        rows = r.stats_by_image(kind)
        if rows:
            lines += [f"**{kind.upper()}s**", "", *_table(rows, "image"), ""]
    if r.check is not None and len(r.check.id):
        icp = np.char.lower(r.check.kind.astype(str)) == "icp"
        if icp.any():
            actual = math.sqrt(np.nanmean(r.check.e[icp] ** 2 + r.check.n[icp] ** 2))
            predicted = math.sqrt(np.nanmean(np.sum(r.predicted_sigma[icp] ** 2, axis=1)))
            lines += [f"ICP RMSE 2D {actual:.2f} m; the posterior covariance predicts "
                      f"{predicted:.2f} m (parameters, image measurement and survey errors).",
                      ""]
    lines += _source_tables(r)
    if r.check is not None:
        lines += _accuracy_table(r)
    pairs = r.ictp_by_pair()
    if pairs:
        lines += ["## Relative accuracy at ICTPs", "",
                  "Each ICTP measurement ray-traced onto the DEM through its adjusted model; "
                  "the discrepancy is the distance between the two ground points.", "",
                  *_table({f"{a} & {b}": st for (a, b), st in pairs.items()}, "overlap"), ""]
    if single is not None:
        lines += ["## Single versus block adjustment", "",
                  "| quantity | single | block |", "|---|---:|---:|"]
        for kind in ("gcp", "icp"):
            s_rows, b_rows = single.stats_by_image(kind), r.stats_by_image(kind)
            for image in b_rows:
                if image in s_rows:
                    lines.append(f"| {kind.upper()} RMSE 2D {image} (m) | "
                                 f"{s_rows[image].rmse_2d:.2f} | {b_rows[image].rmse_2d:.2f} |")
        s_pairs = single.ictp_by_pair()
        for key, st in pairs.items():
            if key in s_pairs:
                lines.append(f"| ICTP RMSE 2D {key[0]} & {key[1]} (m) | "
                             f"{s_pairs[key].rmse_2d:.2f} | {st.rmse_2d:.2f} |")
        lines.append("")
    lines += _residual_table(r)
    lines += _curve_table(r)
    lines += ["## Parameters", ""]
    for image, e in r.parameters.items():
        if not e.names:
            lines += [f"**{image}**: no adjusted parameter (held fixed).", ""]
            continue
        lines += [f"**{image}**", "", "| parameter | unit | a priori | sigma a priori | adjusted "
                  "| sigma |", "|---|---|---:|---:|---:|---:|"]
        for n, u, a, ps, v, s in zip(e.names, e.units, e.prior, e.prior_sigmas, e.values,
                                     e.sigmas, strict=True):
            lines.append(f"| {n} | {u} | {a:.6g} | {ps:.3g} | {v:.6g} | {s:.3g} |")
        lines.append("")
    m = r.measurements
    if m.flagged.any():
        lines += ["## Measurements flagged as blunders", "",
                  "| point | image | kind | v row (px) | v col (px) | test | note |",
                  "|---|---|---|---:|---:|---:|---|"]
        for i in np.flatnonzero(m.flagged)[:200]:
            note = "two rays: not attributable" if m.ambiguous[i] else ""
            lines.append(f"| {m.id[i]} | {m.image[i]} | {m.kind[i]} | {m.v_row[i]:.2f} | "
                         f"{m.v_col[i]:.2f} | {m.test[i]:.1f} | {note} |")
        lines.append("")
    lines += ["## Iterations", "", "| iteration | sigma0 | max step (sigma) | damping | "
              "rejected |", "|---:|---:|---:|---:|---:|"]
    for h in r.history:
        lines.append(f"| {h['iteration']} | {h['sigma0']:.4g} | {h['max_step_sigma']:.3g} | "
                     f"{h['damping']:.3g} | {h['rejected']} |")
    lines.append("")
    if figures:
        lines += ["## Figures", ""]
        for caption, name in figures.items():
            lines += [f"![{caption}]({name})", ""]
    return "\n".join(lines)


def _figures(result: BlockResult, folder: Path) -> dict[str, str]:
    out: dict[str, str] = {}
    chk = result.check
    if chk is not None and len(chk.id):
        m = result.measurements
        for image in result.models:
            sel = chk.image == image
            if not sel.any():
                continue
            # positions: the measured points located through the adjusted model
            rows = np.isin(m.id, chk.id[sel]) & (m.image == image) & np.isin(
                m.kind, ("gcp", "icp"))
            model = result.models[image]
            g = model.backproject(m.row[rows], m.col[rows], 0.0)
            e, n = to_local_en(g.lon, g.lat)
            # align the rows of the measurements with those of the check table
            order = {p: k for k, p in enumerate(m.id[rows].tolist())}
            k = np.array([order[p] for p in chk.id[sel].tolist()])
            name = f"errors_{image}.png"
            error_vector_plot(e[k], n[k], chk.e[sel], chk.n[sel], chk.kind[sel],
                              title=f"{image}: GCP and ICP errors after adjustment",
                              path=folder / name)
            out[f"errors at GCPs and ICPs, {image}"] = name
    m = result.measurements
    for image in result.models:
        sel = (m.image == image) & np.isfinite(m.v_row) & np.isfinite(m.v_col)
        if not sel.any():
            continue
        name = f"residuals_{image}.png"
        error_vector_plot(m.col[sel], m.row[sel], m.v_col[sel], m.v_row[sel],
                          np.char.upper(m.kind[sel].astype(str)),
                          title=f"{image}: image residuals after adjustment",
                          xlabel="col (px)", ylabel="row (px)", unit="px", y_down=True,
                          path=folder / name)
        out[f"image residuals, {image}"] = name
    for image in result.models:
        for curve in correction_curves(result, image):
            name = f"corrections_{image}_{curve.quantity}.png"
            correction_figure(curve, title=f"{image}: {curve.quantity} correction after "
                              "adjustment (detrended), ±2 σ posterior", path=folder / name)
            out[f"{curve.quantity} correction against time, {image}"] = name
    ictp = result.ictp
    if ictp is not None and len(ictp):
        e, n = to_local_en(ictp.lon_a, ictp.lat_a)
        name = "ictp_discrepancies.png"
        error_vector_plot(e, n, ictp.e, ictp.n, "ICTP", title="ICTP discrepancies between images",
                          path=folder / name)
        out["ICTP discrepancies"] = name
    return out


def _previous_output(entry: Path) -> bool:
    """An entry :func:`write_result` writes (so a previous output may be replaced)."""
    if entry.name == "models":
        return entry.is_dir() and not entry.is_symlink() and all(
            m.suffix == ".json" and m.is_file() for m in entry.iterdir())
    return entry.is_file() and (entry.name in ("report.json", "report.md")
                                or entry.suffix == ".png")


def check_output_directory(out_dir: str | os.PathLike[str]) -> None:
    """Refuse, before the adjustment runs, an ``out_dir`` :func:`write_result` would not replace.

    Raises
    ------
    OutputDirectoryError
        ``out_dir`` holds anything but a previous adjustment's output (names one entry).
    """
    files.check_replaceable(out_dir, "adjustment output ", replaces=_previous_output)


def write_result(result: BlockResult, out_dir: str | os.PathLike[str], *,
                 single: BlockResult | None = None, title: str = "Block adjustment",
                 figures: bool = True) -> dict[str, Path]:
    """Write ``models/<image>.json``, ``report.json``, ``report.md`` and the PNG figures.

    Each model JSON carries its posterior covariance (a ``"posterior"`` entry,
    :class:`~geoblock.models.uncertainty.ModelPosterior`), which
    ``geoblock ortho --accuracy-layer`` propagates to the ground.

    The files are written into a temporary directory beside ``out_dir`` and moved into place
    at the end (:func:`geoblock.io.files.atomic_directory`), so an error leaves ``out_dir``
    as it was. An existing ``out_dir`` is replaced as a whole, and so only when it is empty
    or a previous adjustment output (``models/``, ``report.json``, ``report.md``, PNG
    figures and nothing else).

    Raises
    ------
    OutputDirectoryError
        ``out_dir`` holds anything else (named): nothing is deleted.

    Returns
    -------
    dict of str to pathlib.Path
        What was written, by name.
    """
    out = Path(out_dir)
    written: dict[str, Path] = {}
    with files.atomic_directory(out, "adjustment output ", replaces=_previous_output) as tmp:
        files.make_directory(tmp / "models")
        for image, model in result.models.items():
            # the posterior covariance travels with the model: geoblock ortho
            # --accuracy-layer propagates it (geoblock.models.uncertainty)
            posterior = ModelPosterior.from_block_result(result, image,
                                                         source=f"geoblock adjust: {title}")
            write_model(model, tmp / "models" / f"{image}.json", posterior=posterior)
            written[f"model:{image}"] = out / "models" / f"{image}.json"
        figs = _figures(result, tmp) if figures else {}
        for name in figs.values():
            written[f"figure:{name}"] = out / name
        files.write_json(tmp / "report.json", result_dict(result, single), indent=1)
        written["report.json"] = out / "report.json"
        files.write_text(tmp / "report.md",
                         report_markdown(result, single, title=title, figures=figs))
        written["report.md"] = out / "report.md"
    return written
