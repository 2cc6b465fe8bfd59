"""geoblock-rpc: vendor RPC00B models for geoblock (registered as the ``rpc`` model)."""

from geoblock_rpc.model import RpcModel
from geoblock_rpc.rpc00b import TERMS, Rpc00b

__all__ = ["TERMS", "Rpc00b", "RpcModel"]
__version__ = "0.1.0"
