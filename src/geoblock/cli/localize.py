"""``geoblock localize``: image points -> ground points on the DEM (CSV in, CSV out)."""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import click

from geoblock.cli.options import (
    check_outputs,
    crop_offset_opt,
    dem_options,
    force_opt,
    deprecated_aliases,
    model_arg,
    model_for_image_arg,
    model_type_opt,
    no_crop_opt,
    open_dem_arg,
    open_model_arg,
    output_opt,
    overwrite_opt,
    points_arg,
    points_source,
    positive_float,
)

if TYPE_CHECKING:
    from geoblock.models.crop import CroppedModel
    from geoblock.models.protocol import SensorModel

__all__ = ["localize"]


def _crop_to_scene_edge(model: SensorModel, crop_offset: tuple[float, float]) -> CroppedModel:
    """The crop of ``model``'s scene at ``--crop-offset`` with no raster to give its shape: it
    reaches to the scene's far edge. An offset outside the scene is refused (CropError)."""
    from geoblock.errors import CropError
    from geoblock.models.crop import FIT_TOLERANCE_PX, CroppedModel

    rows, cols = (int(v) for v in model.shape)
    row0, col0 = (float(v) for v in crop_offset)
    # to the far edge (as far as the crop may stick out of it, for fractional offsets)
    shape = tuple(max(1, min(n - int(o), math.floor(n + FIT_TOLERANCE_PX - o)))
                  for n, o in ((rows, row0), (cols, col0)))
    try:
        return CroppedModel(model, (row0, col0), shape)
    except CropError as exc:
        raise CropError(
            f"--crop-offset {row0:g} {col0:g} does not lie inside the model's {rows} x {cols} "
            f"px scene ({model.name!r}): the crop's first pixel must be a scene pixel, row "
            f"0..{rows - 1} and col 0..{cols - 1}"
        ) from exc


@deprecated_aliases(model="--model-type", vertical="--dem-vertical", nodata="--dem-voids",
                    interpolation="--dem-interpolation", method="--intersection",
                    tolerance="--intersection-tolerance")
@click.command(short_help="Image points (row, col) -> ground (lon, lat, h) on a DEM.")
@model_arg
@points_arg
@dem_options(voids=True)
@click.option("--intersection", type=click.Choice(["robust", "ray-tracing"]), default="robust",
              show_default=True,
              help="Ray/DEM intersection method: robust (the first intersection from the "
              "sensor, bracketed by a scan of the line of sight, then refined) or ray-tracing "
              "(the papers' fixed-point iteration Z -> XY -> Z').")
@click.option("--intersection-tolerance", type=float, default=1e-3, show_default=True,
              metavar="M", callback=positive_float,
              help="Convergence tolerance of the intersection, metres.")
@click.option("--image", "image", metavar="IMAGE", default=None,
              help="The raster the points were measured on: its shape is checked against "
              "MODEL's and its pixel-unit geotransform, if any, gives the crop offset.")
@crop_offset_opt
@no_crop_opt
@force_opt
@output_opt
@overwrite_opt
@model_type_opt
def localize(model_path: str, points: str, dem_source: str, dem_vertical: str | None,
             geoid: str | None, dem_voids: str | float | None, fill_height: float | None,
             dem_interpolation: str, intersection: str, intersection_tolerance: float,
             image: str | None, crop_offset: tuple[float, float] | None, no_crop: bool,
             force: bool, output: str, overwrite: bool, model_name: str | None) -> None:
    """Intersect the lines of sight of image points of MODEL with the terrain of DEM.

    POINTS is a CSV file with a header line holding at least the columns row, col (pixels;
    0 is the centre of the first pixel); '-' or no POINTS reads standard input. The output
    CSV has every input column (an id column is added when there is none) followed by lon,
    lat (degrees), h (metres above the WGS84 ellipsoid) and status (converged, no_dem,
    no_intersection, max_iterations, diverged, out_of_domain, invalid_input). Points that
    fail get nan; the others are unaffected.

    Pixels are MODEL's unless the points were measured on a crop of its scene: --image IMAGE
    (the crop offset of its pixel-unit geotransform, and a refusal when its shape differs from
    MODEL's with no offset) or --crop-offset ROW COL (the scene pixel of the crop's first
    pixel) shift them into the scene.

    \b
    Examples:
      geoblock localize scene.json --dem N44E005.hgt measures.csv -o ground.csv
      geoblock localize scene.json --dem dem.tif --dem-vertical geoid --dem-voids fill \\
          --fill-height 250 measures.csv -o ground.csv
      printf 'row,col\\n0,0\\n' | geoblock localize scene.json --dem const:100
    """
    from geoblock._array import warn_status
    from geoblock.cli.project import status_names
    from geoblock.dem.intersect import localize as _localize
    from geoblock.io import read_points, write_points

    if no_crop and image is None:
        raise click.UsageError("--no-crop needs --image IMAGE (it says to take IMAGE's pixels "
                               "as MODEL's); without --image the points are MODEL's pixels")
    check_outputs({"--output": output}, {"POINTS": points, "MODEL": model_path, "--image": image},
                  overwrite=overwrite)
    model = open_model_arg(model_path, model_name)
    if image is not None:  # also refuses --crop-offset with --no-crop
        model = model_for_image_arg(model, image, crop_offset, no_crop, force)
    elif crop_offset:
        model = _crop_to_scene_edge(model, crop_offset)
    dem = open_dem_arg(dem_source, dem_vertical, geoid, voids=dem_voids,
                       interpolation=dem_interpolation)
    table = read_points(points_source(points), required=("row", "col"))
    ground, status = _localize(model, table["row"], table["col"], dem, method=intersection,
                               tolerance_m=intersection_tolerance, fill_height=fill_height,
                               warn=False)
    warn_status(status, f"localize with {model.name!r}", stacklevel=2)
    out = dict(table)
    for name in ("lon", "lat", "h"):
        out[name] = getattr(ground, name)
    out["status"] = status_names(status)
    write_points(output, out)
