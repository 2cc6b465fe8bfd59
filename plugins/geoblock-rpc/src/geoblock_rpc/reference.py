"""The vectorised numpy reference of the RPC00B evaluation (no numba).

Slower than :mod:`geoblock_rpc._kernels` and written independently of it, term by term from
:data:`geoblock_rpc.rpc00b.TERMS`; the tests hold the two to agreement.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from geoblock_rpc.rpc00b import Rpc00b, evaluate_terms

__all__ = ["localise", "normalise", "project"]


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


def _term_derivatives(l: np.ndarray, p: np.ndarray,  # noqa: E741
                      h: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """d/dL and d/dP of the 20 terms, each (*S, 20), in :data:`TERMS` order."""
    zero, one = np.zeros_like(l), np.ones_like(l)
    d_l = np.stack([zero, one, zero, zero, p, h, zero, 2 * l, zero, zero, p * h, 3 * l * l,
                    p * p, h * h, 2 * l * p, zero, zero, 2 * l * h, zero, zero], axis=-1)
    d_p = np.stack([zero, zero, one, zero, l, zero, h, zero, 2 * p, zero, l * h, zero,
                    2 * l * p, zero, l * l, 3 * p * p, h * h, zero, 2 * p * h, zero], axis=-1)
    return d_l, d_p


def localise(rpc: Rpc00b, row: ArrayLike, col: ArrayLike, h: ArrayLike, tol_px: float = 1e-6,
             stall_px: float = 1e-3, max_iter: int = 60
             ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Image ``(row, col)`` pixels at height ``h`` metres -> ``(lon, lat, status)``, degrees
    and :class:`geoblock.typing.Status` codes, with no validity-domain check but the Earth's.

    The algorithm of the compiled kernel (``geoblock_rpc._kernels.localise``), vectorised
    over the points: Newton steps in normalised (L, P) from the solution of the first-order
    terms, clamped to 0.5 normalised units and halved while they increase the pixel residual;
    CONVERGED when the residual is at most ``tol_px``, or when no step reduces a residual
    already at most ``stall_px``; DIVERGED on a non-finite residual or Jacobian or a point
    beyond 10 normalised units; MAX_ITERATIONS after ``max_iter`` steps. For a few points
    (the reader's plausibility check): it needs no compiled kernel, so opening a model does
    not compile one; the tests hold it to the kernel.
    """
    from geoblock.typing import Status

    active = np.int8(-1)
    row, col, h = np.broadcast_arrays(*(np.asarray(v, dtype=float) for v in (row, col, h)))
    ln = (row - rpc.line_off) / rpc.line_scale
    sn = (col - rpc.samp_off) / rpc.samp_scale
    H = (h - rpc.height_off) / rpc.height_scale
    c = rpc.coefficients
    st = np.where(np.isfinite(row) & np.isfinite(col) & np.isfinite(h), active,
                  np.int8(Status.INVALID_INPUT)).astype(np.int8)
    with np.errstate(all="ignore"):
        # first-order start: (n1 - ln d1) L + (n2 - ln d2) P = ln (d0 + d3 H) - n0 - n3 H
        a11 = c[0, 1] - ln * c[1, 1]
        a12 = c[0, 2] - ln * c[1, 2]
        b1 = ln * (c[1, 0] + c[1, 3] * H) - c[0, 0] - c[0, 3] * H
        a21 = c[2, 1] - sn * c[3, 1]
        a22 = c[2, 2] - sn * c[3, 2]
        b2 = sn * (c[3, 0] + c[3, 3] * H) - c[2, 0] - c[2, 3] * H
        det = a11 * a22 - a12 * a21
        L = (b1 * a22 - b2 * a12) / det
        P = (a11 * b2 - a21 * b1) / det
        ok = ((np.abs(det) > 1e-12 * (np.abs(a11 * a22) + np.abs(a12 * a21)))
              & (np.abs(L) < 2.0) & (np.abs(P) < 2.0))
        L = np.where(ok, L, 0.0)
        P = np.where(ok, P, 0.0)
        best = np.full(L.shape, np.inf)
        step_l = np.zeros(L.shape)
        step_p = np.zeros(L.shape)
        line_scale, samp_scale = rpc.line_scale, rpc.samp_scale
        for _ in range(max_iter):
            go = st == active
            if not go.any():
                break
            terms = evaluate_terms(L, P, H)
            d_l, d_p = _term_derivatives(L, P, H)
            n_l, d_l_, s_n, s_d = (terms @ c[k] for k in range(4))
            rl, rs = n_l / d_l_, s_n / s_d
            j11 = (d_l @ c[0] - rl * (d_l @ c[1])) / d_l_
            j12 = (d_p @ c[0] - rl * (d_p @ c[1])) / d_l_
            j21 = (d_l @ c[2] - rs * (d_l @ c[3])) / s_d
            j22 = (d_p @ c[2] - rs * (d_p @ c[3])) / s_d
            f_l, f_s = rl - ln, rs - sn
            err = np.maximum(np.abs(f_l) * line_scale, np.abs(f_s) * samp_scale)
            diverged = go & ~np.isfinite(err)
            done = go & ~diverged & (err <= tol_px)
            stuck = go & ~diverged & ~done & (err >= best)
            stalled = stuck & (best <= stall_px)
            halve = stuck & ~stalled
            # a stalled point goes back to the previous, better one; a halved step retries
            step_l = np.where(halve, 0.5 * step_l, step_l)
            step_p = np.where(halve, 0.5 * step_p, step_p)
            L = np.where(stalled | halve, L + step_l, L)
            P = np.where(stalled | halve, P + step_p, P)
            move = go & ~diverged & ~done & ~stuck
            best = np.where(move, err, best)
            dj = j11 * j22 - j12 * j21
            singular = move & ~((dj != 0.0) & np.isfinite(dj))
            move &= ~singular
            new_l = (f_l * j22 - f_s * j12) / dj
            new_p = (j11 * f_s - j21 * f_l) / dj
            size = np.maximum(np.abs(new_l), np.abs(new_p))
            shrink = np.where(size > 0.5, 0.5 / size, 1.0)
            step_l = np.where(move, new_l * shrink, step_l)
            step_p = np.where(move, new_p * shrink, step_p)
            L = np.where(move, L - step_l, L)
            P = np.where(move, P - step_p, P)
            far = move & ((np.abs(L) > 10.0) | (np.abs(P) > 10.0))
            st = np.where(diverged | singular | far, np.int8(Status.DIVERGED), st)
            st = np.where(done | stalled, np.int8(Status.CONVERGED), st)
        st = np.where(st == active, np.int8(Status.MAX_ITERATIONS), st)
        lon = rpc.long_off + L * rpc.long_scale
        lon = lon - 360.0 * np.floor((lon + 180.0) / 360.0)
        lat = rpc.lat_off + P * rpc.lat_scale
    converged = st == Status.CONVERGED
    off_earth = ~((np.abs(lon) <= 540.0) & (np.abs(lat) <= 90.0))
    st = np.where(converged & off_earth, np.int8(Status.OUT_OF_DOMAIN), st)
    good = st == Status.CONVERGED
    return (np.where(good, lon, np.nan), np.where(good, lat, np.nan),
            st.astype(np.uint8))
