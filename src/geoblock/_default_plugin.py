"""geoblock's built-in plugin: core models and geoblock's own model JSON, through the same hooks
as any third-party plugin."""

from __future__ import annotations

import json
from pathlib import Path

from geoblock.errors import GeoblockError, ModelFormatError, UnknownModelError
from geoblock.hookspecs import hookimpl
from geoblock.models.corrections import ImageCorrection


@hookimpl
def geoblock_register_sensor_models(register):
    from geoblock.adjust.collocation import CollocationCorrection
    from geoblock.models.crop import CroppedModel
    from geoblock.models.linescan import LinescanModel
    from geoblock.testing.synthetic import AffineCamera, ConstantVelocityPushbroom

    register(ImageCorrection)
    register(CollocationCorrection)
    register(CroppedModel)
    register(LinescanModel)
    register(AffineCamera)
    register(ConstantVelocityPushbroom)


def _looks_like_model_json(path: Path) -> dict | None:
    if path.suffix.lower() != ".json":
        return None
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except (UnicodeDecodeError, json.JSONDecodeError):
        return None
    if isinstance(data, dict) and isinstance(data.get("model"), str) and "schema_version" in data:
        return data
    return None


@hookimpl(tryfirst=True)
def geoblock_read_sensor_model(path, model_name, options):
    """geoblock model JSON: a ``to_dict()`` object with ``model`` and ``schema_version``."""
    if Path(path).is_dir():
        return None
    data = _looks_like_model_json(path)
    if data is None:
        return None
    if model_name is not None and data["model"] != model_name:
        return None
    from geoblock.models.registry import from_dict

    try:
        return from_dict(data)
    except UnknownModelError as exc:  # the model (or a wrapped one) is not registered
        raise UnknownModelError(f"{path}: {exc}") from exc
    except GeoblockError as exc:  # any model's refusal of its fields: name the file
        if str(path) in str(exc):
            raise
        raise ModelFormatError(f"{path}: {exc}") from exc


@hookimpl(trylast=True)
def geoblock_write_sensor_model(model, path, format, options):
    if format != "json":
        return None
    try:
        text = json.dumps(model.to_dict(), indent=1, sort_keys=True, allow_nan=False)
    except (TypeError, ValueError) as exc:
        raise ModelFormatError(
            f"{path}: model {model.name!r} is not JSON-safe (to_dict() holds {exc})"
        ) from exc
    from geoblock.io._atomic import atomic_path

    with atomic_path(path, "model JSON ") as tmp:
        tmp.write_text(text + "\n", encoding="utf-8")
    return True
