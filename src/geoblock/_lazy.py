"""Names of a package imported on first use (PEP 562), for the packages whose ``import`` must
stay cheap (``geoblock``, ``geoblock.io``, ``geoblock.ortho``, ``geoblock.adjust``): a
command imports only what it uses."""

from __future__ import annotations

import importlib
import sys
from collections.abc import Callable, Mapping
from typing import Any

__all__ = ["lazy_names"]


def lazy_names(package: str, names: Mapping[str, str]
               ) -> tuple[Callable[[str], Any], Callable[[], list[str]]]:
    """The module-level ``__getattr__`` and ``__dir__`` of ``package`` for ``names``
    (``name -> module defining it``): a name is imported from its module when first asked
    for, then kept in the package's namespace.

    Examples
    --------
    In a package ``__init__``, with the names also imported under ``if TYPE_CHECKING:`` for
    type checkers::

        __getattr__, __dir__ = lazy_names(__name__, {"open_dem": "geoblock.io.dem"})
    """

    def __getattr__(name: str) -> Any:
        module = names.get(name)
        if module is None:
            raise AttributeError(f"module {package!r} has no attribute {name!r}")
        value = getattr(importlib.import_module(module), name)
        setattr(sys.modules[package], name, value)  # later lookups skip this function
        return value

    def __dir__() -> list[str]:
        return sorted(set(vars(sys.modules[package])) | set(names))

    return __getattr__, __dir__
