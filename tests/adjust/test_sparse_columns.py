"""Parameters that act locally keep the block's normal equations sparse (issue 27).

A measurement's design-matrix row touches only the parameters whose partials are nonzero
there: a spline in time touches four knots per axis. The engine compresses each row to those
columns (geoblock.adjust.normal.compress_columns) and accumulates with per-measurement column
indices; these tests hold that to the dense per-image layout, on random systems and on whole
adjustments of a test model whose corrections are cubic B-splines along the image rows.
"""

from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np
import pytest
import scipy.sparse

import geoblock.adjust._engine as engine
import geoblock.adjust.normal as normal
from geoblock.adjust import Block, adjust
from geoblock.adjust.normal import NormalSystem, compress_columns, measurement_pairs
from geoblock.testing.blocks import affine_block


def _load_row_spline():
    """tests/adjust/row_spline_model.py (shared with benchmarks/bench_jitter.py)."""
    path = Path(__file__).with_name("row_spline_model.py")
    spec = importlib.util.spec_from_file_location("row_spline_model", path)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module.RowSplineCorrection


RowSplineCorrection = _load_row_spline()


def _spline_block(spacing: float = 100.0, tps: int = 400, seed: int = 5) -> Block:
    sb = affine_block((1, 3), tps=tps, gcps=8, icps=6, seed=seed)
    models = {i: RowSplineCorrection(m.model, spacing) for i, m in sb.block.models.items()}
    b = sb.block
    return Block(models, b.measurements, b.ground, b.dem, b.dem_sigma_m)


# ================================================================================ compression
def test_compress_columns_keeps_nonzero_columns_in_order():
    rng = np.random.default_rng(0)
    p = rng.normal(size=(50, 2, 9))
    p[rng.random((50, 2, 9)) < 0.6] = 0.0
    p[3] = 0.0  # a measurement touching nothing
    p[7, :, 4] = np.nan  # NaN partials count as zero (the engine's whitening zeroes them)
    columns = np.array([10, 11, 12, -1, 13, 14, 15, 16, 17])
    a, cols = compress_columns(p, columns)
    dense = np.nan_to_num(p)
    dense[:, :, 3] = 0.0  # column -1 is dropped
    kc = int(np.max(np.sum(np.any(dense != 0, axis=1), axis=1)))
    assert a.shape == (50, 2, kc) and cols.shape == (50, kc)
    assert np.all(cols[3] == -1) and np.all(a[3] == 0)
    back = np.zeros((50, 2, 18))
    for m in range(50):  # scatter back: the same partials in the same global columns
        ok = cols[m] >= 0
        back[m][:, cols[m][ok]] = a[m][:, ok]
        assert np.all(np.diff(cols[m][ok]) > 0)  # order kept
        assert np.all(a[m][:, ~ok] == 0)
    assert np.array_equal(back[:, :, columns[columns >= 0]], dense[:, :, columns >= 0])


def test_compress_columns_dense_rows_unchanged():
    rng = np.random.default_rng(1)
    p = rng.normal(size=(20, 2, 6))
    a, cols = compress_columns(p, np.arange(6) + 4)
    assert np.array_equal(a, p)
    assert np.array_equal(cols, np.broadcast_to(np.arange(6) + 4, (20, 6)))
    per_row = np.tile(np.arange(6), (20, 1))
    assert np.array_equal(compress_columns(p, per_row)[1], per_row)


# ================================================================================ NormalSystem
def _sparse_problem(seed: int = 0, n_images: int = 4, n_knots: int = 30, n_points: int = 60,
                    dense_cols: int = 3):
    """A random system whose images have ``dense_cols`` global parameters and a spline of
    ``n_knots`` knots; each measurement touches the dense ones and four consecutive knots."""
    rng = np.random.default_rng(seed)
    per = dense_cols + n_knots
    gidx = (np.arange(n_images)[:, None] * per + np.arange(per)).astype(np.intp)
    k = n_images * per
    image_of, point_of = [], []
    for j in range(n_points):
        imgs = rng.choice(n_images, size=rng.integers(2, 5), replace=True)
        image_of.extend(imgs.tolist())
        point_of.extend([j] * imgs.size)
    image_of = np.array(image_of, np.intp)
    point_of = np.array(point_of, np.intp)
    m = image_of.size
    a = np.zeros((m, 2, per))
    a[:, :, :dense_cols] = rng.normal(size=(m, 2, dense_cols))
    first = rng.integers(0, n_knots - 3, size=m)
    rows = np.arange(m)[:, None]
    a[rows, 0, dense_cols + first[:, None] + np.arange(4)] = rng.normal(size=(m, 4))
    a[rows, 1, dense_cols + first[:, None] + np.arange(4)] = rng.normal(size=(m, 4))
    b = rng.normal(size=(m, 2, 3))
    v = rng.normal(size=(m, 2))
    # a smoothness-like prior: tridiagonal within each image's knots, plus a ridge
    n_pp_prior = 0.05 * np.eye(k)
    for i in range(n_images):
        o = i * per + dense_cols
        d2 = np.diff(np.eye(n_knots), 2, axis=0)
        n_pp_prior[o:o + n_knots, o:o + n_knots] += d2.T @ d2
    y = rng.normal(size=(n_points, 3, 3))
    return dict(n_params=k, gidx=gidx, image_of=image_of, point_of=point_of, a=a, b=b, v=v,
                n_pp_prior=n_pp_prior, b_p_prior=rng.normal(size=k),
                n_xx_extra=0.2 * y @ np.swapaxes(y, 1, 2) + 0.1 * np.eye(3),
                b_x_extra=rng.normal(size=(n_points, 3)),
                pairs=measurement_pairs(point_of, n_points))


