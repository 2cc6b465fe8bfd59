"""RpcModel.project_with_status(out=...) and backproject_with_status(out=...): the same bits as
the default path, into the caller's arrays; and the projection kernels against a plain numpy
evaluation in the kernels' order of operations."""

from __future__ import annotations

import numpy as np
import pytest
from geoblock_rpc import RpcModel, _kernels, _small
from geoblock_rpc.model import PARALLEL_MIN_POINTS

from geoblock import Status


def ground_sample(model: RpcModel, n: int, seed: int = 0):
    """Ground points over the image and height range, with a few failures of each kind."""
    rng = np.random.default_rng(seed)
    rows, cols = model.shape
    h = rng.uniform(*model.height_range, n)
    g, _ = model.backproject_with_status(
        rng.uniform(-0.5, rows - 0.5, n), rng.uniform(-0.5, cols - 0.5, n), h
    )
    lon = np.where(np.isfinite(g.lon), g.lon, model.rpc.long_off)
    lat = np.where(np.isfinite(g.lat), g.lat, model.rpc.lat_off)
    lon[:7] = np.nan  # INVALID_INPUT
    lat[7:14] = np.inf
    lon[14:21] += 1.0  # ~27 normalised units off: OUT_OF_DOMAIN
    h[21:28] = 1e7
    lon[28:35] = 1e300
    lon[35:42] += 360.0  # the same place: converges
    return lon, lat, h


def scalar_order_projection(model: RpcModel, lon, lat, h):
    """The kernels' arithmetic, operation by operation, in numpy (IEEE, no FMA): row, col."""
    r = model.rpc
    d = lon - r.long_off
    d = d - 360.0 * np.floor((d + 180.0) / 360.0)
    L = d / r.long_scale
    P = (lat - r.lat_off) / r.lat_scale
    H = (h - r.height_off) / r.height_scale
    LP, LH, PH, LL, PP, HH = L * P, L * H, P * H, L * L, P * P, H * H
    terms = [1.0, L, P, H, LP, LH, PH, LL, PP, HH, LP * H, LL * L, L * PP, L * HH, LL * P,
             PP * P, P * HH, LL * H, PP * H, HH * H]
    sums = []
    for c in model.rpc.coefficients:
        acc = c[0] * terms[0]
        for k in range(1, 20):
            acc = acc + c[k] * terms[k]
        sums.append(acc)
    row = sums[0] / sums[1] * r.line_scale + r.line_off
    col = sums[2] / sums[3] * r.samp_scale + r.samp_off
    return row, col


def empty_out(shape):
    return np.empty(shape), np.empty(shape), np.empty(shape, np.uint8)


@pytest.mark.parametrize("n", [1000, PARALLEL_MIN_POINTS + 1000])  # serial, parallel kernel
def test_out_gives_the_bits_of_the_default_path_into_the_arrays_given(n):
    model = RpcModel.example()
    lon, lat, h = ground_sample(model, n)
    (row, col), status = model.project_with_status(lon, lat, h)
    out = empty_out(n)
    for a in out:
        a.fill(7)  # stale content of a reused buffer
    (row2, col2), status2 = model.project_with_status(lon, lat, h, out=out)
    assert row2 is out[0] and col2 is out[1] and status2 is out[2]
    assert row2.tobytes() == row.tobytes()
    assert col2.tobytes() == col.tobytes()
    assert status2.tobytes() == status.tobytes()
    # again into the same buffers: the same bits
    model.project_with_status(lon, lat, h, out=out)
    assert out[0].tobytes() == row.tobytes() and out[2].tobytes() == status.tobytes()


@pytest.mark.parametrize("n", [1000, PARALLEL_MIN_POINTS + 1000])
def test_projection_kernels_equal_the_scalar_arithmetic_to_the_bit(n):
    """The block loop is SIMD-vectorised; it must still be the per-point IEEE arithmetic."""
    model = RpcModel.example()
    lon, lat, h = ground_sample(model, n, seed=1)
    (row, col), status = model.project_with_status(lon, lat, h)
    ok = status == Status.CONVERGED
    assert ok.sum() > 0.9 * n
    ref_row, ref_col = scalar_order_projection(model, lon[ok], lat[ok], h[ok])
    assert row[ok].tobytes() == ref_row.tobytes()
    assert col[ok].tobytes() == ref_col.tobytes()
    assert np.isnan(row[~ok]).all() and np.isnan(col[~ok]).all()


def test_the_projection_loop_is_simd_vectorised():
    """A branch or an early return in the per-point code leaves LLVM's loop scalar (issue 30:
    25 ns per point on 1 thread against 7 vectorised, slower than rpcfast). The block function
    is compiled afresh (numba shows no IR of cached code) and its optimised IR must divide
    whole vectors of doubles."""
    import re

    import numba

    block = numba.njit(nogil=True, error_model="numpy")(_kernels._project_block.py_func)
    model = RpcModel.example()
    lon, lat, h = ground_sample(model, 64)
    row, col, status = empty_out(64)
    block(lon, lat, h, model._prm, model._coef, row, col, status, 0, 64)
    ir = block.inspect_llvm(block.signatures[0])
    assert re.search(r"fdiv (?:\w+ )*<\d+ x double>", ir), "the projection loop is not vectorised"
    row2, col2, status2 = empty_out(64)
    _kernels.project_serial(lon, lat, h, model._prm, model._coef, row2, col2, status2)
    assert row.tobytes() == row2.tobytes() and status.tobytes() == status2.tobytes()


