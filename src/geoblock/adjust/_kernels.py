"""Numba kernels of :mod:`geoblock.adjust.normal` (the numpy reference lives there).

Each loops over measurements, or over each point's measurements (CSR ``order``/``start``),
and writes into arrays its caller allocates. Parameter cofactors are read through a column
map ``pos`` (K,): ``q[pos[g1], pos[g2]]``, ``pos = arange(K)`` for a dense ``Q_pp`` and the
requested columns' positions (-1 elsewhere) for a selected one; a point or measurement that
needs a column not held gets NaN.
"""

from __future__ import annotations

from typing import TypeAlias

import numpy as np
from numba import njit

from geoblock.typing import BoolArray, Float64Array, IndexArray

F64: TypeAlias = Float64Array
Idx: TypeAlias = IndexArray


@njit(cache=True)
def _nb_accumulate(  # pragma: no cover - numba
    a: F64, b: F64, v: F64, cols: Idx, point_of: Idx, n_pp: F64, b_p: F64,
    n_xx: F64, b_x: F64, n_px: F64, dense: bool, diag_pp: F64,
) -> None:
    """Per measurement: ``N_px = A^T B`` into ``n_px``; ``A^T v`` into ``b_p``, the diagonal
    of ``A^T A`` into ``diag_pp`` and (``dense``) ``A^T A`` scattered into ``n_pp``;
    ``B^T B``, ``B^T v`` into the point's ``n_xx``, ``b_x``."""
    kmax = a.shape[2]
    for m in range(a.shape[0]):
        g = cols[m]
        j = point_of[m]
        for r in range(kmax):
            for c in range(3):
                n_px[m, r, c] = a[m, 0, r] * b[m, 0, c] + a[m, 1, r] * b[m, 1, c]
        for r in range(kmax):
            gr = g[r]
            if gr < 0:
                continue
            b_p[gr] += a[m, 0, r] * v[m, 0] + a[m, 1, r] * v[m, 1]
            diag_pp[gr] += a[m, 0, r] * a[m, 0, r] + a[m, 1, r] * a[m, 1, r]
            if not dense:
                continue
            for c in range(kmax):
                gc = g[c]
                if gc < 0:
                    continue
                n_pp[gr, gc] += a[m, 0, r] * a[m, 0, c] + a[m, 1, r] * a[m, 1, c]
        for r in range(3):
            b_x[j, r] += b[m, 0, r] * v[m, 0] + b[m, 1, r] * v[m, 1]
            for c in range(3):
                n_xx[j, r, c] += b[m, 0, r] * b[m, 0, c] + b[m, 1, r] * b[m, 1, c]


@njit(cache=True)
def _nb_npp_triplets(  # pragma: no cover - numba
    a: F64, cols: Idx, m0: int, m1: int, t_rows: Idx, t_cols: Idx, vals: F64,
) -> int:
    """The triplets of ``A^T A`` of the measurements ``m0 <= m < m1`` (the sparse ``N_pp``);
    returns how many were written."""
    kmax = a.shape[2]
    used = 0
    for m in range(m0, m1):
        g = cols[m]
        for r in range(kmax):
            if g[r] < 0:
                continue
            for c in range(kmax):
                if g[c] < 0:
                    continue
                t_rows[used] = g[r]
                t_cols[used] = g[c]
                vals[used] = a[m, 0, r] * a[m, 0, c] + a[m, 1, r] * a[m, 1, c]
                used += 1
    return used


