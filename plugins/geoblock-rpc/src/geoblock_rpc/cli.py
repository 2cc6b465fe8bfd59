"""geoblock-rpc's commands.

``geoblock fit-rfm``: a terrain-dependent RFM fitted to GCPs (:func:`geoblock_rpc.rfm.fit_rfm`).

``geoblock export-rpc``: any sensor model as an RPC (``_RPC.TXT``, ``.RPB`` or GeoTIFF tags).

The model goes through :func:`geoblock.write_model`, so the ``geoblock_write_sensor_model``
hook (:func:`geoblock_rpc.export.export_rpc`) decides how: an RPC is written as it is, an
image-corrected RPC is folded, anything else is fitted. The command prints which happened,
from the hook's :class:`~geoblock_rpc.export.RpcExportWarning`. The output is written in a
staging folder and moved into place only when complete (:func:`geoblock.io.files.staged_files`).
"""

from __future__ import annotations

import math
import shutil
import warnings
from pathlib import Path
from typing import Any

import click

from geoblock.cli.options import (
    check_outputs,
    deprecated_aliases,
    model_arg,
    model_type_opt,
    open_model_arg,
    overwrite_opt,
    positive_float,
)

__all__ = ["FORMATS", "export_rpc_command", "fit_rfm_command", "infer_format"]

#: ``--format`` value -> :func:`geoblock.write_model` format
FORMATS = {"rpc": "rpc-txt", "rpb": "rpb", "tif": "gtiff"}


def infer_format(path: str | Path) -> str | None:
    """``--format`` from OUT's name: ``_RPC.TXT``/``.txt`` -> rpc, ``.RPB`` -> rpb,
    ``.tif``/``.tiff`` -> tif (any case); None otherwise."""
    suffix = Path(path).suffix.lower()
    return {".txt": "rpc", ".rpb": "rpb", ".tif": "tif", ".tiff": "tif"}.get(suffix)


def _image_copy(image: Path, staged: Path, shape: tuple[int, int]) -> None:
    """Copy the raster ``image`` to ``staged`` as a GeoTIFF (a GeoTIFF byte for byte; any other
    raster through GDAL's GeoTIFF driver), after checking that it is ``shape``."""
    import rasterio.shutil
    from rasterio.errors import RasterioIOError

    from geoblock.errors import CropError, GeoblockIOError
    from geoblock.io import open_quietly

    try:
        with open_quietly(image) as ds:
            driver, size = ds.driver, (ds.height, ds.width)
    except RasterioIOError as exc:
        raise GeoblockIOError(f"--image {image}: not a raster GDAL can read ({exc})") from exc
    if size != tuple(shape):
        raise CropError(
            f"--image {image} is {size[0]} x {size[1]} pixels but the model's image is "
            f"{shape[0]} x {shape[1]}: the RPC would not fit its pixels (for a crop, give the "
            "cropped raster itself as MODEL, or its model JSON, so that the crop's offset is "
            "known)"
        )
    if driver == "GTiff":
        shutil.copyfile(image, staged)
    else:
        rasterio.shutil.copy(str(image), str(staged), driver="GTiff")


def _regularization(ctx: click.Context, param: click.Parameter,
                    value: str | None) -> float | str | None:
    """``--regularization``: a number >= 0 or ``gcv``."""
    if value is None:
        return None
    if value.strip().lower() == "gcv":
        return "gcv"
    try:
        number = float(value)
    except ValueError:
        number = math.nan
    if not (math.isfinite(number) and number >= 0.0):
        raise click.BadParameter(f"{value!r}: expected a number >= 0 or gcv", ctx, param)
    return number


def _renamed(exc: Exception, staged: Path, final: Path) -> Exception:
    """``exc`` with the staged path replaced by the destination in its message."""
    text = str(exc).replace(str(staged), str(final)).replace(str(staged.parent),
                                                            str(final.parent))
    try:
        return type(exc)(text)
    except Exception:  # noqa: BLE001 - an exception class with another signature
        from geoblock.errors import GeoblockError

        return GeoblockError(text)