@pytest.mark.parametrize("kernel", [_kernels.project, _kernels.project_serial])
def test_status_precedence_of_the_branch_free_point(kernel):
    """Every test of a point is evaluated (no early return); the status keeps the order the
    branching code had: INVALID_INPUT, then OUT_OF_DOMAIN, then DIVERGED."""
    model = RpcModel.example()
    n = PARALLEL_MIN_POINTS + 64 if kernel is _kernels.project else 64
    lon, lat, h = ground_sample(model, n)
    lon[42], h[42] = np.nan, 1e7  # invalid and out of the height domain
    lat[43], lon[43] = np.nan, 1e300  # invalid and off the Earth
    lon[44] = -1e300  # off the Earth: not wrapped into the domain
    lat[45] = 90.5  # beyond the pole
    h[46] = -np.inf
    row, col, status = empty_out(n)
    kernel(lon, lat, h, model._prm, model._coef, row, col, status)
    expected = np.full(n, Status.CONVERGED, np.uint8)
    expected[:14] = expected[42:44] = expected[46] = Status.INVALID_INPUT
    expected[14:35] = expected[44:46] = Status.OUT_OF_DOMAIN
    assert status.tolist() == expected.tolist()
    bad = expected != Status.CONVERGED
    assert np.isnan(row[bad]).all() and np.isnan(col[bad]).all()
    assert np.isfinite(row[~bad]).all() and np.isfinite(col[~bad]).all()
    coef = model._coef.copy()
    coef[3] = 0.0  # column denominator: DIVERGED, after the input and domain tests
    kernel(lon, lat, h, model._prm, coef, row, col, status)
    expected[~bad] = Status.DIVERGED
    assert status.tolist() == expected.tolist() and np.isnan(col).all()


def test_nan_and_out_of_domain_inputs_get_nan_and_their_status_through_out():
    model = RpcModel.example()
    lon = np.array([7.05, np.nan, 7.05, 8.05, 7.05, 1e300])
    lat = np.array([43.7, 43.7, -np.inf, 43.7, 43.7, 43.7])
    h = np.array([500.0, 500.0, 500.0, 500.0, 1e7, 500.0])
    out = empty_out(6)
    (row, col), status = model.project_with_status(lon, lat, h, out=out)
    assert list(status) == [Status.CONVERGED, Status.INVALID_INPUT, Status.INVALID_INPUT,
                            Status.OUT_OF_DOMAIN, Status.OUT_OF_DOMAIN, Status.OUT_OF_DOMAIN]
    assert np.isfinite(row[0]) and np.isfinite(col[0])
    assert np.isnan(row[1:]).all() and np.isnan(col[1:]).all()


def test_out_with_scalar_inputs_takes_0d_arrays():
    model = RpcModel.example()
    out = empty_out(())
    (row, col), status = model.project_with_status(7.05, 43.7, 500.0, out=out)
    assert row is out[0] and status is out[2] and row.shape == ()
    (r0, c0), s0 = model.project_with_status(7.05, 43.7, 500.0)
    assert row.tobytes() == r0.tobytes() and col.tobytes() == c0.tobytes()
    assert int(status) == int(s0) == Status.CONVERGED


def test_out_with_2d_broadcast_inputs():
    model = RpcModel.example()
    lon = np.linspace(7.03, 7.07, 12).reshape(3, 4)
    lat = 43.7
    h = np.array([0.0, 100.0, 200.0, 300.0])
    out = empty_out((3, 4))
    (row, col), status = model.project_with_status(lon, lat, h, out=out)
    (r0, c0), s0 = model.project_with_status(lon, lat, h)
    assert row is out[0] and row.shape == (3, 4)
    assert row.tobytes() == r0.tobytes() and col.tobytes() == c0.tobytes()
    assert status.tobytes() == s0.tobytes() and (status == Status.CONVERGED).all()


@pytest.mark.parametrize(
    ("make", "match"),
    [
        (lambda: (np.empty(4), np.empty(5), np.empty(5, np.uint8)),
         r"out\[0\] \(row\).*shape \(5,\)"),
        (lambda: (np.empty(5), np.empty(5, np.float32), np.empty(5, np.uint8)),
         r"out\[1\] \(col\).*float64.*got float32"),
        (lambda: (np.empty(5), np.empty(5), np.empty(5, np.int64)), r"out\[2\] \(status\).*uint8"),
        (lambda: (np.empty(10)[::2], np.empty(5), np.empty(5, np.uint8)),
         r"out\[0\] \(row\).*C-contiguous"),
        (lambda: (np.empty(5), np.empty((5, 1)), np.empty(5, np.uint8)),
         r"out\[1\] \(col\).*shape"),
        (lambda: (np.empty(5), [0.0] * 5, np.empty(5, np.uint8)), r"out\[1\] \(col\).*numpy array"),
        (lambda: (np.empty(5), np.empty(5)), r"out must be 3 arrays \(row, col, status\), got 2"),
        (lambda: np.empty((3, 5)), r"3 arrays.*got ndarray"),
    ],
)
def test_out_refuses_wrong_arrays_naming_the_argument(make, match):
    model = RpcModel.example()
    lon = np.full(5, 7.05)
    with pytest.raises(ValueError, match=match):
        model.project_with_status(lon, 43.7, 500.0, out=make())