def _outputs(p, damping=0.0, **extra):
    system = NormalSystem(**p, **extra)
    dp, dx = system.solve(damping)
    q_pp = system.parameter_cofactor()
    q_xx, q_px = system.point_cofactors(q_pp)
    # Q_px scattered to global columns: (M, K, 3)
    cols = system._cols
    q_px_full = np.zeros((cols.shape[0], p["n_params"], 3))
    rows = np.broadcast_to(np.arange(cols.shape[0])[:, None], cols.shape)
    ok = cols >= 0
    q_px_full[rows[ok], cols[ok]] = q_px[ok]
    touched = np.zeros(q_px_full.shape[:2], bool)
    touched[rows[ok], cols[ok]] = True
    reduced = system.reduced
    reduced = reduced.toarray() if scipy.sparse.issparse(reduced) else reduced
    return dict(n_pp=system.n_pp, b_p=system.b_p, reduced=reduced, dp=dp, dx=dx, q_pp=q_pp,
                q_xx=q_xx, q_px=q_px_full, hat=system.hat_blocks(q_pp, q_xx, q_px),
                touched=touched)


def _assert_close(got, want, rtol=1e-12):
    """``Q_px`` only in the columns each measurement touches in ``got`` (a compressed
    system has its cofactors with its own parameters there only: what the hat blocks need)."""
    assert np.all(want["touched"] | ~got["touched"])
    want = {**want, "q_px": np.where(got["touched"][:, :, None], want["q_px"], 0.0)}
    for key, w in want.items():
        if key == "touched":
            continue
        scale = max(np.abs(w).max(), 1e-300)
        assert np.abs(got[key] - w).max() <= rtol * scale, key


@pytest.fixture(params=[True, False], ids=["numba", "numpy"])
def kernels(request, monkeypatch):
    monkeypatch.setattr(normal, "USE_NUMBA", request.param)
    return request.param


@pytest.mark.parametrize("damping", [0.0, 0.2])
def test_compressed_columns_equal_dense_layout(kernels, damping):
    p = _sparse_problem(2)
    dense = _outputs(p, damping)
    a, cols = compress_columns(p["a"], p["gidx"][p["image_of"]])
    assert a.shape[2] == 3 + 4  # three global parameters and four knots of 33
    _assert_close(_outputs({**p, "a": a}, damping, cols=cols), dense)


def test_compressed_sparse_path_in_runs_of_points(kernels, monkeypatch):
    """The reduced system above DENSE_LIMIT, its triplets built for runs of a few points,
    equals the dense one."""
    p = _sparse_problem(3, n_images=3, n_knots=40, n_points=80)
    a, cols = compress_columns(p["a"], p["gidx"][p["image_of"]])
    pc = {**p, "a": a}
    dense = _outputs(pc, 0.1, cols=cols)
    monkeypatch.setattr(normal, "DENSE_LIMIT", 0)
    monkeypatch.setattr(normal, "SPARSE_CHUNK_TRIPLETS", 500)  # several runs
    n = np.bincount(p["point_of"])
    assert normal._chunks(n * (n + 1) * 49, 500).size > 10
    system = NormalSystem(**pc, cols=cols)
    system.solve(0.1)
    assert scipy.sparse.issparse(system.reduced)
    _assert_close(_outputs(pc, 0.1, cols=cols), dense, rtol=1e-10)


def test_compressed_numba_and_numpy_agree(monkeypatch):
    p = _sparse_problem(4, n_images=5, n_knots=25, n_points=70)
    a, cols = compress_columns(p["a"], p["gidx"][p["image_of"]])
    out = {}
    for flag in (False, True):
        monkeypatch.setattr(normal, "USE_NUMBA", flag)
        out[flag] = _outputs({**p, "a": a}, 0.0, cols=cols)
    _assert_close(out[True], out[False], rtol=1e-10)


