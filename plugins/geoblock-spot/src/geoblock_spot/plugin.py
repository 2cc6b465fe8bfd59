"""geoblock-spot's hook implementations: its models and the DIMAP reader."""

from __future__ import annotations

import geoblock


@geoblock.hookimpl
def geoblock_register_sensor_models(register):
    from geoblock_spot.chenlee import ChenLeeModel

    register(ChenLeeModel)


@geoblock.hookimpl
def geoblock_read_sensor_model(path, model_name, options):
    """A SPOT 1-5 DIMAP v1 ``METADATA.DIM`` -> its line-of-sight model (a ``linescan`` model).

    Answers for ``model_name`` None or ``"linescan"``; returns None for other files. Options
    (see :func:`geoblock_spot.los.spot_dimap_model`): ``parameters`` (``"dg"`` default or
    ``"linescan"``), ``use_attitude``, ``height_range``.
    """
    if model_name not in (None, "linescan"):
        return None
    from geoblock_spot.dimap import is_spot_dimap

    if not is_spot_dimap(path):
        return None
    from geoblock.errors import ModelFormatError
    from geoblock_spot.los import spot_dimap_model

    known = {"parameters", "use_attitude", "height_range"}
    unknown = sorted(set(options) - known)
    if unknown:
        raise ModelFormatError(
            f"{str(path)!r}: unknown option(s) {unknown} for a SPOT DIMAP model; known: "
            f"{sorted(known)}"
        )
    return spot_dimap_model(path, **dict(options))
