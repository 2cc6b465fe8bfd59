"""The reduced system's solvers (geoblock.adjust._solvers) and selected cofactors (issue 29).

Dense Cholesky, sparse direct (SuperLU) and block-Jacobi conjugate gradients solve the same
systems to 1e-6 of a posterior sigma on every parameter and point (the must-show of issue
29, held here 100 times tighter), on random systems, on strip-structured ones and on a
real small block of affine cameras; a sparse prior gives what a dense one does; the selected
cofactor blocks are the dense inverse's; conjugate gradients that do not converge raise.
"""

from __future__ import annotations

import dataclasses
import tracemalloc

import numpy as np
import pytest
import scipy.sparse
from tests.adjust.test_normal import _brute_force, _problem

import geoblock.adjust._solvers as solvers
import geoblock.adjust.normal as normal
from geoblock.adjust.normal import (
    IterativeSolverError,
    NormalSystem,
    SelectedCofactor,
    measurement_pairs,
)

#: the must-show's agreement (sigmas); the solvers are held to 1e-2 of it
AGREEMENT_SIGMA = 1e-6


@pytest.fixture(params=[True, False], ids=["numba", "numpy"])
def kernels(request, monkeypatch):
    monkeypatch.setattr(normal, "USE_NUMBA", request.param)
    return request.param


def strip_problem(strips: int = 4, scenes: int = 6, kb: int = 6, points_per_image: int = 30,
                  seed: int = 0, prior: float = 1e-2) -> dict:
    """A block of ``strips x scenes`` images of ``kb`` parameters, each point seen by 2 to 4
    of the images around one image corner (so every image overlaps its 8 neighbours), the
    parameters weakly held by a block diagonal prior (sparse), the points by nothing else."""
    rng = np.random.default_rng(seed)
    n_images = strips * scenes
    k = n_images * kb
    gidx = np.arange(k, dtype=np.intp).reshape(n_images, kb)
    n_points = points_per_image * n_images
    s0 = rng.integers(0, strips - 1, n_points)
    c0 = rng.integers(0, scenes - 1, n_points)
    corner = np.stack([(s0 + ds) * scenes + c0 + dc for ds in (0, 1) for dc in (0, 1)], 1)
    seen = rng.random((n_points, 4)) < 0.7
    first = rng.integers(0, 4, n_points)  # at least two
    seen[np.arange(n_points), first] = True
    seen[np.arange(n_points), (first + rng.integers(1, 4, n_points)) % 4] = True
    point_of = np.repeat(np.arange(n_points), 4)[seen.ravel()]
    image_of = corner.ravel()[seen.ravel()]
    m = image_of.size
    a = rng.normal(size=(m, 2, kb))
    b = rng.normal(size=(m, 2, 3)) + np.array([[1.0, 0, 0.3], [0, 1.0, 0.2]])
    v = rng.normal(size=(m, 2))
    blocks = rng.normal(size=(n_images, kb, kb))
    blocks = prior * (blocks @ np.swapaxes(blocks, 1, 2) / kb + np.eye(kb))
    prior_w = scipy.sparse.block_diag(list(blocks), format="csr")
    return dict(n_params=k, gidx=gidx, image_of=image_of, point_of=point_of, a=a, b=b, v=v,
                n_pp_prior=prior_w, b_p_prior=rng.normal(size=k),
                n_xx_extra=np.zeros((n_points, 3, 3)), b_x_extra=np.zeros((n_points, 3)),
                pairs=measurement_pairs(point_of, n_points))


def _sigmas(p: dict) -> tuple[np.ndarray, np.ndarray]:
    """Posterior cofactor sigmas of the parameters (K,) and points (J, 3), from the dense
    inverse of the reduced system."""
    system = NormalSystem(**{**p, "solver": "direct"})
    system.solve(0.0)
    q = np.linalg.inv(system.reduced.toarray())
    q_xx, _ = system.point_cofactors(q)
    return np.sqrt(np.diag(q)), np.sqrt(np.einsum("jii->ji", q_xx))


def _steps(p: dict, solver: str, damping: float = 0.0):
    system = NormalSystem(**{**p, "solver": solver})
    dp, dx = system.solve(damping)
    assert system.solver_used == solver
    return dp, dx, system


def _assert_agree(p: dict, damping: float = 0.0, solvers_=("dense", "direct", "iterative"),
                  limit: float = 1e-2 * AGREEMENT_SIGMA) -> dict:
    sig_p, sig_x = _sigmas(p)
    out = {s: _steps(p, s, damping) for s in solvers_}
    ref = out[solvers_[0]]
    for s in solvers_[1:]:
        assert np.max(np.abs(out[s][0] - ref[0]) / sig_p) < limit, s
        assert np.max(np.abs(out[s][1] - ref[1]) / sig_x) < limit, s
    return out


