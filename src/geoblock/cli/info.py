"""``geoblock info``: what a sensor model is, where it looks and at what resolution."""

from __future__ import annotations

import json
import math
from typing import TYPE_CHECKING, Any

import click

from geoblock.cli.options import (
    deprecated_aliases,
    json_opt,
    model_arg,
    model_type_opt,
    open_model_arg,
)

if TYPE_CHECKING:
    from geoblock.models.protocol import SensorModel

__all__ = ["info", "model_info"]

_CORNERS = ("top-left", "top-right", "bottom-right", "bottom-left")


def _num(value: float) -> float | None:
    """JSON-safe float: ``None`` for NaN and infinities."""
    value = float(value)
    return value if math.isfinite(value) else None


def model_info(model: SensorModel, h: float | None = None) -> dict[str, Any]:
    """The facts ``geoblock info`` reports about ``model``, JSON-safe.

    Uses only the :class:`~geoblock.models.SensorModel` protocol.

    Parameters
    ----------
    model : SensorModel
    h : float, optional
        Height of the footprint and the ground sample distance, metres above the ellipsoid;
        default the middle of ``model.height_range``.

    Returns
    -------
    dict
        ``model``, ``shape`` ``{rows, cols, stated}`` (``stated`` False when the model's file
        gives no image size and the shape is the extent the model was fitted over),
        ``height_range``, ``parameters`` (name, value,
        unit, sigma - ``None`` for free -, adjustable), ``footprint`` (``h`` and the four
        outer pixel-edge corners with row, col, lon, lat, clockwise from top-left) and
        ``gsd`` (``h``, ``row_m``, ``col_m``, ``mean_m``: metres between neighbouring pixel
        centres at the image centre). Points the model cannot backproject are ``None``.
    """
    import numpy as np

    from geoblock import coords
    from geoblock.pixels import image_domain

    rows, cols = (int(v) for v in model.shape)
    h_min, h_max = (float(v) for v in model.height_range)
    if h is None:
        h = 0.5 * (h_min + h_max)
    params = model.parameters

    # Outer pixel edges: the half-open box the image covers.
    r0, c0, r1, c1 = image_domain((rows, cols))
    # Centre pixel and its neighbours one row down and one column right.
    rc, cc = (rows - 1) / 2.0, (cols - 1) / 2.0
    row = np.array([r0, r0, r1, r1, rc, rc + 1.0, rc])
    col = np.array([c0, c1, c1, c0, cc, cc, cc + 1.0])
    (lon, lat, hh), _status = model.backproject_with_status(row, col, np.full(row.shape, h))
    xyz = np.stack(coords.geodetic_to_ecef(lon[4:], lat[4:], hh[4:]), axis=-1)
    row_m = float(np.linalg.norm(xyz[1] - xyz[0]))
    col_m = float(np.linalg.norm(xyz[2] - xyz[0]))

    return {
        "model": model.name,
        "shape": {"rows": rows, "cols": cols,
                  "stated": bool(getattr(model, "shape_stated", True))},
        "height_range": [h_min, h_max],
        "parameters": [
            {
                "name": name,
                "value": _num(value),
                "unit": unit,
                "sigma": _num(sigma),
                "adjustable": bool(adjustable),
            }
            for name, value, unit, sigma, adjustable in zip(
                params.names, params.values, params.units, params.sigmas, params.adjustable,
                strict=True,
            )
        ],
        "footprint": {
            "h": float(h),
            "corners": [
                {
                    "corner": _CORNERS[i],
                    "row": float(row[i]),
                    "col": float(col[i]),
                    "lon": _num(lon[i]),
                    "lat": _num(lat[i]),
                }
                for i in range(4)
            ],
        },
        "gsd": {
            "h": float(h),
            "row_m": _num(row_m),
            "col_m": _num(col_m),
            "mean_m": _num(0.5 * (row_m + col_m)),
        },
    }


def _fmt(value: float | None, spec: str) -> str:
    return "nan" if value is None else format(value, spec)


def format_info(data: dict[str, Any]) -> str:
    """The human-readable text of ``geoblock info``."""
    shape, (h_min, h_max) = data["shape"], data["height_range"]
    params = data["parameters"]
    n_adj = sum(p["adjustable"] for p in params)
    lines = [
        f"path:          {data['path']}",
        f"model:         {data['model']}",
        f"shape:         {shape['rows']} rows x {shape['cols']} cols"
        + ("" if shape.get("stated", True) else
           " (not stated by the file: the extent the model was fitted over)"),
        f"height range:  {h_min:g} .. {h_max:g} m (ellipsoidal)",
        f"parameters:    {len(params)} ({n_adj} adjustable)",
    ]
    if params:
        header = ["name", "value", "unit", "sigma", "adjustable"]
        rows = [
            [
                p["name"],
                _fmt(p["value"], ".10g"),
                p["unit"],
                "free" if p["sigma"] is None else format(p["sigma"], ".6g"),
                "yes" if p["adjustable"] else "no",
            ]
            for p in params
        ]
        widths = [max(len(r[i]) for r in [header, *rows]) for i in range(len(header))]
        for r in [header, *rows]:
            cells = [
                r[i].rjust(widths[i]) if i == 1 else r[i].ljust(widths[i]) for i in range(len(r))
            ]
            lines.append(("  " + "  ".join(cells)).rstrip())
    fp = data["footprint"]
    lines.append(f"footprint at h = {fp['h']:g} m (outer pixel edges, degrees):")
    lines.append(f"  {'corner':<12}  {'row':>8}  {'col':>8}  {'lon':>12}  {'lat':>12}")
    for c in fp["corners"]:
        lines.append(
            f"  {c['corner']:<12}  {c['row']:>8g}  {c['col']:>8g}  "
            f"{_fmt(c['lon'], '12.7f')}  {_fmt(c['lat'], '12.7f')}"
        )
    gsd = data["gsd"]
    lines.append(
        f"ground sample distance at image centre, h = {gsd['h']:g} m: "
        f"{_fmt(gsd['mean_m'], '.3f')} m "
        f"(along rows {_fmt(gsd['row_m'], '.3f')} m, along cols {_fmt(gsd['col_m'], '.3f')} m)"
    )
    return "\n".join(lines)


@deprecated_aliases(model="--model-type")
@click.command(short_help="Describe a sensor model: size, parameters, footprint, GSD.")
@model_arg
@model_type_opt
@click.option(
    "--height",
    "height",
    type=float,
    default=None,
    metavar="METRES",
    help="Ellipsoidal height of the footprint and GSD; default the middle of the "
    "model's height range.",
)
@json_opt
def info(model_path: str, model_name: str | None, height: float | None, as_json: bool) -> None:
    """Describe the sensor model read from MODEL.

    Prints the model name, the image shape (rows x cols), the valid height range, the
    parameters (value, unit, a-priori sigma or "free", adjustable), the ground footprint
    (lon/lat of the four outer pixel-edge corners at the middle of the height range) and the
    ground sample distance at the image centre (metres between neighbouring pixel centres).

    \b
    Examples:
      geoblock info scene.json
      geoblock info DIM_SPOT6_P_XXXX.XML --model-type rpc --json
    """
    model = open_model_arg(model_path, model_name)
    data = {"path": model_path, **model_info(model, height)}
    if as_json:
        click.echo(json.dumps(data, indent=2, allow_nan=False))
    else:
        click.echo(format_info(data))
