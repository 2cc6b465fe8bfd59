"""The ``*.frame`` text format: one ``key = value`` per line, ``#`` starts a comment.

Example (``data/sample.frame``)::

    format = geoblock-example-frame 1
    rows = 1100
    cols = 1650
    principal_distance = 128000        # pixels
    principal_point = 549.5 824.5      # row col, pixels (pixel-centre convention)
    centre = 7.05 43.70 475000         # lon lat (degrees) h (metres above WGS84)
    attitude = 0.02 -0.01 0.3          # omega phi kappa, radians
    height_range = -500 4000           # metres above WGS84
    sigma_position = 10                # optional, metres
    sigma_attitude = 1e-4              # optional, radians
    pixel_origin = centre              # optional: "corner" if principal_point is corner-based

The file is read through :mod:`geoblock.io.metadata` (its bytes, then its fields), so every
error names the file and the field, and the reader never opens a file itself.
"""

from __future__ import annotations

import importlib.resources
from pathlib import Path

from geoblock.errors import GeoblockError, GeoblockIOError, ModelFormatError
from geoblock.io.metadata import Fields, decode_text, read_bytes
from geoblock.pixels import corner_to_centre
from geoblock_example.camera import FrameCamera

__all__ = ["MAGIC", "looks_like_frame_file", "read_frame_file", "sample_file"]

MAGIC = "geoblock-example-frame"
SUFFIX = ".frame"


def sample_file() -> Path:
    """The path of the sample ``*.frame`` file shipped with the package."""
    return Path(str(importlib.resources.files("geoblock_example") / "data" / "sample.frame"))


def _parse(text: str) -> dict[str, str]:
    """The ``key = value`` lines of ``text`` as a mapping (comments and blank lines dropped)."""
    items: dict[str, str] = {}
    for line in text.splitlines():
        line = line.split("#", 1)[0].strip()
        if not line:
            continue
        key, sep, value = line.partition("=")
        if sep:
            items[key.strip()] = value.strip()
    return items


def _error(source: str, field: str, problem: str) -> ModelFormatError:
    """This format's error: ``'<file>': field '<key>': <problem>``."""
    return ModelFormatError(f"{source!r}: field {field!r}: {problem}")


# --8<-- [start:read]
def looks_like_frame_file(path: Path) -> bool:
    """Cheap recognition: the ``.frame`` suffix and the ``format`` line in the first 4 kB."""
    if path.suffix.lower() != SUFFIX:
        return False
    try:
        head = decode_text(read_bytes(path, 4096))
    except GeoblockIOError:  # a directory, no permission ...: not ours
        return False
    return _parse(head).get("format", "").split()[:1] == [MAGIC]


def read_frame_file(path: str | Path) -> FrameCamera:
    """Read a ``*.frame`` file into a :class:`FrameCamera`.

    Raises
    ------
    geoblock.errors.GeoblockIOError
        The file cannot be read.
    geoblock.errors.ModelFormatError
        A field is missing or malformed; the message names the file and the field.
    """
    path = Path(path)
    fields = Fields(str(path), _parse(decode_text(read_bytes(path))), error=_error)
    rows = fields.number("rows", integer=True, low=1, from_text=True)
    cols = fields.number("cols", integer=True, low=1, from_text=True)
    row0, col0 = fields.numbers("principal_point", count=2)
    if fields.string("pixel_origin", "centre", choices=("centre", "corner")) == "corner":
        row0, col0 = corner_to_centre(row0, col0)  # convert once, at the boundary
    sigma_pos = fields.number("sigma_position", 10.0, low=0.0, strict_low=True, from_text=True)
    sigma_att = fields.number("sigma_attitude", 1e-4, low=0.0, strict_low=True, from_text=True)
    principal_distance = fields.number("principal_distance", from_text=True)
    centre = tuple(fields.numbers("centre", count=3))
    attitude = fields.numbers("attitude", count=3)
    height_range = tuple(fields.numbers("height_range", count=2))
    try:  # the fields are read (their errors name file and field); now the model's checks
        return FrameCamera(
            shape=(rows, cols),
            principal_distance=principal_distance,
            principal_point=(float(row0), float(col0)),
            centre=centre,
            attitude=attitude,
            sigmas=[sigma_pos] * 3 + [sigma_att] * 3,
            height_range=height_range,
        )
    except GeoblockError as exc:  # the model refuses the values: name the file
        raise ModelFormatError(f"{str(path)!r}: {exc}") from exc
# --8<-- [end:read]
