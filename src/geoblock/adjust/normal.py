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
parameters, and sparsely above (its triplets built for runs of points,
:data:`SPARSE_CHUNK_TRIPLETS` at a time); the point steps follow by back-substitution.

Everything is vectorised over measurements and points: no Python loop runs over either.
Each measurement carries its parameter partials in the columns it touches, with their global
indices (``cols`` (M, Kc), padded with -1 to the largest count ``Kc``; padded columns are zero
and never scattered): an image's adjustable parameters padded to the largest ``K_i``
(``Kc = Kmax``, the default), or, through :func:`compress_columns`, only the nonzero ones, so
that parameters acting locally (splines in time, whose knots a measurement touches four per
axis) cost ``Kc^2`` per measurement and per pair, not ``Kmax^2``.

Two implementations compute the same quantities: numba kernels that loop over measurements
and over each point's measurements (:data:`USE_NUMBA`, the default), and the vectorised
numpy reference (per-pair blocks gathered and scattered with ``bincount``/``add.at``), which
the tests hold the kernels to. The kernels avoid the reference's (pairs, Kc, Kc)
temporaries and its scatter; the Schur complement is accumulated from each point's pairs
``a <= b`` (the other half by symmetry).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, TypeAlias

import numpy as np
import scipy.linalg
import scipy.linalg.lapack
import scipy.sparse
import scipy.sparse.linalg
from numba import njit

from geoblock.typing import BoolArray, Float64Array, IndexArray

__all__ = ["DENSE_LIMIT", "USE_NUMBA", "NormalSystem", "Pairs", "SingularPoints",
           "compress_columns", "measurement_pairs"]

#: up to this many parameters the reduced system is solved densely
DENSE_LIMIT = 4000
#: assemble, reduce and back-substitute with the numba kernels (False: the numpy reference)
USE_NUMBA = True
#: with the kernels, dense reduced systems up to this size are factored on the calling
#: thread (a numba Cholesky): as fast as LAPACK's at this size, and immune to the wake-up
#: delays of BLAS's worker threads competing with numba's for the cores
SERIAL_CHOLESKY_LIMIT = 400
#: above DENSE_LIMIT, the Schur complement's triplets are built for runs of points of at most
#: this many at a time (24 bytes each) and summed into the sparse reduced system
SPARSE_CHUNK_TRIPLETS = 1 << 22

F64: TypeAlias = Float64Array
Idx: TypeAlias = IndexArray
#: the reduced normal matrix: a dense (K, K) array, or a scipy.sparse matrix above
#: DENSE_LIMIT (scipy ships no type information: Any)
ReducedMatrix: TypeAlias = Any


@dataclass(frozen=True)
class Pairs:
    """All ordered pairs ``(a, b)`` of measurements of the same point (``a == b`` included).

    ``point`` (P,) is their point; ``a``, ``b`` (P,) index the measurements. ``order`` (M,)
    lists the measurements by point (stable) and ``start`` (J + 1,) where each point's run
    begins in it (optional: derived from ``point_of`` when missing).
    """

    a: np.ndarray
    b: np.ndarray
    point: np.ndarray
    order: np.ndarray | None = None
    start: np.ndarray | None = None


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
    return Pairs(a, b, point_of[a], order.astype(np.intp),
                 np.concatenate([[0], np.cumsum(counts)]).astype(np.intp))


def _by_point(point_of: np.ndarray, n_points: int, pairs: Pairs) -> tuple[np.ndarray, ...]:
    """``(order, start)``: the measurements grouped by point (CSR), from ``pairs`` if known."""
    if pairs.order is not None and pairs.start is not None \
            and pairs.start.size == n_points + 1 and pairs.order.size == point_of.size:
        return pairs.order, pairs.start
    order = np.argsort(point_of, kind="stable").astype(np.intp)
    counts = np.bincount(point_of, minlength=n_points)
    return order, np.concatenate([[0], np.cumsum(counts)]).astype(np.intp)


