"""open_model / write_model: dispatch to the plugins' reader and writer hooks; geoblock's own
model JSON (``to_dict()`` as a file), which the built-in plugin reads and writes through
:func:`read_model_json` and :func:`write_model_json`."""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import TYPE_CHECKING, Any

from geoblock.errors import GeoblockIOError, ModelFormatError, UnsupportedFormatError
from geoblock.io.files import write_text
from geoblock.io.metadata import read_bytes
from geoblock.io.vsi import VsiPath, as_path
from geoblock.models.protocol import SensorModel

if TYPE_CHECKING:  # pragma: no cover
    from geoblock.models.uncertainty import ModelPosterior
    from geoblock.plugins import HookFailure

__all__ = ["POSTERIOR_KEY", "open_model", "read_model_json", "read_model_posterior",
           "write_model", "write_model_json"]

#: The top-level key of a model JSON that holds the model's posterior covariance
#: (:class:`~geoblock.models.uncertainty.ModelPosterior`); never handed to ``from_dict``.
POSTERIOR_KEY = "posterior"

_FORMATS_BY_SUFFIX = {".json": "json"}


def open_model(
    path: str | os.PathLike[str], model: str | None = None, **options: Any
) -> SensorModel:
    """Open a sensor model from a metadata file.

    Every plugin's ``geoblock_read_sensor_model`` hook is asked in turn (specific readers
    first, generic ones last) until one recognises the file. geoblock's own model JSON
    (``to_dict()`` output, as written by :func:`write_model`) is read by the built-in plugin.
    A reader that fails with anything but a :class:`~geoblock.errors.GeoblockError` is a plugin
    bug: it is skipped with a :class:`~geoblock.errors.PluginWarning` naming the plugin and the
    next reader is asked (:func:`geoblock.plugins.call_firstresult`).

    Parameters
    ----------
    path : str or path-like
        Vendor metadata (DIMAP, RPB, _RPC.TXT, GeoTIFF with RPC tags, ...), a product
        directory a plugin recognises (e.g. a SPOT scene holding ``METADATA.DIM``) or model
        JSON. A GDAL virtual path (``/vsizip/scene.zip/IMAGE.TIF``,
        ``/vsicurl/https://host/IMAGE.TIF``, ``/vsis3/bucket/IMAGE.RPB``, ``/vsimem/...``)
        opens as well: it is kept as given and handed to the readers as a
        :class:`geoblock.io.vsi.VsiPath`, which they read (and look for sidecars beside)
        through GDAL.
    model : str, optional
        The registered model to build (``geoblock plugins`` lists them); by default the
        first reader that recognises the file decides.
    **options
        Reader options, passed to the plugins.

    Returns
    -------
    SensorModel

    Raises
    ------
    GeoblockIOError
        ``path`` does not exist (for a virtual path: GDAL finds nothing there); the message
        names the path as given.
    UnknownModelError
        ``model`` is not a registered model name.
    UnsupportedFormatError
        No reader recognised the file; the message names the file, the plugins consulted and
        the registered models.
    ModelFormatError
        A reader recognised the file but found it invalid.
    """
    from geoblock.plugins import call_firstresult, get_plugin_manager, get_registry

    path = as_path(path)  # a Path, or a VsiPath keeping a virtual path's "//"
    if not (path.is_file() or path.is_dir()):  # a directory: a product (e.g. SPOT DIMAP)
        where = " (GDAL finds nothing there)" if isinstance(path, VsiPath) else ""
        raise GeoblockIOError(f"cannot open sensor model: {str(path)!r} does not exist{where}")
    registry = get_registry()
    if model is not None:
        registry.get(model)  # UnknownModelError listing the registered names
    pm = get_plugin_manager()
    result, failures = call_firstresult(
        pm, "geoblock_read_sensor_model", path=path, model_name=model, options=options
    )
    if result is None:
        consulted = [i.plugin_name for i in pm.hook.geoblock_read_sensor_model.get_hookimpls()]
        wanted = f" as model {model!r}" if model else ""
        what = "product directory" if path.is_dir() else "file"
        raise UnsupportedFormatError(
            f"{str(path)!r}: no geoblock plugin can read this {what}{wanted}. Readers consulted: "
            f"{', '.join(consulted) or '(none)'}{_failed(failures)}; registered models: "
            f"{', '.join(registry.names()) or '(none)'}. Install the plugin for this sensor "
            "or check the file."
        )
    return result


def _failed(failures: list[HookFailure]) -> str:
    """``" (failed and skipped: rpc (RuntimeError: boom))"``, or ``""``."""
    if not failures:
        return ""
    return " (failed and skipped: " + ", ".join(
        f"{f.plugin_name} ({f.reason})" for f in failures
    ) + ")"


