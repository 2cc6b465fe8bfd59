"""numba kernels of the RPC00B model: projection, localisation, partials.

Each kernel takes a point from input to status in registers, so no temporary arrays are made
(localisation takes two points at a time, in lockstep, see :func:`_localise_block`).
Projection and localisation run their points in blocks of :data:`CHUNK`: the parallel kernels
hand the blocks to numba's threads (``prange``), the ``*_serial`` twins run all of them on the
calling thread, through the same compiled block function, so both give the same bits. numba's
thread pool costs a fixed launch per call and must not be entered from several threads at once,
so small batches and calls from worker threads (dask tasks) use the serial twins
(:func:`geoblock_rpc.model.parallel_ok`). The vectorised numpy reference is
:mod:`geoblock_rpc.reference`; the tests check that both agree.

Constants travel in one float64 array ``prm`` (see :func:`pack`) and the coefficients in a
(4, 20) array ``[line_num, line_den, samp_num, samp_den]`` in RPC00B term order. The block
functions copy both into tuples (registers) before their loop, and use numpy's error model (a
zero denominator gives inf/NaN, not ZeroDivisionError): with no memory a store could alias, no
exception exit and a branch-free point (:func:`_project_one`), LLVM vectorises the projection
loop (SIMD, 3.5x on 1 thread) and keeps the arithmetic per point unchanged, in IEEE order, so
the results are those of the scalar code to the bit.
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

from geoblock_rpc._params import (  # noqa: F401 - re-exported: the kernels' constants
    CONVERGED,
    DIVERGED,
    HAS_BOX,
    HEIGHT_LIMIT,
    HEIGHT_OFF,
    HEIGHT_SCALE,
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
    N_PRM,
    OUT_OF_DOMAIN,
    SAMP_OFF,
    SAMP_SCALE,
    pack,
)
from geoblock_rpc._params import INV360 as _INV360

# contract (FMA) and reassociation only: NaN and inf must keep their meaning. Only the
# partials use them: with them the prange and serial loops of projection and localisation
# compile to different roundings, and results must not depend on the thread a batch runs on
# (tested; measured cost: none for projection, ~12 % for localisation).
_FASTMATH = {"contract", "reassoc", "nsz", "arcp"}


#: points per block of the projection and localisation loops (a parallel task each)
CHUNK = 4096


@njit(inline="always")
def _row20(c):
    return (c[0], c[1], c[2], c[3], c[4], c[5], c[6], c[7], c[8], c[9], c[10], c[11], c[12],
            c[13], c[14], c[15], c[16], c[17], c[18], c[19])


@njit(inline="always")
def _constants(prm, coef):
    """``prm`` and ``coef`` as tuples: values in registers that no store can alias."""
    p = (prm[0], prm[1], prm[2], prm[3], prm[4], prm[5], prm[6], prm[7], prm[8], prm[9],
         prm[10], prm[11], prm[12], prm[13], prm[14], prm[15], prm[16])
    return p, (_row20(coef[0]), _row20(coef[1]), _row20(coef[2]), _row20(coef[3]))


@njit(inline="always", fastmath=_FASTMATH)
def _dot20(c, t0, t1, t2, t3, t4, t5, t6, t7, t8, t9, t10, t11, t12, t13, t14, t15, t16,
           t17, t18, t19):
    return (c[0] * t0 + c[1] * t1 + c[2] * t2 + c[3] * t3 + c[4] * t4 + c[5] * t5
            + c[6] * t6 + c[7] * t7 + c[8] * t8 + c[9] * t9 + c[10] * t10 + c[11] * t11
            + c[12] * t12 + c[13] * t13 + c[14] * t14 + c[15] * t15 + c[16] * t16
            + c[17] * t17 + c[18] * t18 + c[19] * t19)


@njit(inline="always", fastmath=_FASTMATH)
def _poly20(c, L, P, H, LP, LH, PH, LL, PP, HH):
    """The RPC00B cubic with coefficients ``c`` at (L, P, H), given their pairwise products
    (the 20 terms of :data:`geoblock_rpc.rpc00b.TERMS`, in their order)."""
    return _dot20(c, 1.0, L, P, H, LP, LH, PH, LL, PP, HH, LP * H, LL * L, L * PP,
                  L * HH, LL * P, PP * P, P * HH, LL * H, PP * H, HH * H)


@njit(inline="always", fastmath=_FASTMATH)
def _ratios(coef, L, P, H):
    """(line_n, samp_n): normalised row and column at normalised ground (L, P, H)."""
    LP = L * P
    LH = L * H
    PH = P * H
    LL = L * L
    PP = P * P
    HH = H * H
    ln = _poly20(coef[0], L, P, H, LP, LH, PH, LL, PP, HH)
    ld = _poly20(coef[1], L, P, H, LP, LH, PH, LL, PP, HH)
    sn = _poly20(coef[2], L, P, H, LP, LH, PH, LL, PP, HH)
    sd = _poly20(coef[3], L, P, H, LP, LH, PH, LL, PP, HH)
    return ln / ld, sn / sd


@njit(inline="always", fastmath=_FASTMATH)
def _ratio_derivatives(cn, cd, L, P, H):
    """One normalised coordinate N/D and its derivatives with respect to L, P and H."""
    LP = L * P
    LH = L * H
    PH = P * H
    LL = L * L
    PP = P * P
    HH = H * H
    n = _poly20(cn, L, P, H, LP, LH, PH, LL, PP, HH)
    d = _poly20(cd, L, P, H, LP, LH, PH, LL, PP, HH)
    # derivatives of the 20 terms (see rpc00b.TERMS) with respect to L, P and H
    n_l = _dot20(cn, 0.0, 1.0, 0.0, 0.0, P, H, 0.0, 2 * L, 0.0, 0.0, PH, 3 * LL, PP,
                 HH, 2 * LP, 0.0, 0.0, 2 * LH, 0.0, 0.0)
    d_l = _dot20(cd, 0.0, 1.0, 0.0, 0.0, P, H, 0.0, 2 * L, 0.0, 0.0, PH, 3 * LL, PP,
                 HH, 2 * LP, 0.0, 0.0, 2 * LH, 0.0, 0.0)
    n_p = _dot20(cn, 0.0, 0.0, 1.0, 0.0, L, 0.0, H, 0.0, 2 * P, 0.0, LH, 0.0, 2 * LP,
                 0.0, LL, 3 * PP, HH, 0.0, 2 * PH, 0.0)
    d_p = _dot20(cd, 0.0, 0.0, 1.0, 0.0, L, 0.0, H, 0.0, 2 * P, 0.0, LH, 0.0, 2 * LP,
                 0.0, LL, 3 * PP, HH, 0.0, 2 * PH, 0.0)
    n_h = _dot20(cn, 0.0, 0.0, 0.0, 1.0, 0.0, L, P, 0.0, 0.0, 2 * H, LP, 0.0, 0.0,
                 2 * LH, 0.0, 0.0, 2 * PH, LL, PP, 3 * HH)
    d_h = _dot20(cd, 0.0, 0.0, 0.0, 1.0, 0.0, L, P, 0.0, 0.0, 2 * H, LP, 0.0, 0.0,
                 2 * LH, 0.0, 0.0, 2 * PH, LL, PP, 3 * HH)
    r = n / d
    return r, (n_l - r * d_l) / d, (n_p - r * d_p) / d, (n_h - r * d_h) / d


# d/dL and d/dP of the 20 terms without their zero terms: the same bits as _dot20 over all
# 20 (c * 0.0 is a signed zero, and adding it changes no sum but the sign of a zero one), half
# the operations. Localisation's Newton steps need no d/dH.
@njit(inline="always")
def _d_dl(c, L, P, H, LP, LH, PH, LL, PP, HH):
    return (c[1] + c[4] * P + c[5] * H + c[7] * (2 * L) + c[10] * PH + c[11] * (3 * LL)
            + c[12] * PP + c[13] * HH + c[14] * (2 * LP) + c[17] * (2 * LH))


@njit(inline="always")
def _d_dp(c, L, P, H, LP, LH, PH, LL, PP, HH):
    return (c[2] + c[4] * L + c[6] * H + c[8] * (2 * P) + c[10] * LH + c[12] * (2 * LP)
            + c[14] * LL + c[15] * (3 * PP) + c[16] * HH + c[18] * (2 * PH))


@njit(inline="always")
def _ratio_lp(cn, cd, L, P, H):
    """One normalised coordinate N/D and its derivatives with respect to L and P."""
    LP = L * P
    LH = L * H
    PH = P * H
    LL = L * L
    PP = P * P
    HH = H * H
    n = _poly20(cn, L, P, H, LP, LH, PH, LL, PP, HH)
    d = _poly20(cd, L, P, H, LP, LH, PH, LL, PP, HH)
    n_l = _d_dl(cn, L, P, H, LP, LH, PH, LL, PP, HH)
    d_l = _d_dl(cd, L, P, H, LP, LH, PH, LL, PP, HH)
    n_p = _d_dp(cn, L, P, H, LP, LH, PH, LL, PP, HH)
    d_p = _d_dp(cd, L, P, H, LP, LH, PH, LL, PP, HH)
    r = n / d
    return r, (n_l - r * d_l) / d, (n_p - r * d_p) / d


@njit(inline="always")
def _off_earth(lon, lat):
    """Whether (lon, lat) is no place on the Earth: wrapping such a longitude modulo 360
    would land it somewhere in the model's domain (lon=1e300 projected as a valid point)."""
    return not (abs(lon) <= LON_LIMIT and abs(lat) <= 90.0)


