"""The plugin manager: lazy, fault-tolerant loading of the ``geoblock`` entry-point group.

* Built-in plugins (:data:`DEFAULT_PLUGINS`) go through the same hooks as third-party ones.
* Each entry point is loaded in its own ``try``: a plugin that fails to import or to register
  is skipped with a :class:`~geoblock.errors.PluginWarning` naming it and its distribution,
  and everything else keeps working.
* ``GEOBLOCK_PLUGINS=a,b`` loads only the entry points named ``a`` and ``b`` (an empty value
  loads none); built-ins always load.
* ``GEOBLOCK_TRACE_PLUGINS=1`` prints every hook call to standard error.
* Factory hooks (``firstresult``: reading and writing models) are called through
  :func:`call_firstresult`, one implementation at a time: an implementation that raises
  anything but a :class:`~geoblock.errors.GeoblockError` is a plugin bug, skipped with a
  :class:`~geoblock.errors.PluginWarning` naming the plugin, and the next one is asked. A
  ``GeoblockError`` (``ModelFormatError``: "I recognised this file and it is invalid") is the
  answer and reaches the user.

Nothing is loaded at import time; :func:`get_plugin_manager` loads once and caches, and
:func:`refresh_plugins` forgets the cache (after installing a plugin in a running session).
"""

from __future__ import annotations

import functools
import importlib
import importlib.metadata
import os
import sys
import warnings
from collections.abc import Iterable
from dataclasses import dataclass
from typing import Any

import pluggy

from geoblock import hookspecs
from geoblock.errors import GeoblockError, PluginWarning

__all__ = [
    "DEFAULT_PLUGINS",
    "ENTRY_POINT_GROUP",
    "GeoblockPluginManager",
    "HookFailure",
    "PluginInfo",
    "call_firstresult",
    "create_plugin_manager",
    "get_plugin_manager",
    "list_plugins",
    "refresh_plugins",
]

ENTRY_POINT_GROUP = "geoblock"
DEFAULT_PLUGINS: tuple[str, ...] = ("geoblock._default_plugin",)


class GeoblockPluginManager(pluggy.PluginManager):
    """A pluggy manager that remembers which distribution each plugin came from."""

    def __init__(self) -> None:
        super().__init__("geoblock")
        self.add_hookspecs(hookspecs)
        #: plugin name -> (distribution, version)
        self.distributions: dict[str, tuple[str | None, str | None]] = {}


@dataclass(frozen=True)
class HookFailure:
    """A hook implementation that raised and was skipped by :func:`call_firstresult`."""

    plugin_name: str
    hook_name: str
    exception: Exception

    @property
    def reason(self) -> str:
        """``"RuntimeError: boom"``."""
        detail = " ".join(str(self.exception).split())
        name = type(self.exception).__name__
        return f"{name}: {detail}" if detail else name


def call_firstresult(
    pm: pluggy.PluginManager, hook_name: str, **kwargs: Any
) -> tuple[Any, list[HookFailure]]:
    """Call a ``firstresult`` hook one implementation at a time, isolating faulty plugins.

    Implementations are asked in pluggy's own order (``tryfirst`` ones first, then the last
    registered first, ``trylast`` ones last) and the first result that is not ``None`` is
    returned. Each implementation runs through :meth:`pluggy.PluginManager.subset_hook_caller`,
    so hook wrappers, tracing (``GEOBLOCK_TRACE_PLUGINS``) and hook-call monitoring still apply.

    The rule for exceptions:

    * a :class:`~geoblock.errors.GeoblockError` (for a reader: "I recognised this file and it
      is invalid", naming the file and the field) propagates: it is the answer, and later
      implementations are not asked. A note naming the plugin is added to it;
    * any other :class:`Exception` is a bug of that plugin: it is skipped with a
      :class:`~geoblock.errors.PluginWarning` naming the plugin, its distribution and the
      exception, and the next implementation is asked;
    * ``KeyboardInterrupt``, ``SystemExit`` and other non-``Exception`` errors propagate.

    Parameters
    ----------
    pm : pluggy.PluginManager
    hook_name : str
        A ``firstresult`` hook, e.g. ``"geoblock_read_sensor_model"``.
    **kwargs
        The hook's arguments.

    Returns
    -------
    result : object or None
        The first non-``None`` result, or ``None`` when no implementation gave one.
    failures : list of HookFailure
        The implementations that raised and were skipped (already warned about), so that a
        "nobody could do it" error can name them.
    """
    caller = getattr(pm.hook, hook_name)
    impls = caller.get_hookimpls()
    answering = [i for i in impls if not (i.hookwrapper or getattr(i, "wrapper", False))]
    failures: list[HookFailure] = []
    asked: list[object] = []
    for impl in reversed(answering):  # the order pluggy's own _multicall uses
        if any(impl.plugin is plugin for plugin in asked):
            continue  # a plugin with several implementations of the hook: asked once, in full
        asked.append(impl.plugin)
        others = [i.plugin for i in answering if i.plugin is not impl.plugin]
        single = pm.subset_hook_caller(hook_name, remove_plugins=others)
        try:
            result = single(**kwargs)
        except GeoblockError as exc:
            if impl.plugin_name not in DEFAULT_PLUGINS:
                exc.add_note(f"(raised by geoblock plugin {impl.plugin_name!r}, {hook_name})")
            raise
        except Exception as exc:  # a bug of third-party code must not break geoblock
            failure = HookFailure(impl.plugin_name, hook_name, exc)
            failures.append(failure)
            dist, version = plugin_distribution(pm, impl.plugin_name)
            origin = f", distribution {dist!r} {version}" if dist else ""
            warnings.warn(
                f"geoblock plugin {impl.plugin_name!r}{origin} failed in {hook_name} and was "
                f"skipped: {failure.reason}",
                PluginWarning,
                stacklevel=3,
            )
            continue
        if result is not None:
            return result, failures
    return None, failures