@pytest.mark.parametrize("damping", [0.0, 0.3])
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_dense_direct_iterative_agree_random(kernels, seed, damping):
    p = _problem(seed)
    out = _assert_agree(p, damping)
    dp_ref, dx_ref, _ = _brute_force(p, damping)
    scale = max(np.abs(dp_ref).max(), np.abs(dx_ref).max())
    for dp, dx, _ in out.values():
        assert np.abs(dp - dp_ref).max() <= 1e-8 * scale
        assert np.abs(dx - dx_ref).max() <= 1e-8 * scale


def test_dense_direct_iterative_agree_strips(kernels):
    p = strip_problem(5, 8, seed=3)
    out = _assert_agree(p, 0.0)
    report = out["iterative"][2].solver_report
    assert report.method == "iterative" and report.iterations > 1
    assert report.error_estimate < solvers.PCG_TOLERANCE
    assert "PCG block-Jacobi" in report.statement and "iterations" in report.statement
    assert "SuperLU" in out["direct"][2].solver_statement
    assert "dense Cholesky" in out["dense"][2].solver_statement


def test_real_affine_block_agree():
    """A real small block (6 affine cameras, GCPs, TPs, a DEM), linearised at its a-priori
    parameters, where the steps are many sigmas long: the three solvers' steps agree."""
    from geoblock.adjust._engine import _Engine
    from geoblock.testing.blocks import affine_block

    block = affine_block((2, 3), tps=150, seed=4).block
    engine = _Engine(block, block.image_ids, use_tps=True, dem_control="soft",
                     tp_sigma_factor=3.0, tp_sigma_m=None, tp_prior="floating", notes=[])
    s = engine.s
    ev = engine.evaluate(s.prior_x, s.x0)
    system = engine.linearize(s.prior_x, s.x0, ev)
    p = {f.name: getattr(system, f.name) for f in dataclasses.fields(system)}
    p["n_pp_prior"] = scipy.sparse.csr_matrix(p["n_pp_prior"])
    out = _assert_agree(p, 0.0)
    sig_p, _ = _sigmas(p)
    assert np.max(np.abs(out["dense"][0]) / sig_p) > 10  # long steps: a real test


def test_sparse_prior_equals_dense_prior(kernels):
    p = _problem(6)
    dense = NormalSystem(**p).solve(0.2)
    sparse = NormalSystem(**{**p, "n_pp_prior": scipy.sparse.csr_matrix(p["n_pp_prior"])}
                          ).solve(0.2)
    for x, y in zip(dense, sparse, strict=True):
        assert np.array_equal(x, y)
    for solver in ("direct", "iterative"):
        got = NormalSystem(**{**p, "n_pp_prior": scipy.sparse.csr_matrix(p["n_pp_prior"]),
                              "solver": solver}).solve(0.2)
        ref = NormalSystem(**{**p, "solver": solver}).solve(0.2)
        for x, y in zip(ref, got, strict=True):
            assert np.abs(x - y).max() <= 1e-12 * np.abs(x).max()


def test_sparse_npp_equals_dense(kernels, monkeypatch):
    p = strip_problem(3, 4, seed=1)
    dense = NormalSystem(**{**p, "solver": "dense"})
    monkeypatch.setattr(normal, "SPARSE_CHUNK_TRIPLETS", 100)  # several runs
    sparse = NormalSystem(**{**p, "solver": "direct"})
    assert scipy.sparse.issparse(sparse.n_pp) and not scipy.sparse.issparse(dense.n_pp)
    assert np.allclose(sparse.n_pp.toarray(), dense.n_pp, rtol=0, atol=1e-12)
    assert np.allclose(sparse.n_pp_diagonal, np.diag(dense.n_pp), rtol=1e-14, atol=0)
    assert np.allclose(dense.n_pp_diagonal, np.diag(dense.n_pp), rtol=1e-14, atol=0)


