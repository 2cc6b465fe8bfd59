"""The RPC00B projection and localisation of small batches in numpy: the compiled kernels'
bits, without numba.

A command that projects a few points (``geoblock project``, a test, a plausibility check)
would spend 0.35 s importing numba and building its typing registries before the kernel's
first call, for microseconds of work. :func:`project` does the very operations of
:func:`geoblock_rpc._kernels._project_one` (numba compiles it without fast-math: IEEE
operations in source order, no fused multiply-add), one numpy operation over all points at a
time, in the kernel's order, so both give the same bits for every point, NaNs and statuses
included (tested on every shared RPC file). :func:`localise` does the same for
:func:`geoblock_rpc._kernels.localise_serial`'s Newton iteration: every point still iterating
takes the kernel's step (its branches become selections between the values each branch
computes), so each point takes the kernel's path through the iterations, to the same bits.
Which of the two runs a batch (:meth:`geoblock_rpc.RpcModel.project_with_status`,
:meth:`~geoblock_rpc.RpcModel.backproject_with_status`) therefore changes no result.
"""

from __future__ import annotations

from typing import Any

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
    MAX_ITERATIONS,
    MAX_LAT,
    MAX_LONG,
    MIN_LAT,
    MIN_LONG,
    OUT_OF_DOMAIN,
    SAMP_OFF,
    SAMP_SCALE,
)

__all__ = ["localise", "project"]


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


_ACTIVE = 255  # a point still iterating (the kernel's -1)
_A = np.ndarray


def _d_dl(c: _A, L: _A, P: _A, H: _A, LP: _A, LH: _A, PH: _A, LL: _A, PP: _A,
          HH: _A) -> _A:
    return (c[1] + c[4] * P + c[5] * H + c[7] * (2 * L) + c[10] * PH + c[11] * (3 * LL)
            + c[12] * PP + c[13] * HH + c[14] * (2 * LP) + c[17] * (2 * LH))


def _d_dp(c: _A, L: _A, P: _A, H: _A, LP: _A, LH: _A, PH: _A, LL: _A, PP: _A,
          HH: _A) -> _A:
    return (c[2] + c[4] * L + c[6] * H + c[8] * (2 * P) + c[10] * LH + c[12] * (2 * LP)
            + c[14] * LL + c[15] * (3 * PP) + c[16] * HH + c[18] * (2 * PH))


def _poly(c: _A, L: _A, P: _A, H: _A, LP: _A, LH: _A, PH: _A, LL: _A, PP: _A,
          HH: _A) -> _A:
    t = (L, P, H, LP, LH, PH, LL, PP, HH, LP * H, LL * L, L * PP, L * HH, LL * P, PP * P,
         P * HH, LL * H, PP * H, HH * H)
    acc: Any = c[0] * 1.0  # a scalar until the first term makes it an array
    for k in range(19):
        acc = acc + c[k + 1] * t[k]
    return acc


