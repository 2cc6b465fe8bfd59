"""geoblock's built-in plugin: core models and geoblock's own model JSON, through the same hooks
as any third-party plugin.

The synthetic test models (``synthetic-affine``, ``synthetic-pushbroom``) are not registered
here: they are test models, loaded on request from :mod:`geoblock.testing.plugin`.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator, Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any

from geoblock.errors import GeoblockError, ModelFormatError, UnknownModelError
from geoblock.hookspecs import hookimpl

if TYPE_CHECKING:
    from geoblock.models.protocol import SensorModel


@hookimpl
def geoblock_register_sensor_models(register: Callable[[type], None]) -> None:
    from geoblock.adjust.collocation import CollocationCorrection
    from geoblock.models.corrections import ImageCorrection
    from geoblock.models.crop import CroppedModel
    from geoblock.models.linescan import LinescanModel

    register(ImageCorrection)
    register(CollocationCorrection)
    register(CroppedModel)
    register(LinescanModel)


@hookimpl(tryfirst=True)
def geoblock_read_sensor_model(
    path: Path, model_name: str | None, options: Mapping[str, Any]
) -> SensorModel | None:
    """geoblock model JSON: a ``to_dict()`` object with ``model`` and ``schema_version``."""
    from geoblock.io.models import read_model_json

    data = read_model_json(path)
    if data is None:
        return None
    if model_name is not None and data["model"] != model_name:
        return None
    from geoblock.plugins import from_dict

    try:
        return from_dict(data)
    except UnknownModelError as exc:  # the model (or a wrapped one) is not registered
        raise UnknownModelError(f"{path}: {exc}{_test_model_hint(data)}") from exc
    except GeoblockError as exc:  # any model's refusal of its fields: name the file
        if str(path) in str(exc):
            raise
        raise ModelFormatError(f"{path}: {exc}") from exc


@hookimpl(trylast=True)
def geoblock_write_sensor_model(
    model: SensorModel, path: Path, format: str, options: Mapping[str, Any]
) -> bool | None:
    if format != "json":
        return None
    from geoblock.io.models import write_model_json

    write_model_json(model, path)
    return True


def _model_names(data: Any) -> Iterator[str]:
    """Every ``"model"`` name in a model dictionary, wrapped models' included."""
    if isinstance(data, Mapping):
        if isinstance(data.get("model"), str):
            yield data["model"]
        for value in data.values():
            yield from _model_names(value)
    elif isinstance(data, list):
        for value in data:
            yield from _model_names(value)


def _test_model_hint(data: Mapping[str, Any]) -> str:
    """How to load geoblock's synthetic test models, when ``data`` uses one of them."""
    from geoblock.testing.plugin import MODEL_NAMES, MODULE

    used = sorted(set(_model_names(data)) & set(MODEL_NAMES))
    if not used:
        return ""
    return (f". {', '.join(map(repr, used))} is one of geoblock's synthetic test models, not "
            f"registered unless asked for: set GEOBLOCK_PLUGIN_MODULES={MODULE} in the "
            "environment, or call geoblock.testing.enable_synthetic_models() in Python")
