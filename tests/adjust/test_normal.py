"""The Schur-reduced normal equations (geoblock.adjust.normal) against brute force."""

from __future__ import annotations

import numpy as np
import pytest

import geoblock.adjust.normal as normal
from geoblock.adjust.normal import NormalSystem, SingularPoints, _inv3, measurement_pairs


def _problem(seed: int = 0, n_images: int = 4, n_points: int = 25, sizes=(6, 6, 3, 6)):
    """A random well-posed system: images with K_i parameters (padded to Kmax), points seen
    by 1-4 images (some twice by one image), priors on the parameters, ground weights."""
    rng = np.random.default_rng(seed)
    kmax = max(sizes)
    gidx = np.full((n_images, kmax), -1, np.intp)
    o = 0
    for i, s in enumerate(sizes[:n_images]):
        gidx[i, :s] = o + np.arange(s)
        o += s
    k = o
    image_of, point_of = [], []
    for j in range(n_points):
        n = rng.integers(1, 5)
        imgs = rng.choice(n_images, size=n, replace=True)
        image_of.extend(imgs.tolist())
        point_of.extend([j] * n)
    image_of = np.array(image_of, np.intp)
    point_of = np.array(point_of, np.intp)
    perm = rng.permutation(image_of.size)  # measurements not grouped by point
    image_of, point_of = image_of[perm], point_of[perm]
    m = image_of.size
    a = rng.normal(size=(m, 2, kmax))
    a[(gidx[image_of] < 0)[:, None, :].repeat(2, 1)] = 0.0
    b = rng.normal(size=(m, 2, 3))
    v = rng.normal(size=(m, 2))
    x = rng.normal(size=(k, k))
    n_pp_prior = 0.1 * (x @ x.T) / k + 0.05 * np.eye(k)
    b_p_prior = rng.normal(size=k)
    y = rng.normal(size=(n_points, 3, 3))
    n_xx_extra = 0.2 * y @ np.swapaxes(y, 1, 2) + 0.1 * np.eye(3)
    b_x_extra = rng.normal(size=(n_points, 3))
    return dict(n_params=k, gidx=gidx, image_of=image_of, point_of=point_of, a=a, b=b, v=v,
                n_pp_prior=n_pp_prior, b_p_prior=b_p_prior, n_xx_extra=n_xx_extra,
                b_x_extra=b_x_extra, pairs=measurement_pairs(point_of, n_points))


def _brute_force(p, damping=0.0):
    """Dense full normal equations (parameters then points), solved directly."""
    k, j = p["n_params"], p["n_xx_extra"].shape[0]
    n = k + 3 * j
    jac = np.zeros((2 * p["a"].shape[0], n))
    for m in range(p["a"].shape[0]):
        g = p["gidx"][p["image_of"][m]]
        ok = g >= 0
        jac[2 * m: 2 * m + 2, g[ok]] = p["a"][m][:, ok]
        c = k + 3 * p["point_of"][m]
        jac[2 * m: 2 * m + 2, c: c + 3] = p["b"][m]
    big = jac.T @ jac
    rhs = jac.T @ p["v"].ravel()
    big[:k, :k] += p["n_pp_prior"]
    rhs[:k] += p["b_p_prior"]
    for jj in range(j):
        sl = slice(k + 3 * jj, k + 3 * jj + 3)
        big[sl, sl] += p["n_xx_extra"][jj]
        rhs[sl] += p["b_x_extra"][jj]
    big += damping * np.diag(np.diag(big))
    sol = np.linalg.solve(big, rhs)
    return sol[:k], sol[k:].reshape(j, 3), np.linalg.inv(big)


@pytest.fixture(params=[True, False], ids=["numba", "numpy"])
def kernels(request, monkeypatch):
    monkeypatch.setattr(normal, "USE_NUMBA", request.param)
    return request.param


@pytest.mark.parametrize("damping", [0.0, 0.3])
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_schur_equals_brute_force(kernels, seed, damping):
    p = _problem(seed)
    dp, dx = NormalSystem(**p).solve(damping)
    dp_ref, dx_ref, _ = _brute_force(p, damping)
    scale = max(np.abs(dp_ref).max(), np.abs(dx_ref).max())
    assert np.abs(dp - dp_ref).max() <= 1e-9 * scale
    assert np.abs(dx - dx_ref).max() <= 1e-9 * scale