@njit(cache=True)
def _nb_reduce(  # pragma: no cover - numba
    n_px: F64, cinv: F64, b_x: F64, cols: Idx, order: Idx, start: Idx, j0: int, j1: int,
    dense: bool, reduced: F64, rhs: F64, t_rows: Idx, t_cols: Idx, vals: F64,
) -> int:
    """Schur complement over the points ``j0 <= j < j1``, point by point:
    ``rhs -= N_pj C_j b_j`` and, for each pair ``a <= b`` of the point's measurements,
    ``-N_pa C_j N_bp`` (and its transpose for ``a < b``) subtracted from ``reduced`` (dense)
    or written as triplets (negated). Returns the number of triplets written."""
    kmax = n_px.shape[1]
    most = 0
    for j in range(j0, j1):
        most = max(most, start[j + 1] - start[j])
    left = np.empty((most, kmax, 3))
    cbx = np.empty(3)
    used = 0
    for j in range(j0, j1):
        m0 = start[j]
        n = start[j + 1] - m0
        cj = cinv[j]
        for i in range(3):
            cbx[i] = cj[i, 0] * b_x[j, 0] + cj[i, 1] * b_x[j, 1] + cj[i, 2] * b_x[j, 2]
        for q in range(n):
            m = order[m0 + q]
            g = cols[m]
            for r in range(kmax):
                for c in range(3):
                    left[q, r, c] = (n_px[m, r, 0] * cj[0, c] + n_px[m, r, 1] * cj[1, c]
                                     + n_px[m, r, 2] * cj[2, c])
                if g[r] >= 0:
                    rhs[g[r]] -= (n_px[m, r, 0] * cbx[0] + n_px[m, r, 1] * cbx[1]
                                  + n_px[m, r, 2] * cbx[2])
        for qa in range(n):
            ga = cols[order[m0 + qa]]
            for qb in range(qa, n):
                mb = order[m0 + qb]
                gb = cols[mb]
                for r in range(kmax):
                    if ga[r] < 0:
                        continue
                    for c in range(kmax):
                        if gb[c] < 0:
                            continue
                        val = (left[qa, r, 0] * n_px[mb, c, 0] + left[qa, r, 1] * n_px[mb, c, 1]
                               + left[qa, r, 2] * n_px[mb, c, 2])
                        if dense:
                            reduced[ga[r], gb[c]] -= val
                            if qb != qa:
                                reduced[gb[c], ga[r]] -= val
                        else:
                            t_rows[used] = ga[r]
                            t_cols[used] = gb[c]
                            vals[used] = -val
                            used += 1
                            if qb != qa:
                                t_rows[used] = gb[c]
                                t_cols[used] = ga[r]
                                vals[used] = -val
                                used += 1
    return used


@njit(cache=True)
def _nb_chunks(weights: Idx, budget: int, out: Idx) -> int:  # pragma: no cover - numba
    """:func:`_chunks` into ``out``; returns the number of boundaries."""
    out[0] = 0
    used = 1
    total = 0
    for i in range(weights.size):
        if total > 0 and total + weights[i] > budget:
            out[used] = i
            used += 1
            total = 0
        total += weights[i]
    if weights.size > 0:
        out[used] = weights.size
        used += 1
    return used


@njit(cache=True)
def _nb_back_substitute(  # pragma: no cover - numba
    n_px: F64, cinv: F64, b_x: F64, cols: Idx, point_of: Idx, dp: F64, dx: F64,
) -> None:
    """``dx_j = C_j (b_j - sum_m N_jp dp)``."""
    kmax = n_px.shape[1]
    t = b_x.copy()
    for m in range(n_px.shape[0]):
        g = cols[m]
        j = point_of[m]
        for r in range(kmax):
            if g[r] < 0:
                continue
            d = dp[g[r]]
            for c in range(3):
                t[j, c] -= n_px[m, r, c] * d
    for j in range(dx.shape[0]):
        for i in range(3):
            dx[j, i] = cinv[j, i, 0] * t[j, 0] + cinv[j, i, 1] * t[j, 1] + cinv[j, i, 2] * t[j, 2]


