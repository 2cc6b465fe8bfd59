"""Solvers of the reduced normal equations ``S dp = s`` (:mod:`geoblock.adjust.normal`).

Three factorisations of the symmetric positive definite reduced system ``S`` (K, K), each
scaled to a unit diagonal first (``D S D``, ``D = diag(S)^(-1/2)``) and each solving for any
number of right-hand sides (the step, or unit columns for selected cofactors):

``dense``
    Cholesky (LAPACK ``potrf``; a numba Cholesky on the calling thread up to
    ``SERIAL_CHOLESKY_LIMIT``) of the dense ``S``; only up to :data:`~geoblock.adjust.normal.
    DENSE_LIMIT` parameters.
``direct``
    Sparse Cholesky-like ``L U`` factorisation by SuperLU (scipy): symmetric mode, the
    multiple minimum degree ordering of ``S + S^T`` (``MMD_AT_PLUS_A``) and diagonal pivots
    only, so that ``L U`` is ``L D L^T`` under one symmetric permutation. Measured on strip
    blocks (every image overlapping its 8 neighbours, 6 parameters each): 10^4 images
    (K = 60000) factor in 1.7 s with 2.6e7 nonzeros; the COLAMD ordering fills twice as
    much and takes 4 times as long. scikit-sparse's CHOLMOD was not used: it is only an
    sdist that needs SuiteSparse's headers to build, so it would not install on a fresh
    machine with pip alone.
``iterative``
    Preconditioned conjugate gradients with a block-Jacobi preconditioner: one block per
    image's parameters (the rows of ``gidx``), the other parameters one block each. It
    stops when the estimated energy norm of its error, ``||e||_S``, is below
    :data:`PCG_TOLERANCE`: by Cauchy-Schwarz no unknown, parameter or ground point (the
    point steps are back-substituted, and the full system's error norm equals the reduced
    one's), then errs by more than that many of its posterior cofactor sigmas. The estimate
    is the Hestenes-Stiefel sum ``sum_k alpha_k r_k^T z_k`` over the last :data:`PCG_DELAY`
    iterations, extrapolated geometrically to the rest (Strakos and Tichy 2002). A run that
    has not met it after :data:`PCG_MAX_ITERATIONS` raises :class:`IterativeSolverError`.

``auto`` (:func:`choose_method`): ``dense`` up to ``DENSE_LIMIT`` parameters; above,
``direct`` while the factor's estimated memory, 16 bytes per nonzero of ``L`` and ``U``, is
at most :data:`DIRECT_MEMORY_LIMIT`, else ``iterative``. The nonzeros are estimated without
factoring ``S``: the image graph (one node per image, an edge where two images' parameters
are coupled) is factored with the same ordering, and each of its factor's nonzeros counts
``(K / nodes)^2``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Protocol

import numpy as np
import scipy.linalg
import scipy.sparse
import scipy.sparse.linalg

from geoblock.adjust._kernels import _nb_cho_solve, _nb_cholesky
from geoblock.typing import Float64Array, IndexArray

__all__ = ["DIRECT_MEMORY_LIMIT", "PCG_DELAY", "PCG_MAX_ITERATIONS", "PCG_TOLERANCE",
           "IterativeSolverError", "SolverReport", "choose_method", "estimate_factor_bytes",
           "factorize"]

#: the sparse direct solver is chosen while its factor's estimated size is at most this
#: (bytes: 16 per nonzero of L and U, values, indices and SuperLU's supernodal slack)
DIRECT_MEMORY_LIMIT = 4 << 30
#: conjugate gradients stop when the estimated energy norm of the error is below this: no
#: unknown is then off by more than this many of its posterior cofactor sigmas
PCG_TOLERANCE = 1e-8
#: ... or, when the step itself is that long, 1e-13 of its length (double precision's floor)
PCG_RELATIVE_FLOOR = 1e-13
#: the iteration cap of conjugate gradients
PCG_MAX_ITERATIONS = 5000
#: the iterations over which the error's energy norm is estimated
PCG_DELAY = 10
#: ill-conditioning test of the factorisations: the unit-diagonal-scaled system's smallest
#: Cholesky pivot below this fraction of its largest (squared for the LDL^T pivots)
PIVOT_RATIO = 1e-7
#: unit columns solved at a time for selected cofactors
COLUMN_CHUNK = 256


class IterativeSolverError(np.linalg.LinAlgError):
    """Conjugate gradients did not reach their tolerance within the iteration cap.

    ``iterations`` (int) run and ``error_estimate`` (float), the last estimated energy norm
    of the error (cofactor sigmas).
    """

    def __init__(self, message: str, iterations: int, error_estimate: float) -> None:
        super().__init__(message)
        self.iterations = iterations
        self.error_estimate = error_estimate


@dataclass
class SolverReport:
    """What solved the reduced system, for the adjustment report.

    ``method`` is ``"dense"``, ``"direct"`` or ``"iterative"``; ``statement`` a one-line
    description (e.g. ``"sparse LDL^T (SuperLU, MMD ordering), K=60000, nnz(L+U)=25903320,
    factored in 1.7 s"``); ``iterations`` and ``error_estimate`` (energy norm of the error
    in cofactor sigmas) the conjugate gradients' outcome of the last solve (0 and 0.0 for
    the factorisations); ``seconds`` the factorisation's or iterations' wall time.
    """

    method: str
    statement: str
    iterations: int = 0
    error_estimate: float = 0.0
    seconds: float = 0.0
    details: dict[str, Any] = field(default_factory=dict)


class Factorization(Protocol):
    report: SolverReport

    def solve(self, rhs: Float64Array) -> Float64Array:
        """``S^-1 rhs`` for (K,) or (K, n) ``rhs``."""


def _scale(diag: Float64Array) -> Float64Array:
    if np.any(~(diag > 0)):
        raise np.linalg.LinAlgError("a parameter has no observation")
    return 1.0 / np.sqrt(diag)


class _Dense:
    def __init__(self, reduced: Float64Array, use_numba: bool, serial_limit: int) -> None:
        import time

        t0 = time.perf_counter()
        k = reduced.shape[0]
        self.d = _scale(np.diag(reduced).copy())
        scaled = reduced * np.outer(self.d, self.d)
        self.low: Float64Array | None = None
        self.factor: Any = None
        if use_numba and k <= serial_limit:
            low = np.zeros(scaled.shape)
            if not _nb_cholesky(np.ascontiguousarray(scaled), low):
                raise np.linalg.LinAlgError("reduced system not positive definite")
            diag = np.diag(low)
            self.low = low
        else:
            try:
                self.factor = scipy.linalg.cho_factor(scaled, lower=True, overwrite_a=True,
                                                      check_finite=False)
            except scipy.linalg.LinAlgError as exc:
                raise np.linalg.LinAlgError(str(exc)) from None
            diag = np.diag(self.factor[0])
        if k and diag.min() < PIVOT_RATIO * diag.max():
            raise np.linalg.LinAlgError("ill-conditioned reduced system")
        self.report = SolverReport("dense", f"dense Cholesky, K={k}",
                                   seconds=time.perf_counter() - t0)

    def solve(self, rhs: Float64Array) -> Float64Array:
        d = self.d if rhs.ndim == 1 else self.d[:, None]
        y = np.ascontiguousarray(rhs * d, dtype=np.float64)
        if self.low is not None:
            if y.ndim == 1:
                _nb_cho_solve(self.low, y)
            else:
                for c in range(y.shape[1]):  # columns, few (cofactor chunks)
                    col = np.ascontiguousarray(y[:, c])
                    _nb_cho_solve(self.low, col)
                    y[:, c] = col
            return y * d
        return scipy.linalg.cho_solve(self.factor, y, check_finite=False) * d


_SUPERLU_OPTIONS = dict(SymmetricMode=True)


def _superlu(matrix: Any) -> Any:
    return scipy.sparse.linalg.splu(matrix, permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0,
                                    options=_SUPERLU_OPTIONS)


class _Direct:
    def __init__(self, reduced: Any) -> None:
        import time

        t0 = time.perf_counter()
        k = reduced.shape[0]
        self.d = _scale(np.asarray(reduced.diagonal(), dtype=np.float64))
        dm = scipy.sparse.diags(self.d)
        scaled = (dm @ reduced @ dm).tocsc()
        try:
            self.lu = _superlu(scaled)
        except RuntimeError as exc:  # "Factor is exactly singular"
            raise np.linalg.LinAlgError(f"singular reduced system ({exc})") from None
        del scaled
        # symmetric elimination (perm_r == perm_c, diagonal pivots): U's diagonal holds the
        # LDL^T pivots, all positive if and only if S is positive definite
        pivots = self.lu.U.diagonal()
        if not np.array_equal(self.lu.perm_r, self.lu.perm_c):
            raise np.linalg.LinAlgError("reduced system: SuperLU left the diagonal")
        if np.any(~(pivots > 0)):
            raise np.linalg.LinAlgError("reduced system not positive definite")
        if k and pivots.min() < PIVOT_RATIO ** 2 * pivots.max():
            raise np.linalg.LinAlgError("ill-conditioned reduced system")
        nnz = int(self.lu.nnz)
        seconds = time.perf_counter() - t0
        self.report = SolverReport(
            "direct", f"sparse LDL^T (SuperLU, MMD ordering), K={k}, nnz(S)={reduced.nnz}, "
            f"nnz(L+U)={nnz} ({16 * nnz / 2**20:.0f} MiB), factored in {seconds:.2f} s",
            seconds=seconds, details={"nnz_factor": nnz})

    def solve(self, rhs: Float64Array) -> Float64Array:
        d = self.d if rhs.ndim == 1 else self.d[:, None]
        scaled = np.asarray(rhs * d, dtype=np.float64)
        if scaled.ndim == 1:
            out = self.lu.solve(scaled) * d
        else:  # column by column: SuperLU's multi-column solve is 7 times slower (K=6000)
            out = np.empty_like(scaled)
            for c in range(scaled.shape[1]):  # columns, few (cofactor chunks)
                out[:, c] = self.lu.solve(np.ascontiguousarray(scaled[:, c]))
            out *= d
        if not np.all(np.isfinite(out)):
            raise np.linalg.LinAlgError("singular reduced system")
        return np.asarray(out)


def block_groups(n_params: int, gidx: IndexArray) -> IndexArray:
    """(G, B) the block-Jacobi blocks: each image's parameters (a row of ``gidx``), then
    every parameter no image owns (e.g. datum shifts) as a block of its own; -1 pads."""
    rows = np.asarray(gidx, dtype=np.intp).reshape(-1, gidx.shape[-1] if gidx.ndim else 1)
    rows = rows[np.any(rows >= 0, axis=1)]
    owned = np.zeros(n_params, bool)
    owned[rows[rows >= 0]] = True
    rest = np.flatnonzero(~owned)
    width = max(rows.shape[1] if rows.size else 1, 1)
    extra = np.full((rest.size, width), -1, np.intp)
    extra[:, 0] = rest
    return np.concatenate([rows, extra]) if rows.size else extra


class _PCG:
    def __init__(self, reduced: Any, groups: IndexArray, tolerance: float,
                 max_iterations: int) -> None:
        import time

        t0 = time.perf_counter()
        k = reduced.shape[0]
        self.d = _scale(np.asarray(reduced.diagonal(), dtype=np.float64))
        dm = scipy.sparse.diags(self.d)
        self.s = (dm @ reduced @ dm).tocsr()
        self.tolerance = tolerance
        self.max_iterations = max_iterations
        # block-Jacobi: the inverse of each group's diagonal block (padding: identity)
        self.groups = groups
        ok = groups >= 0
        g = np.maximum(groups, 0)
        rows = np.broadcast_to(g[:, :, None], (*g.shape, g.shape[1]))
        cols = np.broadcast_to(g[:, None, :], rows.shape)
        both = ok[:, :, None] & ok[:, None, :]
        blocks = np.zeros(rows.shape)
        blocks[both] = np.asarray(self.s[rows[both], cols[both]]).ravel()
        eye = np.eye(g.shape[1], dtype=bool)
        blocks[~both & eye] = 1.0
        try:
            np.linalg.cholesky(blocks)
        except np.linalg.LinAlgError:
            raise np.linalg.LinAlgError("reduced system: a parameter block is not positive "
                                        "definite") from None
        self.block_inv = np.linalg.inv(blocks)
        self.ok = ok
        self.report = SolverReport(
            "iterative", f"PCG block-Jacobi ({groups.shape[0]} blocks), K={k}, not yet run",
            seconds=time.perf_counter() - t0)

    def _precondition(self, r: Float64Array) -> Float64Array:
        """``M^-1 r`` for ``r`` (K, n): the blocks' inverses applied."""
        g = np.maximum(self.groups, 0)
        gathered = np.where(self.ok[:, :, None], r[g], 0.0)  # (G, B, n)
        z_blocks = np.matmul(self.block_inv, gathered)
        z = np.zeros_like(r)
        z[self.groups[self.ok]] = z_blocks[self.ok]
        return z

    def _solve_many(self, b: Float64Array) -> tuple[Float64Array, int, float]:
        """Independent conjugate gradient runs for the columns of ``b`` (K, n), side by side
        (one sparse product with the active columns per iteration); a column stops when its
        own error estimate meets the tolerance. Returns ``(x, iterations, worst
        estimate)``."""
        k, n = b.shape
        x = np.zeros_like(b)
        r = b.copy()
        z = self._precondition(r)
        p = z.copy()
        gamma = np.einsum("kn,kn->n", r, z)
        terms = np.zeros((self.max_iterations, n))
        estimate = np.full(n, math.inf)
        active = gamma > 0.0
        estimate[~active] = 0.0
        it = 0
        while active.any():
            if it == self.max_iterations:
                worst = float(estimate[active].max())
                raise IterativeSolverError(
                    f"conjugate gradients (block-Jacobi) did not converge in "
                    f"{self.max_iterations} iterations (estimated error {worst:.3g} sigma, "
                    f"tolerance {self.tolerance:.3g}); the block is too weakly tied for the "
                    "iterative solver: add tie points or a-priori sigmas, or raise "
                    "DIRECT_MEMORY_LIMIT", self.max_iterations, worst)
            cols = np.flatnonzero(active)
            pa = p[:, cols]
            q = np.asarray(self.s @ pa)
            curvature = np.einsum("kn,kn->n", pa, q)
            if not np.all(curvature > 0):
                raise np.linalg.LinAlgError("reduced system not positive definite "
                                            "(conjugate gradients)")
            alpha = gamma[cols] / curvature
            x[:, cols] += alpha * pa
            r[:, cols] -= alpha * q
            terms[it, cols] = alpha * gamma[cols]  # ||e_k||_S^2 - ||e_k+1||_S^2
            it += 1
            z_a = self._precondition(r[:, cols])
            gamma_new = np.einsum("kn,kn->n", r[:, cols], z_a)
            if it >= PCG_DELAY:
                window = terms[it - PCG_DELAY: it, cols]
                total = window.sum(axis=0)
                with np.errstate(divide="ignore", invalid="ignore"):
                    ratio = np.where(window[0] > 0, window[-1] / window[0], 0.0) \
                        ** (1.0 / (PCG_DELAY - 1))
                    rho = ratio ** PCG_DELAY
                    est = np.where(rho < 0.99, np.sqrt(total * rho / (1.0 - rho)), math.inf)
                estimate[cols] = est
                length = np.sqrt(np.maximum(np.einsum("kn,kn->n", x[:, cols], b[:, cols]),
                                            0.0))  # ||x||_S: x^T S x ~ x^T b
                done = est <= np.maximum(self.tolerance, PCG_RELATIVE_FLOOR * length)
            else:
                done = np.zeros(cols.size, bool)
            done |= gamma_new == 0.0
            estimate[cols[gamma_new == 0.0]] = 0.0
            beta = np.where(gamma[cols] > 0, gamma_new / np.where(gamma[cols] > 0,
                                                                  gamma[cols], 1.0), 0.0)
            p[:, cols] = z_a + beta * pa
            gamma[cols] = gamma_new
            active[cols[done]] = False
        return x, it, float(estimate.max(initial=0.0))

    def solve(self, rhs: Float64Array) -> Float64Array:
        import time

        t0 = time.perf_counter()
        b = np.asarray(rhs, dtype=np.float64)
        cols = b.reshape(b.shape[0], -1) * self.d[:, None]
        out, iterations, worst = self._solve_many(cols)
        out *= self.d[:, None]
        seconds = time.perf_counter() - t0
        k = b.shape[0]
        what = "" if b.ndim == 1 else f" ({cols.shape[1]} right-hand sides)"
        self.report = SolverReport(
            "iterative", f"PCG block-Jacobi ({self.groups.shape[0]} blocks), K={k}{what}, "
            f"{iterations} iterations, estimated error {worst:.1e} sigma "
            f"(tolerance {self.tolerance:.0e}), {seconds:.2f} s",
            iterations=iterations, error_estimate=worst, seconds=seconds)
        return out.reshape(b.shape)


