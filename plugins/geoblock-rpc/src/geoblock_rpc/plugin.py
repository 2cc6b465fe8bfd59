"""geoblock-rpc's hook implementations: the ``rpc`` model, its readers and writers."""

from __future__ import annotations

import geoblock

from geoblock_rpc.model import RpcModel


@geoblock.hookimpl
def geoblock_register_sensor_models(register):
    register(RpcModel)