@njit(inline="always")
def _outside(prm, lon, lat, L, P, H):
    limit = prm[LIMIT]
    # written so that NaN (a non-finite normalised coordinate) is outside too
    if not (abs(L) <= limit and abs(P) <= limit and abs(H) <= prm[HEIGHT_LIMIT]):
        return True
    if _off_earth(lon, lat):
        return True
    if prm[HAS_BOX] != 0.0:
        span_lon = prm[MAX_LONG] - prm[MIN_LONG]
        span_lat = prm[MAX_LAT] - prm[MIN_LAT]
        d = lon - prm[MIN_LONG]
        d -= 360.0 * np.floor((d + 180.0) / 360.0)  # wrap next to MIN_LONG
        margin = 0.5 * (limit - 1.0)
        if d < -margin * span_lon or d > (1.0 + margin) * span_lon:
            return True
        if lat < prm[MIN_LAT] - margin * span_lat or lat > prm[MAX_LAT] + margin * span_lat:
            return True
    return False


@njit(inline="always")
def _wrap_dlon(lon, long_off):
    d = lon - long_off
    return d - 360.0 * np.floor((d + 180.0) / 360.0)


_INF = np.inf


@njit(inline="always")
def _wrap_near(lon, ref):  # pragma: no cover - numba
    """``lon - ref`` wrapped into [-180, 180) (see :data:`_INV360`)."""
    d = lon - ref
    return d - 360.0 * np.floor((d + 180.0) * _INV360)


