"""The one place geoblock opens files: sensor models, DEMs, images, point files and block files."""

from geoblock.io.blocks import (
    Block,
    BlockDem,
    BlockImage,
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