@njit(cache=True)
def _nb_point_cofactors(  # pragma: no cover - numba
    q_pp: F64, pos: Idx, n_px: F64, cinv: F64, cols: Idx, order: Idx, start: Idx,
    q_xx: F64, q_px: F64,
) -> None:
    """:meth:`NormalSystem.point_cofactors`, point by point: ``U_a = sum_b Q[i_a, i_b] N_pb``,
    ``Q_px[a] = -U_a C_j``, ``Q_xx[j] = C_j + C_j (sum_a N_pa^T U_a) C_j``; NaN for a point
    one of whose measurements' columns ``q_pp`` does not hold (``pos`` -1)."""
    kmax = n_px.shape[1]
    u = np.empty((kmax, 3))
    inner = np.empty((3, 3))
    tmp = np.empty((3, 3))
    for j in range(start.size - 1):
        m0 = start[j]
        n = start[j + 1] - m0
        cj = cinv[j]
        held = True
        for qa in range(n):
            ga = cols[order[m0 + qa]]
            for r in range(kmax):
                if ga[r] >= 0 and pos[ga[r]] < 0:
                    held = False
        if not held:
            q_xx[j, :, :] = np.nan
            for qa in range(n):
                q_px[order[m0 + qa], :, :] = np.nan
            continue
        inner[:, :] = 0.0
        for qa in range(n):
            ma = order[m0 + qa]
            ga = cols[ma]
            u[:, :] = 0.0
            for qb in range(n):
                mb = order[m0 + qb]
                gb = cols[mb]
                for r in range(kmax):
                    if ga[r] < 0:
                        continue
                    pr = pos[ga[r]]
                    for c in range(kmax):
                        if gb[c] < 0:
                            continue
                        q = q_pp[pr, pos[gb[c]]]
                        u[r, 0] += q * n_px[mb, c, 0]
                        u[r, 1] += q * n_px[mb, c, 1]
                        u[r, 2] += q * n_px[mb, c, 2]
            for r in range(kmax):
                for c in range(3):
                    q_px[ma, r, c] = -(u[r, 0] * cj[0, c] + u[r, 1] * cj[1, c]
                                       + u[r, 2] * cj[2, c])
            for i in range(3):
                for k in range(3):
                    acc = 0.0
                    for r in range(kmax):
                        acc += n_px[ma, r, i] * u[r, k]
                    inner[i, k] += acc
        for i in range(3):
            for k in range(3):
                tmp[i, k] = cj[i, 0] * inner[0, k] + cj[i, 1] * inner[1, k] + cj[i, 2] * inner[2, k]
        for i in range(3):
            for k in range(3):
                q_xx[j, i, k] = cj[i, k] + (tmp[i, 0] * cj[0, k] + tmp[i, 1] * cj[1, k]
                                            + tmp[i, 2] * cj[2, k])


@njit(cache=True)
def _nb_hat_blocks(  # pragma: no cover - numba
    q_pp: F64, pos: Idx, q_xx: F64, q_px: F64, a: F64, b: F64, cols: Idx, point_of: Idx,
    out: F64,
) -> None:
    """:meth:`NormalSystem.hat_blocks` per measurement; NaN for a measurement one of whose
    columns ``q_pp`` does not hold (``pos`` -1)."""
    kmax = a.shape[2]
    aq = np.empty(kmax)
    for m in range(a.shape[0]):
        g = cols[m]
        j = point_of[m]
        held = True
        for r in range(kmax):
            if g[r] >= 0 and pos[g[r]] < 0:
                held = False
        if not held:
            out[m, :, :] = np.nan
            continue
        for s in range(2):
            for t in range(2):
                acc = 0.0
                # A Q_ii A^T
                for c in range(kmax):
                    aq[c] = 0.0
                for r in range(kmax):
                    if g[r] < 0:
                        continue
                    pr = pos[g[r]]
                    for c in range(kmax):
                        if g[c] >= 0:
                            aq[c] += a[m, s, r] * q_pp[pr, pos[g[c]]]
                for c in range(kmax):
                    acc += aq[c] * a[m, t, c]
                # A Q_px B^T + (B Q_xp A^T)
                for r in range(kmax):
                    for c in range(3):
                        acc += a[m, s, r] * q_px[m, r, c] * b[m, t, c]
                        acc += a[m, t, r] * q_px[m, r, c] * b[m, s, c]
                # B Q_xx B^T
                for r in range(3):
                    for c in range(3):
                        acc += b[m, s, r] * q_xx[j, r, c] * b[m, t, c]
                out[m, s, t] = acc


