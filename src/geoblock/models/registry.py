"""The sensor-model registry, built from the ``geoblock_register_sensor_models`` hook."""

from __future__ import annotations

import re
import warnings
from collections.abc import Iterator, Mapping
from typing import Any

import pluggy

from geoblock.errors import (
    DuplicateModelError,
    GeoblockError,
    PluginError,
    PluginWarning,
    SerializationError,
    UnknownModelError,
)
from geoblock.models.protocol import SensorModel

__all__ = ["ModelRegistry", "build_registry"]

_NAME = re.compile(r"^[a-z][a-z0-9-]*$")
_REQUIRED = (
    "project",
    "backproject",
    "project_with_status",
    "backproject_with_status",
    "partials_ground",
    "partials_parameters",
    "with_parameters",
    "to_dict",
    "from_dict",
)


def _validate(cls: object, plugin: str) -> None:
    if not isinstance(cls, type):
        raise PluginError(f"plugin {plugin!r} registered {cls!r}, which is not a class", plugin)
    name = getattr(cls, "name", None)
    if not isinstance(name, str) or not _NAME.match(name):
        raise PluginError(
            f"plugin {plugin!r}: model class {cls.__qualname__} needs a class attribute "
            f"`name` matching {_NAME.pattern} (lowercase-kebab), got {name!r}",
            plugin,
        )
    missing = [m for m in _REQUIRED if not callable(getattr(cls, m, None))]
    if not isinstance(getattr(cls, "schema_version", None), int):
        missing.append("schema_version")
    if missing:
        raise PluginError(
            f"plugin {plugin!r}: model class {cls.__qualname__} does not implement the "
            f"SensorModel protocol (missing {missing})",
            plugin,
        )


