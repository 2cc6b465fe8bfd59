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
"""

from __future__ import annotations

import importlib.resources
from pathlib import Path

from geoblock.errors import ModelFormatError
from geoblock_example.camera import FrameCamera

__all__ = ["MAGIC", "looks_like_frame_file", "read_frame_file", "sample_file"]

MAGIC = "geoblock-example-frame"
SUFFIX = ".frame"
# key -> number of floats expected
_FIELDS = {
    "rows": 1,
    "cols": 1,
    "principal_distance": 1,
    "principal_point": 2,
    "centre": 3,
    "attitude": 3,
    "height_range": 2,
}
_OPTIONAL = {"sigma_position": 1, "sigma_attitude": 1}


def sample_file() -> Path:
    """The path of the sample ``*.frame`` file shipped with the package."""
    return Path(str(importlib.resources.files("geoblock_example") / "data" / "sample.frame"))


def _parse(text: str) -> dict[str, str]:
    items: dict[str, str] = {}
    for line in text.splitlines():
        line = line.split("#", 1)[0].strip()
        if not line:
            continue
        key, sep, value = line.partition("=")
        if sep:
            items[key.strip()] = value.strip()
    return items


# --8<-- [start:read]
def looks_like_frame_file(path: Path) -> bool:
    """Cheap recognition: the ``.frame`` suffix and the ``format`` line."""
    if path.suffix.lower() != SUFFIX:
        return False
    try:
        head = path.read_text(encoding="utf-8")[:4096]
    except (OSError, UnicodeDecodeError):
        return False
    return _parse(head).get("format", "").split()[:1] == [MAGIC]


def read_frame_file(path: str | Path) -> FrameCamera:
    """Read a ``*.frame`` file into a :class:`FrameCamera`.

    Raises
    ------
    geoblock.errors.ModelFormatError
        A field is missing or malformed; the message names the file and the field.
    """
    path = Path(path)
    items = _parse(path.read_text(encoding="utf-8"))

    def floats(key: str, n: int) -> list[float]:
        if key not in items:
            raise ModelFormatError(f"{str(path)!r}: missing field {key!r}")
        try:
            values = [float(v) for v in items[key].split()]
        except ValueError:
            values = []
        if len(values) != n:
            raise ModelFormatError(
                f"{str(path)!r}: field {key!r} needs {n} number(s), got {items[key]!r}"
            )
        return values

    fields = {key: floats(key, n) for key, n in _FIELDS.items()}
    sigma_pos = floats("sigma_position", 1)[0] if "sigma_position" in items else 10.0
    sigma_att = floats("sigma_attitude", 1)[0] if "sigma_attitude" in items else 1e-4
    try:
        return FrameCamera(
            shape=(int(fields["rows"][0]), int(fields["cols"][0])),
            principal_distance=fields["principal_distance"][0],
            principal_point=tuple(fields["principal_point"]),
            centre=tuple(fields["centre"]),
            attitude=fields["attitude"],
            sigmas=[sigma_pos] * 3 + [sigma_att] * 3,
            height_range=tuple(fields["height_range"]),
        )
    except ValueError as exc:
        raise ModelFormatError(f"{str(path)!r}: {exc}") from exc
# --8<-- [end:read]
