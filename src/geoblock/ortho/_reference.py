"""Vectorised numpy reference of the orthorectifier's compiled resampling kernels (for the
tests only: :mod:`geoblock.ortho.kernels` is held to it, to floating-point rounding).
"""

from __future__ import annotations

import numpy as np

from geoblock.dem.sampling import _keys
from geoblock.ortho.kernels import _TAPS, SINC_HALF_WIDTH
from geoblock.pixels import PIXEL_CENTRE

__all__ = ["resample_reference"]


def _axis(x: np.ndarray, kernel: str) -> tuple[np.ndarray, np.ndarray]:
    """First tap index (M,) intp and weights (M, n) of each finite coordinate ``x`` (M,)."""
    n, first = _TAPS[kernel]
    if kernel == "nearest":
        # the pixel holding the point
        return np.floor(x + PIXEL_CENTRE).astype(np.intp), np.ones((x.size, 1))
    base = np.floor(x)
    t = x - base
    if kernel == "bilinear":
        w = np.stack([1.0 - t, t], axis=-1)
    elif kernel == "bicubic":
        w = _keys(t)
    else:
        d = t[:, None] - np.arange(first, first + n)[None, :]  # point minus tap, (M, 16)
        w = np.where(np.abs(d) < SINC_HALF_WIDTH, np.sinc(d) * np.sinc(d / SINC_HALF_WIDTH), 0.0)
        w = w / w.sum(axis=-1, keepdims=True)
        w[t == 0.0] = (np.arange(first, first + n) == 0).astype(np.float64)  # exactly a delta
    return base.astype(np.intp) + first, w


def resample_reference(
    src: np.ndarray,
    row: np.ndarray,
    col: np.ndarray,
    kernel: str,
    mask: np.ndarray | None = None,
    block: int = 1 << 14,
) -> tuple[np.ndarray, np.ndarray]:
    """Vectorised numpy reference of :func:`~geoblock.ortho.kernels.resample` on flat
    ``row, col`` (N,), ``src`` as :func:`~geoblock.ortho.kernels._prepare` gives it.

    ``mask`` (R, C) is True at nodata pixels. Returns ``values`` (bands, N) and ``valid``
    (N,). Works in blocks of ``block`` points to bound the (bands, M, n, n) tap arrays.
    """
    bands, rows, cols = src.shape
    n_pts = row.size
    values = np.full((bands, n_pts), np.nan)
    valid = np.zeros(n_pts, dtype=bool)
    n = _TAPS[kernel][0]
    step = max(1, block // (n * n))
    for s in range(0, n_pts, step):
        r, c = row[s:s + step], col[s:s + step]
        ok = np.isfinite(r) & np.isfinite(c)
        idx = np.flatnonzero(ok) + s
        if idx.size == 0:
            continue
        r0, wr = _axis(r[ok], kernel)
        c0, wc = _axis(c[ok], kernel)
        ri = r0[:, None] + np.arange(n)  # (M, n)
        ci = c0[:, None] + np.arange(n)
        # taps that matter: non-zero weight in both directions
        need = (wr != 0)[:, :, None] & (wc != 0)[:, None, :]  # (M, n, n)
        rin = (ri >= 0) & (ri < rows)
        cin = (ci >= 0) & (ci < cols)
        inside = rin[:, :, None] & cin[:, None, :]
        good = np.all(inside | ~need, axis=(1, 2))
        rc = np.clip(ri, 0, rows - 1)
        cc = np.clip(ci, 0, cols - 1)
        if mask is not None:
            bad = mask[rc[:, :, None], cc[:, None, :]] & need
            good &= ~bad.any(axis=(1, 2))
        taps = src[:, rc[:, :, None], cc[:, None, :]].astype(np.float64)  # (B, M, n, n)
        taps = np.where(need[None], taps, 0.0)  # an unneeded NaN or edge tap must not leak
        v = np.einsum("mi,bmij,mj->bm", wr, taps, wc)
        good &= np.all(np.isfinite(v), axis=0)
        values[:, idx[good]] = v[:, good]
        valid[idx[good]] = True
    return values, valid
