"""The numpy localisation (geoblock_rpc.reference.localise, used by the reader's plausibility
check so that opening a model compiles no kernel) agrees with the compiled kernel: the same
status for every point, the same ground point to 1e-9 degrees."""

from __future__ import annotations

import numpy as np
import pytest
from geoblock_rpc import _kernels
from geoblock_rpc.readers import read_rpc
from geoblock_rpc.reference import localise
from hypothesis import given, settings
from hypothesis import strategies as st


def _kernel(rpc, row, col, h):
    n = row.size
    lon, lat, status = np.empty(n), np.empty(n), np.empty(n, np.uint8)
    prm = _kernels.pack(rpc, 1e6, 1e6, None)
    _kernels.localise_serial(row, col, h, prm, np.ascontiguousarray(rpc.coefficients),
                             1e-6, 1e-3, 60, lon, lat, status)
    return lon, lat, status


def _compare(rpc, row, col, h):
    lon, lat, status = _kernel(rpc, row, col, h)
    lon_r, lat_r, status_r = localise(rpc, row, col, h, 1e-6, 1e-3, 60)
    np.testing.assert_array_equal(status_r, status)
    ok = status == 0
    np.testing.assert_allclose(lon_r[ok], lon[ok], rtol=0, atol=1e-9)
    np.testing.assert_allclose(lat_r[ok], lat[ok], rtol=0, atol=1e-9)
    assert np.isnan(lon_r[~ok]).all() and np.isnan(lat_r[~ok]).all()
    return status


def _image_grid(rpc, reach):
    u, v, w = np.meshgrid(np.linspace(-reach, reach, 9), np.linspace(-reach, reach, 9),
                          [-1.0, 0.0, 1.0], indexing="ij")
    row = rpc.line_off + u.ravel() * abs(rpc.line_scale)
    col = rpc.samp_off + v.ravel() * abs(rpc.samp_scale)
    h = rpc.height_off + w.ravel() * abs(rpc.height_scale)
    return row, col, h


def test_agrees_with_the_kernel_on_every_real_rpc(data_dir, rpc_file):
    path = data_dir / rpc_file
    if not path.exists():
        pytest.skip(f"{rpc_file} absent")
    rpc = read_rpc(path)[0]
    status = _compare(rpc, *_image_grid(rpc, 1.0))
    assert (status == 0).any()
    _compare(rpc, *_image_grid(rpc, 3.0))  # far outside the image: diverged points too
    _compare(rpc, *_image_grid(rpc, 40.0))
    bad = np.array([np.nan, rpc.line_off, rpc.line_off])
    _compare(rpc, bad, np.array([rpc.samp_off, np.inf, rpc.samp_off]),
             np.array([0.0, 0.0, np.nan]))


@settings(deadline=None, max_examples=60)
@given(st.floats(-2.0, 2.0), st.floats(-2.0, 2.0), st.floats(-1.5, 1.5))
def test_agrees_with_the_kernel_anywhere(data_dir, u, v, w):
    path = data_dir / "stereopipeline/tests/sample.RPB"  # zeros of a denominator in the image
    if not path.exists():
        pytest.skip("sample.RPB absent")
    rpc = read_rpc(path)[0]
    row = np.array([rpc.line_off + u * abs(rpc.line_scale)])
    col = np.array([rpc.samp_off + v * abs(rpc.samp_scale)])
    h = np.array([rpc.height_off + w * abs(rpc.height_scale)])
    _compare(rpc, row, col, h)
