"""geoblock._jit: kernels compiled on first call, agreeing with their Python source."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import textwrap
import threading

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from geoblock._array import _nb_all_finite, _nb_finite_bounds, all_finite, finite_bounds
from geoblock._jit import LazyKernel, lazy_njit

floats = st.floats(allow_nan=True, allow_infinity=True, width=64)


@settings(deadline=None)  # the first example loads numba
@given(arrays(np.float64, st.integers(0, 40), elements=floats),
       arrays(np.float64, st.integers(0, 40), elements=floats))
def test_array_kernels_agree_with_their_python_source(x, y):
    n = min(x.size, y.size)
    x, y = np.ascontiguousarray(x[:n]), np.ascontiguousarray(y[:n])
    assert isinstance(_nb_all_finite, LazyKernel)
    assert _nb_all_finite(x, y) == _nb_all_finite.py_func(x, y)
    fast = _nb_finite_bounds(x, y)
    ref = _nb_finite_bounds.py_func(x, y)
    np.testing.assert_array_equal(np.array(fast), np.array(ref))
    # and the public helpers keep their meaning: numpy's NaN-ignoring reductions
    assert all_finite(x, y) == bool(np.all(np.isfinite(x)) and np.all(np.isfinite(y)))
    expected = []
    for a in (x, y):
        kept = a[~np.isnan(a)]
        expected += [kept.min(), kept.max()] if kept.size else [np.nan, np.nan]
    np.testing.assert_array_equal(np.array(finite_bounds(x, y)), np.array(expected))


def test_finite_bounds_ignores_nan():
    x = np.array([1.0, np.nan, -2.0])
    y = np.array([np.nan, 5.0, 4.0])
    assert finite_bounds(x, y) == (-2.0, 1.0, 4.0, 5.0)
    assert np.isnan(finite_bounds(np.array([np.nan]), np.array([np.nan]))).all()


def test_kernel_compiles_on_first_call_once_across_threads():
    @lazy_njit(nogil=True)
    def add(a, b):
        return a + b

    assert not add.loaded and add.__name__ == "add"
    dispatchers = []
    barrier = threading.Barrier(4)

    def call():
        barrier.wait()
        assert add(1.0, 2.0) == 3.0
        dispatchers.append(add.load())

    threads = [threading.Thread(target=call) for _ in range(4)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert add.loaded and len({id(d) for d in dispatchers}) == 1
    assert "loaded" in repr(add)


def test_importing_the_array_helpers_imports_no_numba():
    code = textwrap.dedent("""
        import json, sys
        import geoblock._array, geoblock.coords
        print(json.dumps("numba" in sys.modules))
    """)
    env = {k: v for k, v in os.environ.items() if k != "GEOBLOCK_PLUGIN_MODULES"}
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True, env=env).stdout.strip().splitlines()[-1]
    assert json.loads(out) is False
