"""``geoblock ortho``: orthorectify an image onto a map grid (tiled GeoTIFF out, atomically)."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import click

from geoblock.cli.options import (
    bounds_value,
    check_outputs,
    crop_offset_opt,
    crs_value,
    dem_options,
    force_opt,
    model_for_image_arg,
    no_crop_opt,
    nonnegative_float,
    open_dem_arg,
    overwrite_opt,
    positive_float,
    scheduler_opt,
    using_scheduler,
    write_options,
)
from geoblock.ortho.limits import MAX_PIXELS

if TYPE_CHECKING:
    import pyproj

    from geoblock.dem.protocol import DemSource
    from geoblock.models.protocol import SensorModel
    from geoblock.ortho.grid import OutputGrid

__all__ = ["ortho"]


@click.command(short_help="Orthorectify an image with its sensor model and a DEM.")
@click.argument("image", metavar="IMAGE")
@click.argument("output", metavar="OUT")
@dem_options(voids=True)
@click.option("--model", "model_file", metavar="MODEL_FILE", default=None,
              help="Sensor-model file (RPB, _RPC.TXT, DIMAP, model JSON, ...); default: the "
              "model stored in IMAGE (e.g. its GeoTIFF RPC tags).")
@crop_offset_opt
@no_crop_opt
@force_opt
@click.option("--crs", metavar="CRS", default=None, callback=crs_value,
              help="Output CRS (EPSG:32631, WKT, PROJ string); default the scene's UTM zone.")
@click.option("--res", "resolution", type=float, metavar="METRES", default=None,
              callback=positive_float,
              help="Output pixel size, CRS units; default the image's ground sample distance "
              "rounded to 1, 2, 2.5 or 5 x 10^k, on a grid aligned to multiples of it (orthos "
              "of one sensor then mosaic together).")
@click.option("--bounds", type=float, nargs=4, metavar="XMIN YMIN XMAX YMAX", default=None,
              callback=bounds_value,
              help="Output extent, CRS units (gdalwarp -te); default the footprint on the DEM.")
@click.option("--resampling", type=click.Choice(["nearest", "bilinear", "bicubic", "sinc"]),
              default="bilinear", show_default=True, help="Resampling kernel.")
@click.option("--tolerance", type=float, default=0.01, show_default=True, metavar="PX",
              callback=nonnegative_float,
              help="Largest lattice interpolation error, source pixels (0: exact per pixel).")
@click.option("--chunks", type=click.IntRange(min=1), default=1024, show_default=True,
              metavar="N", help="Output chunk side, pixels (does not change the result).")
@click.option("--max-pixels", type=click.IntRange(min=1), default=MAX_PIXELS, show_default=True,
              metavar="N", envvar="GEOBLOCK_MAX_PIXELS",
              help="Refuse output grids of more than N pixels (rows x cols) before computing "
              "anything (env GEOBLOCK_MAX_PIXELS).")
@click.option("--allow-empty", is_flag=True, default=False,
              help="Write OUT with a warning when no pixel is valid (DEM not covering the "
              "scene, --bounds missing the footprint); by default that is an error and "
              "nothing is written.")
@click.option("--accuracy-layer", "accuracy_layer", metavar="[ACCURACY.tif]", is_flag=False,
              flag_value="", default=None,
              help="Also write the accuracy layer: the predicted horizontal error of every "
              "pixel, metres (float32, radial RMS; the model's posterior covariance when "
              "MODEL_FILE is a model JSON from 'geoblock adjust', else its a-priori accuracy, "
              "plus --dem-sigma through the viewing geometry); default path: OUT's stem + "
              "'_accuracy.tif'. Needs --dem-sigma.")
@click.option("--dem-sigma", "dem_sigma", type=float, metavar="M", default=None,
              callback=nonnegative_float,
              help="Standard deviation of the DEM's heights, metres (with --accuracy-layer).")
@scheduler_opt
@click.option("--cog", is_flag=True, default=False, help="Write a Cloud-Optimized GeoTIFF.")
@write_options
@overwrite_opt
@click.option("--progress/--no-progress", default=True, show_default=True,
              help="Show a progress bar.")
def ortho(image: str, output: str, dem_source: str, dem_vertical: str | None, geoid: str | None,
          dem_voids: str | float | None, fill_height: float | None, dem_interpolation: str,
          model_file: str | None, crop_offset: tuple[float, float] | None, no_crop: bool,
          force: bool,
          crs: pyproj.CRS | None, resolution: float | None,
          bounds: tuple[float, float, float, float] | None,
          resampling: str, tolerance: float, chunks: int, max_pixels: int, allow_empty: bool,
          accuracy_layer: str | None, dem_sigma: float | None,
          scheduler: str, cog: bool, compress: str, level: int | None,
          creation_options: dict[str, str], overwrite: bool, progress: bool) -> None:
    """Orthorectify IMAGE onto a map grid and write OUT (tiled GeoTIFF).

    Every output pixel centre goes to the ground, takes its height from DEM (ellipsoidal;
    --dem-vertical/--geoid convert geoid heights) and is projected into IMAGE by its sensor
    model, within --tolerance source pixels of the exact projection; the image is resampled
    there. For the same --crs, --res and --bounds the output grid is gdalwarp's
    '-t_srs CRS -tr RES RES -te XMIN YMIN XMAX YMAX' grid. The default grid (the scene's UTM
    zone, its GSD rounded to 1, 2, 2.5 or 5 x 10^k, aligned to multiples of it) is the same
    for every image of one sensor, so their orthos mosaic together. Impossible grids (more
    than --max-pixels, fewer than 2 x 2 pixels, pixels over 1 degree) are refused before
    anything is computed, and so is an OUT that exists (unless --overwrite) or is IMAGE. OUT
    is written under a temporary name and renamed at the end: a failed run leaves nothing
    under OUT, and a run that produced no valid pixel fails (unless --allow-empty).

    Where the DEM has no height (voids inside it, or outside its coverage) the output pixel
    is nodata, unless --dem-voids fills the voids from the surrounding posts or
    --fill-height gives a height for every such place (GDAL's RPC_DEM_MISSING_VALUE).

    --accuracy-layer writes, beside OUT (or at ACCURACY.tif), the predicted horizontal error
    of every pixel in metres on OUT's grid, nodata where OUT has none: the radial RMS
    sqrt(sigma_E^2 + sigma_N^2) of the model's covariance propagated to the ground plus
    --dem-sigma times the tangent of the incidence. The covariance is the posterior that
    'geoblock adjust' stores in its models/<image>.json (give it with --model), else the
    model's a-priori accuracy (parameter sigmas, or the product's stated accuracy such as an
    RPC's ERR_BIAS); a model that states neither is refused. The layer's tags say which.

    IMAGE may be a crop of the model's scene (vendor metadata describe the full scene): the
    crop offset is applied when IMAGE states it with a pixel-unit geotransform (no CRS,
    pixel size 1, origin at the crop's first pixel), or given with --crop-offset ROW COL. An
    IMAGE whose shape differs from the model's with no crop offset is refused (--no-crop uses
    the model's pixels as they are).

    \b
    Examples:
      geoblock ortho scene.tif ortho.tif --dem N43E007.hgt
      geoblock ortho scene.tif ortho.tif --dem dem.tif --model scene_RPC.TXT \\
          --crs EPSG:32632 --res 0.5 --resampling bicubic --scheduler processes
      geoblock ortho scene.tif ortho.tif --dem dem.tif --model adjusted/models/scene.json \\
          --dem-sigma 4 --accuracy-layer
    """
    from geoblock.errors import EmptyOutputError
    from geoblock.io import open_model
    from geoblock.io.images import open_image, write_ortho
    from geoblock.ortho import OutputGrid, ortho_job
    from geoblock.ortho.grid import check_oversampling

    acc_path = _accuracy_output(output, accuracy_layer, dem_sigma)
    check_outputs({"OUT": output, "--accuracy-layer": acc_path},
                  {"IMAGE": image, "--model": model_file, "--dem": dem_source},
                  overwrite=overwrite)
    model = open_model(model_file if model_file is not None else image)
    posterior = None
    if acc_path is not None:  # refused before any work when the model states no accuracy
        from geoblock.io.models import read_model_posterior
        from geoblock.models.uncertainty import model_accuracy

        posterior = read_model_posterior(model_file if model_file is not None else image)
        model_accuracy(model, posterior, where=model_file or image)
    source = open_image(image)
    # a crop of the model's scene: shifted, or refused when nothing says where it lies (also
    # refuses --crop-offset with --no-crop)
    model = model_for_image_arg(model, source, crop_offset, no_crop, force)
    dem = open_dem_arg(dem_source, dem_vertical, geoid, voids=dem_voids,
                       fill_height=fill_height, interpolation=dem_interpolation)
    if bounds and resolution is not None and crs is not None:
        grid = OutputGrid.from_bounds(crs, bounds, resolution)  # gdalwarp -te/-tr
    else:
        grid = OutputGrid.for_model(model, dem, crs=crs, resolution=resolution,
                                    bounds=bounds or None,
                                    align=not bounds, max_pixels=None)
    names = {"resolution": "--res", "bounds": "--bounds", "max_pixels": "--max-pixels"}
    grid.check(max_pixels=max_pixels, names=names)  # before the graph: 10^20 pixels is no job
    if resolution is not None:  # a likely typo: far finer than the image's GSD
        check_oversampling(grid, model, dem, names=names)
    # the model is reconciled with the image already (crop offset applied, or --no-crop)
    data = ortho_job(source, model, dem, grid, kernel=resampling, tolerance_px=tolerance,
                     chunks=chunks, crop=False)
    write: dict[str, Any] = {
        "driver": "COG" if cog else "GTiff", "progress": progress, "compress": compress,
        "level": level, "empty": "warn" if allow_empty else "error", **creation_options}
    try:
        with using_scheduler(scheduler) as where:
            write_ortho(data, output, scheduler=where, **write)
            if acc_path is not None:
                assert dem_sigma is not None  # _accuracy_output refuses the layer without it
                layer = _write_accuracy(data.model, dem, grid, output, acc_path, dem_sigma,
                                        posterior, chunks, where, write)
    except EmptyOutputError as exc:
        raise EmptyOutputError(f"{exc}: {_why_empty(model, dem, grid, bool(bounds))}; "
                               "pass --allow-empty to write it anyway") from exc
    click.echo(f"{output}: {grid.shape[0]} x {grid.shape[1]} px, {source.bands} band(s)",
               err=True)
    if acc_path is not None:
        click.echo(f"{acc_path}: accuracy layer ({layer}), metres", err=True)


def _accuracy_output(output: str, accuracy_layer: str | None,
                     dem_sigma: float | None) -> str | None:
    """The accuracy layer's path (None: not asked for); --dem-sigma is needed with it, and
    only with it."""
    if accuracy_layer is None:
        if dem_sigma is not None:
            raise click.UsageError("--dem-sigma is used only with --accuracy-layer")
        return None
    if dem_sigma is None:
        raise click.UsageError(
            "--accuracy-layer needs --dem-sigma METRES, the standard deviation of the DEM's "
            "heights (its error moves every pixel by sigma x tan(incidence); e.g. about 4-10 m "
            "for SRTM, less for a lidar DTM): geoblock does not guess it")
    if accuracy_layer == "":
        from geoblock.ortho.accuracy import accuracy_path

        return accuracy_path(output)
    return accuracy_layer


def _write_accuracy(model: SensorModel, dem: DemSource, grid: OutputGrid, output: str,
                    path: str, dem_sigma: float, posterior: Any, chunks: int, where: Any,
                    write: dict[str, Any]) -> str:
    """Write the accuracy layer of the ortho just written at ``output`` (its nodata pixels
    masked); returns what the covariance was, for the summary line."""
    from geoblock.io.images import write_ortho
    from geoblock.ortho.accuracy import ACCURACY_DESCRIPTION, accuracy_job

    job = accuracy_job(model, dem, grid, dem_sigma=dem_sigma, posterior=posterior,
                       ortho=output, chunks=chunks)
    write_ortho(job, path, scheduler=where, tags=job.tags,
                band_descriptions=[ACCURACY_DESCRIPTION], units="m", **write)
    return f"{job.accuracy.kind}: {job.accuracy.source}"


def _why_empty(model: SensorModel, dem: DemSource, grid: OutputGrid, bounds_given: bool) -> str:
    """The likely reason an ortho has no valid pixel, for the error message."""
    import math

    import numpy as np

    from geoblock import coords
    from geoblock.dem import coverage_gap
    from geoblock.models.base import image_outline

    try:
        lo, hi = model.height_range
        mid = 0.5 * (lo + hi) if math.isfinite(lo) and math.isfinite(hi) else 0.0
        fp = image_outline(model, mid, n=32)
        lon, lat = np.asarray(fp.lon), np.asarray(fp.lat)
        ok = np.isfinite(lon) & np.isfinite(lat)
        lon, lat = lon[ok], lat[ok]
        x, y = coords.transformer("EPSG:4326", grid.crs).transform(lon, lat)
        xmin, ymin, xmax, ymax = grid.bounds
        if x.max() < xmin or x.min() > xmax or y.max() < ymin or y.min() > ymax:
            what = "--bounds" if bounds_given else "the output grid"
            return (f"{what} ({xmin:.10g}, {ymin:.10g}, {xmax:.10g}, {ymax:.10g}) do not "
                    f"overlap the image footprint ({x.min():.10g}, {y.min():.10g}, "
                    f"{x.max():.10g}, {y.max():.10g}) in {grid.crs.name}")
        gap = coverage_gap(dem, model)
        if gap is not None:
            return f"{gap} (--fill-height H gives a height wherever the DEM has none)"
    except Exception:  # the diagnosis must not hide the error itself
        pass
    return ("check that the DEM covers the scene, that --bounds overlap the footprint and "
            "that the image is not all nodata")