def _ratio_lp(cn: np.ndarray, cd: np.ndarray, L: np.ndarray, P: np.ndarray,
              H: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    LP = L * P
    LH = L * H
    PH = P * H
    LL = L * L
    PP = P * P
    HH = H * H
    n = _poly(cn, L, P, H, LP, LH, PH, LL, PP, HH)
    d = _poly(cd, L, P, H, LP, LH, PH, LL, PP, HH)
    n_l = _d_dl(cn, L, P, H, LP, LH, PH, LL, PP, HH)
    d_l = _d_dl(cd, L, P, H, LP, LH, PH, LL, PP, HH)
    n_p = _d_dp(cn, L, P, H, LP, LH, PH, LL, PP, HH)
    d_p = _d_dp(cd, L, P, H, LP, LH, PH, LL, PP, HH)
    r = n / d
    return r, (n_l - r * d_l) / d, (n_p - r * d_p) / d


def localise(row: np.ndarray, col: np.ndarray, h: np.ndarray, prm: np.ndarray, coef: np.ndarray,
             tol_px: float, stall_px: float, max_iter: int, lon: np.ndarray, lat: np.ndarray,
             status: np.ndarray) -> None:
    """Image -> ground at height h: :func:`geoblock_rpc._kernels.localise_serial`'s
    signature, operations and bits, every active point one Newton step at a time."""
    p = [float(v) for v in prm]
    with np.errstate(all="ignore"):
        ln = (row - p[LINE_OFF]) / p[LINE_SCALE]
        sn = (col - p[SAMP_OFF]) / p[SAMP_SCALE]
        H = (h - p[HEIGHT_OFF]) / p[HEIGHT_SCALE]
        finite = np.isfinite(row) & np.isfinite(col) & np.isfinite(h)
        st = np.full(row.shape, _ACTIVE, np.uint8)
        st[np.abs(H) > p[HEIGHT_LIMIT]] = OUT_OF_DOMAIN
        st[~finite] = INVALID_INPUT
        c0, c1, c2, c3 = np.asarray(coef, dtype=np.float64)
        a11 = c0[1] - ln * c1[1]
        a12 = c0[2] - ln * c1[2]
        b1 = ln * (c1[0] + c1[3] * H) - c0[0] - c0[3] * H
        a21 = c2[1] - sn * c3[1]
        a22 = c2[2] - sn * c3[2]
        b2 = sn * (c3[0] + c3[3] * H) - c2[0] - c2[3] * H
        det = a11 * a22 - a12 * a21
        L = (b1 * a22 - b2 * a12) / det
        P = (a11 * b2 - a21 * b1) / det
        keep = (np.abs(det) > 1e-12 * (np.abs(a11 * a22) + np.abs(a12 * a21))) & (
            np.abs(L) < 2.0) & (np.abs(P) < 2.0)
        L = np.where(keep, L, 0.0)
        P = np.where(keep, P, 0.0)
        best = np.full(row.shape, np.inf)
        step_l = np.zeros(row.shape)
        step_p = np.zeros(row.shape)
        line_scale, samp_scale = p[LINE_SCALE], p[SAMP_SCALE]
        for _ in range(max_iter):
            a = np.flatnonzero(st == _ACTIVE)
            if a.size == 0:
                break
            La, Pa, Ha = L[a], P[a], H[a]
            besta, sla, spa = best[a], step_l[a], step_p[a]
            rl, j11, j12 = _ratio_lp(c0, c1, La, Pa, Ha)
            rs, j21, j22 = _ratio_lp(c2, c3, La, Pa, Ha)
            f_l = rl - ln[a]
            f_s = rs - sn[a]
            e1 = np.abs(f_l) * line_scale
            e2 = np.abs(f_s) * samp_scale
            err = np.where(e2 > e1, e2, e1)  # Python's max(e1, e2), NaN included
            sta = np.full(a.shape, _ACTIVE, np.uint8)
            diverged = ~np.isfinite(err)
            conv = ~diverged & (err <= tol_px)
            worse = ~diverged & ~conv & (err >= besta)
            undo = worse & (besta <= stall_px)
            halve = worse & ~undo
            go = ~diverged & ~conv & ~worse
            sta[diverged] = DIVERGED
            sta[conv | undo] = CONVERGED
            # undo: back to the previous point; halve: half the last step back
            hl = np.where(halve, sla * 0.5, sla)
            hp = np.where(halve, spa * 0.5, spa)
            Lnew = np.where(undo | halve, La + hl, La)
            Pnew = np.where(undo | halve, Pa + hp, Pa)
            best_new = np.where(go, err, besta)
            dj = j11 * j22 - j12 * j21
            bad_dj = go & ((dj == 0.0) | ~np.isfinite(dj))
            sta[bad_dj] = DIVERGED
            ok = go & ~bad_dj
            nl = (f_l * j22 - f_s * j12) / dj
            np_ = (j11 * f_s - j21 * f_l) / dj
            size = np.where(np.abs(np_) > np.abs(nl), np.abs(np_), np.abs(nl))
            big = size > 0.5
            nl = np.where(big, nl * (0.5 / size), nl)
            np_ = np.where(big, np_ * (0.5 / size), np_)
            Lnew = np.where(ok, La - nl, Lnew)
            Pnew = np.where(ok, Pa - np_, Pnew)
            hl = np.where(ok, nl, hl)
            hp = np.where(ok, np_, hp)
            far = ok & ((np.abs(Lnew) > 10.0) | (np.abs(Pnew) > 10.0))
            sta[far] = DIVERGED
            L[a], P[a], best[a], step_l[a], step_p[a], st[a] = Lnew, Pnew, best_new, hl, hp, sta
        st[st == _ACTIVE] = MAX_ITERATIONS
        x = p[LONG_OFF] + L * p[LONG_SCALE]
        x = x - 360.0 * np.floor((x + 180.0) / 360.0)
        y = p[LAT_OFF] + P * p[LAT_SCALE]
        limit = p[LIMIT]
        outside = ~((np.abs(L) <= limit) & (np.abs(P) <= limit) & (np.abs(H) <= p[HEIGHT_LIMIT]))
        outside |= ~((np.abs(x) <= LON_LIMIT) & (np.abs(y) <= 90.0))
        if p[HAS_BOX] != 0.0:
            span_lon = p[MAX_LONG] - p[MIN_LONG]
            span_lat = p[MAX_LAT] - p[MIN_LAT]
            d = x - p[MIN_LONG]
            d = d - 360.0 * np.floor((d + 180.0) / 360.0)
            margin = 0.5 * (limit - 1.0)
            outside |= (d < -margin * span_lon) | (d > (1.0 + margin) * span_lon)
            outside |= (y < p[MIN_LAT] - margin * span_lat) | (y > p[MAX_LAT] + margin * span_lat)
        conv = st == CONVERGED
        st[conv & outside] = OUT_OF_DOMAIN
        good = conv & ~outside
        status[...] = st
        lon[...] = np.where(good, x, np.nan)
        lat[...] = np.where(good, y, np.nan)
