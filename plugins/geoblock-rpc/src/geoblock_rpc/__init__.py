"""geoblock-rpc: vendor RPC00B models (the ``rpc`` model), terrain-dependent RFMs fitted from
GCPs (the ``rfm`` model), sensor-oriented RPCs fitted to any model, and RPC export."""

from geoblock_rpc.fit import fit_rpc
from geoblock_rpc.fold import FoldReport, fold_correction
from geoblock_rpc.model import RpcModel
from geoblock_rpc.readers import read_rpc
from geoblock_rpc.rfm import RfmFit, RfmModel, fit_rfm
from geoblock_rpc.rpc00b import TERMS, Rpc00b

__all__ = [
    "TERMS", "FoldReport", "RfmFit", "RfmModel", "Rpc00b", "RpcModel", "fit_rfm", "fit_rpc",
    "fold_correction", "read_rpc",
]
__version__ = "0.1.0"
