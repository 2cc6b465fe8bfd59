"""``geoblock refine``: an image-space correction (RPCV-0, RPCV-1, order 2) fitted to GCPs.

Generic: MODEL is any registered sensor model; it is wrapped in
:class:`~geoblock.models.corrections.ImageCorrection` and fitted by
:func:`geoblock.adjust.resect`. The refined model is written as geoblock model JSON and, on
request, in other formats through :func:`geoblock.write_model` — the plugins decide whether
they can write the refined model in their format (for example an RPC00B file for a corrected
RPC) and their messages (a warning such as a fold/refit report) are printed with the result.
"""

from __future__ import annotations

import warnings
from pathlib import Path

import click
import numpy as np

from geoblock.cli.options import model_arg, model_name_opt, open_model_arg

__all__ = ["refine"]


def _write_spec(ctx: click.Context, param: click.Parameter, values: tuple[str, ...]):
    """``FORMAT:PATH`` -> ``(format, path)``; a bare PATH infers the format from its suffix."""
    out = []
    for value in values:
        fmt, sep, path = value.partition(":")
        if not sep:
            fmt, path = None, value
        if (sep and not fmt.strip()) or not path.strip():
            raise click.BadParameter(
                f"expected FORMAT:PATH (for example json:out.json), got {value!r}"
            )
        out.append((fmt.strip() if fmt else None, path))
    return tuple(out)


def _read_control(path: str, sigma_px: float):
    from geoblock.adjust import ControlPoints
    from geoblock.io import read_points

    columns = read_points(path, required=("lon", "lat", "h", "row", "col"))
    return ControlPoints.from_columns(columns, sigma_row=sigma_px, sigma_col=sigma_px), columns


def _split_kinds(path: str, sigma_px: float):
    from geoblock.errors import ObservationError

    points, columns = _read_control(path, sigma_px)
    if "kind" not in columns:
        raise ObservationError(f"{path}: --points needs a 'kind' column (gcp or icp)")
    kind = np.char.lower(np.char.strip(np.asarray(columns["kind"], dtype=str)))
    bad = ~np.isin(kind, ("gcp", "icp"))
    if bad.any():
        listed = ", ".join(points.id[bad][:5])
        raise ObservationError(f"{path}: kind must be gcp or icp (points {listed})")
    icp = kind == "icp"
    return points.subset(~icp), (points.subset(icp) if icp.any() else None)


def _stats_table(result) -> list[str]:
    lines = [
        "Accuracy (metres; errors = located - surveyed, along local east E and north N):",
        f"{'set':4s} {'n':>4s} {'RMSE E':>9s} {'RMSE N':>9s} {'RMSE 2D':>9s} {'mean E':>9s}"
        f" {'mean N':>9s} {'max E':>9s} {'max N':>9s}",
    ]
    for label, res in (("GCP", result.gcp), ("ICP", result.icp)):
        if res is None:
            continue
        s = res.stats
        lines.append(
            f"{label:4s} {s.n:4d} {s.rmse_e:9.3f} {s.rmse_n:9.3f} {s.rmse_2d:9.3f} "
            f"{s.mean_e:9.3f} {s.mean_n:9.3f} {s.max_e:9.3f} {s.max_n:9.3f}"
        )
    return lines


@click.command(short_help="Fit an image correction (RPCV-0/RPCV-1/order 2) to GCPs.")
@model_arg
@click.option("--gcps", "gcps_path", metavar="GCPS.csv", default=None,
              help="Ground control points: id, lon, lat, h, row, col[, sigma_row, sigma_col, "
              "sigma_e, sigma_n, sigma_h].")
@click.option("--icps", "icps_path", metavar="ICPS.csv", default=None,
              help="Independent check points (same columns): accuracy only, not fitted.")
@click.option("--points", "points_path", metavar="POINTS.csv", default=None,
              help="One file with a 'kind' column (gcp or icp) instead of --gcps/--icps.")
@click.option("--order", type=click.IntRange(0, 2), default=1, show_default=True,
              help="0: shift (RPCV-0, >= 1 GCP); 1: affine (RPCV-1, >= 3 GCPs); "
              "2: quadratic (>= 6 GCPs).")
@model_name_opt
@click.option("--sigma-px", type=click.FloatRange(min=0.0, min_open=True), default=0.5,
              show_default=True,
              help="Image measurement sigma (pixels) of points without sigma_row/sigma_col.")
@click.option("-o", "--output", metavar="OUT.json", default=None,
              help="Refined model as geoblock JSON; default MODEL's folder and stem "
              "+ '.refined.json'.")
@click.option("--write", "writes", metavar="FORMAT:PATH", multiple=True, callback=_write_spec,
              help="Also write the refined model in FORMAT (a plugin's writer, e.g. rpc-txt); "
              "repeatable.")
def refine(model_path, gcps_path, icps_path, points_path, order, model_name, sigma_px, output,
           writes) -> None:
    """Refine MODEL with an image-space correction fitted to ground control points.

    MODEL (any registered sensor model) is wrapped in a polynomial correction of its image
    coordinates, in u, v = (row, col - image centre) / (half the larger image side):
    order 0 shifts (RPCV-0), order 1 is affine (RPCV-1), order 2 quadratic. The coefficients
    (pixels) are fitted to the GCPs by weighted least squares; the command prints the
    coefficients with their sigmas, the GCP residuals and the accuracy at GCPs and ICPs
    (RMSE E, N and 2D, mean and signed maximum error, metres: Aguilar et al.'s Table 3),
    then writes the refined model.

    Point files are CSV with a header (lon, lat in degrees, h in metres above the WGS84
    ellipsoid, row, col in pixels with 0 the centre of the first pixel).

    \b
    Examples:
      geoblock refine scene.json --gcps gcps.csv --icps icps.csv --order 1
      geoblock refine scene_RPC.TXT --points points.csv --order 0 -o scene.rpcv0.json \\
          --write rpc-txt:scene_refined_RPC.TXT
    """
    from geoblock.adjust import resect
    from geoblock.io import write_model
    from geoblock.models.corrections import ImageCorrection

    if points_path is not None and (gcps_path or icps_path):
        raise click.UsageError("give either --points or --gcps/--icps, not both")
    if points_path is None and gcps_path is None:
        raise click.UsageError("missing --gcps GCPS.csv (or --points with a kind column)")

    model = open_model_arg(model_path, model_name)
    if points_path is not None:
        gcps, icps = _split_kinds(points_path, sigma_px)
    else:
        gcps, _ = _read_control(gcps_path, sigma_px)
        icps = _read_control(icps_path, sigma_px)[0] if icps_path else None

    result = resect(ImageCorrection(model, order), gcps, icps)
    refined = result.model

    lines = [result.report(), "", *_stats_table(result), ""]
    click.echo("\n".join(lines))

    if output is None:
        src = Path(model_path)
        output = str(src.with_name(f"{src.stem}.refined.json"))
    written = write_model(refined, output, format="json")
    click.echo(f"refined model written to {written} (json)")
    for fmt, path in writes:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            written = write_model(refined, path, format=fmt)
        click.echo(f"refined model written to {written} ({fmt or 'from suffix'})")
        for w in caught:
            text = " ".join(str(w.message).split())
            click.echo(f"  {text}")