def test_auto_choice(monkeypatch):
    p = strip_problem(3, 4, seed=2)
    system = NormalSystem(**p)
    system.solve(0.0)
    assert system.solver_used == "dense" and isinstance(system.reduced, np.ndarray)
    monkeypatch.setattr(normal, "DENSE_LIMIT", 10)
    system = NormalSystem(**p)
    dp, _ = system.solve(0.0)
    assert system.solver_used == "direct" and scipy.sparse.issparse(system.reduced)
    assert "auto: estimated factor" in system.solver_statement
    # the estimate is of the right size: within a factor of 3 of the real factor
    real = 16 * system.solver_report.details["nnz_factor"]
    assert real / 3 < system.solver_report.details["factor_estimate_bytes"] < 3 * real
    monkeypatch.setattr(normal, "DIRECT_MEMORY_LIMIT", 1000)
    system = NormalSystem(**p)
    dp_it, _ = system.solve(0.0)
    assert system.solver_used == "iterative"
    assert "PCG" in system.solver_statement
    with pytest.raises(ValueError, match="DENSE_LIMIT"):
        NormalSystem(**{**p, "solver": "dense"})
    with pytest.raises(ValueError, match="unknown solver"):
        NormalSystem(**{**p, "solver": "cholmod"})


def test_pcg_not_converged_raises(monkeypatch):
    p = strip_problem(4, 6, seed=5, prior=1e-6)  # weakly held: many iterations needed
    monkeypatch.setattr(solvers, "PCG_MAX_ITERATIONS", 5)
    system = NormalSystem(**{**p, "solver": "iterative"})
    with pytest.raises(IterativeSolverError, match="did not converge in 5") as info:
        system.solve(0.0)
    assert isinstance(info.value, np.linalg.LinAlgError)
    assert info.value.iterations == 5 and info.value.error_estimate > solvers.PCG_TOLERANCE


@pytest.mark.parametrize("solver", ["direct", "iterative"])
def test_singular_reduced_system_raises(solver):
    p = _problem(7)
    p["n_pp_prior"] = np.zeros_like(p["n_pp_prior"])
    p["a"][p["image_of"] == 2] = 0.0  # image 2's parameters observed by nothing
    with pytest.raises(np.linalg.LinAlgError):
        NormalSystem(**{**p, "solver": solver}).solve(0.0)


@pytest.mark.parametrize("solver", ["dense", "direct", "iterative"])
def test_selected_cofactor_equals_dense_inverse(kernels, solver):
    p = _problem(3, n_images=4, n_points=40)
    system = NormalSystem(**{**p, "solver": solver})
    system.solve(0.0)
    _, _, q = _brute_force(p)
    k = p["n_params"]
    tol = 1e-9 * np.abs(q).max()
    cols = system.cofactor_columns(images=[0, 3])
    assert cols.tolist() == sorted(set(p["gidx"][[0, 3]].ravel()) - {-1})
    sel = system.parameter_cofactor(cols)
    assert isinstance(sel, SelectedCofactor)
    assert np.allclose(sel.q, q[np.ix_(cols, cols)], rtol=0, atol=tol)
    assert np.allclose(sel.block(cols[:3], cols[-2:]), q[np.ix_(cols[:3], cols[-2:])],
                       rtol=0, atol=tol)
    other = np.setdiff1d(np.arange(k), cols)[:2]
    assert np.all(np.isnan(sel.block(other, cols[:2])))
    assert np.all(sel.block(np.array([-1]), cols) == 0.0)
    assert np.array_equal(np.isnan(sel.diagonal()), ~np.isin(np.arange(k), cols))
    # points whose every image is held: Q_xx, Q_px and the hat blocks as the dense ones
    q_xx_d, q_px_d = system.point_cofactors(q[:k, :k])
    hat_d = system.hat_blocks(q[:k, :k], q_xx_d, q_px_d)
    q_xx, q_px = system.point_cofactors(sel)
    hat = system.hat_blocks(sel, q_xx, q_px)
    held_m = np.isin(p["image_of"], [0, 3])
    held_j = np.ones(p["n_xx_extra"].shape[0], bool)
    np.logical_and.at(held_j, p["point_of"], held_m)
    assert held_j.any() and (~held_j).any()
    assert np.allclose(q_xx[held_j], q_xx_d[held_j], rtol=0, atol=tol)
    assert np.all(np.isnan(q_xx[~held_j]))
    mj = held_j[p["point_of"]]
    assert np.allclose(q_px[mj], q_px_d[mj], rtol=0, atol=tol)
    assert np.all(np.isnan(q_px[~mj]))
    assert np.allclose(hat[mj], hat_d[mj], rtol=0, atol=tol)
    assert np.all(np.isnan(hat[~held_m]))
    # all columns: the full inverse
    full = system.parameter_cofactor(np.arange(k))
    assert np.allclose(full.q, q[:k, :k], rtol=0, atol=tol)
    # the columns the points need: every image that sees them
    j = np.flatnonzero(held_j)[:3]
    need = system.cofactor_columns(points=j)
    imgs = np.unique(p["image_of"][np.isin(p["point_of"], j)])
    assert need.tolist() == sorted(set(p["gidx"][imgs].ravel()) - {-1})