@dataclass(frozen=True)
class PluginInfo:
    """What ``geoblock plugins`` shows about one plugin."""

    name: str
    distribution: str | None
    version: str | None
    hooks: tuple[str, ...]
    models: tuple[str, ...] = ()


def _allowed_entry_points() -> set[str] | None:
    value = os.environ.get("GEOBLOCK_PLUGINS")
    if value is None:
        return None
    return {v.strip() for v in value.split(",") if v.strip()}


def create_plugin_manager(
    *,
    entry_points: bool = True,
    plugins: Iterable[object] = (),
) -> GeoblockPluginManager:
    """A new plugin manager with the built-ins, the entry points (optional) and ``plugins``.

    Parameters
    ----------
    entry_points : bool
        Load the ``geoblock`` entry-point group (honouring ``GEOBLOCK_PLUGINS``).
    plugins : iterable
        Extra plugin objects (modules or instances with hook implementations), for tests and
        embedding.
    """
    pm = GeoblockPluginManager()
    for module_name in DEFAULT_PLUGINS:
        pm.register(importlib.import_module(module_name), name=module_name)
        pm.distributions[module_name] = ("geoblock", _version("geoblock"))
    if entry_points:
        _load_entry_points(pm)
    for plugin in plugins:
        _register_guarded(pm, plugin, getattr(plugin, "__name__", None), None)
    _check_pending(pm)
    if os.environ.get("GEOBLOCK_TRACE_PLUGINS"):
        pm.trace.root.setwriter(lambda text: sys.stderr.write(text))
        pm.enable_tracing()
    return pm


def _version(dist: str) -> str | None:
    try:
        return importlib.metadata.version(dist)
    except importlib.metadata.PackageNotFoundError:
        return None


def _load_entry_points(pm: GeoblockPluginManager) -> None:
    allowed = _allowed_entry_points()
    for ep in importlib.metadata.entry_points(group=ENTRY_POINT_GROUP):
        if allowed is not None and ep.name not in allowed:
            continue
        dist = ep.dist.name if ep.dist is not None else None
        version = ep.dist.version if ep.dist is not None else None
        if pm.get_plugin(ep.name) is not None:
            owner = pm.distributions.get(ep.name, (None,))[0]
            warnings.warn(
                f"geoblock plugin {ep.name!r} from distribution {dist!r} was skipped: "
                f"a plugin of that name is already loaded from {owner!r}",
                PluginWarning,
                stacklevel=3,
            )
            continue
        try:
            module = ep.load()
        except Exception as exc:  # any failure of third-party code must not break geoblock
            warnings.warn(
                f"geoblock plugin {ep.name!r} ({ep.value}, distribution {dist!r} {version}) "
                f"failed to import and was skipped: {type(exc).__name__}: {exc}",
                PluginWarning,
                stacklevel=3,
            )
            continue
        _register_guarded(pm, module, ep.name, (dist, version))


def _register_guarded(pm, plugin, name, dist_version) -> None:
    try:
        registered = pm.register(plugin, name=name)
    except Exception as exc:  # pluggy.PluginValidationError, ValueError for duplicates
        warnings.warn(
            f"geoblock plugin {name!r} was skipped: {type(exc).__name__}: {exc}",
            PluginWarning,
            stacklevel=4,
        )
        return
    if registered is not None:
        pm.distributions[registered] = dist_version or (None, None)


def _check_pending(pm: pluggy.PluginManager) -> None:
    """Unregister, with a warning, plugins implementing hooks geoblock does not define."""
    while True:
        try:
            pm.check_pending()
            return
        except pluggy.PluginValidationError as exc:
            name = pm.get_name(exc.plugin)
            warnings.warn(
                f"geoblock plugin {name!r} was skipped: {exc} (a misspelt geoblock_* hook?)",
                PluginWarning,
                stacklevel=3,
            )
            pm.unregister(exc.plugin)


@functools.lru_cache(maxsize=1)
def get_plugin_manager() -> GeoblockPluginManager:
    """The process-wide plugin manager, loaded on first use and cached."""
    return create_plugin_manager()


def refresh_plugins() -> None:
    """Forget the cached plugin manager and model registry; the next use reloads them."""
    from geoblock.models import registry as _registry

    get_plugin_manager.cache_clear()
    _registry.get_registry.cache_clear()


def plugin_distribution(pm: pluggy.PluginManager, name: str) -> tuple[str | None, str | None]:
    """``(distribution, version)`` of a plugin registered under ``name``."""
    return getattr(pm, "distributions", {}).get(name, (None, None))


def list_plugins(pm: pluggy.PluginManager | None = None) -> list[PluginInfo]:
    """Every loaded plugin with its distribution, version, hooks and registered models."""
    from geoblock.models.registry import build_registry, get_registry

    if pm is None:
        pm = get_plugin_manager()
        reg = get_registry()
    else:
        reg = build_registry(pm)
    out = []
    for name, plugin in sorted(pm.list_name_plugin(), key=lambda item: item[0]):
        dist, version = plugin_distribution(pm, name)
        hooks = tuple(sorted(h.name for h in pm.get_hookcallers(plugin) or ()))
        models = tuple(m for m in reg.names() if reg.owner(m) == name)
        out.append(PluginInfo(name, dist, version, hooks, models))
    return out