@njit(cache=True)
def _nb_inv3(m: F64, out: F64, redo: BoolArray, ratio: float) -> None:  # pragma: no cover
    """Per block: scaled to a unit diagonal, its eigenvalues in closed form (trigonometric
    solution) and the inverse by the adjugate. Blocks with a zero or non-finite diagonal, or
    an eigenvalue ratio below ``ratio``, are flagged in ``redo``."""
    s = np.empty((3, 3))
    sc = np.empty(3)
    for j in range(m.shape[0]):
        ok = True
        for i in range(3):
            d = abs(m[j, i, i])
            if not (d > 0.0 and d < np.inf):
                ok = False
            sc[i] = np.sqrt(d)
        if not ok:
            redo[j] = True
            continue
        for i in range(3):
            for k in range(3):
                s[i, k] = m[j, i, k] / (sc[i] * sc[k])
        # eigenvalues of the symmetric s
        p1 = s[0, 1] ** 2 + s[0, 2] ** 2 + s[1, 2] ** 2
        q = (s[0, 0] + s[1, 1] + s[2, 2]) / 3.0
        p2 = (s[0, 0] - q) ** 2 + (s[1, 1] - q) ** 2 + (s[2, 2] - q) ** 2 + 2.0 * p1
        p = np.sqrt(p2 / 6.0)
        if p == 0.0:
            w_min = q
            w_max = q
        else:
            b00 = (s[0, 0] - q) / p
            b11 = (s[1, 1] - q) / p
            b22 = (s[2, 2] - q) / p
            b01 = s[0, 1] / p
            b02 = s[0, 2] / p
            b12 = s[1, 2] / p
            det_b = (b00 * (b11 * b22 - b12 * b12) - b01 * (b01 * b22 - b12 * b02)
                     + b02 * (b01 * b12 - b11 * b02))
            r = min(1.0, max(-1.0, det_b / 2.0))
            phi = np.arccos(r) / 3.0
            w_max = q + 2.0 * p * np.cos(phi)
            w_min = q + 2.0 * p * np.cos(phi + 2.0 * np.pi / 3.0)
        if not (w_min >= ratio * max(w_max, 1e-300)):
            redo[j] = True
            continue
        c00 = s[1, 1] * s[2, 2] - s[1, 2] * s[2, 1]
        c01 = s[0, 2] * s[2, 1] - s[0, 1] * s[2, 2]
        c02 = s[0, 1] * s[1, 2] - s[0, 2] * s[1, 1]
        c11 = s[0, 0] * s[2, 2] - s[0, 2] * s[2, 0]
        c12 = s[0, 2] * s[1, 0] - s[0, 0] * s[1, 2]
        c22 = s[0, 0] * s[1, 1] - s[0, 1] * s[1, 0]
        c10 = s[1, 2] * s[2, 0] - s[1, 0] * s[2, 2]
        c20 = s[1, 0] * s[2, 1] - s[1, 1] * s[2, 0]
        c21 = s[0, 1] * s[2, 0] - s[0, 0] * s[2, 1]
        det = s[0, 0] * c00 + s[0, 1] * c10 + s[0, 2] * c20
        out[j, 0, 0] = c00 / det / (sc[0] * sc[0])
        out[j, 0, 1] = c01 / det / (sc[0] * sc[1])
        out[j, 0, 2] = c02 / det / (sc[0] * sc[2])
        out[j, 1, 0] = c10 / det / (sc[1] * sc[0])
        out[j, 1, 1] = c11 / det / (sc[1] * sc[1])
        out[j, 1, 2] = c12 / det / (sc[1] * sc[2])
        out[j, 2, 0] = c20 / det / (sc[2] * sc[0])
        out[j, 2, 1] = c21 / det / (sc[2] * sc[1])
        out[j, 2, 2] = c22 / det / (sc[2] * sc[2])


@njit(cache=True)
def _nb_cholesky(a: F64, low: F64) -> bool:  # pragma: no cover - numba
    """Lower Cholesky factor of ``a`` into ``low`` (zeroed); False if not positive definite."""
    n = a.shape[0]
    for j in range(n):
        d = a[j, j]
        for k in range(j):
            d -= low[j, k] * low[j, k]
        if not d > 0.0:
            return False
        low[j, j] = np.sqrt(d)
        for i in range(j + 1, n):
            t = a[i, j]
            for k in range(j):
                t -= low[i, k] * low[j, k]
            low[i, j] = t / low[j, j]
    return True