def estimate_factor_bytes(reduced: Any, groups: IndexArray) -> int:
    """Estimated bytes of the sparse direct factor of ``reduced`` (16 per nonzero of L + U).

    The group graph (one node per row of ``groups``, e.g. per image; an edge where ``S``
    couples two groups) is factored by SuperLU with the ordering of the direct solver, and
    each of its factor's nonzeros counts ``(K / groups)^2`` nonzeros of the real factor.
    """
    k = reduced.shape[0]
    if k == 0:
        return 0
    label = np.full(k, -1, np.intp)
    ok = groups >= 0
    label[groups[ok]] = np.nonzero(ok)[0]
    n = groups.shape[0]
    coo = reduced.tocoo()
    a, b = label[coo.row], label[coo.col]
    keep = (a >= 0) & (b >= 0) & (a != b)
    key = np.unique(a[keep] * n + b[keep])
    a, b = key // n, key % n
    degree = np.bincount(a, minlength=n).astype(np.float64)
    graph = scipy.sparse.csc_matrix(
        (np.concatenate([-np.ones(a.size), degree + 1.0]),
         (np.concatenate([a, np.arange(n)]), np.concatenate([b, np.arange(n)]))), shape=(n, n))
    nnz_graph = int(_superlu(graph).nnz)
    return int(16 * nnz_graph * (k / n) ** 2)