def compress_columns(partials: np.ndarray, columns: np.ndarray
                     ) -> tuple[Float64Array, IndexArray]:
    """Each measurement's parameter partials reduced to the columns it touches.

    A measurement's row of the design matrix is nonzero in a few parameters only when a
    model's parameters act locally (a spline in time touches four knots per axis); the
    normal equations then need only those columns. Column order is kept, so a dense row
    comes back unchanged.

    Parameters
    ----------
    partials : ndarray, (N, 2, K)
        Parameter partials of ``N`` measurements (any unit).
    columns : ndarray of intp, (K,) or (N, K)
        Global index of each column in the parameter vector (-1: none, dropped).

    Returns
    -------
    a : ndarray, (N, 2, Kc)
        The partials of the columns where either of a measurement's two rows is nonzero
        (NaN counts as zero, as the engine's whitening makes it), zero-padded to ``Kc``,
        the largest count over the measurements.
    cols : ndarray of intp, (N, Kc)
        Their global indices, -1 in the padding.
    """
    p = np.asarray(partials, dtype=np.float64)
    n, _, k = p.shape
    cols_in = np.broadcast_to(np.asarray(columns, dtype=np.intp), (n, k))
    nz = np.abs(p[:, 0]) > 0.0  # (N, K); NaN is not > 0
    nz |= np.abs(p[:, 1]) > 0.0
    nz &= cols_in >= 0
    count = nz.sum(axis=1)
    kc = int(count.max(initial=0))
    rows, src = np.nonzero(nz)  # row-major: each row's columns in order
    pos = np.arange(rows.size) - np.repeat(np.cumsum(count) - count, count)
    a = np.zeros((n, 2, kc))
    cols = np.full((n, kc), -1, np.intp)
    a[rows, :, pos] = p[rows, :, src]
    cols[rows, pos] = cols_in[rows, src]
    return a, cols


def _cholesky_inverse(scaled: F64) -> F64 | None:
    """The inverse of an exactly symmetric positive definite matrix by LAPACK's ``potrf`` and
    ``potri``, overwriting ``scaled``; None if it is not positive definite."""
    # symmetric: the transpose is the Fortran-ordered array LAPACK works on in place
    factor, info = scipy.linalg.lapack.dpotrf(scaled.T, lower=True, clean=True,
                                              overwrite_a=True)
    del scaled
    if info != 0:
        return None
    low, info = scipy.linalg.lapack.dpotri(factor, lower=True, overwrite_c=True)
    del factor
    if info != 0:
        return None
    inv = low + low.T  # the upper triangle of low is zero (clean)
    np.fill_diagonal(inv, np.diag(low))
    return inv


