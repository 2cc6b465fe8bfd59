"""The vectorised numpy reference of the RPC00B evaluation (no numba).

Slower than :mod:`geoblock_rpc._kernels` and written independently of it, term by term from
:data:`geoblock_rpc.rpc00b.TERMS`; the tests hold the two to agreement.
"""

from __future__ import annotations

import numpy as np

from geoblock_rpc.rpc00b import Rpc00b, evaluate_terms

__all__ = ["normalise", "project"]


def normalise(rpc: Rpc00b, lon, lat, h):
    """Normalised ``(L, P, H)``; ``lon - LONG_OFF`` wrapped into [-180, 180)."""
    d = (np.asarray(lon, float) - rpc.long_off + 180.0) % 360.0 - 180.0
    return (
        d / rpc.long_scale,
        (np.asarray(lat, float) - rpc.lat_off) / rpc.lat_scale,
        (np.asarray(h, float) - rpc.height_off) / rpc.height_scale,
    )


def project(rpc: Rpc00b, lon, lat, h) -> tuple[np.ndarray, np.ndarray]:
    """``(row, col)`` pixels, pixel-centre convention, with no validity-domain check."""
    terms = evaluate_terms(*normalise(rpc, lon, lat, h))
    values = terms @ rpc.coefficients.T  # (*S, 4)
    row = values[..., 0] / values[..., 1] * rpc.line_scale + rpc.line_off
    col = values[..., 2] / values[..., 3] * rpc.samp_scale + rpc.samp_off
    return row, col
