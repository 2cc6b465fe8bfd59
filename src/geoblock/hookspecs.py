"""Hook specifications: the only ways a plugin reaches geoblock.

A plugin is a module registered under the entry-point group ``geoblock``::

    [project.entry-points.geoblock]
    mymodels = "geoblock_mymodels.plugin"

whose functions are decorated with :data:`hookimpl` and named after the hooks below. A hook
implementation may accept fewer arguments than the specification (pluggy's opt-in
arguments). Hooks run when a registry is built, a file is opened or the command line starts,
never inside numeric loops or dask tasks.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any

import pluggy

if TYPE_CHECKING:  # pragma: no cover
    import click

    from geoblock.models.protocol import SensorModel

__all__ = ["hookimpl", "hookspec"]

hookspec = pluggy.HookspecMarker("geoblock")
hookimpl = pluggy.HookimplMarker("geoblock")


# ---------------------------------------------------------------------------------------------
# Registration hooks: every plugin is called; results flow through ``register``
# ---------------------------------------------------------------------------------------------


@hookspec
def geoblock_register_sensor_models(register: Callable[[type[SensorModel]], None]) -> None:
    """Register sensor-model classes: call ``register(cls)`` once per class.

    ``cls.name`` (lowercase-kebab, ``^[a-z][a-z0-9-]*$``) becomes the registry key and the
    ``"model"`` field of ``to_dict()``. A name another plugin already registered raises
    :class:`geoblock.errors.DuplicateModelError` naming both plugins.
    """


@hookspec
def geoblock_register_commands(cli: click.Group) -> None:
    """Add click commands or groups to the ``geoblock`` command line.

    Each plugin's implementation runs in isolation: if it raises, the command line still
    works and ``geoblock plugins`` reports the failure.
    """


# ---------------------------------------------------------------------------------------------
# Factory hooks: stop at the first non-None result
# ---------------------------------------------------------------------------------------------


@hookspec(firstresult=True)
def geoblock_read_sensor_model(
    path: Path, model_name: str | None, options: Mapping[str, Any]
) -> SensorModel | None:
    """Build a sensor model from the metadata file at ``path``.

    Return ``None`` when the file is not recognised or when ``model_name`` names a model this
    plugin does not provide. Raise :class:`geoblock.errors.ModelFormatError` (naming the file
    and the field) when the file is recognised but invalid. Stops at the first non-None
    result; generic readers (an RPC reader that accepts many products) use ``trylast=True`` so
    that specific physical models answer first.

    Parameters
    ----------
    path : pathlib.Path or geoblock.io.vsi.VsiPath
        The file the user gave (it exists), or a product directory (a reader that reads only
        files returns ``None`` for directories). A GDAL virtual path (``/vsizip/...``,
        ``/vsicurl/...``) comes as a :class:`~geoblock.io.vsi.VsiPath`, which has the
        read-only part of ``Path``'s interface (``name``, ``suffix``, ``parent``, ``/``,
        ``is_file``, ``iterdir``...): readers take paths with
        :func:`geoblock.io.vsi.as_path` (never ``Path(path)``, which collapses the ``//`` of
        ``/vsicurl/https://``), read bytes with :func:`geoblock.io.metadata.read_bytes` and
        open rasters with :func:`geoblock.io.open_quietly`, all of which read through GDAL.
    model_name : str or None
        The model the user asked for, or ``None`` for "whatever fits".
    options : mapping
        Reader options given to :func:`geoblock.open_model` as keyword arguments.
    """


@hookspec(firstresult=True)
def geoblock_write_sensor_model(
    model: SensorModel, path: Path, format: str, options: Mapping[str, Any]
) -> bool | None:
    """Write ``model`` to ``path`` in ``format`` (for example ``"rpc-txt"``).

    Return ``True`` when written, ``None`` when this plugin does not write that format or
    model. Raise :class:`geoblock.errors.ModelFormatError` when it does but the model cannot be
    represented exactly in the format. Stops at the first non-None result.
    """
