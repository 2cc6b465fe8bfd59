"""geoblock-rpc: vendor RPC00B models (the ``rpc`` model), terrain-dependent RFMs fitted from
GCPs (the ``rfm`` model), sensor-oriented RPCs fitted to any model, and RPC export.

The public names are imported on first use (PEP 562): geoblock imports this package whenever
it lists its plugins, so importing it must not load numba kernels or numpy.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from geoblock_rpc.direct import DirectRfm, read_direct_rfm
    from geoblock_rpc.fit import fit_rpc
    from geoblock_rpc.fold import FoldReport, fold_correction
    from geoblock_rpc.model import RpcModel
    from geoblock_rpc.readers import read_rpc
    from geoblock_rpc.rfm import RfmFit, RfmModel, fit_rfm
    from geoblock_rpc.rpc00b import TERMS, Rpc00b

__all__ = [
    "TERMS", "DirectRfm", "FoldReport", "RfmFit", "RfmModel", "Rpc00b", "RpcModel", "fit_rfm",
    "fit_rpc", "fold_correction", "read_direct_rfm", "read_rpc",
]
__version__ = "0.1.0"

_LAZY = {
    "DirectRfm": "geoblock_rpc.direct",
    "read_direct_rfm": "geoblock_rpc.direct",
    "fit_rpc": "geoblock_rpc.fit",
    "FoldReport": "geoblock_rpc.fold",
    "fold_correction": "geoblock_rpc.fold",
    "RpcModel": "geoblock_rpc.model",
    "read_rpc": "geoblock_rpc.readers",
    "RfmFit": "geoblock_rpc.rfm",
    "RfmModel": "geoblock_rpc.rfm",
    "fit_rfm": "geoblock_rpc.rfm",
    "TERMS": "geoblock_rpc.rpc00b",
    "Rpc00b": "geoblock_rpc.rpc00b",
}


def __getattr__(name: str) -> Any:
    module = _LAZY.get(name)
    if module is None:
        raise AttributeError(f"module 'geoblock_rpc' has no attribute {name!r}")
    value = getattr(importlib.import_module(module), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(_LAZY))