def test_chunks():
    w = np.array([3, 3, 3, 10, 1, 1, 0, 2])
    e = normal._chunks(w, 6)
    assert e[0] == 0 and e[-1] == w.size and np.all(np.diff(e) > 0)
    sums = np.add.reduceat(w, e[:-1])
    assert np.all((sums <= 6) | (np.diff(e) == 1))  # a heavier point alone
    assert normal._chunks(np.zeros(0, np.intp), 6).tolist() == [0]


def test_cols_must_match_partials():
    p = _sparse_problem(5)
    with pytest.raises(ValueError, match="cols"):
        NormalSystem(**p, cols=np.zeros((p["a"].shape[0], 2), np.intp))


# ================================================================================ engine
def _dense_layout(partials, columns):
    """compress_columns' stand-in keeping every column (the dense per-image layout)."""
    p = np.asarray(partials, float)
    return p, np.ascontiguousarray(np.broadcast_to(columns, p.shape[::2]))


def _result_arrays(r):
    return dict(cov=r.covariance,
                params=np.concatenate([e.values for e in r.parameters.values()]),
                sigmas=np.concatenate([e.sigmas for e in r.parameters.values()]),
                pts=np.stack([r.points.lon, r.points.lat, r.points.h]),
                pcov=r.points.covariance, test=r.measurements.test,
                red=r.measurements.redundancy_row, sigma0=np.array([r.sigma0]))


@pytest.mark.parametrize("options", [{}, {"robust": "snooping"}, {"mode": "single"}],
                         ids=["block", "snooping", "single"])
def test_spline_block_compressed_equals_dense(monkeypatch, options):
    """A whole adjustment of a model with 6 + 3 x 13 parameters per image whose
    measurements touch 18: the engine compresses to 18 columns, with the numbers of the
    dense layout."""
    block = _spline_block(tps=150)
    seen = []

    def spy(partials, columns):
        out = compress_columns(partials, columns)
        seen.append((partials.shape[2], out[1].shape[1]))
        return out

    monkeypatch.setattr(engine, "compress_columns", spy)
    sparse = adjust(block, **options)
    assert {s for s in seen} == {(45, 18)}
    monkeypatch.setattr(engine, "compress_columns", _dense_layout)
    dense = adjust(block, **options)
    assert sparse.iterations == dense.iterations
    got, want = _result_arrays(sparse), _result_arrays(dense)
    for key in want:
        fin = np.isfinite(want[key])
        assert np.array_equal(fin, np.isfinite(got[key])), key
        scale = max(np.abs(want[key][fin]).max(), 1e-300)
        assert np.abs(got[key][fin] - want[key][fin]).max() <= 1e-9 * scale, key


def test_spline_block_recovers_row_dependent_error():
    """The spline set is estimated, not just carried: an injected smooth row shift
    (a few tenths of a pixel, varying along the rows) is recovered to the noise."""
    # a small on-board error: the wave is injected at the measured rows, which then lie
    # within a pixel of the model's (the knots' truth is not blurred by the error)
    sb = affine_block((1, 3), tps=300, gcps=60, icps=6, seed=9, sigma_px=0.05, error_px=1.0,
                      error_affine=1e-4, sigma_ground_m=0.01)
    truth = {}
    models = {}
    for i, m in sb.block.models.items():
        model = RowSplineCorrection(m.model, 100.0, sigma=1.0)
        n = model._n
        wave = 0.3 * np.sin(2 * np.pi * np.arange(n) / 7.0 + len(truth))
        truth[i] = wave
        models[i] = model
    # measurements made through the models carrying the wave (the affine error stays)
    meas = sb.block.measurements
    row = meas.row.copy()
    for i, model in models.items():
        values = model.parameters.values.copy()
        values[6:6 + model._n] = truth[i]
        carrying = model.with_parameters(values)
        sel = meas.image == i
        r0 = model._correction(meas.row[sel], meas.col[sel])[0][:, 0]
        r1 = carrying._correction(meas.row[sel], meas.col[sel])[0][:, 0]
        row[sel] += r1 - r0
    moved = type(meas)(meas.id, meas.image, row, meas.col, meas.sigma_row, meas.sigma_col,
                       meas.kind)
    block = Block(models, moved, sb.block.ground, sb.block.dem, sb.block.dem_sigma_m)
    result = adjust(block)
    assert result.converged
    for i, model in models.items():
        est = result.parameters[i]
        got = est.values[6:6 + model._n]
        # knots under the measured rows (the ends beyond them are held by the prior only)
        inner = slice(2, model._n - 2)
        err = got[inner] - truth[i][inner]
        # a constant and a trend along the rows trade with the affine a0, a1 (a cubic
        # B-spline reproduces a line): compared without them
        k = np.arange(err.size)
        err -= np.polyval(np.polyfit(k, err, 1), k)
        assert np.sqrt(np.mean(err**2)) < 0.05
        assert np.std(truth[i][inner]) > 0.15  # the wave is there to recover