def choose_method(solver: str, reduced: Any, groups: IndexArray, dense_limit: int,
                  memory_limit: int) -> tuple[str, int | None]:
    """The method for ``solver`` (``"auto"`` or a method), and the estimated factor bytes
    (None when not estimated)."""
    if solver == "dense":
        return "dense", None
    if solver in ("direct", "iterative"):
        return solver, None
    if solver != "auto":
        raise ValueError(f"NormalSystem: unknown solver {solver!r} "
                         "(auto, dense, direct, iterative)")
    if not scipy.sparse.issparse(reduced):
        return "dense", None
    estimate = estimate_factor_bytes(reduced, groups)
    return ("direct" if estimate <= memory_limit else "iterative"), estimate


def factorize(method: str, reduced: Any, *, groups: IndexArray, use_numba: bool,
              serial_limit: int, tolerance: float = PCG_TOLERANCE,
              max_iterations: int = PCG_MAX_ITERATIONS) -> Factorization:
    """The factorisation (or preconditioned iteration) of ``reduced`` by ``method``."""
    if method == "dense":
        dense = reduced.toarray() if scipy.sparse.issparse(reduced) else reduced
        return _Dense(np.asarray(dense, dtype=np.float64), use_numba, serial_limit)
    sparse = reduced if scipy.sparse.issparse(reduced) else scipy.sparse.csc_matrix(reduced)
    if method == "direct":
        return _Direct(sparse)
    if method == "iterative":
        return _PCG(sparse, groups, tolerance, max_iterations)
    raise ValueError(f"unknown solver method {method!r}")
