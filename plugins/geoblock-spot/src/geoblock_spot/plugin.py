"""geoblock-spot's hook implementations: its models and the DIMAP v1 / v2 readers."""

from __future__ import annotations

import geoblock


@geoblock.hookimpl
def geoblock_register_sensor_models(register):
    from geoblock_spot.chenlee import ChenLeeModel

    register(ChenLeeModel)


@geoblock.hookimpl
def geoblock_read_sensor_model(path, model_name, options):
    """SPOT/Pleiades physical metadata -> its line-of-sight model (a ``linescan`` model).

    * a SPOT 1-5 DIMAP v1 ``METADATA.DIM`` (or its product directory):
      :func:`geoblock_spot.los.spot_dimap_model`, options ``parameters`` (``"dg"`` default or
      ``"linescan"``), ``use_attitude``, ``height_range``;
    * a DIMAP v2 ``DIM_*.XML`` sensor product (SPOT 6/7, Pleiades) or a Pleiades internal
      ``PHRDIMAP_*.XML``: :func:`geoblock_spot.dimap2.dimap2_model`, options ``parameters``
      (``"linescan"`` default, or ``"dg"`` with ``accuracy_m``), ``accuracy_m``,
      ``attitude_step_s``, ``height_range``.

    Answers for ``model_name`` None or ``"linescan"``; returns None for other files. This
    hook is not ``trylast``, so for a document that also carries an RFM (``PHRDIMAP_*.XML``'s
    ``Global_RFM``) the physical model wins when no model is named; ask for
    ``model="rpc"`` to get the RFM (geoblock-rpc's generic reader is ``trylast``, ARCHITECTURE
    section 5).
    """
    if model_name not in (None, "linescan"):
        return None
    from geoblock.errors import ModelFormatError
    from geoblock_spot.dimap import is_spot_dimap

    if is_spot_dimap(path):
        from geoblock_spot.los import spot_dimap_model

        reader, known = spot_dimap_model, {"parameters", "use_attitude", "height_range"}
        kind = "SPOT DIMAP"
    else:
        from geoblock_spot.dimap2 import dimap2_model, is_dimap2

        if not is_dimap2(path):
            return None
        reader = dimap2_model
        known = {"parameters", "accuracy_m", "attitude_step_s", "height_range"}
        kind = "DIMAP v2 / Pleiades"
    unknown = sorted(set(options) - known)
    if unknown:
        raise ModelFormatError(
            f"{str(path)!r}: unknown option(s) {unknown} for a {kind} model; known: "
            f"{sorted(known)}"
        )
    _check_options(path, options)
    return reader(path, **dict(options))


def _check_options(path, options) -> None:
    """Refuse option values of a wrong type that the readers would take, naming the file and
    option: a ``use_attitude`` that is not a bool (any value is truthy or not), and a bool or
    string for ``accuracy_m`` or a height (``float()`` accepts them). Everything else is
    checked where it is used: ``parameters`` by :func:`geoblock_spot.dimap.with_parameters`,
    ``accuracy_m`` and ``attitude_step_s`` by :func:`geoblock_spot.dimap2.dimap2_model`,
    ``height_range`` by :class:`geoblock.models.linescan.LinescanModel`."""
    from geoblock.errors import ModelFormatError

    def fail(name: str, what: str) -> ModelFormatError:
        return ModelFormatError(f"{str(path)!r}: option {name} must be {what}, got "
                                f"{options[name]!r}")

    def number(value) -> bool:
        return not isinstance(value, (bool, str, bytes))

    if "use_attitude" in options and not isinstance(options["use_attitude"], bool):
        raise fail("use_attitude", "true or false")
    if options.get("accuracy_m") is not None and not number(options["accuracy_m"]):
        raise fail("accuracy_m", "a number")
    heights = options.get("height_range")
    if isinstance(heights, (list, tuple)) and not all(number(h) for h in heights):
        raise fail("height_range", "two heights (h_min, h_max) in metres")
