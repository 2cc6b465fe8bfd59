"""Sparse normal equations of a block, reduced over the ground points (Schur complement).

The unknowns are the adjustable parameters of every image (``K`` in all, image ``i`` owning
``K_i`` of them) and three local coordinates per ground point. An image measurement ``m`` of
point ``j`` in image ``i`` contributes, with its 2 x 2 weight ``W_m``, the blocks
``A^T W A`` (parameters of ``i``), ``A^T W B`` (parameters of ``i`` with point ``j``) and
``B^T W B`` (point ``j``), where ``A`` (2, K_i) and ``B`` (2, 3) are its partials. The 3 x 3
point blocks are inverted per point (``C_j``) and the point unknowns eliminated::

    S = N_pp - sum_j N_pj C_j N_jp,     s = b_p - sum_j N_pj C_j b_j

``S`` is assembled from the pairs of measurements of each point (a point seen by ``n``
images adds ``n^2`` blocks): as a dense array with the dense solver (at most
:data:`DENSE_LIMIT` parameters), else in place into its CSR pattern (the blocks of the
images each point links, built once per system; :data:`CSR_ASSEMBLY`) so that no (K, K)
dense array is ever built. The point steps follow by back-substitution.

Solvers (``NormalSystem(..., solver=)``, :mod:`geoblock.adjust._solvers`): ``"dense"``
Cholesky, ``"direct"`` sparse LDL^T (SuperLU, minimum degree ordering), ``"iterative"``
conjugate gradients with a block-Jacobi preconditioner (one block per image), stopped when
no unknown errs by more than :data:`~geoblock.adjust._solvers.PCG_TOLERANCE` of its
posterior sigma (estimated), an :class:`IterativeSolverError` when the iteration cap comes
first. ``"auto"``: dense up to :data:`AUTO_DENSE_LIMIT`, then direct while the factor's
estimated memory is at most :data:`DIRECT_MEMORY_LIMIT`, iterative beyond; the choice and
its outcome are :attr:`NormalSystem.solver_used` and :attr:`NormalSystem.solver_report`.

Covariances: :meth:`NormalSystem.parameter_cofactor` gives the dense ``Q_pp`` up to
:data:`DENSE_COFACTOR_LIMIT` parameters, or, for the columns asked
(:meth:`NormalSystem.cofactor_columns` of some images and points), a
:class:`SelectedCofactor` solved from the factorisation; :meth:`NormalSystem.point_cofactors`
and :meth:`NormalSystem.hat_blocks` take either (NaN for the points and measurements whose
columns a selection does not hold).

For callers (the block engine): give ``n_pp_prior`` as a scipy.sparse matrix (a dense one is
itself (K, K)); read the damping's diagonal from ``n_pp_diagonal`` (or ``n_pp.diagonal()``,
which works for both storages; ``np.diagonal(n_pp)`` does not); scale convergence tests with
:meth:`NormalSystem.inverse_diagonal`; above :data:`DENSE_COFACTOR_LIMIT` parameters ask
``parameter_cofactor(cofactor_columns(images=..., points=...))`` and expect NaN outside the
selection; state ``solver_statement`` in the report; an :class:`IterativeSolverError` is a
``LinAlgError`` but not a singular system (no point in diagnosing null directions); and
``reduced.toarray()`` of a sparse ``reduced`` is (K, K): only below ``DENSE_LIMIT``.

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

from dataclasses import dataclass, field
from typing import Any, TypeAlias

import numpy as np
import scipy.linalg
import scipy.linalg.lapack
import scipy.sparse
import scipy.sparse.linalg

from geoblock.adjust import _solvers
from geoblock.adjust._covariance import SelectedCofactor
from geoblock.adjust._kernels import (
    _nb_accumulate,
    _nb_back_substitute,
    _nb_chunks,
    _nb_hat_blocks,
    _nb_inv3,
    _nb_npp_csr,
    _nb_npp_triplets,
    _nb_point_cofactors,
    _nb_reduce,
    _nb_reduce_csr,
)
from geoblock.adjust._pattern import _CsrPattern
from geoblock.adjust._solvers import IterativeSolverError, SolverReport
from geoblock.typing import Float64Array, IndexArray

__all__ = ["AUTO_DENSE_LIMIT", "CSR_ASSEMBLY", "DENSE_COFACTOR_LIMIT", "DENSE_LIMIT",
           "DIRECT_MEMORY_LIMIT", "SOLVERS", "USE_NUMBA", "IterativeSolverError",
           "NormalSystem", "Pairs", "SelectedCofactor", "SingularPoints", "SolverReport",
           "compress_columns", "measurement_pairs"]

#: up to this many parameters the reduced system is dense and solved by Cholesky
#: (``solver="auto"``); above, no (K, K) dense array is built
DENSE_LIMIT = 4000
#: ``solver="auto"`` solves densely up to this many parameters (at most DENSE_LIMIT). The
#: sparse direct path is faster from some 500 parameters on strip blocks (reduce + solve of
#: 1200: 0.14 s against 0.62 s; 3600: 0.44 s against 3.2 s; benchmarks/README.md)
AUTO_DENSE_LIMIT = DENSE_LIMIT
#: ``solver="auto"`` above AUTO_DENSE_LIMIT: the sparse direct factorisation while its estimated
#: size (16 bytes per nonzero of L + U) is at most this many bytes, conjugate gradients beyond
DIRECT_MEMORY_LIMIT = _solvers.DIRECT_MEMORY_LIMIT
#: the full (K, K) parameter cofactor (``parameter_cofactor()`` without columns) up to this
#: many parameters (four (K, K) arrays at the peak: 2 GB at 8000); above, ask for columns
DENSE_COFACTOR_LIMIT = 8000
#: the solvers of the reduced system (see :mod:`geoblock.adjust._solvers`)
SOLVERS = ("auto", "dense", "direct", "iterative")
#: assemble, reduce and back-substitute with the numba kernels (False: the numpy reference)
USE_NUMBA = True
#: with the kernels, dense reduced systems up to this size are factored on the calling
#: thread (a numba Cholesky): as fast as LAPACK's at this size, and immune to the wake-up
#: delays of BLAS's worker threads competing with numba's for the cores
SERIAL_CHOLESKY_LIMIT = 400
#: above DENSE_LIMIT, the Schur complement's triplets are built for runs of points of at most
#: this many at a time (24 bytes each) and summed into the sparse reduced system
SPARSE_CHUNK_TRIPLETS = 1 << 22
#: above DENSE_LIMIT, with the kernels: N_pp and the Schur complement summed in place into
#: the reduced system's CSR pattern (built once per system from the images each point links)
#: instead of triplets (False: the triplets, SPARSE_CHUNK_TRIPLETS at a time; 10 times
#: slower, scipy's conversions dominating)
CSR_ASSEMBLY = True

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

    ``cache`` keeps the reduced system's sparse pattern for the next :class:`NormalSystem`
    built with these pairs (the next linearisation of the same block): it is checked as it
    is used, and rebuilt when a measurement's columns leave it.
    """

    a: np.ndarray
    b: np.ndarray
    point: np.ndarray
    order: np.ndarray | None = None
    start: np.ndarray | None = None
    cache: dict[Any, Any] = field(default_factory=dict, compare=False, repr=False)


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
        Global parameter index of each image's padded columns (-1: padding). Its rows are
        the blocks of the iterative solver's block-Jacobi preconditioner.
    image_of, point_of : ndarray of intp, (M,)
        The image and point of each measurement.
    a : ndarray, (M, 2, Kc)
        Whitened parameter partials ``W^(1/2) A`` in the columns ``cols`` (by default the
        image's padded columns ``gidx[image_of]``, ``Kc = Kmax``).
    b : ndarray, (M, 2, 3)
        Whitened point partials ``W^(1/2) B``.
    v : ndarray, (M, 2)
        Whitened residuals, observed minus computed.
    n_pp_prior : ndarray (K, K) or scipy.sparse matrix (K, K)
        Prior weight of the parameters (block diagonal), ``b_p_prior`` (K,) its right-hand
        side. Give it sparse above :data:`DENSE_LIMIT` parameters: a dense one is accepted
        but is itself a (K, K) array.
    n_xx_extra : ndarray, (J, 3, 3)
        Weights on the points other than image measurements (ground pseudo-observations, DEM
        rows), ``b_x_extra`` (J, 3) their right-hand sides.
    pairs : Pairs
    cols : ndarray of intp, (M, Kc), optional
        Global parameter index of each column of ``a`` per measurement (-1: padding, its
        partials zero): the columns a measurement touches (:func:`compress_columns`), so
        that the work per measurement is ``Kc^2``, not ``Kmax^2``. Default
        ``gidx[image_of]``.
    solver : {"auto", "dense", "direct", "iterative"}
        How the reduced system is solved (:mod:`geoblock.adjust._solvers`): ``"dense"``
        Cholesky (only up to :data:`DENSE_LIMIT` parameters: ValueError above),
        ``"direct"`` sparse factorisation (SuperLU), ``"iterative"`` conjugate gradients
        preconditioned by the images' parameter blocks. ``"auto"``: dense up to
        :data:`AUTO_DENSE_LIMIT`, then direct while the factor's estimated size is at most
        :data:`DIRECT_MEMORY_LIMIT` bytes, iterative beyond. After :meth:`solve`,
        :attr:`solver_used` names the method and :attr:`solver_report` (a
        :class:`SolverReport`) states it (``.statement``) and its outcome.

    Attributes
    ----------
    n_pp : ndarray (K, K) or scipy.sparse.csr_matrix
        The parameter block of the normal matrix: dense with the dense solver, sparse
        otherwise (``n_pp.diagonal()`` works for both); ``n_pp_diagonal`` (K,) its diagonal.
    reduced : ndarray or scipy.sparse matrix, (K, K)
        The reduced system of the last :meth:`solve` (damped as it was).
    """

    n_params: int
    gidx: np.ndarray
    image_of: np.ndarray
    point_of: np.ndarray
    a: np.ndarray
    b: np.ndarray
    v: np.ndarray
    n_pp_prior: Any
    b_p_prior: np.ndarray
    n_xx_extra: np.ndarray
    b_x_extra: np.ndarray
    pairs: Pairs
    cols: np.ndarray | None = None
    solver: str = "auto"

    def __post_init__(self) -> None:
        k = self.n_params
        j = self.n_xx_extra.shape[0]
        self._j = j
        self._numba = USE_NUMBA
        if self.solver not in SOLVERS:
            raise ValueError(f"NormalSystem: unknown solver {self.solver!r} "
                             f"(one of {', '.join(SOLVERS)})")
        if self.solver == "dense" and k > DENSE_LIMIT:
            raise ValueError(f"NormalSystem: solver='dense' is limited to DENSE_LIMIT = "
                             f"{DENSE_LIMIT} parameters ({k} here): use 'auto', 'direct' or "
                             "'iterative'")
        self._dense = self.solver == "dense" or (
            self.solver == "auto" and k <= min(AUTO_DENSE_LIMIT, DENSE_LIMIT))
        self._pattern: _CsrPattern | None = None
        self._method: str | None = None
        self.factorization: Any = None
        self.solver_used: str | None = None
        self.solver_report: SolverReport | None = None
        cols = self.gidx[self.image_of] if self.cols is None else self.cols
        self._cols = np.ascontiguousarray(cols, dtype=np.intp)
        if self._cols.shape != (self.a.shape[0], self.a.shape[2]):
            raise ValueError(f"NormalSystem: cols {self._cols.shape} do not match the partials "
                             f"{self.a.shape}")
        prior = self.n_pp_prior
        prior_sparse = scipy.sparse.issparse(prior)
        if prior_sparse:
            prior_diag = np.asarray(prior.diagonal(), dtype=np.float64)
        else:
            prior = np.asarray(prior, dtype=np.float64)
            prior_diag = np.diag(prior).copy()
        if self._numba:
            self.a = np.ascontiguousarray(self.a, dtype=np.float64)
            self.b = np.ascontiguousarray(self.b, dtype=np.float64)
            self.v = np.ascontiguousarray(self.v, dtype=np.float64)
            if self._dense:
                self.n_pp = prior.toarray() if prior_sparse else np.array(prior)
            else:
                self.n_pp = np.empty((0, 0))
            self.b_p = np.array(self.b_p_prior, dtype=np.float64)
            self.n_xx = np.array(self.n_xx_extra, dtype=np.float64)
            self.b_x = np.array(self.b_x_extra, dtype=np.float64)
            self.n_px = np.empty((self.a.shape[0], self.a.shape[2], 3))
            self._order, self._start = _by_point(self.point_of, j, self.pairs)
            diag = prior_diag.copy()
            _nb_accumulate(self.a, self.b, self.v, self._cols, self.point_of,
                           self.n_pp, self.b_p, self.n_xx, self.b_x, self.n_px,
                           self._dense, diag)
            self.n_pp_diagonal = np.diag(self.n_pp).copy() if self._dense else diag
            if not self._dense and CSR_ASSEMBLY:
                self.n_pp = self._csr_npp(prior)
            elif not self._dense:
                self.n_pp = self._sparse_npp(prior)
            return
        at = np.swapaxes(self.a, 1, 2)
        self.n_px = at @ self.b  # (M, Kc, 3)
        n_pp_m = at @ self.a  # (M, Kc, Kc)
        b_p_m = np.einsum("mki,mk->mi", self.a, self.v)  # (M, Kc)
        g = self._cols  # (M, Kc)
        ok = g >= 0
        # image blocks of N_pp and b_p
        both = ok[:, :, None] & ok[:, None, :]
        if self._dense:
            self.n_pp = prior.toarray() if prior_sparse else prior.copy()
            lin = (g[:, :, None] * k + g[:, None, :])[both]
            self.n_pp += np.bincount(lin, n_pp_m[both], minlength=k * k).reshape(k, k)
            self.n_pp_diagonal = np.diag(self.n_pp).copy()
        else:
            rows = np.broadcast_to(g[:, :, None], both.shape)[both]
            cols_ = np.broadcast_to(g[:, None, :], both.shape)[both]
            self.n_pp = (scipy.sparse.csr_matrix(prior) + scipy.sparse.coo_matrix(
                (n_pp_m[both], (rows, cols_)), shape=(k, k)).tocsr()).tocsr()
            self.n_pp_diagonal = np.asarray(self.n_pp.diagonal(), dtype=np.float64)
        self.b_p = self.b_p_prior + np.bincount(g[ok], b_p_m[ok], minlength=k)
        # point blocks
        n_xx_m = np.swapaxes(self.b, 1, 2) @ self.b  # (M, 3, 3)
        self.n_xx = self.n_xx_extra.copy()
        np.add.at(self.n_xx, self.point_of, n_xx_m)
        self.b_x = self.b_x_extra.copy()
        np.add.at(self.b_x, self.point_of, np.einsum("mki,mk->mi", self.b, self.v))

    def _csr_npp(self, prior: Any, fresh: bool = False) -> Any:
        """``N_pp`` in the reduced system's CSR pattern: the previous linearisation's (kept
        in ``pairs.cache``) while every entry falls in it, else (or ``fresh``) built here."""
        k = self.n_params
        self._prior = prior
        coo = scipy.sparse.coo_matrix(prior)
        rows, cols = coo.row.astype(np.intp), coo.col.astype(np.intp)
        key = ("csr", k, self.gidx.shape, hash(np.ascontiguousarray(self.gidx).tobytes()))
        pattern = None if fresh else self.pairs.cache.get(key)
        for _ in range(2):
            if pattern is None:
                pattern = _CsrPattern.build(k, self.gidx, self._cols, self._order,
                                            self._start, rows, cols)
            data = np.zeros(pattern.indices.size)
            pos = pattern.positions(rows, cols)
            if np.all(pos >= 0) and _nb_npp_csr(self.a, self._cols, data, *pattern.lookup):
                break
            pattern = None  # a column or a prior entry outside the cached pattern
        assert pattern is not None
        np.add.at(data, pos, coo.data)
        self.pairs.cache[key] = pattern
        self._pattern = pattern
        return pattern.matrix(data, k)

    def _sparse_npp(self, prior: Any) -> Any:
        """``N_pp`` (CSR): the prior plus each measurement's ``A^T A``, its triplets built
        for runs of measurements (at most SPARSE_CHUNK_TRIPLETS at a time)."""
        k = self.n_params
        kc = self._cols.shape[1]
        out = scipy.sparse.csr_matrix(prior, shape=(k, k), dtype=np.float64)
        m = self.a.shape[0]
        if m == 0 or kc == 0:
            return out
        run = max(1, SPARSE_CHUNK_TRIPLETS // (kc * kc))
        size = min(m, run) * kc * kc
        rows = np.empty(size, np.intp)
        cols = np.empty(size, np.intp)
        vals = np.empty(size)
        for m0 in range(0, m, run):  # runs of measurements, not measurements
            used = _nb_npp_triplets(self.a, self._cols, m0, min(m, m0 + run), rows, cols, vals)
            out = out + scipy.sparse.coo_matrix(
                (vals[:used], (rows[:used], cols[:used])), shape=(k, k)).tocsr()
        return out

    # ------------------------------------------------------------------ solution
    def solve(self, damping: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
        """Parameter and point steps ``(dp (K,), dx (J, 3))`` with Levenberg-Marquardt
        damping ``lambda`` (the diagonals multiplied by ``1 + lambda``).

        The reduced system is solved by :attr:`solver` (the method chosen at the first call
        is kept for the later ones); :attr:`solver_used` and :attr:`solver_report` say how.

        Raises
        ------
        numpy.linalg.LinAlgError
            The point blocks or the reduced system are singular (the caller diagnoses);
            :class:`IterativeSolverError` (a LinAlgError) when conjugate gradients do not
            reach their tolerance within their iteration cap.
        """
        n_pp: Any = self.n_pp
        n_xx = self.n_xx
        if damping:
            n_xx = n_xx + damping * np.einsum("jii->ji", n_xx)[:, :, None] * np.eye(3)
            if self._dense:
                n_pp = n_pp.copy()
                diag = np.arange(n_pp.shape[0])
                n_pp[diag, diag] += damping * n_pp[diag, diag]
            elif self._numba and self._pattern is not None:
                n_pp = n_pp.copy()
                n_pp.data[self._pattern.diag] += damping * self.n_pp_diagonal
            else:
                n_pp = (n_pp + scipy.sparse.diags(damping * self.n_pp_diagonal)).tocsr()
        self.c = _inv3(n_xx, numba=self._numba)  # (J, 3, 3)
        try:
            reduced, rhs = self._reduce(n_pp)
        except _PatternMiss:  # the previous linearisation's pattern: build this one's
            self.n_pp = self._csr_npp(self._prior, fresh=True)
            return self.solve(damping)
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

    @property
    def solver_statement(self) -> str:
        """One line on how the last :meth:`solve` solved the reduced system ("" before)."""
        return "" if self.solver_report is None else self.solver_report.statement

    def _groups(self) -> IndexArray:
        return _solvers.block_groups(self.n_params, self.gidx)

    def _solve_reduced(self, reduced: ReducedMatrix, rhs: F64) -> F64:
        if self._method is None:
            method, estimate = _solvers.choose_method(
                self.solver, reduced, self._groups(), DENSE_LIMIT, DIRECT_MEMORY_LIMIT)
            self._method = method
            self._factor_estimate = estimate
        self.solver_used = self._method
        if reduced.shape[0] == 0:
            self.factorization = None
            self.solver_report = SolverReport(self._method, "no parameters")
            return np.zeros(0)
        self.factorization = _solvers.factorize(
            self._method, reduced, groups=self._groups(), use_numba=USE_NUMBA,
            serial_limit=SERIAL_CHOLESKY_LIMIT, tolerance=_solvers.PCG_TOLERANCE,
            max_iterations=_solvers.PCG_MAX_ITERATIONS)
        out = self.factorization.solve(rhs)
        self.solver_report = self.factorization.report
        if self._factor_estimate is not None:
            self.solver_report.statement += (
                f" (auto: estimated factor {self._factor_estimate / 2**20:.0f} MiB, limit "
                f"{DIRECT_MEMORY_LIMIT / 2**20:.0f} MiB)")
            self.solver_report.details["factor_estimate_bytes"] = self._factor_estimate
        return np.asarray(out)

    def inverse_diagonal(self) -> F64:
        """(K,) ``1 / diag(S)`` of the last reduced system: a cheap lower bound of the
        parameters' cofactor variances (no inverse), good enough to scale a convergence
        test."""
        reduced = self.reduced
        diag = reduced.diagonal()
        return 1.0 / np.maximum(np.asarray(diag, dtype=np.float64), 1e-300)

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
        if self._dense:
            reduced = n_pp - np.bincount(rows * k + cols, vals, minlength=k * k).reshape(k, k)
            return 0.5 * (reduced + reduced.T), rhs
        sub = scipy.sparse.coo_matrix((vals, (rows, cols)), shape=(k, k)).tocsc()
        return scipy.sparse.csc_matrix(n_pp) - sub, rhs

    def _reduce_numba(self, n_pp: Any) -> tuple[ReducedMatrix, F64]:
        k = self.n_params
        rhs = np.array(self.b_p, dtype=np.float64)
        n_points = self._start.size - 1
        if self._dense:
            reduced = np.array(n_pp, dtype=np.float64)
            none = np.empty(0, np.intp)
            _nb_reduce(self.n_px, self.c, self.b_x, self._cols, self._order, self._start,
                       0, n_points, True, reduced, rhs, none, none, np.empty(0))
            reduced += reduced.T
            reduced *= 0.5
            return reduced, rhs
        if self._pattern is not None:  # in place into the CSR pattern
            reduced = n_pp.copy()
            ok = _nb_reduce_csr(self.n_px, self.c, self.b_x, self._cols, self._order,
                                self._start, reduced.data, rhs, *self._pattern.lookup)
            if not ok:  # a pair of images the cached pattern does not link
                raise _PatternMiss
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

    # ------------------------------------------------------------------ covariance
    def cofactor_columns(self, images: Any = None, points: Any = None) -> IndexArray:
        """The parameter columns whose cofactors the given images and points need.

        Parameters
        ----------
        images : array_like of int, optional
            Image indices (rows of ``gidx``): their parameters, for their covariances and
            the hat blocks of their measurements.
        points : array_like of int, optional
            Point indices: the columns of every measurement of them (all the images that
            see them), for their ``Q_xx`` and ``Q_px``.

        Returns
        -------
        ndarray of intp
            Sorted unique global parameter indices, for :meth:`parameter_cofactor`.
        """
        parts = [np.zeros(0, np.intp)]
        if images is not None:
            g = self.gidx[np.asarray(images, dtype=np.intp)]
            parts.append(g[g >= 0])
        if points is not None:
            want = np.zeros(self._j, bool)
            want[np.asarray(points, dtype=np.intp)] = True
            c = self._cols[want[self.point_of]]
            parts.append(c[c >= 0])
        return np.unique(np.concatenate(parts)).astype(np.intp)

    def parameter_cofactor(self, columns: Any = None) -> Any:
        """``Q_pp``, the inverse of the reduced system of the last :meth:`solve` (undamped
        when that was ``solve(0.0)``).

        Parameters
        ----------
        columns : array_like of int, optional
            Global parameter indices (e.g. :meth:`cofactor_columns`). None: every parameter.

        Returns
        -------
        ndarray (K, K) or SelectedCofactor
            Without ``columns``: the dense ``Q_pp`` (at most :data:`DENSE_COFACTOR_LIMIT`
            parameters, ValueError above); with the kernels, a Cholesky inverse in place:
            four (K, K) arrays at the peak, the reduced system's included. With
            ``columns``: a :class:`SelectedCofactor` holding ``Q_pp[columns][:, columns]``,
            solved column by column (256 at a time) from the factorisation of :meth:`solve`
            (conjugate gradients: one run per column); never a (K, K) array.
        """
        if columns is not None:
            return self._selected_cofactor(np.asarray(columns, dtype=np.intp))
        k = self.n_params
        if k > DENSE_COFACTOR_LIMIT:
            raise ValueError(f"NormalSystem.parameter_cofactor: the full ({k}, {k}) cofactor "
                             f"exceeds DENSE_COFACTOR_LIMIT = {DENSE_COFACTOR_LIMIT}; ask for "
                             "the columns needed (cofactor_columns(images=, points=))")
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

    def _selected_cofactor(self, columns: IndexArray) -> SelectedCofactor:
        k = self.n_params
        cols = np.unique(columns)
        if cols.size and (cols[0] < 0 or cols[-1] >= k):
            raise ValueError(f"NormalSystem.parameter_cofactor: columns outside 0..{k - 1}")
        q = np.empty((cols.size, cols.size))
        if cols.size:
            if self.factorization is None:
                raise ValueError("NormalSystem.parameter_cofactor: solve() first")
            chunk = _solvers.COLUMN_CHUNK
            for c0 in range(0, cols.size, chunk):  # chunks of columns, not columns
                sel = cols[c0: c0 + chunk]
                unit = np.zeros((k, sel.size))
                unit[sel, np.arange(sel.size)] = 1.0
                q[:, c0: c0 + sel.size] = self.factorization.solve(unit)[cols]
            q = 0.5 * (q + q.T)
        return SelectedCofactor(n_params=k, columns=cols, q=q)

    @staticmethod
    def _cofactor_lookup(q_pp: Any, k: int) -> tuple[F64, IndexArray]:
        """``(q, pos)``: the held cofactor block and the position of each parameter in it."""
        if isinstance(q_pp, SelectedCofactor):
            return np.ascontiguousarray(q_pp.q, dtype=np.float64), q_pp.pos
        return np.ascontiguousarray(q_pp, dtype=np.float64), np.arange(k, dtype=np.intp)

    def point_cofactors(self, q_pp: Any) -> tuple[np.ndarray, np.ndarray]:
        """``Q_xx`` (J, 3, 3) of the points and ``Q_px`` (M, Kc, 3), the cofactor between
        the parameters of each measurement's columns and its point.

        ``q_pp`` is the dense ``Q_pp`` (K, K) or a :class:`SelectedCofactor`: a point one of
        whose measurements' columns it does not hold gets NaN (``Q_xx`` and the ``Q_px`` of
        all its measurements)."""
        q, pos = self._cofactor_lookup(q_pp, self.n_params)
        if self._numba:
            q_xx = np.empty((self._j, 3, 3))
            q_px = np.empty(self.n_px.shape)
            _nb_point_cofactors(q, pos, self.n_px, self.c, self._cols, self._order,
                                self._start, q_xx, q_px)
            return q_xx, q_px
        p = self.pairs
        ga = self._cols[p.a]
        gb = self._cols[p.b]
        q_ab = _gather(q, pos, ga, gb)  # (P, Kc, Kc)
        u = q_ab @ self.n_px[p.b]  # (P, Kc, 3): Q[i_a, i_b] N_pb
        u_m = np.zeros(self.n_px.shape)
        np.add.at(u_m, p.a, u)
        cb = self.c[self.point_of]
        q_px = -u_m @ cb  # (M, Kc, 3)
        inner = np.zeros((self._j, 3, 3))
        np.add.at(inner, p.point, np.swapaxes(self.n_px[p.a], 1, 2) @ u)
        q_xx = self.c + self.c @ inner @ self.c
        missing = np.zeros(self._j, bool)  # as the kernel: the whole point NaN
        np.logical_or.at(missing, self.point_of, np.isnan(q_px).any(axis=(1, 2)))
        q_xx[missing] = np.nan
        q_px[missing[self.point_of]] = np.nan
        return q_xx, q_px

    def hat_blocks(self, q_pp: Any, q_xx: np.ndarray, q_px: np.ndarray,
                   a: np.ndarray | None = None, b: np.ndarray | None = None) -> np.ndarray:
        """(M, 2, 2) ``W^(1/2) J Q J^T W^(1/2)`` of every measurement.

        ``q_pp`` is the dense ``Q_pp`` or a :class:`SelectedCofactor` (NaN for the
        measurements whose columns or point it does not cover). ``a`` (M, 2, Kc) in the
        system's columns and ``b`` (M, 2, 3) replace the system's whitened partials (e.g.
        partials whitened by the a-priori sigmas alone, without robust weights)."""
        a = self.a if a is None else np.ascontiguousarray(a, dtype=np.float64)
        b = self.b if b is None else np.ascontiguousarray(b, dtype=np.float64)
        q, pos = self._cofactor_lookup(q_pp, self.n_params)
        if self._numba:
            out = np.empty((a.shape[0], 2, 2))
            _nb_hat_blocks(q, pos, np.ascontiguousarray(q_xx, dtype=np.float64),
                           np.ascontiguousarray(q_px, dtype=np.float64), a, b,
                           self._cols, self.point_of, out)
            return out
        g = self._cols
        q_ii = _gather(q, pos, g, g)
        at = np.swapaxes(a, 1, 2)
        bt = np.swapaxes(b, 1, 2)
        cross = a @ q_px @ bt
        return a @ q_ii @ at + cross + np.swapaxes(cross, 1, 2) + b @ q_xx[self.point_of] @ bt


def _gather(q: np.ndarray, pos: np.ndarray, ga: np.ndarray, gb: np.ndarray) -> np.ndarray:
    """(N, Kc, Kc) blocks ``q[pos[ga[n, :]], pos[gb[n, :]]]``: zero where an index is -1,
    NaN where ``pos`` is -1 (a column not held)."""
    ia = pos[np.maximum(ga, 0)]
    ib = pos[np.maximum(gb, 0)]
    block = q[np.maximum(ia, 0)[:, :, None], np.maximum(ib, 0)[:, None, :]]
    block = np.where((ia < 0)[:, :, None] | (ib < 0)[:, None, :], np.nan, block)
    mask = (ga >= 0)[:, :, None] & (gb >= 0)[:, None, :]
    return np.where(mask, block, 0.0)


class _PatternMiss(Exception):
    """A point links two images the cached CSR pattern does not (rebuild it)."""


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