@njit(cache=True)
def _nb_cho_solve(low: F64, x: F64) -> None:  # pragma: no cover - numba
    """Solve ``L L^T y = x`` in place."""
    n = low.shape[0]
    for i in range(n):
        t = x[i]
        for k in range(i):
            t -= low[i, k] * x[k]
        x[i] = t / low[i, i]
    for i in range(n - 1, -1, -1):
        t = x[i]
        for k in range(i + 1, n):
            t -= low[k, i] * x[k]
        x[i] = t / low[i, i]


# ------------------------------------------------------------- the reduced system in CSR
@njit(cache=True)
def _nb_point_groups(  # pragma: no cover - numba
    cols: Idx, order: Idx, start: Idx, group_of: Idx, n_groups: int, count_only: bool,
    count: Idx, keys: Idx,
) -> None:
    """The groups (images) each point's measurements touch: ``count[j]`` how many distinct
    ones; unless ``count_only``, the keys ``G1 * G + G2`` of all their ordered pairs written
    from ``keys[sum(count[:j]^2)]`` on (``count`` then as the first pass left it)."""
    kmax = cols.shape[1]
    most = 0
    for j in range(start.size - 1):
        most = max(most, (start[j + 1] - start[j]) * kmax)
    buf = np.empty(max(most, 1), np.int64)
    at = 0
    for j in range(start.size - 1):
        d = 0
        for q in range(start[j], start[j + 1]):
            g = cols[order[q]]
            for r in range(kmax):
                if g[r] < 0:
                    continue
                grp = group_of[g[r]]
                new = True
                for t in range(d):
                    if buf[t] == grp:
                        new = False
                        break
                if new:
                    buf[d] = grp
                    d += 1
        if count_only:
            count[j] = d
            continue
        for s in range(d):
            for t in range(d):
                keys[at] = buf[s] * n_groups + buf[t]
                at += 1


@njit(cache=True)
def _nb_csr_position(  # pragma: no cover - numba
    g1: int, g2: int, indptr: Idx, group_of: Idx, local_of: Idx, gptr: Idx, gnbr: Idx,
    slot_offset: Idx,
) -> int:
    """Where ``S[g1, g2]`` is in the CSR data: its row's start, the offset of ``g2``'s group
    among the row group's neighbours (binary search), ``g2``'s rank in its group; -1 if the
    pattern does not hold it."""
    a = group_of[g1]
    b = group_of[g2]
    lo = gptr[a]
    end = gptr[a + 1]
    hi = end
    while lo < hi:
        mid = (lo + hi) // 2
        if gnbr[mid] < b:
            lo = mid + 1
        else:
            hi = mid
    if lo == end or gnbr[lo] != b:
        return -1
    return indptr[g1] + slot_offset[lo] + local_of[g2]


@njit(cache=True)
def _nb_slot(a: int, b: int, gptr: Idx, gnbr: Idx, slot_offset: Idx) -> int:  # pragma: no cover
    """Where group ``b``'s columns start in the rows of group ``a``; -1 if the pattern does
    not link them."""
    lo = gptr[a]
    end = gptr[a + 1]
    hi = end
    while lo < hi:
        mid = (lo + hi) // 2
        if gnbr[mid] < b:
            lo = mid + 1
        else:
            hi = mid
    if lo == end or gnbr[lo] != b:
        return -1
    return slot_offset[lo]


@njit(cache=True)
def _nb_positions(  # pragma: no cover - numba
    rows: Idx, cols: Idx, indptr: Idx, group_of: Idx, local_of: Idx, gptr: Idx, gnbr: Idx,
    slot_offset: Idx, out: Idx,
) -> None:
    """:func:`_nb_csr_position` of each ``(rows[i], cols[i])``."""
    for i in range(rows.size):
        out[i] = _nb_csr_position(rows[i], cols[i], indptr, group_of, local_of, gptr, gnbr,
                                  slot_offset)


