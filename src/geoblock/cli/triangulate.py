"""``geoblock triangulate``: image measurements in two or more images -> ground points."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import click

from geoblock.cli.options import (
    check_outputs,
    model_type_opt,
    open_model_arg,
    output_opt,
    overwrite_opt,
    points_source,
    positive_float,
)

if TYPE_CHECKING:
    from geoblock.models.protocol import SensorModel

__all__ = ["triangulate"]


@click.command(short_help="Points measured in 2+ images -> ground (lon, lat, h), no DEM.")
@click.argument("source", metavar="[POINTS | BLOCK.toml]", required=False, default="-")
@click.option("--model", "models", metavar="MODEL_FILE", multiple=True,
              help="Sensor-model file of an image, once per image; with --image-id in the "
              "same order. Not with BLOCK.toml (it names each image's model).")
@click.option("--image-id", "ids", metavar="ID", multiple=True,
              help="The id of each --model's image in the 'image' column of POINTS, once per "
              "--model in the same order; default the model file names without extension.")
@click.option("--sigma-px", "sigma_px", type=float, metavar="PX", default=None,
              callback=positive_float,
              help="Standard deviation of the measurements without a sigma column, pixels, "
              "for the points' sigma_e, sigma_n, sigma_h.  [default: 1]")
@click.option("--max-iterations", type=click.IntRange(min=1), default=10, show_default=True,
              help="Cap on the refinements of each point (rays re-taken around "
              "its height until it moves by less than 0.1 mm).")
@output_opt
@overwrite_opt
@model_type_opt
def triangulate(source: str, models: tuple[str, ...], ids: tuple[str, ...],
                sigma_px: float | None, max_iterations: int, output: str, overwrite: bool,
                model_name: str | None) -> None:
    """Triangulate the points of POINTS measured in two or more images: the least-squares
    intersection of their lines of sight (ECEF), with no DEM.

    POINTS is the image-measurement CSV that 'geoblock match' writes and 'geoblock adjust'
    reads: id, image, row, col (pixels of each image's model; 0 is the centre of the first
    pixel) and optionally sigma (pixels) and kind; '-' or no POINTS reads standard input.
    The models come from --model (with --image-id naming each one's image), or from
    BLOCK.toml: its [[images]] (id and model) and its [points] image file.

    The output CSV has one row per point id: lon, lat (degrees), h (metres above the WGS84
    ellipsoid), miss_m (twice the RMS distance of the point to its rays, metres: for two
    rays the shortest distance between them), rays (how many), rms_px (RMS of the
    residuals), sigma_e, sigma_n, sigma_h (metres, from the measurement sigmas), the
    residual of each image v_row_<image>, v_col_<image> (measured minus the point projected,
    pixels; nan where the image did not measure the point) and status (converged,
    max_iterations, no_intersection: fewer than two rays or parallel ones, out_of_domain...).

    \b
    Examples:
      geoblock triangulate tp.csv --model left.geom --image-id left \\
          --model right.geom --image-id right -o ground.csv
      geoblock triangulate teo/block.toml -o teo/triangulated.csv
    """
    import numpy as np

    from geoblock.io import read_points, write_points
    from geoblock.triangulation import triangulate as _triangulate
    from geoblock.triangulation import warn_triangulation

    block_mode = Path(source).suffix.lower() == ".toml"
    check_outputs({"--output": output},
                  {"BLOCK.toml" if block_mode else "POINTS": source, "--model": models},
                  overwrite=overwrite)
    if block_mode:
        for name, given in (("--model", models), ("--image-id", ids)):
            if given:
                raise click.UsageError(f"{name} applies to POINTS, not to a block file (the "
                                       "block file names each image's model)")
        opened, points = _block_models(source, model_name)
    else:
        if len(models) < 2:
            raise click.UsageError("give --model once per image, for two or more images (or "
                                   "one BLOCK.toml)")
        if ids and len(ids) != len(models):
            raise click.UsageError(f"give --image-id once per --model ({len(models)}), or not "
                                   f"at all; got {len(ids)}")
        names = list(ids) if ids else [Path(m).stem for m in models]
        if len(set(names)) != len(names):
            raise click.UsageError(f"the image ids {names} repeat; give distinct --image-id")
        opened = {n: open_model_arg(m, model_name) for n, m in zip(names, models, strict=True)}
        points = points_source(source)
    table = read_points(points, required=("row", "col"))
    label = "BLOCK.toml's image points" if block_mode else "POINTS"
    if "image" not in table:
        raise click.UsageError(f"{label} has no 'image' column: each measurement must name "
                               f"the image it was measured in (one of {sorted(opened)})")
    if table["id"].size and np.unique(table["id"]).size == table["id"].size:
        raise click.UsageError(f"no point of {label} is measured in two images (every id "
                               "appears once): a point needs an id shared by its measurements "
                               "in two or more images")
    default = 1.0 if sigma_px is None else sigma_px
    sigma = (np.where(np.isfinite(table["sigma"]), table["sigma"], default)
             if "sigma" in table else default)
    result = _triangulate(opened, table["id"], table["image"], table["row"], table["col"],
                          sigma_px=sigma, max_iterations=max_iterations, warn=False)
    warn_triangulation(result.status, "triangulate", stacklevel=2)
    write_points(output, result.to_columns(table["image"]))


def _block_models(path: str, model_name: str | None) -> tuple[dict[str, SensorModel], str]:
    """The models of a block file's images (by id) and its image-measurement file."""
    from geoblock.io.blocks import read_block

    block = read_block(path)
    if block.image_points is None:
        raise click.UsageError(f"{path}: the block file names no image-measurement file "
                               "([points] image = ...)")
    models = {im.id: open_model_arg(str(im.model), model_name) for im in block.images}
    return models, str(block.image_points)
