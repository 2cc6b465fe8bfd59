"""geoblock-spot's hook implementations: its models and the DIMAP reader."""

from __future__ import annotations

import geoblock


@geoblock.hookimpl
def geoblock_register_sensor_models(register):
    pass