class ModelRegistry:
    """Sensor-model classes by name, each with the plugin that registered it.

    Iterating yields the names; ``name in registry`` tests membership. A model class may
    declare ``aliases`` (a class attribute, a tuple of lowercase-kebab names, e.g.
    ``("quickbird", "worldview")`` for ``dg-rigorous``): :meth:`get`, ``in`` and
    :meth:`from_dict` accept them too; :meth:`names` lists the canonical names.
    """

    def __init__(self) -> None:
        self._classes: dict[str, type[SensorModel]] = {}
        self._owners: dict[str, str] = {}
        self._aliases: dict[str, str] = {}  # alias -> canonical name

    def register(self, cls: type[SensorModel], *, plugin: str = "<direct>") -> None:
        """Add a model class under ``cls.name``.

        Raises
        ------
        DuplicateModelError
            If another plugin registered the name already (both are named).
        PluginError
            If ``cls`` is not a class with a valid ``name`` and the protocol's methods.
        """
        _validate(cls, plugin)
        name = cls.name
        aliases = getattr(cls, "aliases", ())
        if isinstance(aliases, str) or not all(
                isinstance(a, str) and _NAME.match(a) for a in aliases):
            raise PluginError(
                f"plugin {plugin!r}: model class {cls.__qualname__}: `aliases` must be a tuple "
                f"of names matching {_NAME.pattern}, got {aliases!r}", plugin_name=plugin)
        for key in (name, *aliases):
            if key in self._classes or key in self._aliases:
                owner = self._aliases.get(key, key)
                other = self._classes[owner]
                raise DuplicateModelError(
                    f"sensor model name {key!r} is registered twice: by plugin "
                    f"{self._owners[owner]!r} ({other.__module__}.{other.__qualname__}) and by "
                    f"plugin {plugin!r} ({cls.__module__}.{cls.__qualname__}); uninstall one of "
                    "them or restrict loading with GEOBLOCK_PLUGINS",
                    plugin_name=plugin,
                )
        self._classes[name] = cls
        self._owners[name] = plugin
        for alias in aliases:
            self._aliases[alias] = name

    def get(self, name: str) -> type[SensorModel]:
        """The class registered as ``name``; :class:`UnknownModelError` lists the known ones."""
        try:
            return self._classes[self._aliases.get(name, name)]
        except (KeyError, TypeError):
            raise UnknownModelError(
                f"no sensor model named {name!r}; registered models: "
                f"{', '.join(self.names()) or '(none)'}. Is its plugin installed? "
                "(`geoblock plugins` lists what is loaded)"
            ) from None

    def owner(self, name: str) -> str:
        """The plugin that registered ``name``."""
        self.get(name)
        return self._owners[self._aliases.get(name, name)]

    def names(self) -> list[str]:
        """Registered model names, sorted."""
        return sorted(self._classes)

    def aliases(self) -> dict[str, str]:
        """Alias -> canonical name of every registered alias."""
        return dict(self._aliases)

    def __contains__(self, name: object) -> bool:
        return name in self._classes or name in self._aliases

    def __iter__(self) -> Iterator[str]:
        return iter(self.names())

    def __len__(self) -> int:
        return len(self._classes)

    def from_dict(self, data: Mapping[str, Any]) -> SensorModel:
        """Rebuild any registered model from its ``to_dict()`` output.

        Dispatches on ``data["model"]`` and checks ``data["schema_version"]``.

        Raises
        ------
        SerializationError
            When ``data`` is not a model dictionary, its schema is newer than the installed
            model understands, or the model's ``from_dict`` rejects it.
        UnknownModelError
            When ``data["model"]`` is not registered.
        """
        if not isinstance(data, Mapping) or not isinstance(data.get("model"), str):
            raise SerializationError(
                "a model dictionary needs a string field 'model' naming the sensor model; got "
                f"{type(data).__name__} with keys "
                f"{sorted(data) if isinstance(data, Mapping) else []}"
            )
        name = data["model"]
        cls = self.get(name)
        version = data.get("schema_version", 1)
        if not isinstance(version, int) or version > cls.schema_version or version < 1:
            raise SerializationError(
                f"model {name!r}: schema_version {version!r} is not supported by the installed "
                f"plugin {self.owner(name)!r} (it reads versions 1..{cls.schema_version}); "
                "upgrade the plugin"
            )
        try:
            return cls.from_dict(data)
        except GeoblockError:
            raise
        except (KeyError, TypeError, ValueError, IndexError) as exc:
            raise SerializationError(
                f"model {name!r}: invalid model dictionary: {type(exc).__name__}: {exc}"
            ) from exc


def build_registry(pm: pluggy.PluginManager) -> ModelRegistry:
    """Build a registry by calling every plugin's ``geoblock_register_sensor_models``.

    Each plugin registers into a staging list first, so a plugin whose hook raises is skipped
    whole (with a :class:`PluginWarning`); a name clash raises :class:`DuplicateModelError`.
    """
    registry = ModelRegistry()
    for impl in reversed(pm.hook.geoblock_register_sensor_models.get_hookimpls()):
        staged: list[type[SensorModel]] = []
        try:
            kwargs = {"register": staged.append}
            impl.function(*[kwargs[a] for a in impl.argnames])
        except Exception as exc:  # third-party code must not take geoblock down
            warnings.warn(
                f"geoblock plugin {impl.plugin_name!r} failed to register its sensor models "
                f"and was skipped: {type(exc).__name__}: {exc}",
                PluginWarning,
                stacklevel=3,
            )
            continue
        try:
            for cls in staged:
                _validate(cls, impl.plugin_name)
        except PluginError as exc:
            warnings.warn(f"{exc}; the plugin's models were skipped", PluginWarning, stacklevel=3)
            continue
        for cls in staged:
            registry.register(cls, plugin=impl.plugin_name)
    return registry


def __getattr__(name: str) -> Any:
    """``get_registry`` and ``from_dict`` live with the process-wide plugin manager
    (:mod:`geoblock.plugins`) since 0.2; they stay importable from here."""
    if name in ("get_registry", "from_dict"):
        from geoblock import plugins

        return getattr(plugins, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
