"""Writers: :class:`~geoblock_rpc.model.RpcModel` -> GDAL ``_RPC.TXT``, DigitalGlobe ``.RPB``,
GeoTIFF RPC tags.

Every number is written as Python's shortest round-tripping decimal (``repr``), so reading a
file back gives bit-identical coefficients. Offsets are written as stored (RPC00B
pixel-centre convention, which is what GDAL and DigitalGlobe expect).

What each format keeps:

* ``"rpc-txt"``: everything, including ``MIN/MAX_LONG/LAT`` when the model has a validity box
  (GDAL ignores those four keys when reading; geoblock reads them back).
* ``"rpb"``: coefficients, offsets, scales, ``errBias``/``errRand`` (``-1`` when unknown);
  RPB has no validity box, so it is dropped (the projection is unchanged).
* ``"gtiff"``: writes GDAL ``RPC`` metadata into the GeoTIFF at ``path``. An existing GeoTIFF
  is updated (its pixels, geotransform and other tags are kept; only the RPC is replaced),
  through a copy put in its place when complete. Otherwise a new 1-band ``uint8`` GeoTIFF of
  the model's shape is created:
  tiled 256x256, ``SPARSE_OK=TRUE`` and deflate, so no pixel block is written and even a
  40 000 x 40 000 placeholder is a few hundred kB (the tile index). The GeoTIFF RPC tag has
  no validity box either.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from pathlib import Path
from typing import Any

from geoblock.errors import ModelFormatError
from geoblock.io import files, open_quietly
from geoblock_rpc.model import RpcModel
from geoblock_rpc.rpc00b import Rpc00b

__all__ = ["WRITERS", "write_gtiff", "write_rpb", "write_rpc_txt"]

_SCALARS = (
    ("LINE_OFF", "line_off"), ("SAMP_OFF", "samp_off"), ("LAT_OFF", "lat_off"),
    ("LONG_OFF", "long_off"), ("HEIGHT_OFF", "height_off"), ("LINE_SCALE", "line_scale"),
    ("SAMP_SCALE", "samp_scale"), ("LAT_SCALE", "lat_scale"), ("LONG_SCALE", "long_scale"),
    ("HEIGHT_SCALE", "height_scale"),
)
_POLYS = (
    ("LINE_NUM_COEFF", "line_num"), ("LINE_DEN_COEFF", "line_den"),
    ("SAMP_NUM_COEFF", "samp_num"), ("SAMP_DEN_COEFF", "samp_den"),
)


def _rpc(model: RpcModel) -> Rpc00b:
    if not isinstance(model, RpcModel):
        raise TypeError(f"the RPC writers need an RpcModel, got {type(model).__name__}")
    return model.rpc


def _num(value: float) -> str:
    return repr(float(value))


def _err(value: float | None) -> str:
    return "-1" if value is None else _num(value)


def rpc_txt_text(rpc: Rpc00b) -> str:
    """The GDAL ``_RPC.TXT`` text of ``rpc`` (``KEY: value`` lines, units omitted)."""
    lines = [f"ERR_BIAS: {_err(rpc.err_bias)}", f"ERR_RAND: {_err(rpc.err_rand)}"]
    lines += [f"{key}: {_num(getattr(rpc, name))}" for key, name in _SCALARS]
    for key, name in _POLYS:
        lines += [f"{key}_{i + 1}: {_num(v)}" for i, v in enumerate(getattr(rpc, name))]
    if rpc.has_validity_box:
        lines += [f"{key}: {_num(getattr(rpc, key.lower()))}"
                  for key in ("MIN_LONG", "MIN_LAT", "MAX_LONG", "MAX_LAT")]
    return "\n".join(lines) + "\n"


def rpb_text(rpc: Rpc00b, satellite_id: str = "UNKNOWN", band_id: str = "P") -> str:
    """The DigitalGlobe ``.RPB`` text of ``rpc`` (GDAL's ``GDALWriteRPBFile`` layout)."""
    names = {
        "line_off": "lineOffset", "samp_off": "sampOffset", "lat_off": "latOffset",
        "long_off": "longOffset", "height_off": "heightOffset", "line_scale": "lineScale",
        "samp_scale": "sampScale", "lat_scale": "latScale", "long_scale": "longScale",
        "height_scale": "heightScale",
    }
    polys = {"line_num": "lineNumCoef", "line_den": "lineDenCoef",
             "samp_num": "sampNumCoef", "samp_den": "sampDenCoef"}
    out = [f'satId = "{satellite_id}";', f'bandId = "{band_id}";', 'SpecId = "RPC00B";',
           "BEGIN_GROUP = IMAGE",
           f"\terrBias = {_err(rpc.err_bias)};", f"\terrRand = {_err(rpc.err_rand)};"]
    out += [f"\t{names[name]} = {_num(getattr(rpc, name))};" for _, name in _SCALARS]
    for name, key in polys.items():
        values = ",\n".join(f"\t\t\t{_num(v)}" for v in getattr(rpc, name))
        out.append(f"\t{key} = (\n{values});")
    out += ["END_GROUP = IMAGE", "END;"]
    return "\n".join(out) + "\n"


def write_rpc_txt(model: RpcModel, path: str | os.PathLike[str]) -> Path:
    """Write ``model`` as a GDAL ``_RPC.TXT`` file.

    Parameters
    ----------
    model : RpcModel
    path : str or path-like
        Destination (GDAL picks it up as a sidecar when named ``<image>_RPC.TXT``); written
        atomically (:func:`geoblock.io.files.write_bytes`).

    Returns
    -------
    pathlib.Path

    Raises
    ------
    GeoblockIOError
        The file cannot be written (one line naming ``path``; a previous file is kept).
    """
    return files.write_bytes(path, rpc_txt_text(_rpc(model)).encode("ascii"), "RPC file ")


def write_rpb(model: RpcModel, path: str | os.PathLike[str], satellite_id: str = "UNKNOWN",
              band_id: str = "P") -> Path:
    """Write ``model`` as a DigitalGlobe ``.RPB`` file.

    Parameters
    ----------
    model : RpcModel
    path : str or path-like
        Destination (GDAL picks it up as a sidecar when named ``<image>.RPB``); written
        atomically (:func:`geoblock.io.files.write_bytes`).
    satellite_id, band_id : str
        ``satId`` and ``bandId`` header values.

    Returns
    -------
    pathlib.Path

    Raises
    ------
    ModelFormatError
        ``satellite_id`` or ``band_id`` holds a quote or a newline.
    GeoblockIOError
        The file cannot be written (one line naming ``path``; a previous file is kept).
    """
    path = Path(path)
    for name, value in (("satellite_id", satellite_id), ("band_id", band_id)):
        if '"' in value or "\n" in value:
            raise ModelFormatError(f"{path}: {name} {value!r} cannot hold quotes or newlines")
    return files.write_bytes(path, rpb_text(_rpc(model), satellite_id, band_id).encode("ascii"),
                             "RPB file ")


def _gdal_items(rpc: Rpc00b) -> dict[str, str]:
    items = {"ERR_BIAS": _err(rpc.err_bias), "ERR_RAND": _err(rpc.err_rand)}
    items.update({key: _num(getattr(rpc, name)) for key, name in _SCALARS})
    items.update({key: " ".join(_num(v) for v in getattr(rpc, name)) for key, name in _POLYS})
    return items


def write_gtiff(model: RpcModel, path: str | os.PathLike[str], create: bool = True) -> Path:
    """Write ``model``'s RPC into the GeoTIFF at ``path`` (GDAL ``RPC`` metadata / TIFF tag).

    Parameters
    ----------
    model : RpcModel
    path : str or path-like
        An existing GeoTIFF is updated (only its RPC changes): a copy beside it is, then put
        in its place, so that a failure leaves it as it was. A missing file is created as a
        sparse, tiled 1-band ``uint8`` GeoTIFF of ``model.shape`` (no pixel data is written)
        unless ``create`` is False, atomically too.
    create : bool
        Whether a missing file may be created.

    Returns
    -------
    pathlib.Path

    Raises
    ------
    ModelFormatError
        ``path`` exists but is not a GeoTIFF GDAL can update, or is missing and ``create``
        is False.
    GeoblockIOError
        The file cannot be written (one line naming ``path``: a full disk says so).
    """
    from rasterio.errors import RasterioIOError

    path = Path(path)
    items = _gdal_items(_rpc(model))
    if not path.exists() and not create:
        raise ModelFormatError(f"{path}: does not exist (create=False)")
    # a copy of an existing file is updated, then put in its place (with any .aux.xml GDAL
    # made): the user's file is replaced only when complete
    with files.staged_files([path], "GeoTIFF ") as (staged,):
        if staged.exists():
            _update_tags(staged, path, items)
        else:
            try:
                with open_quietly(staged, "w", **_placeholder_profile(model.shape)) as ds:
                    ds.update_tags(ns="RPC", **items)
            except (RasterioIOError, OSError) as exc:
                raise files.write_error(path, exc, "GeoTIFF ", staged) from exc
    return path


def _update_tags(staged: Path, path: Path, items: dict[str, str]) -> None:
    """Replace the RPC tags of ``staged``, the copy of the GeoTIFF ``path``."""
    from rasterio.errors import RasterioIOError

    try:
        with open_quietly(staged, "r+") as ds:
            if ds.driver != "GTiff":
                raise ModelFormatError(
                    f"{path}: exists and is a {ds.driver} raster, not a GeoTIFF; "
                    "refusing to write RPC tags into it")
            ds.update_tags(ns="RPC", **items)
    except (RasterioIOError, TypeError) as exc:
        reason = str(exc).replace(str(staged), str(path))
        raise ModelFormatError(f"{path}: exists but is not a GeoTIFF GDAL can update "
                               f"({reason})") from exc


def _placeholder_profile(shape: tuple[int, int]) -> dict[str, Any]:
    """A sparse, tiled 1-band ``uint8`` GeoTIFF of ``shape``: no pixel block is written."""
    rows, cols = shape
    profile: dict[str, Any] = {
        "driver": "GTiff", "height": rows, "width": cols, "count": 1, "dtype": "uint8",
        "compress": "deflate", "sparse_ok": True,
    }
    if rows >= 16 and cols >= 16:
        block = 256 if min(rows, cols) >= 256 else 16
        profile.update(tiled=True, blockxsize=block, blockysize=block)
    if rows * cols > 2**32 - 1:
        profile["bigtiff"] = "YES"
    return profile


#: format name -> writer(model, path, **options)
WRITERS: dict[str, Callable[..., Path]] = {
    "rpc-txt": write_rpc_txt,
    "rpb": write_rpb,
    "gtiff": write_gtiff,
}
