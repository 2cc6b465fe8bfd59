"""The RPC00B projection of small batches in numpy: the compiled kernel's bits, without numba.

A command that projects a few points (``geoblock project``, a test, a plausibility check)
would spend 0.35 s importing numba and building its typing registries before the kernel's
first call, for microseconds of work. :func:`project` does the very operations of
:func:`geoblock_rpc._kernels._project_one` (numba compiles it without fast-math: IEEE
operations in source order, no fused multiply-add), one numpy operation over all points at a
time, in the kernel's order, so both give the same bits for every point, NaNs and statuses
included (tested on every shared RPC file). Which of the two runs a batch
(:func:`geoblock_rpc.model.RpcModel.project_with_status`) therefore changes no result.
"""

from __future__ import annotations

import numpy as np

from geoblock_rpc._params import (
    CONVERGED,
    DIVERGED,
    HAS_BOX,
    HEIGHT_LIMIT,
    HEIGHT_OFF,
    HEIGHT_SCALE,
    INV360,
    INVALID_INPUT,
    LAT_OFF,
    LAT_SCALE,
    LIMIT,
    LINE_OFF,
    LINE_SCALE,
    LON_LIMIT,
    LONG_OFF,
    LONG_SCALE,
    MAX_LAT,
    MAX_LONG,
    MIN_LAT,
    MIN_LONG,
    OUT_OF_DOMAIN,
    SAMP_OFF,
    SAMP_SCALE,
)

__all__ = ["project"]


def _wrap_near(lon: np.ndarray, ref: float) -> np.ndarray:
    """``lon - ref`` wrapped into [-180, 180): the kernel's ``_wrap_near``, operation for
    operation."""
    d = lon - ref
    return d - 360.0 * np.floor((d + 180.0) * INV360)


def project(lon: np.ndarray, lat: np.ndarray, h: np.ndarray, prm: np.ndarray, coef: np.ndarray,
            row: np.ndarray, col: np.ndarray, status: np.ndarray) -> None:
    """Ground (degrees, metres) -> image (pixels), NaN and a status where a point fails.

    The signature and the results of :func:`geoblock_rpc._kernels.project_serial`: ``lon, lat,
    h`` (N,) float64; ``prm`` from :func:`geoblock_rpc._params.pack`; ``coef`` (4, 20) in
    RPC00B term order; written into ``row, col`` (N,) float64 and ``status`` (N,) uint8.
    """
    p = [float(v) for v in prm]  # Python floats are IEEE doubles: the kernel's scalars
    with np.errstate(all="ignore"):
        finite = (np.abs(lon) < np.inf) & (np.abs(lat) < np.inf) & (np.abs(h) < np.inf)
        L = _wrap_near(lon, p[LONG_OFF]) / p[LONG_SCALE]
        P = (lat - p[LAT_OFF]) / p[LAT_SCALE]
        H = (h - p[HEIGHT_OFF]) / p[HEIGHT_SCALE]
        limit = p[LIMIT]
        inside = ((np.abs(L) <= limit) & (np.abs(P) <= limit) & (np.abs(H) <= p[HEIGHT_LIMIT])
                  & (np.abs(lon) <= LON_LIMIT) & (np.abs(lat) <= 90.0))
        if p[HAS_BOX] != 0.0:
            span_lon = p[MAX_LONG] - p[MIN_LONG]
            span_lat = p[MAX_LAT] - p[MIN_LAT]
            margin = 0.5 * (limit - 1.0)
            d = _wrap_near(lon, p[MIN_LONG])
            inside &= ((d >= -margin * span_lon) & (d <= (1.0 + margin) * span_lon)
                       & (lat >= p[MIN_LAT] - margin * span_lat)
                       & (lat <= p[MAX_LAT] + margin * span_lat))
        LP = L * P
        LH = L * H
        PH = P * H
        LL = L * L
        PP = P * P
        HH = H * H
        # the 20 terms of RPC00B (geoblock_rpc.rpc00b.TERMS), products formed as the kernel's
        # _poly20 forms them; the constant term's product with 1.0 is the coefficient itself
        terms = (L, P, H, LP, LH, PH, LL, PP, HH, LP * H, LL * L, L * PP, L * HH, LL * P,
                 PP * P, P * HH, LL * H, PP * H, HH * H)
        # the four polynomials together, summed left to right as _dot20's expression is
        c = np.asarray(coef, dtype=np.float64)
        acc = np.empty((4, lon.shape[0]))
        acc[...] = c[:, :1] * 1.0
        tmp = np.empty_like(acc)
        for k, t in enumerate(terms, start=1):
            np.multiply(c[:, k:k + 1], t, out=tmp)
            acc += tmp
        r = (acc[0] / acc[1]) * p[LINE_SCALE] + p[LINE_OFF]
        cc = (acc[2] / acc[3]) * p[SAMP_SCALE] + p[SAMP_OFF]
        converged = (np.abs(r) < np.inf) & (np.abs(cc) < np.inf)
        st = np.where(converged, np.uint8(CONVERGED), np.uint8(DIVERGED))
        st = np.where(inside, st, np.uint8(OUT_OF_DOMAIN))
        status[...] = np.where(finite, st, np.uint8(INVALID_INPUT))
        good = finite & inside & converged
        row[...] = np.where(good, r, np.nan)
        col[...] = np.where(good, cc, np.nan)