def test_selected_cofactor_kernels_agree(monkeypatch):
    p = _problem(5, n_images=5, n_points=60, sizes=(6, 6, 6, 3, 6))
    out = {}
    for flag in (False, True):
        monkeypatch.setattr(normal, "USE_NUMBA", flag)
        system = NormalSystem(**{**p, "solver": "direct"})
        system.solve(0.0)
        sel = system.parameter_cofactor(system.cofactor_columns(images=[1, 2, 4]))
        q_xx, q_px = system.point_cofactors(sel)
        out[flag] = (sel.q, q_xx, q_px, system.hat_blocks(sel, q_xx, q_px))
    for a, b in zip(out[False], out[True], strict=True):
        assert np.array_equal(np.isnan(a), np.isnan(b))
        ok = ~np.isnan(a)
        assert np.abs(a[ok] - b[ok]).max() <= 1e-10 * np.abs(a[ok]).max()


def test_full_cofactor_refused_above_limit(monkeypatch):
    p = _problem(1)
    system = NormalSystem(**p)
    system.solve(0.0)
    monkeypatch.setattr(normal, "DENSE_COFACTOR_LIMIT", 5)
    with pytest.raises(ValueError, match="cofactor_columns"):
        system.parameter_cofactor()
    assert system.parameter_cofactor(np.arange(3)).q.shape == (3, 3)


def test_inverse_diagonal(kernels):
    p = _problem(2)
    for solver in ("dense", "direct"):
        system = NormalSystem(**{**p, "solver": solver})
        system.solve(0.0)
        reduced = system.reduced
        dense = reduced.toarray() if scipy.sparse.issparse(reduced) else reduced
        assert np.allclose(system.inverse_diagonal(), 1.0 / np.diag(dense), rtol=1e-14)
        # a lower bound of the cofactor variances
        assert np.all(system.inverse_diagonal() <= np.diag(np.linalg.inv(dense)) * (1 + 1e-12))


def test_no_dense_k_by_k_above_dense_limit(monkeypatch):
    """K = 12000 (2000 images): accumulated, reduced, factored and solved, with columns of
    cofactors, and numpy never holds more than 15 % of one (K, K) array (1.15 GB); the
    triplet buffers held to 2^18 (6 MB each)."""
    monkeypatch.setattr(normal, "SPARSE_CHUNK_TRIPLETS", 1 << 18)
    p = strip_problem(40, 50, points_per_image=12, seed=8)
    k = p["n_params"]
    assert k > normal.DENSE_LIMIT
    tracemalloc.start()
    try:
        for solver in ("auto", "iterative"):
            system = NormalSystem(**{**p, "solver": solver})
            system.solve(0.1)
            system.solve(0.0)
            sel = system.parameter_cofactor(system.cofactor_columns(images=[0, 1, 77]))
            q_xx, q_px = system.point_cofactors(sel)
            system.hat_blocks(sel, q_xx, q_px)
            system.inverse_diagonal()
            assert system.solver_used == ("direct" if solver == "auto" else solver)
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert peak < 0.15 * k * k * 8


def _cross_group_problem(seed: int = 9) -> dict:
    """:func:`_problem` with two parameters no image owns (datum shifts) and measurements
    whose columns span an image's parameters, another image's and a shift (as the engine's
    pseudo-measurements do), in compressed columns."""
    p = _problem(seed, n_images=4, n_points=40)
    rng = np.random.default_rng(seed)
    k = p["n_params"] + 2
    cols = p["gidx"][p["image_of"]].copy()
    m = cols.shape[0]
    extra = np.full((m, 2), -1, np.intp)
    a_extra = np.zeros((m, 2, 2))
    some = rng.random(m) < 0.3
    other = p["gidx"][(p["image_of"] + 1) % 4, 0]
    extra[some, 0] = other[some]
    extra[some, 1] = k - 2 + rng.integers(0, 2, some.sum())
    a_extra[some] = rng.normal(size=(some.sum(), 2, 2))
    prior = np.zeros((k, k))
    prior[:-2, :-2] = p["n_pp_prior"]
    prior[-2:, -2:] = [[0.3, 0.1], [0.1, 0.2]]
    return {**p, "n_params": k, "cols": np.concatenate([cols, extra], axis=1),
            "a": np.concatenate([p["a"], a_extra], axis=2), "n_pp_prior": prior,
            "b_p_prior": np.concatenate([p["b_p_prior"], [0.4, -0.2]])}