def _chunks(weights: IndexArray, budget: int) -> IndexArray:
    """Boundaries ``0 = e_0 < e_1 < ... = n`` splitting ``weights`` (n,) greedily into runs of
    total at most ``budget`` (an item heavier than that makes a run of its own)."""
    out = np.empty(weights.size + 1, np.intp)
    used = _nb_chunks(np.ascontiguousarray(weights, dtype=np.int64), int(budget), out)
    return out[:used]


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
    a : ndarray, (M, 2, Kc)
        Whitened parameter partials ``W^(1/2) A`` in the columns ``cols`` (by default the
        image's padded columns ``gidx[image_of]``, ``Kc = Kmax``).
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
    cols : ndarray of intp, (M, Kc), optional
        Global parameter index of each column of ``a`` per measurement (-1: padding, its
        partials zero): the columns a measurement touches (:func:`compress_columns`), so
        that the work per measurement is ``Kc^2``, not ``Kmax^2``. Default
        ``gidx[image_of]``.
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
    cols: np.ndarray | None = None

    def __post_init__(self) -> None:
        k = self.n_params
        j = self.n_xx_extra.shape[0]
        self._j = j
        self._numba = USE_NUMBA
        cols = self.gidx[self.image_of] if self.cols is None else self.cols
        self._cols = np.ascontiguousarray(cols, dtype=np.intp)
        if self._cols.shape != (self.a.shape[0], self.a.shape[2]):
            raise ValueError(f"NormalSystem: cols {self._cols.shape} do not match the partials "
                             f"{self.a.shape}")
        if self._numba:
            self.a = np.ascontiguousarray(self.a, dtype=np.float64)
            self.b = np.ascontiguousarray(self.b, dtype=np.float64)
            self.v = np.ascontiguousarray(self.v, dtype=np.float64)
            self.n_pp = np.array(self.n_pp_prior, dtype=np.float64)
            self.b_p = np.array(self.b_p_prior, dtype=np.float64)
            self.n_xx = np.array(self.n_xx_extra, dtype=np.float64)
            self.b_x = np.array(self.b_x_extra, dtype=np.float64)
            self.n_px = np.empty((self.a.shape[0], self.a.shape[2], 3))
            self._order, self._start = _by_point(self.point_of, j, self.pairs)
            _nb_accumulate(self.a, self.b, self.v, self._cols, self.point_of,
                           self.n_pp, self.b_p, self.n_xx, self.b_x, self.n_px)
            return
        at = np.swapaxes(self.a, 1, 2)
        self.n_px = at @ self.b  # (M, Kc, 3)
        n_pp_m = at @ self.a  # (M, Kc, Kc)
        b_p_m = np.einsum("mki,mk->mi", self.a, self.v)  # (M, Kc)
        g = self._cols  # (M, Kc)
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
            n_pp = n_pp.copy()
            diag = np.arange(n_pp.shape[0])
            n_pp[diag, diag] += damping * n_pp[diag, diag]
        self.c = _inv3(n_xx, numba=self._numba)  # (J, 3, 3)
        reduced, rhs = self._reduce(n_pp)
        del n_pp
        self.reduced = reduced
        dp = self._solve_reduced(reduced, rhs)
        if self._numba:
            dx = np.empty((self._j, 3))
            _nb_back_substitute(self.n_px, self.c, self.b_x, self._cols, self.point_of,
                                np.ascontiguousarray(dp, dtype=np.float64), dx)
            return dp, dx
        g = self._cols
        dp_m = np.where(g >= 0, dp[np.maximum(g, 0)], 0.0)  # (M, Kc)
        t = self.b_x.copy()
        np.add.at(t, self.point_of, -np.einsum("mki,mk->mi", self.n_px, dp_m))
        dx = np.einsum("jik,jk->ji", self.c, t)
        return dp, dx

    def _reduce(self, n_pp: F64) -> tuple[ReducedMatrix, F64]:
        if self._numba:
            return self._reduce_numba(n_pp)
        k = self.n_params
        p = self.pairs
        cb = self.c[self.point_of]  # (M, 3, 3)
        left = self.n_px[p.a] @ cb[p.a]  # (P, Kc, 3)
        block = left @ np.swapaxes(self.n_px[p.b], 1, 2)  # (P, Kc, Kc)
        ga = self._cols[p.a]
        gb = self._cols[p.b]
        mask = (ga >= 0)[:, :, None] & (gb >= 0)[:, None, :]
        rows = np.broadcast_to(ga[:, :, None], mask.shape)[mask]
        cols = np.broadcast_to(gb[:, None, :], mask.shape)[mask]
        vals = block[mask]
        # rhs: b_p - sum_m N_pm C_j b_j
        cbx = np.einsum("mik,mk->mi", cb, self.b_x[self.point_of])  # (M, 3)
        t = np.einsum("mki,mi->mk", self.n_px, cbx)  # (M, Kc)
        g = self._cols
        rhs = self.b_p - np.bincount(g[g >= 0], t[g >= 0], minlength=k)
        if k <= DENSE_LIMIT:
            reduced = n_pp - np.bincount(rows * k + cols, vals, minlength=k * k).reshape(k, k)
            return 0.5 * (reduced + reduced.T), rhs
        sub = scipy.sparse.coo_matrix((vals, (rows, cols)), shape=(k, k)).tocsc()
        return scipy.sparse.csc_matrix(n_pp) - sub, rhs

    def _reduce_numba(self, n_pp: F64) -> tuple[ReducedMatrix, F64]:
        k = self.n_params
        rhs = np.array(self.b_p, dtype=np.float64)
        n_points = self._start.size - 1
        if k <= DENSE_LIMIT:
            reduced = np.array(n_pp, dtype=np.float64)
            none = np.empty(0, np.intp)
            _nb_reduce(self.n_px, self.c, self.b_x, self._cols, self._order, self._start,
                       0, n_points, True, reduced, rhs, none, none, np.empty(0))
            reduced += reduced.T
            reduced *= 0.5
            return reduced, rhs
        # sparse: the triplets of a run of points at a time (bounded memory), summed
        kc = self._cols.shape[1]
        n = np.diff(self._start)
        per_point = n * (n + 1) * kc * kc  # two triplets per pair a < b, one for a == b
        bounds = _chunks(per_point, SPARSE_CHUNK_TRIPLETS)
        size = max((int(per_point[j0:j1].sum()) for j0, j1 in zip(bounds[:-1], bounds[1:],
                                                                    strict=True)), default=0)
        rows = np.empty(size, np.intp)
        cols = np.empty(size, np.intp)
        vals = np.empty(size)
        reduced = scipy.sparse.csc_matrix(n_pp)
        for j0, j1 in zip(bounds[:-1], bounds[1:], strict=True):  # runs of points, not points
            used = _nb_reduce(self.n_px, self.c, self.b_x, self._cols, self._order,
                              self._start, int(j0), int(j1), False, np.empty((0, 0)), rhs,
                              rows, cols, vals)
            reduced = reduced + scipy.sparse.coo_matrix(
                (vals[:used], (rows[:used], cols[:used])), shape=(k, k)).tocsc()
        return reduced, rhs

    @staticmethod
    def _solve_reduced(reduced: ReducedMatrix, rhs: F64) -> F64:
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
        if USE_NUMBA and scaled.shape[0] <= SERIAL_CHOLESKY_LIMIT:
            low = np.zeros(scaled.shape)
            if not _nb_cholesky(np.ascontiguousarray(scaled), low):
                raise np.linalg.LinAlgError("reduced system not positive definite")
            d = np.diag(low)
            if d.min() < 1e-7 * d.max():
                raise np.linalg.LinAlgError("ill-conditioned reduced system")
            out = np.ascontiguousarray(rhs / scale, dtype=np.float64)
            _nb_cho_solve(low, out)
            return out / scale
        try:
            factor = scipy.linalg.cho_factor(scaled, lower=True, overwrite_a=True,
                                             check_finite=False)
        except scipy.linalg.LinAlgError as exc:
            raise np.linalg.LinAlgError(str(exc)) from None
        d = np.diag(factor[0])
        if d.min() < 1e-7 * d.max():
            raise np.linalg.LinAlgError("ill-conditioned reduced system")
        return scipy.linalg.cho_solve(factor, rhs / scale, check_finite=False) / scale

    # ------------------------------------------------------------------ covariance
    def parameter_cofactor(self) -> np.ndarray:
        """(K, K) ``Q_pp``: the inverse of the reduced system (undamped).

        Dense whatever the reduced system's storage (the posterior covariance of every
        parameter); with the kernels, a Cholesky inverse in place: four (K, K) arrays at the
        peak, the reduced system's included."""
        reduced = self.reduced
        if scipy.sparse.issparse(reduced):
            reduced = reduced.toarray()
            reduced += reduced.T  # the triplets' sums are symmetric to rounding only
            reduced *= 0.5
        if reduced.shape[0] == 0:
            return np.zeros((0, 0))
        scale = np.sqrt(np.diag(reduced))
        outer = np.outer(scale, scale)
        if self._numba:  # Cholesky inverse (potrf + potri): a third of a general inverse
            inv = _cholesky_inverse(reduced / outer)
            if inv is not None:
                inv /= outer
                return inv  # exactly symmetric
        inv = np.linalg.inv(reduced / outer) / outer
        return 0.5 * (inv + inv.T)

    def point_cofactors(self, q_pp: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``Q_xx`` (J, 3, 3) of the points and ``Q_px`` (M, Kc, 3), the cofactor between
        the parameters of each measurement's columns and its point."""
        if self._numba:
            q_xx = np.empty((self._j, 3, 3))
            q_px = np.empty(self.n_px.shape)
            _nb_point_cofactors(np.ascontiguousarray(q_pp, dtype=np.float64), self.n_px,
                                self.c, self._cols, self._order, self._start, q_xx, q_px)
            return q_xx, q_px
        p = self.pairs
        ga = self._cols[p.a]
        gb = self._cols[p.b]
        q_ab = _gather(q_pp, ga, gb)  # (P, Kc, Kc)
        u = q_ab @ self.n_px[p.b]  # (P, Kc, 3): Q[i_a, i_b] N_pb
        u_m = np.zeros(self.n_px.shape)
        np.add.at(u_m, p.a, u)
        cb = self.c[self.point_of]
        q_px = -u_m @ cb  # (M, Kc, 3)
        inner = np.zeros((self._j, 3, 3))
        np.add.at(inner, p.point, np.swapaxes(self.n_px[p.a], 1, 2) @ u)
        q_xx = self.c + self.c @ inner @ self.c
        return q_xx, q_px

    def hat_blocks(self, q_pp: np.ndarray, q_xx: np.ndarray, q_px: np.ndarray,
                   a: np.ndarray | None = None, b: np.ndarray | None = None) -> np.ndarray:
        """(M, 2, 2) ``W^(1/2) J Q J^T W^(1/2)`` of every measurement.

        ``a`` (M, 2, Kc) in the system's columns and ``b`` (M, 2, 3) replace the system's
        whitened partials (e.g. partials whitened by the a-priori sigmas alone, without
        robust weights)."""
        a = self.a if a is None else np.ascontiguousarray(a, dtype=np.float64)
        b = self.b if b is None else np.ascontiguousarray(b, dtype=np.float64)
        if self._numba:
            out = np.empty((a.shape[0], 2, 2))
            _nb_hat_blocks(np.ascontiguousarray(q_pp, dtype=np.float64),
                           np.ascontiguousarray(q_xx, dtype=np.float64),
                           np.ascontiguousarray(q_px, dtype=np.float64), a, b,
                           self._cols, self.point_of, out)
            return out
        g = self._cols
        q_ii = _gather(q_pp, g, g)
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


def _inv3(m: np.ndarray, numba: bool = False) -> np.ndarray:
    """Inverses of (J, 3, 3) symmetric positive definite blocks; :class:`SingularPoints`
    naming the blocks that are not.

    A block is singular when a diagonal is 0 or, scaled to a unit diagonal, its smallest
    eigenvalue is below 1e-10 times its largest. ``numba``: the eigenvalues in closed form
    and the inverse by the adjugate, per block in a kernel; blocks whose eigenvalue ratio is
    below 1e-6 (near the test, or ill-conditioned) are redone by the numpy reference.
    """
    if m.shape[0] == 0:
        return m.copy()
    if numba:
        m = np.ascontiguousarray(m, dtype=np.float64)
        out = np.empty(m.shape)
        redo = np.zeros(m.shape[0], np.bool_)
        _nb_inv3(m, out, redo, 1e-6)
        if redo.any():
            idx = np.flatnonzero(redo)
            try:
                out[idx] = _inv3(m[idx])
            except SingularPoints as exc:
                raise SingularPoints(idx[exc.points]) from None
        return out
    scale = np.sqrt(np.abs(np.einsum("jii->ji", m)))
    bad = np.any(scale == 0, axis=1)
    scale[scale == 0] = 1.0
    s = m / (scale[:, :, None] * scale[:, None, :])
    w = np.linalg.eigvalsh(s)
    bad |= w[:, 0] < 1e-10 * np.maximum(w[:, -1], 1e-300)
    if bad.any():
        raise SingularPoints(np.flatnonzero(bad))
    return np.linalg.inv(s) / (scale[:, :, None] * scale[:, None, :])


# ================================================================================ kernels
@njit(cache=True)
def _nb_accumulate(  # pragma: no cover - numba
    a: F64, b: F64, v: F64, cols: Idx, point_of: Idx, n_pp: F64, b_p: F64,
    n_xx: F64, b_x: F64, n_px: F64,
) -> None:
    """Per measurement: ``N_px = A^T B`` into ``n_px``; ``A^T A``, ``A^T v`` scattered into
    ``n_pp``, ``b_p``; ``B^T B``, ``B^T v`` into the point's ``n_xx``, ``b_x``."""
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
    q_pp: F64, n_px: F64, cinv: F64, cols: Idx, order: Idx, start: Idx,
    q_xx: F64, q_px: F64,
) -> None:
    """:meth:`NormalSystem.point_cofactors`, point by point: ``U_a = sum_b Q[i_a, i_b] N_pb``,
    ``Q_px[a] = -U_a C_j``, ``Q_xx[j] = C_j + C_j (sum_a N_pa^T U_a) C_j``."""
    kmax = n_px.shape[1]
    u = np.empty((kmax, 3))
    inner = np.empty((3, 3))
    tmp = np.empty((3, 3))
    for j in range(start.size - 1):
        m0 = start[j]
        n = start[j + 1] - m0
        cj = cinv[j]
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
                    for c in range(kmax):
                        if gb[c] < 0:
                            continue
                        q = q_pp[ga[r], gb[c]]
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
    q_pp: F64, q_xx: F64, q_px: F64, a: F64, b: F64, cols: Idx, point_of: Idx, out: F64,
) -> None:
    """:meth:`NormalSystem.hat_blocks` per measurement."""
    kmax = a.shape[2]
    aq = np.empty(kmax)
    for m in range(a.shape[0]):
        g = cols[m]
        j = point_of[m]
        for s in range(2):
            for t in range(2):
                acc = 0.0
                # A Q_ii A^T
                for c in range(kmax):
                    aq[c] = 0.0
                for r in range(kmax):
                    if g[r] < 0:
                        continue
                    for c in range(kmax):
                        if g[c] >= 0:
                            aq[c] += a[m, s, r] * q_pp[g[r], g[c]]
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