@deprecated_aliases(model="--model-type")
@click.command("export-rpc",
               short_help="Write any sensor model as an RPC (_RPC.TXT, .RPB, GeoTIFF tags).")
@model_arg
@click.argument("out_path", metavar="OUT")
@click.option("--format", "fmt", type=click.Choice(sorted(FORMATS)), default=None,
              help="rpc: GDAL _RPC.TXT; rpb: DigitalGlobe .RPB; tif: a GeoTIFF with RPC tags. "
              "Default: from OUT's suffix (.txt, .RPB, .tif/.tiff).")
@click.option("--image", "image_path", metavar="IMAGE", default=None,
              help="With --format tif: OUT is a copy of this raster (its pixels kept) with the "
              "RPC tags; IMAGE is not modified. Without it OUT is a sparse placeholder of "
              "the model's image size (an existing GeoTIFF OUT keeps its pixels).")
@model_type_opt
@click.option("--grid", nargs=3, type=click.IntRange(min=2), metavar="ROWS COLS HEIGHTS",
              default=None,
              help="Fit grid over the image and the model's height range, for a model that is "
              "not an RPC  [default: 21 21 9].")
@click.option("--regularization", metavar="LAMBDA", default=None, callback=_regularization,
              help="Tikhonov weight of the fit: a number >= 0, or gcv to choose it by "
              "generalised cross-validation  [default: gcv].")
@click.option("--max-error-px", type=click.FloatRange(min=0.0), metavar="PX", default=None,
              help="Refuse an approximate RPC whose largest check-grid error exceeds PX pixels "
              "[default: 0.5 for a fitted model, 0.001 for a refitted corrected RPC].")
@overwrite_opt
def export_rpc_command(model_path: str, out_path: str, fmt: str | None,
                       image_path: str | None, model_name: str | None,
                       grid: tuple[int, int, int] | None, regularization: float | str | None,
                       max_error_px: float | None, overwrite: bool) -> None:
    """Write MODEL as an RPC00B in OUT, for GDAL, QGIS, ASP or s2p.

    MODEL is any file geoblock opens: vendor metadata or geoblock model JSON (from 'geoblock
    refine' or 'geoblock adjust'). An RPC is written exactly; an RPC with an image correction
    (RPCV-0, RPCV-1) is folded into the coefficients, exactly when the algebra allows; any
    other model (physical, adjusted, corrected physical) is fitted over the image and the
    model's height range. One line says which happened, one of:

    \b
      written exactly (RpcModel, or RFM-N in lon/lat is an RPC00B)
      folded exactly (offset): max error ... px over N check points
      refitted (refit: the correction does not fold exactly): check-grid RMS x px, ...
      fitted: check-grid RMS x px, max y px over N points (regularization L)
      written by another plugin's writer (FORMAT: no RPC export report)

    An approximate RPC worse than --max-error-px is refused and nothing is written.
    OUT is replaced only when complete; with --format tif and --image it is a copy of that
    raster with the RPC tags.

    \b
    Examples:
      geoblock export-rpc SPOT5/METADATA.DIM scene_RPC.TXT
      geoblock export-rpc wv.xml wv.RPB --regularization 1e-9
      geoblock export-rpc scene.refined.json scene_rpc.tif --image scene.tif
      gdalwarp -rpc -to RPC_DEM=dem.tif scene_rpc.tif ortho.tif
    """
    from geoblock.errors import GeoblockError
    from geoblock.io import files, write_model
    from geoblock_rpc.export import ExportOutcome, RpcExportWarning
    from geoblock_rpc.model import RpcModel

    final = Path(out_path)
    if fmt is None:
        fmt = infer_format(final)
        if fmt is None:
            raise click.UsageError(
                f"cannot infer the format of {out_path!r} from its suffix {final.suffix!r}: "
                "give --format rpc, rpb or tif (or name it *_RPC.TXT, *.RPB or *.tif)")
    image = None if image_path is None else Path(image_path)
    if image is not None:
        if fmt != "tif":
            raise click.UsageError(f"--image goes with --format tif, not {fmt}")
    # the source raster is never modified; an existing OUT only with --overwrite
    check_outputs({"OUT": out_path}, {"MODEL": model_path, "--image": image_path},
                  overwrite=overwrite)

    model = open_model_arg(model_path, model_name)
    options: dict[str, Any] = {k: v for k, v in (("grid", grid),
                                                 ("regularization", regularization),
                                                 ("max_error_px", max_error_px))
                               if v is not None}
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        with files.staged_files([final]) as (staged,):
            try:
                if image is not None:
                    _image_copy(image, staged, model.shape)
                write_model(model, staged, format=FORMATS[fmt], **options)
            except (GeoblockError, OSError) as exc:  # name OUT, not the staged file
                raise _renamed(exc, staged, final) from exc

    report = None
    for w in caught:
        text = " ".join(str(w.message).split()).replace(str(staged), str(final))
        if isinstance(w.message, RpcExportWarning):
            report = w.message.report
        else:
            warnings.warn(text, w.category, stacklevel=1)
    if report is not None:
        what = report.summary()
    elif isinstance(model, RpcModel):
        what = f"{ExportOutcome.WRITTEN.value} (RpcModel)"
    else:  # another plugin's writer answered first
        what = f"{ExportOutcome.OTHER_WRITER.value} ({FORMATS[fmt]}: no RPC export report)"
    click.echo(f"{final} ({FORMATS[fmt]}): {what}")


