"""Sparse normal equations of a block, reduced over the ground points (Schur complement).

The unknowns are the adjustable parameters of every image (``K`` in all, image ``i`` owning
``K_i`` of them) and three local coordinates per ground point. An image measurement ``m`` of
point ``j`` in image ``i`` contributes, with its 2 x 2 weight ``W_m``, the blocks
``A^T W A`` (parameters of ``i``), ``A^T W B`` (parameters of ``i`` with point ``j``) and
``B^T W B`` (point ``j``), where ``A`` (2, K_i) and ``B`` (2, 3) are its partials. The 3 x 3
point blocks are inverted per point (``C_j``) and the point unknowns eliminated::

    S = N_pp - sum_j N_pj C_j N_jp,     s = b_p - sum_j N_pj C_j b_j

``S`` is assembled from the pairs of measurements of each point (a point seen by ``n``
images adds ``n^2`` blocks). It is solved densely (Cholesky) up to :data:`DENSE_LIMIT`
parameters, and sparsely above; the point steps follow by back-substitution.

Everything is vectorised over measurements and points: no Python loop runs over either.
Parameter blocks are padded to the largest ``K_i`` (``Kmax``); padded columns are zero and
never scattered.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.linalg
import scipy.sparse
import scipy.sparse.linalg

__all__ = ["DENSE_LIMIT", "NormalSystem", "Pairs", "SingularPoints", "measurement_pairs"]

#: up to this many parameters the reduced system is solved densely
DENSE_LIMIT = 4000


@dataclass(frozen=True)
class Pairs:
    """All ordered pairs ``(a, b)`` of measurements of the same point (``a == b`` included).

    ``point`` (P,) is their point; ``a``, ``b`` (P,) index the measurements.
    """

    a: np.ndarray
    b: np.ndarray
    point: np.ndarray


def measurement_pairs(point_of: np.ndarray, n_points: int) -> Pairs:
    """The :class:`Pairs` of measurements whose point index is ``point_of`` (M,)."""
    order = np.argsort(point_of, kind="stable")
    counts = np.bincount(point_of, minlength=n_points)
    start = np.concatenate([[0], np.cumsum(counts)[:-1]])
    n_of = counts[point_of[order]]  # per sorted measurement: measurements of its point
    a_sorted = np.repeat(np.arange(order.size), n_of)
    first = np.repeat(np.cumsum(n_of) - n_of, n_of)
    offset = np.arange(a_sorted.size) - first
    b_sorted = start[point_of[order][a_sorted]] + offset
    a = order[a_sorted]
    b = order[b_sorted]
    return Pairs(a, b, point_of[a])


@dataclass
class NormalSystem:
    """The normal equations of one linearisation, and their reduced solution.

    Parameters
    ----------
    n_params : int
        ``K``, the number of parameter unknowns.
    gidx : ndarray of intp, (I, Kmax)
        Global parameter index of each image's padded columns (-1: padding).
    image_of, point_of : ndarray of intp, (M,)
        The image and point of each measurement.
    a : ndarray, (M, 2, Kmax)
        Whitened parameter partials ``W^(1/2) A``.
    b : ndarray, (M, 2, 3)
        Whitened point partials ``W^(1/2) B``.
    v : ndarray, (M, 2)
        Whitened residuals, observed minus computed.
    n_pp_prior : ndarray, (K, K)
        Prior weight of the parameters (block diagonal), ``b_p_prior`` (K,) its right-hand side.
    n_xx_extra : ndarray, (J, 3, 3)
        Weights on the points other than image measurements (ground pseudo-observations, DEM
        rows), ``b_x_extra`` (J, 3) their right-hand sides.
    pairs : Pairs
    """

    n_params: int
    gidx: np.ndarray
    image_of: np.ndarray
    point_of: np.ndarray
    a: np.ndarray
    b: np.ndarray
    v: np.ndarray
    n_pp_prior: np.ndarray
    b_p_prior: np.ndarray
    n_xx_extra: np.ndarray
    b_x_extra: np.ndarray
    pairs: Pairs

    def __post_init__(self) -> None:
        k = self.n_params
        j = self.n_xx_extra.shape[0]
        at = np.swapaxes(self.a, 1, 2)
        self.n_px = at @ self.b  # (M, Kmax, 3)
        n_pp_m = at @ self.a  # (M, Kmax, Kmax)
        b_p_m = np.einsum("mki,mk->mi", self.a, self.v)  # (M, Kmax)
        g = self.gidx[self.image_of]  # (M, Kmax)
        ok = g >= 0
        # image blocks of N_pp and b_p
        self.n_pp = self.n_pp_prior.copy()
        lin = (g[:, :, None] * k + g[:, None, :])[ok[:, :, None] & ok[:, None, :]]
        self.n_pp += np.bincount(lin, n_pp_m[ok[:, :, None] & ok[:, None, :]],
                                 minlength=k * k).reshape(k, k)
        self.b_p = self.b_p_prior + np.bincount(g[ok], b_p_m[ok], minlength=k)
        # point blocks
        n_xx_m = np.swapaxes(self.b, 1, 2) @ self.b  # (M, 3, 3)
        self.n_xx = self.n_xx_extra.copy()
        np.add.at(self.n_xx, self.point_of, n_xx_m)
        self.b_x = self.b_x_extra.copy()
        np.add.at(self.b_x, self.point_of, np.einsum("mki,mk->mi", self.b, self.v))
        self._j = j

    # ------------------------------------------------------------------ solution
    def solve(self, damping: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
        """Parameter and point steps ``(dp (K,), dx (J, 3))`` with Levenberg-Marquardt
        damping ``lambda`` (the diagonals multiplied by ``1 + lambda``).

        Raises
        ------
        numpy.linalg.LinAlgError
            The point blocks or the reduced system are singular (the caller diagnoses).
        """
        n_xx = self.n_xx
        n_pp = self.n_pp
        if damping:
            n_xx = n_xx + damping * np.einsum("jii->ji", n_xx)[:, :, None] * np.eye(3)
            n_pp = n_pp + damping * np.diag(np.diag(n_pp))
        self.c = _inv3(n_xx)  # (J, 3, 3)
        reduced, rhs = self._reduce(n_pp)
        self.reduced = reduced
        dp = self._solve_reduced(reduced, rhs)
        g = self.gidx[self.image_of]
        dp_m = np.where(g >= 0, dp[np.maximum(g, 0)], 0.0)  # (M, Kmax)
        t = self.b_x.copy()
        np.add.at(t, self.point_of, -np.einsum("mki,mk->mi", self.n_px, dp_m))
        dx = np.einsum("jik,jk->ji", self.c, t)
        return dp, dx

    def _reduce(self, n_pp: np.ndarray):
        k = self.n_params
        p = self.pairs
        cb = self.c[self.point_of]  # (M, 3, 3)
        left = self.n_px[p.a] @ cb[p.a]  # (P, Kmax, 3)
        block = left @ np.swapaxes(self.n_px[p.b], 1, 2)  # (P, Kmax, Kmax)
        ga = self.gidx[self.image_of[p.a]]
        gb = self.gidx[self.image_of[p.b]]
        mask = (ga >= 0)[:, :, None] & (gb >= 0)[:, None, :]
        rows = np.broadcast_to(ga[:, :, None], mask.shape)[mask]
        cols = np.broadcast_to(gb[:, None, :], mask.shape)[mask]
        vals = block[mask]
        # rhs: b_p - sum_m N_pm C_j b_j
        cbx = np.einsum("mik,mk->mi", cb, self.b_x[self.point_of])  # (M, 3)
        t = np.einsum("mki,mi->mk", self.n_px, cbx)  # (M, Kmax)
        g = self.gidx[self.image_of]
        rhs = self.b_p - np.bincount(g[g >= 0], t[g >= 0], minlength=k)
        if k <= DENSE_LIMIT:
            reduced = n_pp - np.bincount(rows * k + cols, vals, minlength=k * k).reshape(k, k)
            return 0.5 * (reduced + reduced.T), rhs
        sub = scipy.sparse.coo_matrix((vals, (rows, cols)), shape=(k, k)).tocsc()
        return scipy.sparse.csc_matrix(n_pp) - sub, rhs

    @staticmethod
    def _solve_reduced(reduced, rhs: np.ndarray) -> np.ndarray:
        if reduced.shape[0] == 0:
            return np.zeros(0)
        if scipy.sparse.issparse(reduced):
            lu = scipy.sparse.linalg.splu(reduced.tocsc())
            out = lu.solve(rhs)
            if not np.all(np.isfinite(out)):
                raise np.linalg.LinAlgError("singular reduced system")
            return out
        scale = np.sqrt(np.abs(np.diag(reduced)))
        if np.any(scale == 0):
            raise np.linalg.LinAlgError("a parameter has no observation")
        scaled = reduced / np.outer(scale, scale)
        try:
            factor = scipy.linalg.cho_factor(scaled, lower=True, check_finite=False)
        except scipy.linalg.LinAlgError as exc:
            raise np.linalg.LinAlgError(str(exc)) from None
        d = np.diag(factor[0])
        if d.min() < 1e-7 * d.max():
            raise np.linalg.LinAlgError("ill-conditioned reduced system")
        return scipy.linalg.cho_solve(factor, rhs / scale, check_finite=False) / scale

    # ------------------------------------------------------------------ covariance
    def parameter_cofactor(self) -> np.ndarray:
        """(K, K) ``Q_pp``: the inverse of the reduced system (undamped)."""
        reduced = self.reduced
        if scipy.sparse.issparse(reduced):
            reduced = reduced.toarray()
        if reduced.shape[0] == 0:
            return np.zeros((0, 0))
        scale = np.sqrt(np.diag(reduced))
        inv = np.linalg.inv(reduced / np.outer(scale, scale)) / np.outer(scale, scale)
        return 0.5 * (inv + inv.T)

    def point_cofactors(self, q_pp: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``Q_xx`` (J, 3, 3) of the points and ``Q_px`` (M, Kmax, 3), the cofactor between
        each measurement's image parameters and its point."""
        p = self.pairs
        ga = self.gidx[self.image_of[p.a]]
        gb = self.gidx[self.image_of[p.b]]
        q_ab = _gather(q_pp, ga, gb)  # (P, Kmax, Kmax)
        u = q_ab @ self.n_px[p.b]  # (P, Kmax, 3): Q[i_a, i_b] N_pb
        u_m = np.zeros(self.n_px.shape)
        np.add.at(u_m, p.a, u)
        cb = self.c[self.point_of]
        q_px = -u_m @ cb  # (M, Kmax, 3)
        inner = np.zeros((self._j, 3, 3))
        np.add.at(inner, p.point, np.swapaxes(self.n_px[p.a], 1, 2) @ u)
        q_xx = self.c + self.c @ inner @ self.c
        return q_xx, q_px

    def hat_blocks(self, q_pp: np.ndarray, q_xx: np.ndarray, q_px: np.ndarray) -> np.ndarray:
        """(M, 2, 2) ``W^(1/2) J Q J^T W^(1/2)`` of every measurement."""
        g = self.gidx[self.image_of]
        q_ii = _gather(q_pp, g, g)
        a, b = self.a, self.b
        at = np.swapaxes(a, 1, 2)
        bt = np.swapaxes(b, 1, 2)
        cross = a @ q_px @ bt
        return a @ q_ii @ at + cross + np.swapaxes(cross, 1, 2) + b @ q_xx[self.point_of] @ bt