def test_out_refuses_read_only_and_overlapping_arrays():
    model = RpcModel.example()
    lon, lat, h = np.full(5, 7.05), np.full(5, 43.7), np.full(5, 500.0)
    row, col, status = empty_out(5)
    row.flags.writeable = False
    with pytest.raises(ValueError, match=r"out\[0\] \(row\) must be C-contiguous and writeable"):
        model.project_with_status(lon, lat, h, out=(row, col, status))
    both = np.empty(5)
    with pytest.raises(ValueError, match=r"out\[1\] \(col\) overlaps out\[0\] \(row\)"):
        model.project_with_status(lon, lat, h, out=(both, both, status))
    with pytest.raises(ValueError, match=r"out\[0\] \(row\) overlaps an input"):
        model.project_with_status(lon, lat, h, out=(lon, col, status))


@pytest.mark.parametrize("kernel", [_kernels.project, _kernels.project_serial,
                                    _small.project])
def test_a_zero_denominator_is_diverged_in_both_kernels(kernel):
    """numpy's error model: the serial kernel used to raise ZeroDivisionError here."""
    model = RpcModel.example()
    coef = model._coef.copy()
    coef[1] = 0.0  # line denominator
    row, col, status = empty_out(3)
    kernel(np.full(3, 7.05), np.full(3, 43.7), np.full(3, 500.0), model._prm, coef, row, col,
           status)
    assert list(status) == [Status.DIVERGED] * 3
    assert np.isnan(row).all() and np.isnan(col).all()


@pytest.mark.parametrize("n", [1001, PARALLEL_MIN_POINTS + 1001])  # serial, parallel; odd
def test_backproject_out_gives_the_bits_of_the_default_path_into_the_arrays_given(n):
    model = RpcModel.example()
    rng = np.random.default_rng(2)
    rows, cols = model.shape
    row = rng.uniform(-0.2 * rows, 1.2 * rows, n)
    col = rng.uniform(-0.2 * cols, 1.2 * cols, n)
    h = rng.uniform(-1000.0, 3000.0, n)
    row[:5] = np.nan
    h[5:10] = 1e7
    g, status = model.backproject_with_status(row, col, h)
    assert {Status.CONVERGED, Status.INVALID_INPUT, Status.OUT_OF_DOMAIN} <= set(status.tolist())
    out = empty_out(n)[:2] + (np.full(n, 7.0), np.full(n, 9, np.uint8))
    g2, status2 = model.backproject_with_status(row, col, h, out=out)
    assert g2.lon is out[0] and g2.lat is out[1] and g2.h is out[2] and status2 is out[3]
    for a, b in zip((*g, status), (*g2, status2), strict=True):
        assert a.tobytes() == b.tobytes()
    ok = status == Status.CONVERGED
    assert (g.h[ok] == h[ok]).all() and np.isnan(g.h[~ok]).all() and np.isnan(g.lon[~ok]).all()


def test_backproject_out_with_scalar_and_2d_inputs_and_its_checks():
    model = RpcModel.example()
    out = empty_out(())[:2] + (np.empty(()), np.empty((), np.uint8))
    g, status = model.backproject_with_status(5000.0, 6000.0, 500.0, out=out)
    assert g.lon is out[0] and g.lon.shape == () and int(status) == Status.CONVERGED
    assert float(g.h) == 500.0
    row = np.linspace(0.0, 9000.0, 6).reshape(2, 3)
    out = empty_out((2, 3))[:2] + (np.empty((2, 3)), np.empty((2, 3), np.uint8))
    g, status = model.backproject_with_status(row, 6000.0, 0.0, out=out)
    g0, s0 = model.backproject_with_status(row, 6000.0, 0.0)
    assert g.lat is out[1] and g.lat.tobytes() == g0.lat.tobytes()
    assert status.tobytes() == s0.tobytes()
    with pytest.raises(ValueError, match=r"out\[2\] \(h\) must be a float64 array of shape \(2, 3"):
        model.backproject_with_status(row, 6000.0, 0.0, out=(*out[:2], np.empty(6), out[3]))
    with pytest.raises(ValueError, match=r"out must be 4 arrays \(lon, lat, h, status\), got 3"):
        model.backproject_with_status(row, 6000.0, 0.0, out=out[:3])
    with pytest.raises(ValueError, match=r"out\[0\] \(lon\) overlaps an input"):
        model.backproject_with_status(row, 6000.0, 0.0, out=(row, *out[1:]))