# ------------------------------------------------------------------------------ fit-rfm
def _control(ground_path: str, image_path: str, image_id: str | None, sigma_px: float
             ) -> tuple[Any, Any, str]:
    """GCPs and ICPs of one image, joined by point id from the two CSV files."""
    import numpy as np

    from geoblock.adjust import GroundPoints, ImagePoints
    from geoblock.errors import ObservationError, PointFileError
    from geoblock.io import read_points

    image_cols = read_points(image_path, required=("row", "col"))
    if "image" not in image_cols:  # a one-image file needs no image column
        image_cols["image"] = np.full(len(image_cols["id"]), Path(image_path).name)
    try:
        ground = GroundPoints.from_columns(read_points(ground_path, required=("lon", "lat", "h")),
                                           source=ground_path)
        images = ImagePoints.from_columns(image_cols, source=image_path, sigma=sigma_px)
    except ObservationError as exc:
        raise PointFileError(str(exc)) from None
    present = sorted(set(images.image.tolist()))
    if image_id is None:
        if len(present) > 1:
            raise click.UsageError(f"{image_path} holds measurements of {len(present)} images "
                                   f"({', '.join(present)}): choose one with --image-id")
        image_id = present[0]
    elif image_id not in present:
        raise click.BadParameter(f"{image_id!r} has no measurement in {image_path}; its images "
                                 f"are {', '.join(present)}", param_hint="--image-id")
    try:
        gcps = images.control_points(ground, image_id, ("gcp",))
        icps = images.control_points(ground, image_id, ("icp",))
    except ObservationError as exc:
        raise ObservationError(f"{exc} (files {ground_path}, {image_path})") from None
    return gcps, icps, image_id


def _order(ctx: click.Context, param: click.Parameter, value: str) -> int | str:
    if value == "auto":
        return value
    return int(value)


@click.command("fit-rfm", short_help="Fit a terrain-dependent RFM (RFM-1/2/3) to GCPs.")
@click.argument("ground_path", metavar="GROUND.csv")
@click.argument("image_path", metavar="IMAGE.csv")
@click.option("--order", type=click.Choice(["1", "2", "3", "auto"]), default="1",
              show_default=True, callback=_order,
              help="Polynomial order (RFM-1 needs >= 7 GCPs, RFM-2 >= 19, RFM-3 >= 39); auto: "
              "the order with the lowest cross-validated error.")
