"""An opt-in plugin registering the synthetic test models (``synthetic-affine``,
``synthetic-pushbroom``, from :mod:`geoblock.testing.synthetic`).

They are test models, not user models: a user's registry does not list them. Load them

* in Python, with :func:`enable_synthetic_models` (for the rest of the process, also after
  :func:`geoblock.plugins.refresh_plugins`);
* for a process started from the shell (the ``geoblock`` command, a subprocess of a test),
  with the environment variable ``GEOBLOCK_PLUGIN_MODULES=geoblock.testing.plugin``.

Once loaded, model JSON naming them opens with :func:`geoblock.open_model`, and models wrapping
them (``ImageCorrection(AffineCamera.example())``) rebuild through the registry. Without it,
the classes still work on their own (build, project, pickle, ``to_dict``/``from_dict``);
only opening their JSON by name needs the registry.
"""

from __future__ import annotations

from typing import Any

from geoblock.hookspecs import hookimpl

__all__ = ["MODEL_NAMES", "MODULE", "disable_synthetic_models", "enable_synthetic_models"]

#: This module's name: the value of ``GEOBLOCK_PLUGIN_MODULES`` that loads it.
MODULE = __name__
#: The names of the models this plugin registers.
MODEL_NAMES: tuple[str, ...] = ("synthetic-affine", "synthetic-pushbroom")


@hookimpl
def geoblock_register_sensor_models(register: Any) -> None:
    from geoblock.testing.synthetic import AffineCamera, ConstantVelocityPushbroom

    register(AffineCamera)
    register(ConstantVelocityPushbroom)


def enable_synthetic_models() -> None:
    """Register the synthetic test models in this process's plugin manager.

    Equivalent to ``geoblock.plugins.enable_plugin_module("geoblock.testing.plugin")``; it
    lasts until :func:`disable_synthetic_models`, :func:`geoblock.plugins.refresh_plugins`
    included. Calling it again does nothing. Subprocesses do not inherit it: set
    ``GEOBLOCK_PLUGIN_MODULES=geoblock.testing.plugin`` in their environment.

    Examples
    --------
    >>> import geoblock.testing
    >>> geoblock.testing.enable_synthetic_models()
    >>> "synthetic-affine" in geoblock.models.get_registry()
    True
    """
    from geoblock.plugins import enable_plugin_module

    enable_plugin_module(MODULE)


def disable_synthetic_models() -> None:
    """Undo :func:`enable_synthetic_models` (the environment variable still applies)."""
    from geoblock.plugins import disable_plugin_module

    disable_plugin_module(MODULE)
