"""GeoTIFF output options of :func:`geoblock.io.write_ortho` (``geoblock ortho``, ``geoblock
mosaic``): the compressions, the default and its measured reason, the levels.

A module of its own, importing only :mod:`geoblock.errors`, so that the command line shows
them in ``--help`` without importing numpy or GDAL.
"""

from __future__ import annotations

from typing import Any

from geoblock.errors import UnsupportedFormatError

__all__ = ["COMPRESSIONS", "DEFAULT_COMPRESS", "FAST_LEVEL", "LEVEL_KEY", "compression_options"]

#: Compressions of :func:`~geoblock.io.write_ortho` (GDAL's GTiff names, lower case; "none":
#: uncompressed, as gdalwarp writes by default).
COMPRESSIONS = ("zstd", "deflate", "lzw", "packbits", "lerc_zstd", "lerc_deflate", "lerc",
                "none")
#: The default: ZSTD at level 1. Measured on a 6000 x 6000 uint16 ortho written while the
#: warp computes on both cores (benchmarks/bench_ortho_cli.py's coarse case): uncompressed
#: 0.75 s and 75.5 MB; ZSTD 1 0.75 s, 51.3 MB; DEFLATE 1 1.11 s, 50.9 MB; DEFLATE 6 (GDAL's
#: default level) 2.0 s, 51.6 MB; LZW 2.4 s, 59.9 MB. ZSTD 1 compresses as well as DEFLATE
#: at no extra time; DEFLATE stays one option away for readers built without ZSTD.
DEFAULT_COMPRESS = "zstd"
#: The level used when none is given: the fastest (GDAL's own defaults, ZSTD 9 and DEFLATE 6,
#: cost 2 to 3 times the warp above).
FAST_LEVEL = {"zstd": 1, "deflate": 1, "lerc_zstd": 1, "lerc_deflate": 1}

#: The GTiff creation option of each compression's level (the COG driver's is ``LEVEL``).
LEVEL_KEY = {"zstd": "zstd_level", "deflate": "zlevel", "lerc_zstd": "zstd_level",
             "lerc_deflate": "zlevel"}


def compression_options(compress: str | None, level: int | None, cog: bool) -> dict[str, Any]:
    """GDAL creation options (lower-case keys) for ``compress`` at ``level``.

    Parameters
    ----------
    compress : str or None
        One of :data:`COMPRESSIONS` (any case); None or ``"none"``: uncompressed.
    level : int, optional
        Compression level; default :data:`FAST_LEVEL` of the compression.
    cog : bool
        For GDAL's COG driver (whose level option is ``LEVEL``) rather than GTiff.

    Raises
    ------
    UnsupportedFormatError
        An unknown compression, or a level for one that has none (a ValueError).
    """
    name = "none" if compress is None else str(compress).lower()
    if name not in COMPRESSIONS:
        raise UnsupportedFormatError(f"write_ortho: compress must be one of {COMPRESSIONS} or "
                                     f"None, got {compress!r}")
    if name == "none":
        return {"compress": "none"} if cog else {}
    options: dict[str, Any] = {"compress": name}
    if level is None:
        level = FAST_LEVEL.get(name)
    if level is not None:
        if name not in LEVEL_KEY:
            raise UnsupportedFormatError(f"write_ortho: {name} has no compression level "
                                         f"(level={level})")
        options["level" if cog else LEVEL_KEY[name]] = int(level)
    return options
