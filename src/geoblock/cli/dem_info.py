"""``geoblock dem-info``: what a DEM covers, its datum, the geoid used, voids and heights."""

from __future__ import annotations

import json
import math
from typing import TYPE_CHECKING, Any

import click

from geoblock.cli.options import DEM_DATUM_HINT, GEOID_HINT, deprecated_aliases, json_opt

if TYPE_CHECKING:
    from geoblock.dem.protocol import DemSource
    from geoblock.dem.raster import RasterDem

__all__ = ["dem_info", "describe_dem"]


def _num(value: float) -> float | None:
    value = float(value)
    return value if math.isfinite(value) else None


def _describe_raster(dem: RasterDem) -> dict[str, Any]:
    stats = dem.statistics()
    rows, cols = dem.shape
    epsg = dem.crs.to_epsg()
    return {
        "path": dem.path,
        "driver": dem.driver,
        "shape": {"rows": rows, "cols": cols},
        "crs": {"name": dem.crs.name, "epsg": epsg},
        "native_bounds": [float(v) for v in dem.native_bounds],
        "bounds": [float(v) for v in dem.bounds],
        "resolution_m": float(dem.resolution_m),
        "vertical": dem.vertical,
        "vertical_source": dem.vertical_source,
        "geoid": None if dem.geoid is None else dem.geoid.path,
        "file_nodata": dem.file_nodata,
        "nodata_share": float(stats["nodata_share"]),
        "file_height_range": [_num(stats["min"]), _num(stats["max"])],
        "height_range": [_num(v) for v in dem.height_range()],
    }


def describe_dem(dem: DemSource) -> dict[str, Any]:
    """The facts ``geoblock dem-info`` reports, JSON-safe.

    Returns
    -------
    dict
        For a raster: ``path``, ``driver``, ``shape``, ``crs`` (name, EPSG code or None),
        ``native_bounds`` (file CRS), ``bounds`` (lon/lat degrees), ``resolution_m``,
        ``vertical`` and ``vertical_source``, ``geoid`` (grid path or None), ``file_nodata``,
        ``nodata_share`` (0..1), ``file_height_range`` (file datum, metres) and
        ``height_range`` (ellipsoidal, metres). A mosaic gives ``tiles``: one such dict each.
    """
    from geoblock.dem.mosaic import MosaicDem
    from geoblock.dem.raster import RasterDem

    if isinstance(dem, RasterDem):
        return _describe_raster(dem)
    if isinstance(dem, MosaicDem):
        return {"bounds": [float(v) for v in dem.bounds],
                "height_range": [_num(v) for v in dem.height_range()],
                "tiles": [_describe_raster(t) for t in dem.tiles]}
    return {"dem": dem.to_dict(), "bounds": list(dem.bounds),
            "height_range": [_num(v) for v in dem.height_range()]}


def _fmt(v: float | None, spec: str = ".3f") -> str:
    return "nan" if v is None else format(v, spec)


def _geoid_text(data: dict[str, Any]) -> str:
    if data["geoid"]:
        return str(data["geoid"])
    return "none (heights already ellipsoidal)" if data["vertical"] else "none"


def format_dem_info(data: dict[str, Any]) -> str:
    """The human-readable text of ``geoblock dem-info``."""
    if "tiles" in data:
        parts = [format_dem_info(t) for t in data["tiles"]]
        lo, hi = data["height_range"]
        parts.append(f"mosaic of {len(parts)} tiles: height range {_fmt(lo)} .. {_fmt(hi)} m "
                     "(ellipsoidal)")
        return "\n\n".join(parts)
    if "path" not in data:
        return json.dumps(data)
    w, s, e, n = data["bounds"]
    lo, hi = data["height_range"]
    flo, fhi = data["file_height_range"]
    crs = data["crs"]
    lines = [
        f"path:            {data['path']}",
        f"driver:          {data['driver']}",
        f"shape:           {data['shape']['rows']} rows x {data['shape']['cols']} cols",
        f"crs:             {crs['name']}" + (f" (EPSG:{crs['epsg']})" if crs["epsg"] else ""),
        "extent:          " + ", ".join(f"{v:.8g}" for v in data["native_bounds"])
        + " (left, bottom, right, top; file CRS)",
        f"extent lon/lat:  west {w:.6f}, south {s:.6f}, east {e:.6f}, north {n:.6f} degrees",
        f"resolution:      {data['resolution_m']:.2f} m",
        f"vertical datum:  {data['vertical'] or 'not stated'} ({data['vertical_source']})",
        *([f"to use it:       {data['hint']}"] if data.get("hint") else []),
        f"geoid used:      {_geoid_text(data)}",
        f"nodata:          {data['file_nodata']} in the file; "
        f"{100.0 * data['nodata_share']:.3f} % of the pixels",
        f"file heights:    {_fmt(flo)} .. {_fmt(fhi)} m (file datum)",
        f"height range:    {_fmt(lo)} .. {_fmt(hi)} m (ellipsoidal, WGS84)"
        if data["vertical"] else "height range:    unknown above the ellipsoid (datum not "
        "stated)",
    ]
    return "\n".join(lines)


