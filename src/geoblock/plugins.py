"""The plugin manager: lazy, fault-tolerant loading of the ``geoblock`` entry-point group.

* Built-in plugins (:data:`DEFAULT_PLUGINS`) go through the same hooks as third-party ones.
* Each entry point is loaded in its own ``try``: a plugin that fails to import or to register
  is skipped with a :class:`~geoblock.errors.PluginWarning` naming it and its distribution,
  and everything else keeps working.
* ``GEOBLOCK_PLUGINS=a,b`` loads only the entry points named ``a`` and ``b`` (an empty value
  loads none); built-ins always load.
* ``GEOBLOCK_PLUGIN_MODULES=pkg.mod,other.mod`` also loads those modules as plugins, without
  an entry point (like pytest's ``-p``): a plugin under development, or geoblock's synthetic
  test models (``geoblock.testing.plugin``). Each is imported in its own ``try`` like an entry
  point, registered under its module name, and listed by ``geoblock plugins``;
  ``GEOBLOCK_PLUGINS`` does not restrict them. In Python, :func:`enable_plugin_module` does the
  same for the rest of the process.
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
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import pluggy

from geoblock import hookspecs
from geoblock.errors import GeoblockError, PluginError, PluginWarning

if TYPE_CHECKING:
    from geoblock.models.protocol import SensorModel
    from geoblock.models.registry import ModelRegistry

__all__ = [
    "DEFAULT_PLUGINS",
    "ENTRY_POINT_GROUP",
    "GeoblockPluginManager",
    "HookFailure",
    "PLUGIN_MODULES_VARIABLE",
    "PluginInfo",
    "call_firstresult",
    "create_plugin_manager",
    "disable_plugin_module",
    "enable_plugin_module",
    "from_dict",
    "get_plugin_manager",
    "get_registry",
    "list_plugins",
    "plugin_modules",
    "refresh_plugins",
]

ENTRY_POINT_GROUP = "geoblock"
DEFAULT_PLUGINS: tuple[str, ...] = ("geoblock._default_plugin",)
#: The environment variable naming extra plugin modules (comma-separated).
PLUGIN_MODULES_VARIABLE = "GEOBLOCK_PLUGIN_MODULES"
#: Modules enabled in this process by :func:`enable_plugin_module`, in order.
_enabled_modules: list[str] = []


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


def plugin_modules() -> tuple[str, ...]:
    """The extra plugin modules a new plugin manager loads.

    Those named in ``GEOBLOCK_PLUGIN_MODULES`` (comma-separated), then those enabled by
    :func:`enable_plugin_module`, each once.
    """
    named = os.environ.get(PLUGIN_MODULES_VARIABLE, "").split(",")
    return tuple(dict.fromkeys(m for m in (n.strip() for n in named + _enabled_modules) if m))


def enable_plugin_module(module_name: str) -> None:
    """Load the module ``module_name`` as a plugin in this process from now on.

    The module (hook implementations at its top level, as an entry point's) is imported now, so
    that a mistake fails here; the cached plugin manager and model registry are refreshed, and
    every manager built later (after :func:`refresh_plugins` too) registers it. Enabling a
    module twice does nothing. Subprocesses do not inherit this: give them
    ``GEOBLOCK_PLUGIN_MODULES`` instead.

    Parameters
    ----------
    module_name : str
        An importable module, e.g. ``"geoblock.testing.plugin"``.

    Raises
    ------
    PluginError
        The module cannot be imported (the message gives the reason).
    """
    try:
        importlib.import_module(module_name)
    except Exception as exc:  # any failure of the module's code
        raise PluginError(
            f"geoblock plugin module {module_name!r} cannot be imported: "
            f"{type(exc).__name__}: {exc}",
            module_name,
        ) from exc
    if module_name not in _enabled_modules:
        _enabled_modules.append(module_name)
        refresh_plugins()


def disable_plugin_module(module_name: str) -> None:
    """Stop loading a module enabled by :func:`enable_plugin_module` (refreshes the cached
    manager; a module named in ``GEOBLOCK_PLUGIN_MODULES`` still loads)."""
    if module_name in _enabled_modules:
        _enabled_modules.remove(module_name)
        refresh_plugins()


def create_plugin_manager(
    *,
    entry_points: bool = True,
    plugins: Iterable[object] = (),
    modules: Iterable[str] | None = None,
) -> GeoblockPluginManager:
    """A new plugin manager with the built-ins, the entry points (optional), the extra plugin
    modules and ``plugins``.

    Parameters
    ----------
    entry_points : bool
        Load the ``geoblock`` entry-point group (honouring ``GEOBLOCK_PLUGINS``).
    plugins : iterable
        Extra plugin objects (modules or instances with hook implementations), for tests and
        embedding.
    modules : iterable of str, optional
        Plugin modules to import and register by name; by default :func:`plugin_modules`
        (``GEOBLOCK_PLUGIN_MODULES`` and :func:`enable_plugin_module`'s), loaded whatever
        ``entry_points`` says. ``()`` loads none.
    """
    pm = GeoblockPluginManager()
    for module_name in DEFAULT_PLUGINS:
        pm.register(importlib.import_module(module_name), name=module_name)
        pm.distributions[module_name] = ("geoblock", _version("geoblock"))
    if entry_points:
        _load_entry_points(pm)
    for module_name in plugin_modules() if modules is None else modules:
        _load_module(pm, module_name)
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


def _load_module(pm: GeoblockPluginManager, module_name: str) -> None:
    """Import and register a plugin module by name; a failure is a warning, not an error."""
    try:
        module = importlib.import_module(module_name)
    except Exception as exc:  # any failure of third-party code must not break geoblock
        warnings.warn(
            f"geoblock plugin module {module_name!r} (from {PLUGIN_MODULES_VARIABLE} or "
            f"enable_plugin_module) failed to import and was skipped: "
            f"{type(exc).__name__}: {exc}",
            PluginWarning,
            stacklevel=3,
        )
        return
    if pm.is_registered(module):  # already loaded as a built-in or an entry point
        return
    _register_guarded(pm, module, module_name, _module_distribution(module_name))


def _module_distribution(module_name: str) -> tuple[str | None, str | None]:
    """``(distribution, version)`` installing the top-level package of ``module_name``:
    the distribution of the package's name (editable installs list no files), else the one
    whose files hold the package, else ``(None, None)`` (a module on ``sys.path``)."""
    top = module_name.partition(".")[0]
    try:
        dist = importlib.metadata.distribution(top)
        return dist.metadata["Name"], dist.version
    except importlib.metadata.PackageNotFoundError:
        pass
    dists = _packages_distributions().get(top, [])
    if len(dists) != 1:  # not installed, or ambiguous
        return None, None
    return dists[0], _version(dists[0])


@functools.lru_cache(maxsize=1)
def _packages_distributions() -> Mapping[str, list[str]]:
    """:func:`importlib.metadata.packages_distributions`, cached (it reads every installed
    distribution's file list); :func:`refresh_plugins` forgets it."""
    return importlib.metadata.packages_distributions()


def _register_guarded(
    pm: GeoblockPluginManager,
    plugin: object,
    name: str | None,
    dist_version: tuple[str | None, str | None] | None,
) -> None:
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


@functools.lru_cache(maxsize=1)
def get_registry() -> ModelRegistry:
    """The model registry of the process-wide plugin manager (cached; see
    :func:`refresh_plugins`)."""
    from geoblock.models.registry import build_registry

    return build_registry(get_plugin_manager())


def from_dict(data: Mapping[str, Any]) -> SensorModel:
    """Rebuild any registered sensor model from its ``to_dict()`` output.

    Raises
    ------
    UnknownModelError
        The ``model`` name is not registered (the message lists the registered names).
    SerializationError
        The dictionary is not a valid model of that name.
    """
    return get_registry().from_dict(data)


def refresh_plugins() -> None:
    """Forget the cached plugin manager and model registry; the next use reloads them."""
    get_plugin_manager.cache_clear()
    get_registry.cache_clear()
    _packages_distributions.cache_clear()


def plugin_distribution(pm: pluggy.PluginManager, name: str) -> tuple[str | None, str | None]:
    """``(distribution, version)`` of a plugin registered under ``name``."""
    return getattr(pm, "distributions", {}).get(name, (None, None))


def list_plugins(pm: pluggy.PluginManager | None = None) -> list[PluginInfo]:
    """Every loaded plugin with its distribution, version, hooks and registered models."""
    from geoblock.models.registry import build_registry

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
