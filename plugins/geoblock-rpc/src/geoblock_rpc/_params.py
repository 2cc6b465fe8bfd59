"""The constants array ``prm`` of the RPC00B evaluation (no numba).

Shared by the compiled kernels (:mod:`geoblock_rpc._kernels`) and the numpy small-batch
projection (:mod:`geoblock_rpc._small`): building a model (:func:`pack`) imports no numba.
"""

from __future__ import annotations

import numpy as np

from geoblock_rpc.rpc00b import Rpc00b

# indices into prm
LAT_OFF, LONG_OFF, HEIGHT_OFF, LAT_SCALE, LONG_SCALE, HEIGHT_SCALE = range(6)
LINE_OFF, SAMP_OFF, LINE_SCALE, SAMP_SCALE, LIMIT = range(6, 11)
MIN_LONG, MAX_LONG, MIN_LAT, MAX_LAT, HAS_BOX, HEIGHT_LIMIT = range(11, 17)
N_PRM = 17

CONVERGED, MAX_ITERATIONS, DIVERGED, OUT_OF_DOMAIN, INVALID_INPUT = 0, 1, 2, 3, 6

#: longitudes beyond this magnitude are no position on the Earth in any convention
#: (-180..180, 0..360, and unwrapped tracks up to half a turn beyond): OUT_OF_DOMAIN
LON_LIMIT = 540.0

#: 1/360 for the longitude wraps of the projection: a product where the quotient would be
#: the slowest instruction of the loop. For every point of a model's domain ``(d + 180) / 360``
#: lies in (0, 1) either way, so the floor is 0 and the wrapped value the same bits; only a
#: point 180 degrees away from the reference (far outside any domain) may wrap to -180 instead
#: of +180, the same place.
INV360 = 1.0 / 360.0


def pack(
    rpc: Rpc00b, limit: float, height_limit: float, box: tuple[float | None, ...] | None
) -> np.ndarray:
    """The constants array of a :class:`~geoblock_rpc.Rpc00b` for the kernels; ``box``
    ``(min_long, max_long, min_lat, max_lat)`` degrees, or None for no validity box."""
    prm = np.zeros(N_PRM)
    prm[HEIGHT_LIMIT] = height_limit
    prm[:11] = (rpc.lat_off, rpc.long_off, rpc.height_off, rpc.lat_scale, rpc.long_scale,
                rpc.height_scale, rpc.line_off, rpc.samp_off, rpc.line_scale, rpc.samp_scale,
                limit)
    if box is not None:
        prm[MIN_LONG:MAX_LAT + 1] = box
        prm[HAS_BOX] = 1.0
    return prm