@click.option("--common-denominator", is_flag=True,
              help="One denominator for rows and columns (default: one each, as Aguilar et al.).")
@click.option("--crs", "crs", default="utm", show_default=True, metavar="utm|geographic|CRS",
              help="Ground frame of the polynomials: the GCPs' UTM zone, lon/lat (an exact "
              "RPC00B), or a projected CRS (EPSG:32630...).")
@click.option("--shape", nargs=2, type=click.IntRange(min=1), default=None,
              metavar="ROWS COLS", help="Image size (default: the GCPs' image extent).")
@click.option("--image", "raster", metavar="IMAGE", default=None,
              help="Take the image size from this raster.")
@click.option("--image-id", default=None, metavar="ID",
              help="The image of IMAGE.csv to fit (needed when it holds several).")
@click.option("--sigma-px", type=float, default=0.5, callback=positive_float,
              show_default=True, metavar="PX",
              help="Image sigma (pixels) of points without one.")
@click.option("-o", "--output", metavar="OUT.json", default=None,
              help="The RFM as geoblock model JSON (default: IMAGE.csv's stem + '.rfm.json').")
@overwrite_opt
def fit_rfm_command(ground_path: str, image_path: str, order: int | str,
                    common_denominator: bool, crs: str, shape: tuple[int, int] | None,
                    raster: str | None, image_id: str | None, sigma_px: float,
                    output: str | None, overwrite: bool) -> None:
    """Fit a terrain-dependent rational function model to ground control points.

    GROUND.csv holds the ground points (id, lon, lat in degrees, h in metres above the WGS84
    ellipsoid[, kind gcp|icp]); IMAGE.csv their measurements (id[, image], row, col in
    pixels with 0 the centre of the first pixel; optionally sigma or sigma_row and sigma_col,
    and kind), joined by id: the point files 'geoblock simulate' writes. GCPs are fitted, ICPs only
    checked. The command prints the fit (order, condition number, regularisation chosen by
    generalised cross-validation), the GCP and ICP residuals in pixels and on the ground
    (RMSE E, N, 2D in metres) and writes the model as JSON, which every geoblock command
    takes as a MODEL (ortho, adjust, refine, export-rpc).

    \b
    Examples:
      geoblock fit-rfm sim/points/ground.csv sim/points/image.csv --order 1
      geoblock fit-rfm ground.csv image.csv --order auto --image scene.tif -o scene.rfm.json
      geoblock fit-rfm ground.csv image.csv --crs geographic -o rfm.json && \\
          geoblock export-rpc rfm.json scene_RPC.TXT
    """
    import geoblock
    from geoblock_rpc.rfm import fit_rfm

    if raster is not None and shape is not None:
        raise click.UsageError("give either --shape or --image, not both")
    out = Path(output) if output else Path(image_path).with_suffix(".rfm.json")
    check_outputs({"--output": out}, {"GROUND.csv": ground_path, "IMAGE.csv": image_path,
                                      "--image": raster}, overwrite=overwrite)
    if raster is not None:
        from geoblock.io import open_quietly

        with open_quietly(raster) as ds:
            shape = (ds.height, ds.width)
    gcps, icps, image_id = _control(ground_path, image_path, image_id, sigma_px)
    click.echo(f"image {image_id}: {len(gcps.id)} GCPs, {len(icps.id)} ICPs")
    frame: str | None = None if crs.lower() == "geographic" else crs
    model = fit_rfm(gcps, order=order, common_denominator=common_denominator, crs=frame,
                    shape=shape, icps=icps if len(icps.id) else None)
    assert model.fit is not None
    click.echo(model.fit.summary())
    size = "" if shape is not None else " (the GCPs' extent: give --shape or --image)"
    click.echo(f"ground frame: {model.crs or 'lon/lat (an exact RPC00B)'}; image "
               f"{model.shape[0]} x {model.shape[1]} px{size}")
    geoblock.write_model(model, out, format="json")
    click.echo(f"wrote {out}")
