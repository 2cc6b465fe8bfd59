"""The one place geoblock opens files: sensor models, DEMs, images, point files and block files.

The names below are imported on first use (PEP 562): the light modules (``geoblock.io.geotiff``,
``geoblock.io.rasters``...) can be imported without the block files' adjustment engine.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from geoblock._lazy import lazy_names

if TYPE_CHECKING:
    from geoblock.io.blocks import (
        Block,
        BlockDem,
        BlockImage,
        BlockReference,
        OpenedBlock,
        open_block,
        read_block,
        write_block,
    )
    from geoblock.io.dem import open_dem, write_dem
    from geoblock.io.images import ImageSource, open_image, write_image, write_ortho
    from geoblock.io.metadata import Fields, XmlFields, read_xml
    from geoblock.io.models import open_model, write_model
    from geoblock.io.points import read_points, write_points
    from geoblock.io.rasters import open_quietly

__all__ = [
    "Block",
    "BlockDem",
    "BlockImage",
    "BlockReference",
    "Fields",
    "ImageSource",
    "OpenedBlock",
    "XmlFields",
    "open_block",
    "open_dem",
    "open_image",
    "open_model",
    "open_quietly",
    "read_block",
    "read_points",
    "read_xml",
    "write_block",
    "write_dem",
    "write_image",
    "write_model",
    "write_ortho",
    "write_points",
]

_LAZY = {
    "Block": "geoblock.io.blocks",
    "BlockDem": "geoblock.io.blocks",
    "BlockImage": "geoblock.io.blocks",
    "BlockReference": "geoblock.io.blocks",
    "OpenedBlock": "geoblock.io.blocks",
    "open_block": "geoblock.io.blocks",
    "read_block": "geoblock.io.blocks",
    "write_block": "geoblock.io.blocks",
    "open_dem": "geoblock.io.dem",
    "write_dem": "geoblock.io.dem",
    "ImageSource": "geoblock.io.images",
    "open_image": "geoblock.io.images",
    "write_image": "geoblock.io.images",
    "write_ortho": "geoblock.io.images",
    "Fields": "geoblock.io.metadata",
    "XmlFields": "geoblock.io.metadata",
    "read_xml": "geoblock.io.metadata",
    "open_model": "geoblock.io.models",
    "write_model": "geoblock.io.models",
    "read_points": "geoblock.io.points",
    "write_points": "geoblock.io.points",
    "open_quietly": "geoblock.io.rasters",
}


__getattr__, __dir__ = lazy_names(__name__, _LAZY)