def test_cofactors_equal_brute_force(kernels):
    p = _problem(3)
    system = NormalSystem(**p)
    system.solve(0.0)
    _, _, q = _brute_force(p)
    k = p["n_params"]
    q_pp = system.parameter_cofactor()
    q_xx, q_px = system.point_cofactors(q_pp)
    assert np.allclose(q_pp, q[:k, :k], rtol=0, atol=1e-9 * np.abs(q).max())
    j = p["n_xx_extra"].shape[0]
    blocks = np.array([q[k + 3 * i: k + 3 * i + 3, k + 3 * i: k + 3 * i + 3] for i in range(j)])
    assert np.allclose(q_xx, blocks, rtol=0, atol=1e-9 * np.abs(q).max())
    for m in range(p["a"].shape[0]):
        g = p["gidx"][p["image_of"][m]]
        ok = g >= 0
        c = k + 3 * p["point_of"][m]
        assert np.allclose(q_px[m][ok], q[g[ok], c: c + 3], rtol=0, atol=1e-9 * np.abs(q).max())
        assert np.all(q_px[m][~ok] == 0)


def test_dense_and_sparse_paths_agree(kernels, monkeypatch):
    p = _problem(4)
    dense = NormalSystem(**p).solve(0.1)
    monkeypatch.setattr(normal, "DENSE_LIMIT", 0)
    system = NormalSystem(**p)
    sparse = system.solve(0.1)
    import scipy.sparse

    assert scipy.sparse.issparse(system.reduced)
    for a, b in zip(dense, sparse, strict=True):
        assert np.abs(a - b).max() <= 1e-10 * np.abs(a).max()
    q_sparse = system.parameter_cofactor()
    monkeypatch.setattr(normal, "DENSE_LIMIT", 4000)
    system = NormalSystem(**p)
    system.solve(0.1)
    assert np.allclose(q_sparse, system.parameter_cofactor(), rtol=1e-10, atol=1e-12)


def test_numba_and_numpy_agree(monkeypatch):
    p = _problem(5, n_images=5, n_points=60, sizes=(6, 6, 6, 3, 6))
    out = {}
    for flag in (False, True):
        monkeypatch.setattr(normal, "USE_NUMBA", flag)
        system = NormalSystem(**p)
        dp, dx = system.solve(0.0)
        q_pp = system.parameter_cofactor()
        q_xx, q_px = system.point_cofactors(q_pp)
        out[flag] = (system.n_pp, system.b_p, system.n_xx, system.b_x, system.n_px,
                     np.asarray(system.reduced), dp, dx, q_pp, q_xx, q_px,
                     system.hat_blocks(q_pp, q_xx, q_px))
    for a, b in zip(out[False], out[True], strict=True):
        assert np.abs(a - b).max() <= 1e-10 * max(np.abs(a).max(), 1e-300)


def test_measurement_pairs():
    point_of = np.array([2, 0, 2, 1, 2, 0])
    pairs = measurement_pairs(point_of, 4)
    got = sorted(zip(pairs.a.tolist(), pairs.b.tolist(), strict=True))
    want = sorted((a, b) for a in range(6) for b in range(6) if point_of[a] == point_of[b])
    assert got == want
    assert np.array_equal(pairs.point, point_of[pairs.a])
    # by-point grouping: stable order, CSR starts (point 3 has none)
    assert pairs.order.tolist() == [1, 5, 3, 0, 2, 4]
    assert pairs.start.tolist() == [0, 2, 3, 6, 6]


def test_inv3_numba_matches_and_flags_singular():
    rng = np.random.default_rng(7)
    y = rng.normal(size=(50, 3, 3))
    m = y @ np.swapaxes(y, 1, 2) + 1e-3 * np.eye(3)
    assert np.allclose(_inv3(m, numba=True), _inv3(m), rtol=1e-10, atol=0)
    m[[3, 17]] = np.outer([1.0, 2.0, 3.0], [1.0, 2.0, 3.0])  # rank 1
    m[20, 1, 1] = 0.0
    m[20, 0, 1] = m[20, 1, 0] = m[20, 1, 2] = m[20, 2, 1] = 0.0
    for flag in (False, True):
        with pytest.raises(SingularPoints) as info:
            _inv3(m, numba=flag)
        assert info.value.points.tolist() == [3, 17, 20]
