"""``geoblock project`` and ``geoblock backproject``: point files through a sensor model.

Both read a CSV point file (a path, or standard input), transform every point in one
vectorised call and write the input columns plus the results and a ``status`` column (the
lowercase :class:`~geoblock.typing.Status` name: ``converged``, ``out_of_domain``,
``invalid_input``, ...). A point that fails is ``nan`` in the result columns; the other
points are unaffected. Result columns already present in the input are replaced in place.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import click

from geoblock.cli.options import (
    check_outputs,
    deprecated_aliases,
    model_arg,
    model_type_opt,
    open_model_arg,
    output_opt,
    overwrite_opt,
    points_arg,
    points_source,
)

if TYPE_CHECKING:
    import numpy as np

__all__ = ["backproject", "project", "status_names"]


def status_names(status: np.ndarray) -> np.ndarray:
    """Lowercase :class:`Status` names (``"converged"``, ...) for a ``uint8`` status array."""
    import numpy as np

    from geoblock.typing import Status

    names = np.array([Status(v).name.lower() if v in set(Status) else str(v)
                      for v in range(max(Status) + 1)])
    status = np.asarray(status, dtype=np.intp)
    known = names[np.clip(status, 0, names.size - 1)]
    return np.where(status < names.size, known, status.astype(str))


def _run(model_path: str, model_name: str | None, points: str, output: str, overwrite: bool,
         inputs: tuple[str, str, str], outputs: tuple[str, ...], method: str, what: str,
         ) -> None:
    from geoblock._array import warn_status
    from geoblock.io import read_points, write_points

    check_outputs({"--output": output}, {"POINTS": points, "MODEL": model_path},
                  overwrite=overwrite)
    model = open_model_arg(model_path, model_name)
    table = read_points(points_source(points), required=inputs)
    coords, status = getattr(model, method)(*(table[c] for c in inputs))
    warn_status(status, f"{what} with {model.name!r}", stacklevel=2)
    out = dict(table)
    for name in outputs:
        out[name] = getattr(coords, name)
    out["status"] = status_names(status)
    write_points(output, out)


@deprecated_aliases(model="--model-type")
@click.command(short_help="Ground points (lon, lat, h) -> image (row, col).")
@model_arg
@points_arg
@output_opt
@overwrite_opt
@model_type_opt
def project(model_path: str, points: str, output: str, overwrite: bool,
            model_name: str | None) -> None:
    """Project ground points into the image of MODEL.

    POINTS is a CSV file with a header line holding at least the columns lon, lat (degrees,
    WGS84) and h (metres above the ellipsoid); '-' or no POINTS reads standard input. The
    output CSV has every input column (an id column 1, 2, ... is added when there is none)
    followed by row, col (pixels; 0 is the centre of the first pixel) and status
    (converged, out_of_domain, invalid_input, ...). A point with an empty or nan
    coordinate gets status invalid_input and nan results; the others are unaffected.

    \b
    Examples:
      geoblock project scene.json gcps.csv -o gcps_image.csv
      cat gcps.csv | geoblock project scene.json > gcps_image.csv
    """
    _run(
        model_path, model_name, points, output, overwrite,
        inputs=("lon", "lat", "h"), outputs=("row", "col"),
        method="project_with_status", what="project",
    )


@deprecated_aliases(model="--model-type")
@click.command(short_help="Image points (row, col) at height h -> ground (lon, lat).")
@model_arg
@points_arg
@output_opt
@overwrite_opt
@model_type_opt
def backproject(model_path: str, points: str, output: str, overwrite: bool,
                model_name: str | None) -> None:
    """Backproject image points of MODEL onto the surface at ellipsoidal height h.

    POINTS is a CSV file with a header line holding at least the columns row, col (pixels;
    0 is the centre of the first pixel) and h (metres above the WGS84 ellipsoid); '-' or no
    POINTS reads standard input. The output CSV has every input column (an id column is
    added when there is none) followed by lon, lat (degrees) and status. Points that fail
    get nan and their status (invalid_input, diverged, ...); the others are unaffected.

    \b
    Examples:
      geoblock backproject scene.json measures.csv -o measures_ground.csv
      printf 'row,col,h\\n0,0,100\\n' | geoblock backproject scene.json
    """
    _run(
        model_path, model_name, points, output, overwrite,
        inputs=("row", "col", "h"), outputs=("lon", "lat"),
        method="backproject_with_status", what="backproject",
    )
