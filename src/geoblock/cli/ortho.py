"""``geoblock ortho``: orthorectify an image onto a map grid (tiled GeoTIFF out, atomically)."""

from __future__ import annotations

import click

__all__ = ["ortho"]


@click.command(short_help="Orthorectify an image with its sensor model and a DEM.")
@click.argument("image", metavar="IMAGE")
@click.argument("output", metavar="OUT")
@click.option("--dem", "dem_source", metavar="DEM", required=True,
              help="DEM file (GeoTIFF, SRTM .hgt, VRT, ...) or 'const:H' (metres).")
@click.option("--dem-vertical", type=click.Choice(["geoid", "ellipsoid"]), default=None,
              help="Vertical datum of the DEM heights; default: as the file states it.")
@click.option("--geoid", metavar="GTX", default=None,
              help="Geoid grid (.gtx) for geoid heights; default GEOBLOCK_GEOID or PROJ's "
              "egm96_15.gtx.")
@click.option("--model", "model_file", metavar="MODEL_FILE", default=None,
              help="Sensor-model file (RPB, _RPC.TXT, DIMAP, model JSON, ...); default: the "
              "model stored in IMAGE (e.g. its GeoTIFF RPC tags).")
@click.option("--crs", metavar="CRS", default=None,
              help="Output CRS (EPSG:32631, WKT, PROJ string); default the scene's UTM zone.")
@click.option("--res", "resolution", type=float, metavar="METRES", default=None,
              help="Output pixel size, CRS units; default the image's ground sample distance.")
@click.option("--bounds", type=float, nargs=4, metavar="XMIN YMIN XMAX YMAX", default=None,
              help="Output extent, CRS units (gdalwarp -te); default the footprint on the DEM.")
@click.option("--resampling", type=click.Choice(["nearest", "bilinear", "bicubic", "sinc"]),
              default="bilinear", show_default=True, help="Resampling kernel.")
@click.option("--tolerance", type=float, default=0.01, show_default=True, metavar="PX",
              help="Largest lattice interpolation error, source pixels (0: exact per pixel).")
@click.option("--chunks", type=int, default=1024, show_default=True, metavar="N",
              help="Output chunk side, pixels (does not change the result).")
@click.option("--scheduler", default="threads", show_default=True,
              metavar="threads|processes|ADDRESS",
              help="dask scheduler: local threads, local processes, or the address of a "
              "dask.distributed scheduler (tcp://host:8786).")
@click.option("--cog", is_flag=True, default=False, help="Write a Cloud-Optimized GeoTIFF.")
@click.option("--progress/--no-progress", default=True, show_default=True,
              help="Show a progress bar.")
def ortho(image, output, dem_source, dem_vertical, geoid, model_file, crs, resolution, bounds,
          resampling, tolerance, chunks, scheduler, cog, progress) -> None:
    """Orthorectify IMAGE onto a map grid and write OUT (tiled GeoTIFF).

    Every output pixel centre goes to the ground, takes its height from DEM (ellipsoidal;
    --dem-vertical/--geoid convert geoid heights) and is projected into IMAGE by its sensor
    model, within --tolerance source pixels of the exact projection; the image is resampled
    there. For the same --crs, --res and --bounds the output grid is gdalwarp's
    '-t_srs CRS -tr RES RES -te XMIN YMIN XMAX YMAX' grid. OUT is written under a temporary
    name and renamed at the end: a failed run leaves nothing under OUT.

    \b
    Examples:
      geoblock ortho scene.tif ortho.tif --dem N43E007.hgt
      geoblock ortho scene.tif ortho.tif --dem dem.tif --model scene_RPC.TXT \\
          --crs EPSG:32632 --res 0.5 --resampling bicubic --scheduler processes
    """
    from geoblock.io import open_dem, open_model
    from geoblock.io.images import open_image, write_ortho
    from geoblock.ortho import OutputGrid, orthorectify

    model = open_model(model_file if model_file is not None else image)
    dem = open_dem(dem_source, vertical=dem_vertical, geoid=geoid)
    source = open_image(image)
    if bounds and resolution is not None and crs is not None:
        grid = OutputGrid.from_bounds(crs, tuple(bounds), resolution)  # gdalwarp -te/-tr
    else:
        grid = OutputGrid.for_model(model, dem, crs=crs, resolution=resolution,
                                    bounds=tuple(bounds) if bounds else None,
                                    align=not bounds)
    data = orthorectify(source, model, dem, grid, kernel=resampling, tolerance_px=tolerance,
                        chunks=chunks)
    driver = "COG" if cog else "GTiff"
    if scheduler in ("threads", "processes", "synchronous"):
        write_ortho(data, output, driver=driver, scheduler=scheduler, progress=progress)
    else:
        from distributed import Client

        with Client(scheduler) as client:
            write_ortho(data, output, driver=driver, scheduler=client, progress=progress)
    click.echo(f"{output}: {grid.shape[0]} x {grid.shape[1]} px, {source.bands} band(s)",
               err=True)