@njit(inline="always")
def _project_one(x, y, z, prm, coef):  # pragma: no cover - numba
    """One point of :func:`project`: (row, col, status); ``prm, coef`` from :func:`_constants`
    (or the arrays: the same values).

    Branch-free: every test is a comparison combined with ``&``/``|`` (no short-circuit), the
    polynomials are evaluated for every point, and the status and the NaNs are selected at the
    end. LLVM's loop vectoriser turns only such a body into SIMD code (one branch, an early
    return, leaves the whole loop scalar: 25 against 7 ns per point on 1 thread, issue 30);
    each lane does the per-point arithmetic of the scalar code in IEEE order, so the bits are
    those of :func:`geoblock_rpc.reference`'s order of operations in the tests. The statuses
    keep their precedence: INVALID_INPUT (a non-finite input), then OUT_OF_DOMAIN (the domain
    of :func:`_outside`, the raw longitude beyond :data:`LON_LIMIT`), then DIVERGED (a
    non-finite result, a zero denominator).
    """
    finite = (abs(x) < _INF) & (abs(y) < _INF) & (abs(z) < _INF)
    # the wrapped longitude only enters L; the Earth test takes the raw one (1e300 modulo 360
    # is some longitude)
    L = _wrap_near(x, prm[LONG_OFF]) / prm[LONG_SCALE]
    P = (y - prm[LAT_OFF]) / prm[LAT_SCALE]
    H = (z - prm[HEIGHT_OFF]) / prm[HEIGHT_SCALE]
    limit = prm[LIMIT]
    # NaN (a non-finite normalised coordinate) fails every comparison: outside
    inside = ((abs(L) <= limit) & (abs(P) <= limit) & (abs(H) <= prm[HEIGHT_LIMIT])
              & (abs(x) <= LON_LIMIT) & (abs(y) <= 90.0))
    span_lon = prm[MAX_LONG] - prm[MIN_LONG]
    span_lat = prm[MAX_LAT] - prm[MIN_LAT]
    margin = 0.5 * (limit - 1.0)
    d = _wrap_near(x, prm[MIN_LONG])
    in_box = ((d >= -margin * span_lon) & (d <= (1.0 + margin) * span_lon)
              & (y >= prm[MIN_LAT] - margin * span_lat) & (y <= prm[MAX_LAT] + margin * span_lat))
    inside = inside & (in_box | (prm[HAS_BOX] == 0.0))
    ln, sn = _ratios(coef, L, P, H)
    r = ln * prm[LINE_SCALE] + prm[LINE_OFF]
    c = sn * prm[SAMP_SCALE] + prm[SAMP_OFF]
    converged = (abs(r) < _INF) & (abs(c) < _INF)
    status = CONVERGED if converged else DIVERGED
    status = status if inside else OUT_OF_DOMAIN
    status = status if finite else INVALID_INPUT
    good = finite & inside & converged
    return (r if good else np.nan), (c if good else np.nan), status