def write_model(
    model: SensorModel, path: str | os.PathLike[str], format: str | None = None, *,
    posterior: ModelPosterior | None = None, **options: Any
) -> Path:
    """Write a sensor model through the plugins' ``geoblock_write_sensor_model`` hook.

    Parameters
    ----------
    model : SensorModel
    path : str or path-like
        Destination; overwritten if it exists.
    format : str, optional
        ``"json"`` (geoblock model JSON, any model) or a format a plugin writes (for example
        ``"rpc-txt"``); inferred from the suffix when omitted (``.json`` -> ``"json"``).
    posterior : ModelPosterior, optional
        The posterior covariance of the model's adjusted parameters (a block adjustment's,
        :meth:`ModelPosterior.from_block_result
        <geoblock.models.uncertainty.ModelPosterior.from_block_result>`), stored beside the
        model under the top-level key ``"posterior"`` of geoblock model JSON
        (:func:`write_model_json`; only that format holds it). ``geoblock ortho
        --accuracy-layer`` propagates it.
    **options
        Writer options, passed to the plugins. A writer failing with anything but a
        :class:`~geoblock.errors.GeoblockError` is skipped with a
        :class:`~geoblock.errors.PluginWarning`, as in :func:`open_model`.

    Returns
    -------
    pathlib.Path
        The path written.

    Raises
    ------
    UnsupportedFormatError
        No writer for the format; a ``posterior`` with a format other than ``"json"``.
    NoAccuracyError
        A ``posterior`` naming parameters the model does not have.
    """
    from geoblock.plugins import call_firstresult, get_plugin_manager

    path = Path(path)
    if format is None:
        format = _FORMATS_BY_SUFFIX.get(path.suffix.lower())
        if format is None:
            raise UnsupportedFormatError(
                f"{str(path)!r}: cannot infer a model format from the suffix "
                f"{path.suffix!r}; pass format= (for example 'json')"
            )
    if not path.parent.is_dir():
        raise GeoblockIOError(
            f"cannot write {str(path)!r}: directory {str(path.parent)!r} does not exist"
        )
    if posterior is not None:  # geoblock's own JSON holds it, whichever plugin made the model
        if format != "json":
            raise UnsupportedFormatError(
                f"{str(path)!r}: a posterior covariance is stored in geoblock model JSON "
                f"only, not as {format!r}")
        return write_model_json(model, path, posterior=posterior)
    pm = get_plugin_manager()
    written, failures = call_firstresult(
        pm, "geoblock_write_sensor_model", model=model, path=path, format=format, options=options
    )
    if not written:
        consulted = [i.plugin_name for i in pm.hook.geoblock_write_sensor_model.get_hookimpls()]
        raise UnsupportedFormatError(
            f"{str(path)!r}: no geoblock plugin writes model {model.name!r} as {format!r}. "
            f"Writers consulted: {', '.join(consulted)}{_failed(failures)}"
        )
    return path


def read_model_json(path: str | os.PathLike[str]) -> dict[str, Any] | None:
    """The ``to_dict()`` mapping in a geoblock model JSON file, or None if it is not one.

    A model JSON file has the suffix ``.json`` (any case) and holds a JSON object with a string
    ``"model"`` and a ``"schema_version"``. Anything else (a directory, another suffix, text
    that is not UTF-8 or not JSON, another JSON document) gives None, so that other readers can
    be asked. A posterior covariance stored beside the model (top-level ``"posterior"``,
    :func:`read_model_posterior`) is not part of the mapping: ``from_dict`` never sees it.

    Raises
    ------
    GeoblockIOError
        A ``.json`` file that exists but cannot be read (names the file).
    """
    path = as_path(path)
    if path.suffix.lower() != ".json" or path.is_dir():
        return None
    try:
        raw = read_bytes(path)
    except GeoblockIOError as exc:
        raise GeoblockIOError(f"cannot read model JSON {exc}") from exc
    try:
        data = json.loads(raw.decode("utf-8-sig"))
    except (UnicodeDecodeError, json.JSONDecodeError):
        return None
    if isinstance(data, dict) and isinstance(data.get("model"), str) and "schema_version" in data:
        data.pop(POSTERIOR_KEY, None)
        return data
    return None


def read_model_posterior(path: str | os.PathLike[str]) -> ModelPosterior | None:
    """The posterior covariance stored in a geoblock model JSON, or None.

    Parameters
    ----------
    path : str or path-like
        A model file. Anything that is not geoblock model JSON (vendor metadata, a JSON
        without the ``"posterior"`` key) gives None.

    Returns
    -------
    ModelPosterior or None

    Raises
    ------
    ModelFormatError
        The ``"posterior"`` entry is malformed (names the file and the field).
    """
    from geoblock.errors import SerializationError
    from geoblock.models.uncertainty import ModelPosterior

    path = as_path(path)
    if path.suffix.lower() != ".json" or path.is_dir() or not path.is_file():
        return None
    try:
        data = json.loads(read_bytes(path).decode("utf-8-sig"))
    except (UnicodeDecodeError, json.JSONDecodeError, GeoblockIOError):
        return None
    if not (isinstance(data, dict) and isinstance(data.get("model"), str)
            and POSTERIOR_KEY in data):
        return None
    try:
        return ModelPosterior.from_dict(data[POSTERIOR_KEY])
    except SerializationError as exc:
        raise ModelFormatError(f"{path}: {exc}") from exc


def write_model_json(model: SensorModel, path: str | os.PathLike[str], *,
                     posterior: ModelPosterior | None = None) -> Path:
    """Write ``model.to_dict()`` as geoblock model JSON (sorted keys, atomically).

    Parameters
    ----------
    model : SensorModel
    path : str or path-like
    posterior : ModelPosterior, optional
        Stored under the top-level key ``"posterior"`` (:func:`read_model_posterior`); its
        names must be parameters of ``model``. Without it the file is exactly
        ``to_dict()``.

    Raises
    ------
    ModelFormatError
        ``to_dict()`` holds something JSON cannot represent (NaN, infinity, an object); the
        message names the file and the model.
    NoAccuracyError
        ``posterior`` names parameters ``model`` does not have.
    GeoblockIOError
        The file cannot be written.
    """
    data = model.to_dict()
    if posterior is not None:
        from geoblock.models.uncertainty import model_accuracy

        model_accuracy(model, posterior, where=str(path))  # its names are the model's
        data = {**data, POSTERIOR_KEY: posterior.to_dict()}
    try:
        text = json.dumps(data, indent=1, sort_keys=True, allow_nan=False)
    except (TypeError, ValueError) as exc:
        raise ModelFormatError(
            f"{path}: model {model.name!r} is not JSON-safe (to_dict() holds {exc})"
        ) from exc
    return write_text(path, text + "\n", "model JSON ")