@njit(cache=True)
def _nb_npp_csr(  # pragma: no cover - numba
    a: F64, cols: Idx, data: F64, indptr: Idx, group_of: Idx, local_of: Idx, gptr: Idx,
    gnbr: Idx, slot_offset: Idx,
) -> bool:
    """Each measurement's ``A^T A`` added into the CSR ``data`` of ``N_pp``; False (data
    partly updated) as soon as an entry falls outside the pattern."""
    kmax = a.shape[2]
    n_groups = gptr.size - 1
    for m in range(a.shape[0]):
        g = cols[m]
        last = -1
        off = 0
        for r in range(kmax):
            if g[r] < 0:
                continue
            grp_r = group_of[g[r]]
            for c in range(kmax):
                if g[c] < 0:
                    continue
                grp_c = group_of[g[c]]
                if grp_r * n_groups + grp_c != last:
                    off = _nb_slot(grp_r, grp_c, gptr, gnbr, slot_offset)
                    if off < 0:
                        return False
                    last = grp_r * n_groups + grp_c
                data[indptr[g[r]] + off + local_of[g[c]]] += (a[m, 0, r] * a[m, 0, c]
                                                              + a[m, 1, r] * a[m, 1, c])
    return True


@njit(cache=True)
def _nb_reduce_csr(  # pragma: no cover - numba
    n_px: F64, cinv: F64, b_x: F64, cols: Idx, order: Idx, start: Idx, data: F64, rhs: F64,
    indptr: Idx, group_of: Idx, local_of: Idx, gptr: Idx, gnbr: Idx, slot_offset: Idx,
) -> bool:
    """:func:`_nb_reduce` over every point, subtracted in place from the CSR ``data``; False
    (data and rhs partly updated) as soon as an entry falls outside the pattern."""
    kmax = n_px.shape[1]
    n_groups = gptr.size - 1
    most = 0
    for j in range(start.size - 1):
        most = max(most, start[j + 1] - start[j])
    left = np.empty((most, kmax, 3))
    cbx = np.empty(3)
    for j in range(start.size - 1):
        m0 = start[j]
        n = start[j + 1] - m0
        cj = cinv[j]
        for i in range(3):
            cbx[i] = cj[i, 0] * b_x[j, 0] + cj[i, 1] * b_x[j, 1] + cj[i, 2] * b_x[j, 2]
        for q in range(n):
            m = order[m0 + q]
            g = cols[m]
            for r in range(kmax):
                for c in range(3):
                    left[q, r, c] = (n_px[m, r, 0] * cj[0, c] + n_px[m, r, 1] * cj[1, c]
                                     + n_px[m, r, 2] * cj[2, c])
                if g[r] >= 0:
                    rhs[g[r]] -= (n_px[m, r, 0] * cbx[0] + n_px[m, r, 1] * cbx[1]
                                  + n_px[m, r, 2] * cbx[2])
        for qa in range(n):
            ga = cols[order[m0 + qa]]
            for qb in range(qa, n):
                mb = order[m0 + qb]
                gb = cols[mb]
                last_ab = -1  # the group pair of the last slot looked up, and its offsets
                off_ab = 0
                off_ba = 0
                for r in range(kmax):
                    if ga[r] < 0:
                        continue
                    grp_a = group_of[ga[r]]
                    for c in range(kmax):
                        if gb[c] < 0:
                            continue
                        grp_b = group_of[gb[c]]
                        key = grp_a * n_groups + grp_b
                        if key != last_ab:
                            off_ab = _nb_slot(grp_a, grp_b, gptr, gnbr, slot_offset)
                            off_ba = _nb_slot(grp_b, grp_a, gptr, gnbr, slot_offset)
                            if off_ab < 0 or off_ba < 0:
                                return False
                            last_ab = key
                        val = (left[qa, r, 0] * n_px[mb, c, 0] + left[qa, r, 1] * n_px[mb, c, 1]
                               + left[qa, r, 2] * n_px[mb, c, 2])
                        data[indptr[ga[r]] + off_ab + local_of[gb[c]]] -= val
                        if qb != qa:
                            data[indptr[gb[c]] + off_ba + local_of[ga[r]]] -= val
    return True
