"""geoblock-rpc: vendor RPC00B models for geoblock (registered as the ``rpc`` model)."""

from geoblock_rpc.fit import fit_rpc
from geoblock_rpc.fold import FoldReport, fold_correction
from geoblock_rpc.model import RpcModel
from geoblock_rpc.readers import read_rpc
from geoblock_rpc.rpc00b import TERMS, Rpc00b

__all__ = ["TERMS", "FoldReport", "Rpc00b", "RpcModel", "fit_rpc", "fold_correction", "read_rpc"]
__version__ = "0.1.0"