def _gather(q: np.ndarray, ga: np.ndarray, gb: np.ndarray) -> np.ndarray:
    """(N, Kmax, Kmax) blocks ``q[ga[n, :], gb[n, :]]``, zero where an index is -1."""
    block = q[np.maximum(ga, 0)[:, :, None], np.maximum(gb, 0)[:, None, :]]
    mask = (ga >= 0)[:, :, None] & (gb >= 0)[:, None, :]
    return np.where(mask, block, 0.0)


class SingularPoints(np.linalg.LinAlgError):
    """Some 3 x 3 point blocks are singular; ``points`` (intp) says which."""

    def __init__(self, points: np.ndarray) -> None:
        super().__init__(f"{points.size} singular point block(s)")
        self.points = points


def _inv3(m: np.ndarray) -> np.ndarray:
    """Inverses of (J, 3, 3) symmetric positive definite blocks; :class:`SingularPoints`
    naming the blocks that are not."""
    if m.shape[0] == 0:
        return m.copy()
    scale = np.sqrt(np.abs(np.einsum("jii->ji", m)))
    bad = np.any(scale == 0, axis=1)
    scale[scale == 0] = 1.0
    s = m / (scale[:, :, None] * scale[:, None, :])
    w = np.linalg.eigvalsh(s)
    bad |= w[:, 0] < 1e-10 * np.maximum(w[:, -1], 1e-300)
    if bad.any():
        raise SingularPoints(np.flatnonzero(bad))
    return np.linalg.inv(s) / (scale[:, :, None] * scale[:, None, :])