@njit(cache=True, nogil=True, error_model="numpy")
def _project_block(lon, lat, h, prm, coef, row, col, status, start, stop):  # pragma: no cover
    """Points ``start:stop`` of :func:`project` (a loop LLVM vectorises: :func:`_project_one`)."""
    p, k = _constants(prm, coef)
    lon = lon[start:stop]
    lat = lat[start:stop]
    h = h[start:stop]
    row = row[start:stop]
    col = col[start:stop]
    status = status[start:stop]
    for i in range(lon.shape[0]):
        row[i], col[i], status[i] = _project_one(lon[i], lat[i], h[i], p, k)


@njit(parallel=True, cache=True)
def project(lon, lat, h, prm, coef, row, col, status):  # pragma: no cover - numba
    """Ground (degrees, metres) -> image (pixels) for every point; NaN and a status if not.

    The threads write the outputs they compute, so fresh output pages fault in on every core.
    """
    n = lon.shape[0]
    for b in prange((n + CHUNK - 1) // CHUNK):
        _project_block(lon, lat, h, prm, coef, row, col, status, b * CHUNK,
                       min(n, (b + 1) * CHUNK))


@njit(cache=True, nogil=True)
def project_serial(lon, lat, h, prm, coef, row, col, status):  # pragma: no cover - numba
    """:func:`project` on the calling thread (small batches, calls from worker threads)."""
    _project_block(lon, lat, h, prm, coef, row, col, status, 0, lon.shape[0])


#: status of a point still iterating in the localisation loop
_ACTIVE = -1


@njit(inline="always")
def _localise_start(r, c, z, prm, coef):  # pragma: no cover - numba
    """Normalised target ``(ln, sn)``, height ``H``, first-order start ``(L, P)``, and the
    status: ``_ACTIVE``, or INVALID_INPUT / OUT_OF_DOMAIN (then the rest is not used)."""
    ln = (r - prm[LINE_OFF]) / prm[LINE_SCALE]
    sn = (c - prm[SAMP_OFF]) / prm[SAMP_SCALE]
    H = (z - prm[HEIGHT_OFF]) / prm[HEIGHT_SCALE]
    st = _ACTIVE
    if not (np.isfinite(r) and np.isfinite(c) and np.isfinite(z)):
        st = INVALID_INPUT
    elif abs(H) > prm[HEIGHT_LIMIT]:
        st = OUT_OF_DOMAIN
    # first-order start: (n1 - ln d1) L + (n2 - ln d2) P = ln (d0 + d3 H) - n0 - n3 H
    a11 = coef[0][1] - ln * coef[1][1]
    a12 = coef[0][2] - ln * coef[1][2]
    b1 = ln * (coef[1][0] + coef[1][3] * H) - coef[0][0] - coef[0][3] * H
    a21 = coef[2][1] - sn * coef[3][1]
    a22 = coef[2][2] - sn * coef[3][2]
    b2 = sn * (coef[3][0] + coef[3][3] * H) - coef[2][0] - coef[2][3] * H
    det = a11 * a22 - a12 * a21
    L = 0.0
    P = 0.0
    if abs(det) > 1e-12 * (abs(a11 * a22) + abs(a12 * a21)):
        L = (b1 * a22 - b2 * a12) / det
        P = (a11 * b2 - a21 * b1) / det
        if not (abs(L) < 2.0 and abs(P) < 2.0):
            L = 0.0
            P = 0.0
    return ln, sn, H, L, P, st


@njit(inline="always")
def _newton_step(ln, sn, H, L, P, best, step_l, step_p, prm, coef, tol_px,
                 stall_px):  # pragma: no cover - numba
    """One iteration of the localisation: ``(L, P, best, step_l, step_p, status)``.

    Steps are analytic Newton steps in normalised (L, P), clamped to 0.5 normalised units,
    and halved while they increase the pixel residual. CONVERGED when the residual is at most
    ``tol_px``; also when no step reduces a residual that is already at most ``stall_px``
    (float64's floor). ``_ACTIVE`` while iterating.
    """
    line_scale = prm[LINE_SCALE]
    samp_scale = prm[SAMP_SCALE]
    rl, j11, j12 = _ratio_lp(coef[0], coef[1], L, P, H)
    rs, j21, j22 = _ratio_lp(coef[2], coef[3], L, P, H)
    f_l = rl - ln
    f_s = rs - sn
    err = max(abs(f_l) * line_scale, abs(f_s) * samp_scale)
    if not np.isfinite(err):
        return L, P, best, step_l, step_p, DIVERGED
    if err <= tol_px:
        return L, P, best, step_l, step_p, CONVERGED
    if err >= best:
        # no progress: float64's floor, or a step to halve
        if best <= stall_px:
            # undo the last step: the previous point was better
            return L + step_l, P + step_p, best, step_l, step_p, CONVERGED
        step_l *= 0.5
        step_p *= 0.5
        return L + step_l, P + step_p, best, step_l, step_p, _ACTIVE
    best = err
    dj = j11 * j22 - j12 * j21
    if dj == 0.0 or not np.isfinite(dj):
        return L, P, best, step_l, step_p, DIVERGED
    step_l = (f_l * j22 - f_s * j12) / dj
    step_p = (j11 * f_s - j21 * f_l) / dj
    size = max(abs(step_l), abs(step_p))
    if size > 0.5:
        step_l *= 0.5 / size
        step_p *= 0.5 / size
    L -= step_l
    P -= step_p
    if abs(L) > 10.0 or abs(P) > 10.0:
        return L, P, best, step_l, step_p, DIVERGED
    return L, P, best, step_l, step_p, _ACTIVE


@njit(inline="always")
def _localise_finish(L, P, H, st, prm):  # pragma: no cover - numba
    """``(lon, lat, status)`` of a point whose iterations ended with status ``st``."""
    if st == _ACTIVE:
        st = MAX_ITERATIONS
    if st != CONVERGED:
        return np.nan, np.nan, st
    x = prm[LONG_OFF] + L * prm[LONG_SCALE]
    x -= 360.0 * np.floor((x + 180.0) / 360.0)
    y = prm[LAT_OFF] + P * prm[LAT_SCALE]
    if _outside(prm, x, y, L, P, H):
        return np.nan, np.nan, OUT_OF_DOMAIN
    return x, y, CONVERGED


@njit(cache=True, nogil=True, error_model="numpy")
def _localise_block(row, col, h, prm, coef, tol_px, stall_px, max_iter, lon, lat, status, start,
                    stop):  # pragma: no cover - numba
    """Points ``start:stop`` of :func:`localise`, two at a time.

    Image (pixels) at height h -> ground (degrees) by Newton in normalised (L, P) from the
    solution of the RPC's first-order terms (:func:`_newton_step`). The two points iterate in
    lockstep, each for itself: the core overlaps their two chains of dependent operations
    (~15 % faster than one point after the other, the same bits).
    """
    p, k = _constants(prm, coef)
    for i in range(start, stop, 2):
        j = min(i + 1, stop - 1)  # an odd last point is computed twice
        ln_a, sn_a, h_a, l_a, p_a, st_a = _localise_start(row[i], col[i], h[i], p, k)
        ln_b, sn_b, h_b, l_b, p_b, st_b = _localise_start(row[j], col[j], h[j], p, k)
        best_a = best_b = np.inf
        sl_a = sp_a = sl_b = sp_b = 0.0
        for _ in range(max_iter):
            if st_a == _ACTIVE:
                l_a, p_a, best_a, sl_a, sp_a, st_a = _newton_step(
                    ln_a, sn_a, h_a, l_a, p_a, best_a, sl_a, sp_a, p, k, tol_px, stall_px)
            if st_b == _ACTIVE:
                l_b, p_b, best_b, sl_b, sp_b, st_b = _newton_step(
                    ln_b, sn_b, h_b, l_b, p_b, best_b, sl_b, sp_b, p, k, tol_px, stall_px)
            if st_a != _ACTIVE and st_b != _ACTIVE:
                break
        lon[i], lat[i], status[i] = _localise_finish(l_a, p_a, h_a, st_a, p)
        lon[j], lat[j], status[j] = _localise_finish(l_b, p_b, h_b, st_b, p)


@njit(parallel=True, cache=True)
def localise(
    row, col, h, prm, coef, tol_px, stall_px, max_iter, lon, lat, status
):  # pragma: no cover
    """Image (pixels) at height h -> ground (degrees), every point (:func:`_localise_block`)."""
    n = row.shape[0]
    for b in prange((n + CHUNK - 1) // CHUNK):
        _localise_block(row, col, h, prm, coef, tol_px, stall_px, max_iter, lon, lat, status,
                        b * CHUNK, min(n, (b + 1) * CHUNK))


@njit(cache=True, nogil=True)
def localise_serial(row, col, h, prm, coef, tol_px, stall_px, max_iter, lon, lat,
                    status):  # pragma: no cover
    """:func:`localise` on the calling thread (small batches, calls from worker threads)."""
    _localise_block(row, col, h, prm, coef, tol_px, stall_px, max_iter, lon, lat, status, 0,
                    row.shape[0])


@njit(inline="always", fastmath=_FASTMATH)
def _partials_one(lon, lat, h, prm, coef, out, i):  # pragma: no cover - numba
    L = _wrap_dlon(lon, prm[LONG_OFF]) / prm[LONG_SCALE]
    P = (lat - prm[LAT_OFF]) / prm[LAT_SCALE]
    H = (h - prm[HEIGHT_OFF]) / prm[HEIGHT_SCALE]
    for k in range(2):
        _, r_l, r_p, r_h = _ratio_derivatives(coef[2 * k], coef[2 * k + 1], L, P, H)
        scale = prm[LINE_SCALE] if k == 0 else prm[SAMP_SCALE]
        out[i, k, 0] = r_l * scale / prm[LONG_SCALE]
        out[i, k, 1] = r_p * scale / prm[LAT_SCALE]
        out[i, k, 2] = r_h * scale / prm[HEIGHT_SCALE]


@njit(parallel=True, cache=True, fastmath=_FASTMATH)
def partials_geodetic(lon, lat, h, prm, coef, out):  # pragma: no cover - numba
    """d(row, col)/d(lon, lat, h) in pixels per degree, degree, metre: out (N, 2, 3)."""
    for i in prange(lon.shape[0]):
        _partials_one(lon[i], lat[i], h[i], prm, coef, out, i)


@njit(cache=True, fastmath=_FASTMATH)
def partials_geodetic_serial(lon, lat, h, prm, coef, out):  # pragma: no cover - numba
    """:func:`partials_geodetic` on the calling thread (small batches, worker threads)."""
    for i in range(lon.shape[0]):
        _partials_one(lon[i], lat[i], h[i], prm, coef, out, i)