@deprecated_aliases(vertical="--dem-vertical")
@click.command("dem-info", short_help="Describe a DEM: extent, CRS, vertical datum, heights.")
@click.argument("dem_paths", metavar="DEM...", nargs=-1, required=True)
@click.option("--dem-vertical", type=click.Choice(["geoid", "ellipsoid"]), default=None,
              help="Vertical datum of the DEM heights when the file does not state it (or to "
              "override it); default: as the file states it.")
@click.option("--geoid", "geoid", default=None, metavar="GTX",
              help="Geoid grid (.gtx) for geoid heights; default GEOBLOCK_GEOID or PROJ's "
              "egm96_15.gtx.")
@json_opt
def dem_info(dem_paths: tuple[str, ...], dem_vertical: str | None, geoid: str | None,
             as_json: bool) -> None:
    """Describe the DEM in DEM (several files: a mosaic of tiles).

    Prints the extent (file CRS and lon/lat), the CRS, the vertical datum and how it was
    decided, the geoid grid used, the share of nodata pixels and the height range above the
    WGS84 ellipsoid. A DEM that does not state its vertical datum is described all the same
    ('vertical datum: not stated', no ellipsoidal height range) with what to pass: the
    commands that use its heights refuse it until the datum is given (--dem-vertical).

    \b
    Examples:
      geoblock dem-info N44E005.hgt
      geoblock dem-info dem.tif --dem-vertical geoid --json
    """
    from geoblock.errors import DemDatumError, GeoidNotFoundError
    from geoblock.io.dem import open_dem

    source = dem_paths[0] if len(dem_paths) == 1 else list(dem_paths)
    try:
        data = describe_dem(open_dem(source, vertical=dem_vertical, geoid=geoid))
    except GeoidNotFoundError as exc:
        raise exc.with_hint(GEOID_HINT) from None
    except DemDatumError as exc:
        if dem_vertical is not None:  # stated by the user: not the cause
            raise exc.with_hint(DEM_DATUM_HINT) from None
        # describe what the files say, each tile as it states itself
        tiles = [_describe_file(path, geoid) for path in dem_paths]
        data = tiles[0] if len(tiles) == 1 else {
            "bounds": [min(t["bounds"][0] for t in tiles), min(t["bounds"][1] for t in tiles),
                       max(t["bounds"][2] for t in tiles), max(t["bounds"][3] for t in tiles)],
            "height_range": [None, None], "tiles": tiles}
    if as_json:
        click.echo(json.dumps(data, indent=2, allow_nan=False))
    else:
        click.echo(format_dem_info(data))


def _describe_file(path: str, geoid: str | None) -> dict[str, Any]:
    """One DEM file described as it states itself; one that states no vertical datum is told
    as it is: the datum not stated, no geoid, no ellipsoidal height range, and the hint."""
    from geoblock.errors import DemDatumError, GeoidNotFoundError
    from geoblock.io.dem import open_dem

    try:
        return describe_dem(open_dem(path, geoid=geoid))
    except GeoidNotFoundError as exc:
        raise exc.with_hint(GEOID_HINT) from None
    except DemDatumError as exc:
        data = describe_dem(open_dem(path, vertical="ellipsoid"))  # heights as in the file
        return {**data, "vertical": None,
                "vertical_source": f"the file's CRS {data['crs']['name']!r} has no vertical "
                "part, and geoblock does not guess it" if "not stated" in exc.reason
                else exc.reason,
                "hint": DEM_DATUM_HINT, "geoid": None, "height_range": [None, None]}