@pytest.mark.parametrize("damping", [0.0, 0.2])
def test_csr_assembly_equals_triplets_and_dense(monkeypatch, damping):
    p = _cross_group_problem()
    monkeypatch.setattr(normal, "USE_NUMBA", False)
    ref = NormalSystem(**{**p, "solver": "dense"})
    dp_ref, dx_ref = ref.solve(damping)
    got = {}
    monkeypatch.setattr(normal, "SPARSE_CHUNK_TRIPLETS", 300)  # the triplets in many runs
    for numba in (True, False):
        for csr in (True, False):
            monkeypatch.setattr(normal, "USE_NUMBA", numba)
            monkeypatch.setattr(normal, "CSR_ASSEMBLY", csr)
            system = NormalSystem(**{**p, "solver": "direct"})
            dp, dx = system.solve(damping)
            assert scipy.sparse.issparse(system.reduced)
            assert (system._pattern is not None) == (numba and csr)
            scale = np.abs(ref.reduced).max()
            assert np.abs(system.reduced.toarray() - ref.reduced).max() <= 1e-12 * scale
            assert np.allclose(system.n_pp.toarray(), ref.n_pp, rtol=0, atol=1e-12 * scale)
            assert np.abs(dp - dp_ref).max() <= 1e-9 * np.abs(dp_ref).max()
            assert np.abs(dx - dx_ref).max() <= 1e-9 * np.abs(dx_ref).max()
            got[numba, csr] = dp
    # the pattern: exactly the blocks of the groups a point or the prior links
    monkeypatch.setattr(normal, "USE_NUMBA", True)
    monkeypatch.setattr(normal, "CSR_ASSEMBLY", True)
    system = NormalSystem(**{**p, "solver": "direct"})
    system.solve(damping)
    structural = np.zeros(system.reduced.shape, bool)
    structural[system.reduced.nonzero()] = True
    assert np.all(structural[np.abs(ref.reduced) > 0])


def test_cached_pattern_rebuilt_when_columns_leave_it():
    """The CSR pattern kept in ``pairs.cache`` for the next linearisation is rebuilt when a
    measurement's columns fall outside it, in N_pp (a measurement spanning two images) or
    only in the Schur complement (a point newly linking two images)."""
    rng = np.random.default_rng(11)
    gidx = np.arange(18, dtype=np.intp).reshape(3, 6)
    # points 0-5 seen by images 0 and 1, points 6-11 by 1 and 2 (no point links 0 and 2)
    image_of = np.array([0, 1] * 6 + [1, 2] * 6, np.intp)
    point_of = np.repeat(np.arange(12), 2)
    m = image_of.size
    p = dict(n_params=18, gidx=gidx, image_of=image_of, point_of=point_of,
             a=rng.normal(size=(m, 2, 6)), b=rng.normal(size=(m, 2, 3)),
             v=rng.normal(size=(m, 2)), n_pp_prior=0.1 * np.eye(18),
             b_p_prior=rng.normal(size=18), n_xx_extra=0.1 * np.tile(np.eye(3), (12, 1, 1)),
             b_x_extra=np.zeros((12, 3)), pairs=measurement_pairs(point_of, 12),
             solver="direct")
    first = NormalSystem(**p)
    first.solve(0.0)
    assert len(p["pairs"].cache) == 1
    links = first.reduced.toarray()[np.ix_(gidx[0], gidx[2])]
    assert not np.any(links)
    # point 0's second measurement now in image 2: a 0-2 link the cached pattern lacks
    cols = gidx[image_of].copy()
    cols[1] = gidx[2]
    for extra in (False, True):
        q = {**p, "cols": cols}
        if extra:  # and a measurement spanning images 0 and 2 (seen in N_pp already)
            c2 = np.concatenate([cols, np.full((m, 1), -1, np.intp)], axis=1)
            c2[0, 6] = gidx[2, 0]
            a2 = np.concatenate([p["a"], np.zeros((m, 2, 1))], axis=2)
            a2[0, :, 6] = [0.3, -0.2]
            q = {**q, "cols": c2, "a": a2}
        p["pairs"].cache.clear()
        NormalSystem(**p).solve(0.0)  # the cache holds the 0-1, 1-2 pattern again
        got = NormalSystem(**q).solve(0.1)
        fresh = NormalSystem(**{**q, "pairs": measurement_pairs(point_of, 12)}).solve(0.1)
        dense = NormalSystem(**{**q, "solver": "dense"}).solve(0.1)
        for x, y, z in zip(got, fresh, dense, strict=True):
            assert np.array_equal(x, y)
            assert np.abs(x - z).max() <= 1e-10 * np.abs(z).max()
