"""``geoblock mosaic``: mosaic GeoTIFF orthos of one CRS and resolution (atomic writes)."""

from __future__ import annotations

from typing import Any

import click

from geoblock.cli.options import write_options

__all__ = ["mosaic"]


@click.command(short_help="Mosaic orthos (priority or feathering) with a contribution band.")
@click.argument("output", metavar="OUT")
@click.argument("orthos", metavar="ORTHO...", nargs=-1, required=True)
@click.option("--method", type=click.Choice(["priority", "feather"]), default="priority",
              show_default=True,
              help="priority: the first ORTHO with a valid pixel wins; feather: blend overlaps "
              "with weights growing with the distance to each ortho's nodata edge.")
@click.option("--feather", "feather_px", type=float, default=32.0, show_default=True,
              metavar="PX", help="Cap of the feathering weights, pixels (with --method feather).")
@click.option("--contribution", "contribution_path", metavar="CONTRIB.tif", default=None,
              help="Also write the contribution band: the 1-based index of the ORTHO each "
              "pixel came from (0: none), uint8.")
@click.option("--nodata", type=float, default=None,
              help="Output nodata; default the first ORTHO's nodata (else 0, NaN for floats).")
@click.option("--chunks", type=click.IntRange(min=1), default=1024, show_default=True,
              metavar="N", help="Chunk side, pixels (does not change the result).")
@click.option("--allow-empty", is_flag=True, default=False,
              help="Write OUT with a warning when no pixel is valid; by default that is an "
              "error and nothing is written.")
@click.option("--scheduler", type=click.Choice(["threads", "processes", "synchronous"]),
              default="threads", show_default=True, help="dask scheduler.")
@click.option("--cog", is_flag=True, default=False, help="Write a Cloud-Optimized GeoTIFF.")
@write_options
@click.option("--progress/--no-progress", default=True, show_default=True,
              help="Show a progress bar.")
def mosaic(output: str, orthos: tuple[str, ...], method: str, feather_px: float,
           contribution_path: str | None, nodata: float | None, chunks: int, allow_empty: bool,
           scheduler: str, cog: bool, compress: str, level: int | None,
           creation_options: dict[str, str], progress: bool) -> None:
    """Mosaic the ORTHO GeoTIFFs (in priority order) onto their union grid and write OUT.

    The orthos must share CRS, resolution and pixel phase (nothing is reprojected or
    resampled) and their number of bands: 'geoblock ortho' with its default grid (or the
    same --crs and --res) gives such orthos for images of one sensor. With --method priority
    the first ORTHO with a valid pixel wins; with --method feather overlaps are blended, each
    ortho weighted by the distance (pixels, capped at --feather) to its nearest nodata pixel.
    OUT (and CONTRIB.tif) are written under a temporary name and renamed at the end: a failed
    run, or one without any valid pixel (unless --allow-empty), leaves nothing there.

    \b
    Examples:
      geoblock mosaic mosaic.tif ortho1.tif ortho2.tif ortho3.tif
      geoblock mosaic mosaic.tif a.tif b.tif --method feather --feather 64 \\
          --contribution contrib.tif
    """
    from geoblock.io.images import write_ortho
    from geoblock.ortho.mosaic import mosaic as make_mosaic
    from geoblock.ortho.mosaic import open_ortho

    sources = [open_ortho(path, chunks=chunks) for path in orthos]
    result = make_mosaic(sources, method=method, feather_px=feather_px, nodata=nodata,
                         chunks=chunks)
    write: dict[str, Any] = {
        "driver": "COG" if cog else "GTiff", "scheduler": scheduler, "progress": progress,
        "compress": compress, "level": level, **creation_options}
    empty = "warn" if allow_empty else "error"
    write_ortho(result["mosaic"], output, empty=empty, **write)
    if contribution_path is not None:  # all 0 exactly when the mosaic is empty
        write_ortho(result["contribution"].expand_dims(band=[1]), contribution_path,
                    empty="ignore", **write)
    rows, cols = result.sizes["y"], result.sizes["x"]
    click.echo(f"{output}: {rows} x {cols} px, {result.sizes['band']} band(s) from "
               f"{len(orthos)} orthos ({method})", err=True)
